// Mirrors and glass in differential instant radiosity (thesis 5.3); driven by specular.rs.
//
// cs_trace, per camera pixel on a mirror or glass object: the reflected ray, and for glass the
// refracted ray through two interfaces (Wyman 2005: the exit point from the back-face G-buffer's
// distance along the view ray), each intersected with the object's distance impostor (a cube map
// of the scene around the object without it: position, normal, albedo per texel; linear search
// then secant refinement, Szirmay-Kalos et al. 2005). The hit surfaces are written as two
// G-buffers in the camera's pixels (GBuf_refl, GBuf_refr) for the shading pass; a ray that hits
// nothing takes the environment's radiance (L_env). Per pixel it also writes the weights: the
// Fresnel factors eta_1, eta_2 and the transmittance T_c = exp(-absorption d).
//
// cs_combine, after both G-buffers are shaded: L'_rv and L'_r by eqs. 5.18-5.20 into the
// camera's solutions, and the camera-image base CI_std of eqs. 5.23-5.25 with back-projection
// of each hit into the photograph, validated by comparing the hit with the surface the camera
// sees there. A component is taken from the photograph only where it is a real surface the
// camera sees; the same component then enters L'_r, so that L'_rv - L'_r keeps only what the
// virtual objects change (for a component not back-projected, L'_rv alone shows it).

struct Params {
    view_proj: mat4x4<f32>,   // the camera
    camera: vec4<f32>,        // xyz: camera position
    size: vec4<u32>,          // width, height, impostor face size, plane stride (texels per row)
    search: vec4<u32>,        // linear steps, secant steps, environment width, height
    env: vec4<f32>,           // rotation (fraction of a turn), has environment, scene radius, 0
    scene: vec4<f32>,         // xyz: scene bounding sphere centre
}

