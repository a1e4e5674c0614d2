"""Reference values for the ca chain's scene noise table (renderer/src/ca/mod.rs,
display_noise_lut): the variance of R(clip(y + sqrt(a*y + b) * Z, 0, 1)) at d = R(y), Z standard
normal, estimated by Monte Carlo with numpy (10^7 normal draws per point) rather than by
quadrature, for the sRGB response (IEC 61966-2-1) and the webcam's Filmic response with
contrast 1.1. Run: python3 ca_noise_lut.py
"""
import numpy as np

def srgb(c):
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)

def filmic_contrast(y, contrast=1.1):
    x = np.maximum(y, 0.0) * 1.25
    c = srgb(x * (1 + x / 16) / (1 + x))
    return np.clip((c - 0.5) * contrast + 0.5, 0.0, 1.0)

def table_entry(curve, a, b, d, rng):
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if curve(mid) < d:
            lo = mid
        else:
            hi = mid
    y = hi
    z = rng.standard_normal(10_000_000)
    v = curve(np.clip(y + np.sqrt(a * y + b) * z, 0.0, 1.0))
    return float(v.var())

rng = np.random.default_rng(1)
for name, curve, (a, b) in [("srgb", srgb, (0.01, 0.001)), ("webcam", filmic_contrast, (0.004, 0.0002))]:
    print(name, {k: round(table_entry(curve, a, b, k / 16, rng), 7) for k in (0, 2, 8, 14)})
