//! `bench render --ca`: how closely noise and blur on the virtual objects match the camera, per
//! scene and camera preset, with the ca factor off, on with the scene's camera parameters and on
//! with parameters estimated from the photograph. The ground truth (path traced, through the
//! simulated camera) shows what the camera does to the virtual objects; the same estimators run
//! on the same pixels of each GPU frame ([`crate::ca::accuracy`]), and on the untouched real
//! pixels of the photograph. Also times the ca pass and reports the frame's error against the
//! ground truth in the affected region. Rows with `"layer": "path-traced"` apply the chain (CPU
//! reference) to the path-traced virtual objects through the camera with its artifact stages
//! off, which isolates the chain from the GPU renderer's shading and tone mapping and shares the
//! ground truth's path-tracing noise.

use std::time::Instant;

use serde::Serialize;

use super::gpu::{ca_pass_ms, with_preset};
use super::{Observer, Plot, Report, Series, ground_truth, load_sized};
use crate::ca::accuracy::{self, RegionStats, Regions};
use crate::ca::{CaParams, ParamSource, estimate};
use crate::error::Result;
use crate::gpu::{DirParams, DirRenderer, GiLevel};
use crate::image::Mask;
use crate::metrics;
use crate::reference::ReferenceParams;
use crate::sensor;

/// One row of `bench render --ca`: a GPU frame or the chain alone on the path-traced layer.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum CaAccuracyRow {
    Gpu(GpuLayerRow),
    PathTraced(PathTracedLayerRow),
}

/// The GPU frame with the ca factor off or on.
#[derive(Clone, Debug, Serialize)]
pub struct GpuLayerRow {
    /// Always `ca-accuracy`.
    pub bench: &'static str,
    pub scene: String,
    pub camera: &'static str,
    /// `off`, `scene` or `estimate`.
    pub ca: &'static str,
    /// The scene × camera configuration's number (the plots' x axis).
    pub configuration: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    #[serde(rename = "virtual")]
    pub virtual_stats: RegionStats,
    pub ground_truth_virtual: RegionStats,
    pub photo_real: RegionStats,
    /// Noise on the frame's virtual objects above the ca-off frame's floor.
    pub virtual_noise_sigma: f32,
    /// The camera's noise on the same pixels of the ground truth, above its noise-free floor.
    pub camera_noise_sigma: f32,
    pub ground_truth_noise_floor: f32,
    pub frame_noise_floor: f32,
    pub noise_ratio_to_ground_truth: Option<f32>,
    pub blur_difference_to_ground_truth_px: Option<f32>,
    pub ca_ms: Option<f64>,
    pub ms: f64,
    pub rmse: f64,
    pub flip: f64,
    pub ca_params: Option<CaParams>,
    /// Always `gpu`.
    pub layer: &'static str,
}

/// The ca chain (CPU reference) alone on the path-traced virtual layer.
#[derive(Clone, Debug, Serialize)]
pub struct PathTracedLayerRow {
    /// Always `ca-accuracy`.
    pub bench: &'static str,
    pub scene: String,
    pub camera: &'static str,
    pub ca: &'static str,
    pub configuration: f64,
    /// Always `path-traced`.
    pub layer: &'static str,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    #[serde(rename = "virtual")]
    pub virtual_stats: RegionStats,
    pub ground_truth_virtual: RegionStats,
    pub photo_real: RegionStats,
    pub noise_ratio_to_ground_truth: Option<f32>,
    pub blur_difference_to_ground_truth_px: Option<f32>,
    /// The CPU chain's time.
    pub ms: f64,
    pub rmse: f64,
    pub flip: f64,
    pub timed_on: &'static str,
}

