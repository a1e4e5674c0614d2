"""Reference numbers for the specular scenes of issue 17, from Mitsuba 3.

Builds the scenes of `specular/spot.toml` and `specular/area.toml` (a glass sphere and a mirror
on a diffuse floor, under a spot light and under an area light) in Mitsuba 3 from those very
files, renders each with independent seeds, and writes the mean radiance and its standard error
over the seeds in every region of `REGIONS` into `mitsuba_specular.json`, which
`renderer/tests/specular.rs` compares with mrstudy's path tracer (it needs no Mitsuba).

Which Mitsuba integrator is the truth where: under the area light, `path` (unidirectional with
next-event estimation) reaches every path, caustics included (a camera path hits the light after
a specular bounce). Under the spot light, `path` cannot reach caustics (light → glass or mirror →
floor: a delta light is never hit), and `ptracer` (light tracing) cannot see anything through
the glass or in the mirror (a camera connection through a delta surface); so floor regions are
compared with `ptracer` and the regions seen through the sphere or in the mirror with `path`.
Both miss a caustic seen through glass or in a mirror, as mrstudy does.

Run (about two minutes on 2 cores):
    python3 -m venv /tmp/mi && /tmp/mi/bin/pip install mitsuba==3.9.1 numpy
    /tmp/mi/bin/python renderer/tests/reference/mitsuba_specular.py [--preview DIR]
"""

import argparse
import json
import math
import pathlib
import tomllib

import mitsuba as mi
import numpy as np

# another script may have chosen a variant before importing this one's scene builder
if mi.variant() is None:
    mi.set_variant("scalar_rgb")
T = mi.ScalarTransform4f

HERE = pathlib.Path(__file__).resolve().parent
SEEDS = 16
SPP = 1024

# Pixel boxes [x0, y0, x1, y1) in the scenes' 96 × 72 images, and which Mitsuba integrator is
# the truth there under a spot light (under the area light `path` is the truth everywhere).
REGIONS = {
    "sphere-caustic": ([53, 52, 59, 57], "ptracer"),
    "caustic-disc": ([36, 62, 46, 70], "ptracer"),
    "mirror-lit-floor": ([10, 58, 22, 68], "ptracer"),
    "direct-lit-floor": ([40, 40, 48, 46], "ptracer"),
    "unlit-floor": ([80, 36, 92, 44], "ptracer"),
    "through-the-sphere": ([55, 29, 67, 35], "path"),
}


def rgb(value):
    if isinstance(value, (int, float)):
        return [float(value)] * 3
    return [float(v) for v in value]


def euler(rotate_deg):
    x, y, z = rotate_deg
    return T().rotate([0, 0, 1], z) @ T().rotate([0, 1, 0], y) @ T().rotate([1, 0, 0], x)


def bsdf(material):
    kind = material.get("kind", "glossy")
    if kind == "glossy":
        unsupported = set(material) - {"albedo", "kind"}
        assert not unsupported, f"the comparison builds diffuse materials only: {unsupported}"
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb(material.get("albedo", 0.8))}}
    if kind == "mirror":
        return {
            "type": "conductor",
            "material": "none",
            "specular_reflectance": {"type": "rgb", "value": rgb(material.get("reflectance", 1.0))},
        }
    if kind == "glass":
        assert "transmittance" not in material, "the comparison builds clear glass only"
        return {"type": "dielectric", "int_ior": material.get("ior", 1.5), "ext_ior": 1.0}
    raise ValueError(kind)


def up_for(direction):
    return [0, 0, 1] if abs(direction[1]) > 0.99 * np.linalg.norm(direction) else [0, 1, 0]