struct SpecularObject {
    centre_radius: vec4<f32>, // bounding sphere
    kind: vec4<f32>,          // x: 0 mirror, 1 glass; y: ior; z: material index; w: 1 real
    colour: vec4<f32>,        // mirror: reflectance; glass: absorption per metre
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var g_position: texture_2d<f32>;
@group(0) @binding(2) var g_normal: texture_2d<f32>;
@group(0) @binding(3) var back_position: texture_2d<f32>;
@group(0) @binding(4) var back_normal: texture_2d<f32>;
@group(0) @binding(5) var imp_position: texture_2d<f32>;
@group(0) @binding(6) var imp_normal: texture_2d<f32>;
@group(0) @binding(7) var imp_albedo: texture_2d<f32>;
@group(0) @binding(8) var<storage, read> objects: array<SpecularObject>;
@group(0) @binding(9) var<storage, read> env_map: array<vec4<f32>>;
// six planes of width x height (row stride size.w): refl position, normal, albedo, refr ...
@group(0) @binding(10) var<storage, read_write> hits: array<vec4<f32>>;
// four per pixel: (eta_1 weight, status refl), (eta_2 T_c weight, status refr),
// (L_env refl, 1 on a specular pixel), (L_env refr, object index); status 0 unused, 1 hit, 2 miss
@group(0) @binding(11) var<storage, read_write> info: array<vec4<f32>>;

const PI: f32 = 3.14159265358979;
const STATUS_HIT: f32 = 1.0;
const STATUS_MISS: f32 = 2.0;

fn role_of(w: f32) -> u32 {
    return u32(w + 0.5) % 4u;
}

fn material_of(w: f32) -> u32 {
    return u32(w + 0.5) / 4u;
}

// The forward, right and up axes of cube face f (+x, -x, +y, -y, +z, -z), as mod.rs's
// look_at builds the face's view.
fn face_forward(f: u32) -> vec3<f32> {
    let axis = f / 2u;
    let sign = select(1.0, -1.0, (f & 1u) == 1u);
    var v = vec3<f32>(0.0);
    v[axis] = sign;
    return v;
}

fn face_up_hint(f: u32) -> vec3<f32> {
    return select(vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(1.0, 0.0, 0.0), f / 2u == 1u);
}

// The impostor texel (x, y in the texture) that direction d from the centre of object k falls in.
fn impostor_texel(k: u32, d: vec3<f32>) -> vec2<i32> {
    let a = abs(d);
    var f = 0u;
    if a.x >= a.y && a.x >= a.z {
        f = select(0u, 1u, d.x < 0.0);
    } else if a.y >= a.z {
        f = select(2u, 3u, d.y < 0.0);
    } else {
        f = select(4u, 5u, d.z < 0.0);
    }
    let forward = face_forward(f);
    let right = normalize(cross(forward, face_up_hint(f)));
    let up = cross(right, forward);
    let depth = max(dot(d, forward), 1e-12);
    let ndc = vec2<f32>(dot(d, right), dot(d, up)) / depth;
    let s = f32(params.size.z);
    let x = clamp(i32((ndc.x * 0.5 + 0.5) * s), 0, i32(params.size.z) - 1);
    let y = clamp(i32((0.5 - ndc.y * 0.5) * s), 0, i32(params.size.z) - 1);
    return vec2<i32>(x + i32(f * params.size.z), y + i32(k * params.size.z));
}

// |x - c| minus the distance the impostor stores in x's direction (1e30 where it saw nothing).
fn beyond(k: u32, x: vec3<f32>) -> f32 {
    let c = objects[k].centre_radius.xyz;
    let stored = textureLoad(imp_position, impostor_texel(k, x - c), 0);
    if stored.w < 0.5 {
        return -1e30;
    }
    return length(x - c) - length(stored.xyz - c);
}

// The impostor texel a ray from o along d hits, or (-1, -1).
fn trace_impostor(k: u32, o: vec3<f32>, d: vec3<f32>) -> vec2<i32> {
    // to where the ray leaves the scene's bounding sphere
    let oc = o - params.scene.xyz;
    let r = params.env.z * 1.05;
    let b = dot(oc, d);
    let disc = b * b - (dot(oc, oc) - r * r);
    let t_max = select(r, -b + sqrt(max(disc, 0.0)), disc > 0.0);
    let steps = max(params.search.x, 1u);
    var t0 = 0.0;
    var f0 = beyond(k, o);
    for (var i = 1u; i <= steps; i++) {
        let t1 = t_max * f32(i) / f32(steps);
        let f1 = beyond(k, o + t1 * d);
        if f0 < 0.0 && f1 >= 0.0 && f0 > -1e29 {
            // secant refinement between t0 and t1
            var a = t0;
            var fa = f0;
            var b2 = t1;
            var fb = f1;
            for (var j = 0u; j < params.search.y; j++) {
                let t = a + (b2 - a) * (-fa) / max(fb - fa, 1e-12);
                let ft = beyond(k, o + t * d);
                if ft < 0.0 {
                    a = t;
                    fa = ft;
                } else {
                    b2 = t;
                    fb = ft;
                }
            }
            // the end of the bracket nearer the stored surface
            var t_hit = b2;
            var residual = fb;
            if -fa < fb {
                t_hit = a;
                residual = -fa;
            }
            let x = o + t_hit * d;
            let c = objects[k].centre_radius.xyz;
            // a crossing at a depth discontinuity of the impostor is no surface: there the
            // stored distance jumps and the residual stays large
            let tolerance = 0.01 * length(x - c) + 4.0 * length(x - c) / f32(params.size.z) + 1e-4;
            if residual < tolerance {
                return impostor_texel(k, x - c);
            }
        }
        t0 = t1;
        f0 = f1;
    }
    return vec2<i32>(-1, -1);
}

// The environment's radiance from direction d (nearest texel), as Environment::eval.
fn environment(d: vec3<f32>) -> vec3<f32> {
    if params.env.y < 0.5 {
        return vec3<f32>(0.0);
    }
    let theta = acos(clamp(d.y, -1.0, 1.0));
    let phi = atan2(d.x, -d.z);
    let u = fract((phi + PI) / (2.0 * PI) + params.env.x);
    let v = theta / PI;
    let w = params.search.z;
    let h = params.search.w;
    let i = min(u32(u * f32(w)), w - 1u);
    let j = min(u32(v * f32(h)), h - 1u);
    return env_map[j * w + i].xyz;
}

fn plane(p: u32, x: u32, y: u32) -> u32 {
    return p * params.size.w * params.size.y + y * params.size.w + x;
}

// Writes a hit (or nothing) into G-buffer `which` (0 refl, 1 refr) and returns the status.
fn write_hit(which: u32, x: u32, y: u32, texel: vec2<i32>) -> f32 {
    if texel.x < 0 {
        for (var q = 0u; q < 3u; q++) {
            hits[plane(3u * which + q, x, y)] = vec4<f32>(0.0);
        }
        return STATUS_MISS;
    }
    hits[plane(3u * which, x, y)] = textureLoad(imp_position, texel, 0);
    hits[plane(3u * which + 1u, x, y)] = textureLoad(imp_normal, texel, 0);
    hits[plane(3u * which + 2u, x, y)] = textureLoad(imp_albedo, texel, 0);
    return STATUS_HIT;
}

fn fresnel(cos_i: f32, eta_i: f32, eta_t: f32) -> f32 {
    let sin_t = eta_i / eta_t * sqrt(max(0.0, 1.0 - cos_i * cos_i));
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = sqrt(max(0.0, 1.0 - sin_t * sin_t));
    let rs = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    let rp = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// The specular object (index) a G-buffer point of material m belongs to: the one of that
// material whose bounding sphere is nearest.
fn object_at(p: vec3<f32>, m: u32) -> i32 {
    var best = -1;
    var best_d = 1e30;
    for (var k = 0u; k < arrayLength(&objects); k++) {
        if u32(objects[k].kind.z + 0.5) != m {
            continue;
        }
        let d = length(p - objects[k].centre_radius.xyz) - objects[k].centre_radius.w;
        if d < best_d {
            best_d = d;
            best = i32(k);
        }
    }
    return best;
}

// The pixel of this view (params.view_proj, width x height) that world point p projects to,
// or (-1, -1) off the image.
fn to_pixel(p: vec3<f32>) -> vec2<i32> {
    let clip = params.view_proj * vec4<f32>(p, 1.0);
    if clip.w <= 0.0 {
        return vec2<i32>(-1, -1);
    }
    let ndc = clip.xy / clip.w;
    let q = vec2<i32>(i32(floor((ndc.x * 0.5 + 0.5) * f32(params.size.x))), i32(floor((0.5 - ndc.y * 0.5) * f32(params.size.y))));
    if q.x < 0 || q.y < 0 || q.x >= i32(params.size.x) || q.y >= i32(params.size.y) {
        return vec2<i32>(-1, -1);
    }
    return q;
}

// How far inside the back faces point p is, seen from the eye: the back face's distance
// where p projects minus p's own (negative once p has left the object through them, or where
// no back face is seen).
fn inside_back(p: vec3<f32>) -> f32 {
    let q = to_pixel(p);
    if q.x < 0 {
        return -1.0;
    }
    let b = textureLoad(back_position, q, 0);
    if role_of(b.w) == 0u {
        return -1.0;
    }
    return length(b.xyz - params.camera.xyz) - length(p - params.camera.xyz);
}

// Where the refracted ray from p1 along t1 leaves a glass object through its back faces: a
// search along the ray in the back-face G-buffer (like the impostor's: linear steps over the
// bounding diameter, then bisection), which refines Wyman's estimate (the back face's distance
// along the view ray, the start when the search brackets nothing).
fn exit_point(p1: vec3<f32>, t1: vec3<f32>, radius: f32, pixel: vec2<i32>) -> vec3<f32> {
    let v = normalize(p1 - params.camera.xyz);
    let back = textureLoad(back_position, pixel, 0);
    var d_view = 0.0;
    if role_of(back.w) != 0u {
        d_view = max(dot(back.xyz - p1, v), 0.0);
    }
    let steps = 24u;
    let t_max = 2.0 * radius;
    var t0 = 0.0;
    for (var i = 1u; i <= steps; i++) {
        let t = t_max * f32(i) / f32(steps);
        if inside_back(p1 + t * t1) < 0.0 {
            var a = t0;
            var b = t;
            for (var j = 0u; j < 8u; j++) {
                let m = 0.5 * (a + b);
                if inside_back(p1 + m * t1) < 0.0 {
                    b = m;
                } else {
                    a = m;
                }
            }
            return p1 + 0.5 * (a + b) * t1;
        }
        t0 = t;
    }
    return p1 + d_view * t1;
}

@compute @workgroup_size(8, 8)
fn cs_trace(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.size.x;
    let height = params.size.y;
    if id.x >= width || id.y >= height {
        return;
    }
    let pixel = id.y * width + id.x;
    let g = textureLoad(g_position, vec2<i32>(id.xy), 0);
    var k = -1;
    if role_of(g.w) != 0u {
        k = object_at(g.xyz, material_of(g.w));
    }
    if k < 0 {
        for (var q = 0u; q < 6u; q++) {
            hits[plane(q, id.x, id.y)] = vec4<f32>(0.0);
        }
        for (var q = 0u; q < 4u; q++) {
            info[4u * pixel + q] = vec4<f32>(0.0);
        }
        return;
    }
    let object = objects[u32(k)];
    let p1 = g.xyz;
    let n1 = normalize(textureLoad(g_normal, vec2<i32>(id.xy), 0).xyz); // faces the camera
    let v = normalize(p1 - params.camera.xyz);
    let eps = 1e-4 * (1.0 + length(p1 - params.camera.xyz));
    let reflected = reflect(v, n1);
    let refl_texel = trace_impostor(u32(k), p1 + eps * n1, reflected);
    let refl_status = write_hit(0u, id.x, id.y, refl_texel);
    let env_refl = select(vec3<f32>(0.0), environment(reflected), refl_status == STATUS_MISS);
    if object.kind.x < 0.5 {
        // a mirror
        for (var q = 3u; q < 6u; q++) {
            hits[plane(q, id.x, id.y)] = vec4<f32>(0.0);
        }
        info[4u * pixel] = vec4<f32>(object.colour.xyz, refl_status);
        info[4u * pixel + 1u] = vec4<f32>(0.0);
        info[4u * pixel + 2u] = vec4<f32>(env_refl, 1.0);
        info[4u * pixel + 3u] = vec4<f32>(0.0, 0.0, 0.0, f32(k));
        return;
    }
    // glass: in at p1, out at the back face (Wyman: the distance along the view ray)
    let ior = object.kind.y;
    let cos1 = max(-dot(v, n1), 0.0);
    let f1 = fresnel(cos1, 1.0, ior);
    let t1 = refract(v, n1, 1.0 / ior);
    let p2 = exit_point(p1, t1, object.centre_radius.w, vec2<i32>(id.xy));
    // the back face's normal where the exit point projects (the pixel's own where it is off
    // the object); the back G-buffer's normal faces the eye, so it opposes t1
    var n2 = textureLoad(back_normal, vec2<i32>(id.xy), 0).xyz;
    let q2 = to_pixel(p2);
    if q2.x >= 0 {
        let at = textureLoad(back_position, q2, 0);
        if role_of(at.w) != 0u {
            n2 = textureLoad(back_normal, q2, 0).xyz;
        }
    }
    n2 = normalize(n2);
    var t2 = refract(t1, n2, ior);
    var f2 = fresnel(max(-dot(t1, n2), 0.0), ior, 1.0);
    if dot(t2, t2) < 1e-12 {
        // total internal reflection at the exit: the light leaves along the mirrored direction
        t2 = reflect(t1, n2);
        f2 = 0.0;
    }
    t2 = normalize(t2);
    let refr_texel = trace_impostor(u32(k), p2 + eps * t2, t2);
    let refr_status = write_hit(1u, id.x, id.y, refr_texel);
    let env_refr = select(vec3<f32>(0.0), environment(t2), refr_status == STATUS_MISS);
    let transmittance = exp(-object.colour.xyz * length(p2 - p1));
    info[4u * pixel] = vec4<f32>(vec3<f32>(f1), refl_status);
    info[4u * pixel + 1u] = vec4<f32>((1.0 - f1) * (1.0 - f2) * transmittance, refr_status);
    info[4u * pixel + 2u] = vec4<f32>(env_refl, 1.0);
    info[4u * pixel + 3u] = vec4<f32>(env_refr, f32(k));
}

// ---- composition inputs (after GBuf_refl and GBuf_refr are shaded) ----

@group(0) @binding(12) var<storage, read_write> solutions: array<vec4<f32>>; // L_rv, then L_r
@group(0) @binding(13) var<storage, read> refl_solutions: array<vec4<f32>>;
@group(0) @binding(14) var<storage, read> refr_solutions: array<vec4<f32>>;
@group(0) @binding(15) var<storage, read> photo: array<vec4<f32>>;
// CI_std per pixel in the photograph's encoding; w: 1 on a specular pixel
@group(0) @binding(16) var<storage, read_write> base: array<vec4<f32>>;
// specular pixels, components used, back-projected, shaded hits not back-projected, misses
@group(0) @binding(17) var<storage, read_write> counts: array<atomic<u32>, 8>;

fn decode(c: vec3<f32>) -> vec3<f32> {
    return pow(max(c, vec3<f32>(0.0)), vec3<f32>(2.2));
}

fn encode(c: vec3<f32>) -> vec3<f32> {
    return pow(clamp(c, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(1.0 / 2.2));
}

// The camera pixel that shows world point h, when the camera sees h itself there and it is
// real (the validation of eq. 5.24); -1 otherwise.
fn back_project(h: vec3<f32>) -> i32 {
    let q = to_pixel(h);
    if q.x < 0 {
        return -1;
    }
    let seen = textureLoad(g_position, q, 0);
    let tolerance = 0.02 * length(h - params.camera.xyz) + 1e-3;
    if role_of(seen.w) != 1u || length(seen.xyz - h) > tolerance {
        return -1;
    }
    return q.y * i32(params.size.x) + q.x;
}

@compute @workgroup_size(8, 8)
fn cs_combine(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.size.x;
    let height = params.size.y;
    if id.x >= width || id.y >= height {
        return;
    }
    let pixel = id.y * width + id.x;
    let n = width * height;
    let env_refl = info[4u * pixel + 2u];
    if env_refl.w < 0.5 {
        base[pixel] = vec4<f32>(0.0);
        return;
    }
    atomicAdd(&counts[0], 1u);
    let real_p = role_of(textureLoad(g_position, vec2<i32>(id.xy), 0).w) == 1u;
    var l_rv = vec3<f32>(0.0);
    var l_r_all = vec3<f32>(0.0);
    var l_r_projected = vec3<f32>(0.0);
    var ci = vec3<f32>(0.0);
    var all_real = real_p;
    for (var c = 0u; c < 2u; c++) {
        let weight = info[4u * pixel + c];
        let status = weight.w;
        if status < 0.5 || all(weight.xyz == vec3<f32>(0.0)) {
            continue;
        }
        atomicAdd(&counts[1], 1u);
        if status > 1.5 {
            // the ray left the modelled scene: L_env (real light, in the photograph only at
            // a real pixel whose every component is real)
            let env = weight.xyz * info[4u * pixel + 2u + c].xyz;
            l_rv += env;
            l_r_all += env;
            atomicAdd(&counts[4], 1u);
            continue;
        }
        var rv = refl_solutions[pixel].xyz;
        var r = refl_solutions[pixel + n].xyz;
        if c == 1u {
            rv = refr_solutions[pixel].xyz;
            r = refr_solutions[pixel + n].xyz;
        }
        l_rv += weight.xyz * rv;
        l_r_all += weight.xyz * r;
        let hit = hits[plane(3u * c, id.x, id.y)];
        if role_of(hit.w) != 1u {
            all_real = false;
            atomicAdd(&counts[3], 1u);
            continue;
        }
        let q = back_project(hit.xyz);
        if q < 0 {
            atomicAdd(&counts[3], 1u);
            continue;
        }
        atomicAdd(&counts[2], 1u);
        ci += weight.xyz * decode(photo[u32(q)].xyz);
        l_r_projected += weight.xyz * r;
    }
    solutions[pixel] = vec4<f32>(l_rv, solutions[pixel].w);
    if all_real {
        // eq. 5.23, first case: the photograph shows the real reflection and refraction
        solutions[pixel + n] = vec4<f32>(l_r_all, 1.0);
        base[pixel] = vec4<f32>(photo[pixel].xyz, 1.0);
    } else {
        solutions[pixel + n] = vec4<f32>(l_r_projected, 1.0);
        base[pixel] = vec4<f32>(encode(ci), 1.0);
    }
}

// ---- caustic maps (5.27-5.29): photons from a light through one mirror or glass object ----
//
// cs_trace has run from the light's view (params: the light's view and the light as "camera"),
// so hits and info hold, per light pixel on the object, where its reflected and refracted
// photons land. cs_photons gives each photon its flux and splats it into the caustic buffer
// in the camera's pixels: a disc kernel on the receiving surface whose radius is the photon's
// own footprint (from the hits of its neighbours in the light's pixel grid), summed in 64-bit
// fixed point so that the result does not depend on the order of the atomic additions.
// cs_caustics_apply adds rho/pi E to L_rv, and to L_r where light, object and receiver are all
// real (5.29).

struct Photons {
    light_position: vec4<f32>,  // xyz; w: 1 real light
    light_direction: vec4<f32>, // xyz: spot axis; w: cos outer
    intensity: vec4<f32>,       // rgb: W/sr; w: cos inner
    camera_view_proj: mat4x4<f32>,
    camera: vec4<f32>,          // xyz: camera position; w: tan of half a camera pixel (y)
    map: vec4<f32>,             // x: tan of half the map's fov; y: map size; z: object index; w: 1 real object
    size: vec4<u32>,            // camera width, height, most splat half-width in pixels, 0
}

@group(0) @binding(18) var<uniform> photons: Photons;
@group(0) @binding(19) var cam_position: texture_2d<f32>;
@group(0) @binding(20) var cam_normal: texture_2d<f32>;
// per camera pixel 12 words: E of all photons (r lo, r hi, g lo, g hi, b lo, b hi), then the
// same for photons whose light, object and receiver are real
@group(0) @binding(21) var<storage, read_write> caustic: array<atomic<u32>>;
// photons with flux, photons that reached a camera pixel
@group(0) @binding(22) var<storage, read_write> photon_counts: array<atomic<u32>, 4>;
@group(0) @binding(23) var cam_albedo: texture_2d<f32>;

const FIXED_SCALE: f32 = 1048576.0; // 2^20 per W/m^2
const TWO_32: f32 = 4294967296.0;

fn add_fixed(index: u32, value: f32) {
    let s = max(value, 0.0) * FIXED_SCALE;
    let hi = floor(s / TWO_32);
    let lo = u32(s - hi * TWO_32);
    let old = atomicAdd(&caustic[index], lo);
    var carry = u32(hi);
    if old + lo < old {
        carry += 1u;
    }
    if carry > 0u {
        atomicAdd(&caustic[index + 1u], carry);
    }
}

fn read_fixed(index: u32) -> f32 {
    let lo = atomicLoad(&caustic[index]);
    let hi = atomicLoad(&caustic[index + 1u]);
    return (f32(hi) * TWO_32 + f32(lo)) / FIXED_SCALE;
}

// Radiant intensity of the light towards `dir` (as shade.wgsl's spot_intensity).
fn light_intensity(dir: vec3<f32>) -> vec3<f32> {
    let c = dot(dir, photons.light_direction.xyz);
    return photons.intensity.xyz * spot_falloff(c, photons.intensity.w, photons.light_direction.w);
}

// The hit of component c of light pixel q, when it is a photon of the target object.
fn photon_hit(c: u32, q: vec2<i32>) -> vec4<f32> {
    let n = i32(params.size.x);
    if q.x < 0 || q.y < 0 || q.x >= n || q.y >= n {
        return vec4<f32>(0.0);
    }
    let pixel = u32(q.y) * params.size.x + u32(q.x);
    if info[4u * pixel + c].w != STATUS_HIT || u32(info[4u * pixel + 3u].w + 0.5) != u32(photons.map.z + 0.5) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(hits[plane(3u * c, u32(q.x), u32(q.y))].xyz, 1.0);
}

@compute @workgroup_size(8, 8)
fn cs_photons(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = params.size.x;
    if id.x >= n || id.y >= n {
        return;
    }
    let pixel = id.y * n + id.x;
    if info[4u * pixel + 2u].w < 0.5 || u32(info[4u * pixel + 3u].w + 0.5) != u32(photons.map.z + 0.5) {
        return;
    }
    let p1 = textureLoad(g_position, vec2<i32>(id.xy), 0).xyz;
    let to_p1 = p1 - photons.light_position.xyz;
    let omega = normalize(to_p1);
    // the solid angle of this light pixel: (2 tan(half) / size)^2 cos^3 of its angle off the axis
    let delta = 2.0 * photons.map.x / photons.map.y;
    let ndc = vec2<f32>((f32(id.x) + 0.5) / photons.map.y * 2.0 - 1.0, 1.0 - (f32(id.y) + 0.5) / photons.map.y * 2.0);
    let plane_xy = ndc * photons.map.x;
    let cos_axis = 1.0 / sqrt(1.0 + dot(plane_xy, plane_xy));
    let d_omega = delta * delta * cos_axis * cos_axis * cos_axis;
    let flux_in = light_intensity(omega) * d_omega;
    if all(flux_in <= vec3<f32>(0.0)) {
        return;
    }
    let real_path = photons.light_position.w > 0.5 && photons.map.w > 0.5;
    for (var c = 0u; c < 2u; c++) {
        let here = photon_hit(c, vec2<i32>(id.xy));
        if here.w < 0.5 {
            continue;
        }
        let weight = info[4u * pixel + c].xyz;
        let flux = flux_in * weight;
        if all(flux <= vec3<f32>(0.0)) {
            continue;
        }
        atomicAdd(&photon_counts[0], 1u);
        let h = here.xyz;
        let n_h = normalize(hits[plane(3u * c + 1u, id.x, id.y)].xyz);
        // the photon's footprint: the spacing of its neighbours' hits in the light's grid
        let path = length(to_p1) + length(h - p1);
        let unfocused = path * delta;
        var spacing = 0.0;
        var found = 0u;
        for (var k = 0u; k < 4u; k++) {
            var step = vec2<i32>(1, 0);
            if k == 1u {
                step = vec2<i32>(-1, 0);
            } else if k == 2u {
                step = vec2<i32>(0, 1);
            } else if k == 3u {
                step = vec2<i32>(0, -1);
            }
            let other = photon_hit(c, vec2<i32>(id.xy) + step);
            if other.w > 0.5 {
                spacing = max(spacing, length(other.xyz - h));
                found += 1u;
            }
        }
        if found == 0u {
            spacing = unfocused;
        }
        // project the hit into the camera
        let clip = photons.camera_view_proj * vec4<f32>(h, 1.0);
        if clip.w <= 0.0 {
            continue;
        }
        let cam_ndc = clip.xy / clip.w;
        let width = photons.size.x;
        let height = photons.size.y;
        let centre = vec2<f32>((cam_ndc.x * 0.5 + 0.5) * f32(width), (0.5 - cam_ndc.y * 0.5) * f32(height));
        let cam_pixel = 2.0 * photons.camera.w * length(h - photons.camera.xyz); // a camera pixel at h
        let r = max(clamp(2.0 * spacing, 0.1 * unfocused, 8.0 * unfocused), 1.5 * cam_pixel);
        let reach = min(i32(ceil(r / max(cam_pixel, 1e-9))), i32(photons.size.z));
        let lo = vec2<i32>(floor(centre)) - vec2<i32>(reach);
        let hi = vec2<i32>(floor(centre)) + vec2<i32>(reach);
        if hi.x < 0 || hi.y < 0 || lo.x >= i32(width) || lo.y >= i32(height) {
            continue;
        }
        let norm = 2.0 / (PI * r * r);
        var reached = false;
        for (var y = max(lo.y, 0); y <= min(hi.y, i32(height) - 1); y++) {
            for (var x = max(lo.x, 0); x <= min(hi.x, i32(width) - 1); x++) {
                let g = textureLoad(cam_position, vec2<i32>(x, y), 0);
                if role_of(g.w) == 0u {
                    continue;
                }
                let dx = g.xyz - h;
                let d2 = dot(dx, dx);
                if d2 >= r * r || abs(dot(dx, n_h)) > 0.25 * r + 1e-4 {
                    continue;
                }
                let n_recv = textureLoad(cam_normal, vec2<i32>(x, y), 0).xyz;
                if dot(n_recv, n_h) < 0.5 {
                    continue;
                }
                let e = flux * (norm * (1.0 - d2 / (r * r)));
                let index = 12u * (u32(y) * width + u32(x));
                add_fixed(index, e.x);
                add_fixed(index + 2u, e.y);
                add_fixed(index + 4u, e.z);
                if real_path && role_of(g.w) == 1u {
                    add_fixed(index + 6u, e.x);
                    add_fixed(index + 8u, e.y);
                    add_fixed(index + 10u, e.z);
                }
                reached = true;
            }
        }
        if reached {
            atomicAdd(&photon_counts[1], 1u);
        }
    }
}

@compute @workgroup_size(8, 8)
fn cs_caustics_apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = photons.size.x;
    let height = photons.size.y;
    if id.x >= width || id.y >= height {
        return;
    }
    let pixel = id.y * width + id.x;
    let index = 12u * pixel;
    let all_e = vec3<f32>(read_fixed(index), read_fixed(index + 2u), read_fixed(index + 4u));
    if all(all_e == vec3<f32>(0.0)) {
        return;
    }
    let real_e = vec3<f32>(read_fixed(index + 6u), read_fixed(index + 8u), read_fixed(index + 10u));
    let rho = textureLoad(cam_albedo, vec2<i32>(id.xy), 0).xyz / PI;
    let n = width * height;
    let rv = solutions[pixel];
    solutions[pixel] = vec4<f32>(rv.xyz + rho * all_e, rv.w);
    let r = solutions[pixel + n];
    solutions[pixel + n] = vec4<f32>(r.xyz + rho * real_e, r.w);
}
