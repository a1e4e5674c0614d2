#!/usr/bin/env python3
"""Reference QUEST+ runs for mrstudy's `threshold::quest` (issue 48).

Tool: questplus 2023.1 (PyPI), numpy, xarray, scipy (versions are written into the fixture).
Run:  pip install --user questplus==2023.1 scipy
      python3 analysis/reference/questplus_reference.py > analysis/tests/reference/questplus_2023_1.json

Cases:
- Watson (2017) Example 1 and the threshold-and-slope example, exactly as questplus's own
  tests/test_qp.py runs them (their expected stimulus sequences are asserted here too), and
  Example 2 (threshold, slope and lapse; 128 responses);
- simulated observers on the grids of the shipped example `studies/threshold-vpls.toml`
  (levels 1, 2, 4, ..., 512 VPLs, intensity = "inverse-knob", x = log10(1/level)), for each
  psychometric function: weibull (questplus's), normal (questplus's norm_cdf: mean = threshold,
  sd = slope, linear in x) and logistic (not in questplus 2023.1: added here through the same
  QuestPlus machinery, p = gamma + (1 - gamma - delta) / (1 + exp(-slope (x - threshold)))),
  and a dB and a linear-scale Weibull. The responses come from a seeded observer that answers
  the stimulus questplus chose; the fixture stores both, so mrstudy replays the answers and
  must choose the same stimulus at every step.
"""
import json
import sys

import numpy as np
import scipy
import scipy.stats
import xarray as xr
import questplus
from questplus import psychometric_function as pf
from questplus.qp import QuestPlus


def logistic(*, intensity, mean, sd, lower_asymptote, lapse_rate, scale="linear"):
    # Same broadcasting as questplus's norm_cdf; `mean` is the threshold, `sd` the slope.
    x = xr.DataArray(data=np.atleast_1d(intensity), dims=["intensity"],
                     coords=dict(intensity=np.atleast_1d(intensity)))
    t = xr.DataArray(data=np.atleast_1d(mean), dims=["mean"], coords=dict(mean=np.atleast_1d(mean)))
    b = xr.DataArray(data=np.atleast_1d(sd), dims=["sd"], coords=dict(sd=np.atleast_1d(sd)))
    g = xr.DataArray(data=np.atleast_1d(lower_asymptote), dims=["lower_asymptote"],
                     coords=dict(lower_asymptote=np.atleast_1d(lower_asymptote)))
    d = xr.DataArray(data=np.atleast_1d(lapse_rate), dims=["lapse_rate"],
                     coords=dict(lapse_rate=np.atleast_1d(lapse_rate)))
    return g + (1 - g - d) / (1 + np.exp(-b * (x - t)))


# questplus 2023.1 dispatches on the name; "norm_cdf" is the slot we borrow for the logistic.
_norm_cdf = pf.norm_cdf


def make(function, scale, x, thresholds, slopes, guess, lapses):
    if function == "weibull":
        pd = dict(threshold=thresholds, slope=slopes, lower_asymptote=[guess], lapse_rate=lapses)
        func, stim_scale = "weibull", scale
    else:
        pf.norm_cdf = _norm_cdf if function == "normal" else logistic
        pd = dict(mean=thresholds, sd=slopes, lower_asymptote=[guess], lapse_rate=lapses)
        func, stim_scale = "norm_cdf", "linear"
    return QuestPlus(stim_domain=dict(intensity=np.asarray(x)), param_domain=pd,
                     outcome_domain=dict(response=["Correct", "Incorrect"]), func=func,
                     stim_scale=stim_scale, stim_selection_method="min_entropy",
                     param_estimation_method="mode")


def estimates(q, function):
    names = ["threshold", "slope", "lapse_rate"] if function == "weibull" else ["mean", "sd", "lapse_rate"]
    q.param_estimation_method = "mode"
    mode = q.param_estimate
    q.param_estimation_method = "mean"
    mean = q.param_estimate
    return ([mode[n] for n in names], [mean[n] for n in names])


def run_fixed(name, function, scale, x, thresholds, slopes, guess, lapses, responses, expected=None):
    q = make(function, scale, x, thresholds, slopes, guess, lapses)
    chosen = []
    for r in responses:
        stim = q.next_stim["intensity"]
        i = int(np.flatnonzero(np.asarray(x) == stim)[0])
        chosen.append(i)
        q.update(stim=dict(intensity=stim), outcome=dict(response="Correct" if r else "Incorrect"))
    if expected is not None:
        got = [float(x[i]) for i in chosen]
        assert got == [float(e) for e in expected], (name, got)
    mode, mean = estimates(q, function)
    return case(name, function, scale, x, thresholds, slopes, guess, lapses, chosen, responses, mode, mean, q)


def run_observer(name, function, scale, x, thresholds, slopes, guess, lapses, truth, trials, seed, coin=False):
    rng = np.random.default_rng(seed)
    q = make(function, scale, x, thresholds, slopes, guess, lapses)
    t, b, d = truth
    chosen, responses = [], []
    for _ in range(trials):
        stim = q.next_stim["intensity"]
        i = int(np.flatnonzero(np.asarray(x) == stim)[0])
        if function == "weibull":
            p = float(pf.weibull(intensity=stim, threshold=t, slope=b, lower_asymptote=guess,
                                 lapse_rate=d, scale=scale).squeeze())
        elif function == "normal":
            p = guess + (1 - guess - d) * scipy.stats.norm.cdf(stim, t, b)
        else:
            p = guess + (1 - guess - d) / (1 + np.exp(-b * (stim - t)))
        if coin:  # a response sequence that ignores the stimulus
            p = 0.5
        correct = bool(rng.random() < p)
        chosen.append(i)
        responses.append(correct)
        q.update(stim=dict(intensity=stim), outcome=dict(response="Correct" if correct else "Incorrect"))
    mode, mean = estimates(q, function)
    return case(name, function, scale, x, thresholds, slopes, guess, lapses, chosen, responses, mode, mean, q)


