//! The colour-mapping passes of the `cm` factor on the GPU (shader: `cm.wgsl`): reductions of
//! per-pixel contributions (statistics; Rohmer's approximation and eq. 2 sums), the argmax of
//! the sample-based matching, and the map of both GI buffers. The tiny solves between passes
//! are the CPU reference's own ([`crate::cm`]), so only the per-pixel work and the sums run here.
//! Each pass is timed into the frame report as `cm <method>: <step>`.

use super::context::GpuContext;
use super::{PassTime, timed};
use crate::cm::{CmInput, CmMethod, CmParams, CmReport, CmState, Mapping, rohmer, samples, statistics};
use glam::{Mat3, Vec3};
use std::time::Instant;

pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("cm.wgsl"));

/// Floats per contribution in `cm.wgsl` (K).
const K: usize = 20;
const GROUP: u32 = 64;
/// Workgroups of a reduction (each thread strides over the pixels).
const MAX_GROUPS: u32 = 512;

/// Matches `Cm` in cm.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CmUniform {
    pub size: [u32; 4],
    pub tone: [f32; 4],
    pub filt: [f32; 4],
    pub m: [[f32; 4]; 3],
}

impl CmUniform {
    pub fn new(params: &CmParams, exposure: f32, width: u32, height: u32, mode: u32, m: [[f32; 4]; 3]) -> CmUniform {
        CmUniform {
            size: [width, height, mode, 0],
            tone: [exposure, params.saturated, params.dark, params.gradient],
            filt: [params.hs_coarse, params.hsv_fine, params.beta_approx, params.beta_fit],
            m,
        }
    }
}

fn rows3(m: &Mat3) -> [[f32; 4]; 3] {
    rohmer::to_rows(*m).map(|r| [r[0], r[1], r[2], 0.0])
}

/// The map pass's uniform code and rows for a mapping.
pub fn mapping_rows(mapping: &Mapping) -> (u32, [[f32; 4]; 3]) {
    match mapping {
        Mapping::Off => (0, [[0.0; 4]; 3]),
        Mapping::Statistics { mean_source, mean_target, ratio } => {
            let v = |a: &[f32; 3]| [a[0], a[1], a[2], 0.0];
            (1, [v(mean_source), v(mean_target), v(ratio)])
        }
        Mapping::Affine { rows } => (2, *rows),
        Mapping::Linear { rows } => (3, rows.map(|r| [r[0], r[1], r[2], 0.0])),
    }
}

pub struct CmPasses {
    reduce: wgpu::ComputePipeline,
    matcher: wgpu::ComputePipeline,
    map: wgpu::ComputePipeline,
}

/// The GPU buffers a frame's colour mapping reads.
pub struct CmBuffers<'a> {
    pub width: u32,
    pub height: u32,
    /// L_rv (w: flag) then L_r, as the shading pass wrote them.
    pub solutions: &'a wgpu::Buffer,
    /// The photograph (display-encoded), one vec4 per pixel.
    pub photo: &'a wgpu::Buffer,
}

/// The colour mapping's parameters and the exposure applied before its tone mapping.
#[derive(Clone, Copy)]
pub struct CmSettings<'a> {
    pub params: &'a CmParams,
    pub exposure: f32,
}

impl CmPasses {
    pub fn new(ctx: &GpuContext) -> Self {
        let [reduce, matcher, map] = ctx.compute_pipelines("cm.wgsl", SHADER, ["cs_reduce", "cs_match", "cs_map"]);
        CmPasses { reduce, matcher, map }
    }

    fn dispatch(
        &self,
        ctx: &GpuContext,
        pipeline: &wgpu::ComputePipeline,
        entries: &[(u32, &wgpu::Buffer)],
        groups: (u32, u32),
    ) {
        let entries: Vec<wgpu::BindGroupEntry> = entries
            .iter()
            .map(|(binding, buffer)| wgpu::BindGroupEntry { binding: *binding, resource: buffer.as_entire_binding() })
            .collect();
        ctx.dispatch("cm", pipeline, &entries, [groups.0, groups.1]);
    }

