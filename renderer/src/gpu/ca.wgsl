// The ca pass: Klein and Murray's camera chain on the virtual layers (driven by artifacts.rs;
// the CPU reference, with the same arithmetic in the same order, is crate::ca::apply_cpu).
// Every buffer is an array of vec4<f32> texels (rgb, w unused unless said). Layers: three
// consecutive images of n = width*height texels: A (virtual colour, premultiplied), M (virtual
// coverage per channel), D (differential effect). Processed images: two consecutive images, B
// (the composite as the camera sees it) and D.

struct Params {
    size: vec4<u32>,    // width, height, seed, flags (1: Bayer)
    counts: vec4<u32>,  // blur taps, 0, 0, 0
    intr: vec4<f32>,    // fx, fy, cx, cy
    k: vec4<f32>,       // k1, k2, p1, p2
    k2: vec4<f32>,      // k3, chromatic aberration, zoom, sharpen
    noise: array<vec4<f32>, 5>, // variance table at display values k/16, k = 0..16
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> aux: array<vec4<f32>>;   // photograph (w: coverage)
@group(0) @binding(3) var<storage, read> aux2: array<vec4<f32>>;  // layers (for the weight)
@group(0) @binding(4) var<storage, read_write> dst: array<vec4<f32>>;
// [0, 64): DCT basis; [64, 128): luma table; [128, 192): chroma table; then blur taps (dx, dy, w)
@group(0) @binding(5) var<storage, read> tables: array<f32>;

const TAU: f32 = 6.283185307179586;

fn pcg_hash(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn normal(seed: u32, pixel: u32, channel: u32) -> f32 {
    let key = pixel * 8u + channel * 2u;
    let h1 = pcg_hash(seed ^ pcg_hash(key));
    let h2 = pcg_hash(seed ^ pcg_hash(key + 1u));
    let u1 = (f32(h1 >> 8u) + 0.5) * (1.0 / 16777216.0);
    let u2 = f32(h2 >> 8u) * (1.0 / 16777216.0);
    return sqrt(-2.0 * log(u1)) * cos(TAU * u2);
}

fn lut_variance(d: f32) -> f32 {
    let t = clamp(d, 0.0, 1.0) * 16.0;
    let i = min(u32(floor(t)), 15u);
    let f = t - f32(i);
    let a = params.noise[i / 4u][i % 4u];
    let b = params.noise[(i + 1u) / 4u][(i + 1u) % 4u];
    return a * (1.0 - f) + b * f;
}

fn bayer_channel(x: u32, y: u32) -> u32 {
    let px = x % 2u;
    let py = y % 2u;
    if px == 0u && py == 0u {
        return 0u;
    }
    if px == 1u && py == 1u {
        return 2u;
    }
    return 1u;
}

fn idx(x: i32, y: i32) -> u32 {
    let w = i32(params.size.x);
    let h = i32(params.size.y);
    return u32(clamp(y, 0, h - 1) * w + clamp(x, 0, w - 1));
}

fn n_pixels() -> u32 {
    return params.size.x * params.size.y;
}

// 1. layers: A = alpha * C, M = alpha, D = (1 - alpha) * (C - P)
@compute @workgroup_size(8, 8)
fn cs_layers(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let i = id.y * params.size.x + id.x;
    let n = n_pixels();
    let c = src[i].xyz;
    let p = aux[i];
    let alpha = p.w;
    dst[i] = vec4<f32>(c * alpha, 0.0);
    dst[i + n] = vec4<f32>(vec3<f32>(alpha), 0.0);
    dst[i + 2u * n] = vec4<f32>((c - p.xyz) * (1.0 - alpha), 0.0);
}

fn sample_channel(layer: u32, px: f32, py: f32, c: u32) -> f32 {
    let x = px - 0.5;
    let y = py - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi = i32(x0);
    let yi = i32(y0);
    let base = layer * n_pixels();
    let a = src[base + idx(xi, yi)][c];
    let b = src[base + idx(xi + 1, yi)][c];
    let cc = src[base + idx(xi, yi + 1)][c];
    let d = src[base + idx(xi + 1, yi + 1)][c];
    let top = a + (b - a) * fx;
    let bottom = cc + (d - cc) * fx;
    return top + (bottom - top) * fy;
}

fn brown_conrady(p: vec2<f32>) -> vec2<f32> {
    let k1 = params.k.x;
    let k2 = params.k.y;
    let p1 = params.k.z;
    let p2 = params.k.w;
    let k3 = params.k2.x;
    let x = p.x;
    let y = p.y;
    let r2 = x * x + y * y;
    let radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
    let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    return vec2<f32>(xd, yd);
}

// 2. distortion and lateral chromatic aberration on the three layers
@compute @workgroup_size(8, 8)
fn cs_warp(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let fx = params.intr.x;
    let fy = params.intr.y;
    let cx = params.intr.z;
    let cy = params.intr.w;
    let xd = (f32(id.x) + 0.5 - cx) / fx;
    let yd = (f32(id.y) + 0.5 - cy) / fy;
    var u = vec2<f32>(xd, yd);
    for (var k = 0; k < 8; k++) {
        let d = brown_conrady(u);
        u.x += xd - d.x;
        u.y += yd - d.y;
    }
    u = u * params.k2.z;
    let ca = params.k2.y;
    let scales = vec3<f32>(1.0 / (1.0 + ca), 1.0, 1.0 / (1.0 - ca));
    let i = id.y * params.size.x + id.x;
    let n = n_pixels();
    for (var layer = 0u; layer < 3u; layer++) {
        var out = vec3<f32>(0.0);
        for (var c = 0u; c < 3u; c++) {
            let sx = cx + u.x * scales[c] * fx;
            let sy = cy + u.y * scales[c] * fy;
            out[c] = sample_channel(layer, sx, sy, c);
        }
        dst[i + layer * n] = vec4<f32>(out, 0.0);
    }
}

// 3. defocus disc on the three layers (normalised taps)
@compute @workgroup_size(8, 8)
fn cs_blur(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let i = id.y * params.size.x + id.x;
    let n = n_pixels();
    for (var layer = 0u; layer < 3u; layer++) {
        var s = vec3<f32>(0.0);
        for (var t = 0u; t < params.counts.x; t++) {
            let dx = i32(tables[192u + 3u * t]);
            let dy = i32(tables[193u + 3u * t]);
            let w = tables[194u + 3u * t];
            s += src[layer * n + idx(i32(id.x) + dx, i32(id.y) + dy)].xyz * w;
        }
        dst[i + layer * n] = vec4<f32>(s, 0.0);
    }
}

// 4. B = P (1 - M) + A + D and D, with noise at the mosaic sites (or every channel without
// Bayer); B gets the full variance and is clipped, D the variance it adds over the photograph's
@compute @workgroup_size(8, 8)
fn cs_noise(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let i = id.y * params.size.x + id.x;
    let n = n_pixels();
    let a = src[i].xyz;
    let m = src[i + n].xyz;
    let d = src[i + 2u * n].xyz;
    let p = aux[i].xyz;
    let b = p * (vec3<f32>(1.0) - m) + a + d;
    var ob = vec3<f32>(0.0);
    var od = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        let vb = lut_variance(b[c]);
        let vp = lut_variance(p[c]);
        let z = normal(params.size.z, i, c);
        ob[c] = clamp(b[c] + sqrt(max(vb, 0.0)) * z, 0.0, 1.0);
        od[c] = d[c] + sqrt(max(vb - vp, 0.0)) * z;
    }
    if (params.size.w & 1u) != 0u {
        // raw mosaic: x = B at the site's channel, y = D at it
        let c = bayer_channel(id.x, id.y);
        dst[i] = vec4<f32>(ob[c], od[c], 0.0, 0.0);
    } else {
        dst[i] = vec4<f32>(ob, 0.0);
        dst[i + n] = vec4<f32>(od, 0.0);
    }
}

// 5. bilinear demosaicing of both mosaics
@compute @workgroup_size(8, 8)
fn cs_demosaic(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let x = i32(id.x);
    let y = i32(id.y);
    let w = i32(params.size.x);
    let h = i32(params.size.y);
    let i = id.y * params.size.x + id.x;
    let n = n_pixels();
    let c0 = bayer_channel(id.x, id.y);
    let v0 = src[i].xy;
    var sum_b = vec3<f32>(0.0);
    var sum_d = vec3<f32>(0.0);
    var cnt = vec3<f32>(0.0);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let xx = clamp(x + dx, 0, w - 1);
            let yy = clamp(y + dy, 0, h - 1);
            let c = bayer_channel(u32(xx), u32(yy));
            if c == c0 && (dx != 0 || dy != 0) {
                continue;
            }
            if c == 1u && dx != 0 && dy != 0 {
                continue;
            }
            let v = src[u32(yy * w + xx)].xy;
            sum_b[c] += v.x;
            sum_d[c] += v.y;
            cnt[c] += 1.0;
        }
    }
    var ob = vec3<f32>(0.0);
    var od = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        if c == c0 {
            ob[c] = v0.x;
            od[c] = v0.y;
        } else if cnt[c] > 0.0 {
            ob[c] = sum_b[c] / cnt[c];
            od[c] = sum_d[c] / cnt[c];
        } else {
            ob[c] = v0.x;
            od[c] = v0.y;
        }
    }
    dst[i] = vec4<f32>(ob, 0.0);
    dst[i + n] = vec4<f32>(od, 0.0);
}

