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
//
// Two ways to splat, one result: `cs_splat` (compute, the default) walks each splat's covered
// texels itself and keeps the nearest distance with an atomic maximum in the atlas buffer
// (`ism_encode`, common.wgsl); `vs_splat`/`fs_splat` rasterise the quads into a depth texture, which
// `cs_from_depth` copies into the same buffer. Both share the splat (`splat_point`,
// `splat_corner`) and the per-texel test (`splat_depth`), and the compute pass covers the
// texels the rasteriser covers (its two triangles, clipped at the far plane as the raster path
// clips them). Driven by ism.rs.

struct IsmParams {
    counts: vec4<u32>,    // x: points per VPL; y: tiles per atlas row; z: tile size (texels); w: atlas size (texels)
    subset: vec4<u32>,    // x: first triangle of the subset; y: its triangle count; z: VPL count; w: splats (VPLs × points)
    scale: vec4<f32>,     // x: 1 / maximum distance; y: splat radius (m)
    layer: vec4<u32>,     // x: the atlas layer (0 real, 1 virtual)
}

@group(0) @binding(0) var<uniform> params: IsmParams;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;   // 3 per triangle
@group(0) @binding(2) var<storage, read> cdf: array<f32>;               // per subset triangle, ends at 1
@group(0) @binding(3) var<storage, read> vpls: array<Vpl>;
// The atlas as the shading pass reads it: per texel (layer, row, column) `ism_encode` of its
// depth (common.wgsl), so the nearest splat is the largest value.
@group(0) @binding(4) var<storage, read_write> atlas: array<atomic<u32>>;
@group(0) @binding(5) var depth_texture: texture_depth_2d_array;        // cs_from_depth only

// pcg, unit, basis_x, basis_y and ism_encode: common.wgsl.

// One splat: the k-th stratified area sample of a VPL's cloud.
struct Splat {
    vpl_index: u32,
    tile: vec2<u32>,
    p: vec3<f32>,     // the point (world)
    n: vec3<f32>,     // its surface's normal
    // a point on the VPL's own plane cannot shadow it (the texel test's first case, which
    // depends on the splat alone): such a splat is not drawn at all — these splats lie along
    // the tile's rim and are the largest when the point is near the VPL
    culled: bool,
}

// `instance` counts splats point-major: consecutive splats belong to consecutive VPLs, so they
// fall in different tiles of the atlas (spread over a rasteriser's screen regions) instead of
// a thousand in a row in one tile; `point_id` is the (VPL, point) pair's VPL-major number,
// which seeds its random numbers, so the splats are the same in either order.
fn splat_point(instance: u32) -> Splat {
    var s: Splat;
    let per_vpl = params.counts.x;
    s.vpl_index = instance % params.subset.z;
    let k = instance / params.subset.z;
    let point_id = s.vpl_index * per_vpl + k;
    let tiles = params.counts.y;
    s.tile = vec2<u32>(s.vpl_index % tiles, s.vpl_index / tiles);

    // the k-th of this VPL's stratified area samples
    let rotation = unit(pcg(s.vpl_index * 2654435761u + 1u));
    let u = fract((f32(k) + 0.5) / f32(per_vpl) + rotation);
    let lo = cdf_search(u, params.subset.y);
    let triangle = params.subset.x + lo;
    let a = positions[3u * triangle].xyz;
    let b = positions[3u * triangle + 1u].xyz;
    let c = positions[3u * triangle + 2u].xyz;
    let h = pcg(point_id ^ 0x9e3779b9u);
    let r1 = sqrt(unit(h));
    let r2 = unit(pcg(h));
    s.p = a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2);
    let n = cross(b - a, c - a);
    s.n = n / max(length(n), 1e-20);
    // (and a VPL slot without flux is no VPL: a live frame's VPLs on the GPU, bounce_chain.wgsl)
    s.culled = abs(dot(s.p - vpls[s.vpl_index].position.xyz, s.n)) < 0.5 * params.scale.y
        || all(vpls[s.vpl_index].flux.xyz == vec3<f32>(0.0));
    return s;
}

