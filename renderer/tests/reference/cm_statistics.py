#!/usr/bin/env python3
"""Reference values for the statistics-based colour mapping (renderer/src/cm/statistics.rs,
thesis 4.5.3, eqs. 4.30-4.38), computed independently of the renderer from a render's buffers,
and the numbers of the dir-lamp-box diagnosis in docs/renderer.md.

Tools: Python 3.11, numpy 2.4.6, colour-science 0.4.7 (CIELab with illuminant E: linear sRGB
primaries, "XYZ Scaling" to E, XYZ_to_Lab with E's white), OpenEXR 3.3.2 (reads l_r.exr and
l_rv.exr), Pillow (reads the PNGs).

Run (the buffers come from the GPU render of a condition with cm; the fixture is gi+cm's, whose
L_rv differs from L_r on real pixels too; the cm condition's numbers are quoted in the docs):

    mrstudy render --scene dir-lamp-box --factors gi,cm --size 256x192 --spp 32 \
        --out /tmp/gi+cm.png --buffers /tmp/buf_gi+cm
    pip install numpy==2.4.6 colour-science==0.4.7 OpenEXR==3.3.2 pillow
    python3 cm_statistics.py /tmp/buf_gi+cm > cm_statistics.json

It prints (1) `full`: over every usable pixel of the render (real, L_r not black, camera below
250/255), the Lab (E) means and population standard deviations of TM(L_r) = L_r/(1+L_r) and of
the sRGB-decoded camera image, the ratios sigma_cam/sigma_r of eqs. 4.36-4.38, the camera's
standard deviation split into 5x5 box means and the residual (noise), the ratios the thesis's
unmasked target (the whole camera image, eq. 4.31) would give, and the report's mapping for
comparison; (2) `subsample`: every 12th pixel of the buffers in each direction (22x16 at
256x192) with flags (2 virtual, 1 real, 0 nothing modelled), the expected mapping and the
expected tau(L_rv), tau(L_r) and additive composite per pixel. The Rust test
`cm::tests::statistics_matches_an_independent_computation_on_dir_lamp_box` runs the CPU
reference on the subsample and compares.
"""
import json
import sys

import colour
import numpy as np
import OpenEXR
from PIL import Image

E = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["E"]
SRGB = colour.RGB_COLOURSPACES["sRGB"]
SATURATED = 250.0 / 255.0
STEP = 12


def lab(rgb):
    xyz = colour.RGB_to_XYZ(rgb, SRGB, illuminant=E, chromatic_adaptation_transform="XYZ Scaling")
    return colour.XYZ_to_Lab(xyz, E)


def lab_inv(lab_values):
    xyz = colour.Lab_to_XYZ(lab_values, E)
    return colour.XYZ_to_RGB(xyz, SRGB, illuminant=E, chromatic_adaptation_transform="XYZ Scaling")


def encode(x):
    return colour.models.eotf_inverse_sRGB(np.clip(x, 0.0, 1.0))


def decode(x):
    return colour.models.eotf_sRGB(np.clip(x, 0.0, 1.0))


def tone_map(x):
    x = np.maximum(x, 0.0)
    return x / (1.0 + x)


def luminance(x):
    return x @ np.array([0.2126, 0.7152, 0.0722])


def exr(path):
    return OpenEXR.File(path).channels()["RGB"].pixels.astype(np.float32)


def statistics(src, tgt):
    """Means, population standard deviations and ratios (ratio 1 where sigma_r < 1e-3)."""
    ms, ss, mt, st = src.mean(0), src.std(0), tgt.mean(0), tgt.std(0)
    ratio = np.where(ss < 1e-3, 1.0, st / np.where(ss < 1e-3, 1.0, ss))
    return ms, ss, mt, st, ratio


def r3(v):
    return [round(float(x), 4) for x in v]


