// A virtual object's solid voxel volume by parity (Rohmer et al. Sec. 6.3; Eisemann and Décoret
// 2008): the GPU twin of the sweeps of `coherent::solid::SolidVolume::build`. A dispatch is one
// sample column per voxel column of one sweep (the CPU's order over the sample columns is the
// order of the dispatches); each invocation finds its column's crossings of the object's
// surfaces among the primitives binned to the voxel column, and adds to that voxel column: the
// outward normal, albedo and count of every crossing, and on the z sweep τ, the share of each
// voxel's extent inside the object. A voxel column belongs to one invocation of a dispatch, so
// nothing is atomic and every sum adds in the CPU's order.
//
// Every loop is short: llvmpipe (lavapipe) stops an invocation's loops after about 2^14
// iterations in all (measured here: one invocation walking its voxel column's 16 sample columns
// over 3 477 triangles each stopped in the fifth), so the host splits the work by sample column
// and refuses a column with more primitives than MAX_COLUMN_PRIMITIVES (`representation.rs`).

struct Prim {
    // a triangle's corners (w: 0), or a sphere's centre in `a` with its radius in a.w (b.w: 1)
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
    // diffuse albedo; w: 1 for a mirror or glass
    albedo: vec4<f32>,
    // a triangle's texture coordinates at its corners: (u0, v0, u1, v1), (u2, v2, pattern,
    // its rings, squares or stripes per unit); pattern 0: none, 1 wood, 2 checker, 3 stripes
    uv01: vec4<f32>,
    uv2: vec4<f32>,
    // the pattern's two colours (wood: light and dark)
    pattern_a: vec4<f32>,
    pattern_b: vec4<f32>,
}

