// Rohmer et al.'s frame on the GPU (renderer/src/gpu/coherent.rs): the queries of a coherent
// frame (EM lookup, DIT trace, VCT cone, the object's solid volume) answered one invocation per
// query (`cs_queries`), then each pixel's terms combined into the object's radiance, eq. 5's
// albedo, the differential background of eqs. 8-9 and the composite (`cs_combine`), following
// coherent/query.rs, impostor.rs, voxel.rs, solid.rs and mod.rs step by step.
//
// llvmpipe stops an invocation's loops after about 2^14 iterations in all: one invocation answers
// one query (a cone of a 128^3 volume marches at most about 450 steps, a DIT trace 30), the
// trilinear lookups are written out corner by corner, and a pixel's combination walks its terms
// (about a hundred on med) once.

// what the CPU's infinities become here: the comparisons the frame makes with them come out the same
const FAR: f32 = 3.0e38;
const PI: f32 = 3.14159265358979;
const NONE: u32 = 0xffffffffu;

// query kinds
const SKY: u32 = 0u;
const LOOKUP: u32 = 1u;
const TRACE: u32 = 2u;
const CONE: u32 = 3u;
const CONE_TO: u32 = 4u;

struct Query {
    // origin (xyz) and the cone's half-angle (w)
    origin: vec4<f32>,
    // unit direction (xyz) and, for CONE_TO, the distance the cone ends at (w)
    dir: vec4<f32>,
    // the object surface's geometric normal (xyz) for the self-shadow test; w: bits of
    // kind | impostor << 8 | self-shadow test << 16
    normal: vec4<f32>,
}

struct Impostor {
    // centre (xyz), the farthest stored distance (w)
    centre: vec4<f32>,
    // texels per face, first texel in `impostor`
    texels: vec4<u32>,
}

struct Solid {
    // corner of voxel (0, 0, 0) (xyz)
    origin: vec4<f32>,
    // voxel edges (xyz)
    voxel: vec4<f32>,
    // voxels per axis (xyz), first voxel in `tau` (w)
    dims: vec4<u32>,
}

