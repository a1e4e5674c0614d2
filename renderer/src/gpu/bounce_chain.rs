//! A live frame's VPLs made and consumed on the GPU (shader: `bounce_chain.wgsl`): the further
//! bounces of the multiple-bounce light source ([`super::bounce`]) and the budget split by flux,
//! recorded in one command buffer, so the frame reads nothing back before its image. The
//! stimulus frame keeps the host's steps (`Bounce::spawn`, `vpl::split_budget`,
//! `vpl::resample`), whose outputs are recorded byte for byte; these follow them with the GPU's
//! `f32` sums (the CDFs, the fluxes), so a live frame's VPLs are drawn the same way but not
//! always the same ones, and are laid out in slots of the budget (zero where none).
//!
//! 1. The first bounce's pilot: the whole budget drawn from the RSMs' candidates
//!    (`VplSampler::draw_resident`).
//! 2. Per further bounce: `cs_link` links the slots to the previous VPLs by flux and gives each a
//!    direction; bounce.wgsl's `cs_nearest` searches its cone; `cs_spawn` makes the pilot's VPLs.
//! 3. `cs_split`: the fluxes and the budget split over the first bounce and the pilots (the plan);
//!    the first bounce's share drawn again by the plan (`cs_draw_planned`), each pilot's
//!    resampled (`cs_resample`) into the frame's VPLs.

use super::bounce::{Bounce, BounceReport, BounceScene, BounceSearch};
use super::context::GpuContext;
use super::pool::Contents;
use super::raster::SceneBuffers;
use super::vpl::{GpuCandidates, GpuVpl, VplSampler};
use std::sync::Arc;

// on one line: the naga test builds a shader from the first line that includes it
#[rustfmt::skip]
pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("cdf.wgsl"), include_str!("material.wgsl"), include_str!("bounce_chain.wgsl"));

/// Sources of the split at most: the first bounce and seven further ones (`MAX_BOUNCES`).
const SOURCES: usize = 8;

/// Matches `ChainParams` in bounce_chain.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct ChainUniform {
    counts: [u32; 4],
    more: [u32; 4],
}

pub struct BounceChain {
    link: wgpu::ComputePipeline,
    spawn: wgpu::ComputePipeline,
    split: wgpu::ComputePipeline,
    resample: wgpu::ComputePipeline,
}

/// What a live frame's chain reads: the first bounce's candidates and pilot, the scene (its
/// candidate points, vertices and materials), the budget and the bounces' search.
pub struct ChainInputs<'a> {
    pub candidates: &'a GpuCandidates,
    /// The first bounce's pilot: `budget` slots drawn from the candidates.
    pub first: &'a wgpu::Buffer,
    pub scene: &'a BounceScene,
    pub buffers: &'a SceneBuffers,
    pub budget: u32,
    /// The bounces in all (2: one further bounce), at most `MAX_BOUNCES`.
    pub bounces: u32,
    pub candidates_per_slot: u32,
    pub cone_degrees: f32,
    pub scene_radius: f32,
}

/// A live frame's VPLs on the GPU, and what the report says of them once read back with the
/// image ([`ChainOutput::report`]).
pub struct ChainOutput {
    /// `budget` slots: the first bounce's share, then each further bounce's.
    pub vpls: Arc<wgpu::Buffer>,
    /// The plan (`cs_split`): counts, offsets and fluxes of the sources, eight words each.
    pub plan: Arc<wgpu::Buffer>,
    /// Per further bounce: slots that found a surface, extra real-only VPLs.
    pub stats: Arc<wgpu::Buffer>,
    pub budget: u32,
    pub bounces: u32,
}

impl ChainOutput {
    /// Words of `plan` and `stats` read back together.
    pub const WORDS: usize = 3 * SOURCES + 2 * SOURCES;

    /// The bounces' reports and the VPLs in all, from the words of `plan` then `stats`.
    pub fn report(&self, words: &[u32]) -> (Vec<BounceReport>, usize) {
        let word = |k: usize| words.get(k).copied().unwrap_or(0);
        let vpls = (0..SOURCES).map(|k| word(k) as usize).sum();
        let reports = (2..=self.bounces)
            .map(|b| {
                let k = (b - 1) as usize;
                BounceReport {
                    bounce: b,
                    slots: self.budget,
                    found: word(3 * SOURCES + 2 * (k - 1)),
                    real_only: word(3 * SOURCES + 2 * (k - 1) + 1),
                    flux: f32::from_bits(word(2 * SOURCES + k)),
                    vpls: word(k) as usize,
                }
            })
            .collect();
        (reports, vpls)
    }
}

/// Binding `binding` to the whole of `buffer`.
fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}

