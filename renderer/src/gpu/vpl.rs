//! VPL creation from reflective shadow maps (thesis 5.2.7, "The Spot Light Source"), of spot
//! lights and of directions of the environment light (orthographic RSMs; the environment is real,
//! and a texel reflects albedo · E · its area across the beam). A real spot
//! has two RSMs, real-only and virtual-only; a virtual spot too (its real-only map is then only
//! used where no virtual surface is in front). Each RSM texel is a candidate VPL carrying the
//! diffusely reflected flux albedo · I(ω) · dω of the light that reaches it; the flags follow
//! section 5.2.3 and eqs. 5.9–5.10:
//!
//! - a real surface with nothing virtual in front: path flag r = r(pl), ir = 0;
//! - a real surface behind a virtual one, for a real light: r = 1, ir = 1 (VPL 3 of Figure 5.7:
//!   it exists only in the real-only solution); for a virtual light it does not exist;
//! - a virtual surface in front (or alone): r = 0, ir = 0.
//!
//! The VPLs are drawn from all candidates of all spot lights together, in proportion to their
//! flux (stratified inversion of the CDF, deterministic), and each carries flux / (N · p): the
//! budget is thereby split over the lights by flux — the thesis's third distribution mode — and
//! over the two RSMs by the flux they hold, with the compensation built in.
//!
//! Two implementations draw the same VPLs. [`VplSampler`] (shader `vpl.wgsl`) makes the
//! candidates on the GPU from the RSM textures and the caustic maps' photons where they were
//! rendered, sums their CDF there and reads back only the drawn VPLs (a stimulus frame), or
//! leaves them there for a live frame's bounces, ISMs and shading (`draw_resident`,
//! `draw_planned`; [`super::bounce_chain`]); the renderer uses it. The
//! CPU's [`Candidates`] works on read-back texels ([`RsmTexels`]): the reference the sampler is
//! tested against, and the renderer's fall-back when the candidates exceed one storage buffer.

use crate::light::SpotLight;
use crate::math::luminance;
use glam::Vec3;
use std::sync::Arc;

/// One VPL: matches `Vpl` in common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuVpl {
    /// xyz; w: the path flag (1: light and surface real).
    pub position: [f32; 4],
    /// xyz; w: ir(VPL) (1: only the real-only solution).
    pub normal: [f32; 4],
    /// rgb: reflected flux (W); w: 1 for a reflected or refracted VPL of a caustic (Figure
    /// 5.23), 0 otherwise (the shaders read only rgb).
    pub flux: [f32; 4],
}

/// One RSM texel: position (w: flag + 4·material, 0 empty), normal, albedo, distance to the light.
pub type RsmTexel = ([f32; 4], [f32; 4], [f32; 4], f32);

/// The read-back RSMs of one spot light.
pub struct RsmTexels {
    pub size: u32,
    /// Half-width of the light's image plane at unit distance (tan of half the field of view).
    pub tan_half_fov: f32,
    /// Per texel of the real-only map.
    pub real: Vec<RsmTexel>,
    /// The same for the virtual-only map.
    pub virt: Vec<RsmTexel>,
}

/// The primary light an RSM was rendered from.
#[derive(Clone, Copy, Debug)]
pub enum RsmLight<'a> {
    /// A spot light (perspective RSM).
    Spot(&'a SpotLight),
    /// A direction of the environment light (orthographic RSM): irradiance on a surface facing
    /// it (W/m²) and the area of one texel across the beam (m²). The environment is real.
    Directional { irradiance: Vec3, texel_area: f32 },
}

impl RsmLight<'_> {
    fn real(&self) -> bool {
        match self {
            RsmLight::Spot(light) => light.real,
            RsmLight::Directional { .. } => true,
        }
    }
}

struct Candidate {
    vpl: GpuVpl,
    weight: f32,
}

impl Candidate {
    /// A VPL as a candidate weighted by its flux's luminance; `None` without usable flux.
    fn of(vpl: &GpuVpl) -> Option<Candidate> {
        let weight = luminance(Vec3::new(vpl.flux[0], vpl.flux[1], vpl.flux[2]));
        (weight > 0.0 && weight.is_finite()).then_some(Candidate { vpl: *vpl, weight })
    }
}

