//! A scene rendered by a coherent method from start to end, as `mrstudy render --gi-method`
//! does: the reference render (the photograph and the ground truth, one path-tracing run), the
//! simulated capture of the real scene, the representation, the frame, and the frame through
//! the scene's camera (the same sensor and noise as the photograph) with its errors against the
//! ground truth; and a study's coherent stimulus ([`render_stimulus`]): the same capture,
//! representation and frame, shown the way a DIR stimulus is (the `cm` factor's colour mapping
//! of the two radiance buffers, the differential composition over the photograph, the `ca`
//! factor's camera artifacts).

use super::query::Representation;
use super::{Coherent, CoherentFrame, CoherentParams, build_representation, ms_since};
use crate::capture::hashgrid::EnvironmentSample;
use crate::capture::{CaptureParams, CaptureReport, capture};
use crate::coherent::solid::SolidVolume;
use crate::coherent::voxel::VoxelVolume;
use crate::error::Result;
use crate::gpu::DirRenderer;
use crate::gpu::PassTime;
use crate::image::Image;
use crate::light::Environment;
use crate::metrics::{StimulusErrors, stimulus_errors};
use crate::pathtracer::{Subset, World};
use crate::reference::{ReferenceOutput, ReferenceParams, render_reference};
use crate::scene::Scene;
use glam::Vec3;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Everything one coherent render of a scene made.
pub struct SceneRender {
    pub reference: ReferenceOutput,
    pub capture: CaptureReport,
    /// The build passes (light probe, impostor or voxel volume) before the frame's passes.
    pub build: Vec<PassTime>,
    pub frame: CoherentFrame,
    /// The composite through the scene's camera (display-encoded).
    pub stimulus: Image,
    pub errors: StimulusErrors,
}

