# Reference for the factor model's participant-cluster robust (sandwich) standard errors
# (analysis/src/analysis/robust.rs), of the factor effects and of the item model's log-worths. Tool: R 4.2.2, base `glm` only (binomial logit, no
# intercept, columns x_left - x_right: the Bradley–Terry factor model), the sandwich by hand:
# V = G/(G-1) * vcov %*% (sum_g u_g u_g') %*% vcov, u_g = sum over participant g's judgments of
# (y - mu) * x (as sandwich::vcovCL(type = "HC0", cadjust = TRUE)).
# Run: Rscript analysis/reference/cluster_robust.R > analysis/tests/reference/cluster_robust.json
set.seed(48)
levels <- rbind(c(0, 0), c(1, 0), c(0, 1), c(1, 1))    # conditions C0..C3, factors a, b
effects <- c(0.5, -0.8)
rows <- NULL
for (p in 0:5) {
  worth <- as.vector(levels %*% effects) + rnorm(4, sd = 0.6)    # the participant's own taste
  for (t in 1:30) {
    pair <- sample(0:3, 2)
    # participants 0-2 see mostly C0-C3; the others every pair
    if (p < 3 && t %% 3 != 0) pair <- sample(c(0, 3))
    pl <- 1 / (1 + exp(worth[pair[2] + 1] - worth[pair[1] + 1]))
    rows <- rbind(rows, c(p, pair[1], pair[2], as.integer(runif(1) < pl)))
  }
}
d <- levels[rows[, 2] + 1, ] - levels[rows[, 3] + 1, ]
y <- rows[, 4]
fit <- glm(y ~ 0 + d, family = binomial)
bread <- vcov(fit)
u <- (y - fitted(fit)) * d
meat <- crossprod(rowsum(u, rows[, 1]))
g <- length(unique(rows[, 1]))
robust <- g / (g - 1) * bread %*% meat %*% bread
# The item model (log-worths of C1..C3, C0 the reference at 0): indicator columns, the same sandwich.
items <- diag(4)[, 2:4]
di <- items[rows[, 2] + 1, ] - items[rows[, 3] + 1, ]
fit_items <- glm(y ~ 0 + di, family = binomial)
bread_items <- vcov(fit_items)
meat_items <- crossprod(rowsum((y - fitted(fit_items)) * di, rows[, 1]))
robust_items <- g / (g - 1) * bread_items %*% meat_items %*% bread_items
num <- function(v) paste(sprintf("%.17g", v), collapse = ", ")
cat("{\n")
cat(sprintf('  "tool": "R %s, glm (binomial logit) and the cluster sandwich by hand",\n', getRversion()))
cat(sprintf('  "rows": [%s],\n', paste(sprintf("[%d, %d, %d, %d]", rows[, 1], rows[, 2], rows[, 3], rows[, 4]), collapse = ", ")))
cat(sprintf('  "estimate": [%s],\n', num(coef(fit))))
cat(sprintf('  "model_se": [%s],\n', num(sqrt(diag(bread)))))
cat(sprintf('  "robust_se": [%s],\n', num(sqrt(diag(robust)))))
cat(sprintf('  "item_log_worth": [%s],\n', num(coef(fit_items))))
cat(sprintf('  "item_model_se": [%s],\n', num(sqrt(diag(bread_items)))))
cat(sprintf('  "item_robust_se": [%s]\n', num(sqrt(diag(robust_items)))))
cat("}\n")
