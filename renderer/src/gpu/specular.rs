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
//! 6. **caustic maps** (5.27–5.29; with `shadows` and `gi`, unless
//!    [`SpecularParams::caustic_map_size`] is 0): per spot or point light and per object it lights, the object's G-buffer from the
//!    light (PGBuf, aimed at the object's bounding sphere — the thesis renders from the spot's
//!    view) and its photons traced by the same ray search (for glass, through both
//!    interfaces); each photon carries I(ω) dω × its Fresnel and transmittance weight and is
//!    splatted into the camera's pixels with a disc kernel on the receiving surface whose
//!    radius is its footprint, from its neighbours' hits in the light's grid (Wyman and Davis
//!    2006 splat quads of a fixed size); summed in 64-bit fixed point (order-independent, so a
//!    real caustic enters L_rv and L_r identically), then ρ/π E added to L_rv, and to L_r where
//!    light, object and receiver are real (5.29);
//! 7. **reflected and refracted VPLs** (Figure 5.23, `gi` only): every photon is also a
//!    candidate VPL where it lands (albedo × its flux), drawn with the RSMs' candidates by flux.
//!
//! Glass's exit point (step 3, for camera rays and photons alike) is searched along the
//! refracted ray in the back-face G-buffer; Wyman's estimate (the back face's distance along
//! the view ray) remains the fallback where that search brackets nothing.
//!
//! Not built: caustics seen in mirrors and glass (the thesis adds them to L'_rv and L'_r);
//! the specular lobe of a glossy receiver under a caustic (ρ/π only); interreflections between
//! mirrors and glass (one specular bounce, as the thesis); VPLs on mirrors or glass (they have
//! no diffuse albedo and make none).

use super::context::GpuContext;
use super::mesh::{GpuMesh, SpecularObject};
use super::pool::Contents;
use super::raster::{GbufferDraw, Raster, SceneBuffers, SurfaceTargets, ViewUniform};
use crate::light::SpotLight;
use crate::material::DeltaBsdf;
use crate::math::luminance;
use crate::scene::Scene;
use glam::{Mat4, Vec3, Vec4};
use serde::Serialize;
use std::sync::Arc;

pub const SHADER: &str = concat!(include_str!("common.wgsl"), include_str!("specular.wgsl"));

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
    /// Resolution of each caustic map (the photon G-buffer of one object from one light; the
    /// thesis: 512²); 0: no caustics. Caustics run with the `shadows` and `gi` conditions.
    pub caustic_map_size: u32,
}

impl Default for SpecularParams {
    fn default() -> Self {
        SpecularParams { impostor_size: 256, search_steps: 48, secant_steps: 6, caustic_map_size: 256 }
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
    /// The caustic maps (None: not run, with the reason in `caustics_skipped`).
    pub caustics: Option<CausticReport>,
    /// Why no caustic map ran, when none did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub caustics_skipped: Option<String>,
}

/// What the caustic maps did in a frame.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CausticReport {
    pub map_size: u32,
    /// One map per light and mirror or glass object it lights ("spot → glass-sphere").
    pub maps: Vec<String>,
    /// Pairs without a map, and why.
    pub skipped: Vec<String>,
    /// Photons with flux (a light pixel on the object, per reflected or refracted component
    /// that hit a surface).
    pub photons: u32,
    /// Photons that reached a surface the camera sees.
    pub splatted: u32,
    /// Reflected and refracted VPLs drawn from the photons (gi only; Figure 5.23).
    pub vpls: usize,
}

/// The traced photons of a frame's caustic maps.
pub struct PhotonMaps {
    map_size: u32,
    maps: Vec<PhotonMap>,
    skipped: Vec<String>,
}

/// One light's photons through one mirror or glass object.
struct PhotonMap {
    pair: String,
    light: SpotLight,
    object: u32,
    object_real: bool,
    tan_half: f32,
    pgbuf: SurfaceTargets,
    search: Search,
}

