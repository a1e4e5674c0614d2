# Reference values for mrstudy_analysis::quantile (issue 51): R's quantile() of type 7 (the
# default; linear interpolation between order statistics, Hyndman & Fan 1996) and of type 1
# (the inverse of the empirical distribution function: the nearest rank), for a few samples
# and probabilities, written to quantile.json beside this script.
#
# Tool: R 4.2.2 Patched (2022-11-10 r83330), package jsonlite.
# Run: Rscript analysis/reference/quantile.R  (from the repository root)
library(jsonlite)
samples <- list(
  c(1, 2, 4, 7, 11),
  c(1, 2, 4, 7),
  c(3),
  as.numeric(1:20),
  c(16.7, 16.9, 17.1, 16.6, 33.4, 16.8, 16.7, 18.2, 16.6, 50.1, 16.7),
  c(-3.5, 0, 2.25, 1e6, -1e-3, 7)
)
probs <- c(0, 0.01, 0.05, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 1)
cases <- lapply(samples, function(x) list(
  values = x,
  probs = probs,
  type7 = unname(quantile(x, probs, type = 7)),
  type1 = unname(quantile(x, probs, type = 1))
))
writeLines(toJSON(list(tool = R.version.string, cases = cases), digits = NA, auto_unbox = FALSE, pretty = TRUE),
           "analysis/reference/quantile.json")