fn candidate(
    light: &RsmLight,
    rsm: &RsmTexels,
    idx: usize,
    texel: &RsmTexel,
    path_flag: f32,
    ir: f32,
) -> Option<Candidate> {
    let (position, normal, albedo, _) = texel;
    let p = Vec3::new(position[0], position[1], position[2]);
    let light = match light {
        RsmLight::Spot(light) => *light,
        RsmLight::Directional { irradiance, texel_area } => {
            // the texel's footprint across the beam receives E · A; a diffuse surface reflects
            // albedo times that, whatever its tilt
            let flux = Vec3::new(albedo[0], albedo[1], albedo[2]) * *irradiance * *texel_area;
            let weight = luminance(flux);
            if weight <= 0.0 || !weight.is_finite() {
                return None;
            }
            return Some(Candidate {
                vpl: GpuVpl {
                    position: [p.x, p.y, p.z, path_flag],
                    normal: [normal[0], normal[1], normal[2], ir],
                    flux: [flux.x, flux.y, flux.z, 0.0],
                },
                weight,
            });
        }
    };
    let to_surface = p - light.position;
    let dist = to_surface.length();
    if dist <= 0.0 {
        return None;
    }
    let intensity = light.intensity_towards(to_surface / dist);
    let d_omega = texel_solid_angle(idx as u32 % rsm.size, idx as u32 / rsm.size, rsm.size, rsm.tan_half_fov);
    let flux = Vec3::new(albedo[0], albedo[1], albedo[2]) * intensity * d_omega;
    let weight = luminance(flux);
    if weight <= 0.0 || !weight.is_finite() {
        return None;
    }
    Some(Candidate {
        vpl: GpuVpl {
            position: [p.x, p.y, p.z, path_flag],
            normal: [normal[0], normal[1], normal[2], ir],
            flux: [flux.x, flux.y, flux.z, 0.0],
        },
        weight,
    })
}

/// The solid angle of texel (ix, iy) of a square perspective map of `size`² whose half field
/// of view has tangent `tan_half`: the texel's area on the unit image plane / (1 + x² + y²)^{3/2}.
pub fn texel_solid_angle(ix: u32, iy: u32, size: u32, tan_half: f32) -> f32 {
    let x = (2.0 * (ix as f32 + 0.5) / size as f32 - 1.0) * tan_half;
    let y = (2.0 * (iy as f32 + 0.5) / size as f32 - 1.0) * tan_half;
    (2.0 * tan_half / size as f32).powi(2) / (1.0 + x * x + y * y).powf(1.5)
}

/// Draws `count` VPLs from the RSMs of the given lights (spot lights and environment
/// directions).
pub fn create(lights: &[(RsmLight, RsmTexels)], count: u32) -> Vec<GpuVpl> {
    create_with(lights, &[], count)
}

/// [`create`], with further candidate VPLs drawn together with the RSMs' in proportion to
/// their flux: the reflected and refracted VPLs of caustics.
pub fn create_with(lights: &[(RsmLight, RsmTexels)], extra: &[GpuVpl], count: u32) -> Vec<GpuVpl> {
    Candidates::new(lights, extra).draw(count)
}

/// The candidate VPLs of [`create_with`] — `extra` first, then every light's RSM texels in
/// order — each weighted by its flux's luminance: made once, drawn from as often as needed (a
/// frame with more bounces draws the first bounce's VPLs twice, as a pilot and for its share of
/// the budget). The lights' maps are gone through on all threads and joined in order, so the
/// candidates, and what is drawn from them, do not depend on the thread count.
pub struct Candidates(Vec<Candidate>);

impl Candidates {
    pub fn new(lights: &[(RsmLight, RsmTexels)], extra: &[GpuVpl]) -> Candidates {
        use rayon::prelude::*;
        let mut candidates: Vec<Candidate> = extra.iter().filter_map(Candidate::of).collect();
        let per_light: Vec<Vec<Candidate>> =
            lights.par_iter().map(|(light, rsm)| light_candidates(light, rsm)).collect();
        candidates.reserve(per_light.iter().map(Vec::len).sum());
        for found in per_light {
            candidates.extend(found);
        }
        Candidates(candidates)
    }

