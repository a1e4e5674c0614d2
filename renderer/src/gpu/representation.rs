//! Rohmer et al.'s scene representations built on the GPU (issue 18, Deliver 2; shader:
//! `representation.wgsl`): the distance impostor and the mip-mapped scene voxel volume, splatted
//! from the captured environment samples by compute passes, then read back as plain maps
//! ([`ImpostorMaps`], [`VoxelLevels`]) that `coherent` turns into the CPU reference's types,
//! which the CPU queries read (this module names none of `coherent`'s types: no module cycle).
//!
//! - **Impostor**: two passes over the samples — the nearest distance per texel by `atomicMin` on
//!   the distance's bits (positive floats order as integers), then the radiance of the sample
//!   that won each texel (a tie between two samples at the very same distance keeps either).
//! - **Voxel volume**: radiance summed per voxel in fixed point (1/4096; one sample's radiance
//!   clamped at 16 383 so that 64 in a voxel cannot overflow), resolved to the mean, then one
//!   pass per mip level. The volume's bounds — one reduction over the samples — are taken on
//!   the CPU, as the CPU build takes them.
//!
//! Each splat is the CPU build's (`coherent::impostor::SPLAT_RADIUS`: a disk in the sample's tangent plane, on
//! each cube face the texels its bounding box projects onto); the impostor passes run one
//! invocation per (sample, face). The tests (`coherent::tests`) compare the two texel for texel
//! and voxel for voxel, and on lavapipe they agree exactly for survey-6's two impostors at 64²,
//! 128² and 256² and for the voxel volume. (With one invocation per sample looping over the
//! six faces, lavapipe lost 9 % of the book's impostor at 256², deterministically and at no
//! other size — likely llvmpipe's limit on an invocation's loop iterations, found with the
//! solid volume below.)
//!
//! - **Solid volume** of the virtual objects (`solid.wgsl`): the sweeps of
//!   `coherent::solid::SolidVolume::build` — one dispatch per sample column of a voxel column
//!   (16 along z, 4 along x and y, in the CPU's order), one invocation per voxel column, which
//!   finds its sample column's crossings among the primitives the CPU binned to that voxel
//!   column (a triangle's or sphere's box across the sweep) and adds τ and the crossings' normals
//!   and albedos to the column's own voxels; no atomics, the CPU's order of every sum. (One
//!   invocation walking all 16 sample columns lost most of the glass figure on lavapipe, which
//!   stops an invocation's loops after about 2¹⁴ iterations in all, silently.)
//!   The procedural patterns (wood, checker, stripes) are evaluated at each crossing as
//!   `Texture::eval` does; an image texture is not, and such an object is built on the CPU. τ's
//!   mip levels follow, one pass per level (the CPU's `downsample`); the surface's means are
//!   formed on the CPU from the read-back sums (`SolidVolume::from_sweeps`), as the CPU build
//!   forms them.
//!
//! `coherent::build_representation` builds with these passes when it is given a
//! [`super::DirRenderer`] (studies, `mrstudy render --gi-method`, `bench render --gi-methods`);
//! [`super::DirRenderer::representation_builder`] compiles them on first use.

use super::context::GpuContext;
use crate::capture::hashgrid::EnvironmentSample;
use crate::geometry::{Aabb, Primitive};
use crate::material::Texture;
use glam::{UVec3, Vec3};
use std::time::Instant;

pub const SHADER: &str = include_str!("representation.wgsl");
pub const SOLID_SHADER: &str = include_str!("solid.wgsl");

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

impl<T> Built<T> {
    /// The same build with its value turned into another type (the CPU's).
    pub fn map<U>(self, into: impl FnOnce(T) -> U) -> Built<U> {
        Built { value: into(self.value), gpu_ms: self.gpu_ms, readback_ms: self.readback_ms, gpu_bytes: self.gpu_bytes }
    }
}

