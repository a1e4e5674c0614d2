//! `bench render --gi-methods`: the global-illumination methods a study can compare (issue 18,
//! Deliver 5) — differential instant radiosity (DIR, the GPU renderer, over VPL counts) and
//! Rohmer et al.'s coherent methods EM, DIT and VCT at the paper's low/med/high settings (the
//! CPU reference, [`crate::coherent`]), with `off` (the object lit without occlusion, no
//! differential background) as the floor — on every built-in scene, each against the
//! path-traced ground truth of the same reference render.
//!
//! Each row gives the time of each stage (capture, representation build, the virtual object,
//! the differential background with material estimation, the whole frame; `ms`, the time per
//! frame, is the representation and the frame, as the capture runs once per scene) and the error of
//! the composite in linear radiance seen through the scene's true camera (so that no method is
//! judged by a colour mapping it does not have): FLIP and display RMSE in the affected region
//! and on the virtual objects, RMSE of the radiance in the affected region. DIR's composite is
//! [`super::gpu::dir_linear_composite`]; its frame is rendered twice and the second timed.
//! Per scene one plot of FLIP in the affected region against time, and one of the mean over
//! the scenes.

use serde::Serialize;

use super::gpu::dir_linear_composite;
use super::{Observer, Plot, Report, Series, ground_truth, load_sized, pass_ms};
use crate::coherent::render::{CapturedScene, render_over};
use crate::coherent::{CoherentParams, Method, Quality};
use crate::error::Result;
use crate::gpu::PassTime;
use crate::gpu::context::FrameCounters;
use crate::gpu::{DirParams, DirRenderer, GiLevel};
use crate::metrics::{self, stimulus_errors};
use crate::reference::ReferenceParams;
use crate::sensor;

/// One method at one setting on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct MethodRow {
    pub scene: String,
    /// `dir`, `off`, `em`, `dit` or `vct`.
    pub method: String,
    /// The coherent methods' quality setting (`low`, `med`, `high`); none for DIR.
    pub quality: Option<String>,
    /// DIR's VPL budget; none for the coherent methods.
    pub vpls: Option<u32>,
    /// Where it ran: the GPU adapter (DIR) or the CPU's threads (the coherent reference).
    pub device: String,
    /// The simulated capture of the real scene (4 poses); 0 for DIR.
    pub capture_ms: f64,
    /// Light probe and distance impostor or voxel volume; 0 for DIR.
    pub representation_ms: f64,
    /// The virtual object's pass (coherent; DIR has no separate one).
    pub object_ms: Option<f64>,
    /// Material estimation and the differential background (coherent).
    pub background_ms: Option<f64>,
    /// The frame: every pass after the representation (DIR: the GPU frame).
    pub frame_ms: f64,
    /// The time per frame: representation and frame (the capture runs once per scene, or
    /// beside the renderer as the sensor streams, in the paper; it is reported on its own).
    pub ms: f64,
    /// FLIP and display RMSE in the affected region.
    pub flip: f64,
    pub rmse: f64,
    /// On the virtual objects.
    pub flip_virtual: Option<f64>,
    pub rmse_virtual: Option<f64>,
    /// RMSE of the linear composite's radiance in the affected region.
    pub rmse_linear: f64,
    pub representation_bytes: usize,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    /// The frame's structure as the GPU context counted it ([`FrameCounters`]): DIR's frame;
    /// for the coherent methods, the representation build and the frame (their GPU work is the
    /// representation), `cpu_ms` their wall-clock time.
    pub counters: FrameCounters,
    pub passes: Vec<PassTime>,
}

