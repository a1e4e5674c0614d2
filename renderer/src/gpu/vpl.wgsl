// VPL creation on the GPU from the reflective shadow maps (thesis 5.2.7), the same candidates and
// the same stratified draw as the CPU's reference in vpl.rs, without reading the RSMs back.
//
// 1. cs_candidates, once per light: every RSM texel gives two candidate slots (weight 0 where
//    there is none), in the CPU's order: a virtual surface in front gives [virtual VPL, the real
//    surface behind it for a real light's real-only solution]; a real surface alone gives [real
//    VPL, none]. A slot's weight is its flux's luminance.
// 1b. cs_caustic_candidates, once per caustic map (before the RSMs' slots, in the CPU's order of
//    `Specular::caustic_vpls`): every photon that left the light through its object gives a
//    reflected and a refracted slot where it lands (Figure 5.23).
// 2. cs_block_sums, cs_scan_blocks, cs_scan: the inclusive prefix sum (CDF) of all slots' weights,
//    in blocks of 2048 (256 threads of 8), each block's offset from a serial scan of the blocks'
//    sums; the order of every addition is fixed, so the CDF is the same on every run.
// 3. cs_draw: stratum k of `count` takes the first slot whose CDF reaches (k + 0.5) / count of the
//    total, and carries flux · total / (count · weight). Driven by vpl.rs (`VplSampler`).

struct MapParams {
    info: vec4<u32>,       // x: 0 spot, 1 environment direction; y: real light; z: has a virtual map; w: size
    offset: vec4<u32>,     // x: first slot of this light
    position: vec4<f32>,   // spot: xyz; w: tan of half the field of view
    direction: vec4<f32>,  // spot: xyz; w: cos_outer
    intensity: vec4<f32>,  // spot: intensity, environment: irradiance; w: cos_inner
    area: vec4<f32>,       // x: an environment texel's area across the beam
}

@group(0) @binding(0) var<uniform> map: MapParams;
@group(0) @binding(1) var real_position: texture_2d<f32>;
@group(0) @binding(2) var real_normal: texture_2d<f32>;
@group(0) @binding(3) var real_albedo: texture_2d<f32>;
@group(0) @binding(4) var real_distance: texture_2d<f32>;
@group(0) @binding(5) var virt_position: texture_2d<f32>;
@group(0) @binding(6) var virt_normal: texture_2d<f32>;
@group(0) @binding(7) var virt_albedo: texture_2d<f32>;
@group(0) @binding(8) var virt_distance: texture_2d<f32>;
@group(0) @binding(9) var<storage, read_write> candidates: array<Vpl>;
@group(0) @binding(10) var<storage, read_write> weights: array<f32>;

fn texel_solid_angle(ix: u32, iy: u32, size: u32, tan_half: f32) -> f32 {
    let x = (2.0 * (f32(ix) + 0.5) / f32(size) - 1.0) * tan_half;
    let y = (2.0 * (f32(iy) + 0.5) / f32(size) - 1.0) * tan_half;
    let side = 2.0 * tan_half / f32(size);
    return side * side / pow(1.0 + x * x + y * y, 1.5);
}

// A spot's intensity towards the unit direction `dir`: `direction` xyz with cos_outer in w,
// `intensity` rgb with cos_inner in w (common.wgsl's falloff, as shade.wgsl's spot_intensity).
fn spot_intensity(dir: vec3<f32>, direction: vec4<f32>, intensity: vec4<f32>) -> vec3<f32> {
    return intensity.xyz * spot_falloff(dot(dir, direction.xyz), intensity.w, direction.w);
}

// One candidate at slot `slot`: weight 0 (and a zero VPL) where the texel gives none.
fn write_candidate(slot: u32, texel: vec2<u32>, position: vec4<f32>, normal: vec4<f32>, albedo: vec4<f32>,
                   path_flag: f32, ir: f32) {
    var flux = vec3<f32>(0.0);
    if map.info.x == 1u {
        flux = albedo.rgb * map.intensity.xyz * map.area.x;
    } else {
        let to_surface = position.xyz - map.position.xyz;
        let dist = length(to_surface);
        if dist > 0.0 {
            let d_omega = texel_solid_angle(texel.x, texel.y, map.info.w, map.position.w);
            flux = albedo.rgb * spot_intensity(to_surface / dist, map.direction, map.intensity) * d_omega;
        }
    }
    var weight = luminance(flux);
    // not finite or not positive: no candidate (a NaN fails every comparison)
    if !(weight > 0.0 && weight <= 3.4e38) {
        weight = 0.0;
        flux = vec3<f32>(0.0);
    }
    candidates[slot] = Vpl(vec4<f32>(position.xyz, path_flag), vec4<f32>(normal.xyz, ir), vec4<f32>(flux, 0.0));
    weights[slot] = weight;
}

