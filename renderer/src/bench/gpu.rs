//! `bench render` (GPU): frame time and error against the path-traced ground truth in the
//! affected region, for the conditions none and shadows and for gi over a VPL sweep
//! (16 … 1024); then the multiple-bounce light source, the ISM resolution, each cm method, the
//! interleaved-sampling split, gi with and without the ca factor through the webcam and phone
//! cameras, and the thesis's setting at its resolution. Each frame is rendered twice and the
//! second timed (the first compiles the shaders on software adapters).
//!
//! Beside DIR's error, the reference path tracer's own error curve on the same frame answers
//! "how long would the path tracer need for the same error" ([`path_tracer_time_to`]).

use std::time::Instant;

use serde::Serialize;

use super::{Observer, Plot, Report, Series, ground_truth, load_sized, pass_ms};
use crate::ca::CaParams;
use crate::cm::{CmMethod, CmParams, CmReport};
use crate::error::Result;
use crate::gpu::{DirParams, DirRenderer, GiLevel, GpuRender, PassTime, bounce::BounceReport};
use crate::image::Image;
use crate::metrics;
use crate::pathtracer::{Accumulator, Subset, TraceParams, World};
use crate::reference::{ReferenceOutput, ReferenceParams, render_photo};
use crate::scene::Scene;
use crate::sensor::{self, SensorParams};

/// One row of `bench render`, by what it varies.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum GpuRow {
    PathTracer(PathTracerRow),
    Condition(ConditionRow),
    Bounces(BouncesRow),
    Ism(IsmRow),
    Cm(CmRow),
    Interleave(InterleaveRow),
    Ca(CaRow),
    Thesis(ThesisRow),
    Specular(SpecularRow),
}

/// gi in a scene with mirrors or glass at one impostor resolution and ray-search length: the
/// time of the specular passes (thesis 5.3) and the frame's error in the affected region.
#[derive(Clone, Debug, Serialize)]
pub struct SpecularRow {
    pub scene: String,
    pub condition: GiLevel,
    pub vpls: u32,
    /// Impostors (one per mirror or glass object) and the size of each cube face.
    pub impostors: usize,
    pub impostor_size: u32,
    pub search_steps: u32,
    pub secant_steps: u32,
    /// Resolution of each caustic map (5.27–5.29); 0: caustics off.
    pub caustic_map_size: u32,
    /// Impostors, back faces, ray search, shading of the hits, combination and caustics.
    pub specular_ms: f64,
    /// Of those, the caustic maps (photon G-buffers, their rays, the splats) and their
    /// addition to L_rv and L_r.
    pub caustic_ms: f64,
    pub ms: f64,
    pub rmse: f64,
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub report: crate::gpu::specular::SpecularReport,
    pub passes: Vec<PassTime>,
}

/// The path tracer's error on the frame at one sample count.
#[derive(Clone, Debug, Serialize)]
pub struct PathTracerRow {
    pub scene: String,
    /// Always `path tracer`.
    pub condition: &'static str,
    pub spp: u32,
    pub ms: f64,
    pub rmse_linear: f64,
    pub flip_camera: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
}

/// A condition (none, shadows, gi at a VPL count) against the ground truth and the path tracer.
#[derive(Clone, Debug, Serialize)]
pub struct ConditionRow {
    pub scene: String,
    pub condition: GiLevel,
    pub vpls: u32,
    pub ms: f64,
    /// Display RMSE and FLIP of the composite in the affected region.
    pub rmse: f64,
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub shadow_map_size: u32,
    pub rsm_size: u32,
    pub ism_size: u32,
    pub ism_points: u32,
    pub bounces: u32,
    /// RMSE of DIR's linear composite ([`dir_linear_composite`]) and its FLIP through the true camera.
    pub rmse_linear: f64,
    pub flip_camera: f64,
    pub path_tracer_ms_to_same_rmse: f64,
    pub path_tracer_bound: Bound,
    pub speedup_over_path_tracer: f64,
    pub path_tracer_ms_to_same_flip: f64,
    pub path_tracer_bound_flip: Bound,
    pub speedup_over_path_tracer_flip: f64,
    pub passes: Vec<PassTime>,
}

