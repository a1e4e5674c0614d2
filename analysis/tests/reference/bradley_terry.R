# Reference values for the Bradley–Terry tests of mrstudy-analysis.
#
# Run from the repository root:
#
#     Rscript analysis/tests/reference/bradley_terry.R
#
# It rewrites every *.json file in analysis/tests/reference/ (see README.md there).
# Needs R with BradleyTerry2 and brglm (jsonlite only for string escaping and for
# re-reading the files as a check). Numbers are written by this script's own
# serializer with the shortest of %.15g/%.16g/%.17g that reads back to the identical
# double, so full precision survives; the script stops if any number is not finite.
#
# Scale: coefficients are log-worths / covariate effects on the logit scale of
# P(i beats j) = plogis(lambda_i - lambda_j), as in BradleyTerry2 and in docs/design.md.

suppressPackageStartupMessages({
  library(BradleyTerry2)
  library(brglm)
  library(jsonlite)
})

args_all <- commandArgs(trailingOnly = FALSE)
script_arg <- sub("^--file=", "", args_all[grep("^--file=", args_all)])
out_dir <- if (length(script_arg) == 1) dirname(normalizePath(script_arg)) else "analysis/tests/reference"

SOURCE <- sprintf("R %s.%s, BradleyTerry2 %s (BTm), brglm %s",
                  R.version$major, R.version$minor,
                  as.character(packageVersion("BradleyTerry2")),
                  as.character(packageVersion("brglm")))

# Tight convergence, so the recorded MLEs / bias-reduced estimates are exact to far
# below the 1e-6 the tests use (R's defaults are epsilon = 1e-8 on the relative
# deviance change for glm and 1e-8 on the summed |modified score| for brglm).
ML_CONTROL <- list(epsilon = 1e-14, maxit = 100)
BR_CONTROL <- list(br.epsilon = 1e-12, br.maxit = 500, epsilon = 1e-14, maxit = 100)

# ---------------------------------------------------------------------------
# Minimal JSON writer (full double precision, deterministic layout).

fmt_num <- function(x) {
  if (!is.finite(x)) stop("non-finite number in output: ", x)
  if (x == 0) return("0")
  if (x == round(x) && abs(x) < 1e15) return(sprintf("%.0f", x))
  for (d in 15:17) {
    s <- sprintf(paste0("%.", d, "g"), x)
    if (as.numeric(s) == x) return(s)
  }
  stop("cannot format ", x)
}

fmt_scalar <- function(x) {
  if (is.factor(x)) x <- as.character(x)
  if (is.character(x)) return(as.character(jsonlite::toJSON(x, auto_unbox = TRUE)))
  if (is.logical(x)) { if (is.na(x)) stop("NA in output"); return(if (x) "true" else "false") }
  if (is.numeric(x)) return(fmt_num(as.numeric(x)))
  stop("unsupported scalar type: ", class(x))
}

to_json <- function(x, indent = 0) {
  pad <- strrep("  ", indent + 1)
  pad0 <- strrep("  ", indent)
  if (is.list(x) && !is.null(names(x))) {
    if (length(x) == 0) return("{}")
    items <- vapply(names(x), function(k)
      paste0(pad, fmt_scalar(k), ": ", to_json(x[[k]], indent + 1)), "")
    return(paste0("{\n", paste(items, collapse = ",\n"), "\n", pad0, "}"))
  }
  if (is.list(x)) {
    # arrays: flat arrays of scalars on one line, anything else one element per line
    flat <- all(vapply(x, function(e) is.atomic(e) && length(e) == 1 && is.null(names(e)), TRUE))
    if (flat) return(paste0("[", paste(vapply(x, fmt_scalar, ""), collapse = ", "), "]"))
    items <- vapply(x, function(e) paste0(pad, to_json(e, indent + 1)), "")
    return(paste0("[\n", paste(items, collapse = ",\n"), "\n", pad0, "]"))
  }
  if (is.atomic(x) && !is.null(names(x))) return(to_json(as.list(x), indent))
  if (is.atomic(x) && length(x) == 1 && !inherits(x, "AsIs")) return(fmt_scalar(x))
  if (is.atomic(x)) return(paste0("[", paste(vapply(unclass(x), fmt_scalar, ""), collapse = ", "), "]"))
  stop("unsupported type")
}

