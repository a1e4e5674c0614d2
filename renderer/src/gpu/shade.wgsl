// The shading pass of differential instant radiosity (thesis Section 5.2, equations 5.1-5.8).
// One invocation per pixel: reads the G-buffer, the real-only and virtual-only shadow maps of
// every primary light, and the VPL buffer; writes L_rv and L_r. Colour mapping (cm.wgsl) and
// composition (compose.wgsl) follow. Driven by shade.rs.

struct Params {
    camera: vec4<f32>,          // xyz: camera position
    size: vec4<u32>,            // width, height, light count, VPL count
    mode: vec4<u32>,            // x: condition (0 none, 1 shadows, 2 gi); y: shadow map size;
                                // z: ISM tile size (0: no VPL visibility); w: ISM tiles per row
    tone: vec4<f32>,            // x: interleaved-sampling split n (1: none); y: VPL distance clamp
                                // (squared); z: 1 / the ISMs' maximum distance
}

struct Light {
    view_proj: mat4x4<f32>,
    position: vec4<f32>,        // xyz; w: r(pl), 1 real, 0 virtual
    direction: vec4<f32>,       // xyz: spot axis, or the direction light travels; w: cos outer
    intensity: vec4<f32>,       // rgb: W/sr (spot) or W/m2 (directional); w: cos inner
    info: vec4<f32>,            // x: kind (0 spot, 1 directional); y: layer of the real-only map
                                // (the virtual-only map is the next); z: texel size (spot: at unit
                                // distance; directional: in metres)
}

struct Material {
    albedo: vec4<f32>,
    pattern_a: vec4<f32>,
    pattern_b: vec4<f32>,
    specular_emission: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var g_position: texture_2d<f32>;
@group(0) @binding(2) var g_normal: texture_2d<f32>;
@group(0) @binding(3) var g_albedo: texture_2d<f32>;
@group(0) @binding(4) var shadow_maps: texture_2d_array<f32>;
@group(0) @binding(5) var<storage, read> lights: array<Light>;
@group(0) @binding(6) var<storage, read> vpls: array<Vpl>;
@group(0) @binding(7) var<storage, read> materials: array<Material>;
@group(0) @binding(8) var<storage, read_write> solutions: array<vec4<f32>>; // L_rv then L_r: direct light
// the ISM atlas (ism.wgsl): per texel (layer 0 real points, 1 virtual points; row; column) its
// depth by `ism_encode` (common.wgsl)
@group(0) @binding(9) var<storage, read> ism: array<u32>;
@group(0) @binding(10) var<storage, read_write> indirect: array<vec4<f32>>; // I_rv then I_r (with VPLs)

const PI: f32 = 3.14159265358979;

// The BRDF of material.rs: kd/pi + ks D(h) / (4 (wi.h) max(cos i, cos o)),
// D = (n+1)/(2 pi) cos^n(theta_h).
fn brdf(n: vec3<f32>, wo: vec3<f32>, wi: vec3<f32>, kd: vec3<f32>, ks: f32, exponent: f32) -> vec3<f32> {
    let co = dot(n, wo);
    let ci = dot(n, wi);
    if co <= 0.0 || ci <= 0.0 {
        return vec3<f32>(0.0);
    }
    var f = kd / PI;
    if ks > 0.0 {
        let h = normalize(wo + wi);
        let d = (exponent + 1.0) / (2.0 * PI) * pow(max(dot(n, h), 0.0), exponent);
        f = f + vec3<f32>(ks * d / (4.0 * max(dot(wi, h), 1e-8) * max(ci, co)));
    }
    return f;
}

// Fraction of a 3x3 neighbourhood of the shadow map `layer` that sees `p` (normal-offset bias).
fn visibility(light: Light, layer: i32, p: vec3<f32>, n: vec3<f32>) -> f32 {
    let size = i32(params.mode.y);
    var texel = light.info.z;
    if light.info.x < 0.5 {
        texel = texel * length(p - light.position.xyz);
    }
    let q = p + n * (1.5 * texel);
    let clip = light.view_proj * vec4<f32>(q, 1.0);
    if clip.w <= 0.0 {
        return 1.0;
    }
    let ndc = clip.xy / clip.w;
    if abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0 {
        return 1.0;
    }
    var d = length(q - light.position.xyz);
    if light.info.x > 0.5 {
        d = dot(q - light.position.xyz, light.direction.xyz);
    }
    let centre = vec2<i32>(floor(vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5) * f32(size)));
    let bias = 2.0 * texel;
    var lit = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let c = clamp(centre + vec2<i32>(dx, dy), vec2<i32>(0), vec2<i32>(size - 1));
            let stored = textureLoad(shadow_maps, c, layer, 0).x;
            lit += select(0.0, 1.0, d <= stored + bias);
        }
    }
    return lit / 9.0;
}