fn write_none(slot: u32) {
    candidates[slot] = Vpl(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
    weights[slot] = 0.0;
}

@compute @workgroup_size(8, 8)
fn cs_candidates(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = map.info.w;
    if id.x >= size || id.y >= size {
        return;
    }
    let texel = id.xy;
    let slot = map.offset.x + 2u * (id.y * size + id.x);
    let light_real = map.info.y == 1u;
    let r_pl = select(0.0, 1.0, light_real);
    let real_p = textureLoad(real_position, texel, 0);
    let has_real = real_p.w > 0.5;
    var has_virt = false;
    var virt_p = vec4<f32>(0.0);
    var virt_d = 1e30;
    if map.info.z == 1u {
        virt_p = textureLoad(virt_position, texel, 0);
        virt_d = textureLoad(virt_distance, texel, 0).x;
        has_virt = virt_p.w > 0.5;
    }
    let real_d = textureLoad(real_distance, texel, 0).x;
    let virtual_in_front = has_virt && (!has_real || virt_d < real_d);
    if virtual_in_front {
        write_candidate(slot, texel, virt_p, textureLoad(virt_normal, texel, 0), textureLoad(virt_albedo, texel, 0),
                        0.0, 0.0);
        if has_real && light_real {
            write_candidate(slot + 1u, texel, real_p, textureLoad(real_normal, texel, 0),
                            textureLoad(real_albedo, texel, 0), 1.0, 1.0);
        } else {
            write_none(slot + 1u);
        }
    } else if has_real {
        write_candidate(slot, texel, real_p, textureLoad(real_normal, texel, 0), textureLoad(real_albedo, texel, 0),
                        r_pl, 0.0);
        write_none(slot + 1u);
    } else {
        write_none(slot);
        write_none(slot + 1u);
    }
}

// ---- the caustic maps' photons (specular.wgsl's search: `info` 4 per photon, `hits` 6 planes) ----

struct CausticParams {
    info: vec4<u32>,       // x: map size n; y: the hit planes' row stride; z: the object's index; w: real light and object
    offset: vec4<u32>,     // x: first slot of this map
    position: vec4<f32>,   // the light's position; w: tan of half the map's field of view
    direction: vec4<f32>,  // xyz; w: cos_outer
    intensity: vec4<f32>,  // rgb; w: cos_inner
}

@group(0) @binding(0) var<uniform> caustic: CausticParams;
@group(0) @binding(1) var photon_position: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> photon_info: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> photon_hits: array<vec4<f32>>;

fn photon_plane(p: u32, x: u32, y: u32) -> vec4<f32> {
    return photon_hits[(p * caustic.info.x + y) * caustic.info.y + x];
}

@compute @workgroup_size(8, 8)
fn cs_caustic_candidates(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = caustic.info.x;
    if id.x >= n || id.y >= n {
        return;
    }
    let pixel = id.y * n + id.x;
    let slot = caustic.offset.x + 2u * pixel;
    // a photon through this object (info 2.w: it left the light; 3.w: the object it met)
    if photon_info[4u * pixel + 2u].w < 0.5 || u32(photon_info[4u * pixel + 3u].w + 0.5) != caustic.info.z {
        write_none(slot);
        write_none(slot + 1u);
        return;
    }
    let p1 = textureLoad(photon_position, id.xy, 0).xyz;
    let to = p1 - caustic.position.xyz;
    let d_omega = texel_solid_angle(id.x, id.y, n, caustic.position.w);
    let flux_in = spot_intensity(to * (1.0 / length(to)), caustic.direction, caustic.intensity) * d_omega;
    for (var c = 0u; c < 2u; c++) {
        let w = photon_info[4u * pixel + c];
        let albedo = photon_plane(3u * c + 2u, id.x, id.y).xyz;
        let flux = flux_in * w.xyz * albedo;
        let weight = luminance(flux);
        let finite = all(abs(flux) <= vec3<f32>(3.4e38));
        if w.w != 1.0 || !(weight > 0.0) || !finite {
            write_none(slot + c);
            continue;
        }
        // position w: role (1 real, 2 virtual) + 4 x material
        let position = photon_plane(3u * c, id.x, id.y);
        let real = caustic.info.w == 1u && u32(position.w + 0.5) % 4u == 1u;
        let normal = photon_plane(3u * c + 1u, id.x, id.y).xyz;
        let length_recip = 1.0 / length(normal);
        var unit_normal = vec3<f32>(0.0);
        if length_recip > 0.0 && length_recip <= 3.4e38 {
            unit_normal = normal * length_recip;
        }
        candidates[slot + c] = Vpl(vec4<f32>(position.xyz, select(0.0, 1.0, real)), vec4<f32>(unit_normal, 0.0),
                                   vec4<f32>(flux, 1.0));
        weights[slot + c] = weight;
    }
}

// ---- the CDF: blocks of 2048 slots, 8 per thread ----

const PER_THREAD: u32 = 8u;
const BLOCK: u32 = 2048u;

struct ScanParams {
    sizes: vec4<u32>,      // x: slots; y: blocks; z: VPLs to draw
}

@group(0) @binding(0) var<uniform> scan: ScanParams;
@group(0) @binding(1) var<storage, read> scan_weights: array<f32>;
@group(0) @binding(2) var<storage, read_write> block_sums: array<f32>;   // sums, then exclusive offsets; last: total
@group(0) @binding(3) var<storage, read_write> cdf: array<f32>;

var<workgroup> shared_sums: array<f32, 256>;

fn thread_sum(first: u32) -> f32 {
    var sum = 0.0;
    for (var i = 0u; i < PER_THREAD; i++) {
        if first + i < scan.sizes.x {
            sum += scan_weights[first + i];
        }
    }
    return sum;
}

@compute @workgroup_size(256)
fn cs_block_sums(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    let block = group.x + group.y * 65535u;
    shared_sums[local] = thread_sum(block * BLOCK + local * PER_THREAD);
    workgroupBarrier();
    for (var stride = 128u; stride > 0u; stride >>= 1u) {
        if local < stride {
            shared_sums[local] += shared_sums[local + stride];
        }
        workgroupBarrier();
    }
    if local == 0u && block < scan.sizes.y {
        block_sums[block] = shared_sums[0];
    }
}

// One thread: the blocks' sums into exclusive offsets, the total after them.
@compute @workgroup_size(1)
fn cs_scan_blocks() {
    var running = 0.0;
    for (var b = 0u; b < scan.sizes.y; b++) {
        let sum = block_sums[b];
        block_sums[b] = running;
        running += sum;
    }
    block_sums[scan.sizes.y] = running;
}

@compute @workgroup_size(256)
fn cs_scan(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    let block = group.x + group.y * 65535u;
    if block >= scan.sizes.y {
        return;
    }
    let first = block * BLOCK + local * PER_THREAD;
    let own = thread_sum(first);
    // Hillis-Steele inclusive scan of the threads' sums
    shared_sums[local] = own;
    workgroupBarrier();
    for (var stride = 1u; stride < 256u; stride <<= 1u) {
        var value = shared_sums[local];
        if local >= stride {
            value += shared_sums[local - stride];
        }
        workgroupBarrier();
        shared_sums[local] = value;
        workgroupBarrier();
    }
    // this thread's exclusive prefix: the scan's value one thread before (not inclusive - own,
    // which would round differently from the block sums)
    var before = 0.0;
    if local > 0u {
        before = shared_sums[local - 1u];
    }
    var running = block_sums[block] + before;
    for (var i = 0u; i < PER_THREAD; i++) {
        if first + i < scan.sizes.x {
            running += scan_weights[first + i];
            cdf[first + i] = running;
        }
    }
}

// ---- the stratified draw ----

@group(0) @binding(0) var<uniform> draw: ScanParams;
@group(0) @binding(1) var<storage, read> draw_candidates: array<Vpl>;
@group(0) @binding(2) var<storage, read> draw_weights: array<f32>;
@group(0) @binding(3) var<storage, read> draw_cdf: array<f32>;
@group(0) @binding(4) var<storage, read> draw_total: array<f32>;          // the blocks' offsets; last: total
@group(0) @binding(5) var<storage, read_write> drawn: array<Vpl>;

// Stratum `index` of `count` (index < count; slots and a positive total): the first slot whose
// CDF reaches it, carrying flux · total / (count · weight).
fn draw_stratum(index: u32, count: u32, n: u32, total: f32) -> Vpl {
    let target_value = (f32(index) + 0.5) / f32(count) * total;
    // the first slot whose CDF reaches the stratum
    var lo = 0u;
    var hi = n - 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if draw_cdf[mid] >= target_value {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    // a slot without weight (the CDF's rounding between threads) gives way to the next with one,
    // or the last before it
    var slot = lo;
    while slot < n - 1u && draw_weights[slot] <= 0.0 {
        slot++;
    }
    while slot > 0u && draw_weights[slot] <= 0.0 {
        slot--;
    }
    let weight = draw_weights[slot];
    var vpl = draw_candidates[slot];
    let scale = total / (f32(count) * weight);
    vpl.flux = vec4<f32>(vpl.flux.rgb * scale, vpl.flux.w);
    return vpl;
}

@compute @workgroup_size(64)
fn cs_draw(@builtin(global_invocation_id) id: vec3<u32>) {
    let count = draw.sizes.z;
    let n = draw.sizes.x;
    let total = draw_total[draw.sizes.y];
    if id.x >= count || n == 0u || !(total > 0.0) {
        return;
    }
    drawn[id.x] = draw_stratum(id.x, count, n, total);
}

// The first bounce's share of a live frame's budget (bounce_chain.wgsl's plan: its first word),
// drawn on the GPU from a count the host never reads.
@group(0) @binding(6) var<storage, read> draw_plan: array<u32>;

@compute @workgroup_size(64)
fn cs_draw_planned(@builtin(global_invocation_id) id: vec3<u32>) {
    let count = draw_plan[0];
    let n = draw.sizes.x;
    let total = draw_total[draw.sizes.y];
    if id.x >= count || n == 0u || !(total > 0.0) {
        return;
    }
    drawn[id.x] = draw_stratum(id.x, count, n, total);
}
