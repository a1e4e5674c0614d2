//! The composition pass (shader: `compose.wgsl`): the colour-mapped differential added to the
//! photograph — additively (thesis 4.17) or scaled by α = L'_cam/τ(L_r) (Debevec; thesis
//! 5.16–5.17) — in display values, or in the camera's gamma-2.2 linear space when the mapping
//! is Rohmer's C⁻¹. Mirrors [`crate::cm::compose`].

use super::context::GpuContext;
use crate::cm::Composition;

pub const SHADER: &str = include_str!("compose.wgsl");

pub struct Compose {
    pipeline: wgpu::ComputePipeline,
    pack: wgpu::ComputePipeline,
}

/// What the composition reads: the mapped buffers over the photograph (and CI_std where mirrors
/// and glass are), at `width`×`height`, in the linear domain where the mapping says so.
#[derive(Clone, Copy)]
pub struct ComposeInputs<'a> {
    pub width: u32,
    pub height: u32,
    pub linear_domain: bool,
    pub composition: Composition,
    pub mapped: &'a wgpu::Buffer,
    pub photo: &'a wgpu::Buffer,
    pub specular_base: Option<&'a wgpu::Buffer>,
}

impl Compose {
    pub fn new(ctx: &GpuContext) -> Self {
        let [pipeline, pack] = ctx.compute_pipelines("compose.wgsl", SHADER, ["cs_compose", "cs_pack"]);
        Compose { pipeline, pack }
    }

    /// Composes `mapped` (τ(L_rv) with the flag in w, then τ(L_r)) over `photo`; returns the
    /// composite buffer (one vec4 per pixel, display-encoded). `specular_base` (from
    /// [`super::specular`]) replaces the photograph at the pixels of mirrors and glass by
    /// CI_std (eq. 5.23), over which the differential is added as at a real pixel (5.22).
    pub fn run(&self, ctx: &GpuContext, inputs: &ComposeInputs) -> std::sync::Arc<wgpu::Buffer> {
        let ComposeInputs { width, height, linear_domain, composition, mapped, photo, specular_base } = *inputs;
        let size = [width, height, linear_domain as u32, (composition == Composition::Scaled) as u32];
        let options = [specular_base.is_some() as u32, 0, 0, 0];
        let placeholder;
        let specular_base = match specular_base {
            Some(buffer) => buffer,
            None => {
                // from the pool (a new buffer each frame would be an allocation each frame)
                placeholder = ctx.upload(&wgpu::util::BufferInitDescriptor {
                    label: Some("no specular base"),
                    contents: &[0u8; 16],
                    usage: wgpu::BufferUsages::STORAGE,
                });
                &placeholder
            }
        };
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("compose params"),
            contents: bytemuck::cast_slice(&[size, options]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let composite = ctx.buffer(
            "composite",
            width as u64 * height as u64 * 16,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            super::pool::Contents::Zeroed,
        );
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: mapped.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: photo.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: composite.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: specular_base.as_entire_binding() },
        ];
        ctx.dispatch("compose", &self.pipeline, &entries, [width.div_ceil(8), height.div_ceil(8)]);
        composite
    }

    /// The composite (`width`×`height` vec4s) packed to 8-bit RGBA, one `u32` a pixel, each
    /// channel rounded as [`crate::image::Image::to_rgb8`] rounds: what a frame that is only
    /// shown reads back.
    pub fn pack(
        &self,
        ctx: &GpuContext,
        composite: &wgpu::Buffer,
        width: u32,
        height: u32,
    ) -> std::sync::Arc<wgpu::Buffer> {
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("pack params"),
            contents: bytemuck::cast_slice(&[[width, height, 0, 0], [0; 4]]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        // from the pool: the pass writes every pixel
        let packed = ctx.buffer(
            "composite rgba8",
            width as u64 * height as u64 * 4,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            super::pool::Contents::Overwritten,
        );
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: composite.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 5, resource: packed.as_entire_binding() },
        ];
        ctx.dispatch("pack rgba8", &self.pack, &entries, [width.div_ceil(8), height.div_ceil(8)]);
        packed
    }
}