write_case <- function(obj) {
  path <- file.path(out_dir, paste0(obj$case, ".json"))
  writeLines(to_json(obj), path, useBytes = TRUE)
  back <- jsonlite::fromJSON(path, simplifyVector = FALSE)   # must parse
  stopifnot(identical(back$case, obj$case))
  cat("wrote", path, "\n")
}

# ---------------------------------------------------------------------------
# Helpers for fits.

strip_names <- function(nm, id) {
  nm <- gsub(paste0("\\[", id, "\\]"), "", nm)        # gi[cond] -> gi
  sub(paste0("^", id), "", nm)                          # condGI   -> GI
}

# sum of binomial log-probabilities at the fitted values (check of logLik)
binom_loglik <- function(fit) {
  y <- fit$y; w <- fit$prior.weights; mu <- fitted(fit)
  sum(dbinom(round(y * w), round(w), mu, log = TRUE))
}

coef_table <- function(fit, id) {
  ct <- summary(fit)$coefficients
  nm <- strip_names(rownames(ct), id)
  est <- setNames(ct[, 1], nm); se <- setNames(ct[, 2], nm)
  z <- setNames(ct[, 3], nm)
  p <- setNames(2 * pnorm(-abs(ct[, 3])), nm)
  stopifnot(all(abs(p - ct[, 4]) <= 1e-12 * pmax(1, p)))
  list(coefficients = est, se = se, z = z, p = p)
}

# full record of a maximum-likelihood fit
ml_record <- function(fit, id, formula = NULL, method = "ml", check = TRUE) {
  if (check) stopifnot(fit$converged)
  ll <- logLik(fit)
  if (check) {
    stopifnot(abs(as.numeric(ll) - binom_loglik(fit)) < 1e-9)
    stopifnot(abs(AIC(fit) - (-2 * as.numeric(ll) + 2 * attr(ll, "df"))) < 1e-9)
  }
  c(if (!is.null(formula)) list(formula = formula),
    coef_table(fit, id),
    list(deviance = deviance(fit),
         loglik = as.numeric(ll),
         aic = AIC(fit),
         df_residual = df.residual(fit),
         converged = fit$converged,
         method = method))
}

# record of a bias-reduced (Firth) fit
br_record <- function(fit, id, formula = NULL) {
  stopifnot(inherits(fit, "brglm"), fit$converged)
  # brglm's deviance is that of the original data at the bias-reduced estimates
  dev_check <- sum(binomial()$dev.resids(fit$y, fitted(fit), fit$prior.weights))
  stopifnot(abs(deviance(fit) - dev_check) < 1e-9)
  c(if (!is.null(formula)) list(formula = formula),
    coef_table(fit, id),
    list(deviance = deviance(fit),
         df_residual = df.residual(fit),
         converged = fit$converged,
         method = "br"))
}

lr_test <- function(small, big) {
  chi2 <- deviance(small) - deviance(big)
  df <- df.residual(small) - df.residual(big)
  p <- pchisq(chi2, df, lower.tail = FALSE)
  a <- anova(small, big, test = "Chisq")
  stopifnot(abs(a$Deviance[2] - chi2) < 1e-9, a$Df[2] == df,
            abs(a[["Pr(>Chi)"]][2] - p) < 1e-12)
  list(chi2 = chi2, df = df, p = p)
}

pairs_list <- function(d) {
  lapply(seq_len(nrow(d)), function(k)
    list(as.character(d$p1[k]), as.character(d$p2[k]), as.integer(d$w1[k]), as.integer(d$w2[k])))
}

item_coefs <- function(fit, id) setNames(coef(fit), strip_names(names(coef(fit)), id))