/// Runs the benchmark on `scene_name` (default: every built-in scene; `quick`: survey-1 small).
pub fn run(scene_name: Option<&str>, quick: bool, observer: &dyn Observer) -> Result<Report<MethodRow>> {
    let names: Vec<String> = match scene_name {
        Some(name) => vec![name.to_string()],
        None if quick => vec!["survey-1".to_string()],
        None => crate::scene::builtin::names().map(str::to_string).collect(),
    };
    let (w, h, ref_spp) = if quick { (64, 48, 16) } else { (160, 120, 128) };
    let qualities: &[Quality] = if quick { &[Quality::Med] } else { &Quality::ALL };
    let vpl_counts: &[u32] = if quick { &[64] } else { &[16, 64, 256, 1024] };
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    let cpu = format!("CPU, {} threads", rayon::current_num_threads());
    observer.note(&format!(
        "DIR on {adapter}; the coherent methods' representations and frames on {adapter} (the frames' rays recorded, and high's frames, on the {cpu})"
    ));
    observer.line(&format!(
        "{:<17} {:<4} {:<5} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>7} {:>7} {:>7} {}",
        "scene",
        "gi",
        "set",
        "capture",
        "repr.",
        "object",
        "backgr.",
        "frame ms",
        "ms",
        "FLIP",
        "RMSE",
        "FLIPvirt",
        FrameCounters::HEADER
    ));
    let mut rows: Vec<MethodRow> = Vec::new();
    let mut plots = Vec::new();
    for name in &names {
        let scene = load_sized(name, w, h)?;
        observer.note(&format!("{name} at {w}x{h}: reference at {ref_spp} spp …"));
        let reference = ground_truth(&scene, ReferenceParams { spp: ref_spp, ..ReferenceParams::default() }, observer)?;
        let first_row = rows.len();
        let affected = &reference.affected_mask;
        // DIR over VPL counts
        for &vpls in vpl_counts {
            let params = DirParams { condition: GiLevel::Gi, vpls, ..DirParams::default() };
            renderer.render(&scene, &reference.photo, &params)?;
            let frame = renderer.render(&scene, &reference.photo, &params)?;
            let linear = dir_linear_composite(&frame, &reference.hdr_real);
            let shown = sensor::apply(&linear, &scene.camera, &scene.sensor);
            let errors = stimulus_errors(&reference.ground_truth, &shown, affected, &reference.virtual_mask);
            rows.push(MethodRow {
                scene: name.clone(),
                method: "dir".into(),
                quality: None,
                vpls: Some(vpls),
                device: adapter.clone(),
                capture_ms: 0.0,
                representation_ms: 0.0,
                object_ms: None,
                background_ms: None,
                frame_ms: frame.report.ms,
                ms: frame.report.ms,
                flip: errors.value("flip_mean", "affected").unwrap_or(0.0),
                rmse: errors.value("rmse_display", "affected").unwrap_or(0.0),
                flip_virtual: errors.value("flip_mean", "virtual"),
                rmse_virtual: errors.value("rmse_display", "virtual"),
                rmse_linear: metrics::rmse(&reference.hdr_full, &linear, Some(affected)),
                representation_bytes: 0,
                width: w,
                height: h,
                reference_spp: ref_spp,
                counters: frame.report.counters,
                passes: frame.report.passes,
            });
            print_row(observer, rows.last().expect("a row"));
        }
        // the coherent methods from one capture: off once, EM, DIT and VCT at each quality
        // (seed 1: CoherentParams::new's, as in mrstudy render --gi-method)
        let captured = CapturedScene::new(&scene, 1, &|done, total| observer.progress("capture", done, total));
        let mut settings = vec![(Method::Off, Quality::Med)];
        for method in [Method::Em, Method::Dit, Method::Vct] {
            settings.extend(qualities.iter().map(|&q| (method, q)));
        }
        for (method, quality) in settings {
            let params = CoherentParams::new(method, quality);
            renderer.ctx.reset_counters();
            let (build, frame, _, errors) =
                render_over(&scene, &captured, &params, &reference, Some(&renderer), &|done, total| {
                    observer.progress("coherent", done, total)
                })?;
            let pass = |prefix: &str| pass_ms(&frame.report.passes, |p| p.starts_with(prefix));
            let capture_ms = captured.ms;
            let representation_ms = build.iter().skip(1).map(|p| p.ms).fold(0.0, |a, b| a + b);
            let frame_ms = frame.report.total_ms();
            // the frame on the GPU: its own counters (the GPU pass starts a frame of the context,
            // after the representation's build), the host's time the whole frame's; on the CPU:
            // the representation's build
            let counters = match frame.report.counters {
                Some(c) => FrameCounters { cpu_ms: frame_ms, ..c },
                None => FrameCounters { cpu_ms: representation_ms + frame_ms, ..renderer.ctx.counters() },
            };
            let device = if frame.report.counters.is_some() {
                format!("representation and frame {adapter}")
            } else {
                format!("representation {adapter}; frame {cpu}")
            };
            rows.push(MethodRow {
                scene: name.clone(),
                method: method.name().into(),
                quality: Some(quality.name().into()),
                vpls: None,
                device,
                capture_ms,
                representation_ms,
                // the GPU frame's queries and shading are one pass: no split
                object_ms: frame.report.counters.is_none().then(|| pass("virtual object")),
                background_ms: frame
                    .report
                    .counters
                    .is_none()
                    .then(|| pass("material estimation") + pass("differential background")),
                frame_ms,
                ms: representation_ms + frame_ms,
                flip: errors.value("flip_mean", "affected").unwrap_or(0.0),
                rmse: errors.value("rmse_display", "affected").unwrap_or(0.0),
                flip_virtual: errors.value("flip_mean", "virtual"),
                rmse_virtual: errors.value("rmse_display", "virtual"),
                rmse_linear: metrics::rmse(&reference.hdr_full, &frame.composite, Some(affected)),
                representation_bytes: frame.report.representation_bytes,
                width: w,
                height: h,
                reference_spp: ref_spp,
                counters,
                passes: build.into_iter().chain(frame.report.passes).collect(),
            });
            print_row(observer, rows.last().expect("a row"));
        }
        if reference.affected_mask.values.iter().all(|&v| v <= 0.5) {
            observer.note(&format!("{name}: the affected region is empty; its errors are 0 by definition"));
        }
        plots.push(error_time_plot(
            format!("render_gi_methods_{}.svg", super::gpu::plot_name(name)),
            format!("FLIP against time by gi method, {name}, {w}x{h} (DIR, the representations and the coherent frames on the GPU where one opens)"),
            &rows[first_row..],
        ));
    }
    if names.len() > 1 {
        plots.push(error_time_plot(
            "render_gi_methods_mean.svg".into(),
            format!("mean FLIP against mean time by gi method over {} scenes, {w}x{h}", names.len()),
            &mean_rows(&rows),
        ));
    }
    Ok(Report { adapter: format!("{adapter}; {cpu}"), rows, plots })
}