impl BounceChain {
    pub fn new(ctx: &GpuContext) -> BounceChain {
        let [link, spawn, split, resample] =
            ctx.compute_pipelines("bounce_chain.wgsl", SHADER, ["cs_link", "cs_spawn", "cs_split", "cs_resample"]);
        BounceChain { link, spawn, split, resample }
    }

    /// The further bounces and the split, recorded and submitted in one command buffer (nothing
    /// waits): the frame's VPLs in `budget` slots.
    pub fn run(&self, ctx: &GpuContext, bounce: &Bounce, sampler: &VplSampler, at: &ChainInputs) -> ChainOutput {
        let budget = at.budget.max(1);
        let pilots = at.bounces.clamp(2, SOURCES as u32) - 1;
        let pilot_slots = 2 * budget;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let buffer = |label: &str, bytes: u64| ctx.buffer(label, bytes.max(16), storage, Contents::Zeroed);
        let vpl_bytes = std::mem::size_of::<GpuVpl>() as u64;
        let pilot_vpls = buffer("bounce pilots", pilots as u64 * pilot_slots as u64 * vpl_bytes);
        let cdf = buffer("bounce chain cdf", pilot_slots as u64 * 4);
        let ranks = buffer("bounce chain ranks", pilot_slots as u64 * 4);
        let slots = buffer("bounce chain slots", budget as u64 * 48);
        let links = buffer("bounce chain links", budget as u64 * 32);
        let plan = buffer("bounce plan", 3 * SOURCES as u64 * 4);
        let stats = buffer("bounce stats", 2 * SOURCES as u64 * 4);
        let out = VplSampler::slots_buffer(ctx, "vpls of the frame", budget);
        let uniform = |counts: [u32; 4], more: [u32; 4]| {
            ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some("bounce chain params"),
                contents: bytemuck::bytes_of(&ChainUniform { counts, more }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let triangles = at.scene.triangles;
        // each search's hits taken (and cleared) before the chain's commands
        let hits: Vec<_> = (0..pilots).map(|_| Bounce::hits(ctx, budget)).collect();
        let mut encoder = ctx.encoder();
        for k in 0..pilots {
            let b = k + 2;
            let seed = b.wrapping_mul(0x9e37_79b9);
            let (sources, first, n) = match k {
                0 => (at.first, 0, budget),
                _ => (&*pilot_vpls, (k - 1) * pilot_slots, pilot_slots),
            };
            let params = uniform([n, budget, seed, k], [triangles, first, 0, 0]);
            let entries = [
                entry(0, &params),
                entry(1, sources),
                entry(2, &cdf),
                entry(3, &slots),
                entry(4, &links),
                entry(15, &ranks),
            ];
            ctx.record_dispatch(&mut encoder, "bounce link", &self.link, &entries, [1, 1]);
            let search = BounceSearch { candidates: at.candidates_per_slot, cone_degrees: at.cone_degrees, seed };
            let hits = &hits[k as usize];
            bounce.record_nearest(ctx, &mut encoder, at.scene, (&slots, budget, hits), &search, at.scene_radius);
            let params = uniform([n, budget, seed, k], [triangles, k * pilot_slots, 0, 0]);
            let entries = [
                entry(0, &params),
                entry(3, &slots),
                entry(5, &links),
                entry(6, hits),
                entry(7, &at.buffers.vertices),
                entry(8, &at.buffers.materials),
                entry(9, &pilot_vpls),
                entry(10, &stats),
            ];
            let groups = budget.div_ceil(64);
            ctx.record_dispatch(
                &mut encoder,
                "bounce spawn",
                &self.spawn,
                &entries,
                [groups.min(65535), groups.div_ceil(65535)],
            );
        }
        let params = uniform([pilot_slots, budget, 0, 0], [triangles, 0, 0, pilots + 1]);
        let entries = [entry(0, &params), entry(1, &pilot_vpls), entry(11, &plan), entry(12, at.first)];
        ctx.record_dispatch(&mut encoder, "bounce split", &self.split, &entries, [1, 1]);
        sampler.draw_planned(ctx, &mut encoder, at.candidates, budget, (&plan, &out));
        for k in 0..pilots {
            let params = uniform([pilot_slots, budget, 0, 0], [triangles, k * pilot_slots, k + 1, 0]);
            let entries = [entry(0, &params), entry(1, &pilot_vpls), entry(2, &cdf), entry(13, &plan), entry(14, &out)];
            ctx.record_dispatch(&mut encoder, "bounce resample", &self.resample, &entries, [1, 1]);
        }
        ctx.submit(encoder);
        ChainOutput { vpls: out, plan, stats, budget, bounces: pilots + 1 }
    }
}
