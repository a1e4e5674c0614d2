// Rasterises the scene's triangles from one viewpoint: the camera's G-buffer, a light's shadow
// map (distance only) or its reflective shadow map (distance and surface attributes).
// Driven by raster.rs; material.wgsl (Material, albedo_at) is prepended.

struct View {
    view_proj: mat4x4<f32>,
    // xyz: the eye (camera or light position); w: 1 for an orthographic (directional) view
    eye: vec4<f32>,
    // xyz: the viewing direction (used for the distance of orthographic views)
    forward: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> materials: array<Material>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) material: u32,
    @location(4) role: u32,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) material: u32,
    @location(4) @interpolate(flat) role: u32,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.uv = v.uv;
    out.material = v.material;
    out.role = v.role;
    return out;
}

fn view_distance(world: vec3<f32>) -> f32 {
    if view.eye.w > 0.5 {
        return dot(world - view.eye.xyz, view.forward.xyz);
    }
    return length(world - view.eye.xyz);
}

struct Surface {
    // xyz: world position; w: role flag (1 real, 2 virtual) + 4 * material index
    @location(0) position: vec4<f32>,
    // xyz: shading normal facing the viewer; w: Blinn-Phong exponent
    @location(1) normal: vec4<f32>,
    // rgb: diffuse albedo; w: specular ks
    @location(2) albedo: vec4<f32>,
}

fn surface(in: VertexOut) -> Surface {
    let m = materials[in.material];
    var n = normalize(in.normal);
    var to_eye = view.eye.xyz - in.world;
    if view.eye.w > 0.5 {
        to_eye = -view.forward.xyz;
    }
    if dot(n, to_eye) < 0.0 {
        n = -n;
    }
    var s: Surface;
    s.position = vec4<f32>(in.world, f32(in.role + 1u) + 4.0 * f32(in.material));
    s.normal = vec4<f32>(n, m.pattern_b.w);
    s.albedo = vec4<f32>(albedo_at(m, in.uv), m.specular_emission.x);
    return s;
}

@fragment
fn fs_gbuffer(in: VertexOut) -> Surface {
    return surface(in);
}

@fragment
fn fs_shadow(in: VertexOut) -> @location(0) f32 {
    return view_distance(in.world);
}

struct RsmOut {
    @location(0) distance: f32,
    @location(1) position: vec4<f32>,
    @location(2) normal: vec4<f32>,
    @location(3) albedo: vec4<f32>,
}

@fragment
fn fs_rsm(in: VertexOut) -> RsmOut {
    let s = surface(in);
    var out: RsmOut;
    out.distance = view_distance(in.world);
    out.position = s.position;
    out.normal = s.normal;
    out.albedo = s.albedo;
    return out;
}