/// A distance impostor's maps as the GPU builds them: six faces of `size`² texels side by side,
/// per texel the radiance and the distance from `centre` (infinity where nothing lies).
#[derive(Clone, Debug)]
pub struct ImpostorMaps {
    pub centre: Vec3,
    pub size: u32,
    pub radiance: Vec<Vec3>,
    pub distance: Vec<f32>,
}

/// A scene voxel volume's levels as the GPU builds them: from `origin`, voxels of edge `voxel`,
/// level 0 first, premultiplied RGBA per voxel.
#[derive(Clone, Debug)]
pub struct VoxelLevels {
    pub origin: Vec3,
    pub voxel: f32,
    pub levels: Vec<Vec<[f32; 4]>>,
}

/// The compiled passes.
pub struct RepresentationBuilder {
    impostor_depth: wgpu::ComputePipeline,
    impostor_radiance: wgpu::ComputePipeline,
    voxel_splat: wgpu::ComputePipeline,
    voxel_resolve: wgpu::ComputePipeline,
    voxel_mip: wgpu::ComputePipeline,
    solid_sweep: wgpu::ComputePipeline,
    solid_mip: wgpu::ComputePipeline,
}

/// A surface the solid sweeps cross: a primitive with its diffuse albedo, the procedural
/// pattern that multiplies it (wood, checker, stripes; an image texture is not evaluated on the
/// GPU), and whether it is a mirror or glass.
#[derive(Clone, Debug)]
pub struct SolidPrimitive {
    pub prim: Primitive,
    pub albedo: Vec3,
    pub pattern: Option<Texture>,
    pub delta: bool,
}

/// What the sweeps of one solid volume add up per voxel of level 0 (x fastest): τ, the outward
/// normals' sum with the crossings' count (w), the albedos' sum with 1 where a mirror or glass
/// was crossed (w); and τ's mip levels from level 1 on (made from τ clamped to [0, 1]), empty
/// where the caller makes them.
#[derive(Clone, Debug, PartialEq)]
pub struct SolidSweeps {
    pub tau: Vec<f32>,
    pub normals: Vec<[f32; 4]>,
    pub albedos: Vec<[f32; 4]>,
    pub mips: Vec<Vec<f32>>,
}

/// The voxels per axis of each mip level of a volume of `dims` (level 0 first): half, rounded
/// up, until one voxel is left along every axis.
pub fn mip_dims(dims: UVec3) -> Vec<UVec3> {
    let mut levels = vec![dims];
    while let Some(&d) = levels.last().filter(|d| d.max_element() > 1) {
        levels.push((d + UVec3::ONE) / 2);
    }
    levels
}

/// Sample columns per voxel and axis across a sweep (the shader's `SUB`, the CPU's).
pub const SOLID_SUB: u32 = 4;

/// The most primitives one voxel column of a sweep may meet for the GPU build: each invocation
/// loops over its column's, and llvmpipe stops an invocation's loops after about 2¹⁴ iterations
/// in all (`solid.wgsl`); a finer volume, or the CPU, takes a mesh denser than that.
pub const MAX_COLUMN_PRIMITIVES: usize = 8192;

/// Where a sweep along `axis` starts and ends for the box `bounds` (a hair outside it).
pub fn sweep_span(bounds: &Aabb, axis: usize) -> (f32, f32) {
    let extent = (bounds.max - bounds.min).max(Vec3::splat(1e-6));
    (bounds.min[axis] - 1e-3 * extent[axis] - 1e-4, bounds.max[axis] + 1e-3 * extent[axis] + 1e-4)
}

