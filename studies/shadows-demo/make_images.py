"""Makes the stimulus images of studies/shadows-demo.toml (run from the repository root:
`python3 studies/shadows-demo/make_images.py`; needs only numpy).

A small ray caster, not mrstudy's renderer: a wooden-toned table before a white wall with a
"real" box and a "virtual" sphere, seen from three camera positions (the scene
configurations). The "real" parts carry photo-like sensor noise and a slight blur; the virtual
sphere is composited on top under four conditions:
  shadow  the sphere casts a soft shadow onto the table (off: no shadow);
  ca      camera artifacts: the sphere gets the same blur and noise as the "photograph".
Catch images: the best composite (`catch-good.png`) against one with the sphere drawn as a
flat, unshaded magenta disc floating in the air (`catch-bad.png`).
The images are deterministic (fixed seeds); they are committed, so this script only documents
how they were made.
"""
import struct, zlib, pathlib
import numpy as np

W, H = 400, 300
OUT = pathlib.Path(__file__).parent

def write_png(path, rgb):
    rgb = np.clip(rgb * 255 + 0.5, 0, 255).astype(np.uint8)
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(rgb.shape[0]))
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", rgb.shape[1], rgb.shape[0], 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    path.write_bytes(png)

def normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)

def box_blur(img, r=1):
    out = np.zeros_like(img)
    pad = np.pad(img, ((r, r), (r, r), (0, 0)), mode="edge")
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out += pad[r + dy:r + dy + img.shape[0], r + dx:r + dx + img.shape[1]]
    return out / (2 * r + 1) ** 2

LIGHT = np.array([-0.6, 1.6, 0.8])
BOX_MIN, BOX_MAX = np.array([0.12, 0.0, -0.22]), np.array([0.32, 0.2, -0.02])