    /// `count` VPLs drawn in proportion to the candidates' flux (see `draw`).
    pub fn draw(&self, count: u32) -> Vec<GpuVpl> {
        draw(&self.0, count)
    }
}

/// The candidates of one light's RSM texels, in texel order.
fn light_candidates(light: &RsmLight, rsm: &RsmTexels) -> Vec<Candidate> {
    let r_pl = if light.real() { 1.0 } else { 0.0 };
    let mut candidates = Vec::new();
    for idx in 0..rsm.real.len() {
        let real = &rsm.real[idx];
        let virt = &rsm.virt[idx];
        let has_real = real.0[3] > 0.5;
        let has_virt = virt.0[3] > 0.5;
        let virtual_in_front = has_virt && (!has_real || virt.3 < real.3);
        let found = if virtual_in_front {
            let shadowed_real =
                if has_real && light.real() { candidate(light, rsm, idx, real, 1.0, 1.0) } else { None };
            [candidate(light, rsm, idx, virt, 0.0, 0.0), shadowed_real]
        } else if has_real {
            [candidate(light, rsm, idx, real, r_pl, 0.0), None]
        } else {
            [None, None]
        };
        candidates.extend(found.into_iter().flatten());
    }
    candidates
}

/// Draws `count` VPLs from weighted candidates: stratified inversion of the weights' CDF, each
/// drawn VPL carrying flux / (count · p) (deterministic).
fn draw(candidates: &[Candidate], count: u32) -> Vec<GpuVpl> {
    let weights: Vec<f64> = candidates.iter().map(|c| c.weight as f64).collect();
    stratify(&weights, count)
        .into_iter()
        .map(|(i, p)| {
            let scale = (1.0 / (count as f64 * p)) as f32;
            let mut vpl = candidates[i].vpl;
            vpl.flux = [vpl.flux[0] * scale, vpl.flux[1] * scale, vpl.flux[2] * scale, vpl.flux[3]];
            vpl
        })
        .collect()
}

/// Stratified inversion of the CDF of non-negative `weights`: for each stratum (k + 0.5) / count,
/// the index whose CDF interval holds it and that index's probability, in index order; empty
/// when the weights sum to zero or `count` is 0. VPL creation and the multiple-bounce source's
/// slots draw with it.
pub fn stratify(weights: &[f64], count: u32) -> Vec<(usize, f64)> {
    let total: f64 = weights.iter().sum();
    if weights.is_empty() || total <= 0.0 || count == 0 {
        return Vec::new();
    }
    let mut drawn = Vec::with_capacity(count as usize);
    let mut cumulative = 0.0f64;
    let mut next = 0usize;
    for (i, w) in weights.iter().enumerate() {
        let p = w / total;
        cumulative += p;
        while next < count as usize && (next as f64 + 0.5) / count as f64 <= cumulative {
            drawn.push((i, p));
            next += 1;
        }
    }
    drawn
}

/// Draws `count` VPLs from a larger set in proportion to their flux, keeping its total flux in
/// expectation (each carries total / count in luminance): how a bounce's pilot VPLs shrink to
/// the bounce's share of the budget.
pub fn resample(vpls: &[GpuVpl], count: u32) -> Vec<GpuVpl> {
    let candidates: Vec<Candidate> = vpls.iter().filter_map(Candidate::of).collect();
    draw(&candidates, count)
}

/// Total luminance flux of a set of VPLs.
pub fn luminance_flux(vpls: &[GpuVpl]) -> f64 {
    vpls.iter().map(|v| luminance(Vec3::new(v.flux[0], v.flux[1], v.flux[2])) as f64).filter(|w| w.is_finite()).sum()
}

