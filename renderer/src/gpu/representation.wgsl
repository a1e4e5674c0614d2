// Rohmer et al.'s scene representations built from the captured environment samples (Sec. 6.1):
// the distance impostor (radiance and distance cube map) and the mip-mapped scene voxel volume.
// The GPU twin of `coherent::impostor::DistanceImpostor::build` and `coherent::voxel::VoxelVolume::
// build`, splat for splat: each sample is a disk in its tangent plane.

struct Sample {
    position: vec4<f32>,
    normal: vec4<f32>,
    colour: vec4<f32>,
}

struct Params {
    // impostor: centre (xyz); voxels: origin of voxel (0, 0, 0) (xyz); w: the disk's radius
    centre: vec4<f32>,
    // x: samples, y: impostor texels per face or voxels per axis, z: bits of the voxel edge
    counts: vec4<u32>,
}

// a mip step: x, y: voxels per axis of the fine and coarse level, z, w: their first voxel
struct Mip {
    levels: vec4<u32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> samples: array<Sample>;
// the impostor's distance per texel as ordered bits (positive floats sort as u32), 0xffffffff empty
@group(0) @binding(2) var<storage, read_write> depth: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read_write> radiance: array<vec4<f32>>;
// per voxel: r, g, b in fixed point (COLOUR_SCALE) and the count
@group(0) @binding(4) var<storage, read_write> sums: array<atomic<u32>>;
// every level of the volume, one after the other
@group(0) @binding(5) var<storage, read_write> levels: array<vec4<f32>>;
@group(0) @binding(6) var<uniform> mip: Mip;

const EMPTY: u32 = 0xffffffffu;
const COLOUR_SCALE: f32 = 4096.0;
// one sample's radiance is clamped here so that 64 of them in a voxel cannot overflow 32 bits
const COLOUR_MAX: f32 = 16383.0;

fn sample_index(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * nwg.x + wid.x) * 64u + lid;
}

fn finite3(v: vec3<f32>) -> bool {
    // NaN fails every comparison; infinity exceeds the largest float
    return all(abs(v) <= vec3<f32>(3.4e38));
}

fn texel_coord(i: i32, size: u32) -> f32 {
    return 2.0 * (f32(i) + 0.5) / f32(size) - 1.0;
}

fn face_dir(face: u32, s: f32, t: f32) -> vec3<f32> {
    var d: vec3<f32>;
    switch face {
        case 0u: { d = vec3<f32>(1.0, -t, -s); }
        case 1u: { d = vec3<f32>(-1.0, -t, s); }
        case 2u: { d = vec3<f32>(s, 1.0, t); }
        case 3u: { d = vec3<f32>(s, -1.0, -t); }
        case 4u: { d = vec3<f32>(s, -t, 1.0); }
        default: { d = vec3<f32>(-s, -t, -1.0); }
    }
    return normalize(d);
}

// (axis, sign) of a face's major axis and of its s and t numerators, as `face_uv` forms them
fn face_axis(face: u32, which: u32) -> vec2<f32> {
    var table = array<vec2<f32>, 18>(
        vec2<f32>(0.0, 1.0), vec2<f32>(2.0, -1.0), vec2<f32>(1.0, -1.0),
        vec2<f32>(0.0, -1.0), vec2<f32>(2.0, 1.0), vec2<f32>(1.0, -1.0),
        vec2<f32>(1.0, 1.0), vec2<f32>(0.0, 1.0), vec2<f32>(2.0, 1.0),
        vec2<f32>(1.0, -1.0), vec2<f32>(0.0, 1.0), vec2<f32>(2.0, -1.0),
        vec2<f32>(2.0, 1.0), vec2<f32>(0.0, 1.0), vec2<f32>(1.0, -1.0),
        vec2<f32>(2.0, -1.0), vec2<f32>(0.0, -1.0), vec2<f32>(1.0, -1.0),
    );
    return table[face * 3u + which];
}

