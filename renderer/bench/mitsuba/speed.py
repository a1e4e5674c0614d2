"""The path tracer's speed beside Mitsuba 3 (issue 17, Deliver 6), measured in one run.

Renders the shared Cornell box `cornell.toml` (diffuse, one area light) with mrstudy's
reference path tracer (`mrstudy render --photo --camera clean`, one pass, the binary at
target/release/mrstudy) and with Mitsuba 3's `path` integrator in the `llvm_ad_rgb` variant
(the fastest CPU variant; its JIT compilation is done by a first render and not timed) and in
`scalar_rgb`, at the same size and samples per pixel, max depth unlimited, Russian roulette
from depth 4 for both. Reports camera paths per CPU-second (user + system time of the process
and its threads) and per wall-second, the ratio mrstudy / Mitsuba, and the mean pixel value
of each image (the same scene must give the same mean within noise), into `speed.json`.

    cargo build --release && python3 -m venv /tmp/mi && /tmp/mi/bin/pip install mitsuba==3.9.1 numpy
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \
      /tmp/mi/bin/python renderer/bench/mitsuba/speed.py [--spp 64] [--repeats 3]

Dr.Jit's LLVM backend needs a newer LLVM than Debian 12's default 14/15 (their instruction
selection fails on `fminimum`): `apt-get install libllvm19` and point DRJIT_LIBLLVM_PATH at it.
"""

import argparse
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time
import tomllib

import mitsuba as mi

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[2]


def cpu_seconds(who):
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def mrstudy(spp, out):
    before = cpu_seconds(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(
        [str(ROOT / "target/release/mrstudy"), "render", "--scene", str(HERE / "cornell.toml"), "--photo",
         "--camera", "clean", "--spp", str(spp), "--out", str(out)],
        check=True, capture_output=True,
    )
    return time.perf_counter() - start, cpu_seconds(resource.RUSAGE_CHILDREN) - before


def mitsuba(variant, scene, spp):
    mi.set_variant(variant)
    sys.path.insert(0, str(ROOT / "renderer/tests/reference"))
    import importlib
    import mitsuba_specular
    importlib.reload(mitsuba_specular)
    description = mitsuba_specular.build(scene, "path", spp, 0)
    loaded = mi.load_dict(description)
    image = mi.render(loaded, seed=1)  # the JIT's compilation, not timed
    mi.Bitmap(image)
    before = cpu_seconds(resource.RUSAGE_SELF)
    start = time.perf_counter()
    image = mi.render(loaded, seed=2)
    bitmap = mi.Bitmap(image)  # forces the evaluation
    wall, cpu = time.perf_counter() - start, cpu_seconds(resource.RUSAGE_SELF) - before
    import numpy as np
    return wall, cpu, float(np.array(bitmap)[:, :, :3].mean())


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    scene = tomllib.loads((HERE / "cornell.toml").read_text())
    paths = scene["camera"]["width"] * scene["camera"]["height"] * args.spp
    rows = []
    with tempfile.TemporaryDirectory() as work:
        out = pathlib.Path(work) / "cornell.exr"
        for _ in range(args.repeats):
            wall, cpu = mrstudy(args.spp, out)
            mi.set_variant("scalar_rgb")
            mean = float(__import__("numpy").array(mi.Bitmap(str(out)))[:, :, :3].mean())
            rows.append({"renderer": "mrstudy", "wall_s": wall, "cpu_s": cpu, "mean": mean})
            for variant in ("llvm_ad_rgb", "scalar_rgb"):
                wall, cpu, mean = mitsuba(variant, scene, args.spp)
                rows.append({"renderer": f"mitsuba {variant}", "wall_s": wall, "cpu_s": cpu, "mean": mean})
    summary = {}
    for name in sorted({row["renderer"] for row in rows}):
        mine = [row for row in rows if row["renderer"] == name]
        best_cpu = min(row["cpu_s"] for row in mine)
        best_wall = min(row["wall_s"] for row in mine)
        summary[name] = {
            "paths_per_cpu_second": paths / best_cpu,
            "paths_per_wall_second": paths / best_wall,
            "mean": sum(row["mean"] for row in mine) / len(mine),
        }
    ours = summary["mrstudy"]["paths_per_cpu_second"]
    for name, row in summary.items():
        row["mrstudy_over_this"] = ours / row["paths_per_cpu_second"]
        print(f"{name:22} {row['paths_per_cpu_second'] / 1e6:6.3f} M paths/CPU-s  "
              f"{row['paths_per_wall_second'] / 1e6:6.3f} M paths/wall-s  mean {row['mean']:.4f}  "
              f"mrstudy/this {row['mrstudy_over_this']:.2f}")
    result = {
        "mitsuba": mi.__version__,
        "scene": "renderer/bench/mitsuba/cornell.toml",
        "spp": args.spp,
        "paths": paths,
        "cores": os.cpu_count(),
        "fastest_of": args.repeats,
        "summary": summary,
        "runs": rows,
    }
    (HERE / "speed.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