def render(eye, sphere_c, sphere_r, shadow, ca, seed, broken=False):
    rng = np.random.default_rng(seed)
    target = np.array([0.0, 0.08, -0.05])
    fwd = normalize(target - eye); right = normalize(np.cross(fwd, [0, 1, 0])); up = np.cross(right, fwd)
    ys, xs = np.mgrid[0:H, 0:W]
    u = (xs + 0.5) / W * 2 - 1; v = 1 - (ys + 0.5) / H * 2
    d = normalize(fwd + u[..., None] * 0.55 * right + v[..., None] * 0.55 * H / W * up)
    o = np.broadcast_to(eye, d.shape)
    inf = np.full((H, W), np.inf)
    # table plane y = 0 (|x|,|z| < 0.6), wall z = -0.6
    t_table = np.where(d[..., 1] < 0, -o[..., 1] / np.where(d[..., 1] == 0, 1, d[..., 1]), inf)
    p = o + t_table[..., None] * d
    t_table = np.where((np.abs(p[..., 0]) < 0.6) & (p[..., 2] > -0.6) & (p[..., 2] < 0.6), t_table, inf)
    t_wall = np.where(d[..., 2] < 0, (-0.6 - o[..., 2]) / np.where(d[..., 2] == 0, 1, d[..., 2]), inf)
    # real box (slab test)
    inv = 1 / np.where(d == 0, 1e-9, d)
    t0 = (BOX_MIN - o) * inv; t1 = (BOX_MAX - o) * inv
    tn = np.minimum(t0, t1).max(-1); tf = np.maximum(t0, t1).min(-1)
    t_box = np.where((tf >= tn) & (tn > 0), tn, inf)
    t_real = np.minimum(np.minimum(t_table, t_wall), t_box)
    p = o + t_real[..., None] * d
    n = np.zeros_like(p); albedo = np.zeros_like(p)
    wall = t_real == t_wall; table = t_real == t_table; box = t_real == t_box
    n[wall] = [0, 0, 1]; albedo[wall] = [0.85, 0.85, 0.82]
    n[table] = [0, 1, 0]
    grain = 0.5 + 0.5 * np.sin(p[..., 0] * 90 + np.sin(p[..., 2] * 40) * 2)
    albedo[table] = (np.array([0.55, 0.36, 0.2]) * (0.8 + 0.2 * grain[..., None]))[table]
    pb = p[box]; c = (BOX_MIN + BOX_MAX) / 2; q = (pb - c) / ((BOX_MAX - BOX_MIN) / 2)
    axis = np.abs(q).argmax(-1); nb = np.zeros_like(pb); nb[np.arange(len(pb)), axis] = np.sign(q[np.arange(len(pb)), axis])
    n[box] = nb; albedo[box] = [0.25, 0.45, 0.7]
    # real shadow of the box onto table and wall (the "photograph" has it)
    def shade(points, normals, occluders):
        l = LIGHT - points; dist = np.linalg.norm(l, axis=-1); l = l / dist[..., None]
        lam = np.clip((normals * l).sum(-1), 0, 1)
        vis = np.ones(points.shape[:-1])
        for occ in occluders:
            vis = vis * occ(points, l, dist)
        return 0.25 + 0.9 * lam * vis
    def box_occ(points, l, dist):
        inv = 1 / np.where(l == 0, 1e-9, l)
        a = (BOX_MIN - points) * inv; b = (BOX_MAX - points) * inv
        n_ = np.minimum(a, b).max(-1); f_ = np.maximum(a, b).min(-1)
        return np.where((f_ >= n_) & (n_ > 1e-4) & (n_ < dist), 0.0, 1.0)
    def sphere_occ(points, l, dist):
        # soft shadow: visibility by the closest approach of the light ray to the sphere
        oc = sphere_c - points; tc = (oc * l).sum(-1)
        closest = np.linalg.norm(oc - tc[..., None] * l, axis=-1)
        soft = np.clip((closest - sphere_r * 0.75) / (sphere_r * 0.6), 0, 1)
        return np.where(tc > 0, 0.35 + 0.65 * soft, 1.0)
    occluders = [box_occ] + ([sphere_occ] if shadow else [])
    img = albedo * shade(p + n * 1e-4, n, occluders)[..., None]
    img[np.isinf(t_real)] = [0.9, 0.9, 0.88]
    # the "photograph": blur and sensor noise
    img = box_blur(img, 1) + rng.normal(0, 0.02, img.shape[:2])[..., None]
    # virtual sphere
    oc = o - sphere_c; b = (oc * d).sum(-1); cc = (oc * oc).sum(-1) - sphere_r ** 2
    disc = b * b - cc; t_s = np.where(disc > 0, -b - np.sqrt(np.maximum(disc, 0)), inf)
    hit = (t_s > 0) & (t_s < t_real)
    ps = o + t_s[..., None] * d; ns = normalize(ps - sphere_c)
    l = normalize(LIGHT - ps); lam = np.clip((ns * l).sum(-1), 0, 1)
    spec = np.clip((normalize(l - d) * ns).sum(-1), 0, 1) ** 40
    sphere = np.array([0.8, 0.62, 0.1]) * (0.25 + 0.9 * lam)[..., None] + 0.5 * spec[..., None]
    if broken:
        sphere = np.broadcast_to(np.array([1.0, 0.0, 1.0]), sphere.shape)
    layer = img.copy(); layer[hit] = sphere[hit]
    mask = hit.astype(float)[..., None]
    if ca:
        layer = box_blur(layer, 1) + rng.normal(0, 0.02, img.shape[:2])[..., None]
        mask = box_blur(mask, 1)
    return np.clip(img * (1 - mask) + layer * mask, 0, 1)

CONFIGS = {  # scene configuration: camera position, sphere centre and radius
    "view-left": (np.array([-0.35, 0.38, 0.42]), np.array([-0.12, 0.07, 0.05]), 0.07),
    "view-centre": (np.array([0.0, 0.42, 0.5]), np.array([-0.05, 0.06, 0.12]), 0.06),
    "view-right": (np.array([0.38, 0.35, 0.4]), np.array([-0.15, 0.08, -0.1]), 0.08),
}
CONDITIONS = {"LQ": (False, False), "SH": (True, False), "CA": (False, True), "SH+CA": (True, True)}

for index, (name, (eye, centre, radius)) in enumerate(CONFIGS.items()):
    for condition, (shadow, ca) in CONDITIONS.items():
        write_png(OUT / f"{name}-{condition}.png", render(eye, centre, radius, shadow, ca, seed=index))
eye, centre, radius = CONFIGS["view-centre"]
write_png(OUT / "catch-good.png", render(eye, centre, radius, True, True, seed=7))
write_png(OUT / "catch-bad.png", render(eye, centre + np.array([0, 0.12, 0]), radius, False, False, seed=7, broken=True))
