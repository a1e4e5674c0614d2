"""psignifit 4.3 (PyPI `psignifit==4.3`, wichmann-lab) on its own demo data (demo_001, the
2AFC data of its "basic usage" page), for `analysis/src/threshold/fit_tests.rs`.

Where the models agree: psignifit's `norm` sigmoid with the guess rate fixed at 0.5 (2AFC) and
the overdispersion `eta` fixed at 0 (a binomial likelihood, as mrstudy's) is mrstudy's
`normal` function on the linear scale: p = γ + (1 − γ − λ)·Φ((x − t)/σ), with psignifit's
threshold (at PC = 0.5 of the sigmoid) = t and its width (from α = 0.05 to 1 − α) =
(Φ⁻¹(0.95) − Φ⁻¹(0.05))·σ. Where they do not: psignifit is Bayesian — its point estimate is the
MAP under its default priors (flat over the data range for the threshold and width, Beta(1, 10)
on the lapse in [0, 0.5]); mrstudy's is the maximum likelihood with the lapse in [0, 0.1].
With the lapse fixed at 0 (where both put it on this data: psignifit's MAP lapse is 1.6e-7) the
flat priors make the MAP the ML, so threshold and width must agree up to psignifit's own
optimiser tolerance (its grid search and Nelder–Mead polish: its fits with the lapse free and
fixed differ by 2.6e-4 and 7e-4 relative in threshold and width).

Run: python3 analysis/reference/psignifit_demo.py > analysis/tests/reference/psignifit_demo.json
"""
import json
import warnings

import numpy as np
import psignifit as ps
from importlib.metadata import version
from scipy.stats import norm

warnings.filterwarnings("ignore")
data = np.array([[0.0010, 45, 90], [0.0015, 50, 90], [0.0020, 44, 90], [0.0025, 44, 90],
                 [0.0030, 52, 90], [0.0035, 53, 90], [0.0040, 62, 90], [0.0045, 64, 90],
                 [0.0050, 76, 90], [0.0060, 79, 90], [0.0070, 88, 90], [0.0080, 90, 90],
                 [0.0100, 90, 90]], float)
span = norm.ppf(0.95) - norm.ppf(0.05)
fits = []
for name, fixed in [("lapse fixed at 0", {"eta": 0.0, "lambda": 0.0}), ("lapse free", {"eta": 0.0})]:
    res = ps.psignifit(data, sigmoid="norm", experiment_type="2AFC", fixed_parameters=fixed, verbose=False)
    est = res.parameter_estimate_MAP
    fits.append({"name": name, "threshold": est["threshold"], "width": est["width"],
                 "sd": est["width"] / span, "lapse": est["lambda"]})
# the ML of the same model (lapse 0) by scipy's Nelder–Mead, for the record: mrstudy's fit gives it
from scipy.optimize import minimize  # noqa: E402


def nll(params):
    t, log_sd = params
    p = np.clip(0.5 + 0.5 * norm.cdf((data[:, 0] - t) / np.exp(log_sd)), 1e-12, 1 - 1e-12)
    return -(data[:, 1] * np.log(p) + (data[:, 2] - data[:, 1]) * np.log(1 - p)).sum()


ml = minimize(nll, [0.0046, np.log(0.0014)], method="Nelder-Mead",
              options={"xatol": 1e-12, "fatol": 1e-12, "maxiter": 20000})
print(json.dumps({
    "scipy_ml_lapse_0": {"threshold": ml.x[0], "sd": float(np.exp(ml.x[1]))},
    "tool": f"psignifit {version('psignifit')}", "sigmoid": "norm", "experiment_type": "2AFC",
    "x": data[:, 0].tolist(), "k": data[:, 1].astype(int).tolist(), "n": data[:, 2].astype(int).tolist(),
    "fits": fits,
}, indent=2))