/// Splits `budget` VPLs over light sources in proportion to their flux (the thesis's third
/// distribution mode), by largest remainder; a source with flux gets at least one VPL while the
/// budget lasts.
pub fn split_budget(budget: u32, fluxes: &[f64]) -> Vec<u32> {
    let valid: Vec<f64> = fluxes.iter().map(|f| if f.is_finite() && *f > 0.0 { *f } else { 0.0 }).collect();
    let total: f64 = valid.iter().sum();
    if total <= 0.0 {
        return vec![0; fluxes.len()];
    }
    let exact: Vec<f64> = valid.iter().map(|f| budget as f64 * f / total).collect();
    let mut counts: Vec<u32> = exact.iter().map(|e| e.floor() as u32).collect();
    let mut left = budget - counts.iter().sum::<u32>();
    // first, every source with flux and no VPL yet; then the largest remainders
    let mut order: Vec<usize> = (0..exact.len()).filter(|&i| valid[i] > 0.0).collect();
    order.sort_by(|&a, &b| {
        (counts[a] > 0)
            .cmp(&(counts[b] > 0))
            .then((exact[b] - exact[b].floor()).total_cmp(&(exact[a] - exact[a].floor())))
    });
    for i in order {
        if left == 0 {
            break;
        }
        counts[i] += 1;
        left -= 1;
    }
    counts
}

/// The sampler's shader (`vpl.wgsl`).
pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("vpl.wgsl"));

/// One light's RSM textures on the GPU, for [`VplSampler::candidates`]: position, normal, albedo
/// and distance of the real-only map, and of the virtual-only map where there is one.
pub struct RsmMaps<'a> {
    pub light: RsmLight<'a>,
    /// Half-width of a spot's image plane at unit distance (0 for an environment direction).
    pub tan_half_fov: f32,
    pub size: u32,
    pub real: [&'a Arc<wgpu::Texture>; 4],
    pub virt: Option<[&'a Arc<wgpu::Texture>; 4]>,
}

/// One caustic map's photons on the GPU (`Specular::caustic_sources`), for
/// [`VplSampler::candidates`]: the GPU's counterpart of `Specular::caustic_vpls`.
pub struct CausticMap<'a> {
    pub light: &'a SpotLight,
    /// The mirror or glass object's index (the photon's `info` names the object it met).
    pub object: u32,
    pub object_real: bool,
    pub tan_half: f32,
    pub size: u32,
    /// The hit planes' row stride (texels).
    pub stride: u32,
    /// Where each photon left the light's image plane onto the object (the photon G-buffer).
    pub position: &'a wgpu::Texture,
    /// Per photon: reflection and refraction weights and status, the object (specular.wgsl).
    pub info: &'a wgpu::Buffer,
    /// The reflected and refracted hits: position, normal, albedo planes.
    pub hits: &'a wgpu::Buffer,
}

/// A light in `CausticParams` and `MapParams` of vpl.wgsl: a spot's position (w: tan of half
/// the map's field of view), direction (w: cos_outer) and intensity (w: cos_inner); an
/// environment direction's irradiance in `intensity`.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct LightRows {
    position: [f32; 4],
    direction: [f32; 4],
    intensity: [f32; 4],
}

impl LightRows {
    fn spot(light: &SpotLight, tan_half: f32) -> LightRows {
        let (p, d, i) = (light.position, light.direction, light.intensity);
        LightRows {
            position: [p.x, p.y, p.z, tan_half],
            direction: [d.x, d.y, d.z, light.cos_outer],
            intensity: [i.x, i.y, i.z, light.cos_inner],
        }
    }
}

/// Matches `CausticParams` in vpl.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct CausticUniform {
    info: [u32; 4],
    offset: [u32; 4],
    light: LightRows,
}

/// Matches `MapParams` in vpl.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct MapUniform {
    info: [u32; 4],
    offset: [u32; 4],
    light: LightRows,
    area: [f32; 4],
}

/// Slots of the CDF's blocks in vpl.wgsl (256 threads of 8).
const BLOCK: u32 = 2048;
/// Workgroups per dispatch row (the limit per dimension).
const ROW: u32 = 65_535;

/// VPL creation on the GPU: the candidates of [`Candidates`] made from the RSM textures where
/// they were rendered, their CDF, and the stratified draw of [`Candidates::draw`] — only the
/// drawn VPLs are read back (48 bytes each), not the RSMs (15 MB at the thesis's 18 maps of
/// 128²). The CDF is summed in `f32` in a fixed order (the CPU's in `f64`), so a stratum that
/// falls within rounding of a CDF step can take the neighbouring candidate: the tests
/// `the_gpu_sampler_draws_the_cpu_references_vpls` (random RSMs) and
/// `a_gi_frames_vpls_are_the_same_made_on_the_gpu_or_the_cpu` (gi frames, with caustics) bound
/// how often.
pub struct VplSampler {
    candidates: wgpu::ComputePipeline,
    caustic_candidates: wgpu::ComputePipeline,
    block_sums: wgpu::ComputePipeline,
    scan_blocks: wgpu::ComputePipeline,
    scan: wgpu::ComputePipeline,
    draw: wgpu::ComputePipeline,
    draw_planned: wgpu::ComputePipeline,
}