def main(d):
    l_r, l_rv = exr(d + "/l_r.exr"), exr(d + "/l_rv.exr")
    photo_u8 = np.asarray(Image.open(d + "/photo.png").convert("RGB"))
    photo = photo_u8.astype(np.float64) / 255.0
    virtual = np.asarray(Image.open(d + "/virtual_mask.png").convert("L")) > 127
    report = json.load(open(d + "/report.json"))["gpu"]["cm"]
    lr64 = l_r.astype(np.float64)
    use = (~virtual) & (luminance(lr64) > 1e-6) & (photo.max(axis=2) < SATURATED)
    src, tgt = lab(tone_map(lr64[use])), lab(decode(photo[use]))
    ms, ss, mt, st, ratio = statistics(src, tgt)
    cam = lab(decode(photo))
    pad = np.pad(cam, ((2, 2), (2, 2), (0, 0)), mode="edge")
    box = np.lib.stride_tricks.sliding_window_view(pad, (5, 5), axis=(0, 1)).mean(axis=(-1, -2))
    whole = cam.reshape(-1, 3)
    full = {
        "size": [int(photo.shape[1]), int(photo.shape[0])],
        "pixels_used": int(use.sum()),
        "mean_source": r3(ms),
        "sd_source": r3(ss),
        "mean_target": r3(mt),
        "sd_target": r3(st),
        "ratio": r3(ratio),
        "sd_target_of_5x5_means": r3(box[use].std(0)),
        "sd_target_residual_of_5x5_means": r3((cam - box)[use].std(0)),
        "ratio_with_the_whole_camera_image_as_target": r3(whole.std(0) / ss),
        "report_mapping": report["mapping"],
    }

    # the subsample the Rust test reads
    sl = (slice(None, None, STEP), slice(None, None, STEP))
    # radiances rounded to 6 significant digits (as f32, what the Rust test parses)
    def rounded(x):
        return np.array([float(f"{c:.6g}") for c in x[sl].reshape(-1)], dtype=np.float32).reshape(x[sl].shape)

    s_lr, s_lrv = rounded(l_r), rounded(l_rv)
    s_photo_u8, s_virtual = photo_u8[sl], virtual[sl]
    h, w = s_virtual.shape
    s_lr64, s_lrv64 = s_lr.astype(np.float64), s_lrv.astype(np.float64)
    s_photo = s_photo_u8.astype(np.float64) / 255.0
    modelled = (luminance(s_lr64) > 1e-6) | (luminance(s_lrv64) > 1e-6)
    flags = np.where(s_virtual, 2, np.where(modelled, 1, 0))
    s_use = (flags == 1) & (luminance(s_lr64) > 1e-6) & (s_photo.max(axis=2) < SATURATED)
    ms, ss, mt, st, ratio = statistics(lab(tone_map(s_lr64[s_use])), lab(decode(s_photo[s_use])))

    def tau(x):
        return encode(np.maximum(lab_inv((lab(tone_map(x)) - ms) * ratio + mt), 0.0))

    m_rv, m_r = tau(s_lrv64), tau(s_lr64)
    composite = np.where(
        (flags == 0)[..., None] | ((flags == 1)[..., None] & np.all(m_rv == m_r, axis=-1, keepdims=True)),
        s_photo,
        np.clip(np.where((flags == 1)[..., None], s_photo, 0.0) + m_rv - np.where((flags == 1)[..., None], m_r, 0.0), 0, 1),
    )
    subsample = {
        "width": w,
        "height": h,
        "step": STEP,
        "flags": flags.reshape(-1).tolist(),
        "l_r": [[float(f"{c:.6g}") for c in p] for p in s_lr.reshape(-1, 3)],
        "l_rv": [[float(f"{c:.6g}") for c in p] for p in s_lrv.reshape(-1, 3)],
        "photo_u8": s_photo_u8.reshape(-1, 3).tolist(),
        "pixels_used": int(s_use.sum()),
        "mean_source": ms.tolist(),
        "mean_target": mt.tolist(),
        "ratio": ratio.tolist(),
        "mapped_rv": np.round(m_rv.reshape(-1, 3), 5).tolist(),
        "mapped_r": np.round(m_r.reshape(-1, 3), 5).tolist(),
        "composite": np.round(composite.reshape(-1, 3), 5).tolist(),
    }
    out = {
        "tools": {"numpy": np.__version__, "colour-science": colour.__version__, "OpenEXR": OpenEXR.__version__},
        "command": sys.argv[2] if len(sys.argv) > 2 else "(not given)",
        "full": full,
        "subsample": subsample,
    }
    json.dump(out, sys.stdout, separators=(",", ":"))
    sys.stdout.write("\n")


if __name__ == "__main__":
    main(sys.argv[1])
