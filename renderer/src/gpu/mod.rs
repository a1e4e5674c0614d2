//! The GPU renderer (wgpu): differential instant radiosity (thesis Section 5.2, Figure 5.3) for
//! the `gi` factor and its lower levels.
//!
//! A frame runs these passes, and only those the scene and the condition need:
//! 1. **shadow maps**: per spot light, and per directional light sampled from the environment
//!    map (the thesis's environment VPLs on the hemisphere, used for direct light), a real-only
//!    map and, when the condition casts virtual shadows and there is virtual geometry, a
//!    virtual-only map (two maps avoid the double shadows of Figure 5.6);
//! 2. **RSMs** (condition `gi` only): per spot light, and along `env_vpl_directions` of the
//!    environment's directions (orthographic), a real-only and a virtual-only reflective shadow
//!    map, and **VPL creation** from them by flux ([`vpl`], on the GPU: only the drawn VPLs are
//!    read back); then the **imperfect
//!    shadow maps** of the VPLs ([`ism`]: real and virtual point clouds, geometry-aligned
//!    splats; not made when `ism_size` is 0 or there are no VPLs);
//!    With `bounces` > 1, the **multiple-bounce light source** ([`bounce`], 5.2.7) spawns
//!    further VPLs from these before the ISMs are made, and the budget is split by flux over
//!    all sources; in a scene with a mirror or glass, with `shadows` or `gi`, the **caustic
//!    maps**' photons ([`specular`], 5.27–5.29) are traced first and, with `gi`, drawn as
//!    reflected and refracted VPL candidates together with the RSMs' (Figure 5.23);
//! 3. the camera's **G-buffer** (position, real/virtual flag and material, normal, albedo and
//!    Blinn–Phong parameters); in a scene with a mirror or glass, the **specular passes**
//!    ([`specular`], thesis 5.3): impostors, back faces of glass, reflected and refracted rays
//!    into two more G-buffers, shaded in step 4 like the camera's, then L'_rv, L'_r and the
//!    photograph's part CI_std by back-projection, composed in step 7; the caustic photons
//!    splatted into the camera's pixels and added to L_rv and L_r after step 5;
//! 4. **shading** ([`shade`]): L_rv and L_r by equations 5.1–5.8, the VPLs of each pixel's
//!    interleaved class only when `interleave` > 1;
//! 5. the **indirect light** ([`indirect`], only with VPLs): the geometry-aware merge of the
//!    interleaved classes and, in live rendering ([`DirRenderer::render_with_state`]), temporal
//!    smoothing by 5.11–5.15, then the sum with the direct light;
//! 6. **colour mapping** ([`cm`], the `cm` factor, [`crate::cm`]): τ applied to both buffers
//!    (thesis 4.18 / 4.28) — `off` is the simplified Reinhard operator x/(1+x) then sRGB
//!    encoding; `statistics`, `samples` and `rohmer` first reduce statistics on the GPU and
//!    solve their tiny systems on the CPU;
//! 7. **composition** ([`compose`]): L_final = L'_cam + τ(L_rv) − τ(L_r), or Debevec's scaled
//!    form, where L'_cam is the photograph with virtual pixels masked out;
//! 8. with the `ca` factor ([`DirParams::camera_artifacts`]), the camera-artifact chain on the
//!    composite's virtual layers ([`ca`], see [`crate::ca`]).
//!
//! Conditions: `none` lights virtual objects directly, with shadows from real blockers only
//! (virtual objects cast none) and no indirect light; `shadows` adds the virtual-only shadow
//! maps (V_rv = min(V_r, V_v)); `gi` adds indirect light from VPLs (`bounces`, default 3).
//!
//! Not built: caustics seen in mirrors and glass (L'_rv, L'_r; see [`specular`]), area lights (emissive surfaces show in both solutions but light nothing),
//! per-object motion vectors (temporal smoothing reprojects with the camera), glossy VPLs (VPLs
//! reflect diffusely).

mod batch;
mod bind_groups;
pub mod bounce;
pub mod bounce_chain;
pub mod ca;
pub mod cm;
pub mod coherent;
pub mod compose;
pub mod context;
mod counters;
mod frame;
pub mod indirect;
pub mod ism;
pub mod mesh;
pub mod pool;
pub mod raster;
mod readback;
pub mod representation;
pub mod shade;
pub mod specular;
pub mod stream;
pub mod vpl;

