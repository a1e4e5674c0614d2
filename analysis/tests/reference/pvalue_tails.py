"""Reference values for analysis/src/pvalue.rs: log tail probabilities of the normal and chi-square
distributions, computed with mpmath at 50 digits (scipy underflows to -inf in the far tails).

Run: python3 analysis/tests/reference/pvalue_tails.py  (mpmath 1.3, scipy 1.17 for comparison)
"""
import mpmath as mp

mp.mp.dps = 50

def norm_logsf(z):
    return mp.log(mp.erfc(mp.mpf(z) / mp.sqrt(2)) / 2)

def chi2_logsf(x, df):
    return mp.log(mp.gammainc(mp.mpf(df) / 2, mp.mpf(x) / 2, mp.inf, regularized=True))

for z in (3, 40):
    print(f"norm.logsf({z}) = {mp.nstr(norm_logsf(z), 17)}")
for x, df in ((10, 4), (2000, 3), (900, 13)):
    print(f"chi2.logsf({x}, {df}) = {mp.nstr(chi2_logsf(x, df), 17)}")
