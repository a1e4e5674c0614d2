// The multiple-bounce light source, the improved direction-based method of thesis 5.2.7: each
// VPL slot is linked to a source VPL and a direction ω_o from it; of the slot's candidate points
// (drawn from the scene's surfaces in proportion to area, like the ISM point clouds), those
// within a small cone around ω_o are valid, and the one nearest to the source wins — where the
// thesis writes the distance into a depth buffer and lets the depth test keep the nearest, one
// workgroup per slot reduces its candidates to the nearest here. Two winners per slot: the
// nearest of all points, and the nearest real point (the path's continuation in the real-only
// solution when a virtual surface is nearer: see bounce.rs). Driven by bounce.rs; common.wgsl
// (pcg, unit) is prepended.

struct BounceParams {
    counts: vec4<u32>,   // x: candidates per slot; y: slots; z: real triangles (the first virtual one); w: all triangles
    cone: vec4<f32>,     // x: cos of the cone's half angle; y: minimum distance (m); z: minimum cos to the source's normal
}

struct Slot {
    origin: vec4<f32>,     // the source VPL's position; w: the slot's rotation of its candidate strata
    normal: vec4<f32>,     // the source VPL's normal
    direction: vec4<f32>,  // ω_o
}

@group(0) @binding(0) var<uniform> params: BounceParams;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;   // 3 per triangle
@group(0) @binding(2) var<storage, read> cdf: array<f32>;               // per triangle, ends at 1
@group(0) @binding(3) var<storage, read> slots: array<Slot>;
// 2 per slot, nearest of all then nearest real: (distance, or -1 for none; triangle; b1; b2)
@group(0) @binding(4) var<storage, read_write> hits: array<vec4<f32>>;

const WORKGROUP: u32 = 64u;
var<workgroup> best_any: array<vec4<f32>, 64>;
var<workgroup> best_real: array<vec4<f32>, 64>;

fn nearer(a: vec4<f32>, b: vec4<f32>) -> vec4<f32> {
    if b.x >= 0.0 && (a.x < 0.0 || b.x < a.x) {
        return b;
    }
    return a;
}

@compute @workgroup_size(64)
fn cs_nearest(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let slot_index = group.x + group.y * 65535u;
    let live = slot_index < params.counts.y;
    var mine_any = vec4<f32>(-1.0, 0.0, 0.0, 0.0);
    var mine_real = vec4<f32>(-1.0, 0.0, 0.0, 0.0);
    if live {
        let slot = slots[slot_index];
        let per_slot = params.counts.x;
        let origin = slot.origin.xyz;
        let rotation = slot.origin.w;
        for (var k = lid; k < per_slot; k += WORKGROUP) {
            // the k-th of this slot's stratified area samples
            let u = fract((f32(k) + 0.5) / f32(per_slot) + rotation);
            let lo = cdf_search(u, params.counts.w);
            let a = positions[3u * lo].xyz;
            let b = positions[3u * lo + 1u].xyz;
            let c = positions[3u * lo + 2u].xyz;
            let h = pcg(slot_index * 2654435761u ^ pcg(k + 0x51ed270bu));
            let r1 = sqrt(unit(h));
            let r2 = unit(pcg(h));
            let b1 = r1 * (1.0 - r2);
            let b2 = r1 * r2;
            let p = a * (1.0 - r1) + b * b1 + c * b2;
            let d = p - origin;
            let dist = length(d);
            if dist < params.cone.y {
                continue;
            }
            let w = d / dist;
            // inside the cone around ω_o, in front of the source's surface, and not on its plane
            if dot(w, slot.direction.xyz) < params.cone.x || dot(w, slot.normal.xyz) < params.cone.z {
                continue;
            }
            var n = cross(b - a, c - a);
            n = n / max(length(n), 1e-20);
            if abs(dot(origin - a, n)) < 0.5 * params.cone.y {
                continue;
            }
            let hit = vec4<f32>(dist, f32(lo), b1, b2);
            mine_any = nearer(mine_any, hit);
            if lo < params.counts.z {
                mine_real = nearer(mine_real, hit);
            }
        }
    }
    best_any[lid] = mine_any;
    best_real[lid] = mine_real;
    workgroupBarrier();
    for (var stride = WORKGROUP / 2u; stride > 0u; stride = stride / 2u) {
        if lid < stride {
            best_any[lid] = nearer(best_any[lid], best_any[lid + stride]);
            best_real[lid] = nearer(best_real[lid], best_real[lid + stride]);
        }
        workgroupBarrier();
    }
    if lid == 0u && live {
        hits[2u * slot_index] = best_any[0];
        hits[2u * slot_index + 1u] = best_real[0];
    }
}
