//! Mirrors and glass in differential instant radiosity (thesis 5.3, eqs. 5.18–5.26; shader:
//! `specular.wgsl`). Runs only in a scene with a mirror or glass object (the mesh's
//! [`SpecularObject`]s); the frame report lists its passes:
//!
//! 1. **impostors**: per mirror or glass object, a distance impostor of the scene around it
//!    (Szirmay-Kalos et al. 2005; a one-layer cube map from the object's centre holding the
//!    G-buffer of every other surface, real and virtual) — this stands in for Popescu et al.'s
//!    per-object billboards: the hit point is refined the same way (a search along the ray in
//!    the stored distances, then secant steps), but a surface hidden from the centre behind
//!    another is missing;
//! 2. **back faces** (glass only): the camera's G-buffer of the farthest surfaces of the glass
//!    objects, for two-sided refraction (Wyman 2005, with the distance d_V along the view ray);
//! 3. **ray search**: per camera pixel on a mirror or glass, the reflected and refracted rays
//!    through the impostor into the G-buffers GBuf_refl and GBuf_refr (the hit surfaces at the
//!    camera's pixels), with the Fresnel factors η₁, η₂ and the transmittance T_c; rays that
//!    leave the modelled scene take the environment's radiance (L_env);
//! 4. **shading** of GBuf_refl and GBuf_refr by the same pass as the camera's G-buffer (every
//!    light and VPL, eqs. 5.1–5.8, so 5.20's real(ls, p) holds: L_r has only real lights on
//!    real surfaces);
//! 5. **combination**: L'_rv and L'_r (5.18, 5.19) into the camera's solutions, and the
//!    camera-image base CI_std (5.23–5.25) by back-projection of each hit into the photograph,
//!    valid where the camera sees that same real surface; [`super::compose`] adds α'ΔL'
//!    (5.21, 5.22, 5.26) to it.
//!
//! One deviation from 5.24, stated: a component (reflected or refracted) is taken from the
//! photograph where its own back-projection is valid, and then also enters L'_r, so that
//! ΔL' keeps only the change the virtual objects make to it; the other component is then
//! rendered. The thesis decides for both together (and takes L'_r for both where either is
//! invalid), with an exception for a virtual glass object whose refraction alone is valid —
//! the per-component rule contains that exception and equals the thesis where both or neither
//! are valid.
//!
//! Not built (yet): caustic maps (5.27–5.29) and reflected or refracted VPLs (Figure 5.23): a
//! glass object's shadow is dark where the ground truth has its caustic; interreflections
//! between mirrors and glass (one specular bounce, as the thesis); VPLs on mirrors or glass
//! (they have no diffuse albedo and make none).

use super::context::GpuContext;
use super::mesh::{GpuMesh, SpecularObject};
use super::raster::{GbufferDraw, Raster, SceneBuffers, SurfaceTargets, ViewUniform};
use crate::material::DeltaBsdf;
use crate::scene::Scene;
use glam::{Mat4, Vec3};
use serde::Serialize;
use wgpu::util::DeviceExt;

pub const SHADER: &str = include_str!("specular.wgsl");

/// The knobs of the specular passes.
#[derive(Clone, Debug, Serialize)]
pub struct SpecularParams {
    /// Resolution of each face of an object's impostor cube map (the thesis: 512² impostor
    /// textures).
    pub impostor_size: u32,
    /// Linear search steps along a reflected or refracted ray through the impostor.
    pub search_steps: u32,
    /// Secant refinement steps once the search has bracketed a hit.
    pub secant_steps: u32,
}

impl Default for SpecularParams {
    fn default() -> Self {
        SpecularParams { impostor_size: 256, search_steps: 48, secant_steps: 6 }
    }
}

/// What the specular passes did in a frame.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SpecularReport {
    /// The mirrors and glass objects, each with its impostor.
    pub objects: Vec<String>,
    pub impostor_size: u32,
    /// Camera pixels on a mirror or glass.
    pub pixels: u32,
    /// Reflected and refracted rays with a weight (a mirror has one, glass two).
    pub rays: u32,
    /// Rays whose hit was taken from the photograph (back-projected and valid).
    pub back_projected: u32,
    /// Rays whose hit was rendered (a virtual surface, or a real one the camera does not see).
    pub rendered: u32,
    /// Rays that left the modelled scene (the environment's radiance).
    pub missed: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    view_proj: [[f32; 4]; 4],
    camera: [f32; 4],
    size: [u32; 4],
    search: [u32; 4],
    env: [f32; 4],
    scene: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuSpecularObject {
    centre_radius: [f32; 4],
    kind: [f32; 4],
    colour: [f32; 4],
}

/// The compiled passes.
pub struct Specular {
    trace: wgpu::ComputePipeline,
    combine: wgpu::ComputePipeline,
}

