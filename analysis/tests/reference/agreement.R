#!/usr/bin/env Rscript
# Reference values for analysis/src/agreement.rs: Kendall & Babington Smith's coefficient of
# agreement u with its chi-square test, the generalisation of u to unbalanced designs with its
# exact null distribution, and the coefficient of consistence zeta.
#
# Produced with R 4.2.2 (base R only) and jsonlite 1.8.4. Run from anywhere:
#
#     Rscript analysis/tests/reference/agreement.R
#
# It writes agreement.json beside this script, holding every input and R's results. Numbers are
# written with jsonlite's `digits = NA` (15 significant digits); every input is an integer.
#
# Sources of the formulas (implemented here afresh in base R, not taken from a package):
# - Kendall, M. G. & Babington Smith, B. (1940). On the method of paired comparisons.
#   Biometrika 31, 324-345. doi:10.1093/biomet/31.3-4.324. With Sigma = sum over i != j of
#   choose(a_ij, 2), t conditions and m judges:
#     u    = 2 Sigma / (choose(m, 2) choose(t, 2)) - 1,
#     chi2 = 4 / (m - 2) * (Sigma - c - choose(t, 2) choose(m, 2) (m - 3) / (2 (m - 2))),
#     df   = choose(t, 2) m (m - 1) / (m - 2)^2,
#   with continuity correction c = 1 (Kendall, Rank Correlation Methods) or c = 0.
#   The R package eba (Wickelmaier), function kendall.u, computes the same u, chi2 and df
#   (continuity correction on by default since eba 1.9, 2018), and its manual prints, for its
#   data set `schoolsubjects` (Kendall & Babington Smith's two school classes):
#     boys:  u = 0.1866,  minimum u = -0.04762, chi2 = 412.22, df = 90.75, p = 1.721e-42
#     girls: u = 0.08218, minimum u = -0.04,    chi2 = 180.12, df = 62.38, p = 2.307e-13
#   (eba is not packaged for this machine and its data file is binary, so the school-subjects
#   matrices themselves were not available. u depends on the data only through Sigma, and the
#   printed u and chi2 both give Sigma = 9718 for the boys (m = 21, t = 13) and Sigma = 8928 for
#   the girls (m = 25, t = 11). `school_subjects_*` below are matrices built to have exactly
#   that Sigma; they reproduce eba's printed output, which checks the formulas, the continuity
#   correction and the degrees of freedom against the package's published numbers.)
# - The generalisation for pairs judged different numbers of times n_ij:
#     u = 2 sum_pairs [choose(a_ij, 2) + choose(a_ji, 2)] / sum_pairs choose(n_ij, 2) - 1,
#   which is Kendall's u when every n_ij = m. Under the null hypothesis every judgment is a fair
#   coin, a_ij ~ Binomial(n_ij, 1/2) independently over pairs; the exact null distribution of
#   the numerator is the convolution over pairs, computed below by brute force.
# - Coefficient of consistence (Kendall & Babington Smith 1940): with s_i the wins of condition
#   i in one judge's tournament, the number of circular triads is
#     d = t (t - 1) (2t - 1) / 12 - sum(s_i^2) / 2
#   (the form eba's `circular` uses; agreement.rs uses the equivalent choose(t, 3) -
#   sum choose(s_i, 2), so this is an independent check), with maximum (t^3 - t) / 24 for odd t
#   and (t^3 - 4t) / 24 for even t, and zeta = 1 - d / max.
#
# Data: `celebrities` is the choice matrix of 234 subjects among nine celebrities from
# Rumelhart & Greeno (1971), J. Math. Psych. 8, 370-381, as shipped in eba's data/celebrities.R
# (row condition chosen over column condition; every pair judged by all 234 subjects).

suppressPackageStartupMessages(library(jsonlite))

args <- commandArgs(trailingOnly = FALSE)
script <- sub("^--file=", "", args[grep("^--file=", args)])
out_dir <- if (length(script) == 1) dirname(normalizePath(script)) else "."

