#!/usr/bin/env python3
"""The fraction of random pairs' trials a scheduler needs, from `early_gap`'s output (issue 48).

Reads the text `cargo run --release -p mrstudy-analysis --example early_gap -- RUNS 20
"random,NAME" long,precise` prints (one line per scheduler, `TRIALS: MEAN ± SE` per checkpoint;
the row named "random pairs" first) and, for the other scheduler at each checkpoint t with RMSE
r, prints t / t*, t* the trials random pairs need for r by log-log interpolation of random's row
(beyond its last checkpoint: extrapolated from its last segment), with an sd from 20 000 normal
draws of every RMSE by its standard error (the two rows' errors taken as independent), the
interval from the scheduler's RMSE ± one se alone, and the distance to 0.727 (within 10 % of the
A-optimal oracle bound 0.661, design_bound.py) in those sds.
Tools: Python 3.11 standard library only (math, random, re). Run:
  python3 analysis/reference/fraction_of_random.py EARLY_GAP_OUTPUT.txt
"""
import math
import random
import re
import sys

LIMIT = 0.727


def rows_of(text):
    rows = {}
    for line in text.splitlines():
        cells = re.findall(r"(\d+): ([\d.]+) ± ([\d.]+)", line)
        if cells:
            rows[line[:29].strip()] = [(int(t), float(m), float(s)) for t, m, s in cells]
    return rows


def fraction(r, t, curve):
    """t / (random's trials for RMSE r), curve = [(trials, rmse)] of random pairs."""
    segments = list(zip(curve, curve[1:]))
    segment = next(((a, b) for a, b in segments if a[1] >= r >= b[1]), segments[-1])
    (ta, ra), (tb, rb) = segment
    log_t = math.log(ta) + (math.log(r) - math.log(ra)) * (math.log(tb) - math.log(ta)) / (math.log(rb) - math.log(ra))
    return t / math.exp(log_t)


def main():
    rows = rows_of(open(sys.argv[1], encoding="utf-8").read())
    rnd = rows.pop("random pairs")
    curve = [(t, m) for t, m, _ in rnd]
    rng = random.Random(1)
    for name, row in rows.items():
        print(name)
        for t, m, s in row:
            f = fraction(m, t, curve)
            draws = [
                fraction(rng.gauss(m, s), t, [(tt, rng.gauss(mm, ss)) for tt, mm, ss in rnd]) for _ in range(20000)
            ]
            mean = sum(draws) / len(draws)
            sd = math.sqrt(sum((d - mean) ** 2 for d in draws) / (len(draws) - 1))
            low, high = fraction(m + s, t, curve), fraction(m - s, t, curve)
            print(
                f"  {t}: fraction {f:.3f} ± {sd:.3f} (its RMSE ± 1 se alone: {low:.3f}-{high:.3f}); "
                f"{(LIMIT - f) / sd:+.2f} sd inside {LIMIT}"
            )


if __name__ == "__main__":
    main()