# compare against a plain glm: lambda differences via the +1/-1 design matrix
glm_item_check <- function(fit, d, levels, ref, id) {
  X <- matrix(0, nrow(d), length(levels), dimnames = list(NULL, levels))
  X[cbind(seq_len(nrow(d)), match(as.character(d$p1), levels))] <- 1
  X[cbind(seq_len(nrow(d)), match(as.character(d$p2), levels))] <- -1
  X <- X[, setdiff(levels, ref), drop = FALSE]
  colnames(X) <- make.names(colnames(X))
  g <- glm.fit(X, cbind(d$w1, d$w2), family = binomial(),
               control = glm.control(epsilon = 1e-14, maxit = 100))
  b <- item_coefs(fit, id)[setdiff(levels, ref)]
  stopifnot(max(abs(unname(g$coefficients) - unname(b))) < 1e-9)
  stopifnot(abs(g$deviance - deviance(fit)) < 1e-9)
}

# BTm evaluates outcome/player arguments in `data`, so build the call unevaluated
fit_ml <- function(...) {
  cl <- match.call(); cl[[1]] <- quote(BTm)
  for (k in names(ML_CONTROL)) cl[[k]] <- ML_CONTROL[[k]]
  eval(cl, parent.frame())
}
fit_br <- function(...) {
  cl <- match.call(); cl[[1]] <- quote(BTm); cl$br <- TRUE
  for (k in names(BR_CONTROL)) cl[[k]] <- BR_CONTROL[[k]]
  eval(cl, parent.frame())
}

# ---------------------------------------------------------------------------
# Synthetic 2^3 design shared by factors, full_design and separation_factor.

CONDS <- c("LQ", "GI", "CM", "CA", "GI+CM", "GI+CA", "CM+CA", "HQ")
COV <- data.frame(gi = c(0, 1, 0, 0, 1, 1, 0, 1),
                  cm = c(0, 0, 1, 0, 1, 0, 1, 1),
                  ca = c(0, 0, 0, 1, 0, 1, 1, 1),
                  row.names = CONDS)
LAMBDA <- with(COV, 0.54 * gi - 0.44 * cm + 0.86 * ca + 0.3 * gi * ca)
names(LAMBDA) <- CONDS

# pairs given as a 2-column matrix of indices into CONDS; one rbinom draw per pair,
# in row order, wins of the first-named condition
simulate_pairs <- function(idx, n, seed) {
  set.seed(seed)
  w1 <- rbinom(nrow(idx), n, plogis(LAMBDA[idx[, 1]] - LAMBDA[idx[, 2]]))
  data.frame(p1 = factor(CONDS[idx[, 1]], levels = CONDS),
             p2 = factor(CONDS[idx[, 2]], levels = CONDS),
             w1 = as.integer(w1), w2 = as.integer(n - w1))
}

F_MAIN <- ~ gi[cond] + cm[cond] + ca[cond]
F_INT  <- ~ gi[cond] + cm[cond] + ca[cond] + gi[cond]:ca[cond]

factor_case <- function(case, d, with_interaction, description) {
  dat <- list(contests = d, predictors = COV)
  item <- fit_ml(outcome = cbind(w1, w2), player1 = p1, player2 = p2, id = "cond", data = dat)
  glm_item_check(item, d, CONDS, "LQ", "cond")
  fac <- suppressWarnings(fit_ml(outcome = cbind(w1, w2), player1 = p1, player2 = p2,
                                 formula = F_MAIN, id = "cond", data = dat))
  models <- list(item = ml_record(item, "cond"),
                 factor = c(ml_record(fac, "cond", formula = "gi+cm+ca"),
                            list(lr_vs_items = lr_test(fac, item))))
  if (with_interaction) {
    fint <- suppressWarnings(fit_ml(outcome = cbind(w1, w2), player1 = p1, player2 = p2,
                                    formula = F_INT, id = "cond", data = dat))
    models$factor_interaction <- c(ml_record(fint, "cond", formula = "gi+cm+ca+gi:ca"),
                                   list(lr_vs_items = lr_test(fint, item),
                                        lr_vs_factor = lr_test(fac, fint)))
  }
  list(source = SOURCE, case = case, description = description,
       conditions = I(CONDS), reference = "LQ", pairs = pairs_list(d),
       covariates = list(gi = I(as.integer(COV$gi)), cm = I(as.integer(COV$cm)),
                         ca = I(as.integer(COV$ca))),
       true_log_worth = setNames(as.list(LAMBDA), CONDS),
       models = models)
}