# --- Kendall's u for a complete balanced design given as a choice matrix --------------------
kendall_u <- function(M, correct) {
  t <- nrow(M)
  m <- M[1, 2] + M[2, 1]
  off <- M[row(M) != col(M)]
  stopifnot(all(M[upper.tri(M)] + t(M)[upper.tri(M)] == m))
  sigma <- sum(choose(off, 2))
  u <- 2 * sigma / (choose(m, 2) * choose(t, 2)) - 1
  min_u <- if (m %% 2 == 1) -1 / m else -1 / (m - 1)
  c <- if (correct) 1 else 0
  chi2 <- 4 / (m - 2) * (sigma - c - choose(t, 2) * choose(m, 2) * (m - 3) / (2 * (m - 2)))
  df <- choose(t, 2) * m * (m - 1) / (m - 2)^2
  log_p <- pchisq(chi2, df, lower.tail = FALSE, log.p = TRUE)
  list(m = m, t = t, sigma = sigma, u = u, min_u = min_u, chi2 = chi2, df = df,
       p = exp(log_p), log10_p = log_p / log(10))
}

matrix_rows <- function(M) lapply(seq_len(nrow(M)), function(i) as.integer(M[i, ]))

balanced_reference <- function(M, note) {
  list(note = note, matrix = matrix_rows(M),
       corrected = kendall_u(M, correct = TRUE),
       uncorrected = kendall_u(M, correct = FALSE))
}

celebrities <- matrix(c(
    0, 159, 163, 175, 183, 179, 173, 160, 142,
   75,   0, 138, 164, 172, 160, 156, 122, 122,
   71,  96,   0, 145, 157, 138, 140, 122, 120,
   59,  70,  89,   0, 176, 115, 124,  86,  61,
   51,  62,  77,  58,   0,  77,  95,  72,  61,
   55,  74,  96, 119, 157,   0, 134,  92,  71,
   61,  78,  94, 110, 139, 100,   0,  67,  48,
   74, 112, 112, 148, 162, 142, 167,   0,  87,
   92, 112, 114, 173, 173, 163, 186, 147,   0
), 9, 9, byrow = TRUE)

# A complete design with t conditions and m judges whose pairs (taken in the order
# (1,2), (1,3), ..., (t-1,t)) have the row condition chosen a[k] times.
matrix_from_counts <- function(t, m, a) {
  M <- matrix(0, t, t)
  k <- 0
  for (i in 1:(t - 1)) for (j in (i + 1):t) {
    k <- k + 1
    M[i, j] <- a[k]
    M[j, i] <- m - a[k]
  }
  M
}

# Boys: 78 pairs, Sigma = 9718 = 59 * 100 + 106 + 142 + 17 * 210.
boys <- matrix_from_counts(13, 21, c(rep(21, 17), 17, 13, rep(11, 59)))
# Girls: 55 pairs, Sigma = 8928 = 48 * 144 + 216 + 6 * 300.
girls <- matrix_from_counts(11, 25, c(rep(25, 6), 21, rep(13, 48)))

boys_ref <- balanced_reference(boys, "synthetic matrix with the Sigma of eba's schoolsubjects$boys")
girls_ref <- balanced_reference(girls, "synthetic matrix with the Sigma of eba's schoolsubjects$girls")
stopifnot(boys_ref$corrected$sigma == 9718, girls_ref$corrected$sigma == 8928)
# The printed eba output, to the digits printed (4 significant digits, or 2 decimals).
signif4 <- function(x, printed) abs(x - printed) <= 0.5 * 10^(floor(log10(abs(printed))) - 3)
decimals2 <- function(x, printed) abs(x - printed) <= 0.005
stopifnot(signif4(boys_ref$corrected$u, 0.1866), decimals2(boys_ref$corrected$chi2, 412.22),
          decimals2(boys_ref$corrected$df, 90.75), signif4(boys_ref$corrected$p, 1.721e-42),
          signif4(boys_ref$corrected$min_u, -0.04762))
stopifnot(signif4(girls_ref$corrected$u, 0.08218), decimals2(girls_ref$corrected$chi2, 180.12),
          decimals2(girls_ref$corrected$df, 62.38), signif4(girls_ref$corrected$p, 2.307e-13),
          girls_ref$corrected$min_u == -0.04)
