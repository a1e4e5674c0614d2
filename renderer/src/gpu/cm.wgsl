// The colour-mapping passes of the cm factor (thesis 4.5; Rohmer et al. Section 4), driven by
// cm.rs; each function mirrors its CPU reference in renderer/src/cm/ line for line.
//   cs_reduce: per-pixel contributions (statistics: Lab sums; rohmer: the approximation's or
//              eq. 2's weighted sums) summed per workgroup; the CPU adds the partials (f64)
//   cs_match:  per virtual sample colour, the best-matching real pixel (eqs. 4.20-4.22), an
//              argmax per workgroup; the CPU finishes it
//   cs_map:    tau(L_rv) and tau(L_r) for the mapping the CPU solved

struct Cm {
    size: vec4<u32>,    // width, height, mode (reduce: 0 statistics, 1 rohmer approximation,
                        // 2 rohmer fit; map: 0 off, 1 statistics, 2 affine, 3 linear), samples
    tone: vec4<f32>,    // exposure, saturated, dark, gradient
    filt: vec4<f32>,    // hs_coarse, hsv_fine, beta_approx, beta_fit
    m0: vec4<f32>,      // mapping or c_{t-1}: three rows (statistics: mean_source, mean_target,
    m1: vec4<f32>,      // ratio)
    m2: vec4<f32>,
}

@group(0) @binding(0) var<uniform> cm: Cm;
@group(0) @binding(1) var<storage, read> solutions: array<vec4<f32>>; // L_rv (w: flag) then L_r
@group(0) @binding(2) var<storage, read> photo: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> partials: array<f32>;
@group(0) @binding(4) var<storage, read> colours: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> matches: array<vec2<u32>>;
@group(0) @binding(6) var<storage, read_write> mapped: array<vec4<f32>>;

const K: u32 = 20u;           // floats per contribution (the largest: rohmer fit, 19)
const GROUP: u32 = 64u;
const TAU: f32 = 6.28318530717959;

var<workgroup> shared_sums: array<f32, 1280>;   // GROUP * K
var<workgroup> shared_score: array<f32, 64>;
var<workgroup> shared_index: array<u32, 64>;

fn tone_map(x: vec3<f32>) -> vec3<f32> {
    let y = max(x, vec3<f32>(0.0)) * cm.tone.x;
    return y / (vec3<f32>(1.0) + y);
}

fn srgb_encode1(x: f32) -> f32 {
    let c = clamp(x, 0.0, 1.0);
    if c <= 0.0031308 {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

fn srgb_decode1(x: f32) -> f32 {
    let c = clamp(x, 0.0, 1.0);
    if c <= 0.04045 {
        return c / 12.92;
    }
    return pow((c + 0.055) / 1.055, 2.4);
}

fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(srgb_encode1(c.x), srgb_encode1(c.y), srgb_encode1(c.z));
}

fn srgb_decode(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(srgb_decode1(c.x), srgb_decode1(c.y), srgb_decode1(c.z));
}

fn gamma_decode1(x: f32) -> f32 {
    return select(0.0, pow(x, 2.2), x > 0.0);
}

fn gamma_decode(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(gamma_decode1(c.x), gamma_decode1(c.y), gamma_decode1(c.z));
}

fn lab_f(t: f32) -> f32 {
    let d = 6.0 / 29.0;
    if t > d * d * d {
        return pow(t, 1.0 / 3.0);
    }
    return t / (3.0 * d * d) + 4.0 / 29.0;
}

fn lab_f_inv(t: f32) -> f32 {
    let d = 6.0 / 29.0;
    if t > d {
        return t * t * t;
    }
    return 3.0 * d * d * (t - 4.0 / 29.0);
}

// linear sRGB -> XYZ (E, white to white) -> Lab; see cm/colour.rs for the source of the matrix
fn linear_to_lab(c: vec3<f32>) -> vec3<f32> {
    let x = 0.43389703 * c.x + 0.3762405 * c.y + 0.18990886 * c.z;
    let y = 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
    let z = 0.017721742 * c.x + 0.10945241 * c.y + 0.8727728 * c.z;
    let fx = lab_f(x);
    let fy = lab_f(y);
    let fz = lab_f(z);
    return vec3<f32>(116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz));
}

fn lab_to_linear(lab: vec3<f32>) -> vec3<f32> {
    let fy = (lab.x + 16.0) / 116.0;
    let fx = fy + lab.y / 500.0;
    let fz = fy - lab.z / 200.0;
    let x = lab_f_inv(fx);
    let y = lab_f_inv(fy);
    let z = lab_f_inv(fz);
    return vec3<f32>(
        3.0800717 * x - 1.537208 * y - 0.54303534 * z,
        -0.92092594 * x + 1.875756 * y + 0.04521498 * z,
        0.052950014 * x - 0.20402105 * y + 1.1511296 * z,
    );
}