/// Renders `scene` by `params`: the reference path tracer at `reference` (its photograph is the
/// frame's input, its ground truth the errors' reference), a capture from 4 poses, then the
/// frame; with `gpu`, the representation is built there and the frame runs there where it can
/// ([`Coherent::render_preferring_gpu`]). `progress(done, total)` counts the
/// reference render's samples per pixel, then the capture's poses and the frame's passes.
pub fn render_scene(
    scene: &Scene,
    params: &CoherentParams,
    reference: &ReferenceParams,
    gpu: Option<&DirRenderer>,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<SceneRender> {
    let total = 2 * reference.spp + POSES + 5;
    let reference_out = render_reference(scene, reference, &|done, _| progress(done, total))?;
    let captured = CapturedScene::new(scene, params.seed, &|done, _| progress(2 * reference.spp + done, total));
    let (build, frame, stimulus, errors) = render_over(scene, &captured, params, &reference_out, gpu, &|done, _| {
        progress(2 * reference.spp + POSES + done, total)
    })?;
    Ok(SceneRender { reference: reference_out, capture: captured.report, build, frame, stimulus, errors })
}

/// Capture poses of a coherent render.
pub const POSES: u32 = 4;

/// The real scene as the simulated depth sensor captured it from [`POSES`] poses: made once per
/// scene and seed, shared by every method and quality rendered from it.
pub struct CapturedScene {
    real: World,
    samples: Vec<EnvironmentSample>,
    /// The hash grid's cell (the samples' footprint).
    cell: f32,
    pub report: CaptureReport,
    /// The capture's time.
    pub ms: f64,
}

/// Where a capture's representation is built and its frame runs.
#[derive(Clone, Copy)]
enum Devices<'a> {
    /// Both on the CPU (no adapter opened).
    Cpu,
    /// The representation on this GPU, the frame on the CPU (a study's stimuli keep the CPU's
    /// frame, so their bytes do not depend on the adapter).
    BuildOnGpu(&'a DirRenderer),
    /// Both on this GPU.
    Gpu(&'a DirRenderer),
}

impl CapturedScene {
    /// Captures `scene`'s real world with the capture's random numbers from `seed`;
    /// `progress(done, total)` counts the poses.
    pub fn new(scene: &Scene, seed: u64, progress: &(dyn Fn(u32, u32) + Sync)) -> CapturedScene {
        let real = World::new(scene, Subset::RealOnly);
        let mut params = CaptureParams::for_scene(scene, &real, POSES as usize);
        params.seed = seed;
        let start = Instant::now();
        let cap = capture(&real, &params, |done, _| progress(done as u32, POSES));
        let ms = ms_since(start);
        let samples = cap.grid.samples().copied().collect();
        CapturedScene { real, samples, cell: params.cell, report: cap.report, ms }
    }

    /// The environment samples the capture kept.
    pub fn samples(&self) -> &[EnvironmentSample] {
        &self.samples
    }

    /// The hash grid's cell: the samples' footprint.
    pub fn cell(&self) -> f32 {
        self.cell
    }

    /// The representation and the frame of `params` over `linear` (the photograph's linear
    /// radiance), with the build passes — the capture's first — and the frame, each where
    /// `devices` says (a frame on the GPU: [`Coherent::render_preferring_gpu`]). `progress(done, total)` counts the frame's passes.
    fn render(
        &self,
        scene: &Scene,
        params: &CoherentParams,
        linear: &Image,
        devices: Devices<'_>,
        progress: &(dyn Fn(u32, u32) + Sync),
    ) -> Result<(Vec<PassTime>, CoherentFrame)> {
        let mut build = vec![PassTime::new(format!("capture ({POSES} poses)"), self.ms)];
        let gpu = match devices {
            Devices::Cpu => None,
            Devices::BuildOnGpu(gpu) | Devices::Gpu(gpu) => Some(gpu),
        };
        let (rep, passes) = self.representation(scene, params, gpu);
        build.extend(passes);
        let frame = match devices {
            Devices::Gpu(gpu) => {
                Coherent::new(scene, &self.real, &rep, *params).render_preferring_gpu(linear, Some(gpu), progress)?
            }
            _ => self.frame(scene, &rep, params, linear, progress)?,
        };
        Ok((build, frame))
    }

    /// What `params` queries, built from this capture ([`build_representation`]), with its
    /// build passes (the light probe first).
    pub fn representation(
        &self,
        scene: &Scene,
        params: &CoherentParams,
        gpu: Option<&DirRenderer>,
    ) -> (Representation, Vec<PassTime>) {
        build_representation(scene, &self.real, &self.samples, self.cell, params, gpu)
    }

    /// One frame of `params` from `rep` (made by [`CapturedScene::representation`] with settings
    /// that build what `params` queries) over `linear`, the photograph's radiance.
    pub fn frame(
        &self,
        scene: &Scene,
        rep: &Representation,
        params: &CoherentParams,
        linear: &Image,
        progress: &(dyn Fn(u32, u32) + Sync),
    ) -> Result<CoherentFrame> {
        Coherent::new(scene, &self.real, rep, *params).render(linear, progress)
    }
}

/// The representation and frame of `scene` from `captured` over a reference render made
/// already (its photograph's radiance the frame's input), the composite through the scene's
/// camera, and its errors against the reference's ground truth. `progress(done, total)` counts
/// the frame's passes.
pub fn render_over(
    scene: &Scene,
    captured: &CapturedScene,
    params: &CoherentParams,
    reference: &ReferenceOutput,
    gpu: Option<&DirRenderer>,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<(Vec<PassTime>, CoherentFrame, Image, StimulusErrors)> {
    let (build, frame) =
        captured.render(scene, params, &reference.hdr_real, gpu.map_or(Devices::Cpu, Devices::Gpu), progress)?;
    let stimulus = crate::sensor::apply(&frame.composite, &scene.camera, &scene.sensor);
    let errors = stimulus_errors(&reference.ground_truth, &stimulus, &reference.affected_mask, &reference.virtual_mask);
    Ok((build, frame, stimulus, errors))
}

/// A study's coherent stimulus and what it took.
pub struct CoherentStimulus {
    /// The stimulus as shown (display-encoded).
    pub composite: Image,
    /// The capture it was rendered from (shared by the scene's coherent stimuli), its
    /// representation, frame and display, in milliseconds.
    pub ms: f64,
    pub frame: CoherentFrame,
    /// The colour mapping of the frame's buffers.
    pub cm: crate::cm::CmReport,
}

/// The photograph a coherent frame is composed over: as shown (display-encoded) and its linear
/// radiance, the same size.
#[derive(Clone, Copy, Debug)]
pub struct Photograph<'a> {
    pub display: &'a Image,
    pub linear: &'a Image,
}

/// How a coherent frame is shown as a DIR stimulus under the same factors: the colour mapping
/// `cm` (the `cm` factor's: Reinhard off, the statistics transfer on) and, when the `ca` factor
/// is on, the camera artifacts `ca` (the CPU reference of the ca chain).
#[derive(Clone, Copy, Debug)]
pub struct Presentation<'a> {
    pub cm: &'a crate::cm::CmParams,
    pub ca: Option<&'a crate::ca::CaParams>,
}

/// A stimulus of `scene` by a coherent method from `captured`, shown as a DIR stimulus is,
/// over `photo`. The frame's two radiance buffers — the real surfaces as photographed (`L_r`)
/// and with the differential added (`L_rv`), the object's radiance on it — go through the
/// colour mapping of `shown` and the differential composition over the photograph, blended by
/// the object's coverage at its edges; then the camera artifacts of `shown`, if any.
pub fn render_stimulus(
    scene: &Scene,
    captured: &CapturedScene,
    photo: Photograph,
    params: &CoherentParams,
    shown: Presentation,
    gpu: Option<&DirRenderer>,
) -> Result<CoherentStimulus> {
    let start = Instant::now();
    // a study's stimuli keep the CPU's frame (their bytes unchanged); the representation is
    // built on the GPU
    let (_, frame) =
        captured.render(scene, params, photo.linear, gpu.map_or(Devices::Cpu, Devices::BuildOnGpu), &|_, _| {})?;
    let (composite, cm) = show(scene, &frame, photo, shown, &mut crate::cm::CmState::default())?;
    Ok(CoherentStimulus { composite, ms: captured.ms + ms_since(start), frame, cm })
}

/// A coherent frame shown as a DIR stimulus is (see [`render_stimulus`]): its two radiance
/// buffers through the colour mapping of `shown` (with the mapping's history `state`, for live
/// frames), the differential composition over `photo`, the object blended by its coverage, and
/// the camera artifacts of `shown`.
fn show(
    scene: &Scene,
    frame: &CoherentFrame,
    Photograph { display: photo, linear }: Photograph,
    Presentation { cm, ca }: Presentation,
    state: &mut crate::cm::CmState,
) -> Result<(Image, crate::cm::CmReport)> {
    use crate::cm::{CmInput, Composition, compose, cpu_frame};
    use crate::surface::{NOTHING, REAL, VIRTUAL};
    let (w, h) = (photo.width, photo.height);
    if (linear.width, linear.height) != (w, h) {
        return Err(crate::error::RenderError::SizeMismatch {
            a_width: w,
            a_height: h,
            b_width: linear.width,
            b_height: linear.height,
        });
    }
    let n = (w * h) as usize;
    let l_r: Vec<Vec3> =
        (0..n).map(|k| if frame.flags[k] == VIRTUAL { Vec3::ZERO } else { linear.pixels[k].max(Vec3::ZERO) }).collect();
    let background: Vec<Vec3> =
        (0..n).map(|k| (linear.pixels[k] + frame.differential.pixels[k]).max(Vec3::ZERO)).collect();
    let l_rv: Vec<Vec3> =
        (0..n).map(|k| if frame.flags[k] == VIRTUAL { frame.object.pixels[k] } else { background[k] }).collect();
    let input = CmInput { width: w, height: h, l_rv: &l_rv, l_r: &l_r, flags: &frame.flags, photo: &photo.pixels };
    let mapped = cpu_frame(&input, cm, 1.0, Composition::Additive, state);
    let mapping = &mapped.report.mapping;
    let linear_domain = mapping.linear_domain();
    let mut composite = Image::new(w, h);
    for k in 0..n {
        let real = linear.pixels[k].max(Vec3::ZERO);
        let flag = if frame.flags[k] == NOTHING { NOTHING } else { REAL };
        let behind = compose(
            linear_domain,
            Composition::Additive,
            photo.pixels[k],
            flag,
            mapping.apply(background[k], 1.0),
            mapping.apply(real, 1.0),
        );
        let c = frame.coverage.values[k];
        composite.pixels[k] = if c > 0.0 {
            let object = mapping.apply(frame.object.pixels[k], 1.0);
            let object = if linear_domain {
                crate::cm::colour::gamma_encode(object.clamp(Vec3::ZERO, Vec3::ONE))
            } else {
                object.clamp(Vec3::ZERO, Vec3::ONE)
            };
            c * object + (1.0 - c) * behind
        } else {
            behind
        };
    }
    if let Some(ca) = ca {
        composite = crate::ca::apply_cpu(&composite, photo, &frame.coverage, &scene.camera, ca)?.0;
    }
    Ok((composite, mapped.report))
}

/// A coherent method run live, frame after frame, as a lab task study runs it: the real scene's
/// capture, its photograph and the light probe are made once; each frame builds what its method
/// queries around the virtual object where it now is — the distance impostors follow the
/// object, as the paper rebuilds them every frame; the scene voxel volume does not depend on
/// the object and is built once per size; the object's solid volume is built once and moved
/// with it — then renders the frame on the CPU and shows it as a
/// stimulus is shown ([`render_stimulus`]).
pub struct LiveCoherent {
    captured: CapturedScene,
    photo: Image,
    linear: Image,
    probe: Arc<Environment>,
    /// Scene voxel volumes built so far, by size.
    voxels: Mutex<Vec<Arc<VoxelVolume>>>,
    /// The objects' solid volumes built so far, by size, with the objects' centres then: a
    /// later frame moves them with the objects instead of rebuilding them.
    solids: Mutex<Vec<(u32, Vec<Vec3>, Vec<SolidVolume>)>>,
}

/// A live coherent frame: the composite (display-encoded) and the passes it took.
pub struct LiveFrame {
    pub composite: Image,
    pub passes: Vec<PassTime>,
}

impl LiveCoherent {
    /// Captures `scene`'s real world (random numbers from `seed`) and path traces the light
    /// probe at its virtual objects' centre; `photo` is the photograph (display-encoded) and
    /// `linear` its linear radiance, both of the scene's camera size.
    pub fn new(scene: &Scene, photo: Image, linear: Image, seed: u64) -> Result<LiveCoherent> {
        let (w, h) = (scene.camera.width, scene.camera.height);
        for image in [&photo, &linear] {
            if (image.width, image.height) != (w, h) {
                return Err(crate::error::RenderError::SizeMismatch {
                    a_width: w,
                    a_height: h,
                    b_width: image.width,
                    b_height: image.height,
                });
            }
        }
        let captured = CapturedScene::new(scene, seed, &|_, _| {});
        let centre = super::virtual_bounds(scene).map_or(scene.camera.position, |b| b.centroid());
        let probe = super::light_probe(&captured.real, centre, super::PROBE_WIDTH, super::PROBE_PATHS, seed);
        Ok(LiveCoherent {
            captured,
            photo,
            linear,
            probe: Arc::new(probe),
            voxels: Mutex::new(Vec::new()),
            solids: Mutex::new(Vec::new()),
        })
    }

    /// One frame of `scene` — the scene this was made for, its virtual objects moved as they
    /// now stand (its real part unchanged) — by `params`, shown with the colour mapping `cm`
    /// and its history `state` (a trial starts with a fresh one). With `gpu`, the
    /// representation is built there.
    pub fn frame(
        &self,
        scene: &Scene,
        params: &CoherentParams,
        cm: &crate::cm::CmParams,
        state: &mut crate::cm::CmState,
        gpu: Option<&DirRenderer>,
    ) -> Result<LiveFrame> {
        let kept = self
            .voxels
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .iter()
            .find(|v| v.res == params.settings.scene_voxels)
            .cloned();
        let size = params.settings.object_voxels;
        let centres: Vec<Vec3> = super::virtual_object_bounds(scene).iter().map(|b| b.centroid()).collect();
        let placed = self
            .solids
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .iter()
            .find(|(n, then, _)| *n == size && then.len() == centres.len())
            .map(|(_, then, volumes)| {
                volumes.iter().zip(then.iter().zip(&centres)).map(|(v, (then, now))| v.moved(*now - *then)).collect()
            });
        let reused = placed.is_some();
        let prebuilt = super::Prebuilt { sky: Arc::clone(&self.probe), voxels: kept.clone(), solids: placed };
        let (rep, mut passes) =
            super::build_queries(scene, &self.captured.samples, self.captured.cell, params, gpu, prebuilt);
        if let (None, Some(built)) = (kept, &rep.voxels) {
            self.voxels.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).push(Arc::clone(built));
        }
        if !reused && !rep.solids.is_empty() {
            let mut solids = self.solids.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
            solids.push((size, centres, rep.solids.clone()));
        }
        let frame = Coherent::new(scene, &self.captured.real, &rep, *params).render(&self.linear, &|_, _| {})?;
        passes.extend(frame.report.passes.iter().cloned());
        let start = Instant::now();
        let photo = Photograph { display: &self.photo, linear: &self.linear };
        let (composite, _) = show(scene, &frame, photo, Presentation { cm, ca: None }, state)?;
        passes.push(PassTime::new("colour mapping and display", ms_since(start)));
        Ok(LiveFrame { composite, passes })
    }
}