boys_ref$published <- list(u = 0.1866, min_u = -0.04762, chi2 = 412.22, df = 90.75, p = 1.721e-42)
girls_ref$published <- list(u = 0.08218, min_u = -0.04, chi2 = 180.12, df = 62.38, p = 2.307e-13)

# --- Generalised u with its exact null distribution ----------------------------------------
# pairs: a matrix with columns i, j, wins_i, wins_j (conditions numbered from 0).
exact_generalised <- function(pairs) {
  n <- pairs[, 3] + pairs[, 4]
  numerator <- sum(choose(pairs[, 3], 2) + choose(pairs[, 4], 2))
  denominator <- sum(choose(n, 2))
  # Distribution of sum_pairs [choose(a, 2) + choose(n - a, 2)], a ~ Binomial(n, 1/2).
  dist <- 1                                   # dist[s + 1] = P(numerator = s)
  for (k in seq_along(n)) {
    values <- choose(0:n[k], 2) + choose(n[k] - 0:n[k], 2)
    probs <- dbinom(0:n[k], n[k], 0.5)
    next_dist <- numeric(length(dist) + max(values))
    for (v in seq_along(values)) {
      idx <- seq_along(dist) + values[v]
      next_dist[idx] <- next_dist[idx] + probs[v] * dist
    }
    dist <- next_dist
  }
  min_numerator <- sum(choose(floor(n / 2), 2) + choose(ceiling(n / 2), 2))
  list(pairs = lapply(seq_len(nrow(pairs)), function(r) as.integer(pairs[r, ])),
       numerator = numerator, denominator = denominator,
       u = 2 * numerator / denominator - 1,
       min_u = 2 * min_numerator / denominator - 1,
       p_exact = sum(dist[(numerator + 1):length(dist)]))
}

# An anchored design: condition 0 against each of 1..4, plus two pairs among the others; one
# pair judged once (contributes nothing) and one pair not judged at all.
anchored <- rbind(c(0, 1, 10, 2), c(0, 2, 7, 2), c(0, 3, 5, 2), c(0, 4, 2, 4),
                  c(1, 2, 3, 1), c(3, 4, 1, 0))
anchored_ref <- exact_generalised(anchored)

# A complete balanced design (t = 5, m = 10): the exact p of the generalised u, which is then
# Kendall's u, against the chi-square approximation.
balanced_pairs <- rbind(c(0, 1, 8, 2), c(0, 2, 8, 2), c(0, 3, 7, 3), c(0, 4, 9, 1),
                        c(1, 2, 6, 4), c(1, 3, 7, 3), c(1, 4, 7, 3), c(2, 3, 4, 6),
                        c(2, 4, 6, 4), c(3, 4, 5, 5))
balanced_ref <- exact_generalised(balanced_pairs)
B <- matrix(0, 5, 5)
for (r in seq_len(nrow(balanced_pairs))) {
  B[balanced_pairs[r, 1] + 1, balanced_pairs[r, 2] + 1] <- balanced_pairs[r, 3]
  B[balanced_pairs[r, 2] + 1, balanced_pairs[r, 1] + 1] <- balanced_pairs[r, 4]
}
balanced_ref$corrected <- kendall_u(B, correct = TRUE)
balanced_ref$uncorrected <- kendall_u(B, correct = FALSE)
stopifnot(abs(balanced_ref$u - balanced_ref$corrected$u) < 1e-15)

