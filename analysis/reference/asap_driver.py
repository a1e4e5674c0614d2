#!/usr/bin/env python3
"""Runs ASAP's published scheduler (Mikhailiuk et al., ICPR 2020; `gfxdisp/asap` at 90082a3,
`python/asap_cpu.py`: full TrueSkill posterior update, batch mode — a minimum spanning tree of
N − 1 pairs per batch) against simulated Thurstone observers, P(i over j) = Phi(w_i − w_j), and
writes the judgment log that `score_design_logs.py` scores (columns run,trial,i,j,i_won).
ASAP's code is not part of this repository: pass the directory holding its `asap_cpu.py`.

    asap_driver.py ASAP_DIR WORTHS.csv RUNS TRIALS FIRST_RUN > LOG.csv

Run r seeds Python's `random` and numpy's global generator (ASAP's own draws) with r, and the
outcomes with numpy's default_rng(100000 + r). Run here with Python 3.11, numpy 2.4.6,
scipy 1.17.1, networkx 2.8.8 (ASAP calls `networkx.from_numpy_matrix`, gone in networkx 3).
"""
import csv
import random
import sys

import numpy as np
from scipy.stats import norm


def main():
    asap_dir, worths_csv, runs, trials, first = sys.argv[1], sys.argv[2], *map(int, sys.argv[3:6])
    sys.path.insert(0, asap_dir)
    import asap_cpu  # noqa: E402 (ASAP's module, from the directory given)

    with open(worths_csv) as f:
        worths = np.array([float(row["log_worth"]) for row in csv.DictReader(f)])
    n = len(worths)
    out = csv.writer(sys.stdout)
    out.writerow(["run", "trial", "i", "j", "i_won"])
    for run in range(first, first + runs):
        random.seed(run)
        np.random.seed(run)
        outcomes = np.random.default_rng(100000 + run)
        scheduler = asap_cpu.ASAP(n, selective_eig=False, approx=False)
        wins = np.zeros((n, n), dtype=int)
        trial = 0
        while trial < trials:
            for i, j in scheduler.run_asap(wins.copy(), mst_mode=True):
                if trial == trials:
                    break
                i, j = int(i), int(j)
                i_won = outcomes.random() < norm.cdf(worths[i] - worths[j])
                winner, loser = (i, j) if i_won else (j, i)
                wins[winner][loser] += 1
                trial += 1
                out.writerow([run, trial, i, j, int(i_won)])
        sys.stdout.flush()


if __name__ == "__main__":
    main()