/// The traced rays of a frame, waiting for their G-buffers to be shaded.
pub struct Traced {
    /// GBuf_refl and GBuf_refr, in the camera's pixels.
    pub refl: SurfaceTargets,
    pub refr: SurfaceTargets,
    params: wgpu::Buffer,
    hits: wgpu::Buffer,
    info: wgpu::Buffer,
    pub report: SpecularReport,
    /// Where shading of the hit G-buffers looks from (Blinn–Phong's view direction): the
    /// first specular object's centre.
    pub eye: Vec3,
}

/// The forward axis of cube face `f` (+x, −x, +y, −y, +z, −z), as `specular.wgsl` reads it.
fn face_forward(f: u32) -> Vec3 {
    let mut forward = Vec3::ZERO;
    forward[(f / 2) as usize] = if f % 2 == 1 { -1.0 } else { 1.0 };
    forward
}

fn row_stride(width: u32) -> u32 {
    // copy_buffer_to_texture needs rows of a multiple of 256 bytes (16 texels of 16 bytes)
    width.div_ceil(16) * 16
}

impl Specular {
    pub fn new(ctx: &GpuContext) -> Self {
        let [trace, combine] = ctx.compute_pipelines("specular.wgsl", SHADER, ["cs_trace", "cs_combine"]);
        Specular { trace, combine }
    }