/// A frame's candidate VPLs on the GPU and their CDF ([`VplSampler::candidates`]), drawn from
/// as often as needed ([`VplSampler::draw`]).
pub struct GpuCandidates {
    slots: u32,
    blocks: u32,
    candidates: std::sync::Arc<wgpu::Buffer>,
    weights: std::sync::Arc<wgpu::Buffer>,
    /// The blocks' exclusive offsets, then the total weight.
    offsets: std::sync::Arc<wgpu::Buffer>,
    cdf: std::sync::Arc<wgpu::Buffer>,
}

impl GpuCandidates {
    /// Candidate slots (two per RSM texel, one per extra candidate), most of them empty.
    pub fn slots(&self) -> u32 {
        self.slots
    }
}

impl VplSampler {
    pub fn new(ctx: &super::context::GpuContext) -> VplSampler {
        let [candidates, caustic_candidates, block_sums, scan_blocks, scan, draw, draw_planned] = ctx
            .compute_pipelines(
                "vpl.wgsl",
                SHADER,
                [
                    "cs_candidates",
                    "cs_caustic_candidates",
                    "cs_block_sums",
                    "cs_scan_blocks",
                    "cs_scan",
                    "cs_draw",
                    "cs_draw_planned",
                ],
            );
        VplSampler { candidates, caustic_candidates, block_sums, scan_blocks, scan, draw, draw_planned }
    }

    /// The bytes of the candidates' buffer for `slots` slots: more than the device binds in one
    /// storage buffer means the RSMs must be sampled on the CPU.
    pub fn fits(ctx: &super::context::GpuContext, slots: u64) -> bool {
        let limits = ctx.device.limits();
        slots * std::mem::size_of::<GpuVpl>() as u64
            <= limits.max_storage_buffer_binding_size.min(limits.max_buffer_size)
    }

    /// Candidate slots for `extra` candidates, `caustics` and `maps`.
    pub fn slots(extra: usize, caustics: &[CausticMap], maps: &[RsmMaps]) -> u64 {
        let square = |size: u32| 2 * size as u64 * size as u64;
        extra as u64
            + caustics.iter().map(|c| square(c.size)).sum::<u64>()
            + maps.iter().map(|m| square(m.size)).sum::<u64>()
    }

