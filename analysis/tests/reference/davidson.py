"""Reference values for analysis/src/scales/davidson.rs: a direct maximum-likelihood fit of
Davidson's (1970) tie model with SciPy 1.17.1 (NumPy 2.4.6), Python 3.11.

P(i over j) = pi_i / (pi_i + pi_j + nu sqrt(pi_i pi_j)), P(tie) = nu sqrt(pi_i pi_j) / (same).
Parameters (lambda_c = ln pi_c for every condition but the reference, which is 0; theta = ln nu),
the likelihood written in that original form (not the Rust code's cosh form), minimised by
scipy.optimize.minimize (BFGS, gradient by complex-step differentiation, exact to rounding),
then polished by Newton steps on the finite-difference Hessian of that gradient; standard
errors from the inverse of that Hessian, se(nu) = nu se(theta).

Run: python3 davidson.py > davidson.json
"""
import json

import numpy as np
import scipy
from scipy.optimize import minimize

rng = np.random.default_rng(49)


def simulate(log_worth, nu, pairs, n):
    out = []
    for i, j in pairs:
        pi, pj = np.exp(log_worth[i]), np.exp(log_worth[j])
        den = pi + pj + nu * np.sqrt(pi * pj)
        counts = rng.multinomial(n, [pi / den, pj / den, nu * np.sqrt(pi * pj) / den])
        out.append([i, j, int(counts[0]), int(counts[1]), int(counts[2])])
    return out


def negative_log_likelihood(x, pairs, k, reference):
    lam = np.concatenate([x[:reference], [0.0], x[reference:k - 1]]).astype(x.dtype)
    nu = np.exp(x[k - 1])
    total = 0.0
    for i, j, wi, wj, t in pairs:
        pi, pj = np.exp(lam[i]), np.exp(lam[j])
        den = pi + pj + nu * np.sqrt(pi * pj)
        total = total + wi * np.log(pi / den) + wj * np.log(pj / den) + t * np.log(nu * np.sqrt(pi * pj) / den)
    return -total


def gradient(x, pairs, k, reference):
    h = 1e-30
    g = np.zeros(len(x))
    for m in range(len(x)):
        z = x.astype(complex)
        z[m] += 1j * h
        g[m] = negative_log_likelihood(z, pairs, k, reference).imag / h
    return g


def fit(pairs, k, reference):
    x0 = np.zeros(k)
    res = minimize(negative_log_likelihood, x0, args=(pairs, k, reference), jac=gradient,
                   method="BFGS", options={"gtol": 1e-10, "maxiter": 10000})
    x = res.x
    for _ in range(5):
        hessian = np.zeros((k, k))
        for m in range(k):
            e = np.zeros(k)
            e[m] = 1e-5
            hessian[:, m] = (gradient(x + e, pairs, k, reference) - gradient(x - e, pairs, k, reference)) / 2e-5
        hessian = (hessian + hessian.T) / 2
        x = x - np.linalg.solve(hessian, gradient(x, pairs, k, reference))
    covariance = np.linalg.inv(hessian)
    se = np.sqrt(np.diag(covariance))
    lam = np.concatenate([x[:reference], [0.0], x[reference:k - 1]])
    lam_se = np.concatenate([se[:reference], [0.0], se[reference:k - 1]])
    nu = float(np.exp(x[k - 1]))
    return {
        "log_worth": lam.tolist(),
        "se": lam_se.tolist(),
        "nu": nu,
        "nu_se": nu * float(se[k - 1]),
        "log_likelihood_kernel": -float(negative_log_likelihood(x, pairs, k, reference)),
        "gradient_max": float(np.abs(gradient(x, pairs, k, reference)).max()),
    }


sets = []
full = [(i, j) for i in range(5) for j in range(i + 1, 5)]
data = simulate([0.0, 0.3, -0.4, 0.9, 0.5], 0.6, full, 40)
sets.append({"name": "full", "conditions": 5, "reference": 0, "pairs": data, **fit(data, 5, 0)})
chain = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (0, 2), (2, 4), (1, 5)]
data = simulate([0.0, -0.5, 0.2, 0.8, 1.1, 0.4], 1.3, chain, 25)
sets.append({"name": "incomplete, many ties", "conditions": 6, "reference": 2, "pairs": data, **fit(data, 6, 2)})
print(json.dumps({"tool": f"scipy {scipy.__version__}, numpy {np.__version__}", "sets": sets}, indent=1))