# ---------------------------------------------------------------------------
# 1. citations (Agresti): item model, reference Biometrika

cit <- countsToBinomial(citations)
names(cit)[1:2] <- c("p1", "p2"); names(cit)[3:4] <- c("w1", "w2")
cit_levels <- levels(cit$p1)
stopifnot(identical(cit_levels, levels(cit$p2)))
cit_fit <- fit_ml(outcome = cbind(w1, w2), player1 = p1, player2 = p2,
                  formula = ~ journal, id = "journal", data = cit)
glm_item_check(cit_fit, cit, cit_levels, cit_levels[1], "journal")
stopifnot(abs(item_coefs(cit_fit, "journal")[["Comm Statist"]] + 2.95) < 0.01)
write_case(list(
  source = SOURCE, case = "citations",
  description = paste("BradleyTerry2::citations (Agresti 2002), countsToBinomial;",
                      "wins_i = citations of journal i by journal j.",
                      "BTm(cbind(win1, win2), player1, player2, ~ journal, id = 'journal')"),
  conditions = I(cit_levels), reference = cit_levels[1], pairs = pairs_list(cit),
  models = list(item = ml_record(cit_fit, "journal"))))

# ---------------------------------------------------------------------------
# 2. baseball: item model without home advantage, aggregated to unordered pairs

bb_levels <- levels(baseball$home.team)
stopifnot(identical(bb_levels, levels(baseball$away.team)))
bb_orig <- fit_ml(outcome = cbind(home.wins, away.wins), player1 = home.team,
                  player2 = away.team, id = "team", data = baseball)
h <- match(as.character(baseball$home.team), bb_levels)
a <- match(as.character(baseball$away.team), bb_levels)
lo <- pmin(h, a); hi <- pmax(h, a)
w_lo <- ifelse(h < a, baseball$home.wins, baseball$away.wins)
w_hi <- ifelse(h < a, baseball$away.wins, baseball$home.wins)
key <- paste(lo, hi)
ukeys <- unique(key[order(lo, hi)])
bb <- do.call(rbind, lapply(ukeys, function(k) {
  s <- key == k
  data.frame(p1 = bb_levels[lo[s][1]], p2 = bb_levels[hi[s][1]],
             w1 = sum(w_lo[s]), w2 = sum(w_hi[s]))
}))
bb$p1 <- factor(bb$p1, levels = bb_levels); bb$p2 <- factor(bb$p2, levels = bb_levels)
stopifnot(nrow(bb) == choose(length(bb_levels), 2),
          sum(bb$w1 + bb$w2) == sum(baseball$home.wins + baseball$away.wins))
bb_fit <- fit_ml(outcome = cbind(w1, w2), player1 = p1, player2 = p2, id = "team", data = bb)
glm_item_check(bb_fit, bb, bb_levels, bb_levels[1], "team")
# MLE and SEs are invariant to the aggregation
stopifnot(max(abs(coef(bb_fit) - coef(bb_orig))) < 1e-9,
          max(abs(sqrt(diag(vcov(bb_fit))) - sqrt(diag(vcov(bb_orig))))) < 1e-9)
bb_orig_rec <- ml_record(bb_orig, "team")
write_case(list(
  source = SOURCE, case = "baseball",
  description = paste("BradleyTerry2::baseball (1987 AL East), no home advantage.",
                      "BTm(cbind(home.wins, away.wins), home.team, away.team, id = 'team');",
                      "models.item is the fit on the data aggregated to one row per unordered",
                      "pair (the pairs below), whose MLE and SEs equal the 42-row fit;",
                      "deviance/loglik/aic/df_residual of the 42-row (ordered home/away) fit",
                      "are in models.item_home_away_rows for information."),
  conditions = I(bb_levels), reference = bb_levels[1], pairs = pairs_list(bb),
  models = list(
    item = ml_record(bb_fit, "team"),
    item_home_away_rows = list(deviance = bb_orig_rec$deviance, loglik = bb_orig_rec$loglik,
                               aic = bb_orig_rec$aic, df_residual = bb_orig_rec$df_residual))))