def build(scene, integrator, spp, seed):
    camera = scene["camera"]
    mitsuba = {
        "type": "scene",
        "integrator": {"type": integrator, "max_depth": -1, "rr_depth": 4},
        "sensor": {
            "type": "perspective",
            "fov": camera["fov_y_deg"],
            "fov_axis": "y",
            "to_world": T().look_at(origin=camera["position"], target=camera["look_at"], up=camera.get("up", [0, 1, 0])),
            "film": {
                "type": "hdrfilm",
                "width": camera["width"],
                "height": camera["height"],
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        },
    }
    materials = scene["materials"]
    for object in scene["objects"]:
        material = bsdf(materials[object["material"]])
        translate = object.get("translate", [0, 0, 0])
        rotation = euler(object.get("rotate_deg", [0, 0, 0]))
        if object["shape"] == "sphere":
            assert "rotate_deg" not in object and "scale" not in object
            shape = {"type": "sphere", "center": translate, "radius": object["radius"], "bsdf": material}
        elif object["shape"] in ("quad", "plane"):
            sx, sz = object["size"]
            # mrstudy's quad lies in x–z facing +Y; Mitsuba's rectangle in x–y facing +Z
            to_world = T().translate(translate) @ rotation @ T().rotate([1, 0, 0], -90) @ T().scale([sx / 2, sz / 2, 1])
            shape = {"type": "rectangle", "to_world": to_world, "bsdf": material}
        else:
            raise ValueError(object["shape"])
        mitsuba[object["name"]] = shape
    for light in scene["lights"]:
        position, target = light["position"], light["target"]
        frame = T().look_at(origin=position, target=target, up=up_for(np.subtract(target, position)))
        value = [c * light["intensity"] for c in rgb(light.get("color", 1.0))]
        if light["kind"] == "spot":
            inner, outer = light.get("inner_deg", 20.0), light.get("outer_deg", 30.0)
            # mrstudy's falloff is smooth in cos θ, Mitsuba's linear in θ: the scenes use a
            # hard cone (inner = outer), which both draw the same
            assert inner == outer, "the comparison uses hard spot cones"
            mitsuba[light["name"]] = {
                "type": "spot",
                "to_world": frame,
                "intensity": {"type": "rgb", "value": value},
                "cutoff_angle": outer,
                "beam_width": outer - 1e-3,
            }
        elif light["kind"] == "area":
            w, h = light["size"]
            mitsuba[light["name"]] = {
                "type": "rectangle",
                "to_world": frame @ T().scale([w / 2, h / 2, 1]),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": value}},
            }
        else:
            raise ValueError(light["kind"])
    return mitsuba


def region_mean(image, box):
    x0, y0, x1, y1 = box
    return float(image[y0:y1, x0:x1, :3].mean())


def render(scene, integrator):
    images = []
    for seed in range(SEEDS):
        # mi.render's own seed (default 0) overrides the sampler's: pass it here
        images.append(np.array(mi.render(mi.load_dict(build(scene, integrator, SPP, seed)), seed=seed)))
    return images


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--preview", type=pathlib.Path, help="write the mean images as PNG here")
    args = parser.parse_args()
    result = {
        "mitsuba": mi.__version__,
        "variant": mi.variant(),
        "seeds": SEEDS,
        "spp": SPP,
        "regions": {name: box for name, (box, _) in REGIONS.items()},
        "scenes": {},
    }
    for name in ("spot", "area"):
        scene = tomllib.loads((HERE / "specular" / f"{name}.toml").read_text())
        integrators = {"path"} if name == "area" else {"path", "ptracer"}
        rendered = {integrator: render(scene, integrator) for integrator in sorted(integrators)}
        regions = {}
        for region, (box, truth) in REGIONS.items():
            integrator = truth if name == "spot" else "path"
            means = [region_mean(image, box) for image in rendered[integrator]]
            regions[region] = {
                "integrator": integrator,
                "mean": float(np.mean(means)),
                "standard_error": float(np.std(means, ddof=1) / math.sqrt(len(means))),
            }
            print(f"{name:5} {region:20} {integrator:8} {regions[region]['mean']:.5f} ± {regions[region]['standard_error']:.5f}")
        result["scenes"][name] = regions
        if args.preview:
            args.preview.mkdir(parents=True, exist_ok=True)
            for integrator, images in rendered.items():
                mean = np.mean(images, axis=0)
                np.save(args.preview / f"{name}-{integrator}.npy", mean)
    (HERE / "mitsuba_specular.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