// 6. unsharp mask (3x3 binomial) on B (clipped) and D
@compute @workgroup_size(8, 8)
fn cs_sharpen(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let i = id.y * params.size.x + id.x;
    let n = n_pixels();
    let kern = vec3<f32>(1.0, 2.0, 1.0);
    let amount = params.k2.w;
    for (var img = 0u; img < 2u; img++) {
        var s = vec3<f32>(0.0);
        for (var j = 0; j < 3; j++) {
            for (var k = 0; k < 3; k++) {
                s += src[img * n + idx(i32(id.x) + k - 1, i32(id.y) + j - 1)].xyz * (kern[k] * kern[j]);
            }
        }
        let c = src[img * n + i].xyz;
        var v = c + (c - s * (1.0 / 16.0)) * amount;
        if img == 0u {
            v = clamp(v, vec3<f32>(0.0), vec3<f32>(1.0));
        }
        dst[img * n + i] = vec4<f32>(v, 0.0);
    }
}

fn weight(m: vec3<f32>) -> f32 {
    return clamp((m.x + m.y + m.z) * (1.0 / 3.0), 0.0, 1.0);
}

// 7. composition: P + w (B - P) + (1 - w) D where anything changed, else P untouched
@compute @workgroup_size(8, 8)
fn cs_compose(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let i = id.y * params.size.x + id.x;
    let n = n_pixels();
    let w = weight(aux2[i + n].xyz);
    let d = src[i + n].xyz;
    let p = aux[i].xyz;
    if w > 0.0 || any(d != vec3<f32>(0.0)) {
        dst[i] = vec4<f32>(clamp(p + (src[i].xyz - p) * w + d * (1.0 - w), vec3<f32>(0.0), vec3<f32>(1.0)), 1.0);
    } else {
        dst[i] = vec4<f32>(p, 1.0);
    }
}