/// The most camera pixels a photon's splat reaches from its centre (a wider footprint is cut).
const MAX_SPLAT_REACH: u32 = 24;

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

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct PhotonUniform {
    light_position: [f32; 4],
    light_direction: [f32; 4],
    intensity: [f32; 4],
    camera_view_proj: [[f32; 4]; 4],
    camera: [f32; 4],
    map: [f32; 4],
    size: [u32; 4],
}

/// The compiled passes.
pub struct Specular {
    trace: wgpu::ComputePipeline,
    combine: wgpu::ComputePipeline,
    photons: wgpu::ComputePipeline,
    apply: wgpu::ComputePipeline,
}

/// The distance impostors of a frame's mirrors and glass, and what every ray search reads.
pub struct Impostors {
    targets: SurfaceTargets,
    size: u32,
    objects: Arc<wgpu::Buffer>,
    environment: Arc<wgpu::Buffer>,
    env_size: [u32; 2],
    env_rotation: f32,
    has_environment: bool,
    bounds: (Vec3, f32),
    names: Vec<String>,
}

/// One ray search's output: hits (six planes) and weights.
struct Search {
    params: Arc<wgpu::Buffer>,
    hits: Arc<wgpu::Buffer>,
    info: Arc<wgpu::Buffer>,
    stride: u32,
}

/// The traced rays of a frame, waiting for their G-buffers to be shaded.
pub struct Traced {
    /// GBuf_refl and GBuf_refr, in the camera's pixels.
    pub refl: SurfaceTargets,
    pub refr: SurfaceTargets,
    params: Arc<wgpu::Buffer>,
    hits: Arc<wgpu::Buffer>,
    info: Arc<wgpu::Buffer>,
    pub report: SpecularReport,
    /// Where shading of the hit G-buffers looks from (Blinn–Phong's view direction): the
    /// first specular object's centre.
    pub eye: Vec3,
}

/// The scene as a frame's specular passes see it: the description, its triangles and their
/// GPU buffers.
#[derive(Clone, Copy)]
pub struct FrameScene<'a> {
    pub scene: &'a Scene,
    pub mesh: &'a GpuMesh,
    pub buffers: &'a SceneBuffers,
}

/// What the camera's ray search reads: the impostors and the camera's G-buffer and view.
#[derive(Clone, Copy)]
pub struct RayInputs<'a> {
    pub impostors: &'a Impostors,
    pub gbuffer: &'a SurfaceTargets,
    pub view: &'a ViewUniform,
    pub view_proj: Mat4,
}

