//! `bench render --cm`: each colour-mapping method's colour error on the virtual objects against
//! the ground-truth composite through the known camera. Per built-in scene the path tracer
//! renders the real-only and full HDR buffers once; per camera preset and setting
//! ([`CM_SETTINGS`]) both go through the simulated camera — with its geometric stages
//! (distortion, chromatic aberration, defocus) off, as they belong to the `ca` factor — and the
//! GPU frame (gi, 128 VPLs) is composed over the photograph with each cm method. Error:
//! CIEDE2000 (sRGB → CIELab; the E-scaled Lab of `cm::colour` equals D65 Lab for sRGB input) over
//! the pixels where the G-buffer sees a virtual surface and the path tracer's coverage is full.

use std::collections::BTreeMap;

use serde::Serialize;

use super::{Observer, Plot, Report, Series, ground_truth, load_sized, pass_ms};
use crate::builtin;
use crate::cm::{CmMethod, CmParams, colour::ciede2000_display};
use crate::error::{RenderError, Result};
use crate::gpu::{DirParams, DirRenderer, GiLevel};
use crate::metrics;
use crate::reference::ReferenceParams;
use crate::sensor::{self, SensorParams};
use crate::surface;

/// The camera settings of the benchmark: Figure 4.16's rows (normal; contrast up and down;
/// saturation up and down) and exposure changes, each relative to the preset.
pub const CM_SETTINGS: [(&str, fn(&mut SensorParams)); 7] = [
    ("normal", |_| {}),
    ("contrast+", |p| p.contrast *= 1.3),
    ("contrast-", |p| p.contrast *= 0.75),
    ("saturation+", |p| p.saturation *= 1.4),
    ("saturation-", |p| p.saturation *= 0.6),
    ("exposure+1", |p| p.exposure_ev += 1.0),
    ("exposure-1", |p| p.exposure_ev -= 1.0),
];

/// The GPU frame's VPL budget.
const VPLS: u32 = 128;

/// One row of `bench render --cm`: one frame, or a mean over the scenes.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum CmAccuracyRow {
    Frame(FrameRow),
    Mean(MeanRow),
}

/// One scene through one camera preset and setting, composed with one cm method.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRow {
    pub scene: String,
    pub camera: String,
    pub setting: &'static str,
    pub cm: &'static str,
    /// CIEDE2000 on the virtual pixels: mean and 95th percentile ([`metrics::quantile`]).
    pub de2000_mean: f64,
    pub de2000_p95: f64,
    pub pixels: usize,
    pub cm_ms: f64,
    pub ms: f64,
    pub fallback: Option<String>,
    pub cm_pairs: usize,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub vpls: u32,
}

/// The mean over the scenes (with virtual pixels) of a preset, setting and method.
#[derive(Clone, Debug, Serialize)]
pub struct MeanRow {
    /// Always `mean over scenes`.
    pub scene: &'static str,
    pub scenes: usize,
    pub camera: String,
    pub setting: &'static str,
    pub cm: &'static str,
    pub de2000_mean: f64,
    pub de2000_p95: f64,
}

