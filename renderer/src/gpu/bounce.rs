//! The multiple-bounce light source (thesis 5.2.7, the improved direction-based method; shader:
//! `bounce.wgsl`): VPLs that carry one more bounce of light, spawned from existing VPLs.
//!
//! 1. **Source VPLs** are linked to the slots in proportion to their flux (stratified inversion
//!    of the luminance CDF, as [`super::vpl`] draws RSM texels).
//! 2. Each slot gets a **direction** ω_o from its source: the VPLs reflect diffusely, so ω_o is
//!    drawn from the cosine lobe around the source's normal (a per-source Hammersley set with a
//!    random rotation) — the thesis draws diffuse directions uniformly; the cosine lobe is the
//!    same lobe importance-sampled.
//! 3. On the GPU, each slot draws its candidate points from all surfaces by area (the point
//!    clouds of the ISMs) and keeps those within `cone_degrees` (the thesis: 5°) of ω_o; the
//!    one **nearest** to the source becomes the new VPL, without a further visibility test —
//!    as in the thesis, which keeps the nearest by the depth test.
//!
//! The new VPL reflects albedo ⊙ Φ_source / (p_source · slots): with ω_o drawn from the cosine
//! lobe, the flux leaving in the sampled direction estimates all of the source's flux. Its flags
//! follow eqs. 5.9–5.10: the path flag x̄ = x̄_source · r(p) and ir copied from the source, whose
//! ir = 1 (lights only the real-only solution) admits only real candidates. One addition keeps
//! the differential consistent as the two RSMs of a real spot light do (VPL 3 of Figure 5.7):
//! when a real path (x̄ = 1) meets a virtual surface first, the same slot also spawns, at the
//! nearest real candidate, an ir = 1 VPL — where the light would have gone without the virtual
//! object — so L_r keeps the real interreflection the photograph already shows.
//!
//! Slots whose cone holds no candidate make no VPL: the light escaped the scene, or the
//! candidates were too sparse to find the surface (a bias towards darkness that more candidates
//! reduce; [`BounceReport::found`] counts both).

use super::context::GpuContext;
use super::mesh::GpuMesh;
use super::vpl::GpuVpl;
use std::sync::Arc;
// the PCG hash of common.wgsl, written once in Rust
use crate::material::Material;
use crate::math::luminance;
use crate::math::pcg_hash as hash;
use glam::{Vec2, Vec3};
use serde::Serialize;

pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("cdf.wgsl"), include_str!("bounce.wgsl"));

/// Matches `BounceParams` in bounce.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct BounceUniform {
    counts: [u32; 4],
    cone: [f32; 4],
}

/// Matches `Slot` in bounce.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct SlotGpu {
    origin: [f32; 4],
    normal: [f32; 4],
    direction: [f32; 4],
}

/// What one additional bounce made.
#[derive(Clone, Debug, Serialize)]
pub struct BounceReport {
    /// The bounce this light source adds (2: the second bounce of light, …).
    pub bounce: u32,
    /// Slots evaluated (the pilot that measures the bounce's flux) and those whose cone held a
    /// candidate.
    pub slots: u32,
    pub found: u32,
    /// Extra VPLs of real paths blocked by a virtual surface (ir = 1, at the real surface behind).
    pub real_only: u32,
    /// Luminance flux of the bounce (sum over its VPLs), which decides its share of the budget.
    pub flux: f32,
    /// VPLs the bounce got in the frame.
    pub vpls: usize,
}

/// The scene's triangles as the bounce pass reads them, uploaded once per scene.
#[derive(Clone)]
pub struct BounceScene {
    positions: Arc<wgpu::Buffer>,
    cdf: Arc<wgpu::Buffer>,
    pub(super) triangles: u32,
    real_triangles: u32,
}

impl BounceScene {
    /// `None` when the scene has no surface area.
    pub fn new(ctx: &GpuContext, mesh: &GpuMesh) -> Option<BounceScene> {
        let positions = mesh.positions_with_role();
        let triangles = mesh.vertices.len() / 3;
        let (cdf, _) = super::ism::area_cdf(&positions, 0..triangles)?;
        // kept from frame to frame while the scene is the same ([`GpuContext::resident`])
        Some(BounceScene {
            positions: ctx.resident("bounce positions", bytemuck::cast_slice(&positions), wgpu::BufferUsages::STORAGE),
            cdf: ctx.resident("bounce cdf", bytemuck::cast_slice(&cdf), wgpu::BufferUsages::STORAGE),
            triangles: triangles as u32,
            real_triangles: mesh.real_count / 3,
        })
    }
}

/// How the slots look for their surfaces.
#[derive(Clone, Copy, Debug)]
pub struct BounceSearch {
    /// Candidate points per slot.
    pub candidates: u32,
    /// Half angle of the cone around ω_o (degrees).
    pub cone_degrees: f32,
    /// Seeds the directions (a different seed per bounce).
    pub seed: u32,
}

pub struct Bounce {
    pipeline: wgpu::ComputePipeline,
}

/// One slot's source and direction (CPU side).
struct SlotSource {
    source: usize,
    /// Probability of the source (its share of the flux).
    p: f64,
    direction: Vec3,
}

