#!/usr/bin/env Rscript
# Reference values for analysis/src/task/ (task.rs before it was split) (lab-task statistics: Friedman test, Kendall's W,
# paired Wilcoxon signed-rank post hoc tests, Holm adjustment, descriptives).
#
# Produced with R 4.2.2 (stats package) and jsonlite 1.8.4. Run from anywhere:
#
#     Rscript analysis/tests/reference/task_stats.R
#
# It writes task_stats_*.json beside this script, each holding its inputs and R's results.
# Numbers are written with jsonlite's `digits = NA` (15 significant digits), far finer than the
# tolerances of the Rust tests. Every input value is a short decimal, so the inputs read back as
# exactly the doubles R used.

suppressPackageStartupMessages(library(jsonlite))

args <- commandArgs(trailingOnly = FALSE)
script <- sub("^--file=", "", args[grep("^--file=", args)])
out_dir <- if (length(script) == 1) dirname(normalizePath(script)) else "."

write_reference <- function(x, name) {
  x$generated_by <- paste0("R ", getRversion(), " (stats), jsonlite ", packageVersion("jsonlite"),
                           ", by task_stats.R")
  path <- file.path(out_dir, name)
  write_json(x, path, digits = NA, auto_unbox = TRUE, pretty = TRUE)
  cat("wrote", path, "\n")
}

friedman_reference <- function(y) {
  test <- friedman.test(y)
  n <- nrow(y)
  k <- ncol(y)
  ranks <- t(apply(y, 1L, rank))
  list(statistic = unname(test$statistic),
       df = unname(test$parameter),
       p = test$p.value,
       log10_p = pchisq(unname(test$statistic), k - 1, lower.tail = FALSE, log.p = TRUE) / log(10),
       kendall_w = unname(test$statistic) / (n * (k - 1)),
       mean_ranks = unname(colMeans(ranks)))
}

wilcoxon_reference <- function(x, y) {
  test <- suppressWarnings(wilcox.test(x, y, paired = TRUE))
  d <- x - y
  list(v = unname(test$statistic),
       p = test$p.value,
       method = if (grepl("exact", test$method)) "exact" else "normal",
       n_nonzero = sum(d != 0))
}

# --- 1. R's friedman.test help-page example (Hollander & Wolfe 1973, p. 140 ff.):
#        rounding first base, 22 players, three methods. Has ties within rows.
RoundingTimes <-
  matrix(c(5.40, 5.50, 5.55,
           5.85, 5.70, 5.75,
           5.20, 5.60, 5.50,
           5.55, 5.50, 5.40,
           5.90, 5.85, 5.70,
           5.45, 5.55, 5.60,
           5.40, 5.40, 5.35,
           5.45, 5.50, 5.35,
           5.25, 5.15, 5.00,
           5.85, 5.80, 5.70,
           5.25, 5.20, 5.10,
           5.65, 5.55, 5.45,
           5.60, 5.35, 5.45,
           5.05, 5.00, 4.95,
           5.50, 5.50, 5.40,
           5.45, 5.55, 5.50,
           5.55, 5.55, 5.35,
           5.45, 5.50, 5.55,
           5.50, 5.45, 5.25,
           5.65, 5.60, 5.40,
           5.70, 5.65, 5.55,
           6.30, 6.30, 6.25),
         nrow = 22, byrow = TRUE,
         dimnames = list(1:22, c("Round Out", "Narrow Angle", "Wide Angle")))
write_reference(list(
  description = "friedman.test help-page example RoundingTimes (Hollander & Wolfe)",
  conditions = colnames(RoundingTimes),
  blocks = unname(lapply(seq_len(nrow(RoundingTimes)), function(i) unname(RoundingTimes[i, ]))),
  friedman = friedman_reference(RoundingTimes)
), "task_stats_friedman_roundingtimes.json")

# --- 2. Friedman with heavy ties: 7-point ratings of four conditions by 10 participants,
#        including a row tied throughout and rows with two- and three-way ties.
ratings <- matrix(c(4, 5, 6, 6,
                    3, 3, 5, 7,
                    5, 5, 5, 5,
                    2, 4, 4, 6,
                    4, 4, 4, 5,
                    1, 3, 2, 3,
                    5, 6, 7, 7,
                    3, 2, 4, 4,
                    6, 6, 7, 6,
                    2, 5, 5, 5),
                  nrow = 10, byrow = TRUE,
                  dimnames = list(1:10, c("LQ", "GI", "CM", "HQ")))