use crate::cm::{CmParams, CmReport, CmState, Composition};
use crate::error::{RenderError, Result};
use crate::image::{Image, Mask};
use crate::scene::Scene;
use context::GpuContext;
use glam::{Mat4, Vec3};
use raster::{Raster, SceneBuffers, Subset, SurfaceTargets, ViewUniform};
use serde::Serialize;
use shade::{GpuLight, Shade, ShadeParams};
use std::sync::Arc;
use std::time::Instant;

/// The level of the `gi` factor, in the three modes of the preliminary study (thesis 6.3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GiLevel {
    /// gi off: virtual objects lit directly; no shadows cast by them, no indirect light.
    None,
    /// Shadows of virtual objects, no indirect light.
    Shadows,
    /// Shadows and indirect light exchanged between real and virtual objects
    /// ([`DirParams::bounces`]).
    Gi,
}

impl GiLevel {
    pub fn parse(name: &str) -> Option<GiLevel> {
        match name.trim().to_ascii_lowercase().as_str() {
            "none" | "off" | "lq" => Some(GiLevel::None),
            "shadows" => Some(GiLevel::Shadows),
            "gi" => Some(GiLevel::Gi),
            _ => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            GiLevel::None => "none",
            GiLevel::Shadows => "shadows",
            GiLevel::Gi => "gi",
        }
    }
}

/// The knobs of a GPU frame.
#[derive(Clone, Debug, Serialize)]
pub struct DirParams {
    pub condition: GiLevel,
    /// VPL budget (gi only), split over the spot lights by flux.
    pub vpls: u32,
    /// Resolution of each shadow map (spot and environment lights).
    pub shadow_map_size: u32,
    /// Directional lights sampled from the environment map (importance by radiance), each with
    /// its own real-only and virtual-only orthographic shadow maps; 0 ignores the environment.
    pub env_lights: u32,
    /// Resolution of each reflective shadow map (gi only).
    pub rsm_size: u32,
    /// Environment directions that also get RSMs and so make VPLs (gi only): the environment's
    /// light bounces; 0: only spot lights make VPLs.
    pub env_vpl_directions: u32,
    /// Exposure applied before the tone mapping x/(1+x) (every cm method but `rohmer` maps
    /// tone-mapped values).
    pub exposure: f32,
    /// The geometry term of a VPL uses max(d², clamp²): this distance in metres.
    pub vpl_clamp_distance: f32,
    /// Resolution of each VPL's imperfect shadow map (its tile of the atlas); 0: VPLs are
    /// unshadowed (V = 1), no ISMs are made.
    pub ism_size: u32,
    /// Points of each point cloud (real, virtual) splatted into each VPL's ISM.
    pub ism_points: u32,
    /// How the ISMs' splats are drawn ([`ism::IsmSplatting`]): a compute pass (default) or
    /// the rasteriser.
    pub ism_splatting: ism::IsmSplatting,
    /// The colour mapping of both GI buffers (the `cm` factor); default `off` (Reinhard).
    pub cm: CmParams,
    /// How the mapped differential is added to the photograph.
    pub composition: Composition,
    /// Interleaved sampling (thesis 5.2.10): the G-buffer is split into n × n classes, each
    /// pixel shades 1/n² of the VPLs, a geometry-aware filter merges the classes; 1: off.
    pub interleave: u32,
    /// The weights of temporal smoothing (5.11–5.14), used by [`DirRenderer::render_with_state`].
    pub temporal: indirect::TemporalParams,
    /// The `ca` factor: the camera-artifact chain applied after the composite ([`ca`]);
    /// None: off.
    pub camera_artifacts: Option<crate::ca::CaParams>,
    /// Bounces of indirect light (gi only): 1 is the single bounce of the RSM VPLs; each further
    /// bounce adds the multiple-bounce light source of 5.2.7 ([`bounce`]), spawned from the
    /// VPLs of the bounce before, and takes its share of `vpls` by flux. At most
    /// [`MAX_BOUNCES`].
    pub bounces: u32,
    /// Candidate points each multiple-bounce slot searches (drawn by area from all surfaces).
    pub bounce_candidates: u32,
    /// Half angle (degrees) of the cone around a slot's direction in which a candidate is valid
    /// (the thesis: 5°).
    pub bounce_cone_degrees: f32,
    /// The passes of mirrors and glass (thesis 5.3, [`specular`]); they run only in a scene
    /// with such an object.
    pub specular: specular::SpecularParams,
}