fn unit(v: u32) -> f32 {
    (v >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Links `slots` slots to sources in proportion to their luminance flux (stratified), and gives
/// each a cosine-distributed direction from a Hammersley set over the source's slots.
fn link_slots(sources: &[GpuVpl], slots: u32, seed: u32) -> Vec<SlotSource> {
    let weights: Vec<f64> = sources
        .iter()
        .map(|v| luminance(Vec3::new(v.flux[0], v.flux[1], v.flux[2])).max(0.0) as f64)
        .map(|w| if w.is_finite() { w } else { 0.0 })
        .collect();
    let linked = super::vpl::stratify(&weights, slots);
    let mut out = Vec::with_capacity(linked.len());
    let mut start = 0;
    while start < linked.len() {
        let source = linked[start].0;
        let end = start + linked[start..].iter().take_while(|(s, _)| *s == source).count();
        let m = (end - start) as u32;
        let n = Vec3::from_slice(&sources[source].normal[..3]).normalize_or(Vec3::Y);
        let (t, b) = n.any_orthonormal_pair();
        let h = hash(seed ^ hash(source as u32 + 1));
        let (rot1, rot2) = (unit(h), unit(hash(h)));
        for l in 0..m {
            let u1 = ((l as f32 + 0.5) / m as f32 + rot1).fract();
            let u2 = (super::radical_inverse(l) + rot2).fract();
            let (r, phi) = (u1.sqrt(), 2.0 * std::f32::consts::PI * u2);
            let direction = (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize();
            out.push(SlotSource { source, p: linked[start].1, direction });
        }
        start = end;
    }
    out
}

/// The scene a bounce searches: its candidate points on the GPU, its triangles and materials
/// (for the new VPLs' albedo) and its bounding radius.
#[derive(Clone, Copy)]
pub struct BounceInputs<'a> {
    pub scene: &'a BounceScene,
    pub mesh: &'a GpuMesh,
    pub materials: &'a [Material],
    pub scene_radius: f32,
}

impl Bounce {
    pub fn new(ctx: &GpuContext) -> Self {
        let [pipeline] = ctx.compute_pipelines("bounce.wgsl", SHADER, ["cs_nearest"]);
        Bounce { pipeline }
    }

    /// One additional bounce: `slots` new VPL slots spawned from `sources`. Returns the new
    /// VPLs (up to two per slot, see the module notes) and the number of slots that found a
    /// surface.
    pub fn spawn(
        &self,
        ctx: &GpuContext,
        at: &BounceInputs,
        sources: &[GpuVpl],
        slots: u32,
        search: &BounceSearch,
    ) -> (Vec<GpuVpl>, u32, u32) {
        let BounceInputs { scene, mesh, materials, scene_radius } = *at;
        let linked = link_slots(sources, slots, search.seed);
        if linked.is_empty() {
            return (Vec::new(), 0, 0);
        }
        let gpu_slots: Vec<SlotGpu> = linked
            .iter()
            .map(|s| {
                let v = &sources[s.source];
                SlotGpu {
                    origin: [v.position[0], v.position[1], v.position[2], 0.0],
                    normal: [v.normal[0], v.normal[1], v.normal[2], 0.0],
                    direction: [s.direction.x, s.direction.y, s.direction.z, 0.0],
                }
            })
            .collect();
        let hits = self.nearest(ctx, scene, &gpu_slots, search, scene_radius);
        spawn_from_hits(mesh, materials, sources, &linked, &hits)
    }

    /// The GPU search: per slot (origin, normal, direction ω_o), the nearest candidate point in
    /// the cone and the nearest real one, 8 floats per slot: (distance or −1, triangle, b1, b2)
    /// twice.
    fn nearest(
        &self,
        ctx: &GpuContext,
        scene: &BounceScene,
        slots: &[SlotGpu],
        search: &BounceSearch,
        scene_radius: f32,
    ) -> Vec<f32> {
        let gpu_slots: Vec<SlotGpu> = slots
            .iter()
            .enumerate()
            .map(|(j, s)| SlotGpu {
                origin: [
                    s.origin[0],
                    s.origin[1],
                    s.origin[2],
                    unit(hash(search.seed.wrapping_mul(31) ^ hash(j as u32 + 7))),
                ],
                ..*s
            })
            .collect();
        let n = gpu_slots.len() as u32;
        let slot_buffer = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("bounce slots"),
            contents: bytemuck::cast_slice(&gpu_slots),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let hits = Bounce::hits(ctx, n);
        let mut encoder = ctx.encoder();
        self.record_nearest(ctx, &mut encoder, scene, (&slot_buffer, n, &hits), search, scene_radius);
        ctx.submit(encoder);
        ctx.read_f32(&hits)
    }

    /// The hits' buffer of a search of `n` slots ([`Bounce::record_nearest`]), zeroed: taken
    /// before the search's encoder (a frame's passes record into one: [`super::stream`]).
    pub(super) fn hits(ctx: &GpuContext, n: u32) -> Arc<wgpu::Buffer> {
        ctx.buffer(
            "bounce hits",
            (2 * n as u64) * 16,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            super::pool::Contents::Zeroed,
        )
    }

    /// Records the GPU search of `n` slots in the buffer `slots` (bounce.wgsl's `Slot`: origin
    /// with the rotation of its strata in w, normal, direction ω_o) into `hits` ([`Bounce::hits`]),
    /// two per slot (nearest of all points, nearest real point: distance or −1, triangle, b1,
    /// b2). A live frame's chain ([`super::bounce_chain`]) fills the slots on the GPU.
    pub(super) fn record_nearest(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &BounceScene,
        (slots, n, hits): (&wgpu::Buffer, u32, &wgpu::Buffer),
        search: &BounceSearch,
        scene_radius: f32,
    ) {
        // a minimum distance of a millimetre per metre of scene keeps the source's own surface out
        let min_distance = (1e-3 * scene_radius).max(1e-5);
        let uniform = BounceUniform {
            counts: [search.candidates.max(1), n, scene.real_triangles, scene.triangles],
            cone: [search.cone_degrees.clamp(0.01, 90.0).to_radians().cos(), min_distance, 0.01, 0.0],
        };
        let uniform_buffer = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("bounce params"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        ctx.record_dispatch(
            encoder,
            "bounce",
            &self.pipeline,
            &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: scene.positions.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: scene.cdf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: slots.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: hits.as_entire_binding() },
            ],
            [n.min(65535), n.div_ceil(65535)],
        );
    }
}

/// A hit as the shader writes it: (distance or −1, triangle, b1, b2).
fn surface_point(
    mesh: &GpuMesh,
    materials: &[Material],
    hit: &[f32],
    towards: Vec3,
) -> Option<(Vec3, Vec3, Vec3, bool)> {
    if hit[0] < 0.0 || !hit.iter().all(|v| v.is_finite()) {
        return None;
    }
    let t = hit[1] as usize;
    let vertices = mesh.vertices.get(3 * t..3 * t + 3)?;
    let (b1, b2) = (hit[2], hit[3]);
    let b0 = 1.0 - b1 - b2;
    let p = |k: usize| Vec3::from_array(vertices[k].position);
    let uv = |k: usize| Vec2::from_array(vertices[k].uv);
    let position = p(0) * b0 + p(1) * b1 + p(2) * b2;
    let mut normal = (p(1) - p(0)).cross(p(2) - p(0)).normalize_or_zero();
    if normal == Vec3::ZERO {
        return None;
    }
    // two-sided surfaces: the side that faces the source reflects
    if normal.dot(towards - position) < 0.0 {
        normal = -normal;
    }
    let albedo = materials
        .get(vertices[0].material as usize)
        .map(|m| m.albedo_at(uv(0) * b0 + uv(1) * b1 + uv(2) * b2))
        .unwrap_or(Vec3::ZERO);
    Some((position, normal, albedo, vertices[0].role == 0))
}

/// Builds the new VPLs from the nearest hits of every slot (two per slot: of all points, of the
/// real ones). Returns (VPLs, slots that found a surface, extra real-only VPLs).
fn spawn_from_hits(
    mesh: &GpuMesh,
    materials: &[Material],
    sources: &[GpuVpl],
    linked: &[SlotSource],
    hits: &[f32],
) -> (Vec<GpuVpl>, u32, u32) {
    let slots = linked.len() as f64;
    let mut out = Vec::new();
    let (mut found, mut real_only) = (0u32, 0u32);
    for (j, s) in linked.iter().enumerate() {
        let source = &sources[s.source];
        let origin = Vec3::from_slice(&source.position[..3]);
        let path_real = source.position[3] > 0.5;
        let ir = source.normal[3] > 0.5;
        let scale = (1.0 / (s.p * slots)) as f32;
        let flux_in = Vec3::from_slice(&source.flux[..3]) * scale;
        let make = |(position, normal, albedo, _): (Vec3, Vec3, Vec3, bool), path: bool, ir: bool| {
            let flux = albedo * flux_in;
            (luminance(flux) > 0.0 && flux.is_finite()).then_some(GpuVpl {
                position: [position.x, position.y, position.z, if path { 1.0 } else { 0.0 }],
                normal: [normal.x, normal.y, normal.z, if ir { 1.0 } else { 0.0 }],
                flux: [flux.x, flux.y, flux.z, 0.0],
            })
        };
        let any = surface_point(mesh, materials, &hits[8 * j..8 * j + 4], origin);
        let real = surface_point(mesh, materials, &hits[8 * j + 4..8 * j + 8], origin);
        if ir {
            // lights only the real-only solution: it can only have reached real surfaces
            if let Some(hit) = real {
                found += 1;
                out.extend(make(hit, true, true));
            }
            continue;
        }
        let Some(hit) = any else { continue };
        found += 1;
        let hit_real = hit.3;
        out.extend(make(hit, path_real && hit_real, false));
        if path_real
            && !hit_real
            && let Some(behind) = real
        {
            real_only += 1;
            out.extend(make(behind, true, true));
        }
    }
    (out, found, real_only)
}

#[cfg(test)]
mod tests;