/// What L'_rv, L'_r and CI_std are combined from ([`Specular::combine`]): the camera's
/// G-buffer and solutions, the shaded reflected and refracted hits, the photograph.
#[derive(Clone, Copy)]
pub struct CombineInputs<'a> {
    pub gbuffer: &'a SurfaceTargets,
    pub solutions: &'a wgpu::Buffer,
    pub reflected: &'a wgpu::Buffer,
    pub refracted: &'a wgpu::Buffer,
    pub photo: &'a wgpu::Buffer,
    pub width: u32,
    pub height: u32,
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
        let [trace, combine, photons, apply] = ctx.compute_pipelines(
            "specular.wgsl",
            SHADER,
            ["cs_trace", "cs_combine", "cs_photons", "cs_caustics_apply"],
        );
        Specular { trace, combine, photons, apply }
    }

    /// The distance impostors of the scene's mirrors and glass (step 1), one pass.
    pub fn impostors(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        passes: &mut Vec<super::PassTime>,
        at: FrameScene,
        params: &SpecularParams,
    ) -> Impostors {
        let FrameScene { scene, mesh, buffers } = at;
        let device = &ctx.device;
        let objects = &mesh.specular;
        let max_dimension = device.limits().max_texture_dimension_2d;
        let size = params.impostor_size.clamp(8, max_dimension / 6).min(max_dimension / objects.len().max(1) as u32);
        // six faces side by side per object, one object per row
        let targets = SurfaceTargets::new(ctx, 6 * size, size * objects.len() as u32, "impostors");
        let total = mesh.vertices.len() as u32;
        let far = 2.0 * mesh.bounds_radius
            + objects.iter().map(|o| (o.centre - mesh.bounds_centre).length()).fold(0.0, f32::max);
        let near = (far * 1e-5).max(1e-5);
        // a cube face: 90° field of view
        let projection = super::perspective(1.0, near, far);
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
            raster.gbuffer_draws(ctx, buffers, &targets, &draws, false)
        });
        let (env_map, env_size, rotation) = match &scene.environment {
            Some(env) => (
                env.map.pixels.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect::<Vec<[f32; 4]>>(),
                [env.map.width, env.map.height],
                env.rotation,
            ),
            None => (vec![[0.0; 4]], [1, 1], 0.0),
        };
        let gpu_objects: Vec<GpuSpecularObject> = objects.iter().map(gpu_object).collect();
        let storage = |label: &str, bytes: &[u8]| {
            ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        Impostors {
            objects: storage("specular objects", bytemuck::cast_slice(&gpu_objects)),
            environment: storage("environment", bytemuck::cast_slice(&env_map)),
            targets,
            size,
            env_size,
            env_rotation: rotation,
            has_environment: scene.environment.is_some(),
            bounds: (mesh.bounds_centre, mesh.bounds_radius),
            names: objects.iter().map(|o| o.name.clone()).collect(),
        }
    }

    /// The back faces of the glass objects among `ranges` seen from `view` (step 2): the
    /// farthest surfaces, for the exit of two-sided refraction; 1×1 without glass (the shader
    /// reads none, but the binding must exist).
    #[allow(clippy::too_many_arguments)]
    fn back_faces(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        buffers: &SceneBuffers,
        glass: &[std::ops::Range<u32>],
        view: &ViewUniform,
        width: u32,
        height: u32,
    ) -> SurfaceTargets {
        if glass.is_empty() {
            return SurfaceTargets::placeholder(ctx, "no back faces");
        }
        let back = SurfaceTargets::new(ctx, width, height, "back faces");
        let draw = GbufferDraw { view: *view, viewport: [0, 0, width, height], ranges: glass };
        raster.gbuffer_draws(ctx, buffers, &back, std::slice::from_ref(&draw), true);
        back
    }

    /// The ray search (step 3) for every pixel of `gbuffer` (width × height, seen from `eye`
    /// through `view_proj`) on a mirror or glass: hits and weights, submitted.
    #[allow(clippy::too_many_arguments)]
    fn search(
        &self,
        ctx: &GpuContext,
        impostors: &Impostors,
        gbuffer: &SurfaceTargets,
        back: &SurfaceTargets,
        view_proj: Mat4,
        eye: Vec3,
        width: u32,
        height: u32,
        params: &SpecularParams,
    ) -> Search {
        let stride = row_stride(width);
        let (centre, radius) = impostors.bounds;
        let uniform = Params {
            view_proj: view_proj.to_cols_array_2d(),
            camera: eye.extend(0.0).to_array(),
            size: [width, height, impostors.size, stride],
            search: [params.search_steps.max(1), params.secant_steps, impostors.env_size[0], impostors.env_size[1]],
            env: [impostors.env_rotation, impostors.has_environment as u32 as f32, radius, 0.0],
            scene: centre.extend(0.0).to_array(),
        };
        let params_buffer = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("specular params"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let plane_texels = stride as u64 * height as u64;
        let buffer = |label: &str, texels: u64| {
            ctx.buffer(label, texels * 16, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC, Contents::Zeroed)
        };
        let hits = buffer("specular hits", 6 * plane_texels);
        let info = buffer("specular weights", 4 * width as u64 * height as u64);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let texture_views = [
            view(&gbuffer.position),
            view(&gbuffer.normal),
            view(&back.position),
            view(&back.normal),
            view(&impostors.targets.position),
            view(&impostors.targets.normal),
            view(&impostors.targets.albedo),
        ];
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: params_buffer.as_entire_binding() }];
        for (k, texture) in texture_views.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 1 + k as u32,
                resource: wgpu::BindingResource::TextureView(texture),
            });
        }
        entries.push(wgpu::BindGroupEntry { binding: 8, resource: impostors.objects.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 9, resource: impostors.environment.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 10, resource: hits.as_entire_binding() });
        entries.push(wgpu::BindGroupEntry { binding: 11, resource: info.as_entire_binding() });
        ctx.dispatch("specular trace", &self.trace, &entries, [width.div_ceil(8), height.div_ceil(8)]);
        Search { params: params_buffer, hits, info, stride }
    }

    /// Back faces and the ray search from the camera (steps 2–3); `passes` gets one entry each.
    pub fn trace(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        passes: &mut Vec<super::PassTime>,
        at: FrameScene,
        rays: &RayInputs,
        params: &SpecularParams,
    ) -> Traced {
        let FrameScene { scene, mesh, buffers } = at;
        let RayInputs { impostors, gbuffer, view: camera_view, view_proj: camera_view_proj } = *rays;
        let device = &ctx.device;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let glass: Vec<std::ops::Range<u32>> = mesh
            .specular
            .iter()
            .filter(|o| matches!(o.delta, DeltaBsdf::Dielectric { .. }))
            .map(|o| o.range.clone())
            .collect();
        let back = if glass.is_empty() {
            self.back_faces(ctx, raster, buffers, &glass, camera_view, width, height)
        } else {
            super::timed(ctx, passes, "back faces of glass".into(), || {
                self.back_faces(ctx, raster, buffers, &glass, camera_view, width, height)
            })
        };
        let label = format!(
            "reflected and refracted rays ({} search + {} secant steps)",
            params.search_steps.max(1),
            params.secant_steps
        );
        let refl = SurfaceTargets::new(ctx, width, height, "GBuf_refl");
        let refr = SurfaceTargets::new(ctx, width, height, "GBuf_refr");
        let search = super::timed(ctx, passes, label, || {
            let search = self.search(
                ctx,
                impostors,
                gbuffer,
                &back,
                camera_view_proj,
                scene.camera.position,
                width,
                height,
                params,
            );
            let plane_texels = search.stride as u64 * height as u64;
            let mut encoder = device.create_command_encoder(&Default::default());
            let targets = [&refl.position, &refl.normal, &refl.albedo, &refr.position, &refr.normal, &refr.albedo];
            for (p, texture) in targets.into_iter().enumerate() {
                encoder.copy_buffer_to_texture(
                    wgpu::TexelCopyBufferInfo {
                        buffer: &search.hits,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: p as u64 * plane_texels * 16,
                            bytes_per_row: Some(search.stride * 16),
                            rows_per_image: Some(height),
                        },
                    },
                    texture.as_image_copy(),
                    wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                );
            }
            ctx.submit(encoder);
            search
        });
        let report =
            SpecularReport { objects: impostors.names.clone(), impostor_size: impostors.size, ..Default::default() };
        Traced {
            refl,
            refr,
            params: search.params,
            hits: search.hits,
            info: search.info,
            report,
            eye: mesh.specular[0].centre,
        }
    }

    /// Caustic maps (5.27–5.29), first half: for every light and every mirror or glass object
    /// it lights, the object's G-buffer from the light (PGBuf) and its photons traced through
    /// the impostor like the camera's rays. [`Specular::caustic_vpls`] makes VPLs of them,
    /// [`Specular::splat`] the caustic buffer.
    pub fn photon_maps(
        &self,
        ctx: &GpuContext,
        raster: &Raster,
        passes: &mut Vec<super::PassTime>,
        at: FrameScene,
        impostors: &Impostors,
        params: &SpecularParams,
    ) -> PhotonMaps {
        let FrameScene { scene, mesh, buffers } = at;
        let map_size = params.caustic_map_size.clamp(8, ctx.device.limits().max_texture_dimension_2d);
        let mut maps = PhotonMaps { map_size, maps: Vec::new(), skipped: Vec::new() };
        let everything = 0..mesh.vertices.len() as u32;
        for light in &scene.spots {
            for (k, object) in mesh.specular.iter().enumerate() {
                let pair = format!("{} → {}", light.name, object.name);
                let Some((matrix, forward, tan_half)) = photon_view(light, object) else {
                    maps.skipped.push(format!("{pair}: the light is inside the object's bounds or its cone misses it"));
                    continue;
                };
                let view = ViewUniform::perspective(matrix, light.position, forward);
                let label = format!("caustic map {pair} ({map_size}²)");
                let (pgbuf, search) = super::timed(ctx, passes, label, || {
                    let pgbuf = SurfaceTargets::new(ctx, map_size, map_size, "PGBuf");
                    let draw = GbufferDraw {
                        view,
                        viewport: [0, 0, map_size, map_size],
                        ranges: std::slice::from_ref(&everything),
                    };
                    raster.gbuffer_draws(ctx, buffers, &pgbuf, std::slice::from_ref(&draw), false);
                    let glass: Vec<std::ops::Range<u32>> = match object.delta {
                        DeltaBsdf::Dielectric { .. } => vec![object.range.clone()],
                        DeltaBsdf::Mirror { .. } => Vec::new(),
                    };
                    let back = self.back_faces(ctx, raster, buffers, &glass, &view, map_size, map_size);
                    let search =
                        self.search(ctx, impostors, &pgbuf, &back, matrix, light.position, map_size, map_size, params);
                    (pgbuf, search)
                });
                maps.maps.push(PhotonMap {
                    pair,
                    light: light.clone(),
                    object: k as u32,
                    object_real: object.real,
                    tan_half,
                    pgbuf,
                    search,
                });
            }
        }
        maps
    }

    /// The caustic maps' photons where they are, for VPL creation on the GPU
    /// ([`super::vpl::VplSampler::candidates`], the counterpart of [`Specular::caustic_vpls`]).
    pub fn caustic_sources<'a>(&self, maps: &'a PhotonMaps) -> Vec<super::vpl::CausticMap<'a>> {
        maps.maps
            .iter()
            .map(|map| super::vpl::CausticMap {
                light: &map.light,
                object: map.object,
                object_real: map.object_real,
                tan_half: map.tan_half,
                size: maps.map_size,
                stride: map.search.stride,
                position: &map.pgbuf.position,
                info: &map.search.info,
                hits: &map.search.hits,
            })
            .collect()
    }

    /// Reflected and refracted VPLs (Figure 5.23): every photon of the caustic maps as a
    /// candidate VPL where it lands, carrying the flux the surface there reflects (albedo ×
    /// the photon's flux); real where light, object and surface are all real. Read back and
    /// made on the CPU: the reference for `vpl.wgsl`'s `cs_caustic_candidates`, which makes the
    /// same candidates on the GPU ([`Specular::caustic_sources`]).
    pub fn caustic_vpls(&self, ctx: &GpuContext, maps: &PhotonMaps) -> Vec<super::vpl::GpuVpl> {
        use rayon::prelude::*;
        let mut candidates = Vec::new();
        let n = maps.map_size as usize;
        // every map's buffers copied for reading first, then its positions read with one wait
        // for all (not three waits per map)
        let staged: Vec<(Arc<wgpu::Buffer>, Arc<wgpu::Buffer>)> =
            maps.maps.iter().map(|map| (ctx.stage(&map.search.info), ctx.stage(&map.search.hits))).collect();
        let textures: Vec<(&wgpu::Texture, u32)> = maps.maps.iter().map(|map| (&*map.pgbuf.position, 16)).collect();
        let positions_bytes = ctx.read_textures(&textures);
        for ((map, (info, hits)), positions) in maps.maps.iter().zip(&staged).zip(&positions_bytes) {
            let positions: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(positions);
            let info = ctx.read_staged_f32(info);
            let hits = ctx.read_staged_f32(hits);
            // texel (x, y) of hit plane p (see specular.wgsl's `plane`)
            let plane = |p: usize, x: usize, y: usize| {
                let texel = 4 * ((p * n + y) * map.search.stride as usize + x);
                Vec4::from_slice(&hits[texel..texel + 4])
            };
            // rows on all threads, joined in row order
            let rows: Vec<Vec<super::vpl::GpuVpl>> = (0..n)
                .into_par_iter()
                .map(|y| {
                    let mut candidates = Vec::new();
                    for x in 0..n {
                        let pixel = y * n + x;
                        let weights = |q: usize| &info[16 * pixel + 4 * q..16 * pixel + 4 * q + 4];
                        if weights(2)[3] < 0.5 || (weights(3)[3] + 0.5) as u32 != map.object {
                            continue;
                        }
                        let p1 = Vec3::from_slice(&positions[pixel][..3]);
                        let to = p1 - map.light.position;
                        let d_omega = super::vpl::texel_solid_angle(x as u32, y as u32, n as u32, map.tan_half);
                        let flux_in = map.light.intensity_towards(to.normalize()) * d_omega;
                        for c in 0..2 {
                            let w = weights(c);
                            if w[3] != 1.0 {
                                continue;
                            }
                            let albedo = plane(3 * c + 2, x, y).truncate();
                            let flux = flux_in * Vec3::new(w[0], w[1], w[2]) * albedo;
                            if luminance(flux) <= 0.0 || !flux.is_finite() {
                                continue;
                            }
                            // position w: role (1 real, 2 virtual) + 4 × material
                            let position = plane(3 * c, x, y);
                            let real = map.light.real && map.object_real && (position.w + 0.5) as u32 % 4 == 1;
                            let position = position.truncate();
                            let normal = plane(3 * c + 1, x, y).truncate().normalize_or_zero();
                            candidates.push(super::vpl::GpuVpl {
                                position: position.extend(if real { 1.0 } else { 0.0 }).to_array(),
                                normal: normal.extend(0.0).to_array(),
                                flux: flux.extend(1.0).to_array(),
                            });
                        }
                    }
                    candidates
                })
                .collect();
            candidates.extend(rows.into_iter().flatten());
        }
        candidates
    }

    /// Caustic maps, second half: splats every photon into the caustic buffer in the camera's
    /// pixels. Returns the buffer for [`Specular::apply_caustics`] and the report.
    pub fn splat(
        &self,
        ctx: &GpuContext,
        maps: &PhotonMaps,
        scene: &Scene,
        gbuffer: &SurfaceTargets,
        camera_view_proj: Mat4,
    ) -> (Arc<wgpu::Buffer>, CausticReport) {
        let (width, height) = (scene.camera.width, scene.camera.height);
        let caustic = ctx.buffer(
            "caustic buffer",
            12 * 4 * width as u64 * height as u64,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            Contents::Zeroed,
        );
        let counts = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("photon counts"),
            contents: &[0u8; 16],
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let cam_position = gbuffer.position.create_view(&Default::default());
        let cam_normal = gbuffer.normal.create_view(&Default::default());
        for map in &maps.maps {
            let light = &map.light;
            let uniform = PhotonUniform {
                light_position: light.position.extend(if light.real { 1.0 } else { 0.0 }).to_array(),
                light_direction: light.direction.extend(light.cos_outer).to_array(),
                intensity: light.intensity.extend(light.cos_inner).to_array(),
                camera_view_proj: camera_view_proj.to_cols_array_2d(),
                camera: scene.camera.position.extend(0.5 / scene.camera.fy).to_array(),
                map: [map.tan_half, maps.map_size as f32, map.object as f32, if map.object_real { 1.0 } else { 0.0 }],
                size: [width, height, MAX_SPLAT_REACH, 0],
            };
            let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
                label: Some("photons"),
                contents: bytemuck::bytes_of(&uniform),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let light_position = map.pgbuf.position.create_view(&Default::default());
            let entries = [
                wgpu::BindGroupEntry { binding: 0, resource: map.search.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&light_position) },
                wgpu::BindGroupEntry { binding: 10, resource: map.search.hits.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 11, resource: map.search.info.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 18, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 19, resource: wgpu::BindingResource::TextureView(&cam_position) },
                wgpu::BindGroupEntry { binding: 20, resource: wgpu::BindingResource::TextureView(&cam_normal) },
                wgpu::BindGroupEntry { binding: 21, resource: caustic.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 22, resource: counts.as_entire_binding() },
            ];
            let groups = maps.map_size.div_ceil(8);
            ctx.dispatch("photons", &self.photons, &entries, [groups, groups]);
        }
        let counts: Vec<u32> = ctx.read_f32(&counts).into_iter().map(f32::to_bits).collect();
        let report = CausticReport {
            map_size: maps.map_size,
            maps: maps.maps.iter().map(|m| m.pair.clone()).collect(),
            skipped: maps.skipped.clone(),
            photons: counts[0],
            splatted: counts[1],
            vpls: 0,
        };
        (caustic, report)
    }

    /// Adds the caustic buffer's irradiance, as diffuse radiance rho/pi E, to L_rv and (where
    /// light, object and receiver are real) to L_r.
    pub fn apply_caustics(
        &self,
        ctx: &GpuContext,
        caustic: &wgpu::Buffer,
        gbuffer: &SurfaceTargets,
        solutions: &wgpu::Buffer,
        width: u32,
        height: u32,
    ) {
        let uniform = PhotonUniform { size: [width, height, 0, 0], ..bytemuck::Zeroable::zeroed() };
        let uniform = ctx.upload(&wgpu::util::BufferInitDescriptor {
            label: Some("caustics apply"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let albedo = gbuffer.albedo.create_view(&Default::default());
        let entries = [
            wgpu::BindGroupEntry { binding: 12, resource: solutions.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 18, resource: uniform.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 21, resource: caustic.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 23, resource: wgpu::BindingResource::TextureView(&albedo) },
        ];
        ctx.dispatch("caustics apply", &self.apply, &entries, [width.div_ceil(8), height.div_ceil(8)]);
    }

    /// L'_rv, L'_r and CI_std (step 5): rewrites `solutions` at the specular pixels and returns
    /// the base buffer [`super::compose`] reads (CI_std, w = 1 at a specular pixel).
    pub fn combine(&self, ctx: &GpuContext, traced: &mut Traced, inputs: &CombineInputs) -> Arc<wgpu::Buffer> {
        let CombineInputs {
            gbuffer,
            solutions,
            reflected: refl_solutions,
            refracted: refr_solutions,
            photo,
            width,
            height,
        } = *inputs;
        let base = ctx.buffer(
            "specular base",
            width as u64 * height as u64 * 16,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            Contents::Zeroed,
        );
        let counts = ctx.upload(&wgpu::util::BufferInitDescriptor {
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
        ctx.dispatch("specular combine", &self.combine, &entries, [width.div_ceil(8), height.div_ceil(8)]);
        let counts: Vec<u32> = ctx.read_f32(&counts).into_iter().map(f32::to_bits).collect();
        let report = &mut traced.report;
        (report.pixels, report.rays, report.back_projected, report.rendered, report.missed) =
            (counts[0], counts[1], counts[2], counts[3], counts[4]);
        base
    }
}

/// The view of `light` onto `object` for its caustic map: aimed at the object's bounding
/// sphere, which it just contains; returns (matrix, forward axis, tan of half the fov), or None
/// where the light is inside the sphere or a spot's cone misses it.
fn photon_view(light: &SpotLight, object: &SpecularObject) -> Option<(Mat4, Vec3, f32)> {
    let to = object.centre - light.position;
    let distance = to.length();
    if distance <= object.radius * 1.001 {
        return None;
    }
    let forward = to / distance;
    let half = ((object.radius / distance).asin() * 1.02).min(80f32.to_radians());
    let off_axis = forward.dot(light.direction).clamp(-1.0, 1.0).acos();
    if light.cos_outer > -1.0 && off_axis - half > light.cos_outer.clamp(-1.0, 1.0).acos() {
        return None;
    }
    let far = distance + object.radius * 1.01;
    let near = ((distance - object.radius) * 0.01).max(1e-4);
    let projection = super::perspective(1.0 / half.tan(), near, far);
    Some((projection * super::look_at(light.position, forward, super::up_hint(forward)), forward, half.tan()))
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