struct Params {
    // the corner of voxel (0, 0, 0); w: the sweep's axis (0, 1, 2)
    origin: vec4<f32>,
    // a voxel's edges
    voxel: vec4<f32>,
    // voxels per axis (w unused)
    dims: vec4<u32>,
    // x: where each sample column starts along the axis, y: where it ends, z: the box's far side
    // along z (closes an odd last interval)
    span: vec4<f32>,
    // x, y: this dispatch's sample column within each voxel column (across u, across v)
    sub: vec4<u32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> prims: array<Prim>;
// the columns' primitives: column c's are indices[offsets[c] .. offsets[c + 1]]
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;
@group(0) @binding(4) var<storage, read_write> tau: array<f32>;
// per voxel: the outward normals' sum (xyz) and the crossings (w)
@group(0) @binding(5) var<storage, read_write> normals: array<vec4<f32>>;
// per voxel: the albedos' sum (xyz), 1 where a mirror or glass was crossed (w)
@group(0) @binding(6) var<storage, read_write> albedos: array<vec4<f32>>;
@group(0) @binding(7) var<uniform> mip: Mip;

// a mip step of τ (every level in `tau`, one after the other): the fine and the coarse level's
// voxels per axis (w: their first voxel)
struct Mip {
    fine: vec4<u32>,
    coarse: vec4<u32>,
}

const SUB: u32 = 4u;
// the path tracer's RAY_EPSILON: a crossing closer than this to the one before is not seen
const EPSILON: f32 = 1e-4;
// the crossings kept per sample column
const MAX_CROSSINGS: u32 = 64u;

var<private> crossing_t: array<f32, 64>;
var<private> crossing_prim: array<u32, 64>;
// a triangle crossing's barycentric u, v (Möller–Trumbore's)
var<private> crossing_uv: array<vec2<f32>, 64>;
const PI: f32 = 3.14159265358979;

fn axis_of(v: vec3<f32>, axis: u32) -> f32 {
    return select(select(v.z, v.y, axis == 1u), v.x, axis == 0u);
}

// the voxel at (cu, cv) across a sweep along `axis` and k along it
fn cell_of(axis: u32, cu: u32, cv: u32, k: u32) -> vec3<u32> {
    return select(select(vec3<u32>(cv, k, cu), vec3<u32>(k, cu, cv), axis == 0u), vec3<u32>(cu, cv, k), axis == 2u);
}

fn unit(axis: u32) -> vec3<f32> {
    return vec3<f32>(select(0.0, 1.0, axis == 0u), select(0.0, 1.0, axis == 1u), select(0.0, 1.0, axis == 2u));
}

// Möller–Trumbore, as `Primitive::intersect_t` for a triangle: (t along `dir`, u, v), t = -1
// for a miss
fn hit_triangle(p: Prim, origin: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    let e1 = p.b.xyz - p.a.xyz;
    let e2 = p.c.xyz - p.a.xyz;
    let h = cross(dir, e2);
    let det = dot(e1, h);
    if abs(det) < 1e-12 {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    let inv = 1.0 / det;
    let s = origin - p.a.xyz;
    let u = dot(s, h) * inv;
    if u < 0.0 || u > 1.0 {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    let q = cross(s, e1);
    let v = dot(dir, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return vec3<f32>(-1.0, 0.0, 0.0);
    }
    return vec3<f32>(dot(e2, q) * inv, u, v);
}

// Rust's f32::fract: x - trunc(x) (negative below zero, unlike WGSL's fract)
fn fract_trunc(x: f32) -> f32 {
    return x - trunc(x);
}

// `Texture::eval` of the procedural patterns at `uv`
fn pattern(p: Prim, uv: vec2<f32>) -> vec3<f32> {
    let kind = u32(p.uv2.z);
    let scale = p.uv2.w;
    if kind == 1u {
        let x = uv.x;
        let y = uv.y * 7.0;
        let warp = 0.15 * sin(y * 3.1 + sin(x * 2.3)) + 0.05 * sin(y * 17.0);
        let r = fract_trunc((x + warp) * scale);
        let grain = 0.5 + 0.5 * cos(r * 2.0 * PI);
        let t = pow(grain, 3.0);
        return mix(p.pattern_a.xyz, p.pattern_b.xyz, t * 0.8);
    }
    var i: i32;
    if kind == 2u {
        i = i32(floor(uv.x * scale)) + i32(floor(uv.y * scale));
    } else {
        i = i32(floor(uv.y * scale));
    }
    return select(p.pattern_b.xyz, p.pattern_a.xyz, ((i % 2) + 2) % 2 == 0);
}

// the albedo where a crossing of `p` at `point` (barycentric `bary` on a triangle) lies
fn albedo_at(p: Prim, point: vec3<f32>, bary: vec2<f32>) -> vec3<f32> {
    if u32(p.uv2.z) == 0u {
        return p.albedo.xyz;
    }
    var uv: vec2<f32>;
    if p.b.w > 0.5 {
        let n = normalize((point - p.a.xyz) / p.a.w);
        uv = vec2<f32>(0.5 + atan2(n.z, n.x) / (2.0 * PI), acos(clamp(n.y, -1.0, 1.0)) / PI);
    } else {
        let w = 1.0 - bary.x - bary.y;
        uv = p.uv01.xy * w + p.uv01.zw * bary.x + p.uv2.xy * bary.y;
    }
    return p.albedo.xyz * pattern(p, uv);
}

// records a crossing at `t` (beyond the start's epsilon and before `t_max`) among the `count`
// kept so far, keeping the list sorted by t; the new count
fn record(t: f32, prim: u32, bary: vec2<f32>, t_max: f32, count: u32) -> u32 {
    if !(t > EPSILON && t < t_max) || count >= MAX_CROSSINGS {
        return count;
    }
    var k = count;
    loop {
        if k == 0u {
            break;
        }
        if !(crossing_t[k - 1u] > t) {
            break;
        }
        crossing_t[k] = crossing_t[k - 1u];
        crossing_prim[k] = crossing_prim[k - 1u];
        crossing_uv[k] = crossing_uv[k - 1u];
        k -= 1u;
    }
    crossing_t[k] = t;
    crossing_prim[k] = prim;
    crossing_uv[k] = bary;
    return count + 1u;
}

fn geometric_normal(p: Prim, point: vec3<f32>) -> vec3<f32> {
    if p.b.w > 0.5 {
        return normalize((point - p.a.xyz) / p.a.w);
    }
    let n = cross(p.b.xyz - p.a.xyz, p.c.xyz - p.a.xyz);
    let l = length(n);
    return select(vec3<f32>(0.0), n / l, l > 0.0);
}

@compute @workgroup_size(64)
fn cs_solid_sweep(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                  @builtin(local_invocation_index) lid: u32) {
    let axis = u32(params.origin.w);
    let u_axis = (axis + 1u) % 3u;
    let v_axis = (axis + 2u) % 3u;
    let dims = params.dims.xyz;
    let dims_f = vec3<f32>(dims);
    let nu = u32(axis_of(dims_f, u_axis));
    let nv = u32(axis_of(dims_f, v_axis));
    let column = (wid.y * nwg.x + wid.x) * 64u + lid;
    if column >= nu * nv {
        return;
    }
    let cu = column % nu;
    let cv = column / nu;
    let dir = unit(axis);
    let origin = params.origin.xyz;
    let voxel = params.voxel.xyz;
    let t_max = params.span.y - params.span.x;
    // the sample column: across the sweep at its place in the voxel column, along it at span.x
    let du = (f32(cu * SUB + params.sub.x) + 0.5) / f32(SUB) * axis_of(voxel, u_axis);
    let dv = (f32(cv * SUB + params.sub.y) + 0.5) / f32(SUB) * axis_of(voxel, v_axis);
    let start = select(origin + unit(u_axis) * du + unit(v_axis) * dv, vec3<f32>(params.span.x), dir > vec3<f32>(0.5));

    var count = 0u;
    let last = offsets[column + 1u];
    for (var k = offsets[column]; k < last; k += 1u) {
        let index = indices[k];
        let p = prims[index];
        if p.b.w > 0.5 {
            // a sphere: both roots
            let oc = start - p.a.xyz;
            let half_b = dot(oc, dir);
            let disc = half_b * half_b - (dot(oc, oc) - p.a.w * p.a.w);
            if disc >= 0.0 {
                let sq = sqrt(disc);
                count = record(-half_b - sq, index, vec2<f32>(0.0), t_max, count);
                count = record(-half_b + sq, index, vec2<f32>(0.0), t_max, count);
            }
        } else {
            let hit = hit_triangle(p, start, dir);
            count = record(hit.x, index, hit.yz, t_max, count);
        }
    }
    // the CPU walks from crossing to crossing, each search starting beyond EPSILON
    var kept = 0u;
    var previous = -1.0;
    for (var n = 0u; n < count; n += 1u) {
        let t = crossing_t[n];
        if kept > 0u && !(t - previous > EPSILON) {
            continue;
        }
        crossing_t[kept] = t;
        crossing_prim[kept] = crossing_prim[n];
        crossing_uv[kept] = crossing_uv[n];
        kept += 1u;
        previous = t;
    }
    let n_along = u32(axis_of(dims_f, axis));
    for (var n = 0u; n < kept; n += 1u) {
        let point = start + dir * crossing_t[n];
        let p = prims[crossing_prim[n]];
        let normal = geometric_normal(p, point);
        let along = (axis_of(point, axis) - axis_of(origin, axis)) / axis_of(voxel, axis);
        let cell = cell_of(axis, cu, cv, u32(clamp(i32(floor(along)), 0, i32(n_along) - 1)));
        // entering (even) crossings face against the sweep, leaving ones along it
        let outward = select(normal, -normal, (n % 2u == 0u) == (axis_of(normal, axis) > 0.0));
        let at = cell.x + dims.x * (cell.y + dims.y * cell.z);
        normals[at] += vec4<f32>(outward, 1.0);
        let albedo = albedo_at(p, point, crossing_uv[n]);
        albedos[at] = vec4<f32>(albedos[at].xyz + albedo, max(albedos[at].w, p.albedo.w));
    }
    if axis != 2u {
        return;
    }
    // τ: the inside intervals' share of each voxel's extent
    for (var n = 0u; n < kept; n += 2u) {
        let enter = start.z + crossing_t[n];
        let leave = select(params.span.z, start.z + crossing_t[n + 1u], n + 1u < kept);
        let lo_k = u32(min(max(floor((enter - origin.z) / voxel.z), 0.0), f32(dims.z - 1u)));
        let hi_k = u32(min(max(floor((leave - origin.z) / voxel.z), 0.0), f32(dims.z - 1u)));
        for (var k = lo_k; k <= hi_k; k += 1u) {
            let lo = origin.z + f32(k) * voxel.z;
            let hi = origin.z + f32(k + 1u) * voxel.z;
            let covered = max(min(leave, hi) - max(enter, lo), 0.0) / voxel.z;
            tau[cu + dims.x * (cv + dims.y * k)] += covered / f32(SUB * SUB);
        }
    }
}

// One mip level of τ from the level below: each coarse voxel the mean of the fine 2×2×2 block
// (a block cut by the edge averages the voxels it has), level 0 read clamped to [0, 1] — the
// CPU's `downsample`, sum for sum.
@compute @workgroup_size(64)
fn cs_solid_mip(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                @builtin(local_invocation_index) lid: u32) {
    let coarse = mip.coarse.xyz;
    let fine = mip.fine.xyz;
    let index = (wid.y * nwg.x + wid.x) * 64u + lid;
    if index >= coarse.x * coarse.y * coarse.z {
        return;
    }
    let x = index % coarse.x;
    let y = (index / coarse.x) % coarse.y;
    let z = index / (coarse.x * coarse.y);
    var sum = 0.0;
    var n = 0u;
    for (var c = 0u; c < 8u; c += 1u) {
        let v = vec3<u32>(2u * x + (c & 1u), 2u * y + ((c >> 1u) & 1u), 2u * z + (c >> 2u));
        if all(v < fine) {
            var t = tau[mip.fine.w + v.x + fine.x * (v.y + fine.y * v.z)];
            if mip.fine.w == 0u {
                t = clamp(t, 0.0, 1.0);
            }
            sum += t;
            n += 1u;
        }
    }
    tau[mip.coarse.w + index] = sum / f32(n);
}