/// Runs the benchmark on `scene_name` (default: every built-in scene, one with `quick`).
pub fn run(scene_name: Option<&str>, quick: bool, observer: &dyn Observer) -> Result<Report<CmAccuracyRow>> {
    let names: Vec<String> = match scene_name {
        Some(n) => vec![n.to_string()],
        None if quick => vec!["survey-1".to_string()],
        None => builtin::names().map(str::to_string).collect(),
    };
    let (w, h, spp) = if quick { (80, 60, 16) } else { (160, 120, 64) };
    let presets: Vec<&str> = if quick { vec!["webcam"] } else { SensorParams::PRESETS.to_vec() };
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    observer.note(&format!("adapter: {adapter}"));
    let mut rows = Vec::new();
    let mut warmed = false;
    // (preset, setting, method) → per-scene (mean, p95)
    let mut summary: BTreeMap<(usize, usize, usize), Vec<(f64, f64)>> = BTreeMap::new();
    observer.line(&format!(
        "{:<18} {:<7} {:<12} {:<11} {:>8} {:>8} {:>7} {:>8}",
        "scene", "camera", "setting", "cm", "dE mean", "dE p95", "pixels", "cm ms"
    ));
    for name in &names {
        let scene = load_sized(name, w, h)?;
        observer.note(&format!("{name} at {w}x{h}: reference at {spp} spp …"));
        let reference = ground_truth(&scene, ReferenceParams { spp, ..ReferenceParams::default() }, observer)?;
        for (pi, preset) in presets.iter().enumerate() {
            for (si, (setting, alter)) in CM_SETTINGS.iter().enumerate() {
                let mut sensor = SensorParams::preset(preset)
                    .ok_or_else(|| RenderError::Unsupported(format!("no camera preset `{preset}`")))?;
                sensor.seed = scene.sensor.seed;
                sensor.distortion = [0.0; 5];
                sensor.chromatic_aberration = 0.0;
                sensor.defocus_px = 0.0;
                alter(&mut sensor);
                let photo = sensor::apply(&reference.hdr_real, &scene.camera, &sensor);
                let truth = sensor::apply(&reference.hdr_full, &scene.camera, &sensor);
                for (mi, method) in CmMethod::ALL.iter().enumerate() {
                    let params = DirParams {
                        condition: GiLevel::Gi,
                        vpls: VPLS,
                        cm: CmParams { method: *method, ..CmParams::default() },
                        ..DirParams::default()
                    };
                    if !warmed {
                        // the first frame of each method compiles its shaders on software adapters
                        renderer.render(&scene, &photo, &params)?;
                    }
                    let frame = renderer.render(&scene, &photo, &params)?;
                    let mut errors: Vec<f64> = (0..photo.pixels.len())
                        .filter(|&i| frame.flags[i] == surface::VIRTUAL && reference.virtual_mask.values[i] >= 0.999)
                        .map(|i| ciede2000_display(truth.pixels[i], frame.composite.pixels[i]))
                        .collect();
                    errors.sort_by(f64::total_cmp);
                    let pixels = errors.len();
                    let mean = if pixels == 0 { 0.0 } else { errors.iter().sum::<f64>() / pixels as f64 };
                    let p95 = metrics::quantile(&errors, 0.95);
                    let cm_ms = pass_ms(&frame.report.passes, |p| p.starts_with("cm "));
                    observer.line(&format!(
                        "{:<18} {:<7} {:<12} {:<11} {:>8.2} {:>8.2} {:>7} {:>8.2}",
                        name,
                        preset,
                        setting,
                        method.name(),
                        mean,
                        p95,
                        pixels,
                        cm_ms
                    ));
                    rows.push(CmAccuracyRow::Frame(FrameRow {
                        scene: name.clone(),
                        camera: preset.to_string(),
                        setting,
                        cm: method.name(),
                        de2000_mean: mean,
                        de2000_p95: p95,
                        pixels,
                        cm_ms,
                        ms: frame.report.ms,
                        fallback: frame.report.cm.fallback,
                        cm_pairs: frame.report.cm.pairs,
                        width: w,
                        height: h,
                        reference_spp: spp,
                        vpls: VPLS,
                    }));
                    if pixels > 0 {
                        summary.entry((pi, si, mi)).or_default().push((mean, p95));
                    }
                }
                warmed = true;
            }
        }
    }
    // the averages over scenes: a table and, per camera preset, a plot
    observer.line("");
    observer.line("mean over scenes of CIEDE2000 on virtual pixels: mean (95th percentile)");
    let mut header = format!("{:<7} {:<12}", "camera", "setting");
    for m in CmMethod::ALL {
        header += &format!(" {:>16}", m.name());
    }
    observer.line(&header);
    let mut plots = Vec::new();
    for (pi, preset) in presets.iter().enumerate() {
        let mut series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); CmMethod::ALL.len()];
        for (si, (setting, _)) in CM_SETTINGS.iter().enumerate() {
            let mut line = format!("{:<7} {:<12}", preset, setting);
            for (mi, method) in CmMethod::ALL.iter().enumerate() {
                let v = summary.get(&(pi, si, mi)).cloned().unwrap_or_default();
                let n = v.len().max(1) as f64;
                let (mean, p95) = (v.iter().map(|x| x.0).sum::<f64>() / n, v.iter().map(|x| x.1).sum::<f64>() / n);
                line += &format!(" {:>7.2} ({:>6.2})", mean, p95);
                series[mi].push(((si + 1) as f64, mean));
                rows.push(CmAccuracyRow::Mean(MeanRow {
                    scene: "mean over scenes",
                    scenes: v.len(),
                    camera: preset.to_string(),
                    setting,
                    cm: method.name(),
                    de2000_mean: mean,
                    de2000_p95: p95,
                }));
            }
            observer.line(&line);
        }
        plots.push(Plot {
            file: format!("render_cm_{preset}.svg"),
            title: format!("cm accuracy, camera {preset} ({w}x{h}, mean over {} scenes, {adapter})", names.len()),
            x_label:
                "setting: 1 normal, 2 contrast+, 3 contrast-, 4 saturation+, 5 saturation-, 6 exposure+1, 7 exposure-1"
                    .into(),
            y_label: "CIEDE2000 on virtual pixels (mean)".into(),
            x_log: false,
            y_log: false,
            series: CmMethod::ALL.iter().zip(series).map(|(m, points)| Series::new(m.name(), points)).collect(),
        });
    }
    Ok(Report { adapter, rows, plots })
}