# ---------------------------------------------------------------------------
# 3. factors: anchored design (every condition vs LQ and vs HQ, plus LQ-HQ), n = 280

ANCHORED <- rbind(cbind(1, 2:8), cbind(2:7, 8))      # 13 unordered pairs
fac_d <- simulate_pairs(ANCHORED, 280, 2013)
write_case(factor_case("factors", fac_d, TRUE, paste(
  "Synthetic 2^3 web-survey design, anchored: every condition vs LQ and vs HQ, plus LQ-HQ",
  "(13 pairs), n = 280 per pair. set.seed(2013); wins of the first-named condition =",
  "rbinom(13, 280, plogis(lambda_i - lambda_j)) in the pair order listed;",
  "lambda = 0.54 gi - 0.44 cm + 0.86 ca + 0.3 gi ca.",
  "Factor models: BTm(..., formula = ~ gi[cond] + cm[cond] + ca[cond] (+ gi[cond]:ca[cond]),",
  "id = 'cond') with the covariates as player predictors (no intercept, no random effect).",
  "lr_vs_items: deviance difference to the item model; lr_vs_factor: interaction model vs gi+cm+ca.")))

# ---------------------------------------------------------------------------
# 4. full_design: all 28 pairs, n = 50, set.seed(7)

FULL <- t(combn(8, 2))
full_d <- simulate_pairs(FULL, 50, 7)
write_case(factor_case("full_design", full_d, FALSE, paste(
  "Same 8 conditions and true lambda as factors.json, all 28 unordered pairs (combn order),",
  "n = 50 per pair. set.seed(7); wins of the first-named condition =",
  "rbinom(28, 50, plogis(lambda_i - lambda_j)) in the pair order listed.")))

# ---------------------------------------------------------------------------
# 5. separation: 5 conditions, round robin, A never loses; reference B

SEP_TRUE <- c(A = 0.8, B = 0.4, C = 0, D = -0.3, E = -0.7)
sep_idx <- t(combn(5, 2))
set.seed(11)
sep_w1 <- rbinom(nrow(sep_idx), 20,
                 plogis(SEP_TRUE[sep_idx[, 1]] - SEP_TRUE[sep_idx[, 2]]))
sep_levels <- c("B", "A", "C", "D", "E")                 # first level B = reference
sep_d <- data.frame(p1 = factor(names(SEP_TRUE)[sep_idx[, 1]], levels = sep_levels),
                    p2 = factor(names(SEP_TRUE)[sep_idx[, 2]], levels = sep_levels),
                    w1 = as.integer(sep_w1), w2 = as.integer(20 - sep_w1))
sep_d_generated <- sep_d
isA <- sep_d$p1 == "A"                                   # A is always p1 (combn order)
sep_d$w1[isA] <- 20L; sep_d$w2[isA] <- 0L
# only A is separated: every other pair has both outcomes or at least no all-win subset
stopifnot(all(sep_d$w1[!isA] > 0 & sep_d$w2[!isA] > 0))
sep_br <- fit_br(outcome = cbind(w1, w2), player1 = p1, player2 = p2, id = "cond", data = sep_d)
sep_ml <- suppressWarnings(BTm(cbind(w1, w2), p1, p2, id = "cond", data = sep_d))   # R defaults
write_case(list(
  source = SOURCE, case = "separation",
  description = paste(
    "5 conditions A..E, round robin (10 pairs, combn order of A..E), 20 judgments per pair:",
    "set.seed(11); w1 = rbinom(10, 20, plogis(lambda_i - lambda_j)) with true lambda",
    "A..E = 0.8, 0.4, 0, -0.3, -0.7; then every pair involving A set to 20-0 for A",
    "(generated counts in pairs_generated). Factor levels B, A, C, D, E (reference B).",
    "item_br: BTm(..., br = TRUE), Firth/bias-reduced (brglm, pl = FALSE, i.e. Jeffreys",
    "penalty for the logit link), SEs from the Fisher information at the estimates.",
    "item_ml: ordinary glm with R's default control (epsilon 1e-8, maxit 25): the MLE does",
    "not exist (A -> +infinity); the numbers only document the blow-up and are not a",
    "reference to match."),
  conditions = I(sep_levels), reference = "B", pairs = pairs_list(sep_d),
  pairs_generated = pairs_list(sep_d_generated),
  models = list(item_br = br_record(sep_br, "cond"),
                item_ml = ml_record(sep_ml, "cond", method = "ml-nonexistent", check = FALSE))))