// Corner `corner` (0..3; two triangles 0 1 2 and 2 1 3) of the splat's quad in its point's
// tangent plane, mapped into the VPL's hemisphere: xy its atlas position in texels (the
// framebuffer's pixel coordinates), z its depth, w 1 where the corner lies behind the VPL's
// surface (more than a little below its horizon).
fn splat_corner(s: Splat, corner: u32) -> vec4<f32> {
    let corners = array<vec2<f32>, 4>(vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(-1.0, 1.0), vec2<f32>(1.0, 1.0));
    let offset = corners[corner] * params.scale.y;
    let q = s.p + basis_x(s.n) * offset.x + basis_y(s.n) * offset.y;
    let vpl = vpls[s.vpl_index];
    let nv = vpl.normal.xyz;
    let d = q - vpl.position.xyz;
    let dist = max(length(d), 1e-6);
    let local = vec3<f32>(dot(d, basis_x(nv)), dot(d, basis_y(nv)), dot(d, nv)) / dist;
    let uv = local.xy / (1.0 + max(local.z, 0.0));
    let texel = (vec2<f32>(s.tile) + (uv * 0.5 + vec2<f32>(0.5))) * f32(params.counts.z);
    return vec4<f32>(texel, clamp(dist * params.scale.x, 0.0, 1.0), select(0.0, 1.0, local.z < -0.05));
}

// The splat's centre and normal in its VPL's frame (basis_x, basis_y, normal; origin at the
// VPL), which is all the per-texel test needs.
fn splat_frame(s: Splat) -> array<vec3<f32>, 2> {
    let vpl = vpls[s.vpl_index];
    let nv = vpl.normal.xyz;
    let bx = basis_x(nv);
    let by = basis_y(nv);
    let to_point = s.p - vpl.position.xyz;
    return array<vec3<f32>, 2>(
        vec3<f32>(dot(to_point, bx), dot(to_point, by), dot(to_point, nv)),
        vec3<f32>(dot(s.n, bx), dot(s.n, by), dot(s.n, nv)),
    );
}

// The depth a splat writes at the texel whose centre is `pixel` (atlas texels): the exact
// distance along the texel's direction to the splat's plane, over the maximum; -1 where the
// texel is outside the splat's tile, its VPL's hemisphere or its disc. `point` and `normal`
// are in the VPL's frame (splat_frame).
fn splat_depth(pixel: vec2<f32>, tile: vec2<u32>, point: vec3<f32>, normal: vec3<f32>) -> f32 {
    let tile_size = f32(params.counts.z);
    if any(vec2<u32>(floor(pixel / tile_size)) != tile) {
        return -1.0;
    }
    // the texel centre's direction: the inverse paraboloid mapping
    let uv = (pixel / tile_size - vec2<f32>(tile)) * 2.0 - vec2<f32>(1.0);
    let r2 = dot(uv, uv);
    if r2 > 1.0 {
        return -1.0;
    }
    let dir = vec3<f32>(2.0 * uv, 1.0 - r2) / (1.0 + r2);
    let denom = dot(dir, normal);
    if abs(denom) < 1e-6 {
        return -1.0;
    }
    let t = dot(point, normal) / denom;
    if t <= 0.0 || length(dir * t - point) > params.scale.y {
        return -1.0;
    }
    return clamp(t * params.scale.x, 0.0, 1.0);
}

// ---- compute splatting ----

// Twice the signed area of (a, b, p): which side of a→b the point p lies on.
fn edge(a: vec2<f32>, b: vec2<f32>, p: vec2<f32>) -> f32 {
    return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
}

// A triangle of a splat's quad as the rasteriser draws it: clipped at the far plane, where a
// corner behind the VPL's surface lies (the raster path puts it at depth 2 in the atlas's
// centre); a convex polygon of up to four vertices.
struct Polygon {
    v: array<vec2<f32>, 4>,
    count: u32,
}

fn clipped(a: vec4<f32>, b: vec4<f32>, c: vec4<f32>) -> Polygon {
    let centre = vec2<f32>(0.5 * f32(params.counts.w));
    // position and depth of each corner; behind: the raster path's (centre, 2)
    var corners = array<vec3<f32>, 3>(
        select(a.xyz, vec3<f32>(centre, 2.0), a.w > 0.0),
        select(b.xyz, vec3<f32>(centre, 2.0), b.w > 0.0),
        select(c.xyz, vec3<f32>(centre, 2.0), c.w > 0.0),
    );
    var out: Polygon;
    out.count = 0u;
    for (var i = 0u; i < 3u; i++) {
        let start = corners[i];
        let end = corners[(i + 1u) % 3u];
        if start.z <= 1.0 {
            out.v[out.count] = start.xy;
            out.count += 1u;
        }
        if (start.z <= 1.0) != (end.z <= 1.0) {
            let t = (1.0 - start.z) / (end.z - start.z);
            out.v[out.count] = mix(start.xy, end.xy, t);
            out.count += 1u;
        }
    }
    return out;
}

