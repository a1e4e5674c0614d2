//! Rohmer et al.'s scene representations built on the GPU (issue 18, Deliver 2; shader:
//! `representation.wgsl`): the distance impostor and the mip-mapped scene voxel volume, splatted
//! from the captured environment samples by compute passes, then read back into the CPU
//! reference's types ([`DistanceImpostor`], [`VoxelVolume`]), which the CPU queries read.
//!
//! - **Impostor**: two passes over the samples — the nearest distance per texel by `atomicMin` on
//!   the distance's bits (positive floats order as integers), then the radiance of the sample
//!   that won each texel (a tie between two samples at the very same distance keeps either).
//! - **Voxel volume**: radiance summed per voxel in fixed point (1/4096; one sample's radiance
//!   clamped at 16 383 so that 64 in a voxel cannot overflow), resolved to the mean, then one
//!   pass per mip level. The volume's bounds — one reduction over the samples — are taken on
//!   the CPU, as the CPU build takes them.
//!
//! Each splat is the CPU build's ([`SPLAT_RADIUS`]: a disk in the sample's tangent plane, on
//! each cube face the texels its bounding box projects onto); the impostor passes run one
//! invocation per (sample, face). The tests (`coherent::tests`) compare the two texel for texel
//! and voxel for voxel, and on lavapipe they agree exactly for survey-6's two impostors at 64²,
//! 128² and 256² and for the voxel volume. (With one invocation per sample looping over the
//! six faces, lavapipe lost 9 % of the book's impostor at 256², deterministically and at no
//! other size; why was not found.)
//!
//! `coherent::build_representation` builds with these passes when it is given a
//! [`super::DirRenderer`] (studies, `mrstudy render --gi-method`, `bench render --gi-methods`);
//! [`super::DirRenderer::representation_builder`] compiles them on first use.

use super::context::GpuContext;
use crate::capture::hashgrid::EnvironmentSample;
use crate::capture::impostor::{DistanceImpostor, SPLAT_RADIUS};
use crate::capture::voxel::VoxelVolume;
use glam::Vec3;
use std::time::Instant;
use wgpu::util::DeviceExt;

pub const SHADER: &str = include_str!("representation.wgsl");

/// Threads per workgroup of every entry point (`@workgroup_size(64)`).
const GROUP: u32 = 64;

/// A representation built on the GPU and how long it took.
pub struct Built<T> {
    pub value: T,
    /// Upload, passes and the wait for them, without the readback.
    pub gpu_ms: f64,
    /// The readback into the CPU's types.
    pub readback_ms: f64,
    /// GPU memory the passes held (samples, maps or volume, fixed-point sums).
    pub gpu_bytes: u64,
}

/// The compiled passes.
pub struct RepresentationBuilder {
    impostor_depth: wgpu::ComputePipeline,
    impostor_radiance: wgpu::ComputePipeline,
    voxel_splat: wgpu::ComputePipeline,
    voxel_resolve: wgpu::ComputePipeline,
    voxel_mip: wgpu::ComputePipeline,
}

/// Workgroups (x, y) for `n` threads: rows of at most 65 535 groups.
fn groups(n: u32) -> [u32; 2] {
    let total = n.div_ceil(GROUP).max(1);
    let x = total.min(65_535);
    [x, total.div_ceil(x)]
}

/// The samples as the shader reads them: position, normal and colour, each a vec4.
fn sample_buffer(ctx: &GpuContext, samples: &[EnvironmentSample]) -> wgpu::Buffer {
    let mut data: Vec<[f32; 4]> = Vec::with_capacity(3 * samples.len().max(1));
    for s in samples {
        data.push(s.position.extend(0.0).to_array());
        data.push(s.normal.extend(0.0).to_array());
        data.push(s.colour.extend(0.0).to_array());
    }
    if data.is_empty() {
        data.resize(3, [0.0; 4]);
    }
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("environment samples"),
        contents: bytemuck::cast_slice(&data),
        usage: wgpu::BufferUsages::STORAGE,
    })
}

