"""Reference values for mrstudy's SUREAL MLE_CO fit (analysis/src/ratings/sureal.rs).

Tool: sureal 0.9.0 (PyPI, `pip install --user sureal==0.9.0`), numpy as it pulls in; the
data sets are those the Netflix/sureal repository ships in resource/dataset/ (commit
526715c9d94ec02367e61ef980b94b8c886e4022), read from a checkout given as the first argument.

Model: MaximumLikelihoodEstimationModelContentOblivious (TYPE 'MLE_CO'),
run_modeling(delta_thr=1e-13): the content-oblivious model
    X_es = x_e + B_es,  B_es ~ N(b_s, v_s^2),
solved by SUREAL's damped fixed-point iteration ('simplified' gradient, refresh rate 0.1).
The default stop (delta_thr = 1e-8 on the step of x_e) leaves up to ~1e-6 of the iteration's
error in x_e on these sets; 1e-13 leaves it far below the test's tolerance (1e-6), and the
fixed point is the same maximum-likelihood estimate. Standard errors as SUREAL reports them
(`*_std`): 1/sqrt of the diagonal of the observed information, per parameter.
Subject biases have mean 0 over subjects (force_subjbias_zeromean, SUREAL's default).

The full model (MaximumLikelihoodEstimationModel, TYPE 'MLE', content ambiguity a_c per content
id) is run too; the fixture's `full` keeps its quality, bias and their standard errors, which
depend on v_s^2 + a_c^2 only (see sureal_full_ridge.py for why the split is not identifiable).

Sets (subsets keep the fixture small; the subset is taken before the fit):
- nflx_subset: NFLX_dataset_public_raw.py, the distorted videos of content ids 0-3
  (BigBuckBunny, BirdsInCage, CrowdRun, ElFuente1), all 26 subjects, ratings 1-5.
- vqeg_525_low_subset: vqeg_frtv_p1_525_line_low_dataset.py (VQEG FR-TV Phase I, 525 line,
  low quality), content ids 1-2, scores 0-100, subjects keyed by name (missing cells).
- simulated: 30 stimuli x 12 subjects, x_e, b_s, v_s drawn with numpy seed 20261128, ratings
  rounded and clipped to 1..5, about 15 % of the cells missing and one subject rating twice
  (repetitions).
- simulated_degenerate: the same with 12 stimuli x 9 subjects, where SUREAL's iteration drives
  subject 4's inconsistency to 0 (2.9e-15): MLE_CO's likelihood has no upper bound (any one
  subject's ratings fitted exactly with v_s -> 0), and this set finds that direction.

Run from the repository root:
    python3 analysis/reference/sureal_reference.py /path/to/sureal-checkout \
        > analysis/tests/reference/sureal_mle_co.json
"""

import contextlib
import io
import json
import sys
import types

import numpy as np
import sureal
from sureal.dataset_reader import RawDatasetReader
from sureal.subjective_model import (MaximumLikelihoodEstimationModel,
                                     MaximumLikelihoodEstimationModelContentOblivious)
from sureal.tools.misc import import_python_file


def subset(dataset, content_ids):
    out = types.SimpleNamespace()
    out.dataset_name = dataset.dataset_name
    out.ref_videos = [r for r in dataset.ref_videos if r['content_id'] in content_ids]
    # the VQEG files give content ids as floats (1.0): SUREAL indexes lists with them
    out.dis_videos = [dict(d, content_id=int(d['content_id'])) for d in dataset.dis_videos
                      if int(d['content_id']) in content_ids]
    return out


def simulated(seed, E, S):
    rng = np.random.RandomState(seed)
    x_e = rng.uniform(1.5, 4.5, E)
    b_s = rng.normal(0.0, 0.4, S)
    v_s = rng.uniform(0.3, 1.0, S)
    ds = types.SimpleNamespace()
    ds.dataset_name = 'simulated'
    ds.ref_videos = [{'content_id': c, 'content_name': f'scene{c}', 'path': f'scene{c}'} for c in range(3)]
    ds.dis_videos = []
    for e in range(E):
        os = {}
        for s in range(S):
            if rng.uniform() < 0.15:
                continue  # a missing cell
            reps = 2 if s == 0 else 1
            scores = [float(np.clip(np.round(x_e[e] + b_s[s] + rng.normal(0, v_s[s])), 1, 5)) for _ in range(reps)]
            os[f's{s}'] = scores if reps > 1 else scores[0]
        ds.dis_videos.append({'asset_id': e, 'content_id': e % 3, 'os': os, 'path': f'e{e}'})
    return ds


