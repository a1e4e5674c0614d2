"""Why mrstudy does not report SUREAL's full model (docs/analysis.md, "Rating studies").

Tool: sureal 0.9.0 (PyPI), MaximumLikelihoodEstimationModel (TYPE 'MLE', the full model with
content ambiguity), run_modeling(delta_thr=1e-13), on the NFLX subset and the simulated set of
sureal_reference.py. Prints the iterations, the range of the subject inconsistencies v_s, the
content ambiguities a_c, and the log-likelihood at SUREAL's estimate and after moving
k = half the smallest a_c^2 from every a_c^2 to every v_s^2: the two agree (a flat ridge), so
v_s and a_c are identifiable only as the sums v_s^2 + a_c^2.

Run from the repository root: python3 analysis/reference/sureal_full_ridge.py /path/to/sureal
Output of the run behind docs/analysis.md:
  nflx 3720 v 1.9e-171 0.689 a [0.310 0.330 0.378 0.339] -747.8215453477923 -747.8215453477924
  sim 1705 v 5.4e-79 1.062 a [0.333 0.381 0.385] -253.1801872949899 -253.1801872949899
"""

import contextlib
import io
import os
import sys

import numpy as np
from sureal.dataset_reader import RawDatasetReader
from sureal.subjective_model import MaximumLikelihoodEstimationModel
from sureal.tools.misc import import_python_file

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sureal_reference as reference  # noqa: E402


def main():
    root = sys.argv[1].rstrip('/') + '/resource/dataset/'
    nflx = import_python_file(root + 'NFLX_dataset_public_raw.py')
    for name, dataset in [('nflx', reference.subset(nflx, {0, 1, 2, 3})),
                          ('sim', reference.simulated(20261128, 30, 12))]:
        reader = RawDatasetReader(dataset)
        with contextlib.redirect_stdout(io.StringIO()):
            result = MaximumLikelihoodEstimationModel(reader).run_modeling(delta_thr=1e-13)
        v = np.array(result['observer_inconsistency'])
        a = np.array(result['content_ambiguity'])
        x = np.array(result['quality_scores'])
        b = np.array(result['observer_bias'])

        def loglik(v, a):
            return np.nansum(MaximumLikelihoodEstimationModel.loglikelihood_fcn(
                reader.opinion_score_3darray, x, b, v, a, reader.content_id_of_dis_videos, 1, 'gaussian'))

        k = 0.5 * np.min(a[a > 0] ** 2)
        print(name, result['num_iter'], 'v', v.min(), v.max(), 'a', a,
              loglik(v, a), loglik(np.sqrt(v ** 2 + k), np.sqrt(np.maximum(a ** 2 - k, 0))))


if __name__ == '__main__':
    main()
