#!/usr/bin/env python3
"""Reference centred MAP log-worths for `mrstudy analyze`'s `log_worth_map` (issue 48).

Model: Bradley-Terry on the logit scale, P(i over j) = 1 / (1 + exp(-(l_i - l_j))), with the
prior l_i ~ N(0, prior_sd^2) independently per condition; the MAP maximises
sum over judgments of log P(winner over loser) - sum_i l_i^2 / (2 prior_sd^2), and the reported
estimate is the MAP centred to mean 0 over the conditions.

Tool: scipy (scipy.optimize.minimize, method "trust-exact" with the analytic gradient and
Hessian, gtol 1e-10; the script asserts the gradient's largest component is below 1e-7 at the
result, and the Hessian's eigenvalues are at least 1 / prior_sd^2 >= 1, so each value is within
about 1e-7 of the MAP), numpy; versions are written into the fixture. Data: simulated judgments
(numpy default_rng with fixed seeds), written as the trials CSV `mrstudy analyze` reads.
Run:  python3 analysis/reference/log_worth_map_reference.py > analysis/tests/reference/log_worth_map_scipy.json
"""
import json

import numpy as np
import scipy
from scipy import optimize


def map_fit(n, judgments, prior_sd):
    """judgments: list of (winner, loser) indices."""
    w = np.array([j[0] for j in judgments])
    lo = np.array([j[1] for j in judgments])
    precision = 1.0 / prior_sd**2

    def negative(theta):
        d = theta[w] - theta[lo]
        return np.sum(np.logaddexp(0.0, -d)) + 0.5 * precision * np.sum(theta**2)

    def gradient(theta):
        d = theta[w] - theta[lo]
        r = 1.0 / (1.0 + np.exp(d))  # 1 - sigma(d)
        g = precision * theta
        np.add.at(g, w, -r)
        np.add.at(g, lo, r)
        return g

    def hessian(theta):
        d = theta[w] - theta[lo]
        s = 1.0 / (1.0 + np.exp(-d))
        h = s * (1.0 - s)
        m = precision * np.eye(n)
        np.add.at(m, (w, w), h)
        np.add.at(m, (lo, lo), h)
        np.add.at(m, (w, lo), -h)
        np.add.at(m, (lo, w), -h)
        return m

    result = optimize.minimize(
        negative, np.zeros(n), jac=gradient, hess=hessian, method="trust-exact", options={"gtol": 1e-10}
    )
    theta = result.x
    # converged: the Hessian is at least the prior precision, so the MAP is within max|g| / precision
    assert np.max(np.abs(gradient(theta))) < 1e-7, (result.message, gradient(theta))
    return theta - theta.mean()


def case(name, names, judgments, prior_sd, note):
    rows = ["participant,left,right,chosen"]
    for k, (winner, loser) in enumerate(judgments):
        participant = f"p{k % 7}"
        # `chosen` names the winner; sides alternate
        left, right = (winner, loser) if k % 2 == 0 else (loser, winner)
        rows.append(f"{participant},{names[left]},{names[right]},{names[winner]}")
    theta = map_fit(len(names), judgments, prior_sd)
    return {
        "name": name,
        "note": note,
        "prior_sd": prior_sd,
        "trials_csv": "\n".join(rows) + "\n",
        "log_worth_map": {names[i]: float(theta[i]) for i in range(len(names))},
    }


def simulated(seed, worths, count):
    rng = np.random.default_rng(seed)
    n = len(worths)
    judgments = []
    for _ in range(count):
        i, j = rng.choice(n, size=2, replace=False)
        p = 1.0 / (1.0 + np.exp(-(worths[i] - worths[j])))
        judgments.append((i, j) if rng.random() < p else (j, i))
    return judgments


def main():
    names6 = ["LQ", "GI", "CM", "CA", "GI+CA", "HQ"]
    worths6 = [0.0, 0.3, -0.2, 0.45, 0.7, 1.1]
    six = simulated(2013, worths6, 150)
    names5 = ["A", "B", "C", "D", "E"]
    five = simulated(11, [0.0, 0.4, -0.3, 0.2, -0.6], 80)
    # separation: A wins every judgment it is in (its maximum-likelihood log-worth is infinite)
    five = [(a, b) if a == 0 or b != 0 else (b, a) for (a, b) in five]
    cases = [
        case("six conditions, 150 random judgments, prior sd 1", names6, six, 1.0, "worths " + str(worths6)),
        case("five conditions, A never beaten, prior sd 0.5", names5, five, 0.5, "separation: no MLE exists"),
    ]
    print(
        json.dumps(
            {
                "source": f"analysis/reference/log_worth_map_reference.py; scipy {scipy.__version__}, numpy {np.__version__}",
                "cases": cases,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
