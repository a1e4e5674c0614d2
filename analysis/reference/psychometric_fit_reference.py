#!/usr/bin/env python3
"""Reference maximum-likelihood psychometric fits for mrstudy's `threshold::fit` (issue 48).

Tool: scipy (scipy.optimize.minimize, L-BFGS-B from many starts, then a tight polish), numpy;
versions are written into the fixture. Model exactly as `threshold::fit` (questplus 2023.1's
parameterisations): p = guess + (1 - guess - lapse) F(u) with
  weibull log10: 1 - exp(-10^(slope (x - t)));  dB: 1 - exp(-10^(slope (x - t) / 20));
  weibull linear: 1 - exp(-(x / t)^slope);  logistic: 1 / (1 + exp(-slope (x - t)));
  normal: Phi((x - t) / slope).
Threshold and slope free (slope > 0), lapse in [0, 0.1], guess fixed.
Run:  python3 analysis/reference/psychometric_fit_reference.py > analysis/tests/reference/psychometric_fit_scipy.json
"""
import json
import sys

import numpy as np
import scipy
from scipy import optimize, stats

LAPSE_MAX = 0.1


def prob(function, scale, x, t, b, d, g):
    x = np.asarray(x, dtype=float)
    if function == "weibull":
        if scale == "log10":
            return 1 - d - (1 - g - d) * np.exp(-(10 ** (b * (x - t))))
        if scale == "dB":
            return 1 - d - (1 - g - d) * np.exp(-(10 ** (b * (x - t) / 20)))
        return 1 - d - (1 - g - d) * np.exp(-((x / t) ** b))
    if function == "logistic":
        return g + (1 - g - d) / (1 + np.exp(-b * (x - t)))
    return g + (1 - g - d) * stats.norm.cdf((x - t) / b)


def negll(theta, function, scale, x, n, k, g):
    t, b, d = theta
    if b <= 0 or (function == "weibull" and scale == "linear" and t <= 0):
        return 1e300
    p = np.clip(prob(function, scale, x, t, b, d, g), 1e-300, 1 - 1e-16)
    return -float(np.sum(k * np.log(p) + (n - k) * np.log1p(-p)))


def ml(function, scale, x, n, k, g):
    lo, hi = x.min(), x.max()
    w = hi - lo
    if function == "weibull" and scale == "linear":
        t_starts = np.exp(np.linspace(np.log(lo), np.log(hi), 7))
        t_bounds = (lo * 1e-3, hi * 1e3)
    else:
        t_starts = np.linspace(lo, hi, 7)
        t_bounds = (lo - 2 * w, hi + 2 * w)
    if function == "normal":
        b_starts = w / np.array([1.0, 3.0, 10.0, 30.0])
    elif function == "weibull" and scale == "dB":
        b_starts = 20 * np.array([1.0, 3.0, 10.0, 30.0]) / w
    elif function == "weibull" and scale == "linear":
        b_starts = np.array([0.5, 1.0, 2.0, 4.0, 8.0])
    else:
        b_starts = np.array([1.0, 3.0, 10.0, 30.0]) / w
    best = None
    for t0 in t_starts:
        for b0 in b_starts:
            for d0 in (0.0, 0.02, 0.08):
                r = optimize.minimize(negll, [t0, b0, d0], args=(function, scale, x, n, k, g), method="L-BFGS-B",
                                      bounds=[t_bounds, (1e-8, None), (0.0, LAPSE_MAX)],
                                      options=dict(ftol=1e-15, gtol=1e-10, maxiter=5000))
                if best is None or r.fun < best.fun:
                    best = r
    # Polish from the best start with Nelder-Mead on the interior, then L-BFGS-B again.
    r = optimize.minimize(negll, best.x, args=(function, scale, x, n, k, g), method="L-BFGS-B",
                          bounds=[t_bounds, (1e-8, None), (0.0, LAPSE_MAX)],
                          options=dict(ftol=1e-16, gtol=1e-12, maxiter=20000))
    if r.fun <= best.fun:
        best = r
    return best


def simulate(rng, function, scale, x, n, truth, g):
    p = prob(function, scale, x, *truth, g)
    return rng.binomial(n, p)


def main():
    rng = np.random.default_rng(2026)
    levels = np.array([2.0 ** j for j in range(10)])
    xlog = np.sort(np.log10(1.0 / levels))
    cases = []
    specs = [
        ("weibull-log10", "weibull", "log10", xlog, 40, (-1.5, 3.5, 0.02)),
        ("weibull-log10-small", "weibull", "log10", xlog, 12, (-1.2, 2.5, 0.0)),
        ("weibull-dB", "weibull", "dB", 20 * xlog, 30, (-30.0, 3.0, 0.03)),
        ("weibull-linear", "weibull", "linear", np.sort(1.0 / levels), 30, (0.03, 1.5, 0.01)),
        ("logistic-log10", "logistic", "log10", xlog, 40, (-1.4, 6.0, 0.02)),
        ("normal-log10", "normal", "log10", xlog, 40, (-1.6, 0.3, 0.04)),
        ("weibull-log10-high-lapse", "weibull", "log10", xlog, 60, (-1.2, 2.0, 0.08)),
    ]
    for name, function, scale, x, per, truth in specs:
        n = np.full(len(x), per)
        k = simulate(rng, function, scale, x, n, truth, 0.5)
        r = ml(function, scale, x, n, k, 0.5)
        cases.append(dict(name=name, function=function, scale=scale, guess=0.5, lapse_max=LAPSE_MAX,
                          x=[float(v) for v in x], n=[int(v) for v in n], k=[int(v) for v in k],
                          truth=list(truth), threshold=float(r.x[0]), slope=float(r.x[1]), lapse=float(r.x[2]),
                          log_likelihood=-float(r.fun)))
    json.dump(dict(tool="scipy.optimize.minimize (L-BFGS-B, multi-start)",
                   versions=dict(scipy=scipy.__version__, numpy=np.__version__, python=sys.version.split()[0]),
                   script="analysis/reference/psychometric_fit_reference.py", cases=cases), sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
