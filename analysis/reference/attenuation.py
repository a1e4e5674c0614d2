"""The factor effects the pooled Bradley–Terry analysis converges to when every simulated
participant has their own taste (log-worths = truth + N(0, sd²) per condition) and lapses
(a coin flip with probability `lapse`), as `mrstudy simulate` draws them (issue 48 item 6).

The analysis fits one logistic model to all participants' judgments, so with many participants
its estimate tends to the β* solving the score equation
    Σ_pairs w_ij · (P̄_ij − σ((x_i − x_j)ᵀβ*)) · (x_i − x_j) = 0,
P̄_ij = (1 − lapse) · E[σ(d_ij + ε)] + lapse / 2, ε ~ N(0, 2 sd²), d_ij the true difference:
the population-averaged (marginal) effect, smaller than the per-participant (conditional)
effect the simulation's truth names, by an amount that depends on which pairs are compared
(w_ij). Tools: Python 3, numpy 2.4.6, scipy 1.17.1 (Gauss–Hermite nodes, fsolve).
Run: python3 analysis/reference/attenuation.py
"""
import itertools

import numpy as np
from scipy.optimize import fsolve

EFFECTS = np.array([0.27, -0.22, 0.43])  # gi, cm, ca (Knecht 2013, Table 6.1)
LEVELS = np.array(list(itertools.product([0, 1], repeat=3)))[:, ::-1]  # any order of the 8
NAMES = ["".join(n for n, on in zip(["GI", "CM", "CA"], row) if on) or "LQ" for row in LEVELS]
NODES, WEIGHTS = np.polynomial.hermite_e.hermegauss(60)  # ∫ f(z) φ(z) dz = Σ w f(z) / √(2π)
WEIGHTS = WEIGHTS / np.sqrt(2 * np.pi)


def sigmoid(x):
    return 1 / (1 + np.exp(-x))


def marginal(d, sd, lapse):
    """P(i preferred to j) over the population, true difference d."""
    return (1 - lapse) * np.sum(WEIGHTS * sigmoid(d + np.sqrt(2) * sd * NODES)) + lapse / 2


def limit(pairs, sd, lapse):
    """β* of the pooled factor model over the equally weighted `pairs` (index pairs)."""
    dx = np.array([LEVELS[i] - LEVELS[j] for i, j in pairs], dtype=float)
    p = np.array([marginal(row @ EFFECTS, sd, lapse) for row in dx])
    return fsolve(lambda beta: dx.T @ (p - sigmoid(dx @ beta)), EFFECTS, xtol=1e-13)


def main():
    index = {name: k for k, name in enumerate(NAMES)}
    lq, hq = index["LQ"], index["GICMCA"]
    anchored = [(c, a) for a in (lq, hq) for c in range(8) if c not in (lq, hq)] + [(hq, lq)]
    every = list(itertools.combinations(range(8), 2))
    one_factor = [(i, j) for i, j in every if np.abs(LEVELS[i] - LEVELS[j]).sum() == 1]
    print("design         sd    lapse  gi              cm              ca")
    for sd, lapse in [(0.3, 0.02), (0.3, 0.0), (0.0, 0.02)]:
        for name, pairs in [("anchored", anchored), ("all pairs", every), ("one-factor", one_factor)]:
            beta = limit(pairs, sd, lapse)
            cells = "  ".join(f"{b:+.4f} ({b / e - 1:+.1%})" for b, e in zip(beta, EFFECTS))
            print(f"{name:12s}  {sd:.1f}  {lapse:.2f}   {cells}")
    # A single pair's attenuation against its true difference: logit(P̄)/d.
    print("pair attenuation logit(P̄)/d, sd 0.3, lapse 0.02:")
    for d in [0.05, 0.2, 0.43, 0.7, 1.0]:
        p = marginal(d, 0.3, 0.02)
        print(f"  d = {d:.2f}: {np.log(p / (1 - p)) / d:.4f}")


if __name__ == "__main__":
    main()