/// [`render_scene`], saved to `out` (`.png` the camera's output, `.exr` the linear composite)
/// and, with `buffers`, every buffer: composite.png, composite.exr, differential.exr,
/// albedo.png, coverage.png, photo.png, ground_truth.png and report.json. Returns the lines to
/// show the user.
pub fn render_to_file(
    scene: &Scene,
    params: &CoherentParams,
    reference: &ReferenceParams,
    out: &std::path::Path,
    buffers: Option<&std::path::Path>,
    gpu: Option<&DirRenderer>,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<Vec<String>> {
    let result = render_scene(scene, params, reference, gpu, progress)?;
    crate::image::save_by_extension(out, &result.frame.composite, &result.stimulus)?;
    let report = &result.frame.report;
    if let Some(dir) = buffers {
        crate::image::create_buffers_dir(dir)?;
        result.stimulus.save_png(&dir.join("composite.png"))?;
        result.frame.composite.save_exr(&dir.join("composite.exr"))?;
        result.frame.differential.save_exr(&dir.join("differential.exr"))?;
        result.frame.albedo.linear_to_srgb().save_png(&dir.join("albedo.png"))?;
        result.frame.coverage.save_png(&dir.join("coverage.png"))?;
        result.reference.photo.save_png(&dir.join("photo.png"))?;
        result.reference.ground_truth.save_png(&dir.join("ground_truth.png"))?;
        let json = serde_json::json!({
            "scene": scene.name,
            "params": params,
            "capture": result.capture,
            "build": result.build,
            "frame": report,
            "errors": result.errors,
        });
        crate::image::save_json(&dir.join("report.json"), &json)?;
    }
    let mut lines = vec![format!(
        "capture: {} environment samples from {} poses (position error median {:.2} mm)",
        result.capture.stored, result.capture.poses, result.capture.position_error_mm.median
    )];
    for pass in result.build.iter().chain(&report.passes) {
        lines.push(format!("  {:<44} {:>10.1} ms", pass.pass, pass.ms));
    }
    lines.push(format!(
        "  object {} pixels; background {} pixels computed, {} left as photographed (no direction met the object's box); {} directions traced, {} scaled (eq. 9)",
        report.object_pixels, report.background_pixels, report.background_skipped, report.rays_traced, report.rays_scaled
    ));
    if report.albedo_clamped + report.albedo_unlit > 0 {
        lines.push(format!(
            "  albedo estimates above 1 (clamped): {}; pixels no light reached (albedo 0): {}",
            report.albedo_clamped, report.albedo_unlit
        ));
    }
    for skipped in &report.skipped {
        lines.push(format!("  skipped: {skipped}"));
    }
    if let Some(c) = &report.counters {
        lines.push(format!(
            "  frame on the GPU: {} submits, {} host waits, {:.3} MB read back, {:.3} MB uploaded, {} allocations, {:.1} ms on the host in the GPU pass",
            c.submits,
            c.host_waits,
            c.readback_bytes as f64 / 1e6,
            c.upload_bytes as f64 / 1e6,
            c.allocations,
            c.cpu_ms
        ));
    }
    for region in ["affected", "virtual"] {
        let value = |metric: &str| result.errors.value(metric, region);
        if let (Some(flip), Some(rmse)) = (value("flip_mean"), value("rmse_display")) {
            lines
                .push(format!("  against the ground truth, {region} region: FLIP {flip:.4}, RMSE {rmse:.4} (display)"));
        }
    }
    for skipped in &result.errors.skipped {
        lines.push(format!("  errors skipped: {skipped}"));
    }
    lines.push(format!(
        "wrote {} (gi {} at quality {}): reference {:.1} s on the CPU, capture {:.0} ms, representation {:.0} ms, frame {:.0} ms",
        out.display(),
        params.method.name(),
        params.quality.name(),
        result.reference.stats.seconds,
        result.build[0].ms,
        result.build[1..].iter().map(|p| p.ms).sum::<f64>(),
        report.total_ms()
    ));
    Ok(lines)
}