write_reference(list(
  description = "Friedman test on tied 7-point ratings, tie-corrected statistic",
  conditions = colnames(ratings),
  blocks = unname(lapply(seq_len(nrow(ratings)), function(i) unname(ratings[i, ]))),
  friedman = friedman_reference(ratings)
), "task_stats_friedman_ties.json")

# --- 3. Paired Wilcoxon signed-rank, exact (n < 50, no ties, no zero differences).
exact_x <- c(1.83, 0.50, 1.62, 2.48, 1.68, 1.88, 1.55, 3.06, 1.30, 2.01, 1.11)
exact_y <- c(0.878, 0.647, 0.598, 2.05, 1.06, 1.29, 1.06, 3.14, 1.29, 1.57, 1.14)
exact_cases <- list(
  list(x = exact_x, y = exact_y),
  list(x = c(0.4, 0.9, 1.6, 2.2), y = c(0.3, 1.2, 1.1, 1.9)),
  list(x = c(12.1, 9.4, 15.0, 11.3, 10.2, 13.9, 8.8), y = c(10.0, 9.9, 12.3, 11.0, 9.1, 12.2, 8.45)),
  # n = 30: the exact null distribution far from the tiny cases, p of order 1e-5.
  list(x = c(2.031, 1.774, 0.992, 2.551, 1.342, 0.615, 1.888, 2.204, 0.741, 1.467,
             2.915, 1.103, 0.877, 1.659, 2.388, 1.215, 0.534, 1.976, 2.662, 1.051,
             0.713, 1.594, 2.127, 1.338, 0.926, 2.473, 1.782, 0.468, 1.149, 2.806),
       y = c(1.312, 1.901, 0.404, 1.637, 0.529, 0.851, 1.113, 1.050, 0.352, 0.776,
             1.721, 0.368, 1.205, 0.894, 1.489, 0.457, 0.689, 1.032, 1.402, 0.218,
             0.981, 0.764, 1.286, 0.627, 0.118, 1.566, 0.923, 0.741, 0.273, 1.917)),
  list(x = 2.5, y = 1.0))
write_reference(list(
  description = "wilcox.test(x, y, paired = TRUE), exact p (small n, no ties, no zeros)",
  cases = lapply(exact_cases, function(case) c(list(x = I(case$x), y = I(case$y)),
                                          wilcoxon_reference(case$x, case$y)))
), "task_stats_wilcoxon_exact.json")

# --- 4. Paired Wilcoxon with tied |differences| and zero differences: R drops the zeros and
#        uses the normal approximation with continuity and tie correction.
normal_cases <- list(
  list(x = c(3, 5, 4, 6, 2, 5, 7, 4, 3, 6, 5, 4), y = c(2, 5, 2, 4, 3, 3, 5, 4, 1, 6, 4, 2)),
  list(x = c(10, 12, 11, 14, 9, 10, 13, 12), y = c(10, 11, 12, 12, 9, 8, 11, 13)),
  # n >= 50 without ties: normal approximation with continuity correction only.
  list(x = round(seq(1, 60) * 1.037 + sin(seq(1, 60)) * 3, 3), y = round(seq(1, 60) * 1.0, 3)))
write_reference(list(
  description = "wilcox.test(x, y, paired = TRUE), normal approximation (ties/zeros or n >= 50)",
  cases = lapply(normal_cases, function(case) c(list(x = I(case$x), y = I(case$y)),
                                          wilcoxon_reference(case$x, case$y)))
), "task_stats_wilcoxon_normal.json")

# --- 4b. The smallest attainable two-sided p: every difference of one sign (V = n(n+1)/2).
#         Exact for n = 1..7 without ties (2/2^n: above 0.05 for n < 6). With tied magnitudes
#         R uses the normal approximation, which goes below 2/2^n (five equal differences:
#         0.037 < 0.0625); the Rust side keeps 2/2^n, the exact sign-flip bound, and calls a
#         pair whose bound exceeds 0.05 not estimable.
min_p_cases <- c(
  lapply(1:7, function(n) list(x = round(seq_len(n) * 1.1 + 0.3, 3), y = rep(0, n))),
  list(list(x = c(2, 2, 3, 4, 4, 5), y = c(1, 1, 1, 1, 1, 1)),
       list(x = c(1, 1, 1, 1, 1), y = c(0, 0, 0, 0, 0))))
write_reference(list(
  description = "wilcox.test(x, y, paired = TRUE) with every difference positive: the smallest p",
  cases = lapply(min_p_cases, function(case) c(list(x = I(case$x), y = I(case$y)),
                                         wilcoxon_reference(case$x, case$y)))
), "task_stats_wilcoxon_min_p.json")