/// The most bounces of indirect light a frame computes ([`DirParams::bounces`]).
pub const MAX_BOUNCES: u32 = 8;

impl Default for DirParams {
    fn default() -> Self {
        DirParams {
            condition: GiLevel::Gi,
            vpls: 256,
            shadow_map_size: 512,
            env_lights: 32,
            rsm_size: 128,
            env_vpl_directions: 8,
            exposure: 1.0,
            vpl_clamp_distance: 0.05,
            ism_size: 128,
            ism_points: 1024,
            ism_splatting: ism::IsmSplatting::default(),
            cm: CmParams::default(),
            composition: Composition::Additive,
            interleave: 1,
            temporal: indirect::TemporalParams::default(),
            camera_artifacts: None,
            bounces: 3,
            bounce_candidates: 4096,
            bounce_cone_degrees: 5.0,
            specular: specular::SpecularParams::default(),
        }
    }
}

/// One pass that ran and its wall-clock time (submitted alone and waited for).
#[derive(Clone, Debug, Serialize)]
pub struct PassTime {
    pub pass: String,
    pub ms: f64,
    /// The GPU's own time in the pass's command buffers (timestamps before and after each),
    /// where the context's GPU timer is on (a hardware adapter with timestamp queries:
    /// [`context::GpuContext::enable_gpu_timer`]) and the pass was timed with waits; what is
    /// left of `ms` is the host's work and waiting.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_ms: Option<f64>,
}

impl PassTime {
    /// A pass's wall-clock time, without a GPU time (a pass on the CPU, or one not timed by
    /// the GPU's timestamps).
    pub fn new(pass: impl Into<String>, ms: f64) -> PassTime {
        PassTime { pass: pass.into(), ms, gpu_ms: None }
    }
}

/// A GPU frame's images and report.
pub struct GpuRender {
    /// The composite, display-encoded like the photograph.
    pub composite: Image,
    /// Linear L_rv and L_r.
    pub l_rv: Image,
    pub l_r: Image,
    /// 1 where the camera sees a virtual object (from the G-buffer).
    pub virtual_mask: Mask,
    /// Per pixel, from the G-buffer: [`crate::surface::NOTHING`], [`crate::surface::REAL`]
    /// or [`crate::surface::VIRTUAL`].
    pub flags: Vec<u32>,
    /// The VPLs the frame used.
    pub vpls: Vec<vpl::GpuVpl>,
    pub report: GpuReport,
}

