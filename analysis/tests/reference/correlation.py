"""Reference values for analysis/src/stimulus_metrics.rs: Spearman's rho and Kendall's tau-b, on
fixed tables with ties, computed by scipy.stats.spearmanr and scipy.stats.kendalltau (variant
"b", the default).

Run from anywhere (scipy 1.17.1, numpy; Python 3):

    python3 analysis/tests/reference/correlation.py

It writes correlation.json beside this script: each case's x, y and scipy's rho and tau. Numbers
are written with repr (shortest round-trip), so they read back to the same double.
"""
import json
import os

import numpy
import scipy
from scipy import stats

CASES = {
    # A metric with ties against log-worths with ties (the tied cases the ranks must average).
    "ties_both": (
        [0.10, 0.25, 0.25, 0.40, 0.40, 0.40, 0.55, 0.70, 0.70, 0.90, 1.20, 1.20],
        [1.30, 0.90, 1.10, 0.20, 0.90, 0.40, 0.00, -0.30, 0.20, -0.80, -0.80, -1.10],
    ),
    # Ties only in x: a metric that rounds to few values.
    "ties_in_x": (
        [1, 1, 1, 2, 2, 3, 3, 3, 3, 4],
        [0.3, -0.2, 0.5, 0.1, 0.9, 1.2, 0.8, 1.5, 0.4, 2.0],
    ),
    # Three items (the fewest the analysis correlates), one tie.
    "three_items": ([0.5, 0.5, 0.9], [0.2, 0.0, -1.0]),
    # Perfectly monotone decreasing but non-linear, with a tie in y.
    "monotone": ([0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0], [3.0, 2.5, 2.5, 1.0, 0.0, -2.0, -7.5]),
    # Negative values and a tie group of four.
    "negative": (
        [-2.0, -1.5, -1.5, -1.5, -1.5, 0.0, 0.5, 0.75, 3.0],
        [0.0, 0.1, -0.1, 0.1, 0.2, 0.3, -0.5, 0.1, 0.9],
    ),
}

here = os.path.dirname(os.path.abspath(__file__))
out = {
    "source": f"scipy {scipy.__version__} (stats.spearmanr, stats.kendalltau variant b), numpy {numpy.__version__}",
    "cases": [],
}
for name, (x, y) in CASES.items():
    rho = stats.spearmanr(x, y).statistic
    tau = stats.kendalltau(x, y, variant="b").statistic
    out["cases"].append({"name": name, "x": x, "y": y, "spearman_rho": float(rho), "kendall_tau_b": float(tau)})
with open(os.path.join(here, "correlation.json"), "w") as f:
    json.dump(out, f, indent=1)
    f.write("\n")