    fn uniform_buffer(ctx: &GpuContext, uniform: &CmUniform) -> std::sync::Arc<wgpu::Buffer> {
        ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("cm params"),
            contents: bytemuck::bytes_of(uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        })
    }

    fn output(ctx: &GpuContext, label: &str, bytes: u64) -> std::sync::Arc<wgpu::Buffer> {
        ctx.buffer(
            label,
            bytes.max(16),
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            super::pool::Contents::Zeroed,
        )
    }

    /// One reduction (mode 0 statistics, 1 Rohmer approximation, 2 Rohmer fit): the sums of
    /// the contributions, partials added in f64 on the CPU.
    pub fn reduce(&self, ctx: &GpuContext, buffers: &CmBuffers, uniform: &CmUniform) -> [f64; K] {
        let pixels = buffers.width * buffers.height;
        let groups = pixels.div_ceil(GROUP).clamp(1, MAX_GROUPS);
        let partials = Self::output(ctx, "cm partials", groups as u64 * K as u64 * 4);
        let uni = Self::uniform_buffer(ctx, uniform);
        self.dispatch(
            ctx,
            &self.reduce,
            &[(0, &uni), (1, buffers.solutions), (2, buffers.photo), (3, &partials)],
            (groups, 1),
        );
        let values = ctx.read_f32(&partials);
        let mut sums = [0f64; K];
        for chunk in values.chunks_exact(K) {
            for k in 0..K {
                sums[k] += chunk[k] as f64;
            }
        }
        sums
    }

    /// For each tone-mapped sample colour, the best-matching usable real pixel.
    pub fn matches(
        &self,
        ctx: &GpuContext,
        buffers: &CmBuffers,
        uniform: &CmUniform,
        colours: &[Vec3],
    ) -> Vec<Option<usize>> {
        if colours.is_empty() {
            return Vec::new();
        }
        let pixels = buffers.width * buffers.height;
        let groups = pixels.div_ceil(GROUP).clamp(1, 64);
        let texels: Vec<[f32; 4]> = colours.iter().map(|c| [c.x, c.y, c.z, 0.0]).collect();
        let colour_buffer = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("cm colours"),
            contents: bytemuck::cast_slice(&texels),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let out = Self::output(ctx, "cm matches", groups as u64 * colours.len() as u64 * 8);
        let uni = Self::uniform_buffer(ctx, uniform);
        self.dispatch(
            ctx,
            &self.matcher,
            &[(0, &uni), (1, buffers.solutions), (2, buffers.photo), (4, &colour_buffer), (5, &out)],
            (groups, colours.len() as u32),
        );
        let words: Vec<u32> = bytemuck::cast_slice(&ctx.read_f32(&out)).to_vec();
        (0..colours.len())
            .map(|j| {
                let mut best: Option<(f32, u32)> = None;
                for g in 0..groups as usize {
                    let k = 2 * (j * groups as usize + g);
                    let (score, index) = (f32::from_bits(words[k]), words[k + 1]);
                    if index == u32::MAX {
                        continue;
                    }
                    if best.is_none_or(|(s, i)| score > s || (score == s && index < i)) {
                        best = Some((score, index));
                    }
                }
                best.map(|(_, i)| i as usize)
            })
            .collect()
    }

    /// τ(L_rv) and τ(L_r) into a new buffer of the same layout as the solutions.
    pub fn map(&self, ctx: &GpuContext, buffers: &CmBuffers, uniform: &CmUniform) -> std::sync::Arc<wgpu::Buffer> {
        let texels = 2 * buffers.width as u64 * buffers.height as u64;
        let mapped = Self::output(ctx, "cm mapped", texels * 16);
        let uni = Self::uniform_buffer(ctx, uniform);
        let rows = (texels as u32).div_ceil(256 * GROUP);
        self.dispatch(ctx, &self.map, &[(0, &uni), (1, buffers.solutions), (6, &mapped)], (256, rows.max(1)));
        mapped
    }

    /// The whole colour mapping of a frame: estimate (updating `state`), then map. `photo` is
    /// the photograph on the CPU (the sample-based method reads its pairs from it).
    pub fn run(
        &self,
        ctx: &GpuContext,
        passes: &mut Vec<PassTime>,
        buffers: &CmBuffers,
        photo: &[Vec3],
        settings: &CmSettings,
        state: &mut CmState,
    ) -> (std::sync::Arc<wgpu::Buffer>, CmReport) {
        let CmSettings { params, exposure } = *settings;
        let (w, h) = (buffers.width, buffers.height);
        let base = |mode: u32, m: [[f32; 4]; 3]| CmUniform::new(params, exposure, w, h, mode, m);
        let name = params.method.name();
        let mut warning = None;
        let (mapping, pairs, fallback) = match params.method {
            CmMethod::Off => (Mapping::Off, 0, None),
            CmMethod::Statistics => {
                let sums = timed(ctx, passes, format!("cm {name}: reduction"), || {
                    self.reduce(ctx, buffers, &base(0, [[0.0; 4]; 3]))
                });
                let sums: &[f64; statistics::K] = sums[..statistics::K].try_into().expect("K ≥ 13");
                warning = statistics::ratio_warning(sums);
                statistics::solve(sums)
            }
            CmMethod::Samples => {
                // the samples and their pairs are picked on the CPU from the read-back buffers
                let (solutions, input_photo) = timed(ctx, passes, format!("cm {name}: read back L_rv, L_r"), || {
                    (ctx.read_f32(buffers.solutions), photo.to_vec())
                });
                let n = (w * h) as usize;
                let texel = |k: usize| Vec3::new(solutions[4 * k], solutions[4 * k + 1], solutions[4 * k + 2]);
                let l_rv: Vec<Vec3> = (0..n).map(texel).collect();
                let l_r: Vec<Vec3> = (n..2 * n).map(texel).collect();
                let flags: Vec<u32> = (0..n).map(|k| (solutions[4 * k + 3] + 0.5) as u32).collect();
                let input = CmInput { width: w, height: h, l_rv: &l_rv, l_r: &l_r, flags: &flags, photo: &input_photo };
                let uniform = base(0, [[0.0; 4]; 3]);
                let start = Instant::now();
                let out = samples::estimate(&input, params, exposure, state, &|colours| {
                    self.matches(ctx, buffers, &uniform, colours)
                });
                passes.push(PassTime::new(
                    format!("cm {name}: matching (GPU) and regression"),
                    start.elapsed().as_secs_f64() * 1e3,
                ));
                out
            }
            CmMethod::Rohmer => {
                let approx = timed(ctx, passes, format!("cm {name}: approximation reduction"), || {
                    self.reduce(ctx, buffers, &base(1, [[0.0; 4]; 3]))
                });
                let (a, _) = rohmer::approximation(&approx, params);
                let previous = state.rohmer.map(rohmer::from_rows).unwrap_or(a);
                let fit = timed(ctx, passes, format!("cm {name}: eq. 2 reduction"), || {
                    self.reduce(ctx, buffers, &base(2, rows3(&previous)))
                });
                rohmer::solve(&approx[..rohmer::KA], &fit[..rohmer::KF], params, state)
            }
        };
        state.frames += 1;
        let (code, rows) = mapping_rows(&mapping);
        let mapped =
            timed(ctx, passes, format!("cm {name}: map L_rv, L_r"), || self.map(ctx, buffers, &base(code, rows)));
        (mapped, CmReport { method: params.method, mapping, pairs, fallback, warning })
    }
}