fn print_row(observer: &dyn Observer, row: &MethodRow) {
    let setting = match (&row.quality, row.vpls) {
        (Some(quality), _) => quality.clone(),
        (None, Some(vpls)) => format!("{vpls}"),
        (None, None) => String::new(),
    };
    let optional = |value: Option<f64>, digits: usize| value.map_or("–".to_string(), |v| format!("{v:.digits$}"));
    observer.line(&format!(
        "{:<17} {:<4} {:<5} {:>8.1} {:>8.1} {:>8} {:>8} {:>9.1} {:>9.1} {:>7.4} {:>7.4} {:>7} {}",
        row.scene,
        row.method,
        setting,
        row.capture_ms,
        row.representation_ms,
        optional(row.object_ms, 1),
        optional(row.background_ms, 1),
        row.frame_ms,
        row.ms,
        row.flip,
        row.rmse,
        optional(row.flip_virtual, 4),
        row.counters.cells(),
    ));
}

/// The rows' means over scenes per method and setting, for the summary plot.
fn mean_rows(rows: &[MethodRow]) -> Vec<MethodRow> {
    let mut means: Vec<(MethodRow, usize)> = Vec::new();
    for row in rows {
        match means.iter_mut().find(|(m, _)| m.method == row.method && m.quality == row.quality && m.vpls == row.vpls) {
            Some((mean, count)) => {
                mean.ms += row.ms;
                mean.flip += row.flip;
                *count += 1;
            }
            None => means.push((row.clone(), 1)),
        }
    }
    means
        .into_iter()
        .map(|(mut mean, count)| {
            mean.ms /= count as f64;
            mean.flip /= count as f64;
            mean.scene = "mean".into();
            mean
        })
        .collect()
}

/// FLIP in the affected region against total time: one series per method (DIR over its VPL
/// counts, the coherent methods over their qualities, `off` a single point).
fn error_time_plot(file: String, title: String, rows: &[MethodRow]) -> Plot {
    let series = ["dir", "em", "dit", "vct", "off"]
        .iter()
        .map(|&method| {
            let mut points: Vec<(f64, f64)> =
                rows.iter().filter(|r| r.method == method).map(|r| (r.ms.max(1e-3), r.flip)).collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            let name = match method {
                "dir" => "DIR (VPLs)".to_string(),
                "off" => "off".to_string(),
                other => format!("{} (low, med, high)", other.to_uppercase()),
            };
            Series::new(&name, points)
        })
        .filter(|s| !s.points.is_empty())
        .collect();
    Plot {
        file,
        title,
        x_label: "time per frame: representation and frame (ms)".into(),
        y_label: "FLIP in the affected region".into(),
        x_log: true,
        y_log: false,
        series,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_rows_average_each_method_and_setting_over_scenes() {
        let row = |scene: &str, method: &str, quality: Option<&str>, ms: f64, flip: f64| MethodRow {
            scene: scene.into(),
            method: method.into(),
            quality: quality.map(str::to_string),
            vpls: None,
            device: String::new(),
            capture_ms: 0.0,
            representation_ms: 0.0,
            object_ms: None,
            background_ms: None,
            frame_ms: ms,
            ms,
            flip,
            rmse: 0.0,
            flip_virtual: None,
            rmse_virtual: None,
            rmse_linear: 0.0,
            representation_bytes: 0,
            width: 1,
            height: 1,
            reference_spp: 1,
            counters: FrameCounters::default(),
            passes: Vec::new(),
        };
        let rows = vec![
            row("a", "dit", Some("med"), 10.0, 0.2),
            row("b", "dit", Some("med"), 30.0, 0.4),
            row("a", "dit", Some("high"), 50.0, 0.1),
        ];
        let means = mean_rows(&rows);
        assert_eq!(means.len(), 2);
        assert_eq!((means[0].ms, means[0].flip), (20.0, 0.30000000000000004));
        assert_eq!((means[1].ms, means[1].flip), (50.0, 0.1));
        let plot = error_time_plot("x.svg".into(), "t".into(), &rows);
        assert_eq!(plot.series.len(), 1);
        assert_eq!(plot.series[0].points, [(10.0, 0.2), (30.0, 0.4), (50.0, 0.1)]);
    }
}