struct Params {
    // x: queries, y: impostors, z: solids, w: voxel levels (0: no volume)
    counts: vec4<u32>,
    // voxel volume: corner of voxel (0, 0, 0) (xyz), level-0 edge (w)
    volume: vec4<f32>,
    // x, y: the light probe's width and height (0: none), z: its rotation (bits), w: bits of pi / m
    sky: vec4<u32>,
    // x: pixels, y: first query of this dispatch, z: voxels per axis of level 0
    frame: vec4<u32>,
    impostors: array<Impostor, 8>,
    solids: array<Solid, 8>,
    // per voxel level: voxels per axis (x), first voxel (y)
    levels: array<vec4<u32>, 16>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> queries: array<Query>;
// per query: radiance (xyz) and distance (w); CONE_TO: the opacity before its end (x)
@group(0) @binding(2) var<storage, read_write> results: array<vec4<f32>>;
// every impostor's texels: radiance (xyz) and distance from the centre (w; negative: empty)
@group(0) @binding(3) var<storage, read> impostor: array<vec4<f32>>;
// every level of the scene voxel volume: premultiplied radiance (xyz) and opacity (w)
@group(0) @binding(4) var<storage, read> voxels: array<vec4<f32>>;
// every solid volume's tau at level 0, x fastest
@group(0) @binding(5) var<storage, read> tau: array<f32>;
// the light probe's texels, rows top down
@group(0) @binding(6) var<storage, read> sky: array<vec4<f32>>;

fn sky_radiance(d: vec3<f32>) -> vec3<f32> {
    let w = params.sky.x;
    let h = params.sky.y;
    if w == 0u {
        return vec3<f32>(0.0);
    }
    let theta = acos(clamp(d.y, -1.0, 1.0));
    let phi = atan2(d.x, -d.z);
    let x = (phi + PI) / (2.0 * PI) + bitcast<f32>(params.sky.z);
    let u = x - floor(x);
    let v = theta / PI;
    let i = min(u32(max(u * f32(w), 0.0)), w - 1u);
    let j = min(u32(max(v * f32(h), 0.0)), h - 1u);
    return sky[j * w + i].xyz;
}

// ---- the distance impostor (coherent/impostor.rs) ----

fn impostor_texel(k: u32, d: vec3<f32>) -> u32 {
    let a = abs(d);
    var face = 5u;
    var sc = -d.x;
    var tc = -d.y;
    var ma = a.z;
    if a.x >= a.y && a.x >= a.z {
        ma = a.x;
        tc = -d.y;
        if d.x > 0.0 {
            face = 0u;
            sc = -d.z;
        } else {
            face = 1u;
            sc = d.z;
        }
    } else if a.y >= a.z {
        ma = a.y;
        sc = d.x;
        if d.y > 0.0 {
            face = 2u;
            tc = d.z;
        } else {
            face = 3u;
            tc = -d.z;
        }
    } else if d.z > 0.0 {
        face = 4u;
        sc = d.x;
        tc = -d.y;
    }
    let u = 0.5 * (sc / ma + 1.0);
    let v = 0.5 * (tc / ma + 1.0);
    let size = params.impostors[k].texels.x;
    // a NaN coordinate reads texel 0, as the CPU's saturating cast does
    var x = 0u;
    var y = 0u;
    if u * f32(size) > 0.0 {
        x = min(u32(u * f32(size)), size - 1u);
    }
    if v * f32(size) > 0.0 {
        y = min(u32(v * f32(size)), size - 1u);
    }
    return params.impostors[k].texels.y + face * size * size + y * size + x;
}

// the texel the CPU reads for a NaN direction: face 5, texel (0, 0)
fn nan_texel(k: u32) -> u32 {
    let size = params.impostors[k].texels.x;
    return params.impostors[k].texels.y + 5u * size * size;
}

fn lookup(k: u32, origin: vec3<f32>, dir: vec3<f32>) -> vec4<f32> {
    let l = length(dir);
    var d = vec3<f32>(0.0);
    if l > 0.0 {
        d = dir / l;
    }
    let t = impostor[impostor_texel(k, d)];
    if t.w >= 0.0 {
        let point = params.impostors[k].centre.xyz + d * t.w;
        return vec4<f32>(t.xyz, length(point - origin));
    }
    return vec4<f32>(sky_radiance(dir), FAR);
}

// f(t) of the linear search: |x(t) - c| - stored distance (w: 1 when the texel holds a sample)
fn beyond(k: u32, origin: vec3<f32>, dir: vec3<f32>, t: f32) -> vec2<f32> {
    let d = origin + dir * t - params.impostors[k].centre.xyz;
    let l = impostor[impostor_texel(k, d)].w;
    if l < 0.0 {
        // the CPU's |x - c| - infinity
        return vec2<f32>(-FAR, 0.0);
    }
    return vec2<f32>(length(d) - l, 1.0);
}

fn trace(k: u32, origin: vec3<f32>, dir: vec3<f32>) -> vec4<f32> {
    let miss = vec4<f32>(sky_radiance(dir), FAR);
    let far = params.impostors[k].centre.w;
    if far <= 0.0 {
        return miss;
    }
    let centre = params.impostors[k].centre.xyz;
    let t_end = 2.0 * far + length(origin - centre);
    var t_prev = 0.0;
    // whether f_prev is the CPU's minus infinity (no sample in the origin's direction)
    var f_prev = beyond(k, origin, dir, 0.0);
    if f_prev.y > 0.0 && f_prev.x > 0.0 {
        return miss;
    }
    for (var s = 1u; s <= 24u; s++) {
        let x = f32(s) / 24.0;
        let t = t_end * (x * x);
        let ft = beyond(k, origin, dir, t);
        if ft.y > 0.0 && ft.x >= 0.0 {
            var a = t_prev;
            var fa = f_prev.x;
            var a_inf = f_prev.y == 0.0;
            var b = t;
            var fb = ft.x;
            // the CPU's b once a secant step from minus infinity made it NaN
            var b_nan = false;
            for (var r = 0u; r < 6u; r++) {
                var m_nan = b_nan || a_inf;
                var m = 0.0;
                if !m_nan {
                    if fb - fa != 0.0 {
                        m = a - fa * (b - a) / (fb - fa);
                    } else {
                        m = 0.5 * (a + b);
                    }
                    m = clamp(m, min(a, b), max(a, b));
                }
                var fm = vec2<f32>(0.0);
                if m_nan {
                    let l = impostor[nan_texel(k)].w;
                    fm = vec2<f32>(0.0, select(0.0, 1.0, l >= 0.0));
                } else {
                    fm = beyond(k, origin, dir, m);
                }
                if fm.y == 0.0 {
                    break;
                }
                if !m_nan && fm.x < 0.0 {
                    a = m;
                    fa = fm.x;
                    a_inf = false;
                } else {
                    // NaN compares false: the CPU moves b
                    b = m;
                    fb = fm.x;
                    b_nan = m_nan;
                }
            }
            if b_nan {
                return vec4<f32>(impostor[nan_texel(k)].xyz, FAR);
            }
            let p = origin + dir * b;
            let texel = impostor[impostor_texel(k, p - centre)];
            let point = centre + normalize(p - centre) * texel.w;
            return vec4<f32>(texel.xyz, length(point - origin));
        }
        if ft.y > 0.0 {
            t_prev = t;
            f_prev = ft;
        }
    }
    return miss;
}

// ---- the scene voxel volume (coherent/voxel.rs) ----

fn corner(level: u32, base: vec3<i32>, o: vec3<i32>, f: vec3<f32>) -> vec4<f32> {
    let res = i32(params.levels[level].x);
    let c = base + o;
    if any(c < vec3<i32>(0)) || any(c >= vec3<i32>(res)) {
        return vec4<f32>(0.0);
    }
    let w = select(1.0 - f.x, f.x, o.x == 1) * select(1.0 - f.y, f.y, o.y == 1) * select(1.0 - f.z, f.z, o.z == 1);
    let i = params.levels[level].y + u32((c.z * res + c.y) * res + c.x);
    return w * voxels[i];
}

fn sample_level(p: vec3<f32>, level: u32) -> vec4<f32> {
    let size = params.volume.w * f32(1u << level);
    let c = (p - params.volume.xyz) / size - 0.5;
    let base = floor(c);
    let f = c - base;
    let b = vec3<i32>(base);
    // the CPU's corner order (x fastest), one by one: no loop
    var out = corner(level, b, vec3<i32>(0, 0, 0), f);
    out += corner(level, b, vec3<i32>(1, 0, 0), f);
    out += corner(level, b, vec3<i32>(0, 1, 0), f);
    out += corner(level, b, vec3<i32>(1, 1, 0), f);
    out += corner(level, b, vec3<i32>(0, 0, 1), f);
    out += corner(level, b, vec3<i32>(1, 0, 1), f);
    out += corner(level, b, vec3<i32>(0, 1, 1), f);
    out += corner(level, b, vec3<i32>(1, 1, 1), f);
    return out;
}

fn sample_volume(p: vec3<f32>, level_in: f32) -> vec4<f32> {
    let top = f32(params.counts.w - 1u);
    let level = clamp(level_in, 0.0, top);
    let lo = u32(floor(level));
    let hi = min(lo + 1u, params.counts.w - 1u);
    let t = level - f32(lo);
    let a = sample_level(p, lo);
    if t == 0.0 || hi == lo {
        return a;
    }
    let b = sample_level(p, hi);
    return a + t * (b - a);
}

// (radiance, opacity) gathered and the distance the opacity passed one half (FAR: never)
struct Cone {
    radiance: vec3<f32>,
    opacity: f32,
    distance: f32,
}

fn cone_to(origin: vec3<f32>, dir: vec3<f32>, half_angle: f32, t_max: f32) -> Cone {
    var hit = Cone(vec3<f32>(0.0), 0.0, FAR);
    let tan_half = tan(clamp(half_angle, 1e-3, 1.4));
    let voxel = params.volume.w;
    let size = voxel * f32(params.frame.z);
    let lo = params.volume.xyz;
    let hi = lo + vec3<f32>(size);
    let inv = 1.0 / dir;
    let t0 = (lo - origin) * inv;
    let t1 = (hi - origin) * inv;
    let tx = max(t0, t1);
    let tn = min(t0, t1);
    let t_exit = min(min(min(tx.x, tx.y), tx.z), t_max);
    let t_enter = max(max(max(tn.x, tn.y), tn.z), 0.0);
    if !(t_exit > t_enter) {
        return hit;
    }
    var t = max(t_enter, voxel);
    while t < t_exit && hit.opacity < 0.95 {
        let diameter = max(2.0 * t * tan_half, voxel);
        let level = log2(diameter / voxel);
        let s = sample_volume(origin + dir * t, level);
        if s.w > 1e-6 {
            let a = 1.0 - sqrt(1.0 - min(s.w, 1.0));
            let colour = s.xyz / s.w;
            hit.radiance += (1.0 - hit.opacity) * a * colour;
            hit.opacity += (1.0 - hit.opacity) * a;
            if hit.distance == FAR && hit.opacity >= 0.5 {
                hit.distance = t;
            }
        }
        t += 0.5 * diameter;
    }
    return hit;
}

// ---- the virtual objects' solid volumes (coherent/solid.rs): does a self-shadow ray stop? ----

fn solid_tau(k: u32, v: vec3<i32>) -> f32 {
    let dims = params.solids[k].dims;
    let i = dims.w + u32(v.x) + dims.x * (u32(v.y) + dims.y * u32(v.z));
    return tau[i];
}

fn solid_blocks(k: u32, origin_in: vec3<f32>, normal: vec3<f32>, dir: vec3<f32>) -> bool {
    let s = params.solids[k];
    let voxel = s.voxel.xyz;
    let diagonal = length(voxel);
    let origin = origin_in + normal * diagonal;
    let t_min = 0.5 * diagonal;
    let dims = vec3<i32>(s.dims.xyz);
    let lo = s.origin.xyz;
    let hi = lo + voxel * vec3<f32>(s.dims.xyz);
    let inv = 1.0 / dir;
    let t0 = (lo - origin) * inv;
    let t1 = (hi - origin) * inv;
    let tn = min(t0, t1);
    let tx = max(t0, t1);
    let enter = max(max(max(tn.x, tn.y), tn.z), t_min);
    let leave = min(min(tx.x, tx.y), tx.z);
    if !(enter <= leave) {
        return false;
    }
    let local = (origin + dir * enter - lo) / voxel;
    var cell = vec3<i32>(clamp(floor(local), vec3<f32>(0.0), vec3<f32>(dims) - 1.0));
    let step = select(vec3<i32>(-1), vec3<i32>(1), dir >= vec3<f32>(0.0));
    let boundary = (vec3<f32>(cell) + select(vec3<f32>(0.0), vec3<f32>(1.0), dir > vec3<f32>(0.0))) * voxel + lo;
    var t_next = select((boundary - origin) * inv, vec3<f32>(FAR), dir == vec3<f32>(0.0));
    let delta = abs(voxel * inv);
    // at most one step per voxel along each axis
    let steps = dims.x + dims.y + dims.z + 1;
    for (var n = 0; n < steps; n++) {
        if solid_tau(k, cell) >= 0.5 {
            return true;
        }
        var axis = 2;
        if t_next.x < t_next.y && t_next.x < t_next.z {
            axis = 0;
        } else if t_next.y < t_next.z {
            axis = 1;
        }
        let t = t_next[axis];
        if t > leave {
            return false;
        }
        cell[axis] += step[axis];
        if cell[axis] < 0 || cell[axis] >= dims[axis] {
            return false;
        }
        t_next[axis] += delta[axis];
    }
    return false;
}

fn query_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * nwg.x + wid.x) * 64u + lid;
}