// the range of a signed axis over the box lo..hi
fn axis_range(lo: vec3<f32>, hi: vec3<f32>, axis: vec2<f32>) -> vec2<f32> {
    let i = u32(axis.x);
    let a = axis.y * lo[i];
    let b = axis.y * hi[i];
    return vec2<f32>(min(a, b), max(a, b));
}

// the texel columns (or rows) that a numerator range n over a major range m projects onto, one
// wider on each side; x > y where none (as `face_bounds` in impostor.rs)
fn texel_span(n: vec2<f32>, m: vec2<f32>, size: u32) -> vec2<i32> {
    var low: f32;
    var high: f32;
    if m.x > 0.0 {
        low = min(n.x / m.x, n.x / m.y);
        high = max(n.y / m.x, n.y / m.y);
    } else {
        low = select(n.x / m.y, -1.0, n.x < 0.0);
        high = select(n.y / m.y, 1.0, n.y > 0.0);
    }
    if low > 1.0 || high < -1.0 {
        return vec2<i32>(1, 0);
    }
    let last = i32(size) - 1;
    let a = clamp(i32(0.5 * (clamp(low, -1.0, 1.0) + 1.0) * f32(size)), 0, last);
    let b = clamp(i32(0.5 * (clamp(high, -1.0, 1.0) + 1.0) * f32(size)), 0, last);
    return vec2<i32>(max(a - 1, 0), min(b + 1, last));
}

// Sample k's splat on one face of the impostor: every texel of `f` whose direction from the
// centre crosses the sample's disk, among those its bounding box projects onto (`face_bounds`
// in impostor.rs); one invocation per (sample, face). WGSL has no closures: `write` picks the
// pass (false: the nearest distance by atomicMin; true: the radiance where this sample won).
fn splat_impostor(k: u32, f: u32, write: bool) {
    let s = samples[k];
    let size = params.counts.y;
    let centre = params.centre.xyz;
    let radius = params.centre.w;
    let d = s.position.xyz - centre;
    let dist = length(d);
    if !(dist > 1e-6) || !finite3(s.colour.xyz) || !finite3(s.position.xyz) {
        return;
    }
    let dir = d / dist;
    var normal = dir;
    if finite3(s.normal.xyz) && dot(s.normal.xyz, s.normal.xyz) > 0.5 {
        normal = normalize(s.normal.xyz);
    }
    let half = radius * sqrt(max(vec3<f32>(1.0) - normal * normal, vec3<f32>(0.0)));
    let lo = d - half;
    let hi = d + half;
    let m = axis_range(lo, hi, face_axis(f, 0u));
    if !(m.y > 0.0) {
        return;
    }
    let xs = texel_span(axis_range(lo, hi, face_axis(f, 1u)), m, size);
    let ys = texel_span(axis_range(lo, hi, face_axis(f, 2u)), m, size);
    for (var y = ys.x; y <= ys.y; y++) {
        for (var x = xs.x; x <= xs.y; x++) {
            let t = face_dir(f, texel_coord(x, size), texel_coord(y, size));
            let facing = dot(normal, t);
            if abs(facing) < 1e-4 {
                continue;
            }
            let along = dot(normal, d) / facing;
            if !(along > 0.0) || length(centre + t * along - s.position.xyz) > radius {
                continue;
            }
            let i = f * size * size + u32(y) * size + u32(x);
            let bits = bitcast<u32>(along);
            if write {
                if atomicLoad(&depth[i]) == bits {
                    radiance[i] = vec4<f32>(s.colour.xyz, 1.0);
                }
            } else {
                atomicMin(&depth[i], bits);
            }
        }
    }
}

@compute @workgroup_size(64)
fn cs_impostor_depth(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = sample_index(wid, nwg, lid);
    if k < 6u * params.counts.x {
        splat_impostor(k / 6u, k % 6u, false);
    }
}