/// gi with a number of bounces and candidates per multiple-bounce slot (thesis 5.2.7).
#[derive(Clone, Debug, Serialize)]
pub struct BouncesRow {
    pub scene: String,
    pub condition: GiLevel,
    pub vpls: u32,
    pub bounces: u32,
    pub bounce_candidates: u32,
    pub bounce_ms: f64,
    pub ms: f64,
    pub rmse: f64,
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub bounce_report: Vec<BounceReport>,
    pub passes: Vec<PassTime>,
}

/// gi at 256 VPLs with one ISM resolution (0: VPLs unshadowed).
#[derive(Clone, Debug, Serialize)]
pub struct IsmRow {
    pub scene: String,
    pub condition: GiLevel,
    pub vpls: u32,
    pub ism_size: u32,
    pub ism_points: u32,
    pub ism_ms: f64,
    pub ms: f64,
    pub rmse: f64,
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub passes: Vec<PassTime>,
}

/// gi with one colour-mapping method: the time of its passes and of the composition.
#[derive(Clone, Debug, Serialize)]
pub struct CmRow {
    pub scene: String,
    pub condition: GiLevel,
    pub cm: &'static str,
    pub vpls: u32,
    pub ms: f64,
    pub cm_ms: f64,
    pub composition_ms: f64,
    pub rmse: f64,
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub passes: Vec<PassTime>,
    pub cm_report: CmReport,
}

/// gi at 256 VPLs with an n × n interleaved-sampling split.
#[derive(Clone, Debug, Serialize)]
pub struct InterleaveRow {
    pub scene: String,
    pub condition: GiLevel,
    pub vpls: u32,
    pub interleave: u32,
    pub shading_ms: f64,
    pub ms: f64,
    pub rmse: f64,
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub passes: Vec<PassTime>,
}

/// gi or gi+ca through a camera preset: the ca pass's time and the error.
#[derive(Clone, Debug, Serialize)]
pub struct CaRow {
    pub scene: String,
    /// `gi` or `gi+ca`.
    pub condition: &'static str,
    pub camera: &'static str,
    pub vpls: u32,
    pub ms: f64,
    pub ca_ms: Option<f64>,
    pub rmse: f64,
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub passes: Vec<PassTime>,
}

/// The thesis's setting at its resolution: frame time only.
#[derive(Clone, Debug, Serialize)]
pub struct ThesisRow {
    pub scene: String,
    pub condition: GiLevel,
    pub vpls: u32,
    pub ism_size: u32,
    pub ism_points: u32,
    pub interleave: u32,
    /// Always `thesis`.
    pub setting: &'static str,
    pub ms: f64,
    pub fps: f64,
    pub width: u32,
    pub height: u32,
    pub passes: Vec<PassTime>,
}