// The polygon's edges as line equations, one per column (a, b, c: a·x + b·y + c ≥ 0 inside,
// edges included), which `row_span` intersects row by row. Unused columns are always inside; a
// degenerate polygon (fewer than three vertices, no area) is never.
fn edges_of(poly: Polygon) -> mat4x3<f32> {
    var m = mat4x3<f32>(vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(0.0, 0.0, 1.0));
    let never = mat4x3<f32>(vec3<f32>(0.0, 0.0, -1.0), vec3<f32>(0.0, 0.0, -1.0), vec3<f32>(0.0, 0.0, -1.0), vec3<f32>(0.0, 0.0, -1.0));
    if poly.count < 3u {
        return never;
    }
    var area = 0.0;
    for (var i = 1u; i + 1u < poly.count; i++) {
        area += edge(poly.v[0], poly.v[i], poly.v[i + 1u]);
    }
    if area == 0.0 {
        return never;
    }
    let orientation = sign(area);
    for (var i = 0u; i < poly.count; i++) {
        let a = poly.v[i];
        let b = poly.v[(i + 1u) % poly.count];
        // edge(a, b, p) written as a line equation in p
        m[i] = orientation * vec3<f32>(-(b.y - a.y), b.x - a.x, (b.y - a.y) * a.x - (b.x - a.x) * a.y);
    }
    return m;
}

// The bounds `b` (low x, low y, high x, high y) grown by the polygon's vertices.
fn grow_bounds(b: vec4<f32>, poly: Polygon) -> vec4<f32> {
    var out = b;
    for (var i = 0u; i < poly.count; i++) {
        out = vec4<f32>(min(out.xy, poly.v[i]), max(out.zw, poly.v[i]));
    }
    return out;
}

// Narrows the span `s` (x from, x to) of a row at height `y` to where the line equation `e`
// holds (a·x + b·y + c ≥ 0).
fn narrow(s: vec2<f32>, e: vec3<f32>, y: f32) -> vec2<f32> {
    let rest = e.y * y + e.z;
    if e.x > 0.0 {
        return vec2<f32>(max(s.x, -rest / e.x), s.y);
    }
    if e.x < 0.0 {
        return vec2<f32>(s.x, min(s.y, -rest / e.x));
    }
    return select(vec2<f32>(1.0, 0.0), s, rest >= 0.0);
}

// The texels (first, last column) of row `y` whose centres lie in the polygon of `edges`,
// within the columns lo..hi; empty when first > last.
fn row_span(edges: mat4x3<f32>, y: i32, lo: i32, hi: i32) -> vec2<i32> {
    let cy = f32(y) + 0.5;
    var s = vec2<f32>(-3.0e38, 3.0e38);
    s = narrow(s, edges[0], cy);
    s = narrow(s, edges[1], cy);
    s = narrow(s, edges[2], cy);
    s = narrow(s, edges[3], cy);
    if s.x > s.y {
        return vec2<i32>(1, 0);
    }
    // centre x + 0.5 within [s.x, s.y]
    let first = max(f32(lo), ceil(s.x - 0.5));
    let last = min(f32(hi), floor(s.y - 0.5));
    return vec2<i32>(i32(first), i32(last));
}