impl GpuRender {
    /// Writes the frame's buffers into `dir`: photo.png (the `photo` it was composed over),
    /// composite.png, l_rv.exr, l_r.exr, virtual_mask.png, and report.json with the report and
    /// the fields of `extra` (an object).
    pub fn write_buffers(&self, dir: &std::path::Path, photo: &Image, extra: serde_json::Value) -> Result<()> {
        crate::image::create_buffers_dir(dir)?;
        photo.save_png(&dir.join("photo.png"))?;
        self.composite.save_png(&dir.join("composite.png"))?;
        self.l_rv.save_exr(&dir.join("l_rv.exr"))?;
        self.l_r.save_exr(&dir.join("l_r.exr"))?;
        self.virtual_mask.save_png(&dir.join("virtual_mask.png"))?;
        let mut report = serde_json::json!({ "gpu": self.report });
        if let (Some(report), serde_json::Value::Object(extra)) = (report.as_object_mut(), extra) {
            report.extend(extra);
        }
        crate::image::save_json(&dir.join("report.json"), &report)
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct GpuReport {
    pub adapter: String,
    pub scene: String,
    pub condition: GiLevel,
    pub width: u32,
    pub height: u32,
    pub vpls: usize,
    pub params: DirParams,
    pub passes: Vec<PassTime>,
    /// Sum of the pass times.
    pub ms: f64,
    /// What the colour mapping estimated, and any fallback it took.
    pub cm: CmReport,
    /// What the ca pass saw (None when it did not run).
    pub camera_artifacts: Option<crate::ca::CaReport>,
    /// The multiple-bounce light sources that ran (empty with one bounce).
    pub bounces: Vec<bounce::BounceReport>,
    /// What the passes of mirrors and glass did (None in a scene without them: not run).
    pub specular: Option<specular::SpecularReport>,
    /// Whether the indirect light was smoothed against a previous frame (5.11–5.15; a live
    /// frame after another of the same size).
    pub temporal_smoothing: bool,
    /// The GPU buffers and textures the frame took from the pool: made anew or reused from an
    /// earlier frame ([`pool`]); with other frames on the same device at the same time, theirs too.
    pub memory: pool::PoolStats,
    /// The frame's structure as the context counted it: submissions, host waits, bytes read
    /// back and uploaded, resources made anew, host time ([`context::FrameCounters`]).
    pub counters: context::FrameCounters,
}

/// What live rendering carries from frame to frame: the colour mapping's smoothing and the
/// indirect light's temporal smoothing (5.2.9). A fresh state has no history.
#[derive(Default)]
pub struct LiveState {
    pub cm: CmState,
    pub temporal: Option<indirect::TemporalState>,
}

/// A live frame that is only shown ([`DirRenderer::render_display`]).
pub struct DisplayFrame {
    /// The composite, display-encoded like the photograph, in 8 bits a channel.
    pub composite: crate::image::Rgba8,
    pub report: GpuReport,
}

/// What a frame keeps from one frame to the next and reads back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Frame {
    /// A stimulus: no history, every buffer read back.
    Stimulus,
    /// A live frame: temporal smoothing against the state, every buffer read back.
    Live,
    /// A live frame only shown: the composite read back, not L_rv and L_r.
    Display,
}

/// The device and the compiled pipelines, reusable across frames and scenes.
pub struct DirRenderer {
    pub ctx: GpuContext,
    raster: Raster,
    shade: Shade,
    ism: ism::Ism,
    cm: cm::CmPasses,
    compose: compose::Compose,
    indirect: indirect::IndirectPass,
    pub(crate) artifacts: ca::Artifacts,
    bounce: bounce::Bounce,
    /// A live frame's further bounces and budget split on the GPU.
    bounce_chain: bounce_chain::BounceChain,
    specular: specular::Specular,
    /// Rohmer et al.'s representation builds, compiled when a coherent stimulus first asks.
    representation: std::sync::OnceLock<representation::RepresentationBuilder>,
    /// Rohmer et al.'s frame (queries and shading), compiled when a coherent frame first asks.
    coherent: std::sync::OnceLock<coherent::CoherentPasses>,
    /// VPL creation on the GPU from the RSMs where they were rendered.
    vpl_sampler: vpl::VplSampler,
    /// Read the RSMs back and create the VPLs on the CPU instead (the reference; for tests, and
    /// by itself when the candidates exceed one storage buffer).
    cpu_vpls: std::sync::atomic::AtomicBool,
    /// The last scene's mesh, kept while its geometry stays ([`mesh::MeshCache`]).
    meshes: mesh::MeshCache,
    /// Its buffers and the bounces' triangles, kept with it ([`mesh::PerMesh`]).
    scene_buffers: mesh::PerMesh<SceneBuffers>,
    bounce_scenes: mesh::PerMesh<Option<bounce::BounceScene>>,
    ism_clouds: mesh::PerMesh<ism::IsmClouds>,
}

/// One light's rendered RSMs: the light, a spot's tan of half its field of view, and the
/// real-only and virtual-only maps (surfaces and distance).
type RenderedRsms<'a> =
    (vpl::RsmLight<'a>, f32, ((SurfaceTargets, Arc<wgpu::Texture>), Option<(SurfaceTargets, Arc<wgpu::Texture>)>));

/// A frame's first-bounce candidate VPLs, drawn from once, or twice with further bounces (the
/// pilot and the bounce's share of the budget).
pub(crate) enum FirstBounce {
    Gpu(vpl::GpuCandidates),
    Cpu(vpl::Candidates),
}

impl FirstBounce {
    fn draw(&self, renderer: &DirRenderer, count: u32) -> Vec<vpl::GpuVpl> {
        match self {
            FirstBounce::Gpu(candidates) => renderer.vpl_sampler.draw(&renderer.ctx, candidates, count),
            FirstBounce::Cpu(candidates) => candidates.draw(count),
        }
    }
}

/// The camera's view-projection: the pinhole intrinsics of [`crate::camera::Camera`] as a
/// clip-space matrix (depth 0..1), so that pixel centres match the CPU tracer's.
pub fn camera_matrix(camera: &crate::camera::Camera, near: f32, far: f32) -> Mat4 {
    let (w, h) = (camera.width as f32, camera.height as f32);
    let rows = [
        [2.0 * camera.fx / w, 0.0, 1.0 - 2.0 * camera.cx / w, 0.0],
        [0.0, 2.0 * camera.fy / h, -(1.0 - 2.0 * camera.cy / h), 0.0],
        [0.0, 0.0, far / (near - far), near * far / (near - far)],
        [0.0, 0.0, -1.0, 0.0],
    ];
    let projection = Mat4::from_cols_array_2d(&rows).transpose();
    let view = Mat4::from_mat3(camera.rotation.transpose()) * Mat4::from_translation(-camera.position);
    projection * view
}

/// A spot light's perspective view over the scene bounds; returns (matrix, tan of half the fov).
fn spot_view(position: Vec3, direction: Vec3, cos_outer: f32, centre: Vec3, radius: f32) -> (Mat4, f32) {
    let half = (cos_outer.clamp(-1.0, 1.0).acos() * 1.05 + 0.01).min(80f32.to_radians());
    let up = up_hint(direction);
    let far = (position - centre).length() + radius * 1.5;
    let near = (far * 1e-4).max(1e-4);
    (perspective(1.0 / half.tan(), near, far) * look_at(position, direction, up), half.tan())
}

/// A square perspective projection looking down −z with depth 0..1 between `near` and `far`;
/// `f` is 1 / tan of half the field of view.
fn perspective(f: f32, near: f32, far: f32) -> Mat4 {
    Mat4::from_cols_array_2d(&[
        [f, 0.0, 0.0, 0.0],
        [0.0, f, 0.0, 0.0],
        [0.0, 0.0, far / (near - far), near * far / (near - far)],
        [0.0, 0.0, -1.0, 0.0],
    ])
    .transpose()
}

/// Van der Corput radical inverse in base 2 (the second coordinate of a Hammersley set).
fn radical_inverse(mut bits: u32) -> f32 {
    bits = bits.reverse_bits();
    bits as f32 * (1.0 / 4_294_967_296.0)
}

/// An orthographic view along `forward` covering a sphere of `radius` around `centre` across,
/// and `depth` in front of and behind it along the light.
fn directional_view(forward: Vec3, centre: Vec3, radius: f32, depth: f32) -> (Mat4, Vec3) {
    let up = up_hint(forward);
    let eye = centre - forward * depth;
    let (near, far) = (0.0, 2.0 * depth);
    let projection = Mat4::from_cols_array_2d(&[
        [1.0 / radius, 0.0, 0.0, 0.0],
        [0.0, 1.0 / radius, 0.0, 0.0],
        [0.0, 0.0, -1.0 / (far - near), -near / (far - near)],
        [0.0, 0.0, 0.0, 1.0],
    ])
    .transpose();
    (projection * look_at(eye, forward, up), eye)
}

/// The up vector a view along `forward` is built with ([`look_at`]): +y, or +x when looking
/// along the y axis.
fn up_hint(forward: Vec3) -> Vec3 {
    if forward.cross(Vec3::Y).length() < 1e-3 { Vec3::X } else { Vec3::Y }
}

/// World to a right-handed view space looking down −z along `direction`.
fn look_at(eye: Vec3, direction: Vec3, up: Vec3) -> Mat4 {
    let f = direction.normalize();
    let s = f.cross(up).normalize();
    let u = s.cross(f);
    Mat4::from_cols_array_2d(&[
        [s.x, s.y, s.z, -s.dot(eye)],
        [u.x, u.y, u.z, -u.dot(eye)],
        [-f.x, -f.y, -f.z, f.dot(eye)],
        [0.0, 0.0, 0.0, 1.0],
    ])
    .transpose()
}

/// Runs the pass `f` and, while the context times passes ([`GpuContext::set_pass_waits`]),
/// waits for the device and records the pass's wall-clock time under `name`.
fn timed<T>(ctx: &GpuContext, passes: &mut Vec<PassTime>, name: String, f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = f();
    if ctx.pass_waits() {
        ctx.wait();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        passes.push(PassTime { pass: name, ms, gpu_ms: ctx.take_gpu_ms() });
    }
    out
}

/// An image of RGBA texels (alpha dropped), converted on all threads (a 1024×768 frame's three
/// images took 10–23 ms on one).
fn to_image(width: u32, height: u32, texels: &[f32]) -> Image {
    use rayon::prelude::*;
    Image { width, height, pixels: texels.par_chunks_exact(4).map(|c| Vec3::new(c[0], c[1], c[2])).collect() }
}

impl DirRenderer {
    /// Opens the GPU (see [`GpuContext::new`]) and compiles the shaders.
    pub fn new() -> Result<DirRenderer> {
        Ok(DirRenderer::with_context(GpuContext::new()?))
    }

    pub fn with_context(ctx: GpuContext) -> DirRenderer {
        let raster = Raster::new(&ctx);
        let shade = Shade::new(&ctx);
        let ism = ism::Ism::new(&ctx);
        let cm = cm::CmPasses::new(&ctx);
        let compose = compose::Compose::new(&ctx);
        let indirect = indirect::IndirectPass::new(&ctx);
        let artifacts = ca::Artifacts::new(&ctx);
        let bounce = bounce::Bounce::new(&ctx);
        let bounce_chain = bounce_chain::BounceChain::new(&ctx);
        let specular = specular::Specular::new(&ctx);
        let vpl_sampler = vpl::VplSampler::new(&ctx);
        DirRenderer {
            ctx,
            raster,
            shade,
            ism,
            cm,
            compose,
            indirect,
            artifacts,
            bounce,
            bounce_chain,
            specular,
            representation: std::sync::OnceLock::new(),
            coherent: std::sync::OnceLock::new(),
            vpl_sampler,
            cpu_vpls: std::sync::atomic::AtomicBool::new(false),
            meshes: Default::default(),
            scene_buffers: Default::default(),
            bounce_scenes: Default::default(),
            ism_clouds: Default::default(),
        }
    }

    /// Creates the VPLs on the CPU from read-back RSMs (the reference the GPU sampler is tested
    /// against) instead of on the GPU.
    #[cfg(test)]
    pub(crate) fn set_cpu_vpls(&self, on: bool) {
        self.cpu_vpls.store(on, std::sync::atomic::Ordering::Relaxed);
    }

    /// The CPU's candidate VPLs: every RSM read back (one wait), unpacked map by map on all
    /// threads, then [`vpl::Candidates::new`].
    fn cpu_candidates(
        &self,
        ctx: &GpuContext,
        passes: &mut Vec<PassTime>,
        rendered: &[RenderedRsms],
        rsm_size: u32,
        extra: &[vpl::GpuVpl],
    ) -> vpl::Candidates {
        let maps: Vec<&(SurfaceTargets, Arc<wgpu::Texture>)> =
            rendered.iter().flat_map(|(_, _, (real, virt))| std::iter::once(real).chain(virt)).collect();
        let textures: Vec<(&wgpu::Texture, u32)> = maps
            .iter()
            .flat_map(|(t, d)| [(&*t.position, 16), (&*t.normal, 16), (&*t.albedo, 16), (&**d, 4)])
            .collect();
        let bytes =
            timed(ctx, passes, format!("RSMs read back ({} maps)", maps.len()), || ctx.read_textures(&textures));
        let start = Instant::now();
        // each map's texels on its own thread (in map order)
        let texels: Vec<Vec<vpl::RsmTexel>> = {
            use rayon::prelude::*;
            bytes
                .par_chunks_exact(4)
                .map(|b| {
                    let quads = |bytes: &[u8]| -> Vec<[f32; 4]> { bytemuck::pod_collect_to_vec(bytes) };
                    let (position, normal, albedo) = (quads(&b[0]), quads(&b[1]), quads(&b[2]));
                    let dist: Vec<f32> = bytemuck::pod_collect_to_vec(&b[3]);
                    (0..position.len()).map(|k| (position[k], normal[k], albedo[k], dist[k])).collect::<Vec<_>>()
                })
                .collect()
        };
        let mut texels = texels.into_iter();
        let mut rsms = Vec::new();
        for (light, tan_half_fov, (_, virt)) in rendered.iter() {
            let real = texels.next().expect("a real map per light");
            let virt = match virt {
                Some(_) => texels.next().expect("a virtual map per light"),
                None => vec![([0.0; 4], [0.0; 4], [0.0; 4], 1e30); real.len()],
            };
            rsms.push((*light, vpl::RsmTexels { size: rsm_size, tan_half_fov: *tan_half_fov, real, virt }));
        }
        let candidates = vpl::Candidates::new(&rsms, extra);
        passes.push(PassTime::new("VPL candidates (CPU)", start.elapsed().as_secs_f64() * 1e3));
        candidates
    }

    /// The compute passes that build Rohmer et al.'s representations on this GPU
    /// ([`representation`]), compiled on first use.
    pub fn representation_builder(&self) -> &representation::RepresentationBuilder {
        self.representation.get_or_init(|| representation::RepresentationBuilder::new(&self.ctx))
    }

    /// The compute passes of Rohmer et al.'s frame on this GPU ([`coherent`]), compiled on
    /// first use.
    pub fn coherent_passes(&self) -> &coherent::CoherentPasses {
        self.coherent.get_or_init(|| coherent::CoherentPasses::new(&self.ctx))
    }

    /// Renders `scene` under `params.condition` over `photo` (the camera image of the real
    /// scene, display-encoded, at the scene's resolution), as a single frame without colour
    /// mapping history.
    pub fn render(&self, scene: &Scene, photo: &Image, params: &DirParams) -> Result<GpuRender> {
        self.render_frame(scene, photo, params, None, &mut LiveState::default(), Frame::Stimulus)
    }

    /// [`DirRenderer::render`] for live use: `state` carries the colour mapping's smoothing
    /// (sample-based, eq. 4.27), Rohmer's previous C_t and the indirect light of the previous
    /// frame for temporal smoothing (5.11–5.15, weights `params.temporal`) from frame to frame.
    pub fn render_with_state(
        &self,
        scene: &Scene,
        photo: &Image,
        params: &DirParams,
        state: &mut LiveState,
    ) -> Result<GpuRender> {
        self.render_frame(scene, photo, params, None, state, Frame::Live)
    }

    /// [`DirRenderer::render_with_state`] for a live frame that is only shown (the lab's): the
    /// composite is the only image read back, packed to 8-bit RGBA on the GPU (3.1 MB at
    /// 1024×768, not 38 MB of floats with L_rv and L_r) and handed on as those bytes; with the
    /// ca factor, which needs the virtual objects' mask from the radiance buffers and works on
    /// the composite in floats, the floats are read back and quantised on the host. Either way
    /// the bytes are those of `render_with_state`'s composite quantised ([`crate::image::Rgba8::from_image`]).
    ///
    /// The photograph comes shared: its kept buffer holds the `Arc`, and a frame given the same
    /// one uploads and compares nothing of it (a new `Arc`, or one changed through
    /// `Arc::make_mut`, is compared bit for bit and uploaded when it differs).
    pub fn render_display(
        &self,
        scene: &Scene,
        photo: &Arc<Image>,
        params: &DirParams,
        state: &mut LiveState,
    ) -> Result<DisplayFrame> {
        let shared = frame::PhotoRef::Shared(photo);
        let (frame, shown) = self.render_frame_shown(scene, shared, params, None, state, Frame::Display)?;
        let composite = shown.unwrap_or_else(|| crate::image::Rgba8::from_image(&frame.composite));
        Ok(DisplayFrame { composite, report: frame.report })
    }
}

#[cfg(test)]
mod invariants;

#[cfg(test)]
mod cm_tests;

#[cfg(test)]
mod tests;

#[cfg(test)]
mod specular_tests;

#[cfg(test)]
mod frame_tests;