# --- 5. Holm adjustment (p.adjust(method = "holm")), including tied p and values that cap at 1.
holm_p <- c(0.01, 0.04, 0.03, 0.005, 0.04, 0.5, 1e-12)
write_reference(list(
  description = "p.adjust(p, method = \"holm\")",
  p = holm_p,
  holm = p.adjust(holm_p, method = "holm")
), "task_stats_holm.json")

# --- 6. The whole pipeline on a long CSV in the lab-task export shape
#        participant,task,measure,condition,value (+ an extra column), two measures:
#        completion time (continuous; one participant lacks HQ and is excluded from Friedman;
#        one participant has two HQ values, averaged) and a 7-point rating (ties and zeros).
set.seed(20130603)
conditions <- c("LQ", "GI", "HQ")
participants <- sprintf("p%02d", 1:12)
rows <- list()
add_row <- function(participant, task, measure, condition, value) {
  rows[[length(rows) + 1]] <<- data.frame(participant = participant, task = task,
                                          measure = measure, condition = condition,
                                          value = value, trial = length(rows) + 1)
}
for (p in participants) {
  base <- rnorm(1, 30, 5)
  for (c in conditions) {
    if (p == "p07" && c == "HQ") next
    shift <- c(LQ = 4, GI = 1.5, HQ = 0)[[c]]
    add_row(p, "placement", "time_s", c, round(base + shift + rnorm(1, 0, 2), 3))
    if (p == "p03" && c == "HQ") add_row(p, "placement", "time_s", c, round(base + rnorm(1, 0, 2), 3))
  }
}
for (p in participants) {
  for (c in conditions) {
    shift <- c(LQ = 0, GI = 1, HQ = 1.5)[[c]]
    add_row(p, "placement", "rating", c, min(7, max(1, round(3 + shift + rnorm(1, 0, 1)))))
  }
}
long <- do.call(rbind, rows)
csv_text <- paste(capture.output(write.csv(long, row.names = FALSE, quote = FALSE)), collapse = "\n")
# Read the text back so R computes from exactly what the Rust parser sees.
long <- read.csv(text = csv_text, stringsAsFactors = FALSE)

quantile7 <- function(v, prob) unname(quantile(v, prob, type = 7))
group_reference <- function(d) {
  cells <- aggregate(value ~ participant + condition, data = d, FUN = mean)
  ids <- unique(d$participant)
  wide <- matrix(NA_real_, nrow = length(ids), ncol = length(conditions),
                 dimnames = list(ids, conditions))
  for (i in seq_len(nrow(cells))) wide[cells$participant[i], cells$condition[i]] <- cells$value[i]
  complete <- wide[complete.cases(wide), , drop = FALSE]
  descriptives <- lapply(conditions, function(c) {
    v <- na.omit(wide[, c])
    list(condition = c, n = length(v), mean = mean(v), sd = sd(v), median = median(v),
         q1 = quantile7(v, 0.25), q3 = quantile7(v, 0.75), min = min(v), max = max(v))
  })
  pairs <- combn(seq_along(conditions), 2, simplify = FALSE)
  post_hoc <- lapply(pairs, function(ij) {
    a <- wide[, ij[1]]
    b <- wide[, ij[2]]
    ok <- complete.cases(a, b)
    c(list(condition_a = conditions[ij[1]], condition_b = conditions[ij[2]], n = sum(ok)),
      wilcoxon_reference(a[ok], b[ok]))
  })
  holm <- p.adjust(sapply(post_hoc, function(x) x$p), method = "holm")
  for (i in seq_along(post_hoc)) post_hoc[[i]]$p_holm <- holm[i]
  list(task = d$task[1], measure = d$measure[1],
       participants = length(ids),
       excluded_participants = I(setdiff(ids, rownames(complete))),
       descriptives = descriptives,
       friedman = c(list(participants = nrow(complete)), friedman_reference(complete)),
       post_hoc = post_hoc)
}
groups <- lapply(unique(long$measure), function(m) group_reference(long[long$measure == m, ]))
write_reference(list(
  description = paste("long CSV participant,task,measure,condition,value,trial; per measure:",
                      "descriptives (quantile type 7), friedman.test on complete participants,",
                      "pairwise wilcox.test(paired = TRUE) on pairwise-complete participants,",
                      "p.adjust holm; duplicate cells averaged"),
  csv = csv_text,
  groups = groups
), "task_stats_pipeline.json")