/// Runs the benchmark on `scene_name` (default: two survey and two DIR scenes, one with `quick`).
pub fn run(scene_name: Option<&str>, quick: bool, observer: &dyn Observer) -> Result<Report<CaAccuracyRow>> {
    let names: Vec<String> = match scene_name {
        Some(n) => vec![n.to_string()],
        None if quick => vec!["dir-double-shadow".to_string()],
        None => ["survey-1", "survey-4", "dir-double-shadow", "dir-lamp-box"].iter().map(|s| s.to_string()).collect(),
    };
    let (w, h, ref_spp) = if quick { (128, 96, 64) } else { (192, 144, 256) };
    let presets = ["webcam", "phone"];
    let renderer = DirRenderer::new()?;
    let adapter = renderer.ctx.adapter_name();
    observer.note(&format!("adapter: {adapter}"));
    let mut rows = Vec::new();
    let modes: [(&'static str, Option<ParamSource>); 3] =
        [("off", None), ("scene", Some(ParamSource::Scene)), ("estimate", Some(ParamSource::Estimate))];
    let mut noise_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut blur_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut layer_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut layer_blur_series: Vec<Vec<(f64, f64)>> = vec![Vec::new(); modes.len() + 1];
    let mut configuration = 0.0;
    let fmt = |v: Option<f32>| v.map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into());
    // σ_virt: noise on the frame's virtual objects above the ca-off frame's floor; σ_gt: the
    // camera's noise on the same pixels of the ground truth (above its noise-free floor);
    // σ_real: the photograph's untouched pixels; r: blur as a disc radius (px)
    observer.line(&format!(
        "{:<18} {:<7} {:<9} {:>9} {:>9} {:>9} {:>7} {:>7} {:>7} {:>9} {:>9}",
        "scene", "camera", "ca", "σ_virt", "σ_gt", "σ_real", "r_virt", "r_gt", "r_real", "ca ms", "rmse(aff)"
    ));
    for name in &names {
        let base = load_sized(name, w, h)?;
        observer.note(&format!("{name} at {w}x{h}: reference at {ref_spp} spp …"));
        let reference = ground_truth(&base, ReferenceParams { spp: ref_spp, ..ReferenceParams::default() }, observer)?;
        for preset in presets {
            let scene = with_preset(&base, preset)?;
            let photo = sensor::apply(&reference.hdr_real, &scene.camera, &scene.sensor);
            let truth = sensor::apply(&reference.hdr_full, &scene.camera, &scene.sensor);
            // the ground truth without sensor noise: its σ is the path tracer's noise and the
            // shading's residue, which the camera's σ is corrected for (σ_cam² = σ_gt² − σ_floor²)
            let mut quiet = scene.sensor.clone();
            quiet.noise = [0.0, 0.0];
            let truth_quiet = sensor::apply(&reference.hdr_full, &scene.camera, &quiet);
            let regions = Regions::new(&reference.virtual_mask, &reference.affected_mask, &scene.camera, &scene.sensor);
            let affected = accuracy::warp_mask(&reference.affected_mask, &scene.camera, &scene.sensor);
            let real = accuracy::measure(&photo, &regions.real, &regions.real);
            let gt = accuracy::measure(&truth, &regions.virtual_inner, &regions.virtual_edges);
            let floor = accuracy::measure(&truth_quiet, &regions.virtual_inner, &regions.virtual_edges).noise_sigma;
            let camera_sigma = (gt.noise_sigma.powi(2) - floor.powi(2)).max(0.0).sqrt();
            configuration += 1.0;
            noise_series[modes.len()].push((configuration, camera_sigma as f64));
            if let Some(r) = gt.blur_radius_px {
                blur_series[modes.len()].push((configuration, r as f64));
            }
            let mut frame_floor = 0.0f32;
            for (k, (mode, source)) in modes.iter().enumerate() {
                let camera_artifacts = source.map(|s| match s {
                    ParamSource::Scene => CaParams::from_sensor(&scene.sensor),
                    ParamSource::Estimate => estimate::params_from_photo(&photo, &scene.sensor).0,
                });
                let params = DirParams { condition: GiLevel::Gi, camera_artifacts, ..DirParams::default() };
                renderer.render(&scene, &photo, &params)?;
                let frame = renderer.render(&scene, &photo, &params)?;
                let stats = accuracy::measure(&frame.composite, &regions.virtual_inner, &regions.virtual_edges);
                if k == 0 {
                    frame_floor = stats.noise_sigma;
                }
                let virtual_sigma = (stats.noise_sigma.powi(2) - frame_floor.powi(2)).max(0.0).sqrt();
                let ca_ms = ca_pass_ms(&frame);
                let rmse = metrics::rmse(&truth, &frame.composite, Some(&affected));
                let flip = metrics::flip(&truth, &frame.composite, Some(&affected));
                observer.line(&format!(
                    "{:<18} {:<7} {:<9} {:>9.5} {:>9.5} {:>9.5} {:>7} {:>7} {:>7} {:>9} {:>9.5}",
                    name,
                    preset,
                    mode,
                    virtual_sigma,
                    camera_sigma,
                    real.noise_sigma,
                    fmt(stats.blur_radius_px),
                    fmt(gt.blur_radius_px),
                    fmt(real.blur_radius_px),
                    ca_ms.map(|m| format!("{m:.2}")).unwrap_or_else(|| "-".into()),
                    rmse
                ));
                noise_series[k].push((configuration, virtual_sigma as f64));
                if let Some(r) = stats.blur_radius_px {
                    blur_series[k].push((configuration, r as f64));
                }
                let blur_difference = stats.blur_radius_px.zip(gt.blur_radius_px).map(|(a, b)| a - b);
                rows.push(CaAccuracyRow::Gpu(GpuLayerRow {
                    bench: "ca-accuracy",
                    scene: name.clone(),
                    camera: preset,
                    ca: mode,
                    configuration,
                    width: w,
                    height: h,
                    reference_spp: ref_spp,
                    virtual_stats: stats,
                    ground_truth_virtual: gt.clone(),
                    photo_real: real.clone(),
                    virtual_noise_sigma: virtual_sigma,
                    camera_noise_sigma: camera_sigma,
                    ground_truth_noise_floor: floor,
                    frame_noise_floor: frame_floor,
                    noise_ratio_to_ground_truth: if camera_sigma > 0.0 {
                        Some(virtual_sigma / camera_sigma)
                    } else {
                        None
                    },
                    blur_difference_to_ground_truth_px: blur_difference,
                    ca_ms,
                    ms: frame.report.ms,
                    rmse,
                    flip,
                    ca_params: frame.report.params.camera_artifacts,
                    layer: "gpu",
                }));
            }
            // the chain alone, without the GPU renderer's shading and tone differences: the
            // virtual layer is the path-traced radiance through the camera with every artifact
            // stage off (the same path-tracing noise as the ground truth), then the ca chain
            let mut clean = scene.sensor.clone();
            clean.distortion = [0.0; 5];
            clean.chromatic_aberration = 0.0;
            clean.defocus_px = 0.0;
            clean.bayer = false;
            clean.noise = [0.0, 0.0];
            clean.sharpen = 0.0;
            clean.jpeg_quality = None;
            clean.vignetting = 0.0;
            let clean_full = sensor::apply(&reference.hdr_full, &scene.camera, &clean);
            let coverage = Mask {
                width: w,
                height: h,
                values: reference.virtual_mask.values.iter().map(|v| if *v > 0.5 { 1.0 } else { 0.0 }).collect(),
            };
            let mut layer = photo.clone();
            for (i, px) in layer.pixels.iter_mut().enumerate() {
                if coverage.values[i] > 0.0 {
                    *px = clean_full.pixels[i];
                }
            }
            for (k, (mode, source)) in modes.iter().enumerate() {
                let mut cpu_ms = 0.0;
                let out = match source {
                    None => layer.clone(),
                    Some(s) => {
                        let p = if *s == ParamSource::Scene {
                            CaParams::from_sensor(&scene.sensor)
                        } else {
                            estimate::params_from_photo(&photo, &scene.sensor).0
                        };
                        let start = Instant::now();
                        let out = crate::ca::apply_cpu(&layer, &photo, &coverage, &scene.camera, &p)?.0;
                        cpu_ms = start.elapsed().as_secs_f64() * 1e3;
                        out
                    }
                };
                let rmse = metrics::rmse(&truth, &out, Some(&affected));
                let flip = metrics::flip(&truth, &out, Some(&affected));
                let stats = accuracy::measure(&out, &regions.virtual_inner, &regions.virtual_edges);
                observer.line(&format!(
                    "{:<18} {:<7} {:<9} {:>9.5} {:>9.5} {:>9.5} {:>7} {:>7} {:>7} {:>9} {:>9.5}",
                    name,
                    preset,
                    format!("pt-{mode}"),
                    stats.noise_sigma,
                    gt.noise_sigma,
                    real.noise_sigma,
                    fmt(stats.blur_radius_px),
                    fmt(gt.blur_radius_px),
                    fmt(real.blur_radius_px),
                    format!("{cpu_ms:.0} cpu"),
                    rmse
                ));
                layer_series[k].push((configuration, stats.noise_sigma as f64));
                if let Some(r) = stats.blur_radius_px {
                    layer_blur_series[k].push((configuration, r as f64));
                }
                let noise_ratio = if gt.noise_sigma > 0.0 { Some(stats.noise_sigma / gt.noise_sigma) } else { None };
                let blur_difference = stats.blur_radius_px.zip(gt.blur_radius_px).map(|(a, b)| a - b);
                rows.push(CaAccuracyRow::PathTraced(PathTracedLayerRow {
                    bench: "ca-accuracy",
                    scene: name.clone(),
                    camera: preset,
                    ca: mode,
                    configuration,
                    layer: "path-traced",
                    width: w,
                    height: h,
                    reference_spp: ref_spp,
                    virtual_stats: stats,
                    ground_truth_virtual: gt.clone(),
                    photo_real: real.clone(),
                    noise_ratio_to_ground_truth: noise_ratio,
                    blur_difference_to_ground_truth_px: blur_difference,
                    ms: cpu_ms,
                    rmse,
                    flip,
                    timed_on: "cpu (CPU reference implementation)",
                }));
            }
            layer_series[modes.len()].push((configuration, gt.noise_sigma as f64));
            if let Some(r) = gt.blur_radius_px {
                layer_blur_series[modes.len()].push((configuration, r as f64));
            }
        }
    }
    let names_of = ["ca off", "ca scene", "ca estimate", "ground truth"];
    let series = |data: &[Vec<(f64, f64)>]| data.iter().zip(names_of).map(|(p, n)| Series::new(n, p.clone())).collect();
    let plot = |file: &str, title: String, y_label: &str, y_log: bool, series: Vec<Series>| Plot {
        file: file.into(),
        title,
        x_label: "configuration (scene × camera, see the table)".into(),
        y_label: y_label.into(),
        x_log: false,
        y_log,
        series,
    };
    let plots = vec![
        plot(
            "render_ca_noise.svg",
            format!("ca: noise σ on the virtual objects ({w}x{h}, {adapter})"),
            "camera noise σ above the noise-free floor (Immerkær, display)",
            true,
            series(&noise_series),
        ),
        plot(
            "render_ca_blur.svg",
            format!("ca: blur on the virtual objects' edges ({w}x{h}, {adapter})"),
            "equivalent disc radius (px)",
            false,
            series(&blur_series),
        ),
        plot(
            "render_ca_noise_layer.svg",
            format!("ca chain alone on the path-traced virtual layer: noise σ ({w}x{h}, CPU reference)"),
            "Immerkær σ on the virtual objects (display)",
            true,
            series(&layer_series),
        ),
        plot(
            "render_ca_blur_layer.svg",
            format!("ca chain alone on the path-traced virtual layer: blur ({w}x{h}, CPU reference)"),
            "equivalent disc radius (px)",
            false,
            series(&layer_blur_series),
        ),
    ];
    Ok(Report { adapter, rows, plots })
}
