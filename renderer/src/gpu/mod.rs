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

pub mod bounce;
pub mod ca;
pub mod cm;
pub mod compose;
pub mod context;
pub mod indirect;
pub mod ism;
pub mod mesh;
pub mod pool;
pub mod raster;
pub mod representation;
pub mod shade;
pub mod specular;
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
    /// The composite, display-encoded like the photograph.
    pub composite: Image,
    pub report: GpuReport,
}

/// What a frame keeps from one frame to the next and reads back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Frame {
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
    specular: specular::Specular,
    /// Rohmer et al.'s representation builds, compiled when a coherent stimulus first asks.
    representation: std::sync::OnceLock<representation::RepresentationBuilder>,
    /// VPL creation on the GPU from the RSMs where they were rendered.
    vpl_sampler: vpl::VplSampler,
    /// Read the RSMs back and create the VPLs on the CPU instead (the reference; for tests, and
    /// by itself when the candidates exceed one storage buffer).
    cpu_vpls: std::sync::atomic::AtomicBool,
}

/// One light's rendered RSMs: the light, a spot's tan of half its field of view, and the
/// real-only and virtual-only maps (surfaces and distance).
type RenderedRsms<'a> =
    (vpl::RsmLight<'a>, f32, ((SurfaceTargets, Arc<wgpu::Texture>), Option<(SurfaceTargets, Arc<wgpu::Texture>)>));

/// A frame's first-bounce candidate VPLs, drawn from once, or twice with further bounces (the
/// pilot and the bounce's share of the budget).
enum FirstBounce {
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
            specular,
            representation: std::sync::OnceLock::new(),
            vpl_sampler,
            cpu_vpls: std::sync::atomic::AtomicBool::new(false),
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
    /// composite is the only image read back (12 MB at 1024×768, not 38 MB with L_rv and L_r),
    /// with the radiance buffers only where the ca factor needs the virtual objects' mask. The
    /// composite equals `render_with_state`'s bit for bit.
    pub fn render_display(
        &self,
        scene: &Scene,
        photo: &Image,
        params: &DirParams,
        state: &mut LiveState,
    ) -> Result<DisplayFrame> {
        let frame = self.render_frame(scene, photo, params, None, state, Frame::Display)?;
        Ok(DisplayFrame { composite: frame.composite, report: frame.report })
    }

    /// [`DirRenderer::render`], with the VPLs given instead of created (tests of eqs. 5.6–5.7),
    /// temporal smoothing against `state` in live frames, and the read-back `mode` asks for.
    fn render_frame(
        &self,
        scene: &Scene,
        photo: &Image,
        params: &DirParams,
        given_vpls: Option<&[vpl::GpuVpl]>,
        state: &mut LiveState,
        mode: Frame,
    ) -> Result<GpuRender> {
        let temporal = mode != Frame::Stimulus;
        let ctx = &self.ctx;
        let (width, height) = (scene.camera.width, scene.camera.height);
        if photo.width != width || photo.height != height {
            return Err(RenderError::SizeMismatch {
                a_width: width,
                a_height: height,
                b_width: photo.width,
                b_height: photo.height,
            });
        }
        ctx.begin_frame();
        let mut passes = Vec::new();
        let start = Instant::now();
        let mesh = mesh::build(scene);
        passes.push(PassTime::new("scene mesh (CPU)", start.elapsed().as_secs_f64() * 1e3));
        let buffers = timed(ctx, &mut passes, "upload scene".into(), || SceneBuffers::new(ctx, &mesh));
        let has_virtual = mesh.virtual_count() > 0;
        let virtual_maps = params.condition != GiLevel::None && has_virtual;

        // 1. shadow maps: layer 2i real-only, 2i+1 virtual-only
        let size = params.shadow_map_size.max(16);
        // the environment as directional lights: Hammersley points through the map's importance
        // sampler, each carrying E = L / (N · pdf); they are real (r(pl) = 1)
        let mut env_dirs = Vec::new();
        if let Some(env) = scene.environment.as_ref().filter(|_| params.env_lights > 0) {
            let n = params.env_lights;
            for k in 0..n {
                if let Some((dir, radiance, pdf)) = env.sample((k as f32 + 0.5) / n as f32, radical_inverse(k))
                    && pdf > 0.0
                    && radiance.max_element() > 0.0
                {
                    env_dirs.push((-dir, radiance / (n as f32 * pdf)));
                }
            }
        }
        let n_lights = (scene.spots.len() + env_dirs.len()) as u32;
        // from the pool: every layer the shaders read is rendered with a clear below (the
        // virtual layers are read only where they are drawn: `virtual_maps`)
        let shadow_maps = ctx.texture(&wgpu::TextureDescriptor {
            label: Some("shadow maps"),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: (2 * n_lights).max(2) },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: raster::DISTANCE_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let layer_view = |layer: u32| {
            shadow_maps.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: layer,
                array_layer_count: Some(1),
                ..Default::default()
            })
        };
        let mut lights = Vec::new();
        let mut spot_views = Vec::new();
        for (i, spot) in scene.spots.iter().enumerate() {
            let (matrix, tan_half) =
                spot_view(spot.position, spot.direction, spot.cos_outer, mesh.bounds_centre, mesh.bounds_radius);
            let view = ViewUniform::perspective(matrix, spot.position, spot.direction);
            let layer = 2 * i as u32;
            timed(ctx, &mut passes, format!("shadow map {} real", spot.name), || {
                self.raster.shadow_map(ctx, &buffers, &view, Subset::Real, &layer_view(layer), size)
            });
            if virtual_maps {
                timed(ctx, &mut passes, format!("shadow map {} virtual", spot.name), || {
                    self.raster.shadow_map(ctx, &buffers, &view, Subset::Virtual, &layer_view(layer + 1), size)
                });
            }
            lights.push(GpuLight {
                view_proj: matrix.to_cols_array_2d(),
                position: [spot.position.x, spot.position.y, spot.position.z, if spot.real { 1.0 } else { 0.0 }],
                direction: [spot.direction.x, spot.direction.y, spot.direction.z, spot.cos_outer],
                intensity: [spot.intensity.x, spot.intensity.y, spot.intensity.z, spot.cos_inner],
                info: [0.0, layer as f32, 2.0 * tan_half / size as f32, 0.0],
            });
            spot_views.push((view, tan_half));
        }
        // the environment's maps cover where virtual objects can change anything: around them (3×
        // their bounding radius, where their shadows fall), or everything without them
        let (env_centre, env_radius) = match mesh.virtual_bounds {
            Some((c, r)) => (c, (3.0 * r).min(mesh.bounds_radius)),
            None => (mesh.bounds_centre, mesh.bounds_radius),
        };
        let env_depth = (mesh.bounds_centre - env_centre).length() + mesh.bounds_radius + 1e-3;
        if !env_dirs.is_empty() {
            let (centre, radius, depth) = (env_centre, env_radius, env_depth);
            let first = lights.len() as u32;
            timed(
                ctx,
                &mut passes,
                format!(
                    "shadow maps environment ({} directions{})",
                    env_dirs.len(),
                    if virtual_maps { ", real and virtual" } else { ", real" }
                ),
                || {
                    // every direction's maps in one submission
                    let mut maps = Vec::new();
                    for (k, (forward, irradiance)) in env_dirs.iter().enumerate() {
                        let (matrix, eye) = directional_view(*forward, centre, radius, depth);
                        let view = ViewUniform::orthographic(matrix, eye, *forward);
                        let layer = 2 * (first + k as u32);
                        maps.push((view, Subset::Real, layer_view(layer)));
                        if virtual_maps {
                            maps.push((view, Subset::Virtual, layer_view(layer + 1)));
                        }
                        lights.push(GpuLight {
                            view_proj: matrix.to_cols_array_2d(),
                            position: [eye.x, eye.y, eye.z, 1.0],
                            direction: [forward.x, forward.y, forward.z, 0.0],
                            intensity: [irradiance.x, irradiance.y, irradiance.z, 0.0],
                            info: [1.0, layer as f32, 2.0 * radius / size as f32, 0.0],
                        });
                    }
                    let maps: Vec<(ViewUniform, Subset, &wgpu::TextureView)> =
                        maps.iter().map(|(view, subset, target)| (*view, *subset, target)).collect();
                    self.raster.shadow_maps(ctx, &buffers, &maps, size);
                },
            );
        }

        // 1c. mirrors and glass (5.3): their impostors, and the photons of their caustic maps
        // (with the conditions that show virtual objects' shadows)
        let impostors = (!mesh.specular.is_empty())
            .then(|| self.specular.impostors(ctx, &self.raster, &mut passes, scene, &mesh, &buffers, &params.specular));
        let photon_maps = match &impostors {
            None => Err("no mirror or glass"),
            Some(_) if params.condition == GiLevel::None => {
                Err("the none condition: virtual objects cast neither shadows nor caustics")
            }
            Some(_) if params.specular.caustic_map_size == 0 => Err("caustic_map_size is 0 (caustics off)"),
            Some(_) if scene.spots.is_empty() => Err("no spot or point light (caustic maps are made from those)"),
            Some(impostors) => Ok(self.specular.photon_maps(
                ctx,
                &self.raster,
                &mut passes,
                scene,
                &mesh,
                &buffers,
                impostors,
                &params.specular,
            )),
        };

        // 2. RSMs and VPLs (gi only)
        let mut vpls = Vec::new();
        // the first bounce's candidate VPLs, kept for the budget split below
        let mut first_bounce: Option<FirstBounce> = None;
        if params.condition == GiLevel::Gi && n_lights > 0 && params.vpls > 0 {
            let rsm_size = params.rsm_size.max(4);
            // every RSM is rendered first, then all are read at once: by the GPU's VPL sampler, or
            // read back for the CPU's reference (one wait, not four per map)
            // (their targets from the pool: each RSM pass clears them)
            let render_rsm = |passes: &mut Vec<PassTime>, view: &ViewUniform, name: &str, subset: Subset| {
                let targets = SurfaceTargets::new(ctx, rsm_size, rsm_size, "rsm");
                let distance = raster::texture_2d(ctx, rsm_size, rsm_size, raster::DISTANCE_FORMAT, "rsm distance");
                let label = if subset == Subset::Real { "real" } else { "virtual" };
                timed(ctx, passes, format!("RSM {name} {label}"), || {
                    self.raster.rsm(ctx, &buffers, view, subset, &distance.create_view(&Default::default()), &targets)
                });
                (targets, distance)
            };
            let render_pair = |passes: &mut Vec<PassTime>, view: &ViewUniform, name: &str| {
                let real = render_rsm(passes, view, name, Subset::Real);
                let virt = has_virtual.then(|| render_rsm(passes, view, name, Subset::Virtual));
                (real, virt)
            };
            let mut rendered = Vec::new();
            for (spot, (view, tan_half)) in scene.spots.iter().zip(&spot_views) {
                rendered.push((vpl::RsmLight::Spot(spot), *tan_half, render_pair(&mut passes, view, &spot.name)));
            }
            // the environment's light bounces too: orthographic RSMs along a subset of its
            // directions (evenly spread over the importance-sampled ones), each standing for
            // n / k of them
            let k = (params.env_vpl_directions as usize).min(env_dirs.len());
            for j in 0..k {
                let (forward, irradiance) = env_dirs[j * env_dirs.len() / k];
                let (matrix, eye) = directional_view(forward, env_centre, env_radius, env_depth);
                let view = ViewUniform::orthographic(matrix, eye, forward);
                let light = vpl::RsmLight::Directional {
                    irradiance: irradiance * (env_dirs.len() as f32 / k as f32),
                    texel_area: (2.0 * env_radius / rsm_size as f32).powi(2),
                };
                rendered.push((light, 0.0, render_pair(&mut passes, &view, &format!("environment {}", j + 1))));
            }
            // the RSMs' texels on the GPU where they were rendered, with the reflected and
            // refracted VPLs where the caustics land (Figure 5.23)
            let maps: Vec<vpl::RsmMaps> = rendered
                .iter()
                .map(|(light, tan_half_fov, (real, virt))| {
                    fn textures((t, d): &(SurfaceTargets, Arc<wgpu::Texture>)) -> [&wgpu::Texture; 4] {
                        [&t.position, &t.normal, &t.albedo, d]
                    }
                    vpl::RsmMaps {
                        light: *light,
                        tan_half_fov: *tan_half_fov,
                        size: rsm_size,
                        real: textures(real),
                        virt: virt.as_ref().map(textures),
                    }
                })
                .collect();
            let caustics = photon_maps.as_ref().map_or_else(|_| Vec::new(), |maps| self.specular.caustic_sources(maps));
            let slots = vpl::VplSampler::slots(0, &caustics, &maps);
            let candidates =
                if !self.cpu_vpls.load(std::sync::atomic::Ordering::Relaxed) && vpl::VplSampler::fits(ctx, slots) {
                    let label = format!(
                        "VPL candidates and their CDF ({slots} slots: {} RSMs, {} caustic maps; GPU)",
                        rendered.iter().map(|(_, _, (_, virt))| 1 + virt.is_some() as usize).sum::<usize>(),
                        caustics.len()
                    );
                    FirstBounce::Gpu(timed(ctx, &mut passes, label, || {
                        self.vpl_sampler.candidates(ctx, &[], &caustics, &maps)
                    }))
                } else {
                    let caustic_candidates = match &photon_maps {
                        Ok(maps) => timed(ctx, &mut passes, "caustic VPL candidates (read back)".into(), || {
                            self.specular.caustic_vpls(ctx, maps)
                        }),
                        Err(_) => Vec::new(),
                    };
                    FirstBounce::Cpu(self.cpu_candidates(ctx, &mut passes, &rendered, rsm_size, &caustic_candidates))
                };
            drop(maps);
            // the RSM targets go back to the pool for the next frame (the passes reading them are
            // submitted, so the next frame's RSM passes are queued after those)
            drop(rendered);
            vpls = match &candidates {
                // a GPU pass: reported only while passes are timed
                FirstBounce::Gpu(_) => {
                    timed(ctx, &mut passes, "VPLs drawn (GPU, read back)".into(), || candidates.draw(self, params.vpls))
                }
                FirstBounce::Cpu(_) => {
                    let start = Instant::now();
                    let drawn = candidates.draw(self, params.vpls);
                    passes.push(PassTime::new("VPLs drawn (CPU)", start.elapsed().as_secs_f64() * 1e3));
                    drawn
                }
            };
            first_bounce = Some(candidates);
        }

        if let Some(given) = given_vpls {
            vpls = given.to_vec();
        }

        // 2a. the multiple-bounce light source (5.2.7), once per further bounce: a pilot over the
        // whole budget measures the bounce's flux; the budget is then split by flux over the
        // primary lights and the bounces (the third distribution mode) — the thesis takes those
        // fluxes from the previous frame, a single stimulus frame measures them first
        let mut bounce_reports: Vec<bounce::BounceReport> = Vec::new();
        if params.condition == GiLevel::Gi
            && params.bounces > 1
            && !vpls.is_empty()
            && let Some(bounce_scene) = bounce::BounceScene::new(ctx, &mesh)
        {
            let budget = params.vpls.max(1);
            let mut pilots: Vec<Vec<vpl::GpuVpl>> = Vec::new();
            let mut sources = vpls.clone();
            for b in 2..=params.bounces.min(MAX_BOUNCES) {
                let search = bounce::BounceSearch {
                    candidates: params.bounce_candidates,
                    cone_degrees: params.bounce_cone_degrees,
                    seed: b.wrapping_mul(0x9e37_79b9),
                };
                let label = format!(
                    "bounce {b} ({budget} slots, {} candidates each, cone {}°)",
                    search.candidates, search.cone_degrees
                );
                let (next, found, real_only) = timed(ctx, &mut passes, label, || {
                    self.bounce.spawn(
                        ctx,
                        &bounce_scene,
                        &mesh,
                        &scene.materials,
                        &sources,
                        budget,
                        &search,
                        mesh.bounds_radius,
                    )
                });
                bounce_reports.push(bounce::BounceReport {
                    bounce: b,
                    slots: budget,
                    found,
                    real_only,
                    flux: vpl::luminance_flux(&next) as f32,
                    vpls: 0,
                });
                if next.is_empty() {
                    break;
                }
                pilots.push(next.clone());
                sources = next;
            }
            let start = Instant::now();
            let mut fluxes = vec![vpl::luminance_flux(&vpls)];
            fluxes.extend(pilots.iter().map(|p| vpl::luminance_flux(p)));
            let counts = vpl::split_budget(budget, &fluxes);
            if given_vpls.is_none() {
                // no first-bounce candidates: no RSMs were drawn, so there is nothing to draw from
                vpls = first_bounce.as_ref().map_or_else(Vec::new, |candidates| candidates.draw(self, counts[0]));
            }
            for (k, pilot) in pilots.iter().enumerate() {
                let drawn = vpl::resample(pilot, counts[k + 1]);
                bounce_reports[k].vpls = drawn.len();
                vpls.extend(drawn);
            }
            let drawn_where = match &first_bounce {
                Some(FirstBounce::Gpu(_)) => "; the first bounce's share drawn on the GPU",
                _ => "",
            };
            passes.push(PassTime::new(
                format!("VPL budget split by flux over {} sources (CPU{drawn_where})", fluxes.len()),
                start.elapsed().as_secs_f64() * 1e3,
            ));
        }

        // 2b. imperfect shadow maps: VPL visibility from the real and the virtual point clouds
        let ism_atlas = if !vpls.is_empty() && params.ism_size > 0 && params.ism_points > 0 {
            let max_distance = 2.0 * mesh.bounds_radius * 1.01;
            Some(timed(
                ctx,
                &mut passes,
                format!(
                    "ISMs ({} VPLs, {}² each, {} points per cloud, {} splatting)",
                    vpls.len(),
                    params.ism_size,
                    params.ism_points,
                    params.ism_splatting.name()
                ),
                || {
                    self.ism.render(
                        ctx,
                        &mesh,
                        &vpls,
                        params.ism_points,
                        params.ism_size,
                        max_distance,
                        params.ism_splatting,
                    )
                },
            ))
        } else {
            None
        };

        // 3. G-buffer
        let gbuffer = SurfaceTargets::new(ctx, width, height, "g-buffer");
        let far = (scene.camera.position - mesh.bounds_centre).length() + 2.0 * mesh.bounds_radius;
        let camera_view_proj = camera_matrix(&scene.camera, (far * 1e-5).max(1e-4), far);
        let camera_view =
            ViewUniform::perspective(camera_view_proj, scene.camera.position, -scene.camera.rotation.z_axis);
        timed(ctx, &mut passes, "g-buffer".into(), || self.raster.gbuffer(ctx, &buffers, &camera_view, &gbuffer));

        // 3a. mirrors and glass (5.3): back faces, reflected and refracted rays
        let mut traced = impostors.as_ref().map(|impostors| {
            self.specular.trace(
                ctx,
                &self.raster,
                &mut passes,
                scene,
                &mesh,
                &buffers,
                impostors,
                &gbuffer,
                &camera_view,
                camera_view_proj,
                &params.specular,
            )
        });
        // 3b. the caustics' photons splatted into the camera's pixels
        let mut caustic_buffer = None;
        if let Some(traced) = traced.as_mut() {
            match &photon_maps {
                Ok(maps) => {
                    let (buffer, mut report) = timed(ctx, &mut passes, "caustic splats".into(), || {
                        self.specular.splat(ctx, maps, scene, &gbuffer, camera_view_proj)
                    });
                    report.vpls = vpls.iter().filter(|v| v.flux[3] > 0.5).count();
                    caustic_buffer = Some(buffer);
                    traced.report.caustics = Some(report);
                }
                Err(reason) => traced.report.caustics_skipped = Some(reason.to_string()),
            }
        }

        // 4. shading
        let condition_code = match params.condition {
            GiLevel::None => 0,
            GiLevel::Shadows => 1,
            GiLevel::Gi => 2,
        };
        let shade_params = ShadeParams {
            camera: [scene.camera.position.x, scene.camera.position.y, scene.camera.position.z, 0.0],
            size: [width, height, n_lights, vpls.len() as u32],
            mode: [
                if virtual_maps { condition_code } else { 0 },
                size,
                ism_atlas.as_ref().map_or(0, |a| a.tile_size),
                ism_atlas.as_ref().map_or(1, |a| a.tiles_per_row),
            ],
            tone: [
                params.interleave.max(1) as f32,
                params.vpl_clamp_distance * params.vpl_clamp_distance,
                ism_atlas.as_ref().map_or(0.0, |a| a.inv_max_distance),
                0.0,
            ],
        };
        let shading_label = if params.interleave > 1 && !vpls.is_empty() {
            format!("shading (VPLs interleaved {0}×{0})", params.interleave)
        } else {
            "shading".to_string()
        };
        let output = timed(ctx, &mut passes, shading_label, || {
            self.shade.run(
                ctx,
                &shade_params,
                &gbuffer,
                &shadow_maps,
                &lights,
                &vpls,
                &buffers,
                ism_atlas.as_ref().map(|a| &*a.buffer),
            )
        });

        // 4b. the indirect light: merge of the interleaved classes, temporal smoothing, sum
        let mut smoothed = false;
        if let Some(raw) = &output.indirect {
            let split = params.interleave.max(1);
            let inputs = indirect::IndirectInputs {
                width,
                height,
                split,
                gbuffer: &gbuffer,
                raw,
                solutions: &output.solutions,
                camera: scene.camera.position,
                view_proj: camera_view_proj,
                scene_radius: mesh.bounds_radius,
            };
            let mut steps = Vec::new();
            if split > 1 {
                steps.push(format!("merge {split}×{split}"));
            }
            if temporal {
                // the history is used only at this frame's size (`IndirectPass::run`)
                smoothed = state.temporal.as_ref().is_some_and(|t| t.fits(width, height));
                steps.push(if smoothed {
                    "temporal smoothing".to_string()
                } else {
                    "temporal smoothing (first frame)".to_string()
                });
            }
            steps.push("sum".into());
            let label = format!("indirect light ({})", steps.join(", "));
            timed(ctx, &mut passes, label, || {
                self.indirect.run(ctx, &inputs, temporal.then_some((&params.temporal, &mut state.temporal)))
            });
        }

        // 4c. the caustics into L_rv and L_r
        if let Some(caustic) = &caustic_buffer {
            timed(ctx, &mut passes, "caustics into L_rv and L_r".into(), || {
                self.specular.apply_caustics(ctx, caustic, &gbuffer, &output.solutions, width, height)
            });
        }

        // 4d. the hit G-buffers of mirrors and glass shaded by every light and VPL, then L'_rv, L'_r
        let photo_texels: Vec<[f32; 4]> = photo.pixels.iter().map(|p| [p.x, p.y, p.z, 1.0]).collect();
        let photo_buffer = timed(ctx, &mut passes, "upload photograph".into(), || {
            use wgpu::util::DeviceExt;
            ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("photo"),
                contents: bytemuck::cast_slice(&photo_texels),
                usage: wgpu::BufferUsages::STORAGE,
            })
        });
        let specular_base = match traced.as_mut() {
            Some(traced) => {
                let hit_params = ShadeParams { camera: traced.eye.extend(0.0).to_array(), ..shade_params };
                let mut shaded = Vec::new();
                for (name, targets) in [("reflected", &traced.refl), ("refracted", &traced.refr)] {
                    let label = format!("shading the {name} hits");
                    let hit = timed(ctx, &mut passes, label, || {
                        self.shade.run(
                            ctx,
                            &hit_params,
                            targets,
                            &shadow_maps,
                            &lights,
                            &vpls,
                            &buffers,
                            ism_atlas.as_ref().map(|a| &*a.buffer),
                        )
                    });
                    if let Some(raw) = &hit.indirect {
                        let inputs = indirect::IndirectInputs {
                            width,
                            height,
                            split: params.interleave.max(1),
                            gbuffer: targets,
                            raw,
                            solutions: &hit.solutions,
                            camera: traced.eye,
                            view_proj: camera_view_proj,
                            scene_radius: mesh.bounds_radius,
                        };
                        timed(ctx, &mut passes, format!("indirect light of the {name} hits"), || {
                            self.indirect.run(ctx, &inputs, None)
                        });
                    }
                    shaded.push(hit.solutions);
                }
                Some(timed(ctx, &mut passes, "mirrors and glass: L'_rv, L'_r and the photograph's part".into(), || {
                    self.specular.combine(
                        ctx,
                        traced,
                        &gbuffer,
                        &output.solutions,
                        &shaded[0],
                        &shaded[1],
                        &photo_buffer,
                        width,
                        height,
                    )
                }))
            }
            None => None,
        };

        // 5. colour mapping of both buffers (the cm factor)
        let cm_buffers = cm::CmBuffers { width, height, solutions: &output.solutions, photo: &photo_buffer };
        let (mapped, cm_report) =
            self.cm.run(ctx, &mut passes, &cm_buffers, &photo.pixels, &params.cm, params.exposure, &mut state.cm);

        // 6. composition
        let composite = timed(ctx, &mut passes, "composition".into(), || {
            self.compose.run(
                ctx,
                width,
                height,
                cm_report.mapping.linear_domain(),
                params.composition,
                &mapped,
                &photo_buffer,
                specular_base.as_deref(),
            )
        });
        // in two timed steps: the GPU's copies into staging buffers, then the host's map and copy;
        // a frame only shown needs the radiance buffers only for the ca pass's mask
        let radiance = mode != Frame::Display || params.camera_artifacts.is_some();
        let staged = timed(ctx, &mut passes, "readback: copies to staging (GPU)".into(), || {
            (ctx.stage(&composite), radiance.then(|| ctx.stage(&output.solutions)))
        });
        let (composite, solutions) = timed(ctx, &mut passes, "readback: mapped and copied to the host".into(), || {
            (ctx.read_staged_f32(&staged.0), staged.1.as_ref().map_or_else(Vec::new, |s| ctx.read_staged_f32(s)))
        });
        let start = Instant::now();
        let half = solutions.len() / 2;
        let mut composite = to_image(width, height, &composite);
        let virtual_mask = Mask {
            width,
            height,
            values: solutions[..half].chunks_exact(4).map(|c| if c[3] > 1.5 { 1.0 } else { 0.0 }).collect(),
        };
        let (l_rv, l_r, flags) = if mode == Frame::Display {
            (Image::filled(0, 0, Vec3::ZERO), Image::filled(0, 0, Vec3::ZERO), Vec::new())
        } else {
            use rayon::prelude::*;
            (
                to_image(width, height, &solutions[..half]),
                to_image(width, height, &solutions[half..]),
                solutions[..half].par_chunks_exact(4).map(|c| (c[3] + 0.5) as u32).collect(),
            )
        };
        passes.push(PassTime::new("images from the read-back buffers (CPU)", start.elapsed().as_secs_f64() * 1e3));
        // 5. camera artifacts (the ca factor) on the virtual layers of the composite
        let mut ca_report = None;
        if let Some(ca) = &params.camera_artifacts {
            let (out, report) = timed(ctx, &mut passes, "camera artifacts (ca)".into(), || {
                self.artifacts.run(ctx, &composite, photo, &virtual_mask, &scene.camera, ca)
            })?;
            composite = out;
            ca_report = Some(report);
        }
        let ms = passes.iter().map(|p| p.ms).sum();
        Ok(GpuRender {
            composite,
            l_rv,
            l_r,
            virtual_mask,
            flags,
            vpls: vpls.clone(),
            report: GpuReport {
                adapter: ctx.adapter_name(),
                scene: scene.name.clone(),
                condition: params.condition,
                width,
                height,
                vpls: vpls.len(),
                params: params.clone(),
                passes,
                ms,
                cm: cm_report,
                camera_artifacts: ca_report,
                bounces: bounce_reports,
                temporal_smoothing: smoothed,
                memory: ctx.pool_stats(),
                specular: traced.map(|traced| traced.report),
            },
        })
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