@compute @workgroup_size(64)
fn cs_queries(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let q = query_index(wid, nwg, lid);
    if q >= params.counts.x {
        return;
    }
    let query = queries[q];
    let origin = query.origin.xyz;
    let dir = query.dir.xyz;
    let bits = bitcast<u32>(query.normal.w);
    let kind = bits & 0xffu;
    let k = (bits >> 8u) & 0xffu;
    if ((bits >> 16u) & 1u) == 1u {
        // the object's own solid volume stops the ray first: on med its light is zero
        for (var s = 0u; s < params.counts.z; s++) {
            if solid_blocks(s, origin, query.normal.xyz, dir) {
                results[q] = vec4<f32>(0.0, 0.0, 0.0, FAR);
                return;
            }
        }
    }
    var out = vec4<f32>(sky_radiance(dir), FAR);
    if kind == LOOKUP {
        out = lookup(k, origin, dir);
    } else if kind == TRACE {
        out = trace(k, origin, dir);
    } else if kind == CONE {
        let hit = cone_to(origin, dir, query.origin.w, FAR);
        out = vec4<f32>(hit.radiance + (1.0 - hit.opacity) * sky_radiance(dir), hit.distance);
    } else if kind == CONE_TO {
        let hit = cone_to(origin, dir, query.origin.w, query.dir.w);
        out = vec4<f32>(hit.opacity, 0.0, 0.0, 0.0);
    }
    results[q] = out;
}

