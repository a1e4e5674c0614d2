// Imperfect shadow maps (Ritschel et al. 2008; thesis 5.2.4 and 5.2.8): one small hemispherical
// depth map per VPL, all in one atlas, rendered from a point cloud instead of the triangles.
// One instance per (point, VPL), point-major: the point is drawn on the GPU from the subset's triangles in
// proportion to their area (stratified per VPL, rotated by a per-VPL offset, so every VPL sees
// its own cloud spread over all surfaces), then splatted as a quad in the point's tangent plane
// (geometry-aligned splats, 5.2.8) whose four corners are each mapped into the VPL's hemisphere
// (paraboloid mapping of every corner, so a splat grows and shrinks with its position relative
// to the VPL). Each covered texel then intersects its own direction with the splat's plane and
// keeps the hit only inside the splat's disc, writing the exact distance to the VPL (over a
// scene-wide maximum) rather than a depth interpolated across the quad: a surface's own splats
// then lie exactly in it, which keeps receivers from shadowing themselves at grazing angles.
// Driven by ism.rs.

struct IsmParams {
    counts: vec4<u32>,    // x: points per VPL; y: tiles per atlas row; z: tile size (texels); w: atlas size (texels)
    subset: vec4<u32>,    // x: first triangle of the subset; y: its triangle count; z: VPL count
    scale: vec4<f32>,     // x: 1 / maximum distance; y: splat radius (m)
}

@group(0) @binding(0) var<uniform> params: IsmParams;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;   // 3 per triangle
@group(0) @binding(2) var<storage, read> cdf: array<f32>;               // per subset triangle, ends at 1
@group(0) @binding(3) var<storage, read> vpls: array<Vpl>;

struct SplatOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) tile: vec2<u32>,
    // the splat's centre and normal in its VPL's frame (basis_x, basis_y, normal; origin at
    // the VPL), so the fragment shader needs neither the VPL nor its frame
    @location(1) @interpolate(flat) point: vec3<f32>,
    @location(2) @interpolate(flat) normal: vec3<f32>,
}

// pcg, unit, basis_x and basis_y: common.wgsl.

@vertex
fn vs_splat(@builtin(vertex_index) vertex: u32) -> SplatOut {
    // four vertices per splat, shared by its two triangles through the index buffer (ism.rs)
    let instance = vertex / 4u;
    var out: SplatOut;
    // point-major order: consecutive splats belong to consecutive VPLs, so they fall in
    // different tiles of the atlas (spread over the rasteriser's screen regions) instead of a
    // thousand in a row in one tile; `point_id` is the (VPL, point) pair's VPL-major number,
    // which seeds its random numbers, so the splats are the same in either order
    let per_vpl = params.counts.x;
    let vpl_index = instance % params.subset.z;
    let k = instance / params.subset.z;
    let point_id = vpl_index * per_vpl + k;
    let tiles = params.counts.y;
    out.tile = vec2<u32>(vpl_index % tiles, vpl_index / tiles);

    // the k-th of this VPL's stratified area samples
    let rotation = unit(pcg(vpl_index * 2654435761u + 1u));
    let u = fract((f32(k) + 0.5) / f32(per_vpl) + rotation);
    var lo = 0u;
    var hi = params.subset.y - 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if cdf[mid] < u {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    let triangle = params.subset.x + lo;
    let a = positions[3u * triangle].xyz;
    let b = positions[3u * triangle + 1u].xyz;
    let c = positions[3u * triangle + 2u].xyz;
    let h = pcg(point_id ^ 0x9e3779b9u);
    let r1 = sqrt(unit(h));
    let r2 = unit(pcg(h));
    let p = a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2);
    var n = cross(b - a, c - a);
    n = n / max(length(n), 1e-20);

    // the splat's corner in the point's tangent plane (two triangles: corners 0 1 2, 2 1 3)
    let corners = array<vec2<f32>, 4>(vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(-1.0, 1.0), vec2<f32>(1.0, 1.0));
    let corner = corners[vertex % 4u] * params.scale.y;
    let q = p + basis_x(n) * corner.x + basis_y(n) * corner.y;

    // into the VPL's hemisphere
    let vpl = vpls[vpl_index];
    // a point on the VPL's own plane cannot shadow it (the fragment shader's first test, which
    // depends on the splat alone): the whole splat goes beyond the far plane instead of being
    // rasterised and discarded texel by texel — these splats lie along the tile's rim and are
    // the largest when the point is near the VPL
    if abs(dot(p - vpl.position.xyz, n)) < 0.5 * params.scale.y {
        out.clip = vec4<f32>(0.0, 0.0, 2.0, 1.0);
        return out;
    }
    let nv = vpl.normal.xyz;
    let bx = basis_x(nv);
    let by = basis_y(nv);
    let to_point = p - vpl.position.xyz;
    out.point = vec3<f32>(dot(to_point, bx), dot(to_point, by), dot(to_point, nv));
    out.normal = vec3<f32>(dot(n, bx), dot(n, by), dot(n, nv));
    let d = q - vpl.position.xyz;
    let dist = max(length(d), 1e-6);
    let local = vec3<f32>(dot(d, bx), dot(d, by), dot(d, nv)) / dist;
    // behind the VPL's surface: nothing there can shadow its light; put it beyond the far plane
    if local.z < -0.05 {
        out.clip = vec4<f32>(0.0, 0.0, 2.0, 1.0);
        return out;
    }
    let uv = local.xy / (1.0 + max(local.z, 0.0));
    let texel = (vec2<f32>(out.tile) + (uv * 0.5 + vec2<f32>(0.5))) * f32(params.counts.z);
    let ndc = texel / f32(params.counts.w) * 2.0 - vec2<f32>(1.0);
    out.clip = vec4<f32>(ndc.x, -ndc.y, clamp(dist * params.scale.x, 0.0, 1.0), 1.0);
    return out;
}

// Keeps a splat inside its VPL's tile and its disc; writes the exact distance along the texel's
// direction to the splat's plane. All in the VPL's frame (the vertex shader's `point` and
// `normal`); a splat on the VPL's own plane never gets here (the vertex shader culls it).
@fragment
fn fs_splat(in: SplatOut) -> @builtin(frag_depth) f32 {
    let tile_size = f32(params.counts.z);
    let tile = vec2<u32>(floor(in.clip.xy / tile_size));
    if any(tile != in.tile) {
        discard;
    }
    // the texel centre's direction: the inverse paraboloid mapping
    let uv = (in.clip.xy / tile_size - vec2<f32>(in.tile)) * 2.0 - vec2<f32>(1.0);
    let r2 = dot(uv, uv);
    if r2 > 1.0 {
        discard;
    }
    let dir = vec3<f32>(2.0 * uv, 1.0 - r2) / (1.0 + r2);
    let denom = dot(dir, in.normal);
    if abs(denom) < 1e-6 {
        discard;
    }
    let t = dot(in.point, in.normal) / denom;
    if t <= 0.0 || length(dir * t - in.point) > params.scale.y {
        discard;
    }
    return clamp(t * params.scale.x, 0.0, 1.0);
}
