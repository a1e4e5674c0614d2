// A material as the GPU reads it (mesh.rs's `GpuMaterial`) and its albedo at a texture
// coordinate; the Rust side prepends this file to raster.wgsl and bounce_chain.wgsl.

struct Material {
    albedo: vec4<f32>,       // kd; w: pattern kind (0 none, 1 wood, 2 checker, 3 stripes)
    pattern_a: vec4<f32>,    // w: pattern scale
    pattern_b: vec4<f32>,    // w: Blinn-Phong exponent
    specular_emission: vec4<f32>, // x: ks; yzw: emission
}

const PI: f32 = 3.14159265358979;

// The albedo at a texture coordinate: kd times the pattern (as material.rs evaluates it).
fn albedo_at(m: Material, uv: vec2<f32>) -> vec3<f32> {
    let kind = u32(m.albedo.w + 0.5);
    var t = vec3<f32>(1.0);
    if kind == 1u {
        let x = uv.x;
        let y = uv.y * 7.0;
        let warp = 0.15 * sin(y * 3.1 + sin(x * 2.3)) + 0.05 * sin(y * 17.0);
        let r = fract((x + warp) * m.pattern_a.w);
        let grain = 0.5 + 0.5 * cos(r * 2.0 * PI);
        t = mix(m.pattern_a.xyz, m.pattern_b.xyz, pow(grain, 3.0) * 0.8);
    } else if kind == 2u {
        let i = i32(floor(uv.x * m.pattern_a.w)) + i32(floor(uv.y * m.pattern_a.w));
        t = select(m.pattern_b.xyz, m.pattern_a.xyz, (i & 1) == 0);
    } else if kind == 3u {
        let i = i32(floor(uv.y * m.pattern_a.w));
        t = select(m.pattern_b.xyz, m.pattern_a.xyz, (i & 1) == 0);
    }
    return m.albedo.xyz * t;
}