// basis_x and basis_y: common.wgsl.

// Visibility of VPL `index` at p from the ISM atlas `layer` (ism.wgsl's paraboloid tiles). The
// splats store exact distances to their surfaces' planes, so a receiver is offset along its
// normal only by about two texels' footprint at its distance (plus 2 mm) and compared with a
// 0.5 % depth bias; 1 where no ISMs were made.
fn ism_visibility(index: u32, layer: i32, p: vec3<f32>, n: vec3<f32>) -> f32 {
    let tile_size = params.mode.z;
    if tile_size == 0u {
        return 1.0;
    }
    let vpl = vpls[index];
    let footprint = length(p - vpl.position.xyz) * 4.0 / f32(tile_size);
    let q = p + n * (footprint + 0.002);
    let d = q - vpl.position.xyz;
    let dist = max(length(d), 1e-6);
    let nv = vpl.normal.xyz;
    let local = vec3<f32>(dot(d, basis_x(nv)), dot(d, basis_y(nv)), dot(d, nv)) / dist;
    if local.z <= 0.0 {
        return 1.0;
    }
    let uv = local.xy / (1.0 + local.z);
    let tiles = params.mode.w;
    let tile = vec2<f32>(f32(index % tiles), f32(index / tiles));
    let texel = vec2<i32>(floor((tile + (uv * 0.5 + vec2<f32>(0.5))) * f32(tile_size)));
    let lo = vec2<i32>(tile) * i32(tile_size);
    let c = clamp(texel, lo, lo + vec2<i32>(i32(tile_size) - 1));
    let width = tiles * tile_size;
    let stored = ism_decode(ism[(u32(layer) * width + u32(c.y)) * width + u32(c.x)]);
    return select(0.0, 1.0, dist * 0.995 * params.tone.z <= stored);
}

// Radiant intensity of a spot towards `dir` (from the light): smoothstep between the cones.
fn spot_intensity(light: Light, dir: vec3<f32>) -> vec3<f32> {
    return light.intensity.xyz * spot_falloff(dot(dir, light.direction.xyz), light.intensity.w, light.direction.w);
}