// ---- a pixel's terms combined (coherent/mod.rs: object_pixel, estimate_albedo, differential) ----

// term operations
const CONST: u32 = 0u;
const INCIDENT: u32 = 1u;
const TRANSMITS: u32 = 2u;
const RAY_END: u32 = 3u;

// registers
const OBJECT: u32 = 0u;
const IRRADIANCE: u32 = 1u;
const LIGHTS: u32 = 2u;
const SUM: u32 = 3u;
const CHANGE: u32 = 4u;
const BOUNCE: u32 = 5u;

struct Term {
    // op, register, query, second query (RAY_END: the cone before the object, NONE without)
    code: vec4<u32>,
    // weight (xyz; RAY_END: x the random numbers its bounce draws); w: INCIDENT's divisor,
    // TRANSMITS' distance, RAY_END's distance to the object
    weight: vec4<f32>,
}

struct Pixel {
    // first term, term count, covered subsamples, flags (1: a real surface, 2: its albedo estimated)
    terms: vec4<u32>,
    // x: eq. 9's scale over N, y: coverage
    scale: vec4<f32>,
}

@group(0) @binding(7) var<storage, read> terms: array<Term>;
@group(0) @binding(8) var<storage, read> pixels: array<Pixel>;
// the photograph's linear radiance
@group(0) @binding(9) var<storage, read> photo: array<vec4<f32>>;
// per pixel four vec4: composite, differential, albedo (unclamped: eq. 5's rho), object
@group(0) @binding(10) var<storage, read_write> frame: array<vec4<f32>>;