    /// Impostors, back faces and the ray search (steps 1–3); `passes` gets one entry each.
    #[allow(clippy::too_many_arguments)]
    pub fn trace(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        passes: &mut Vec<super::PassTime>,
        scene: &Scene,
        mesh: &GpuMesh,
        buffers: &SceneBuffers,
        gbuffer: &SurfaceTargets,
        camera_view: &ViewUniform,
        camera_view_proj: Mat4,
        params: &SpecularParams,
    ) -> Traced {
        let device = &ctx.device;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let objects = &mesh.specular;
        let max_dimension = device.limits().max_texture_dimension_2d;
        let size = params.impostor_size.clamp(8, max_dimension / 6).min(max_dimension / objects.len().max(1) as u32);
        // 1. impostors: six faces side by side per object, one object per row
        let impostors = SurfaceTargets::new(ctx, 6 * size, size * objects.len() as u32, "impostors");
        let total = mesh.vertices.len() as u32;
        let far = 2.0 * mesh.bounds_radius
            + objects.iter().map(|o| (o.centre - mesh.bounds_centre).length()).fold(0.0, f32::max);
        let near = (far * 1e-5).max(1e-5);
        let projection = Mat4::from_cols_array_2d(&[
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, far / (near - far), near * far / (near - far)],
            [0.0, 0.0, -1.0, 0.0],
        ])
        .transpose();
        let others: Vec<[std::ops::Range<u32>; 2]> =
            objects.iter().map(|o| [0..o.range.start, o.range.end..total]).collect();
        let mut draws = Vec::new();
        for (k, object) in objects.iter().enumerate() {
            for f in 0..6 {
                let forward = face_forward(f);
                let matrix = projection * super::look_at(object.centre, forward, super::up_hint(forward));
                draws.push(GbufferDraw {
                    view: ViewUniform::perspective(matrix, object.centre, forward),
                    viewport: [f * size, k as u32 * size, size, size],
                    ranges: &others[k],
                });
            }
        }
        let names: Vec<&str> = objects.iter().map(|o| o.name.as_str()).collect();
        super::timed(ctx, passes, format!("impostors ({}, 6 × {size}² each)", names.join(", ")), || {
            raster.gbuffer_draws(ctx, buffers, &impostors, &draws, false)
        });
        // 2. the back faces of the glass objects
        let glass: Vec<std::ops::Range<u32>> = objects
            .iter()
            .filter(|o| matches!(o.delta, DeltaBsdf::Dielectric { .. }))
            .map(|o| o.range.clone())
            .collect();
        // without glass the shader reads no back face, but the binding must exist
        let back = if glass.is_empty() {
            SurfaceTargets::new(ctx, 1, 1, "no back faces")
        } else {
            SurfaceTargets::new(ctx, width, height, "back faces")
        };
        if !glass.is_empty() {
            let draw = GbufferDraw { view: *camera_view, viewport: [0, 0, width, height], ranges: &glass };
            super::timed(ctx, passes, "back faces of glass".into(), || {
                raster.gbuffer_draws(ctx, buffers, &back, std::slice::from_ref(&draw), true)
            });
        }
        // 3. the ray search
        let (env_map, env_size, rotation) = match &scene.environment {
            Some(env) => (
                env.map.pixels.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect::<Vec<[f32; 4]>>(),
                [env.map.width, env.map.height],
                env.rotation,
            ),
            None => (vec![[0.0; 4]], [1, 1], 0.0),
        };
        let stride = row_stride(width);
        let uniform = Params {
            view_proj: camera_view_proj.to_cols_array_2d(),
            camera: scene.camera.position.extend(0.0).to_array(),
            size: [width, height, size, stride],
            search: [params.search_steps.max(1), params.secant_steps, env_size[0], env_size[1]],
            env: [rotation, scene.environment.is_some() as u32 as f32, mesh.bounds_radius, 0.0],
            scene: mesh.bounds_centre.extend(0.0).to_array(),
        };
        let gpu_objects: Vec<GpuSpecularObject> = objects.iter().map(gpu_object).collect();
        let storage = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: bytes, usage })
        };
        let params_buffer = storage("specular params", bytemuck::bytes_of(&uniform), wgpu::BufferUsages::UNIFORM);
        let objects_buffer =
            storage("specular objects", bytemuck::cast_slice(&gpu_objects), wgpu::BufferUsages::STORAGE);
        let env_buffer = storage("environment", bytemuck::cast_slice(&env_map), wgpu::BufferUsages::STORAGE);
        let plane_texels = stride as u64 * height as u64;
        let buffer = |label: &str, texels: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: texels * 16,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let hits = buffer("specular hits", 6 * plane_texels);
        let info = buffer("specular weights", 4 * width as u64 * height as u64);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let texture_views = [
            view(&gbuffer.position),
            view(&gbuffer.normal),
            view(&back.position),
            view(&back.normal),
            view(&impostors.position),
            view(&impostors.normal),
            view(&impostors.albedo),
        ];
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: params_buffer.as_entire_binding() }];
        for (k, texture) in texture_views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 1 + k as u32,
                resource: wgpu::BindingResource::TextureView(texture),
            });
        }
        entries.push(wgpu::BindGroupEntry { binding: 8, resource: objects_buffer.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 9, resource: env_buffer.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 10, resource: hits.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 11, resource: info.as_entire_binding() });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("specular trace"),
            layout: &self.trace.get_bind_group_layout(0),
            entries: &entries,
        });
        let refl = SurfaceTargets::new(ctx, width, height, "GBuf_refl");
        let refr = SurfaceTargets::new(ctx, width, height, "GBuf_refr");
        let label = format!(
            "reflected and refracted rays ({} search + {} secant steps)",
            params.search_steps.max(1),
            params.secant_steps
        );
        super::timed(ctx, passes, label, || {
            let mut encoder = device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.trace);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
            }
            let targets = [&refl.position, &refl.normal, &refl.albedo, &refr.position, &refr.normal, &refr.albedo];
            for (p, texture) in targets.into_iter().enumerate() {
                encoder.copy_buffer_to_texture(
                    wgpu::TexelCopyBufferInfo {
                        buffer: &hits,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: p as u64 * plane_texels * 16,
                            bytes_per_row: Some(stride * 16),
                            rows_per_image: Some(height),
                        },
                    },
                    texture.as_image_copy(),
                    wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                );
            }
            ctx.queue.submit([encoder.finish()]);
        });
        let report = SpecularReport {
            objects: objects.iter().map(|o| o.name.clone()).collect(),
            impostor_size: size,
            ..Default::default()
        };
        Traced { refl, refr, params: params_buffer, hits, info, report, eye: objects[0].centre }
    }

    /// L'_rv, L'_r and CI_std (step 5): rewrites `solutions` at the specular pixels and returns
    /// the base buffer [`super::compose`] reads (CI_std, w = 1 at a specular pixel).
    #[allow(clippy::too_many_arguments)]
    pub fn combine(
        &self,
        ctx: &GpuContext,
        traced: &mut Traced,
        gbuffer: &SurfaceTargets,
        solutions: &wgpu::Buffer,
        refl_solutions: &wgpu::Buffer,
        refr_solutions: &wgpu::Buffer,
        photo: &wgpu::Buffer,
        width: u32,
        height: u32,
    ) -> wgpu::Buffer {
        let device = &ctx.device;
        let base = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("specular base"),
            size: width as u64 * height as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let counts = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("specular counts"),
            contents: &[0u8; 32],
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let position = gbuffer.position.create_view(&Default::default());
        let entries = [
            wgpu::BindGroupEntry { binding: 0, resource: traced.params.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&position) },
            wgpu::BindGroupEntry { binding: 10, resource: traced.hits.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 11, resource: traced.info.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 12, resource: solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 13, resource: refl_solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 14, resource: refr_solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 15, resource: photo.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 16, resource: base.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 17, resource: counts.as_entire_binding() },
        ];
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("specular combine"),
            layout: &self.combine.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.combine);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        ctx.queue.submit([encoder.finish()]);
        let counts: Vec<u32> = ctx.read_f32(&counts).into_iter().map(f32::to_bits).collect();
        let report = &mut traced.report;
        (report.pixels, report.rays, report.back_projected, report.rendered, report.missed) =
            (counts[0], counts[1], counts[2], counts[3], counts[4]);
        base
    }
}

fn gpu_object(object: &SpecularObject) -> GpuSpecularObject {
    let (kind, ior, colour) = match object.delta {
        DeltaBsdf::Mirror { reflectance } => (0.0, 1.0, reflectance),
        DeltaBsdf::Dielectric { ior, absorption } => (1.0, ior, absorption),
    };
    GpuSpecularObject {
        centre_radius: object.centre.extend(object.radius).to_array(),
        kind: [kind, ior, object.material as f32, if object.real { 1.0 } else { 0.0 }],
        colour: colour.extend(0.0).to_array(),
    }
}