@compute @workgroup_size(8, 8)
fn cs_shade(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.size.x;
    let height = params.size.y;
    if id.x >= width || id.y >= height {
        return;
    }
    let pixel = id.y * width + id.x;
    let pix = vec2<i32>(id.xy);
    let gp = textureLoad(g_position, pix, 0);
    let flag = u32(gp.w + 0.5) & 3u;
    if flag == 0u {
        // nothing modelled here: composition keeps the photograph
        solutions[pixel] = vec4<f32>(0.0);
        solutions[pixel + width * height] = vec4<f32>(0.0);
        if params.size.w > 0u {
            indirect[pixel] = vec4<f32>(0.0);
            indirect[pixel + width * height] = vec4<f32>(0.0);
        }
        return;
    }
    let material = materials[u32(gp.w + 0.5) / 4u];
    let gn = textureLoad(g_normal, pix, 0);
    let ga = textureLoad(g_albedo, pix, 0);
    let p = gp.xyz;
    let n = normalize(gn.xyz);
    let wo = normalize(params.camera.xyz - p);
    let kd = ga.xyz;
    let ks = ga.w;
    let exponent = gn.w;
    // r(p): 1 for a real surface point
    let r_p = select(0.0, 1.0, flag == 1u);
    let condition = params.mode.x;

    // emitters are seen directly in both solutions (real) or in L_rv only (virtual)
    var l_rv = material.specular_emission.yzw;
    var l_r = material.specular_emission.yzw * r_p;

    // direct light from the primary lights (eqs. 5.1-5.5)
    for (var i = 0u; i < params.size.z; i++) {
        let light = lights[i];
        var wi: vec3<f32>;
        var e: vec3<f32>;
        if light.info.x < 0.5 {
            let to_light = light.position.xyz - p;
            let d2 = max(dot(to_light, to_light), 1e-8);
            wi = to_light / sqrt(d2);
            e = spot_intensity(light, -wi) / d2;
        } else {
            wi = -light.direction.xyz;
            e = light.intensity.xyz;
        }
        let l_o = brdf(n, wo, wi, kd, ks, exponent) * e * max(dot(n, wi), 0.0);
        if all(l_o == vec3<f32>(0.0)) {
            continue;
        }
        let layer = i32(light.info.y);
        let v_r = visibility(light, layer, p, n);
        var v_v = 1.0;
        if condition >= 1u {
            v_v = visibility(light, layer + 1, p, n);
        }
        let v_rv = min(v_r, v_v);                       // eq. 5.3
        l_rv += l_o * v_rv;                             // eq. 5.1
        l_r += l_o * (light.position.w * r_p) * v_r;    // eq. 5.2
    }

    // one indirect bounce from the VPLs (eqs. 5.6-5.8), visibility from the ISMs: V_r from the
    // real point cloud, V_v from the virtual one, min(V_r, V_v) for L_rv as in eq. 5.3. With
    // interleaved sampling (split n > 1) this pixel takes only the VPLs of its class, scaled by
    // n², and indirect.wgsl merges the classes.
    if params.size.w > 0u {
        let split = max(u32(params.tone.x + 0.5), 1u);
        let classes = split * split;
        var i_rv = vec3<f32>(0.0);
        var i_r = vec3<f32>(0.0);
        for (var i = (id.x % split) + split * (id.y % split); i < params.size.w; i += classes) {
            let vpl = vpls[i];
            // a slot without flux is no VPL (a live frame's VPLs on the GPU: bounce_chain.wgsl)
            if all(vpl.flux.xyz == vec3<f32>(0.0)) {
                continue;
            }
            let to_vpl = vpl.position.xyz - p;
            let d2 = max(dot(to_vpl, to_vpl), params.tone.y);   // the clamped geometry term
            let wi = normalize(to_vpl);
            let cos_vpl = max(dot(vpl.normal.xyz, -wi), 0.0);
            let l_o = brdf(n, wo, wi, kd, ks, exponent) * (vpl.flux.xyz / PI) * cos_vpl * max(dot(n, wi), 0.0) / d2;
            if all(l_o == vec3<f32>(0.0)) {
                continue;
            }
            let v_r = ism_visibility(i, 0, p, n);
            let v_v = ism_visibility(i, 1, p, n);
            i_rv += l_o * min(v_r, v_v) * (1.0 - vpl.normal.w);   // eq. 5.6
            i_r += l_o * v_r * (vpl.position.w * r_p);            // eq. 5.7 (r(pl) folded into the path flag)
        }
        indirect[pixel] = vec4<f32>(i_rv * f32(classes), 0.0);
        indirect[pixel + width * height] = vec4<f32>(i_r * f32(classes), 0.0);
    }

    // direct light (and emission); indirect.wgsl adds the indirect light
    solutions[pixel] = vec4<f32>(l_rv, f32(flag)); // w: 1 real, 2 virtual surface
    solutions[pixel + width * height] = vec4<f32>(l_r, 1.0);
}
