"""Reference values for d' of two-alternative forced choice in analysis/src/detection.rs:
d' = sqrt(2) * z(pc), by scipy.stats.norm.ppf, checked against published table values.

Published values (three decimals) of 2AFC d' from the table of Hacker & Ratcliff (1979), A
revised table of d' for M-alternative forced choice, Perception & Psychophysics 26(2), 168-170,
which Macmillan & Creelman, Detection Theory: A User's Guide, reprint in their appendix tables:
    pc = 0.60 -> 0.358,  pc = 0.75 -> 0.954,  pc = 0.90 -> 1.812.
(These three were taken as quoted in issue 15; the printed tables were not at hand here.)
The script asserts that sqrt(2) * norm.ppf(pc) rounds to those, then writes d_prime.json with
full-precision values for more proportions (scipy 1.17.1):

    python3 analysis/tests/reference/d_prime.py
"""
import json
import math
import os

import scipy
from scipy.stats import norm

PUBLISHED = {0.60: 0.358, 0.75: 0.954, 0.90: 1.812}
for pc, table in PUBLISHED.items():
    value = math.sqrt(2) * norm.ppf(pc)
    assert round(value, 3) == table, (pc, value, table)

PROPORTIONS = [0.025, 0.3, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 0.975, 0.99]
here = os.path.dirname(os.path.abspath(__file__))
out = {
    "source": f"scipy {scipy.__version__} (stats.norm.ppf); published 2AFC table: Hacker & Ratcliff 1979 (as reprinted by Macmillan & Creelman)",
    "published": [{"pc": pc, "d_prime": d} for pc, d in PUBLISHED.items()],
    "computed": [{"pc": pc, "d_prime": math.sqrt(2) * float(norm.ppf(pc))} for pc in PROPORTIONS],
}
with open(os.path.join(here, "d_prime.json"), "w") as f:
    json.dump(out, f, indent=1)
    f.write("\n")