/// Runs the benchmark on `scene_name` (default: three DIR scenes, one with `quick`).
pub fn run(scene_name: Option<&str>, quick: bool, observer: &dyn Observer) -> Result<Report<GpuRow>> {
    let names: Vec<String> = match scene_name {
        Some(n) => vec![n.to_string()],
        None if quick => vec!["dir-lamp-box".to_string()],
        None => vec!["dir-lamp-box".to_string(), "dir-double-shadow".to_string(), "dir-lamp-cornell".to_string()],
    };
    let (w, h, ref_spp) = if quick { (96, 72, 64) } else { (256, 192, 512) };
    let vpl_counts: &[u32] = if quick { &[16, 64, 256] } else { &[16, 32, 64, 128, 256, 512, 1024] };
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    observer.note(&format!("adapter: {adapter}"));
    let mut rows = Vec::new();
    let mut plots = Vec::new();
    observer
        .line(&format!("{:<18} {:<8} {:>6} {:>10} {:>10} {:>8}", "scene", "cond", "vpls", "ms", "rmse(aff)", "flip"));
    let line = |name: &str, condition: &str, frame: &GpuRender, rmse: f64, flip: f64, rest: &str| {
        observer.line(&format!(
            "{:<18} {:<8} {:>6} {:>10.2} {:>10.5} {:>8.4}{rest}",
            name, condition, frame.report.vpls, frame.report.ms, rmse, flip
        ));
    };
    for name in &names {
        let scene = load_sized(name, w, h)?;
        observer.note(&format!("{name} at {w}x{h}: reference at {ref_spp} spp …"));
        let reference = ground_truth(&scene, ReferenceParams { spp: ref_spp, ..ReferenceParams::default() }, observer)?;
        let affected = &reference.affected_mask;
        // the path tracer's own error against time on this frame: the full scene (real and
        // virtual) path traced at 1, 2, 4, … spp (another seed), through the same camera
        let pt_curve = path_tracer_curve(&scene, &reference, if quick { 64 } else { 256 });
        for point in &pt_curve {
            rows.push(GpuRow::PathTracer(PathTracerRow {
                scene: name.clone(),
                condition: "path tracer",
                spp: point.spp,
                ms: point.ms,
                rmse_linear: point.rmse,
                flip_camera: point.flip,
                width: w,
                height: h,
                reference_spp: ref_spp,
            }));
        }
        let mut dir_points = Vec::new();
        // one frame rendered twice (the first compiles the shaders on software adapters), the
        // second timed, and its error against the ground truth in the affected region
        let measure = |params: &DirParams| -> Result<(GpuRender, f64, f64)> {
            renderer.render(&scene, &reference.photo, params)?;
            let frame = renderer.render(&scene, &reference.photo, params)?;
            let rmse = metrics::rmse(&reference.ground_truth, &frame.composite, Some(affected));
            let flip = metrics::flip(&reference.ground_truth, &frame.composite, Some(affected));
            Ok((frame, rmse, flip))
        };
        let mut settings: Vec<(GiLevel, u32)> = vec![(GiLevel::None, 0), (GiLevel::Shadows, 0)];
        settings.extend(vpl_counts.iter().map(|&n| (GiLevel::Gi, n)));
        let mut points_rmse = Vec::new();
        let mut points_flip = Vec::new();
        for (gi, vpls) in settings {
            let params = DirParams { condition: gi, vpls, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let ms = frame.report.ms;
            // the light transport against the path tracer's: DIR's linear composite, its RMSE
            // and its FLIP through the true camera, and the path tracer's time to the same RMSE
            let linear = dir_linear_composite(&frame, &reference.hdr_real);
            let rmse_linear = metrics::rmse(&reference.hdr_full, &linear, Some(affected));
            let flip_camera = metrics::flip(
                &reference.ground_truth,
                &sensor::apply(&linear, &scene.camera, &scene.sensor),
                Some(affected),
            );
            let (pt_ms, bound) = path_tracer_time_to(&pt_curve, rmse_linear, |p| p.rmse);
            let (pt_ms_flip, bound_flip) = path_tracer_time_to(&pt_curve, flip_camera, |p| p.flip);
            let speedup = pt_ms / ms.max(1e-9);
            let speedup_flip = pt_ms_flip / ms.max(1e-9);
            let versus = match bound {
                Bound::Exact => {
                    format!("linear RMSE {rmse_linear:.4}: the path tracer needs {pt_ms:.0} ms, {speedup:.2}×")
                }
                Bound::AtMost => format!(
                    "linear RMSE {rmse_linear:.4}: the path tracer at 1 spp ({pt_ms:.0} ms) is as close, ≤ {speedup:.2}×"
                ),
                Bound::AtLeast => format!(
                    "linear RMSE {rmse_linear:.4}: the path tracer is not as close in {pt_ms:.0} ms, > {speedup:.2}×"
                ),
            };
            line(name, gi.name(), &frame, rmse, flip, &format!("   {versus}"));
            if gi == GiLevel::Gi {
                points_rmse.push((vpls as f64, rmse));
                points_flip.push((vpls as f64, flip));
                dir_points.push((ms, rmse_linear));
            }
            rows.push(GpuRow::Condition(ConditionRow {
                scene: name.clone(),
                condition: gi,
                vpls,
                ms,
                rmse,
                flip,
                width: w,
                height: h,
                reference_spp: ref_spp,
                shadow_map_size: params.shadow_map_size,
                rsm_size: params.rsm_size,
                ism_size: params.ism_size,
                ism_points: params.ism_points,
                bounces: params.bounces,
                rmse_linear,
                flip_camera,
                path_tracer_ms_to_same_rmse: pt_ms,
                path_tracer_bound: bound,
                speedup_over_path_tracer: speedup,
                path_tracer_ms_to_same_flip: pt_ms_flip,
                path_tracer_bound_flip: bound_flip,
                speedup_over_path_tracer_flip: speedup_flip,
                passes: frame.report.passes,
            }));
        }
        plots.push(Plot {
            file: format!("render_gpu_vs_path_tracer_{}.svg", plot_name(name)),
            title: format!(
                "DIR gi (16–1024 VPLs) vs the path tracer (1–{} spp), {name}, {w}x{h}",
                pt_curve.last().map_or(0, |p| p.spp)
            ),
            x_label: "time (ms)".into(),
            y_label: "RMSE of radiance in the affected region".into(),
            x_log: true,
            y_log: true,
            series: vec![
                Series::new("path tracer", pt_curve.iter().map(|p| (p.ms, p.rmse)).collect()),
                Series::new("DIR gi", dir_points),
            ],
        });
        // the multiple-bounce light source (5.2.7): bounces and candidates per slot
        let bounce_settings: &[(u32, u32, u32)] = if quick {
            &[(256, 1, 4096), (256, 3, 4096)]
        } else {
            &[
                (256, 1, 4096),
                (256, 2, 4096),
                (256, 3, 1024),
                (256, 3, 4096),
                (256, 3, 16384),
                (1024, 1, 4096),
                (1024, 3, 4096),
            ]
        };
        for &(vpls, bounces, bounce_candidates) in bounce_settings {
            let params = DirParams { condition: GiLevel::Gi, vpls, bounces, bounce_candidates, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let bounce_ms = pass_ms(&frame.report.passes, |p| p.starts_with("bounce "));
            let found: Vec<String> = frame
                .report
                .bounces
                .iter()
                .map(|b| format!("{}/{} found, {} VPLs", b.found, b.slots, b.vpls))
                .collect();
            line(
                name,
                "gi",
                &frame,
                rmse,
                flip,
                &format!(
                    "   bounces {bounces}, {bounce_candidates} candidates ({bounce_ms:.1} ms; {})",
                    found.join("; ")
                ),
            );
            rows.push(GpuRow::Bounces(BouncesRow {
                scene: name.clone(),
                condition: GiLevel::Gi,
                vpls,
                bounces,
                bounce_candidates,
                bounce_ms,
                ms: frame.report.ms,
                rmse,
                flip,
                width: w,
                height: h,
                reference_spp: ref_spp,
                bounce_report: frame.report.bounces,
                passes: frame.report.passes,
            }));
        }
        // ISM resolution at 256 VPLs (0: VPLs unshadowed, no ISMs made)
        let ism_sizes: &[u32] = if quick { &[0, 64] } else { &[0, 32, 64, 128, 256] };
        let mut ism_rmse = Vec::new();
        let mut ism_flip = Vec::new();
        for &ism_size in ism_sizes {
            let params = DirParams { condition: GiLevel::Gi, vpls: 256, ism_size, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let ism_ms = pass_ms(&frame.report.passes, |p| p.starts_with("ISMs"));
            line(name, "gi", &frame, rmse, flip, &format!("   ISM {}² ({:.1} ms)", ism_size, ism_ms));
            ism_rmse.push((ism_size.max(1) as f64, rmse));
            ism_flip.push((ism_size.max(1) as f64, flip));
            rows.push(GpuRow::Ism(IsmRow {
                scene: name.clone(),
                condition: GiLevel::Gi,
                vpls: 256,
                ism_size,
                ism_points: params.ism_points,
                ism_ms,
                ms: frame.report.ms,
                rmse,
                flip,
                width: w,
                height: h,
                reference_spp: ref_spp,
                passes: frame.report.passes,
            }));
        }
        plots.push(error_plot(
            format!("render_gpu_ism_{}.svg", plot_name(name)),
            format!("DIR gi, 256 VPLs: error against ISM size ({name}, {w}x{h}, {adapter}; 1 = no ISMs)"),
            "ISM size (texels per side)",
            ism_rmse,
            ism_flip,
        ));
        // mirrors and glass (5.3): impostor resolution and ray-search length at 64 VPLs
        if !crate::gpu::mesh::build(&scene).specular.is_empty() {
            // (impostor face size, search steps, caustic map size)
            let sizes: &[(u32, u32, u32)] = if quick {
                &[(64, 48, 256), (256, 48, 0), (256, 48, 256), (256, 12, 256)]
            } else {
                &[
                    (32, 48, 256),
                    (64, 48, 256),
                    (128, 48, 256),
                    (256, 48, 256),
                    (512, 48, 256),
                    (256, 6, 256),
                    (256, 12, 256),
                    (256, 24, 256),
                    (256, 96, 256),
                    (256, 48, 0),
                    (256, 48, 64),
                    (256, 48, 128),
                    (256, 48, 512),
                ]
            };
            let (mut size_rmse, mut size_flip) = (Vec::new(), Vec::new());
            let (mut caustic_rmse, mut caustic_flip) = (Vec::new(), Vec::new());
            for &(impostor_size, search_steps, caustic_map_size) in sizes {
                let specular = crate::gpu::specular::SpecularParams {
                    impostor_size,
                    search_steps,
                    caustic_map_size,
                    ..Default::default()
                };
                let params = DirParams { condition: GiLevel::Gi, vpls: 64, specular, ..DirParams::default() };
                let (frame, rmse, flip) = measure(&params)?;
                let caustic_ms = pass_ms(&frame.report.passes, |p| p.starts_with("caustic"));
                let specular_ms = caustic_ms
                    + pass_ms(&frame.report.passes, |p| {
                        p.starts_with("impostors")
                            || p.starts_with("back faces")
                            || p.starts_with("reflected and refracted")
                            || p.ends_with(" hits")
                            || p.starts_with("mirrors and glass")
                    });
                let report = frame.report.specular.clone().unwrap_or_default();
                let photons = report.caustics.as_ref().map_or(0, |c| c.photons);
                line(
                    name,
                    "gi",
                    &frame,
                    rmse,
                    flip,
                    &format!(
                        "   impostors {}× {impostor_size}², {search_steps} search steps, caustic maps {caustic_map_size}² ({specular_ms:.1} ms, caustics {caustic_ms:.1} ms; {} of {} rays back-projected, {} missed; {photons} photons)",
                        report.objects.len(),
                        report.back_projected,
                        report.rays,
                        report.missed
                    ),
                );
                if search_steps == 48 && caustic_map_size == 256 {
                    size_rmse.push((impostor_size as f64, rmse));
                    size_flip.push((impostor_size as f64, flip));
                }
                if search_steps == 48 && impostor_size == 256 {
                    caustic_rmse.push((caustic_map_size as f64, rmse));
                    caustic_flip.push((caustic_map_size as f64, flip));
                }
                rows.push(GpuRow::Specular(SpecularRow {
                    scene: name.clone(),
                    condition: GiLevel::Gi,
                    vpls: 64,
                    impostors: report.objects.len(),
                    impostor_size,
                    search_steps,
                    secant_steps: params.specular.secant_steps,
                    caustic_map_size,
                    specular_ms,
                    caustic_ms,
                    ms: frame.report.ms,
                    rmse,
                    flip,
                    width: w,
                    height: h,
                    reference_spp: ref_spp,
                    report,
                    passes: frame.report.passes,
                }));
            }
            caustic_rmse.sort_by(|a, b| a.0.total_cmp(&b.0));
            caustic_flip.sort_by(|a, b| a.0.total_cmp(&b.0));
            if caustic_rmse.len() > 1 {
                // a linear axis: 0 (caustics off) is one of the sizes
                plots.push(Plot {
                    x_log: false,
                    ..error_plot(
                        format!("render_gpu_caustics_{}.svg", plot_name(name)),
                        format!("DIR gi: error against caustic map size, 0 = off ({name}, {w}x{h}, {adapter})"),
                        "caustic map size (texels per side)",
                        caustic_rmse,
                        caustic_flip,
                    )
                });
            }
            plots.push(error_plot(
                format!("render_gpu_specular_{}.svg", plot_name(name)),
                format!("DIR gi with mirrors and glass: error against impostor size ({name}, {w}x{h}, {adapter})"),
                "impostor face size (texels per side)",
                size_rmse,
                size_flip,
            ));
        }
        // the colour mappings at gi: the time of each cm pass and of the composition
        let cm_vpls = if quick { 64 } else { 256 };
        for method in CmMethod::ALL {
            let params = DirParams {
                condition: GiLevel::Gi,
                vpls: cm_vpls,
                cm: CmParams { method, ..CmParams::default() },
                ..DirParams::default()
            };
            let (frame, rmse, flip) = measure(&params)?;
            let cm_ms = pass_ms(&frame.report.passes, |p| p.starts_with("cm "));
            let compose_ms = pass_ms(&frame.report.passes, |p| p == "composition");
            line(
                name,
                "gi",
                &frame,
                rmse,
                flip,
                &format!("  cm {:<10} {:>8.2} ms (+ composition {:.2} ms)", method.name(), cm_ms, compose_ms),
            );
            rows.push(GpuRow::Cm(CmRow {
                scene: name.clone(),
                condition: GiLevel::Gi,
                cm: method.name(),
                vpls: cm_vpls,
                ms: frame.report.ms,
                cm_ms,
                composition_ms: compose_ms,
                rmse,
                flip,
                width: w,
                height: h,
                reference_spp: ref_spp,
                passes: frame.report.passes,
                cm_report: frame.report.cm,
            }));
        }
        // interleaved sampling at 256 VPLs: the tile split n (n × n classes, merge filter)
        let splits: &[u32] = if quick { &[1, 4] } else { &[1, 2, 4] };
        for &interleave in splits {
            let params = DirParams { condition: GiLevel::Gi, vpls: 256, interleave, ..DirParams::default() };
            let (frame, rmse, flip) = measure(&params)?;
            let shading_ms =
                pass_ms(&frame.report.passes, |p| p.starts_with("shading") || p.starts_with("indirect light"));
            line(
                name,
                "gi",
                &frame,
                rmse,
                flip,
                &format!("   tiles {interleave}×{interleave} (shading + merge {shading_ms:.1} ms)"),
            );
            rows.push(GpuRow::Interleave(InterleaveRow {
                scene: name.clone(),
                condition: GiLevel::Gi,
                vpls: 256,
                interleave,
                shading_ms,
                ms: frame.report.ms,
                rmse,
                flip,
                width: w,
                height: h,
                reference_spp: ref_spp,
                passes: frame.report.passes,
            }));
        }
        // the ca factor on top of gi (scene camera parameters): its pass time and the error
        for preset in ["webcam", "phone"] {
            let cam_scene = with_preset(&scene, preset)?;
            let photo = sensor::apply(&reference.hdr_real, &cam_scene.camera, &cam_scene.sensor);
            let truth = sensor::apply(&reference.hdr_full, &cam_scene.camera, &cam_scene.sensor);
            for ca in [false, true] {
                let params = DirParams {
                    condition: GiLevel::Gi,
                    camera_artifacts: ca.then(|| CaParams::from_sensor(&cam_scene.sensor)),
                    ..DirParams::default()
                };
                renderer.render(&cam_scene, &photo, &params)?;
                let frame = renderer.render(&cam_scene, &photo, &params)?;
                let rmse = metrics::rmse(&truth, &frame.composite, Some(affected));
                let flip = metrics::flip(&truth, &frame.composite, Some(affected));
                let ca_ms = ca_pass_ms(&frame);
                let label = if ca { format!("gi+ca/{preset}") } else { format!("gi/{preset}") };
                observer.line(&format!(
                    "{:<18} {:<12} {:>6} {:>10.2} {:>10.5} {:>8.4}   ca pass {}",
                    name,
                    label,
                    frame.report.vpls,
                    frame.report.ms,
                    rmse,
                    flip,
                    ca_ms.map(|m| format!("{m:.2} ms")).unwrap_or_else(|| "-".into())
                ));
                rows.push(GpuRow::Ca(CaRow {
                    scene: name.clone(),
                    condition: if ca { "gi+ca" } else { "gi" },
                    camera: preset,
                    vpls: params.vpls,
                    ms: frame.report.ms,
                    ca_ms,
                    rmse,
                    flip,
                    width: w,
                    height: h,
                    reference_spp: ref_spp,
                    passes: frame.report.passes,
                }));
            }
        }
        plots.push(error_plot(
            format!("render_gpu_{}.svg", plot_name(name)),
            format!("DIR gi: error against VPL count ({name}, {w}x{h}, {adapter})"),
            "VPLs",
            points_rmse,
            points_flip,
        ));
    }
    // the thesis's setting at its resolution: 256 VPLs, 128² ISMs of 1024 points, 4×4 tiles,
    // 1024×768 — frame time only (a path-traced reference at this size is beyond this bench)
    let (tw, th) = if quick { (320, 240) } else { (1024, 768) };
    let scene = load_sized(&names[0], tw, th)?;
    let (_, photo, _) = render_photo(&scene, &ReferenceParams { spp: 1, ..ReferenceParams::default() }, &|_, _| {})?;
    for interleave in [1, 4] {
        let params = DirParams {
            condition: GiLevel::Gi,
            vpls: 256,
            ism_size: 128,
            ism_points: 1024,
            interleave,
            ..DirParams::default()
        };
        renderer.render(&scene, &photo, &params)?;
        let frame = renderer.render(&scene, &photo, &params)?;
        let fps = 1000.0 / frame.report.ms.max(1e-9);
        observer.line(&format!(
            "{:<18} {:<8} {:>6} {:>10.2}   thesis setting at {tw}x{th}, tiles {interleave}×{interleave}: {fps:.2} fps",
            names[0], "gi", 256, frame.report.ms
        ));
        rows.push(GpuRow::Thesis(ThesisRow {
            scene: names[0].clone(),
            condition: GiLevel::Gi,
            vpls: 256,
            ism_size: 128,
            ism_points: 1024,
            interleave,
            setting: "thesis",
            ms: frame.report.ms,
            fps,
            width: tw,
            height: th,
            passes: frame.report.passes,
        }));
    }
    Ok(Report { adapter, rows, plots })
}

/// The scene through a camera preset, keeping the scene camera's seed.
pub(super) fn with_preset(scene: &Scene, preset: &str) -> Result<Scene> {
    let mut scene = scene.clone();
    let seed = scene.sensor.seed;
    scene.sensor = SensorParams::preset(preset)
        .ok_or_else(|| crate::error::RenderError::Unsupported(format!("no camera preset `{preset}`")))?;
    scene.sensor.seed = seed;
    Ok(scene)
}

/// The time of the frame's ca pass, if it ran.
pub(super) fn ca_pass_ms(frame: &GpuRender) -> Option<f64> {
    frame.report.passes.iter().find(|p| p.pass.starts_with("camera artifacts")).map(|p| p.ms)
}

/// One point of the path tracer's error curve: RMSE of linear radiance against the ground
/// truth's, FLIP of the camera's output against the ground truth's (affected region).
#[derive(Clone, Copy, Debug)]
pub struct PtPoint {
    pub spp: u32,
    pub ms: f64,
    pub rmse: f64,
    pub flip: f64,
}

/// The reference path tracer on the whole frame (real and virtual objects, seed 1000 — not the
/// ground truth's), at 1, 2, 4, … `max_spp` samples per pixel: cumulative time and the errors
/// of its image against the ground truth in the affected region.
pub fn path_tracer_curve(scene: &Scene, reference: &ReferenceOutput, max_spp: u32) -> Vec<PtPoint> {
    let world = World::new(scene, Subset::All);
    let params = TraceParams { seed: 1000, ..TraceParams::default() };
    let mut acc = Accumulator::new(scene.camera.width, scene.camera.height);
    let mut points = Vec::new();
    let start = Instant::now();
    let mut spp = 1;
    while spp <= max_spp {
        acc.add_samples(&world, &scene.camera, &params, spp - acc.spp);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let image = acc.image();
        let display = sensor::apply(&image, &scene.camera, &scene.sensor);
        let rmse = metrics::rmse(&reference.hdr_full, &image, Some(&reference.affected_mask));
        let flip = metrics::flip(&reference.ground_truth, &display, Some(&reference.affected_mask));
        points.push(PtPoint { spp, ms, rmse, flip });
        spp *= 2;
    }
    points
}

/// DIR's composite in linear radiance, as the path tracer would see it: the photograph's
/// radiance (the reference's real-only render, which the camera would capture) plus
/// L_rv − L_r, and L_rv where the camera sees a virtual object. Errors of this image measure
/// the light transport alone — the display composite adds the tone mapping's mismatch with the
/// camera (the cm factor's business), which the path tracer, rendered through the true camera,
/// does not have.
pub fn dir_linear_composite(frame: &GpuRender, photo_radiance: &Image) -> Image {
    let mut out = photo_radiance.clone();
    for (i, p) in out.pixels.iter_mut().enumerate() {
        let (rv, r) = (frame.l_rv.pixels[i], frame.l_r.pixels[i]);
        let differential = *p + rv - r;
        *p = if frame.virtual_mask.values[i] > 0.5 { rv } else { differential.max(differential * 0.0) };
    }
    out
}

/// Whether the path tracer's time to an error is measured or only bounded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Bound {
    /// Interpolated between the two sample counts that bracket the error.
    #[serde(rename = "interpolated")]
    Exact,
    /// Already reached at 1 spp: the time is an upper bound.
    #[serde(rename = "at most")]
    AtMost,
    /// Not reached at the curve's largest count: the time is a lower bound.
    #[serde(rename = "at least")]
    AtLeast,
}

/// The path tracer's time to reach `error` by `metric`: interpolated in log time between the
/// two sample counts that bracket it (the error falls with the samples in expectation; the
/// first crossing is taken).
pub fn path_tracer_time_to(curve: &[PtPoint], error: f64, metric: impl Fn(&PtPoint) -> f64) -> (f64, Bound) {
    let Some(first) = curve.first() else { return (0.0, Bound::AtLeast) };
    if metric(first) <= error {
        return (first.ms, Bound::AtMost);
    }
    for pair in curve.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let (ea, eb) = (metric(a), metric(b));
        if eb <= error {
            let f = if ea > eb { (ea - error) / (ea - eb) } else { 1.0 };
            return ((a.ms.ln() + f * (b.ms.ln() - a.ms.ln())).exp(), Bound::Exact);
        }
    }
    (curve.last().map_or(0.0, |p| p.ms), Bound::AtLeast)
}

/// A plot of RMSE and FLIP in the affected region (display-encoded) against a knob on a log
/// axis.
fn error_plot(file: String, title: String, x_label: &str, rmse: Vec<(f64, f64)>, flip: Vec<(f64, f64)>) -> Plot {
    Plot {
        file,
        title,
        x_label: x_label.into(),
        y_label: "error in the affected region (display)".into(),
        x_log: true,
        y_log: false,
        series: vec![Series::new("RMSE", rmse), Series::new("FLIP", flip)],
    }
}

/// A scene name (a built-in name or a scene file's path) as part of a file name.
pub(super) fn plot_name(name: &str) -> String {
    let stem = std::path::Path::new(name).file_stem().map_or(name.into(), |s| s.to_string_lossy().to_string());
    stem.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '-' }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_tracers_time_to_an_error_is_interpolated_or_bounded() {
        let curve: Vec<PtPoint> = [(1, 10.0, 0.8), (2, 20.0, 0.6), (4, 40.0, 0.4)]
            .iter()
            .map(|&(spp, ms, flip)| PtPoint { spp, ms, rmse: 0.0, flip })
            .collect();
        let (ms, bound) = path_tracer_time_to(&curve, 0.5, |p| p.flip);
        // halfway between 0.6 and 0.4: halfway in log time between 20 and 40 ms
        assert!(matches!(bound, Bound::Exact) && (ms - 800f64.sqrt()).abs() < 1e-9, "{ms}");
        let (ms, bound) = path_tracer_time_to(&curve, 0.6, |p| p.flip);
        assert!(matches!(bound, Bound::Exact) && (ms - 20.0).abs() < 1e-9, "{ms}");
        assert!(matches!(path_tracer_time_to(&curve, 0.9, |p| p.flip), (10.0, Bound::AtMost)));
        assert!(matches!(path_tracer_time_to(&curve, 0.1, |p| p.flip), (40.0, Bound::AtLeast)));
        assert!(matches!(path_tracer_time_to(&[], 0.1, |p| p.flip), (_, Bound::AtLeast)));
    }

    #[test]
    fn bounds_serialise_by_their_old_names() {
        let names: Vec<String> =
            [Bound::Exact, Bound::AtMost, Bound::AtLeast].iter().map(|b| serde_json::to_string(b).unwrap()).collect();
        assert_eq!(names, ["\"interpolated\"", "\"at most\"", "\"at least\""]);
    }
}
