// The multiple-bounce light source of a live frame, made and consumed on the GPU (bounce_chain.rs;
// bounce.rs says what a bounce computes, and its CPU steps are the reference these follow):
//
// 1. cs_link (one workgroup): the slots linked to the source VPLs in proportion to their
//    luminance flux (stratified inversion of their CDF, as vpl.rs's `stratify`), each with a
//    cosine-distributed direction from a Hammersley set over its source's slots (bounce.rs's
//    `link_slots`); bounce.wgsl's cs_nearest then searches each slot's cone;
// 2. cs_spawn (a thread per slot): the new VPLs at the nearest hits (bounce.rs's
//    `spawn_from_hits`): two slots of the pilot per search slot, zero where none;
// 3. cs_split (one workgroup): every source's luminance flux (the first bounce's VPLs, each
//    pilot) and the budget split over them by largest remainder (vpl.rs's `split_budget`): the
//    plan, which the draws read;
// 4. cs_resample (one workgroup per pilot): the pilot's share drawn from it in proportion to
//    flux (vpl.rs's `resample`) into the frame's VPLs at the pilot's offset; the first bounce's
//    share is drawn by vpl.wgsl's cs_draw_planned.
//
// A VPL slot without flux (zero) is no VPL: the ISMs and the shading skip it. common.wgsl, cdf.wgsl
// (cdf_search over `cdf`) and material.wgsl are prepended. Every loop runs at most
// n / 256 + 256 times per invocation (llvmpipe ends longer loops).

const GROUP: u32 = 256u;
const SOURCES: u32 = 8u;   // the first bounce and at most 7 further ones (MAX_BOUNCES)

struct ChainParams {
    counts: vec4<u32>,   // x: entries (sources / pilot slots); y: slots or budget; z: seed; w: bounce index (0: bounce 2)
    more: vec4<u32>,     // x: triangles; y: the first entry read (link, resample) or pilot slot written (spawn); z: the plan's source index; w: sources
}

struct Slot {
    origin: vec4<f32>,     // the source VPL's position; w: the slot's rotation of its candidate strata
    normal: vec4<f32>,     // the source VPL's normal
    direction: vec4<f32>,  // ω_o (zero: a dead slot, whose cone holds nothing)
}

struct Link {
    flux: vec4<f32>,       // the source's flux / (p · slots); w: 1 for a live slot
    flags: vec4<f32>,      // x: the source's path flag; y: its ir
}

@group(0) @binding(0) var<uniform> chain: ChainParams;
@group(0) @binding(1) var<storage, read> entries: array<Vpl>;          // sources, or pilots
@group(0) @binding(2) var<storage, read_write> cdf: array<f32>;        // scratch: the entries' CDF
@group(0) @binding(3) var<storage, read_write> slots: array<Slot>;
@group(0) @binding(4) var<storage, read_write> links: array<Link>;

// cs_link: per entry, how many entries before it have weight (its index in the host's list of
// the previous bounce's VPLs, which holds only those: it seeds the entry's directions)
@group(0) @binding(15) var<storage, read_write> ranks: array<u32>;

var<workgroup> partial: array<f32, 256>;
var<workgroup> partial_count: array<u32, 256>;
var<workgroup> total_weight: f32;

// A VPL's weight: the luminance of its flux, 0 where that is not positive and finite.
fn weight_of(v: Vpl) -> f32 {
    let w = luminance(v.flux.xyz);
    return select(0.0, w, w > 0.0 && w <= 3.4e38);
}

// The inclusive prefix sum of `cdf[0..n]` in place, by the workgroup (chunks of n / 256 per
// thread, the chunks' sums scanned by one thread); the total is left in `total_weight`. Called
// in uniform control flow.
fn scan_cdf(n: u32, lid: u32) {
    let chunk = (n + GROUP - 1u) / GROUP;
    let first = lid * chunk;
    let last = min(first + chunk, n);
    var sum = 0.0;
    for (var i = first; i < last; i++) {
        sum += cdf[i];
    }
    partial[lid] = sum;
    workgroupBarrier();
    if lid == 0u {
        var running = 0.0;
        for (var t = 0u; t < GROUP; t++) {
            let own = partial[t];
            partial[t] = running;
            running += own;
        }
        total_weight = running;
    }
    workgroupBarrier();
    var running = partial[lid];
    for (var i = first; i < last; i++) {
        running += cdf[i];
        cdf[i] = running;
    }
    storageBarrier();
    workgroupBarrier();
}