@compute @workgroup_size(64)
fn cs_combine(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = query_index(wid, nwg, lid);
    if k >= params.frame.x {
        return;
    }
    let pixel = pixels[k];
    var reg: array<vec3<f32>, 6>;
    for (var r = 0u; r < 6u; r++) {
        reg[r] = vec3<f32>(0.0);
    }
    let first = params.frame.y;
    // random numbers the differential's bounces drew so far (coherent/gpu_frame.rs)
    var drawn = 0u;
    for (var i = pixel.terms.x; i < pixel.terms.x + pixel.terms.y; i++) {
        let term = terms[i];
        let w = term.weight;
        if term.code.x == CONST {
            reg[term.code.y] += w.xyz;
        } else if term.code.x == INCIDENT {
            // code.w: the count of the differential's random numbers it was drawn after (NONE: any)
            if term.code.w == NONE || term.code.w == drawn {
                reg[term.code.y] += w.xyz * results[term.code.z - first].xyz / w.w;
            }
        } else if term.code.x == TRANSMITS {
            if !(results[term.code.z - first].w < w.w * 0.98) {
                reg[term.code.y] += w.xyz;
            }
        } else if term.code.x == RAY_END {
            let env = results[term.code.z - first];
            var skipped = false;
            var d = reg[BOUNCE] - env.xyz;
            if term.code.w != NONE {
                // eq. 6: the environment seen up to the object weights the difference
                d = (1.0 - results[term.code.w - first].x) * d;
            } else if env.w < w.w {
                // the environment is nearer: the CPU stops before the bounce draws its numbers
                d = vec3<f32>(0.0);
                skipped = true;
            }
            if !skipped {
                drawn += u32(w.x);
            }
            reg[SUM] += d;
            reg[BOUNCE] = vec3<f32>(0.0);
        }
    }
    let photo_k = photo[k].xyz;
    var object = vec3<f32>(0.0);
    if pixel.terms.z > 0u {
        object = reg[OBJECT] / f32(pixel.terms.z);
    }
    var rho = vec3<f32>(0.0);
    var delta = vec3<f32>(0.0);
    if (pixel.terms.w & 2u) != 0u {
        let irradiance = reg[IRRADIANCE] * bitcast<f32>(params.sky.w) + reg[LIGHTS];
        rho = select(vec3<f32>(0.0), PI * photo_k / irradiance, irradiance > vec3<f32>(1e-8));
        let clamped = clamp(rho, vec3<f32>(0.0), vec3<f32>(1.0));
        delta = clamped * reg[SUM] * pixel.scale.x + clamped / PI * reg[CHANGE];
    }
    var background = photo_k;
    if (pixel.terms.w & 1u) != 0u {
        background = max(photo_k + delta, vec3<f32>(0.0));
    }
    var composite = background;
    if pixel.terms.z > 0u {
        let c = pixel.scale.y;
        composite = c * object + (1.0 - c) * background;
    }
    frame[4u * k] = vec4<f32>(composite, 0.0);
    frame[4u * k + 1u] = vec4<f32>(delta, 0.0);
    frame[4u * k + 2u] = vec4<f32>(rho, 0.0);
    frame[4u * k + 3u] = vec4<f32>(object, 0.0);
}
