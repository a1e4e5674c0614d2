//! The ca pass on the GPU (shader: `ca.wgsl`): Klein and Murray's camera chain applied to
//! a frame's virtual layers, as compute passes — layers, distortion with chromatic aberration,
//! defocus disc, noise at the Bayer sites, demosaicing, sharpening, composition, JPEG-style
//! compression. The arithmetic and its order are those of the CPU reference
//! [`crate::ca::apply_cpu`] (see [`crate::ca`] for what is processed and why), so both agree to
//! 1e-3 (tested on lavapipe). Input non-finite values are replaced on the CPU before upload and
//! counted in the report.

use super::context::GpuContext;
use crate::ca::{self, CaParams, CaReport, NOISE_LUT};
use crate::camera::Camera;
use crate::error::{RenderError, Result};
use crate::image::{Image, Mask};
use glam::Vec3;

pub const SHADER: &str = include_str!("ca.wgsl");

/// Matches `Params` in ca.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct ArtifactParams {
    size: [u32; 4],
    counts: [u32; 4],
    intr: [f32; 4],
    k: [f32; 4],
    k2: [f32; 4],
    noise: [[f32; 4]; 5],
}

const STAGES: [&str; 8] =
    ["cs_layers", "cs_warp", "cs_blur", "cs_noise", "cs_demosaic", "cs_sharpen", "cs_compose", "cs_jpeg"];

/// The compiled stages of the ca pass.
pub struct Artifacts {
    layout: wgpu::BindGroupLayout,
    pipelines: Vec<wgpu::ComputePipeline>,
}

impl Artifacts {
    pub fn new(ctx: &GpuContext) -> Artifacts {
        let device = &ctx.device;
        let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("artifacts"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1, true),
                storage(2, true),
                storage(3, true),
                storage(4, false),
                storage(5, true),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("artifacts"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("ca.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let pipelines = STAGES
            .iter()
            .map(|entry| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
            .collect();
        Artifacts { layout, pipelines }
    }

    /// Runs the chain on the GPU: the frame's `composite` over `photo` with virtual coverage
    /// `mask` → the composite with camera artifacts, and the report.
    pub fn run(
        &self,
        ctx: &GpuContext,
        composite: &Image,
        photo: &Image,
        mask: &Mask,
        camera: &Camera,
        p: &CaParams,
    ) -> Result<(Image, CaReport)> {
        let (w, h) = (composite.width, composite.height);
        let (comp, photo, mask, invalid_inputs) = ca::checked_inputs(composite, photo, mask, p)?;
        let n = (w * h) as u64;
        let device = &ctx.device;
        let limit = device.limits().max_storage_buffer_binding_size;
        if 3 * n * 16 > limit {
            return Err(RenderError::Unsupported(format!(
                "the ca pass needs {} MiB storage buffers for {w}x{h} and this adapter allows {} MiB; render smaller or use the CPU reference (ca::apply_cpu)",
                (3 * n * 16) >> 20,
                limit >> 20
            )));
        }

        let taps = p.blur_taps();
        let mut noise = [[0.0f32; 4]; 5];
        for k in 0..NOISE_LUT {
            noise[k / 4][k % 4] = p.noise_variance[k];
        }
        let params = ArtifactParams {
            size: [w, h, p.seed, if p.bayer { 1 } else { 0 }],
            counts: [taps.len() as u32, 0, 0, 0],
            intr: [camera.fx, camera.fy, camera.cx, camera.cy],
            k: [p.distortion[0], p.distortion[1], p.distortion[2], p.distortion[3]],
            k2: [
                p.distortion[4],
                p.chromatic_aberration,
                crate::sensor::distortion_zoom(camera, p.distortion, p.chromatic_aberration),
                p.sharpen,
            ],
            noise,
        };
        let mut tables: Vec<f32> = ca::jpeg::dct_basis().to_vec();
        let quality = p.jpeg_quality.unwrap_or(100);
        tables.extend(ca::jpeg::scaled_table(&ca::jpeg::STD_LUMA, quality));
        tables.extend(ca::jpeg::scaled_table(&ca::jpeg::STD_CHROMA, quality));
        for &(dx, dy, wt) in &taps {
            tables.extend([dx as f32, dy as f32, wt]);
        }

        let texels = |img: &Image, alpha: Option<&[f32]>| -> Vec<[f32; 4]> {
            img.pixels.iter().enumerate().map(|(i, q)| [q.x, q.y, q.z, alpha.map_or(0.0, |a| a[i])]).collect()
        };
        let init = |label: &str, bytes: &[u8]| {
            ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("artifact params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let comp_buf = init("ca composite", bytemuck::cast_slice(&texels(&comp, None)));
        let photo_buf = init("ca photo", bytemuck::cast_slice(&texels(&photo, Some(&mask.values))));
        let tables_buf = init("ca tables", bytemuck::cast_slice(&tables));
        let dummy = init("ca dummy", &[0u8; 16]);
        let scratch = |label: &str, images: u64| {
            ctx.buffer(
                label,
                images * n * 16,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                super::pool::Contents::Zeroed,
            )
        };
        let (la, lb) = (scratch("ca layers a", 3), scratch("ca layers b", 3));
        let (pa, pb) = (scratch("ca images a", 2), scratch("ca images b", 2));
        let (oa, ob) = (scratch("ca out a", 1), scratch("ca out b", 1));

        let mut encoder = ctx.encoder();
        let (gx, gy) = (w.div_ceil(8), h.div_ceil(8));
        let mut stage = |k: usize, src: &wgpu::Buffer, aux2: &wgpu::Buffer, dst: &wgpu::Buffer, groups: (u32, u32)| {
            let bind_group = ctx.bind_group(&wgpu::BindGroupDescriptor {
                label: Some(STAGES[k]),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: src.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: photo_buf.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: aux2.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: dst.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 5, resource: tables_buf.as_entire_binding() },
                ],
            });
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(STAGES[k]), timestamp_writes: None });
            pass.set_pipeline(&self.pipelines[k]);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        };
        stage(0, &comp_buf, &dummy, &la, (gx, gy));
        let mut layers = (&la, &lb);
        if p.warps() {
            stage(1, layers.0, &dummy, layers.1, (gx, gy));
            layers = (layers.1, layers.0);
        }
        if !taps.is_empty() {
            stage(2, layers.0, &dummy, layers.1, (gx, gy));
            layers = (layers.1, layers.0);
        }
        let layers = layers.0;
        stage(3, layers, &dummy, &pa, (gx, gy));
        let mut images = (&pa, &pb);
        if p.bayer {
            stage(4, images.0, &dummy, images.1, (gx, gy));
            images = (images.1, images.0);
        }
        if p.sharpen > 0.0 {
            stage(5, images.0, &dummy, images.1, (gx, gy));
            images = (images.1, images.0);
        }
        stage(6, images.0, layers, &oa, (gx, gy));
        let mut out = &oa;
        if p.jpeg_quality.is_some() {
            stage(7, &oa, layers, &ob, (w.div_ceil(8).div_ceil(8), h.div_ceil(8).div_ceil(8)));
            out = &ob;
        }
        ctx.submit(encoder);
        let data = ctx.read_f32(out);
        let pixels: Vec<Vec3> = data.chunks_exact(4).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let processed = (0..n as usize).filter(|&i| pixels[i] != photo.pixels[i] || mask.values[i] > 0.0).count();
        Ok((
            Image { width: w, height: h, pixels },
            CaReport { invalid_inputs, processed_fraction: processed as f32 / n.max(1) as f32 },
        ))
    }
}
