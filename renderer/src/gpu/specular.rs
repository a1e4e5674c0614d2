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

mod caustics;
mod rays;

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
    /// The combine pass's counts still on the GPU (pixels, rays, back-projected, rendered,
    /// missed: five `u32`s), read back with the frame's images into `report` (the frame's
    /// read-back pass).
    pub counts: Option<Arc<wgpu::Buffer>>,
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
        // the scene's: kept from frame to frame while it is the same
        let resident = |key: &str, bytes: &[u8]| ctx.resident(key, bytes, wgpu::BufferUsages::STORAGE);
        Impostors {
            objects: resident("specular objects", bytemuck::cast_slice(&gpu_objects)),
            environment: resident("environment", bytemuck::cast_slice(&env_map)),
            targets,
            size,
            env_size,
            env_rotation: rotation,
            has_environment: scene.environment.is_some(),
            bounds: (mesh.bounds_centre, mesh.bounds_radius),
            names: objects.iter().map(|o| o.name.clone()).collect(),
        }
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