def case(name, function, scale, x, thresholds, slopes, guess, lapses, chosen, responses, mode, mean, q):
    post = q.posterior.values.reshape(len(thresholds), len(slopes), len(lapses))
    return dict(name=name, function=function, scale=scale, x=[float(v) for v in x],
                thresholds=[float(v) for v in thresholds], slopes=[float(v) for v in slopes],
                guess=float(guess), lapses=[float(v) for v in lapses], chosen=chosen,
                correct=[bool(r) for r in responses], mode=[float(v) for v in mode],
                mean=[float(v) for v in mean],
                posterior_max=float(post.max()), posterior_entropy=float(-(post[post > 0] * np.log(post[post > 0])).sum()))


def test_lists(function_name):
    """The `expected_contrasts` and `responses` lists of a test in questplus's tests/test_qp.py."""
    import ast
    import os
    path = os.path.join(os.path.dirname(questplus.__file__), "tests", "test_qp.py")
    tree = ast.parse(open(path).read())
    fn = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == function_name)
    found = {}
    for node in ast.walk(fn):
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            if node.targets[0].id in ("expected_contrasts", "responses"):
                found[node.targets[0].id] = ast.literal_eval(node.value)
    return found["expected_contrasts"], [r == "Correct" for r in found["responses"]]


def main():
    cases = []
    # Watson 2017 Example 1 (test_qp.py::test_threshold).
    thr = np.arange(-40, 0 + 1)
    exp1, resp1 = test_lists("test_threshold")
    cases.append(run_fixed("watson2017-example1", "weibull", "dB", thr, thr, [3.5], 0.5, [0.02], resp1, exp1))
    # test_qp.py::test_threshold_slope.
    exp2, resp2 = test_lists("test_threshold_slope")
    cases.append(run_fixed("watson2017-threshold-slope", "weibull", "dB", thr, thr, np.arange(2, 6), 0.5, [0.02], resp2, exp2))
    # test_qp.py::test_threshold_slope_lapse (Watson 2017 Example 2).
    exp3, resp3 = test_lists("test_threshold_slope_lapse")
    cases.append(run_fixed("watson2017-example2", "weibull", "dB", thr, thr, np.arange(2, 6), 0.5,
                           np.arange(0, 0.04 + 0.01, 0.01), resp3, exp3))

    # The shipped example's grids: levels 1..512 VPLs, inverse-knob, log10.
    levels = [2 ** k for k in range(10)]
    x = np.sort(np.log10(1.0 / np.asarray(levels, dtype=float)))  # ascending intensity
    thresholds = np.round(np.arange(-3.0, 0.0 + 1e-9, 0.25), 10)
    slopes = [1.0, 2.0, 3.5, 5.0]
    lapses = [0.0, 0.01, 0.02, 0.04]
    seed = 48
    for function in ["weibull", "logistic", "normal"]:
        for k, truth in enumerate([(-1.5, 3.5, 0.02), (-2.2, 2.0, 0.0), (-0.6, 5.0, 0.04), (-1.0, 1.0, 0.01)]):
            t, b, d = truth
            if function == "normal":
                b = 1.0 / b  # an sd in log units
            slope_grid = slopes if function != "normal" else [0.1, 0.2, 0.35, 0.5, 1.0]
            cases.append(run_observer(f"vpls-{function}-{k}", function, "log10", x, thresholds, slope_grid, 0.5,
                                      lapses, (t, b, d), 40, seed))
            seed += 1
    # dB and linear Weibull on the same levels.
    xdb = 20 * x
    cases.append(run_observer("vpls-weibull-dB", "weibull", "dB", xdb, 20 * thresholds, [10.0, 20.0, 35.0, 50.0],
                              0.5, lapses, (-30.0, 35.0, 0.02), 40, 100))
    xl = np.sort(1.0 / np.asarray(levels, dtype=float))
    cases.append(run_observer("vpls-weibull-linear", "weibull", "linear", xl, [0.005, 0.01, 0.02, 0.04, 0.08, 0.16],
                              [1.0, 2.0, 3.5, 5.0], 0.5, lapses, (0.03, 2.0, 0.02), 40, 101))
    # Random response sequences (fair coin, whatever was shown).
    for k, function in enumerate(["weibull", "logistic", "normal", "weibull"]):
        slope_grid = slopes if function != "normal" else [0.1, 0.2, 0.35, 0.5, 1.0]
        cases.append(run_observer(f"vpls-{function}-coin-{k}", function, "log10", x, thresholds, slope_grid, 0.5,
                                  lapses, (0.0, 1.0, 0.0), 40, 200 + k, coin=True))
    out = dict(tool="questplus", versions=dict(questplus=questplus.__version__, numpy=np.__version__,
                                               scipy=scipy.__version__, xarray=xr.__version__,
                                               python=sys.version.split()[0]),
               script="analysis/reference/questplus_reference.py", cases=cases)
    json.dump(out, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