@compute @workgroup_size(64)
fn cs_impostor_radiance(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = sample_index(wid, nwg, lid);
    if k < 6u * params.counts.x {
        splat_impostor(k / 6u, k % 6u, true);
    }
}

// A sample's disk into the voxels it passes through (level 0), summed in fixed point.
@compute @workgroup_size(64)
fn cs_voxel_splat(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let k = sample_index(wid, nwg, lid);
    if k >= params.counts.x {
        return;
    }
    let s = samples[k];
    if !finite3(s.position.xyz) || !finite3(s.colour.xyz) {
        return;
    }
    let res = i32(params.counts.y);
    let voxel = bitcast<f32>(params.counts.z);
    let origin = params.centre.xyz;
    let radius = params.centre.w;
    let has_normal = finite3(s.normal.xyz) && dot(s.normal.xyz, s.normal.xyz) > 0.5;
    var n = vec3<f32>(0.0);
    var slab = 3.4e38;
    if has_normal {
        n = normalize(s.normal.xyz);
        slab = 0.5 * voxel * (abs(n.x) + abs(n.y) + abs(n.z));
    }
    let reach = i32(ceil(radius / voxel));
    let c = (s.position.xyz - origin) / voxel;
    let cc = vec3<i32>(floor(c));
    let colour = vec3<u32>(round(clamp(s.colour.xyz, vec3<f32>(0.0), vec3<f32>(COLOUR_MAX)) * COLOUR_SCALE));
    for (var z = cc.z - reach; z <= cc.z + reach; z++) {
        for (var y = cc.y - reach; y <= cc.y + reach; y++) {
            for (var x = cc.x - reach; x <= cc.x + reach; x++) {
                if x < 0 || y < 0 || z < 0 || x >= res || y >= res || z >= res {
                    continue;
                }
                let centre = origin + (vec3<f32>(f32(x), f32(y), f32(z)) + 0.5) * voxel;
                let offset = centre - s.position.xyz;
                let across = dot(n, offset);
                if abs(across) > slab || length(offset - n * across) > radius {
                    continue;
                }
                let v = 4u * u32((z * res + y) * res + x);
                atomicAdd(&sums[v], colour.x);
                atomicAdd(&sums[v + 1u], colour.y);
                atomicAdd(&sums[v + 2u], colour.z);
                atomicAdd(&sums[v + 3u], 1u);
            }
        }
    }
}

// Level 0: the mean radiance of the samples in a voxel, opacity 1 where any landed.
@compute @workgroup_size(64)
fn cs_voxel_resolve(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let v = sample_index(wid, nwg, lid);
    let res = params.counts.y;
    if v >= res * res * res {
        return;
    }
    let count = atomicLoad(&sums[4u * v + 3u]);
    if count == 0u {
        levels[v] = vec4<f32>(0.0);
        return;
    }
    let sum = vec3<f32>(f32(atomicLoad(&sums[4u * v])), f32(atomicLoad(&sums[4u * v + 1u])), f32(atomicLoad(&sums[4u * v + 2u])));
    levels[v] = vec4<f32>(sum / (COLOUR_SCALE * f32(count)), 1.0);
}

// One mip step: each coarse voxel the mean of its (up to) eight fine voxels, over eight.
@compute @workgroup_size(64)
fn cs_voxel_mip(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let v = sample_index(wid, nwg, lid);
    let fine = mip.levels.x;
    let r = mip.levels.y;
    if v >= r * r * r {
        return;
    }
    let x = v % r;
    let y = (v / r) % r;
    let z = v / (r * r);
    var acc = vec4<f32>(0.0);
    for (var k = 0u; k < 8u; k++) {
        let f = vec3<u32>(2u * x + (k & 1u), 2u * y + ((k >> 1u) & 1u), 2u * z + ((k >> 2u) & 1u));
        if all(f < vec3<u32>(fine)) {
            acc += levels[mip.levels.z + (f.z * fine + f.y) * fine + f.x] / 8.0;
        }
    }
    levels[mip.levels.w + v] = acc;
}
