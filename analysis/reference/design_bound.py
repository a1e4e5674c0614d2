#!/usr/bin/env python3
"""The best any pair-selection rule can do, asymptotically, against uniform random pairs: the
A-optimal allocation of paired comparisons for an *oracle* that knows the true log-worths.

For Thurstone observers (P(i over j) = Phi((w_i - w_j) / s), s = sqrt(1 + 2 taste^2) for
per-participant taste noise of sd `taste` per condition), one comparison of i and j carries
Fisher information I_ij = phi(d/s)^2 / (s^2 Phi(d/s) (1 - Phi(d/s))) along a = e_i - e_j. With a
share p_ij of N comparisons on pair ij, the covariance of the centred estimates is
pinv(sum p_ij I_ij a a^T) / N, and the mean squared error of the centred log-worths is its trace
over n. The A-optimal shares minimise that trace (a convex problem; solved by the multiplicative
algorithm p <- p * sqrt(g), g_ij = I_ij a^T C^2 a, until the equivalence theorem
max g / sum p g = 1 holds to 1e-6). The ratio trace(optimal) / trace(uniform) is the fraction of
random pairs' trials that the best possible design needs for the same RMSE, as N grows; an
adaptive design, which does not know the worths, needs at least that.

    design_bound.py [WORTHS.csv]

prints the ratio for the worths of WORTHS.csv (column `log_worth`) and for seeded N(0, 1)
draws of the same size (20 when no file is given): Thurstone observers at taste 0 and 0.3, and
Bradley-Terry observers (worths on the logit scale, information p (1 - p)). Run here with numpy
2.4.6, scipy 1.17.1.
"""
import csv
import sys

import numpy as np
from scipy.stats import norm


def information(d, taste, link="probit"):
    if link == "logit":
        # Bradley-Terry observers without taste noise: P = sigma(d), information sigma'(d).
        p = 1.0 / (1.0 + np.exp(-d))
        return p * (1.0 - p)
    s = np.sqrt(1.0 + 2.0 * taste**2)
    z = d / s
    p = norm.cdf(z)
    return (norm.pdf(z) / s) ** 2 / (p * (1.0 - p))


def bound(worths, taste, link="probit"):
    n = len(worths)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    a = np.zeros((len(pairs), n))
    for k, (i, j) in enumerate(pairs):
        a[k, i], a[k, j] = 1.0, -1.0
    info = np.array([information(worths[i] - worths[j], taste, link) for i, j in pairs])

    def trace_and_gradient(p):
        c = np.linalg.pinv((a.T * (p * info)) @ a)
        return np.trace(c) / n, info * np.einsum("ki,ij,kj->k", a, c @ c, a)

    uniform = np.full(len(pairs), 1.0 / len(pairs))
    p = uniform.copy()
    for _ in range(100_000):
        _, g = trace_and_gradient(p)
        if g.max() / (p @ g) < 1.0 + 1e-6:
            break
        p *= np.sqrt(g)
        p /= p.sum()
    else:
        sys.exit("the multiplicative algorithm did not converge")
    return trace_and_gradient(p)[0] / trace_and_gradient(uniform)[0]


def main():
    sets = []
    if len(sys.argv) > 1:
        with open(sys.argv[1]) as f:
            sets.append((sys.argv[1], np.array([float(r["log_worth"]) for r in csv.DictReader(f)])))
    n = len(sets[0][1]) if sets else 20
    rng = np.random.default_rng(2024)
    sets += [(f"N(0, 1) draw {k + 1}", rng.standard_normal(n)) for k in range(5)]
    print("| worths | Thurstone, taste sd 0 | Thurstone, taste sd 0.3 | Bradley-Terry (logit scale) |")
    print("|---|---:|---:|---:|")
    for name, worths in sets:
        row = [bound(worths, 0.0), bound(worths, 0.3), bound(worths, 0.0, "logit")]
        print(f"| {name} | " + " | ".join(f"{r:.3f}" for r in row) + " |")


if __name__ == "__main__":
    main()