fn uniform_buffer(ctx: &GpuContext, label: &str, data: &[u8]) -> wgpu::Buffer {
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: data,
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

fn storage(ctx: &GpuContext, label: &str, bytes: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The `Params` uniform: a point and a radius, then four counts.
fn params(point: Vec3, radius: f32, counts: [u32; 4]) -> Vec<u8> {
    let mut bytes = bytemuck::cast_slice(&point.extend(radius).to_array()).to_vec();
    bytes.extend_from_slice(bytemuck::cast_slice(&counts));
    bytes
}

impl RepresentationBuilder {
    pub fn new(ctx: &GpuContext) -> Self {
        let [impostor_depth, impostor_radiance, voxel_splat, voxel_resolve, voxel_mip] = ctx.compute_pipelines(
            "representation.wgsl",
            SHADER,
            ["cs_impostor_depth", "cs_impostor_radiance", "cs_voxel_splat", "cs_voxel_resolve", "cs_voxel_mip"],
        );
        RepresentationBuilder { impostor_depth, impostor_radiance, voxel_splat, voxel_resolve, voxel_mip }
    }

    /// The distance impostor of `samples` at `centre`, `size`² texels per face, as
    /// [`DistanceImpostor::build`] makes it.
    pub fn impostor(
        &self,
        ctx: &GpuContext,
        samples: &[EnvironmentSample],
        centre: Vec3,
        size: u32,
        footprint: f32,
    ) -> std::result::Result<Built<DistanceImpostor>, String> {
        let start = Instant::now();
        let size = size.max(1);
        let texels = 6 * size as u64 * size as u64;
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        if texels * 16 > limit || samples.len() as u64 * 48 > limit {
            return Err(format!(
                "a 6×{size}² impostor of {} samples needs more than the {:.0} MB the adapter binds",
                samples.len(),
                limit as f64 / 1e6
            ));
        }
        let count = samples.len() as u32;
        let uniform =
            uniform_buffer(ctx, "impostor params", &params(centre, SPLAT_RADIUS * footprint, [count, size, 0, 0]));
        let samples_buffer = sample_buffer(ctx, samples);
        let depth = storage(ctx, "impostor distance", texels * 4);
        let radiance = storage(ctx, "impostor radiance", texels * 16);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        // 0xffffffff: no sample (the bits of a NaN, above every distance's bits)
        ctx.queue.write_buffer(&depth, 0, &vec![0xffu8; texels as usize * 4]);
        encoder.clear_buffer(&radiance, 0, None);
        ctx.queue.submit([encoder.finish()]);
        // both passes run the one splat function, so both bind all four
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: samples_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: depth.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: radiance.as_entire_binding() },
        ];
        ctx.dispatch("impostor distance", &self.impostor_depth, &entries, groups(6 * count));
        ctx.dispatch("impostor radiance", &self.impostor_radiance, &entries, groups(6 * count));
        ctx.wait();
        let gpu_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        let bits: Vec<u32> = bytemuck::cast_slice(&ctx.read_storage(&depth)).to_vec();
        let rgba = ctx.read_f32(&radiance);
        let distance: Vec<f32> =
            bits.iter().map(|&b| if b == u32::MAX { f32::INFINITY } else { f32::from_bits(b) }).collect();
        let radiance: Vec<Vec3> = rgba.chunks_exact(4).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let value = DistanceImpostor::from_maps(centre, size, radiance, distance);
        let gpu_bytes = texels * 20 + samples.len() as u64 * 48;
        Ok(Built { value, gpu_ms, readback_ms: start.elapsed().as_secs_f64() * 1e3, gpu_bytes })
    }

    /// The scene voxel volume of `samples`, `res`³ voxels with mipmaps, as
    /// [`VoxelVolume::build`] makes it; an error in words when a buffer it needs is larger than
    /// the adapter lets a shader bind (256³ voxels need 268 MB; lavapipe binds 134 MB).
    pub fn voxels(
        &self,
        ctx: &GpuContext,
        samples: &[EnvironmentSample],
        res: u32,
        footprint: f32,
    ) -> std::result::Result<Built<VoxelVolume>, String> {
        let start = Instant::now();
        let (origin, voxel, res) = VoxelVolume::frame(samples, res, footprint);
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        // level 0's sums, and every level together (8/7 of level 0)
        let needed = (res as u64).pow(3) * 16 * 8 / 7;
        if needed > limit || samples.len() as u64 * 48 > limit {
            return Err(format!(
                "{res}³ voxels need a {:.0} MB buffer, more than the {:.0} MB the adapter binds",
                needed as f64 / 1e6,
                limit as f64 / 1e6
            ));
        }
        let count = samples.len() as u32;
        let radius = (SPLAT_RADIUS * footprint).max(0.5 * voxel);
        let uniform = uniform_buffer(ctx, "voxel params", &params(origin, radius, [count, res, voxel.to_bits(), 0]));
        let samples_buffer = sample_buffer(ctx, samples);
        let mut sizes = vec![res];
        while let Some(&r) = sizes.last().filter(|&&r| r > 1) {
            sizes.push(r.div_ceil(2));
        }
        let offsets: Vec<u64> = sizes
            .iter()
            .scan(0u64, |at, &r| {
                let here = *at;
                *at += (r as u64).pow(3);
                Some(here)
            })
            .collect();
        let total = offsets.last().copied().unwrap_or(0) + 1;
        let base = (res as u64).pow(3);
        let sums = storage(ctx, "voxel sums", base * 16);
        let levels = storage(ctx, "voxel levels", total * 16);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&sums, 0, None);
        ctx.queue.submit([encoder.finish()]);
        if count > 0 {
            let entries = [
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: samples_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: sums.as_entire_binding() },
            ];
            ctx.dispatch("voxel splat", &self.voxel_splat, &entries, groups(count));
        }
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: sums.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 5, resource: levels.as_entire_binding() },
        ];
        ctx.dispatch("voxel resolve", &self.voxel_resolve, &entries, groups(base as u32));
        for k in 1..sizes.len() {
            let step = [sizes[k - 1], sizes[k], offsets[k - 1] as u32, offsets[k] as u32];
            let mip = uniform_buffer(ctx, "voxel mip", bytemuck::cast_slice(&step));
            let entries = [
                wgpu::BindGroupEntry { binding: 5, resource: levels.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: mip.as_entire_binding() },
            ];
            ctx.dispatch("voxel mip", &self.voxel_mip, &entries, groups(sizes[k].pow(3)));
        }
        ctx.wait();
        let gpu_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        let all = ctx.read_f32(&levels);
        let data: Vec<Vec<[f32; 4]>> = sizes
            .iter()
            .zip(&offsets)
            .map(|(&r, &at)| {
                let from = at as usize * 4;
                all[from..from + (r as usize).pow(3) * 4].chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect()
            })
            .collect();
        let value = VoxelVolume::from_levels(origin, voxel, data);
        let gpu_bytes = base * 16 + total * 16 + samples.len() as u64 * 48;
        Ok(Built { value, gpu_ms, readback_ms: start.elapsed().as_secs_f64() * 1e3, gpu_bytes })
    }
}