/// The primitives `prims` binned to the voxel columns of a sweep along `axis` (columns
/// `dims[u] × dims[v]`, u = axis + 1, v = axis + 2, u fastest) by their box across the sweep:
/// CSR offsets and indices.
fn bin_columns(prims: &[SolidPrimitive], origin: Vec3, voxel: Vec3, dims: UVec3, axis: usize) -> (Vec<u32>, Vec<u32>) {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let (nu, nv) = (dims[u] as usize, dims[v] as usize);
    let range = |lo: f32, hi: f32, k: usize, n: usize| -> Option<(usize, usize)> {
        // a sample column on the box's edge still meets the primitive: pad by a hair
        let pad = 1e-4 * voxel[k];
        let a = ((lo - pad - origin[k]) / voxel[k]).floor();
        let b = ((hi + pad - origin[k]) / voxel[k]).floor();
        if !(b >= 0.0 && a < n as f32) {
            return None;
        }
        Some((a.max(0.0) as usize, (b as usize).min(n - 1)))
    };
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); nu * nv];
    for (index, p) in prims.iter().enumerate() {
        let (lo, hi) = match &p.prim {
            Primitive::Triangle(t) => (t.p[0].min(t.p[1]).min(t.p[2]), t.p[0].max(t.p[1]).max(t.p[2])),
            &Primitive::Sphere { center, radius } => (center - Vec3::splat(radius), center + Vec3::splat(radius)),
        };
        let (Some((u0, u1)), Some((v0, v1))) = (range(lo[u], hi[u], u, nu), range(lo[v], hi[v], v, nv)) else {
            continue;
        };
        for cv in v0..=v1 {
            for cu in u0..=u1 {
                lists[cu + nu * cv].push(index as u32);
            }
        }
    }
    let mut offsets = Vec::with_capacity(lists.len() + 1);
    let mut indices = Vec::new();
    offsets.push(0);
    for list in lists {
        indices.extend(list);
        offsets.push(indices.len() as u32);
    }
    (offsets, indices)
}

/// Where each of consecutive blocks of `counts` elements starts in one buffer, and the total:
/// the mip levels of a volume laid one after the other.
fn level_offsets(counts: impl Iterator<Item = u64>) -> (Vec<u64>, u64) {
    let mut total = 0;
    let offsets = counts
        .map(|count| {
            let here = total;
            total += count;
            here
        })
        .collect();
    (offsets, total)
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
    ctx.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("environment samples"),
        contents: bytemuck::cast_slice(&data),
        usage: wgpu::BufferUsages::STORAGE,
    })
}

fn uniform_buffer(ctx: &GpuContext, label: &str, data: &[u8]) -> wgpu::Buffer {
    ctx.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: data,
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

fn storage(ctx: &GpuContext, label: &str, bytes: u64) -> wgpu::Buffer {
    ctx.create_buffer(&wgpu::BufferDescriptor {
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

/// Why the GPU does not build a representation (the CPU builds it instead), with the sizes;
/// each displays as one sentence.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BuildRefused {
    #[error(
        "a {}×{}×{} solid volume of {primitives} primitives needs more than the {limit_mb:.0} MB the adapter binds",
        .dims.x, .dims.y, .dims.z
    )]
    SolidTooLarge { dims: UVec3, primitives: usize, limit_mb: f64 },
    #[error("an image texture on a virtual object, which the GPU's sweeps do not evaluate")]
    ImageTexture,
    #[error(
        "a voxel column meets {primitives} primitives, more than the {MAX_COLUMN_PRIMITIVES} one GPU invocation walks"
    )]
    CrowdedColumn { primitives: usize },
    #[error("a 6×{size}² impostor of {samples} samples needs more than the {limit_mb:.0} MB the adapter binds")]
    ImpostorTooLarge { size: u32, samples: usize, limit_mb: f64 },
    #[error("{res}³ voxels need a {needed_mb:.0} MB buffer, more than the {limit_mb:.0} MB the adapter binds")]
    VoxelsTooLarge { res: u32, needed_mb: f64, limit_mb: f64 },
}

impl RepresentationBuilder {
    pub fn new(ctx: &GpuContext) -> Self {
        let [impostor_depth, impostor_radiance, voxel_splat, voxel_resolve, voxel_mip] = ctx.compute_pipelines(
            "representation.wgsl",
            SHADER,
            ["cs_impostor_depth", "cs_impostor_radiance", "cs_voxel_splat", "cs_voxel_resolve", "cs_voxel_mip"],
        );
        let [solid_sweep, solid_mip] =
            ctx.compute_pipelines("solid.wgsl", SOLID_SHADER, ["cs_solid_sweep", "cs_solid_mip"]);
        RepresentationBuilder {
            impostor_depth,
            impostor_radiance,
            voxel_splat,
            voxel_resolve,
            voxel_mip,
            solid_sweep,
            solid_mip,
        }
    }

