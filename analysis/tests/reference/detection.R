#!/usr/bin/env Rscript
# Reference values for analysis/src/detection.rs: the exact binomial test and the Clopper-Pearson
# interval of R's binom.test, the exact power of that test, and 2AFC d' with its delta-method SE.
#
# Produced with R 4.2.2 (base R only: binom.test, dbinom, qnorm, dnorm). Run from anywhere:
#
#     Rscript analysis/tests/reference/detection.R
#
# It writes detection.json beside this script. Numbers are written with 17 significant digits
# (sprintf "%.17g"), which read back to the same double; the script stops on a non-finite one.
#
# - binom.test(x, n, p0): two-sided p-value (the sum of dbinom over outcomes no more likely than
#   x, within R's relative tolerance 1 + 1e-7) and the 95 % Clopper-Pearson conf.int.
# - power(n): sum of dbinom(x, n, 0.75) over the outcomes x in 0..n whose binom.test(x, n, 0.5)
#   p-value is <= 0.05, i.e. the exact probability that the test rejects at alpha = 0.05 when
#   the true detection rate is 0.75.
# - d' = sqrt(2) * qnorm(pc) for two-alternative forced choice (Macmillan & Creelman, Detection
#   Theory, 2nd ed., eq. 7.3), pc = x/n with 0 and n replaced by 1/(2n) and 1 - 1/(2n)
#   (Macmillan & Kaplan 1985); se = sqrt(2) * sqrt(pc (1 - pc) / n) / dnorm(qnorm(pc)).

here <- local({
  args <- commandArgs(trailingOnly = FALSE)
  file <- sub("^--file=", "", args[grep("^--file=", args)])
  if (length(file) == 1) dirname(normalizePath(file)) else getwd()
})

num <- function(v) {
  if (!is.finite(v)) stop("non-finite number")
  sprintf("%.17g", v)
}

tests <- list(
  c(0, 1, 0.5), c(1, 1, 0.5), c(0, 20, 0.5), c(20, 20, 0.5), c(10, 20, 0.5), c(13, 20, 0.5),
  c(7, 20, 0.5), c(15, 20, 0.5), c(5, 20, 0.5), c(31, 50, 0.5), c(64, 100, 0.5), c(40, 100, 0.5),
  c(58, 100, 0.5), c(61, 100, 0.5), c(100, 100, 0.5), c(500, 1000, 0.5), c(530, 1000, 0.5),
  c(3, 10, 0.3), c(7, 25, 0.75), c(25, 25, 0.75), c(0, 12, 0.1), c(9, 40, 0.37)
)
test_lines <- vapply(tests, function(t) {
  r <- binom.test(t[1], t[2], t[3])
  sprintf('    {"x": %d, "n": %d, "p0": %s, "p": %s, "ci": [%s, %s]}',
          as.integer(t[1]), as.integer(t[2]), num(t[3]), num(r$p.value),
          num(r$conf.int[1]), num(r$conf.int[2]))
}, "")

power <- function(n) {
  x <- 0:n
  p <- vapply(x, function(k) binom.test(k, n, 0.5)$p.value, 0)
  sum(dbinom(x[p <= 0.05], n, 0.75))
}
power_ns <- c(1, 5, 6, 10, 17, 20, 24, 25, 26, 30, 40, 50, 100, 200)
power_lines <- vapply(power_ns, function(n) sprintf('    {"n": %d, "power": %s}', as.integer(n), num(power(n))), "")

d_prime <- function(x, n) {
  pc <- if (x == 0) 1 / (2 * n) else if (x == n) 1 - 1 / (2 * n) else x / n
  z <- qnorm(pc)
  c(sqrt(2) * z, sqrt(2) * sqrt(pc * (1 - pc) / n) / dnorm(z))
}
d_cases <- list(c(60, 100), c(75, 100), c(90, 100), c(13, 20), c(0, 20), c(20, 20), c(1, 1), c(3, 7))
d_lines <- vapply(d_cases, function(d) {
  r <- d_prime(d[1], d[2])
  sprintf('    {"correct": %d, "trials": %d, "d_prime": %s, "se": %s}',
          as.integer(d[1]), as.integer(d[2]), num(r[1]), num(r[2]))
}, "")

out <- c(
  "{",
  sprintf('  "source": "%s, base R binom.test / dbinom / qnorm / dnorm",', R.version.string),
  '  "alpha": 0.05, "alternative_rate": 0.75, "level": 0.95,',
  '  "binom_test": [', paste(test_lines, collapse = ",\n"), "  ],",
  '  "power": [', paste(power_lines, collapse = ",\n"), "  ],",
  '  "d_prime": [', paste(d_lines, collapse = ",\n"), "  ]",
  "}"
)
writeLines(out, file.path(here, "detection.json"))