fn hsv(x: vec3<f32>) -> vec3<f32> {
    let c = max(x, vec3<f32>(0.0));
    let mx = max(max(c.x, c.y), c.z);
    let mn = min(min(c.x, c.y), c.z);
    let delta = mx - mn;
    if delta <= 0.0 || mx <= 0.0 {
        return vec3<f32>(0.0, 0.0, mx);
    }
    var h: f32;
    if mx == c.x {
        h = (c.y - c.z) / delta;
    } else if mx == c.y {
        h = (c.z - c.x) / delta + 2.0;
    } else {
        h = (c.x - c.y) / delta + 4.0;
    }
    h = h / 6.0;
    if h < 0.0 {
        h = h + 1.0;
    }
    if h >= 1.0 {
        h = h - 1.0;
    }
    return vec3<f32>(h, delta / mx, mx);
}

fn hue_distance(a: f32, b: f32) -> f32 {
    let d = abs(a - b);
    return min(d, 1.0 - d);
}

fn disc(c: vec3<f32>) -> vec3<f32> {
    let h = hsv(c);
    let angle = h.x * TAU;
    return vec3<f32>(h.y * cos(angle), h.y * sin(angle), h.z);
}

fn hs_distance(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let p = disc(a);
    let q = disc(b);
    return length(p.xy - q.xy);
}

fn hsv_distance(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let p = disc(a);
    let q = disc(b);
    let dv = abs(p.z - q.z) / max(max(p.z, q.z), 1e-6);
    return sqrt(dot(p.xy - q.xy, p.xy - q.xy) + dv * dv);
}

fn pixel_count() -> u32 {
    return cm.size.x * cm.size.y;
}

fn flag_of(i: u32) -> u32 {
    return u32(solutions[i].w + 0.5);
}

fn l_r(i: u32) -> vec3<f32> {
    return solutions[i + pixel_count()].xyz;
}

// cm::usable: a real modelled surface, L_r not black, the camera not saturated
fn usable(i: u32) -> bool {
    let p = photo[i].xyz;
    return flag_of(i) == 1u && luminance(l_r(i)) > 1e-6 && max(max(p.x, p.y), p.z) < cm.tone.y;
}

fn display_r(i: u32) -> vec3<f32> {
    return srgb_encode(tone_map(l_r(i)));
}

// rohmer::filter1: the hue-saturation distance, or -1 when the pair is dropped
fn filter1(i: u32) -> f32 {
    let w = cm.size.x;
    let h = cm.size.y;
    let x = i % w;
    let y = i / w;
    if flag_of(i) != 1u || !(luminance(l_r(i)) > 1e-6) {
        return -1.0;
    }
    let cam = photo[i].xyz;
    let top = max(max(cam.x, cam.y), cam.z);
    if top >= cm.tone.y || top <= cm.tone.z {
        return -1.0;
    }
    if x == 0u || y == 0u || x + 1u >= w || y + 1u >= h {
        return -1.0;
    }
    let l = i - 1u;
    let r = i + 1u;
    let u = i - w;
    let d = i + w;
    if flag_of(l) != 1u || flag_of(r) != 1u || flag_of(u) != 1u || flag_of(d) != 1u {
        return -1.0;
    }
    let gc = (abs(photo[r].xyz - photo[l].xyz) + abs(photo[d].xyz - photo[u].xyz)) * 0.5;
    let gr = (abs(display_r(r) - display_r(l)) + abs(display_r(d) - display_r(u))) * 0.5;
    if max(max(gc.x, gc.y), gc.z) > cm.tone.w || max(max(gr.x, gr.y), gr.z) > cm.tone.w {
        return -1.0;
    }
    let d_hs = hs_distance(gamma_decode(cam), l_r(i));
    if !(d_hs <= cm.filt.x) {
        return -1.0;
    }
    return d_hs;
}

