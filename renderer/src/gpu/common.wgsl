// Functions shared by several shaders of the GPU renderer; the Rust side prepends this file to
// ism.wgsl, shade.wgsl, bounce.wgsl, specular.wgsl, cm.wgsl and vpl.wgsl (`concat!`), so each
// of them is defined once.

// One VPL (vpl.rs's `GpuVpl`).
struct Vpl {
    position: vec4<f32>,        // xyz; w: the path flag r(x) of eq. 5.9 (1: every element real)
    normal: vec4<f32>,          // xyz; w: ir(VPL), 1: illuminates the real-only solution only
    flux: vec4<f32>,            // rgb: reflected flux (W); w: 1 for a caustic's reflected or refracted VPL
}

// An ISM atlas texel (ism.wgsl writes them, shade.wgsl reads them): the bits of 1.0 minus the
// bits of the stored depth in [0, 1], so a zeroed texel is "nothing nearer than the far plane"
// and the nearest splat is the largest value (non-negative floats order as their bits do).
fn ism_encode(depth: f32) -> u32 {
    return 0x3f800000u - bitcast<u32>(clamp(depth, 0.0, 1.0));
}

fn ism_decode(stored: u32) -> f32 {
    return bitcast<f32>(0x3f800000u - stored);
}

// A 32-bit integer hash (Jarzynski & Olano's PCG hash) and floats in [0, 1) from it.
fn pcg(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn unit(v: u32) -> f32 {
    return f32(v >> 8u) * (1.0 / 16777216.0);
}

// An orthonormal basis around n (Duff et al. 2017).
fn basis_x(n: vec3<f32>) -> vec3<f32> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    return vec3<f32>(1.0 + s * n.x * n.x * a, s * n.x * n.y * a, -s * n.x);
}

fn basis_y(n: vec3<f32>) -> vec3<f32> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    return vec3<f32>(n.x * n.y * a, s + n.y * n.y * a, -n.y);
}

// A spot's fraction of its intensity at cosine c off its axis: 1 inside the inner cone, 0
// outside the outer, smoothstep between (as light.rs's SpotLight::intensity_towards).
fn spot_falloff(c: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    if c >= cos_inner {
        return 1.0;
    }
    if c <= cos_outer {
        return 0.0;
    }
    let t = (c - cos_outer) / (cos_inner - cos_outer);
    return t * t * (3.0 - 2.0 * t);
}

// Rec. 709 luminance of linear RGB (as math.rs's `luminance`).
fn luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}