# ---------------------------------------------------------------------------
# 6. separation_factor: factors.json counts, but ca = 1 always beats ca = 0

sf_d <- fac_d
ca1 <- COV[as.character(sf_d$p1), "ca"]; ca2 <- COV[as.character(sf_d$p2), "ca"]
n_sf <- sf_d$w1 + sf_d$w2
sf_d$w1 <- as.integer(ifelse(ca1 == 1 & ca2 == 0, n_sf, ifelse(ca1 == 0 & ca2 == 1, 0L, sf_d$w1)))
sf_d$w2 <- as.integer(n_sf - sf_d$w1)
sf_dat <- list(contests = sf_d, predictors = COV)
sf_br <- suppressWarnings(fit_br(outcome = cbind(w1, w2), player1 = p1, player2 = p2,
                                 formula = F_MAIN, id = "cond", data = sf_dat))
sf_ml <- suppressWarnings(BTm(cbind(w1, w2), p1, p2, formula = F_MAIN, id = "cond", data = sf_dat))
sf_item_br <- fit_br(outcome = cbind(w1, w2), player1 = p1, player2 = p2, id = "cond", data = sf_dat)
write_case(list(
  source = SOURCE, case = "separation_factor",
  description = paste(
    "factors.json design and counts, except every pair of a ca = 1 with a ca = 0 condition",
    "is set to all judgments for the ca = 1 condition (quasi-separation: the ML ca effect",
    "is +infinity). factor_br: BTm(..., formula = ~ gi[cond] + cm[cond] + ca[cond], br = TRUE).",
    "item_br: bias-reduced item model (the item MLE does not exist either).",
    "factor_ml: ordinary glm with R's default control, documents the blow-up only."),
  conditions = I(CONDS), reference = "LQ", pairs = pairs_list(sf_d),
  covariates = list(gi = I(as.integer(COV$gi)), cm = I(as.integer(COV$cm)),
                    ca = I(as.integer(COV$ca))),
  models = list(factor_br = br_record(sf_br, "cond", formula = "gi+cm+ca"),
                item_br = br_record(sf_item_br, "cond"),
                factor_ml = ml_record(sf_ml, "cond", formula = "gi+cm+ca",
                                      method = "ml-nonexistent", check = FALSE))))

# ---------------------------------------------------------------------------
# 7. reference_choice: citations with refcat = "JASA"

rc_fit <- fit_ml(outcome = cbind(w1, w2), player1 = p1, player2 = p2,
                 formula = ~ journal, id = "journal", refcat = "JASA", data = cit)
glm_item_check(rc_fit, cit, cit_levels, "JASA", "journal")
b0 <- c(Biometrika = 0, item_coefs(cit_fit, "journal"))
b1 <- item_coefs(rc_fit, "journal")
stopifnot(max(abs(b1 - (b0[names(b1)] - b0[["JASA"]]))) < 1e-9)
write_case(list(
  source = SOURCE, case = "reference_choice",
  description = paste("citations.json data, item model with refcat = 'JASA'",
                      "(log-worth of JASA fixed at 0). Deviance/loglik equal citations.json."),
  conditions = I(cit_levels), reference = "JASA", pairs = pairs_list(cit),
  models = list(item = ml_record(rc_fit, "journal"))))
