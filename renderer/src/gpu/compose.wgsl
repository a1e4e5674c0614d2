// The differential composition (thesis 4.17 / 4.19 / 4.29, or Debevec's scaled form 5.16-5.17)
// of the colour-mapped GI buffers over the photograph; driven by compose.rs, mirrors
// cm::compose in renderer/src/cm/mod.rs.
//   flag 0 (nothing modelled), or a real pixel whose mapped differential is exactly zero:
//     the photograph as it is
//   otherwise: cam' + alpha (tau(L_rv) - tau(L_r)), clamped to [0, 1], where cam' is the
//     photograph masked at virtual pixels (where tau(L_r) counts as 0: no real solution), alpha = 1 (additive) or cam'/tau(L_r) per channel
//     (scaled; 1 where tau(L_r) <= 1e-4 or at virtual pixels); in the linear domain (Rohmer)
//     cam is the photograph decoded with gamma 2.2 and the result is encoded again.
//   a pixel of a mirror or glass (specular.wgsl): cam' is CI_std (eq. 5.23) from the specular
//     base, alpha' = CI_std / tau(L'_r) when scaled (5.26), the differential as at a real pixel.

struct Compose {
    size: vec4<u32>,    // width, height, linear domain (0/1), composition (0 additive, 1 scaled)
    options: vec4<u32>, // x: 1 when the specular base is bound
}

@group(0) @binding(0) var<uniform> params: Compose;
@group(0) @binding(1) var<storage, read> mapped: array<vec4<f32>>;   // tau(L_rv) (w: flag), tau(L_r)
@group(0) @binding(2) var<storage, read> photo: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> composite: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> specular_base: array<vec4<f32>>; // CI_std; w: 1 on a mirror or glass

fn gamma_decode1(x: f32) -> f32 {
    return select(0.0, pow(x, 2.2), x > 0.0);
}

fn gamma_encode1(x: f32) -> f32 {
    let c = clamp(x, 0.0, 1.0);
    return select(0.0, pow(c, 1.0 / 2.2), c > 0.0);
}

fn alpha(cam: f32, m: f32, real: bool) -> f32 {
    if real && m > 1e-4 {
        return cam / m;
    }
    return 1.0;
}

@compute @workgroup_size(8, 8)
fn cs_compose(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.size.x;
    let height = params.size.y;
    if id.x >= width || id.y >= height {
        return;
    }
    let pixel = id.y * width + id.x;
    let rv = mapped[pixel];
    let m_rv = rv.xyz;
    let m_r = mapped[pixel + width * height].xyz;
    let flag = u32(rv.w + 0.5);
    let p = photo[pixel];
    if flag == 0u || (flag == 1u && all(m_rv == m_r)) {
        composite[pixel] = p;
        return;
    }
    var real = flag == 1u;
    let linear = params.size.z == 1u;
    var cam = p.xyz;
    if params.options.x == 1u {
        let base = specular_base[pixel];
        if base.w > 0.5 {
            // eqs. 5.22-5.26: CI_std, and L'_r holds exactly what it shows of the real scene
            cam = base.xyz;
            real = true;
        }
    }
    if linear {
        cam = vec3<f32>(gamma_decode1(cam.x), gamma_decode1(cam.y), gamma_decode1(cam.z));
    }
    cam = cam * select(0.0, 1.0, real);
    // a virtual pixel has no real solution: tau(L_rv) alone, not minus tau(0) (an offset)
    let m_r_real = m_r * select(0.0, 1.0, real);
    var delta = m_rv - m_r_real;
    if params.size.w == 1u {
        delta = delta * vec3<f32>(alpha(cam.x, m_r.x, real), alpha(cam.y, m_r.y, real), alpha(cam.z, m_r.z, real));
    }
    var out = clamp(cam + delta, vec3<f32>(0.0), vec3<f32>(1.0));
    if linear {
        out = vec3<f32>(gamma_encode1(out.x), gamma_encode1(out.y), gamma_encode1(out.z));
    }
    composite[pixel] = vec4<f32>(out, 1.0);
}

// The composite packed to 8-bit RGBA for display (one read-back of 4 bytes a pixel): each
// channel as Image::to_rgb8 makes it, clamped to [0, 1], times 255, rounded half away from zero
// (WGSL's round() rounds half to even), alpha 255.
@group(0) @binding(5) var<storage, read_write> packed: array<u32>;

fn to_byte(c: f32) -> u32 {
    let v = clamp(c, 0.0, 1.0) * 255.0;
    let r = floor(v);
    return u32(select(r, r + 1.0, v - r >= 0.5));
}

@compute @workgroup_size(8, 8)
fn cs_pack(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.size.x;
    if id.x >= width || id.y >= params.size.y {
        return;
    }
    let pixel = id.y * width + id.x;
    let c = composite[pixel];
    packed[pixel] = to_byte(c.x) | (to_byte(c.y) << 8u) | (to_byte(c.z) << 16u) | (255u << 24u);
}