    /// The candidates of [`Candidates::new`] — `extra` first (made on the CPU), then every
    /// caustic map's photons (two slots each: reflected, refracted), then every light's RSM texels
    /// in order (two slots each) — and their CDF, submitted in one command buffer (nothing waits).
    /// With the caustic maps' candidates of `Specular::caustic_vpls` as `extra` instead of
    /// `caustics`, the same candidates in the same order.
    pub fn candidates(
        &self,
        ctx: &super::context::GpuContext,
        extra: &[GpuVpl],
        caustics: &[CausticMap],
        maps: &[RsmMaps],
    ) -> GpuCandidates {
        let slots = u32::try_from(Self::slots(extra.len(), caustics, maps)).expect("candidate slots fit in u32");
        let blocks = slots.div_ceil(BLOCK).max(1);
        let storage = |label: &str, bytes: u64| {
            ctx.buffer(
                label,
                bytes.max(16),
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                super::pool::Contents::Zeroed,
            )
        };
        let out = GpuCandidates {
            slots,
            blocks,
            candidates: storage("vpl candidates", slots as u64 * std::mem::size_of::<GpuVpl>() as u64),
            weights: storage("vpl candidate weights", slots as u64 * 4),
            offsets: storage("vpl cdf offsets", (blocks as u64 + 1) * 4),
            cdf: storage("vpl cdf", slots as u64 * 4),
        };
        if !extra.is_empty() {
            let weights: Vec<f32> = extra.iter().map(|v| Candidate::of(v).map_or(0.0, |c| c.weight)).collect();
            ctx.write_buffer(&out.candidates, 0, bytemuck::cast_slice(extra));
            ctx.write_buffer(&out.weights, 0, bytemuck::cast_slice(&weights));
        }
        let mut encoder = ctx.encoder();
        let mut offset = extra.len() as u32;
        for map in caustics {
            let (light, n) = (map.light, map.size);
            let uniform = CausticUniform {
                info: [n, map.stride, map.object, (light.real && map.object_real) as u32],
                offset: [offset, 0, 0, 0],
                light: LightRows::spot(light, map.tan_half),
            };
            let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some("vpl caustic map"),
                contents: bytemuck::bytes_of(&uniform),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let position = map.position.create_view(&Default::default());
            ctx.record_dispatch(
                &mut encoder,
                "vpl caustic candidates",
                &self.caustic_candidates,
                &[
                    wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&position) },
                    wgpu::BindGroupEntry { binding: 2, resource: map.info.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: map.hits.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 9, resource: out.candidates.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 10, resource: out.weights.as_entire_binding() },
                ],
                [n.div_ceil(8), n.div_ceil(8)],
            );
            offset += 2 * n * n;
        }
        for map in maps {
            let (kind, light, area) = match &map.light {
                RsmLight::Spot(spot) => (0, LightRows::spot(spot, map.tan_half_fov), 0.0),
                RsmLight::Directional { irradiance, texel_area } => {
                    let intensity = [irradiance.x, irradiance.y, irradiance.z, 0.0];
                    (1, LightRows { intensity, ..LightRows::default() }, *texel_area)
                }
            };
            let uniform = MapUniform {
                info: [kind, map.light.real() as u32, map.virt.is_some() as u32, map.size],
                offset: [offset, 0, 0, 0],
                light,
                area: [area, 0.0, 0.0, 0.0],
            };
            let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some("vpl map"),
                contents: bytemuck::bytes_of(&uniform),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            // without a virtual map the real one is bound in its place (the shader does not read it)
            // (kept with the pool's textures from frame to frame)
            let views: Vec<Arc<wgpu::TextureView>> =
                map.real.iter().chain(map.virt.as_ref().unwrap_or(&map.real)).map(|t| ctx.views.of(t)).collect();
            let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() }];
            entries.extend(views.iter().enumerate().map(|(k, view)| wgpu::BindGroupEntry {
                binding: 1 + k as u32,
                resource: wgpu::BindingResource::TextureView(view),
            }));
            entries.push(wgpu::BindGroupEntry { binding: 9, resource: out.candidates.as_entire_binding() });
            entries.push(wgpu::BindGroupEntry { binding: 10, resource: out.weights.as_entire_binding() });
            let groups = map.size.div_ceil(8);
            ctx.record_dispatch(&mut encoder, "vpl candidates", &self.candidates, &entries, [groups, groups]);
            offset += 2 * map.size * map.size;
        }
        let sizes = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("vpl cdf sizes"),
            contents: bytemuck::bytes_of(&[slots, blocks, 0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let rows = [blocks.min(ROW), blocks.div_ceil(ROW)];
        let steps: [(&wgpu::ComputePipeline, &[u32], [u32; 2]); 3] = [
            (&self.block_sums, &[0, 1, 2], rows),
            (&self.scan_blocks, &[0, 2], [1, 1]),
            (&self.scan, &[0, 1, 2, 3], rows),
        ];
        for (pipeline, bindings, groups) in steps {
            let buffers = [&sizes, &out.weights, &out.offsets, &out.cdf];
            let entries: Vec<wgpu::BindGroupEntry> = bindings
                .iter()
                .map(|&b| wgpu::BindGroupEntry { binding: b, resource: buffers[b as usize].as_entire_binding() })
                .collect();
            ctx.record_dispatch(&mut encoder, "vpl cdf", pipeline, &entries, groups);
        }
        ctx.submit(encoder);
        out
    }

    /// `count` VPL slots on the GPU (zeroed: a slot without flux is no VPL).
    pub fn slots_buffer(ctx: &super::context::GpuContext, label: &str, count: u32) -> std::sync::Arc<wgpu::Buffer> {
        let bytes = count.max(1) as u64 * std::mem::size_of::<GpuVpl>() as u64;
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        ctx.buffer(label, bytes, usage, super::pool::Contents::Zeroed)
    }

    /// Records the draw of `count` VPLs into `drawn` (`cs_draw`), or of as many as `plan`'s first
    /// word says (`cs_draw_planned`, `count` threads), as [`Candidates::draw`] draws them.
    fn record_draw(
        &self,
        ctx: &super::context::GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        candidates: &GpuCandidates,
        count: u32,
        drawn: &wgpu::Buffer,
        plan: Option<&wgpu::Buffer>,
    ) {
        let sizes = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("vpl draw sizes"),
            contents: bytemuck::bytes_of(&[candidates.slots, candidates.blocks, count, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let mut entries = vec![
            wgpu::BindGroupEntry { binding: 0, resource: sizes.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: candidates.candidates.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: candidates.weights.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: candidates.cdf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: candidates.offsets.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 5, resource: drawn.as_entire_binding() },
        ];
        entries.extend(plan.map(|p| wgpu::BindGroupEntry { binding: 6, resource: p.as_entire_binding() }));
        let pipeline = if plan.is_some() { &self.draw_planned } else { &self.draw };
        ctx.record_dispatch(encoder, "vpl draw", pipeline, &entries, [count.div_ceil(64).max(1), 1]);
    }

    /// [`VplSampler::draw`] left on the GPU (a live frame's VPLs, which the ISMs and the shading
    /// read there): `count` slots, zero where no candidate has flux. Nothing waits.
    pub fn draw_resident(
        &self,
        ctx: &super::context::GpuContext,
        candidates: &GpuCandidates,
        count: u32,
    ) -> std::sync::Arc<wgpu::Buffer> {
        let drawn = Self::slots_buffer(ctx, "vpls drawn", count);
        if count > 0 && candidates.slots > 0 {
            let mut encoder = ctx.encoder();
            self.record_draw(ctx, &mut encoder, candidates, count, &drawn, None);
            ctx.submit(encoder);
        }
        drawn
    }

    /// The first bounce's share of a live frame's budget into the first slots of `out`: as many
    /// VPLs as `plan`'s first word (bounce_chain.wgsl's `cs_split`), at most `capacity`.
    pub fn draw_planned(
        &self,
        ctx: &super::context::GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        candidates: &GpuCandidates,
        capacity: u32,
        (plan, out): (&wgpu::Buffer, &wgpu::Buffer),
    ) {
        if capacity > 0 && candidates.slots > 0 {
            self.record_draw(ctx, encoder, candidates, capacity, out, Some(plan));
        }
    }

    /// `count` VPLs drawn from `candidates` as [`Candidates::draw`] does (stratified, each carrying
    /// flux / (count · p)); empty when no candidate has flux. Waits for the device to read
    /// back the drawn VPLs.
    pub fn draw(&self, ctx: &super::context::GpuContext, candidates: &GpuCandidates, count: u32) -> Vec<GpuVpl> {
        if count == 0 || candidates.slots == 0 {
            return Vec::new();
        }
        let vpl_bytes = count as u64 * std::mem::size_of::<GpuVpl>() as u64;
        let zeroed = super::pool::Contents::Zeroed;
        let drawn =
            ctx.buffer("vpls drawn", vpl_bytes, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC, zeroed);
        let staging = ctx.buffer("vpls drawn read back", vpl_bytes + 4, wgpu::BufferUsages::MAP_READ, zeroed);
        let mut encoder = ctx.encoder();
        self.record_draw(ctx, &mut encoder, candidates, count, &drawn, None);
        encoder.copy_buffer_to_buffer(&drawn, 0, &staging, 0, vpl_bytes);
        encoder.copy_buffer_to_buffer(&candidates.offsets, candidates.blocks as u64 * 4, &staging, vpl_bytes, 4);
        ctx.submit(encoder);
        let bytes = ctx.read_buffer(&staging);
        if bytes.len() as u64 != vpl_bytes + 4 {
            return Vec::new();
        }
        let total = f32::from_le_bytes(bytes[vpl_bytes as usize..].try_into().expect("4 bytes"));
        if !(total > 0.0 && total.is_finite()) {
            return Vec::new();
        }
        bytemuck::pod_collect_to_vec(&bytes[..vpl_bytes as usize])
    }
}

#[cfg(test)]
mod tests;
