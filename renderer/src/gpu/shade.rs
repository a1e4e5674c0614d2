//! The shading pass (shader: `shade.wgsl`): L_rv and L_r by equations 5.1–5.8 from the
//! G-buffer, the shadow maps and the VPLs. Colour mapping ([`super::cm`]) and composition
//! ([`super::compose`]) read its output.

use super::context::GpuContext;
use super::pool::Contents;
use super::raster::{SceneBuffers, SurfaceTargets};
use super::vpl::GpuVpl;

pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("shade.wgsl"));

/// Matches `Params` in shade.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShadeParams {
    pub camera: [f32; 4],
    pub size: [u32; 4],
    pub mode: [u32; 4],
    pub tone: [f32; 4],
}

/// Matches `Light` in shade.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLight {
    pub view_proj: [[f32; 4]; 4],
    pub position: [f32; 4],
    pub direction: [f32; 4],
    pub intensity: [f32; 4],
    pub info: [f32; 4],
}

pub struct Shade {
    pipeline: wgpu::ComputePipeline,
}

/// What the shading pass writes, still on the GPU.
pub struct ShadeOutput {
    /// L_rv (first width·height texels; w: 0 nothing modelled, 1 real, 2 virtual surface) then
    /// L_r: the direct light (and emission) only.
    pub solutions: std::sync::Arc<wgpu::Buffer>,
    /// The indirect light from the VPLs, I_rv then I_r, as shaded (one interleaved class per
    /// pixel, scaled); `None` without VPLs.
    pub indirect: Option<std::sync::Arc<wgpu::Buffer>>,
}

/// What shading reads besides its parameters: a G-buffer (the camera's or a specular hit
/// G-buffer) lit by the frame's lights and VPLs.
#[derive(Clone, Copy)]
pub struct ShadeInputs<'a> {
    pub gbuffer: &'a SurfaceTargets,
    pub shadow_maps: &'a wgpu::Texture,
    pub lights: &'a [GpuLight],
    /// The VPLs on the host (a stimulus frame's), or already on the GPU (a live frame's, slots
    /// without flux skipped: [`super::bounce_chain`]); `params.size[3]` says how many.
    pub vpls: ShadeVpls<'a>,
    pub scene: &'a SceneBuffers,
    /// The ISM atlas (None: VPLs unshadowed).
    pub ism: Option<&'a wgpu::Buffer>,
}

/// Where the shading pass takes its VPLs from.
#[derive(Clone, Copy)]
pub enum ShadeVpls<'a> {
    Host(&'a [GpuVpl]),
    Gpu(&'a wgpu::Buffer),
}

impl Shade {
    pub fn new(ctx: &GpuContext) -> Self {
        let [pipeline] = ctx.compute_pipelines("shade.wgsl", SHADER, ["cs_shade"]);
        Shade { pipeline }
    }

    /// Shades `inputs.gbuffer` by `params`: L_rv and L_r, and the raw indirect light.
    pub fn run(&self, ctx: &GpuContext, params: &ShadeParams, inputs: &ShadeInputs) -> ShadeOutput {
        let ShadeInputs { gbuffer, shadow_maps, lights, vpls, scene, ism } = *inputs;
        let storage = |label: &str, bytes: &[u8]| {
            ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let zero_light: GpuLight = bytemuck::Zeroable::zeroed();
        let zero_vpl: GpuVpl = bytemuck::Zeroable::zeroed();
        let lights_buffer = storage(
            "lights",
            bytemuck::cast_slice(if lights.is_empty() { std::slice::from_ref(&zero_light) } else { lights }),
        );
        let uploaded;
        let (vpls_buffer, has_vpls) = match vpls {
            ShadeVpls::Host(vpls) => {
                uploaded = storage(
                    "vpls",
                    bytemuck::cast_slice(if vpls.is_empty() { std::slice::from_ref(&zero_vpl) } else { vpls }),
                );
                (&*uploaded, !vpls.is_empty())
            }
            ShadeVpls::Gpu(buffer) => (buffer, params.size[3] > 0),
        };
        let pixels = (params.size[0] * params.size[1]) as u64;
        let output = |label: &str, texels: u64| {
            ctx.buffer(label, texels * 16, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC, Contents::Zeroed)
        };
        let solutions = output("solutions", 2 * pixels);
        let indirect = output("indirect", if has_vpls { 2 * pixels } else { 1 });
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("shade params"),
            contents: bytemuck::bytes_of(params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        // (kept with the pool's textures from frame to frame)
        let view = |t: &std::sync::Arc<wgpu::Texture>| ctx.views.of(t);
        let (gp, gn, ga) = (view(&gbuffer.position), view(&gbuffer.normal), view(&gbuffer.albedo));
        let shadow_view = shadow_maps.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        // without ISMs the shader reads none (tile size 0), but the binding must exist
        let placeholder;
        let ism = match ism {
            Some(buffer) => buffer,
            None => {
                placeholder = storage("no ism", &[0u8; 4]);
                &placeholder
            }
        };
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&gp) },
            wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&gn) },
            wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&ga) },
            wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&shadow_view) },
            wgpu::BindGroupEntry { binding: 5, resource: lights_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 6, resource: vpls_buffer.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 7, resource: scene.materials.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 8, resource: solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 9, resource: ism.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 10, resource: indirect.as_entire_binding() },
        ];
        ctx.dispatch("shade", &self.pipeline, &entries, [params.size[0].div_ceil(8), params.size[1].div_ceil(8)]);
        ShadeOutput { solutions, indirect: has_vpls.then_some(indirect) }
    }
}