fn to_ycc(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        0.299 * c.x + 0.587 * c.y + 0.114 * c.z - 128.0,
        -0.168736 * c.x - 0.331264 * c.y + 0.5 * c.z,
        0.5 * c.x - 0.418688 * c.y - 0.081312 * c.z,
    );
}

fn from_ycc(c: vec3<f32>) -> vec3<f32> {
    let y = c.x + 128.0;
    return vec3<f32>(y + 1.402 * c.z, y - 0.344136 * c.y - 0.714136 * c.z, y + 1.772 * c.y);
}

// 8. JPEG-style compression, one invocation per 8x8 block, blended in with the virtual weight
@compute @workgroup_size(8, 8)
fn cs_jpeg(@builtin(global_invocation_id) id: vec3<u32>) {
    let bx = i32(id.x) * 8;
    let by = i32(id.y) * 8;
    let w = i32(params.size.x);
    let h = i32(params.size.y);
    if bx >= w || by >= h {
        return;
    }
    let n = n_pixels();
    var f: array<vec3<f32>, 64>;
    for (var y = 0; y < 8; y++) {
        for (var x = 0; x < 8; x++) {
            let c = clamp(src[idx(bx + x, by + y)].xyz, vec3<f32>(0.0), vec3<f32>(1.0));
            f[y * 8 + x] = to_ycc(c * 255.0);
        }
    }
    // forward: rows then columns
    var t: array<vec3<f32>, 64>;
    for (var y = 0; y < 8; y++) {
        for (var u = 0; u < 8; u++) {
            var s = vec3<f32>(0.0);
            for (var x = 0; x < 8; x++) {
                s += tables[u * 8 + x] * f[y * 8 + x];
            }
            t[y * 8 + u] = s;
        }
    }
    var q: array<vec3<f32>, 64>;
    for (var v = 0; v < 8; v++) {
        for (var u = 0; u < 8; u++) {
            var s = vec3<f32>(0.0);
            for (var y = 0; y < 8; y++) {
                s += tables[v * 8 + y] * t[y * 8 + u];
            }
            let step = vec3<f32>(tables[64 + v * 8 + u], tables[128 + v * 8 + u], tables[128 + v * 8 + u]);
            q[v * 8 + u] = floor(s / step + 0.5) * step;
        }
    }
    // inverse: rows then columns
    for (var v = 0; v < 8; v++) {
        for (var x = 0; x < 8; x++) {
            var s = vec3<f32>(0.0);
            for (var u = 0; u < 8; u++) {
                s += tables[u * 8 + x] * q[v * 8 + u];
            }
            t[v * 8 + x] = s;
        }
    }
    for (var y = 0; y < 8; y++) {
        for (var x = 0; x < 8; x++) {
            if bx + x < w && by + y < h {
                var s = vec3<f32>(0.0);
                for (var v = 0; v < 8; v++) {
                    s += tables[v * 8 + y] * t[v * 8 + x];
                }
                let rgb = clamp(from_ycc(s) * (1.0 / 255.0), vec3<f32>(0.0), vec3<f32>(1.0));
                let i = u32((by + y) * w + bx + x);
                let before = src[i].xyz;
                let wv = weight(aux2[i + n].xyz);
                var out = before;
                if wv > 0.0 {
                    out = before + (rgb - before) * wv;
                }
                dst[i] = vec4<f32>(out, 1.0);
            }
        }
    }
}
