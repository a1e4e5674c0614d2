// The indirect light's post pass: the geometry-aware merge of interleaved sampling, then
// temporal smoothing (thesis 5.2.9, equations 5.11-5.15), then the sum with the direct light.
//
// Interleaved sampling (Segovia et al. 2006, thesis 5.2.10): with an n x n split, the pixel at
// (x, y) evaluated only the VPLs of its class (x mod n) + n (y mod n), scaled by n^2; here each
// pixel averages the n x n window around it — which holds every class once — over the pixels
// that lie on the same kind of surface (real/virtual), face the same way (normals within ~25°)
// and are near in depth (within 5 % of the distance to the camera).
//
// Temporal smoothing: the pixel's world position is projected with the previous frame's camera;
// the previous frame's position, normal and smoothed indirect light at that pixel give
//   e_pos  = |(dx, dy, dd) * w_p|  (screen motion in units of the image size, depth change in
//                                   units of the scene's radius)        (5.11)
//   e_n    = (1 - n . n_prev) w_n                                       (5.12)
//   e_ill  = saturate(|I_new - I_prev|^3) w_i                           (5.13)
//   c      = saturate(1 - max(e_pos, e_n, e_ill)) c_B                   (5.14)
//   I      = c I_prev + (1 - c) I_new                                   (5.15)
// separately for L_rv's and L_r's indirect light (the confidence from the L_rv light). Without a
// previous frame c = 0. Driven by indirect.rs.

struct Params {
    size: vec4<u32>,            // width, height, interleave n, has history (0/1)
    weights: vec4<f32>,         // w_p.x, w_p.y, w_p.z, w_n
    more: vec4<f32>,            // w_i, c_B, scene radius, unused
    camera: vec4<f32>,          // xyz: camera position
    prev_view_proj: mat4x4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var g_position: texture_2d<f32>;
@group(0) @binding(2) var g_normal: texture_2d<f32>;
@group(0) @binding(3) var<storage, read> raw: array<vec4<f32>>;              // indirect I_rv then I_r, as shaded
@group(0) @binding(4) var<storage, read_write> solutions: array<vec4<f32>>;  // direct light in, L_rv then L_r out
@group(0) @binding(5) var<storage, read> prev_indirect: array<vec4<f32>>;    // last frame's smoothed I_rv, I_r
@group(0) @binding(6) var<storage, read> prev_surface: array<vec4<f32>>;     // last frame's position+flag, then normal
@group(0) @binding(7) var<storage, read_write> next_indirect: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> next_surface: array<vec4<f32>>;

@compute @workgroup_size(8, 8)
fn cs_indirect(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.size.x;
    let height = params.size.y;
    if id.x >= width || id.y >= height {
        return;
    }
    let pixels = width * height;
    let pixel = id.y * width + id.x;
    let gp = textureLoad(g_position, vec2<i32>(id.xy), 0);
    let gn = textureLoad(g_normal, vec2<i32>(id.xy), 0);
    let flag = u32(gp.w + 0.5) & 3u;
    next_surface[pixel] = vec4<f32>(gp.xyz, f32(flag));
    next_surface[pixel + pixels] = vec4<f32>(gn.xyz, 0.0);
    if flag == 0u {
        next_indirect[pixel] = vec4<f32>(0.0);
        next_indirect[pixel + pixels] = vec4<f32>(0.0);
        return;
    }
    let p = gp.xyz;
    let n = normalize(gn.xyz);

    // 1. merge of the interleaved classes
    var i_rv = raw[pixel].xyz;
    var i_r = raw[pixel + pixels].xyz;
    let split = params.size.z;
    if split > 1u {
        let view_distance = length(p - params.camera.xyz);
        let lo = vec2<i32>(id.xy) - vec2<i32>(i32(split / 2u));
        var sum_rv = vec3<f32>(0.0);
        var sum_r = vec3<f32>(0.0);
        var weight = 0.0;
        for (var dy = 0; dy < i32(split); dy++) {
            for (var dx = 0; dx < i32(split); dx++) {
                let q = clamp(lo + vec2<i32>(dx, dy), vec2<i32>(0), vec2<i32>(i32(width) - 1, i32(height) - 1));
                let qp = textureLoad(g_position, q, 0);
                let qn = textureLoad(g_normal, q, 0);
                let q_flag = u32(qp.w + 0.5) & 3u;
                let same = q_flag == flag && dot(normalize(qn.xyz), n) > 0.9 && abs(length(qp.xyz - params.camera.xyz) - view_distance) < 0.05 * view_distance;
                if same {
                    let k = u32(q.y) * width + u32(q.x);
                    sum_rv += raw[k].xyz;
                    sum_r += raw[k + pixels].xyz;
                    weight += 1.0;
                }
            }
        }
        // the pixel itself always counts, so weight >= 1
        i_rv = sum_rv / weight;
        i_r = sum_r / weight;
    }

    // 2. temporal smoothing against the previous frame
    var confidence = 0.0;
    var prev_rv = vec3<f32>(0.0);
    var prev_r = vec3<f32>(0.0);
    if params.size.w == 1u {
        let clip = params.prev_view_proj * vec4<f32>(p, 1.0);
        if clip.w > 0.0 {
            let ndc = clip.xy / clip.w;
            let prev_xy = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
            if all(prev_xy >= vec2<f32>(0.0)) && all(prev_xy < vec2<f32>(1.0)) {
                let prev_pixel_xy = vec2<u32>(prev_xy * vec2<f32>(f32(width), f32(height)));
                let k = prev_pixel_xy.y * width + prev_pixel_xy.x;
                let prev_p = prev_surface[k];
                if u32(prev_p.w + 0.5) == flag {
                    let here = (vec2<f32>(id.xy) + vec2<f32>(0.5)) / vec2<f32>(f32(width), f32(height));
                    let depth_change = length(prev_p.xyz - p) / max(params.more.z, 1e-6);
                    let e_pos = length(vec3<f32>(here - prev_xy, depth_change) * params.weights.xyz);      // 5.11
                    let e_n = (1.0 - dot(n, normalize(prev_surface[k + pixels].xyz))) * params.weights.w;  // 5.12
                    prev_rv = prev_indirect[k].xyz;
                    prev_r = prev_indirect[k + pixels].xyz;
                    let change = length(i_rv - prev_rv);
                    let e_ill = clamp(change * change * change, 0.0, 1.0) * params.more.x;             // 5.13
                    confidence = clamp(1.0 - max(e_pos, max(e_n, e_ill)), 0.0, 1.0) * params.more.y;  // 5.14
                }
            }
        }
    }
    i_rv = confidence * prev_rv + (1.0 - confidence) * i_rv;                                          // 5.15
    i_r = confidence * prev_r + (1.0 - confidence) * i_r;
    next_indirect[pixel] = vec4<f32>(i_rv, confidence);
    next_indirect[pixel + pixels] = vec4<f32>(i_r, 0.0);

    // 3. with the direct light
    solutions[pixel] = vec4<f32>(solutions[pixel].xyz + i_rv, solutions[pixel].w);
    solutions[pixel + pixels] = vec4<f32>(solutions[pixel + pixels].xyz + i_r, solutions[pixel + pixels].w);
}
