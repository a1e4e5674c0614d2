#!/usr/bin/env python3
"""Reference values for renderer/src/cm/colour.rs (CIELab with illuminant E, CIEDE2000).

Run:  pip install colour-science==0.4.7 numpy && python3 cm_colour.py > cm_colour.json

* CIEDE2000: the 34 test pairs of Sharma, Wu & Dalal (2005), "The CIEDE2000 color-difference
  formula: implementation notes, supplementary test data, and mathematical observations",
  Color Res. Appl. 30(1), Table 1 (the published ΔE00 to 4 decimals, as reprinted in
  colour-science 0.4.7, colour/difference/tests/test_delta_e.py), plus colour-science's
  `delta_E(method="CIE 2000")` on the same pairs and on 200 seeded random pairs.
* Lab (illuminant E): linear sRGB primaries, XYZ scaled so that RGB white maps to XYZ white
  (1, 1, 1) (colour.RGB_to_XYZ with chromatic_adaptation_transform="XYZ Scaling" to E), then
  colour.XYZ_to_Lab with the E white point: the "white maps to white" conversion of the thesis.
"""
import json

import colour
import numpy as np

LAB1 = [[50.0, 2.6772, -79.7751], [50.0, 3.1571, -77.2803], [50.0, 2.8361, -74.02], [50.0, -1.3802, -84.2814],
        [50.0, -1.1848, -84.8006], [50.0, -0.9009, -85.5211], [50.0, 0.0, 0.0], [50.0, -1.0, 2.0],
        [50.0, 2.49, -0.001], [50.0, 2.49, -0.001], [50.0, 2.49, -0.001], [50.0, 2.49, -0.001],
        [50.0, -0.001, 2.49], [50.0, -0.001, 2.49], [50.0, -0.001, 2.49], [50.0, 2.5, 0.0],
        [50.0, 2.5, 0.0], [50.0, 2.5, 0.0], [50.0, 2.5, 0.0], [50.0, 2.5, 0.0], [50.0, 2.5, 0.0],
        [50.0, 2.5, 0.0], [50.0, 2.5, 0.0], [50.0, 2.5, 0.0], [60.2574, -34.0099, 36.2677],
        [63.0109, -31.0961, -5.8663], [61.2901, 3.7196, -5.3901], [35.0831, -44.1164, 3.7933],
        [22.7233, 20.0904, -46.694], [36.4612, 47.858, 18.3852], [90.8027, -2.0831, 1.441],
        [90.9257, -0.5406, -0.9208], [6.7747, -0.2908, -2.4247], [2.0776, 0.0795, -1.135]]
LAB2 = [[50.0, 0.0, -82.7485], [50.0, 0.0, -82.7485], [50.0, 0.0, -82.7485], [50.0, 0.0, -82.7485],
        [50.0, 0.0, -82.7485], [50.0, 0.0, -82.7485], [50.0, -1.0, 2.0], [50.0, 0.0, 0.0],
        [50.0, -2.49, 0.0009], [50.0, -2.49, 0.001], [50.0, -2.49, 0.0011], [50.0, -2.49, 0.0012],
        [50.0, 0.0009, -2.49], [50.0, 0.001, -2.49], [50.0, 0.0011, -2.49], [50.0, 0.0, -2.5],
        [73.0, 25.0, -18.0], [61.0, -5.0, 29.0], [56.0, -27.0, -3.0], [58.0, 24.0, 15.0],
        [50.0, 3.1736, 0.5854], [50.0, 3.2972, 0.0], [50.0, 1.8634, 0.5757], [50.0, 3.2592, 0.335],
        [60.4626, -34.1751, 39.4387], [62.8187, -29.7946, -4.0864], [61.4292, 2.248, -4.962],
        [35.0232, -40.0716, 1.5901], [23.0331, 14.973, -42.5619], [36.2715, 50.5065, 21.2231],
        [91.1528, -1.6435, 0.0447], [88.6381, -0.8985, -0.7239], [5.8714, -0.0985, -2.2286],
        [0.9033, -0.0636, -0.5514]]
PUBLISHED = [2.0425, 2.8615, 3.4412, 1.0, 1.0, 1.0, 2.3669, 2.3669, 7.1792, 7.1792, 7.2195, 7.2195,
             4.8045, 4.8045, 4.7461, 4.3065, 27.1492, 22.8977, 31.903, 19.4535, 1.0, 1.0, 1.0, 1.0,
             1.2644, 1.263, 1.8731, 1.8645, 2.0373, 1.4146, 1.4441, 1.5381, 0.6377, 0.9082]


def main():
    rng = np.random.default_rng(20050101)
    l1 = np.array(LAB1)
    l2 = np.array(LAB2)
    sharma = colour.delta_E(l1, l2, method="CIE 2000")
    r1 = np.column_stack([rng.uniform(0, 100, 200), rng.uniform(-100, 100, 200), rng.uniform(-100, 100, 200)])
    r2 = r1 + rng.normal(0, 8, (200, 3))
    r2[:, 0] = np.clip(r2[:, 0], 0, 100)
    random = colour.delta_E(r1, r2, method="CIE 2000")

    E = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["E"]
    rgb = np.vstack([np.eye(3), [[1, 1, 1], [0.5, 0.5, 0.5], [0.0, 0.0, 0.0], [2.5, 1.0, 0.2], [0.18, 0.3, 0.05]],
                     rng.uniform(0, 1, (20, 3))])
    srgb = colour.RGB_COLOURSPACES["sRGB"]
    xyz = colour.RGB_to_XYZ(rgb, srgb, illuminant=E, chromatic_adaptation_transform="XYZ Scaling", apply_cctf_decoding=False)
    lab = colour.XYZ_to_Lab(xyz, illuminant=E)
    out = {
        "source": "colour-science %s; Sharma, Wu & Dalal (2005) Table 1" % colour.__version__,
        "sharma": [{"lab1": a, "lab2": b, "published": p, "colour_science": float(d)} for a, b, p, d in zip(LAB1, LAB2, PUBLISHED, sharma)],
        "random": [{"lab1": a.tolist(), "lab2": b.tolist(), "colour_science": float(d)} for a, b, d in zip(r1, r2, random)],
        "linear_rgb_to_lab_e": [{"rgb": a.tolist(), "xyz": x.tolist(), "lab": l.tolist()} for a, x, l in zip(rgb, xyz, lab)],
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