// `ranks[i]`: the entries before i with weight (`cdf[0..n]` holding the weights), by the
// workgroup in chunks as `scan_cdf`. Called in uniform control flow.
fn rank_entries(n: u32, lid: u32) {
    let chunk = (n + GROUP - 1u) / GROUP;
    let first = lid * chunk;
    let last = min(first + chunk, n);
    var count = 0u;
    for (var i = first; i < last; i++) {
        count += select(0u, 1u, cdf[i] > 0.0);
    }
    partial_count[lid] = count;
    workgroupBarrier();
    if lid == 0u {
        var running = 0u;
        for (var t = 0u; t < GROUP; t++) {
            let own = partial_count[t];
            partial_count[t] = running;
            running += own;
        }
    }
    workgroupBarrier();
    var running = partial_count[lid];
    for (var i = first; i < last; i++) {
        ranks[i] = running;
        running += select(0u, 1u, cdf[i] > 0.0);
    }
    storageBarrier();
    workgroupBarrier();
}

// The entry stratum `k` of `count` falls in (cdf_search: the first whose CDF reaches it).
fn stratum_entry(k: u32, count: u32, n: u32, total: f32) -> u32 {
    return cdf_search((f32(k) + 0.5) / f32(count) * total, n);
}

fn radical_inverse(bits: u32) -> f32 {
    return f32(reverseBits(bits)) * (1.0 / 4294967296.0);
}

@compute @workgroup_size(256)
fn cs_link(@builtin(local_invocation_index) lid: u32) {
    let n = chain.counts.x;
    let count = chain.counts.y;
    let seed = chain.counts.z;
    let first = chain.more.y;
    for (var i = lid; i < n; i += GROUP) {
        cdf[i] = weight_of(entries[first + i]);
    }
    storageBarrier();
    workgroupBarrier();
    rank_entries(n, lid);
    scan_cdf(n, lid);
    let total = workgroupUniformLoad(&total_weight);
    for (var j = lid; j < count; j += GROUP) {
        var slot: Slot;
        var link: Link;
        slot.origin = vec4<f32>(0.0, 0.0, 0.0, unit(pcg((seed * 31u) ^ pcg(j + 7u))));
        if !(total > 0.0) {
            slots[j] = slot;
            links[j] = link;
            continue;
        }
        let source = stratum_entry(j, count, n, total);
        // the source's slots: the strata before and after j that fall in it (a binary search
        // over the strata, which fall in order)
        var lo = 0u;
        var hi = j;
        while lo < hi {
            let mid = (lo + hi) / 2u;
            if stratum_entry(mid, count, n, total) < source {
                lo = mid + 1u;
            } else {
                hi = mid;
            }
        }
        let start = lo;
        lo = j;
        hi = count - 1u;
        while lo < hi {
            let mid = (lo + hi + 1u) / 2u;
            if stratum_entry(mid, count, n, total) > source {
                hi = mid - 1u;
            } else {
                lo = mid;
            }
        }
        let m = lo + 1u - start;
        let l = j - start;
        let v = entries[first + source];
        let w = weight_of(v);
        var nrm = v.normal.xyz;
        if dot(nrm, nrm) > 0.0 {
            nrm = normalize(nrm);
        } else {
            nrm = vec3<f32>(0.0, 1.0, 0.0);
        }
        let t = basis_x(nrm);
        let b = basis_y(nrm);
        let h = pcg(seed ^ pcg(ranks[source] + 1u));
        let u1 = fract((f32(l) + 0.5) / f32(m) + unit(h));
        let u2 = fract(radical_inverse(l) + unit(pcg(h)));
        let r = sqrt(u1);
        let phi = 2.0 * PI * u2;
        let direction = normalize(t * (r * cos(phi)) + b * (r * sin(phi)) + nrm * sqrt(max(1.0 - u1, 0.0)));
        slot.origin = vec4<f32>(v.position.xyz, slot.origin.w);
        slot.normal = vec4<f32>(v.normal.xyz, 0.0);
        slot.direction = vec4<f32>(direction, 0.0);
        // flux / (p · slots), p = w / total
        link.flux = vec4<f32>(v.flux.xyz * (total / (w * f32(count))), 1.0);
        link.flags = vec4<f32>(v.position.w, v.normal.w, 0.0, 0.0);
        slots[j] = slot;
        links[j] = link;
    }
}

// ---- the new VPLs at the hits ----

