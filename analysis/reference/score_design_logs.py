#!/usr/bin/env python3
"""Scores judgment logs of paired-comparison designs with one common estimator, so that only the
pairs differ: the MAP of the Thurstone model (P(i over j) = Phi(w_i - w_j)) under the prior
w ~ N(0, 1) per condition (mrstudy's active posterior uses the same prior), then the RMSE of the
centred estimate against the centred truth, averaged over runs, at given trial counts.

    score_design_logs.py WORTHS.csv CHECKPOINTS NAME=LOG.csv [NAME=LOG.csv ...]

WORTHS.csv has a `log_worth` column (one row per condition, in index order); CHECKPOINTS is
comma-separated trial counts; each LOG.csv has columns run,trial,i,j,i_won (1 when i won),
trials numbered from 1 within a run. For each design after the first it also prints how many
trials it used as a fraction of the trials the first design needs for the same RMSE (log-log
interpolation of the first design's curve): below 1 means fewer trials than the first.
Needs numpy and scipy (run here with numpy 2.4.6, scipy 1.17.1).
"""
import csv
import sys

import numpy as np
from scipy.optimize import minimize
from scipy.special import log_ndtr
from scipy.stats import norm


def map_fit(n, winners, losers):
    def objective(w):
        d = w[winners] - w[losers]
        value = -log_ndtr(d).sum() + 0.5 * (w @ w)
        ratio = np.exp(norm.logpdf(d) - log_ndtr(d))  # phi / Phi, stable in the tails
        grad = w.copy()
        np.add.at(grad, winners, -ratio)
        np.add.at(grad, losers, ratio)
        return value, grad

    result = minimize(objective, np.zeros(n), jac=True, method="L-BFGS-B", options={"gtol": 1e-10, "maxiter": 1000})
    return result.x


def centred_rmse(estimate, truth):
    return float(np.sqrt(np.mean(((estimate - estimate.mean()) - (truth - truth.mean())) ** 2)))


def main():
    with open(sys.argv[1]) as f:
        truth = np.array([float(row["log_worth"]) for row in csv.DictReader(f)])
    checkpoints = [int(c) for c in sys.argv[2].split(",")]
    curves = {}
    for spec in sys.argv[3:]:
        name, path = spec.split("=", 1)
        runs = {}
        with open(path) as f:
            for row in csv.DictReader(f):
                i, j, won = int(row["i"]), int(row["j"]), row["i_won"] == "1"
                runs.setdefault(int(row["run"]), []).append((i, j) if won else (j, i))
        rows = []
        for c in checkpoints:
            values = []
            if min(len(log) for log in runs.values()) < c:
                print(f"({name}: skipped {c} trials, its runs are shorter)", file=sys.stderr)
                continue
            for log in runs.values():
                pairs = np.array(log[:c])
                values.append(centred_rmse(map_fit(len(truth), pairs[:, 0], pairs[:, 1]), truth))
            values = np.array(values)
            rows.append((c, values.mean(), values.std(ddof=1) / np.sqrt(len(values)), len(values)))
        curves[name] = rows
    first = next(iter(curves))
    base_t = np.log([r[0] for r in curves[first]])
    base_e = np.log([r[1] for r in curves[first]])
    print("| design | trials | runs | RMSE (common MAP) | trials as a fraction of `%s`'s for this RMSE |" % first)
    print("|---|---:|---:|---:|---:|")
    for name, rows in curves.items():
        for c, mean, se, n in rows:
            fraction = ""
            if name != first:
                # base_e decreases with trials: interpolate log trials against log RMSE.
                e = np.log(mean)
                if base_e[-1] <= e <= base_e[0]:
                    fraction = "%.2f" % (c / np.exp(np.interp(e, base_e[::-1], base_t[::-1])))
                else:
                    fraction = "outside %s's curve" % first
            print(f"| {name} | {c} | {n} | {mean:.3f} ± {se:.3f} | {fraction} |")


if __name__ == "__main__":
    main()