    /// The sweeps of a solid volume of `prims` over `bounds`, `dims` voxels of edges `voxel`
    /// from `bounds.min`, as `coherent::solid::SolidVolume::build` makes them: τ from the z
    /// sweep with its mip levels, the surface's sums from all three. An image texture, or a
    /// voxel column meeting more than [`MAX_COLUMN_PRIMITIVES`], is refused in words.
    pub fn solid_sweeps(
        &self,
        ctx: &GpuContext,
        prims: &[SolidPrimitive],
        bounds: Aabb,
        voxel: Vec3,
        dims: UVec3,
    ) -> std::result::Result<Built<SolidSweeps>, BuildRefused> {
        let start = Instant::now();
        let count = dims.x as u64 * dims.y as u64 * dims.z as u64;
        let levels = mip_dims(dims);
        let (level_offsets, total) = level_offsets(levels.iter().map(|d| d.x as u64 * d.y as u64 * d.z as u64));
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        if count * 16 > limit || total * 4 > limit || prims.len() as u64 * 128 > limit {
            return Err(BuildRefused::SolidTooLarge { dims, primitives: prims.len(), limit_mb: limit as f64 / 1e6 });
        }
        let mut data: Vec<[f32; 4]> = Vec::with_capacity(8 * prims.len().max(1));
        for p in prims {
            let uv = match &p.prim {
                Primitive::Triangle(t) => {
                    data.extend(t.p.map(|v| v.extend(0.0).to_array()));
                    t.uv
                }
                &Primitive::Sphere { center, radius } => {
                    data.extend([center.extend(radius).to_array(), [0.0, 0.0, 0.0, 1.0], [0.0; 4]]);
                    [glam::Vec2::ZERO; 3]
                }
            };
            data.push(p.albedo.extend(if p.delta { 1.0 } else { 0.0 }).to_array());
            let (kind, scale, a, b) = match &p.pattern {
                None => (0.0, 0.0, Vec3::ZERO, Vec3::ZERO),
                Some(Texture::Wood { light, dark, rings }) => (1.0, *rings, *light, *dark),
                Some(Texture::Checker { a, b, squares }) => (2.0, *squares, *a, *b),
                Some(Texture::Stripes { a, b, count }) => (3.0, *count, *a, *b),
                Some(Texture::Image(_)) => {
                    return Err(BuildRefused::ImageTexture);
                }
            };
            data.push([uv[0].x, uv[0].y, uv[1].x, uv[1].y]);
            data.push([uv[2].x, uv[2].y, kind, scale]);
            data.push(a.extend(0.0).to_array());
            data.push(b.extend(0.0).to_array());
        }
        if data.is_empty() {
            data.resize(8, [0.0; 4]);
        }
        let prim_buffer = ctx.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("solid primitives"),
            contents: bytemuck::cast_slice(&data),
            usage: wgpu::BufferUsages::STORAGE,
        });
        // τ of every level, one after the other
        let tau = storage(ctx, "solid tau", total * 4);
        let normals = storage(ctx, "solid normals", count * 16);
        let albedos = storage(ctx, "solid albedos", count * 16);
        let mut encoder = ctx.encoder();
        for buffer in [&tau, &normals, &albedos] {
            encoder.clear_buffer(buffer, 0, None);
        }
        ctx.submit(encoder);
        let origin = bounds.min;
        let mut gpu_bytes = total * 4 + count * 32 + data.len() as u64 * 16;
        for axis in 0..3 {
            let (offsets, indices) = bin_columns(prims, origin, voxel, dims, axis);
            if let Some(most) = offsets.windows(2).map(|w| (w[1] - w[0]) as usize).max()
                && most > MAX_COLUMN_PRIMITIVES
            {
                return Err(BuildRefused::CrowdedColumn { primitives: most });
            }
            gpu_bytes += 4 * (offsets.len() + indices.len()) as u64;
            let list = |label: &str, values: &[u32]| {
                let values = if values.is_empty() { &[0u32][..] } else { values };
                ctx.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(values),
                    usage: wgpu::BufferUsages::STORAGE,
                })
            };
            let (offsets_buffer, indices_buffer) = (list("solid offsets", &offsets), list("solid indices", &indices));
            let (from, to) = sweep_span(&bounds, axis);
            let columns = offsets.len() as u32 - 1;
            // one dispatch per sample column of a voxel column, in the CPU's order: τ needs the z
            // sweep's every one, the normals of the other two every other one
            let stride = if axis == 2 { 1 } else { 2 };
            for jj in (0..SOLID_SUB).step_by(stride) {
                for ii in (0..SOLID_SUB).step_by(stride) {
                    let mut uniform: Vec<u8> = bytemuck::cast_slice(&origin.extend(axis as f32).to_array()).to_vec();
                    uniform.extend_from_slice(bytemuck::cast_slice(&voxel.extend(0.0).to_array()));
                    uniform.extend_from_slice(bytemuck::cast_slice(&[dims.x, dims.y, dims.z, 0]));
                    uniform.extend_from_slice(bytemuck::cast_slice(&[from, to, bounds.max.z, 0.0]));
                    uniform.extend_from_slice(bytemuck::cast_slice(&[ii, jj, 0, 0]));
                    let uniform = uniform_buffer(ctx, "solid params", &uniform);
                    let entries = [
                        wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 1, resource: prim_buffer.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 2, resource: offsets_buffer.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 3, resource: indices_buffer.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 4, resource: tau.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 5, resource: normals.as_entire_binding() },
                        wgpu::BindGroupEntry { binding: 6, resource: albedos.as_entire_binding() },
                    ];
                    ctx.dispatch("solid sweep", &self.solid_sweep, &entries, groups(columns));
                }
            }
        }
        // (the mip passes start after the sweeps are done: queued behind them, lavapipe often took
        // 0.8 s more for a volume of 16 voxels — not understood — and on a GPU it costs one wait)
        ctx.wait();
        for k in 1..levels.len() {
            let (fine, coarse) = (levels[k - 1], levels[k]);
            let step = [
                fine.x,
                fine.y,
                fine.z,
                level_offsets[k - 1] as u32,
                coarse.x,
                coarse.y,
                coarse.z,
                level_offsets[k] as u32,
            ];
            let uniform = uniform_buffer(ctx, "solid mip", bytemuck::cast_slice(&step));
            let entries = [
                wgpu::BindGroupEntry { binding: 4, resource: tau.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: uniform.as_entire_binding() },
            ];
            ctx.dispatch("solid mip", &self.solid_mip, &entries, groups(coarse.x * coarse.y * coarse.z));
        }
        ctx.wait();
        let gpu_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        let quads = |values: Vec<f32>| values.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect::<Vec<_>>();
        let all = ctx.read_f32(&tau);
        let level = |k: usize| {
            let d = levels[k];
            let from = level_offsets[k] as usize;
            all[from..from + (d.x * d.y * d.z) as usize].to_vec()
        };
        let value = SolidSweeps {
            tau: level(0),
            normals: quads(ctx.read_f32(&normals))[..count as usize].to_vec(),
            albedos: quads(ctx.read_f32(&albedos))[..count as usize].to_vec(),
            mips: (1..levels.len()).map(level).collect(),
        };
        Ok(Built { value, gpu_ms, readback_ms: start.elapsed().as_secs_f64() * 1e3, gpu_bytes })
    }

    /// The distance impostor of `samples` at `centre`, `size`² texels per face, each sample a
    /// disk of `splat_radius`, as [`crate::coherent::impostor::DistanceImpostor::build`] makes it.
    pub fn impostor(
        &self,
        ctx: &GpuContext,
        samples: &[EnvironmentSample],
        centre: Vec3,
        size: u32,
        splat_radius: f32,
    ) -> std::result::Result<Built<ImpostorMaps>, BuildRefused> {
        let start = Instant::now();
        let size = size.max(1);
        let texels = 6 * size as u64 * size as u64;
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        if texels * 16 > limit || samples.len() as u64 * 48 > limit {
            return Err(BuildRefused::ImpostorTooLarge { size, samples: samples.len(), limit_mb: limit as f64 / 1e6 });
        }
        let count = samples.len() as u32;
        let uniform = uniform_buffer(ctx, "impostor params", &params(centre, splat_radius, [count, size, 0, 0]));
        let samples_buffer = sample_buffer(ctx, samples);
        let depth = storage(ctx, "impostor distance", texels * 4);
        let radiance = storage(ctx, "impostor radiance", texels * 16);
        // 0xffffffff: no sample (the bits of a NaN, above every distance's bits)
        ctx.write_buffer(&depth, 0, &vec![0xffu8; texels as usize * 4]);
        let mut encoder = ctx.encoder();
        encoder.clear_buffer(&radiance, 0, None);
        ctx.submit(encoder);
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
        let value = ImpostorMaps { centre, size, radiance, distance };
        let gpu_bytes = texels * 20 + samples.len() as u64 * 48;
        Ok(Built { value, gpu_ms, readback_ms: start.elapsed().as_secs_f64() * 1e3, gpu_bytes })
    }

    /// The scene voxel volume of `samples` in `frame` (origin, voxel edge, `res`³ voxels) with
    /// mipmaps, each sample a disk of `splat_radius` (at least half a voxel), as
    /// [`crate::coherent::voxel::VoxelVolume::build`] makes it; an error in words when a buffer it
    /// needs is larger than the adapter lets a shader bind (256³ voxels need 268 MB; lavapipe
    /// binds 134 MB).
    pub fn voxels(
        &self,
        ctx: &GpuContext,
        samples: &[EnvironmentSample],
        frame: (Vec3, f32, u32),
        splat_radius: f32,
    ) -> std::result::Result<Built<VoxelLevels>, BuildRefused> {
        let start = Instant::now();
        let (origin, voxel, res) = frame;
        let limit = ctx.device.limits().max_storage_buffer_binding_size;
        // level 0's sums, and every level together (8/7 of level 0)
        let needed = (res as u64).pow(3) * 16 * 8 / 7;
        if needed > limit || samples.len() as u64 * 48 > limit {
            return Err(BuildRefused::VoxelsTooLarge {
                res,
                needed_mb: needed as f64 / 1e6,
                limit_mb: limit as f64 / 1e6,
            });
        }
        let count = samples.len() as u32;
        let radius = splat_radius.max(0.5 * voxel);
        let uniform = uniform_buffer(ctx, "voxel params", &params(origin, radius, [count, res, voxel.to_bits(), 0]));
        let samples_buffer = sample_buffer(ctx, samples);
        let mut sizes = vec![res];
        while let Some(&r) = sizes.last().filter(|&&r| r > 1) {
            sizes.push(r.div_ceil(2));
        }
        let (offsets, total) = level_offsets(sizes.iter().map(|&r| (r as u64).pow(3)));
        let base = (res as u64).pow(3);
        let sums = storage(ctx, "voxel sums", base * 16);
        let levels = storage(ctx, "voxel levels", total * 16);
        let mut encoder = ctx.encoder();
        encoder.clear_buffer(&sums, 0, None);
        ctx.submit(encoder);
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
        let value = VoxelLevels { origin, voxel, levels: data };
        let gpu_bytes = base * 16 + total * 16 + samples.len() as u64 * 48;
        Ok(Built { value, gpu_ms, readback_ms: start.elapsed().as_secs_f64() * 1e3, gpu_bytes })
    }
}