@group(0) @binding(5) var<storage, read> spawn_links: array<Link>;
@group(0) @binding(6) var<storage, read> hits: array<vec4<f32>>;       // bounce.wgsl's: 2 per slot
@group(0) @binding(7) var<storage, read> vertices: array<f32>;         // mesh.rs's GpuVertex: 10 words
@group(0) @binding(8) var<storage, read> materials: array<Material>;
@group(0) @binding(9) var<storage, read_write> pilot: array<Vpl>;      // 2 per slot
@group(0) @binding(10) var<storage, read_write> stats: array<atomic<u32>>;   // per bounce: found, real-only

const VERTEX_WORDS: u32 = 10u;

fn vertex_position(v: u32) -> vec3<f32> {
    let at = VERTEX_WORDS * v;
    return vec3<f32>(vertices[at], vertices[at + 1u], vertices[at + 2u]);
}

fn vertex_uv(v: u32) -> vec2<f32> {
    let at = VERTEX_WORDS * v + 6u;
    return vec2<f32>(vertices[at], vertices[at + 1u]);
}

struct SurfacePoint {
    found: bool,
    real: bool,
    position: vec3<f32>,
    normal: vec3<f32>,
    albedo: vec3<f32>,
}

// A hit (distance or -1, triangle, b1, b2) as a surface point facing `towards`.
fn surface_point(hit: vec4<f32>, towards: vec3<f32>) -> SurfacePoint {
    var s: SurfacePoint;
    s.found = false;
    let t = u32(hit.y + 0.5);
    if !(hit.x >= 0.0) || t >= chain.more.x {
        return s;
    }
    let b0 = 1.0 - hit.z - hit.w;
    let p0 = vertex_position(3u * t);
    let p1 = vertex_position(3u * t + 1u);
    let p2 = vertex_position(3u * t + 2u);
    s.position = p0 * b0 + p1 * hit.z + p2 * hit.w;
    let n = cross(p1 - p0, p2 - p0);
    if !(dot(n, n) > 0.0) {
        return s;
    }
    s.normal = normalize(n);
    // two-sided surfaces: the side that faces the source reflects
    if dot(s.normal, towards - s.position) < 0.0 {
        s.normal = -s.normal;
    }
    let words = VERTEX_WORDS * 3u * t;
    let material = bitcast<u32>(vertices[words + 8u]);
    let uv = vertex_uv(3u * t) * b0 + vertex_uv(3u * t + 1u) * hit.z + vertex_uv(3u * t + 2u) * hit.w;
    s.albedo = vec3<f32>(0.0);
    if material < arrayLength(&materials) {
        s.albedo = albedo_at(materials[material], uv);
    }
    s.real = bitcast<u32>(vertices[words + 9u]) == 0u;
    s.found = true;
    return s;
}