fn contribution(i: u32) -> array<f32, 20> {
    var c: array<f32, 20>;
    let mode = cm.size.z;
    if mode == 0u {
        if !usable(i) {
            return c;
        }
        let s = linear_to_lab(tone_map(l_r(i)));
        let t = linear_to_lab(srgb_decode(photo[i].xyz));
        c[0] = 1.0;
        c[1] = s.x; c[2] = s.y; c[3] = s.z;
        c[4] = s.x * s.x; c[5] = s.y * s.y; c[6] = s.z * s.z;
        c[7] = t.x; c[8] = t.y; c[9] = t.z;
        c[10] = t.x * t.x; c[11] = t.y * t.y; c[12] = t.z * t.z;
        return c;
    }
    let d = filter1(i);
    if d < 0.0 {
        return c;
    }
    let u = gamma_decode(photo[i].xyz);
    let r = l_r(i);
    if mode == 1u {
        let w = pow(1.0 - min(d, 1.0), cm.filt.z);
        c[0] = 1.0;
        c[1] = w;
        c[2] = w * u.x; c[3] = w * u.y; c[4] = w * u.z;
        c[5] = w * r.x; c[6] = w * r.y; c[7] = w * r.z;
        return c;
    }
    let p = vec3<f32>(dot(cm.m0.xyz, u), dot(cm.m1.xyz, u), dot(cm.m2.xyz, u));
    if hsv_distance(p, r) > cm.filt.y {
        return c;
    }
    let w = pow(1.0 - min(d, 1.0), cm.filt.w);
    c[0] = 1.0;
    for (var a = 0u; a < 3u; a++) {
        for (var b = 0u; b < 3u; b++) {
            c[1u + 3u * a + b] = w * u[a] * u[b];
            c[10u + 3u * a + b] = w * u[a] * r[b];
        }
    }
    return c;
}

@compute @workgroup_size(64)
fn cs_reduce(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    var acc: array<f32, 20>;
    let n = pixel_count();
    let stride = groups.x * GROUP;
    for (var i = wg.x * GROUP + lid; i < n; i += stride) {
        let c = contribution(i);
        for (var k = 0u; k < K; k++) {
            acc[k] += c[k];
        }
    }
    for (var k = 0u; k < K; k++) {
        shared_sums[lid * K + k] = acc[k];
    }
    workgroupBarrier();
    for (var half = GROUP / 2u; half > 0u; half /= 2u) {
        if lid < half {
            for (var k = 0u; k < K; k++) {
                shared_sums[lid * K + k] += shared_sums[(lid + half) * K + k];
            }
        }
        workgroupBarrier();
    }
    if lid == 0u {
        for (var k = 0u; k < K; k++) {
            partials[wg.x * K + k] = shared_sums[k];
        }
    }
}

// samples::match_score
fn match_score(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let h_m = 0.5 - hue_distance(hsv(a).x, hsv(b).x);
    return h_m / (1.0 + length(a - b));
}

@compute @workgroup_size(64)
fn cs_match(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let a = colours[wg.y].xyz;
    let n = pixel_count();
    let stride = groups.x * GROUP;
    var best = -1.0;
    var best_index = 0xffffffffu;
    for (var i = wg.x * GROUP + lid; i < n; i += stride) {
        if usable(i) {
            let s = match_score(a, tone_map(l_r(i)));
            if s > best {
                best = s;
                best_index = i;
            }
        }
    }
    shared_score[lid] = best;
    shared_index[lid] = best_index;
    workgroupBarrier();
    for (var half = GROUP / 2u; half > 0u; half /= 2u) {
        if lid < half {
            let s = shared_score[lid + half];
            let j = shared_index[lid + half];
            if s > shared_score[lid] || (s == shared_score[lid] && j < shared_index[lid]) {
                shared_score[lid] = s;
                shared_index[lid] = j;
            }
        }
        workgroupBarrier();
    }
    if lid == 0u {
        matches[wg.y * groups.x + wg.x] = vec2<u32>(bitcast<u32>(shared_score[0]), shared_index[0]);
    }
}

// cm::Mapping::apply
fn apply(x: vec3<f32>) -> vec3<f32> {
    let kind = cm.size.z;
    if kind == 0u {
        return srgb_encode(tone_map(x));
    }
    if kind == 1u {
        let lab = linear_to_lab(tone_map(x));
        let t = (lab - cm.m0.xyz) * cm.m2.xyz + cm.m1.xyz;
        return srgb_encode(max(lab_to_linear(t), vec3<f32>(0.0)));
    }
    if kind == 2u {
        let c = srgb_encode(tone_map(x));
        return vec3<f32>(dot(cm.m0.xyz, c) + cm.m0.w, dot(cm.m1.xyz, c) + cm.m1.w, dot(cm.m2.xyz, c) + cm.m2.w);
    }
    let y = max(x, vec3<f32>(0.0));
    return vec3<f32>(dot(cm.m0.xyz, y), dot(cm.m1.xyz, y), dot(cm.m2.xyz, y));
}

@compute @workgroup_size(64)
fn cs_map(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.y * (256u * GROUP) + id.x;
    if i >= 2u * pixel_count() {
        return;
    }
    let s = solutions[i];
    mapped[i] = vec4<f32>(apply(s.xyz), s.w);
}