def fit(dataset, delta_thr):
    reader = RawDatasetReader(dataset)
    with contextlib.redirect_stdout(io.StringIO()):
        result = MaximumLikelihoodEstimationModelContentOblivious(reader).run_modeling(delta_thr=delta_thr)
    x = reader.opinion_score_3darray
    E, S, R = x.shape
    ratings = [[e, s, float(x[e, s, r])] for e in range(E) for s in range(S) for r in range(R) if not np.isnan(x[e, s, r])]
    return {
        'stimuli': E,
        'subjects': S,
        'ratings': ratings,
        'quality': [float(v) for v in result['quality_scores']],
        'quality_se': [float(v) for v in result['quality_scores_std']],
        'bias': [float(v) for v in result['observer_bias']],
        'bias_se': [float(v) for v in result['observer_bias_std']],
        'inconsistency': [float(v) for v in result['observer_inconsistency']],
        'inconsistency_se': [float(v) for v in result['observer_inconsistency_std']],
        'iterations': int(result['num_iter']),
        'content': [int(c) for c in reader.content_id_of_dis_videos],
    }


def fit_full(dataset, delta_thr):
    """The full model (TYPE 'MLE'): only the parts that do not depend on where on the ridge of
    equal likelihood the iteration ends (quality, bias and their standard errors depend on
    v_s^2 + a_c^2 only); inconsistency and ambiguity are recorded for information."""
    reader = RawDatasetReader(dataset)
    with contextlib.redirect_stdout(io.StringIO()):
        result = MaximumLikelihoodEstimationModel(reader).run_modeling(delta_thr=delta_thr)
    return {
        'quality': [float(v) for v in result['quality_scores']],
        'quality_se': [float(v) for v in result['quality_scores_std']],
        'bias': [float(v) for v in result['observer_bias']],
        'bias_se': [float(v) for v in result['observer_bias_std']],
        'inconsistency': [float(v) for v in result['observer_inconsistency']],
        # a content id without stimuli in the subset has no ambiguity (SUREAL: NaN)
        'ambiguity': [float(v) if np.isfinite(v) else None for v in result['content_ambiguity']],
        'iterations': int(result['num_iter']),
    }


def main():
    root = sys.argv[1].rstrip('/') + '/resource/dataset/'
    nflx = import_python_file(root + 'NFLX_dataset_public_raw.py')
    vqeg = import_python_file(root + 'vqeg_frtv_p1_525_line_low_dataset.py')
    sets = {
        'nflx_subset': subset(nflx, {0, 1, 2, 3}),
        'vqeg_525_low_subset': subset(vqeg, {1, 2}),
        'simulated': simulated(20261128, 30, 12),
        # SUREAL's iteration drives one subject's inconsistency to 0 here (the likelihood
        # grows without bound): the Rust fit must say so rather than report it
        'simulated_degenerate': simulated(20261128, 12, 9),
    }
    out = {
        'source': f'sureal {sureal.__version__}, MaximumLikelihoodEstimationModelContentOblivious, delta_thr 1e-13; '
                  'Netflix/sureal resource/dataset at 526715c9d94ec02367e61ef980b94b8c886e4022',
        'sets': {},
    }
    for name, dataset in sets.items():
        out['sets'][name] = fit(dataset, 1e-13)
        if name != 'simulated_degenerate':
            out['sets'][name]['full'] = fit_full(dataset, 1e-13)
        # how far SUREAL's default stop (1e-8) is from the converged fit, for the record
        default = fit(dataset, 1e-8)
        out['sets'][name]['default_stop_max_quality_difference'] = float(
            np.max(np.abs(np.array(default['quality']) - np.array(out['sets'][name]['quality']))))
    json.dump(out, sys.stdout, indent=None, separators=(',', ':'))
    sys.stdout.write('\n')


if __name__ == '__main__':
    main()