# Three anchor pairs judged 10^9 (and 7 * 10^8) times, a_ij = n/2 + z sqrt(n)/2. The numerator
# minus its null mean is sum_pairs (a_ij - n/2)^2 - n/4 = sum_pairs n/4 (z^2 - 1) to within the
# rounding of a_ij, so for large n the null distribution of the statistic is that of a weighted
# sum of chi-square(1) variables; with the weights n/4 the p-value is
# P(sum w_k X_k >= sum w_k z_k^2), computed here by numerical integration (the weights take
# two distinct values, so a one-dimensional integral over the third chi-square suffices).
huge_n <- c(1e9, 1e9, 7e8)
huge_z <- c(2.0, -1.5, 1.0)
huge_wins <- round(huge_n / 2 + huge_z * sqrt(huge_n) / 2)
huge_w <- huge_n / 4
huge_stat <- sum(huge_w * ((huge_wins - huge_n / 2) / sqrt(huge_w))^2)
# X = w1 (C1 + C2) + w3 C3 with C1 + C2 ~ chi2(2): P(X >= s) = integral over c3 of
# P(chi2_2 >= (s - w3 c3) / w1) dchisq(c3, 1).
huge_p <- integrate(function(c3) {
  pchisq(pmax((huge_stat - huge_w[3] * c3) / huge_w[1], 0), 2, lower.tail = FALSE) * dchisq(c3, 1)
}, 0, Inf, rel.tol = 1e-10)$value
huge_ref <- list(
  note = "a_ij = round(n/2 + z sqrt(n)/2); p from the large-n chi-square limit of the null",
  pairs = list(c(0, 1, huge_wins[1], huge_n[1] - huge_wins[1]),
               c(0, 2, huge_wins[2], huge_n[2] - huge_wins[2]),
               c(0, 3, huge_wins[3], huge_n[3] - huge_wins[3])),
  z = huge_z, p_limit = huge_p)

# --- Coefficient of consistence -------------------------------------------------------------
# tournament: t x t 0/1 matrix, row i beat column j.
consistence <- function(name, W) {
  t <- nrow(W)
  s <- rowSums(W)
  d <- t * (t - 1) * (2 * t - 1) / 12 - sum(s^2) / 2
  d_max <- if (t %% 2 == 1) (t^3 - t) / 24 else (t^3 - 4 * t) / 24
  judgments <- list()
  for (i in 1:(t - 1)) for (j in (i + 1):t)
    judgments[[length(judgments) + 1]] <- list(i - 1, j - 1, W[i, j] == 1)
  list(name = name, t = t, judgments = judgments, circular_triads = d,
       max_circular_triads = d_max, zeta = 1 - d / d_max)
}
transitive <- function(t) { W <- matrix(0, t, t); W[upper.tri(W)] <- 1; W }
regular5 <- matrix(0, 5, 5)
for (i in 0:4) for (k in 1:2) regular5[i + 1, (i + k) %% 5 + 1] <- 1
set.seed(1940)
random_tournament <- function(t) {
  W <- matrix(0, t, t)
  W[upper.tri(W)] <- rbinom(choose(t, 2), 1, 0.5)
  W[lower.tri(W)] <- (1 - t(W))[lower.tri(W)]
  W
}
consistence_refs <- list(
  consistence("transitive, t = 5", transitive(5)),
  consistence("regular, t = 5", regular5),
  consistence("random, t = 6", random_tournament(6)),
  consistence("random, t = 7", random_tournament(7)),
  consistence("random, t = 10", random_tournament(10)))

reference <- list(
  celebrities = balanced_reference(celebrities, "Rumelhart & Greeno (1971), eba data/celebrities.R"),
  school_subjects_boys = boys_ref,
  school_subjects_girls = girls_ref,
  anchored_exact = anchored_ref,
  balanced_exact = balanced_ref,
  huge_anchored = huge_ref,
  consistence = consistence_refs,
  generated_by = paste0("R ", getRversion(), " (base), jsonlite ", packageVersion("jsonlite"),
                        ", by agreement.R"))
path <- file.path(out_dir, "agreement.json")
write_json(reference, path, digits = NA, auto_unbox = TRUE, pretty = TRUE)
cat("wrote", path, "\n")
cat("anchored: u =", anchored_ref$u, " p_exact =", anchored_ref$p_exact, "\n")
cat("balanced: u =", balanced_ref$u, " p_exact =", balanced_ref$p_exact,
    " p_chi2 (corrected) =", balanced_ref$corrected$p,
    " p_chi2 (uncorrected) =", balanced_ref$uncorrected$p, "\n")
cat("celebrities: u =", reference$celebrities$corrected$u, " chi2 =", reference$celebrities$corrected$chi2,
    " p =", reference$celebrities$corrected$p, "\n")
cat("huge: stat =", huge_stat, " p =", huge_p, "\n")