// One invocation per splat (2D dispatch of 64-wide groups, numbered row by row): the texels of
// its tile whose centres lie in its quad as the rasteriser draws it (the same two triangles,
// clipped the same way) and pass the texel test keep the nearest depth.
@compute @workgroup_size(64)
fn cs_splat(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let instance = id.x + id.y * groups.x * 64u;
    if instance >= params.subset.w {
        return;
    }
    let s = splat_point(instance);
    if s.culled {
        return;
    }
    let k0 = splat_corner(s, 0u);
    let k1 = splat_corner(s, 1u);
    let k2 = splat_corner(s, 2u);
    let k3 = splat_corner(s, 3u);
    let first = clipped(k0, k1, k2);
    let second = clipped(k2, k1, k3);
    if first.count + second.count == 0u {
        return;
    }
    let first_edges = edges_of(first);
    let second_edges = edges_of(second);
    // the texels whose centres the polygons' bounds reach, within the tile
    let bounds = grow_bounds(grow_bounds(vec4<f32>(3.0e38, 3.0e38, -3.0e38, -3.0e38), first), second);
    let lo_f = bounds.xy;
    let hi_f = bounds.zw;
    let frame = splat_frame(s);
    let tile_size = i32(params.counts.z);
    let tile_lo = vec2<i32>(s.tile) * tile_size;
    let tile_hi = tile_lo + vec2<i32>(tile_size - 1);
    let lo = clamp(vec2<i32>(ceil(lo_f - vec2<f32>(0.5))), tile_lo, tile_hi + vec2<i32>(1));
    let hi = clamp(vec2<i32>(floor(hi_f - vec2<f32>(0.5))), tile_lo - vec2<i32>(1), tile_hi);
    let width = u32(params.counts.w);
    let base = params.layer.x * width * width;
    for (var y = lo.y; y <= hi.y; y++) {
        // the row's texels in either triangle: the first's span, then the second's outside it
        let one = row_span(first_edges, y, lo.x, hi.x);
        let two = row_span(second_edges, y, lo.x, hi.x);
        for (var x = one.x; x <= one.y; x++) {
            splat_texel(x, y, s.tile, frame, base, width);
        }
        for (var x = two.x; x <= two.y; x++) {
            if x >= one.x && x <= one.y {
                continue;
            }
            splat_texel(x, y, s.tile, frame, base, width);
        }
    }
}

// One covered texel of a splat: the texel test, and the nearest depth kept.
fn splat_texel(x: i32, y: i32, tile: vec2<u32>, frame: array<vec3<f32>, 2>, base: u32, width: u32) {
    let depth = splat_depth(vec2<f32>(f32(x), f32(y)) + vec2<f32>(0.5), tile, frame[0], frame[1]);
    if depth >= 0.0 {
        atomicMax(&atlas[base + u32(y) * width + u32(x)], ism_encode(depth));
    }
}

// ---- raster splatting ----

struct SplatOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) tile: vec2<u32>,
    // the splat's centre and normal in its VPL's frame, so the fragment shader needs neither
    // the VPL nor its frame
    @location(1) @interpolate(flat) point: vec3<f32>,
    @location(2) @interpolate(flat) normal: vec3<f32>,
}

@vertex
fn vs_splat(@builtin(vertex_index) vertex: u32) -> SplatOut {
    // four vertices per splat, shared by its two triangles through the index buffer (ism.rs)
    let s = splat_point(vertex / 4u);
    var out: SplatOut;
    out.tile = s.tile;
    if s.culled {
        out.clip = vec4<f32>(0.0, 0.0, 2.0, 1.0);
        return out;
    }
    let frame = splat_frame(s);
    out.point = frame[0];
    out.normal = frame[1];
    let corner = splat_corner(s, vertex % 4u);
    // behind the VPL's surface: nothing there can shadow its light; put it beyond the far plane
    if corner.w > 0.0 {
        out.clip = vec4<f32>(0.0, 0.0, 2.0, 1.0);
        return out;
    }
    let ndc = corner.xy / f32(params.counts.w) * 2.0 - vec2<f32>(1.0);
    out.clip = vec4<f32>(ndc.x, -ndc.y, corner.z, 1.0);
    return out;
}

@fragment
fn fs_splat(in: SplatOut) -> @builtin(frag_depth) f32 {
    let depth = splat_depth(in.clip.xy, in.tile, in.point, in.normal);
    if depth < 0.0 {
        discard;
    }
    return depth;
}

// The raster splatting's depth texture into the atlas buffer (one invocation per texel, both
// layers).
@compute @workgroup_size(8, 8)
fn cs_from_depth(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.counts.w;
    if id.x >= width || id.y >= width {
        return;
    }
    for (var layer = 0u; layer < 2u; layer++) {
        let depth = textureLoad(depth_texture, vec2<u32>(id.xy), i32(layer), 0);
        atomicStore(&atlas[(layer * width + id.y) * width + id.x], ism_encode(depth));
    }
}