// A new VPL at `s` carrying albedo ⊙ flux_in; zero where it has no flux.
fn spawned(s: SurfacePoint, flux_in: vec3<f32>, path: bool, ir: bool) -> Vpl {
    let flux = s.albedo * flux_in;
    let w = luminance(flux);
    if !(w > 0.0) || any(abs(flux) > vec3<f32>(3.4e38)) {
        return Vpl(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
    }
    return Vpl(vec4<f32>(s.position, select(0.0, 1.0, path)), vec4<f32>(s.normal, select(0.0, 1.0, ir)),
               vec4<f32>(flux, 0.0));
}

@compute @workgroup_size(64)
fn cs_spawn(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = id.x + id.y * groups.x * 64u;
    if j >= chain.counts.y {
        return;
    }
    let none = Vpl(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
    let at = chain.more.y + 2u * j;
    pilot[at] = none;
    pilot[at + 1u] = none;
    let link = spawn_links[j];
    if link.flux.w < 0.5 {
        return;
    }
    let origin = slots[j].origin.xyz;
    let path_real = link.flags.x > 0.5;
    let ir = link.flags.y > 0.5;
    let any_hit = surface_point(hits[2u * j], origin);
    let real_hit = surface_point(hits[2u * j + 1u], origin);
    let k = chain.counts.w;
    if ir {
        // lights only the real-only solution: it can only have reached real surfaces
        if real_hit.found {
            atomicAdd(&stats[2u * k], 1u);
            pilot[at] = spawned(real_hit, link.flux.xyz, true, true);
        }
        return;
    }
    if !any_hit.found {
        return;
    }
    atomicAdd(&stats[2u * k], 1u);
    pilot[at] = spawned(any_hit, link.flux.xyz, path_real && any_hit.real, false);
    if path_real && !any_hit.real && real_hit.found {
        atomicAdd(&stats[2u * k + 1u], 1u);
        pilot[at + 1u] = spawned(real_hit, link.flux.xyz, true, true);
    }
}

// ---- the budget split over the sources ----

// The plan: counts[8], offsets[8], the sources' luminance flux (f32 bits)[8].
@group(0) @binding(11) var<storage, read_write> plan: array<u32>;
@group(0) @binding(12) var<storage, read> first_vpls: array<Vpl>;

var<workgroup> fluxes: array<f32, 8>;

@compute @workgroup_size(256)
fn cs_split(@builtin(local_invocation_index) lid: u32) {
    let budget = chain.counts.y;
    let sources = min(chain.more.w, SOURCES);
    let pilot_slots = chain.counts.x;
    for (var k = 0u; k < sources; k++) {
        var sum = 0.0;
        if k == 0u {
            for (var i = lid; i < budget; i += GROUP) {
                sum += weight_of(first_vpls[i]);
            }
        } else {
            for (var i = lid; i < pilot_slots; i += GROUP) {
                sum += weight_of(entries[(k - 1u) * pilot_slots + i]);
            }
        }
        partial[lid] = sum;
        workgroupBarrier();
        for (var stride = GROUP / 2u; stride > 0u; stride >>= 1u) {
            if lid < stride {
                partial[lid] += partial[lid + stride];
            }
            workgroupBarrier();
        }
        if lid == 0u {
            fluxes[k] = partial[0];
        }
        workgroupBarrier();
    }
    if lid != 0u {
        return;
    }
    // vpl.rs's split_budget: floors of the exact shares, then one more for every source with flux
    // and none yet, then by the largest remainders
    var total = 0.0;
    for (var k = 0u; k < sources; k++) {
        total += fluxes[k];
    }
    var counts = array<u32, 8>(0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
    var exact = array<f32, 8>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    var left = 0u;
    if total > 0.0 {
        var given = 0u;
        for (var k = 0u; k < sources; k++) {
            exact[k] = f32(budget) * fluxes[k] / total;
            counts[k] = min(u32(floor(exact[k])), budget);
            given += counts[k];
        }
        left = budget - min(given, budget);
    }
    var taken = array<bool, 8>(false, false, false, false, false, false, false, false);
    for (var pass_index = 0u; pass_index < sources && left > 0u; pass_index++) {
        var best = SOURCES;
        for (var k = 0u; k < sources; k++) {
            if taken[k] || !(fluxes[k] > 0.0) {
                continue;
            }
            if best == SOURCES {
                best = k;
                continue;
            }
            let none_k = counts[k] == 0u;
            let none_best = counts[best] == 0u;
            let rem_k = exact[k] - floor(exact[k]);
            let rem_best = exact[best] - floor(exact[best]);
            if (none_k && !none_best) || (none_k == none_best && rem_k > rem_best) {
                best = k;
            }
        }
        if best == SOURCES {
            break;
        }
        taken[best] = true;
        counts[best] += 1u;
        left -= 1u;
    }
    var offset = 0u;
    for (var k = 0u; k < SOURCES; k++) {
        plan[k] = counts[k];
        plan[SOURCES + k] = offset;
        plan[2u * SOURCES + k] = bitcast<u32>(fluxes[k]);
        offset += counts[k];
    }
}

// ---- a pilot's share ----

@group(0) @binding(13) var<storage, read> resample_plan: array<u32>;
@group(0) @binding(14) var<storage, read_write> frame_vpls: array<Vpl>;

@compute @workgroup_size(256)
fn cs_resample(@builtin(local_invocation_index) lid: u32) {
    let n = chain.counts.x;
    let first = chain.more.y;
    let source = chain.more.z;
    for (var i = lid; i < n; i += GROUP) {
        cdf[i] = weight_of(entries[first + i]);
    }
    storageBarrier();
    workgroupBarrier();
    scan_cdf(n, lid);
    let total = workgroupUniformLoad(&total_weight);
    let count = resample_plan[source];
    let offset = resample_plan[SOURCES + source];
    if !(total > 0.0) {
        return;
    }
    for (var s = lid; s < count; s += GROUP) {
        let i = stratum_entry(s, count, n, total);
        var v = entries[first + i];
        let w = weight_of(v);
        if w > 0.0 {
            v.flux = vec4<f32>(v.flux.xyz * (total / (f32(count) * w)), v.flux.w);
        } else {
            v = Vpl(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
        }
        frame_vpls[offset + s] = v;
    }
}
