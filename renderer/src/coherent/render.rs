//! A scene rendered by a coherent method from start to end, as `mrstudy render --gi-method`
//! does: the reference render (the photograph and the ground truth, one path-tracing run), the
//! simulated capture of the real scene, the representation, the frame, and the frame through
//! the scene's camera (the same sensor and noise as the photograph) with its errors against the
//! ground truth.

use super::{Coherent, CoherentFrame, CoherentParams, Pass, build_representation};
use crate::capture::{CaptureParams, CaptureReport, capture};
use crate::error::Result;
use crate::image::Image;
use crate::metrics::{StimulusErrors, stimulus_errors};
use crate::pathtracer::{Subset, World};
use crate::reference::{ReferenceOutput, ReferenceParams, render_reference};
use crate::scene::Scene;
use std::time::Instant;

/// Everything one coherent render of a scene made.
pub struct SceneRender {
    pub reference: ReferenceOutput,
    pub capture: CaptureReport,
    /// The build passes (light probe, impostor or voxel volume) before the frame's passes.
    pub build: Vec<Pass>,
    pub frame: CoherentFrame,
    /// The composite through the scene's camera (display-encoded).
    pub stimulus: Image,
    pub errors: StimulusErrors,
}

/// Renders `scene` by `params`: the reference path tracer at `reference` (its photograph is the
/// frame's input, its ground truth the errors' reference), a capture from 4 poses, then the
/// frame. `progress(done, total)` counts the reference render's samples per pixel, then the
/// capture's poses and the frame's passes.
pub fn render_scene(
    scene: &Scene,
    params: &CoherentParams,
    reference: &ReferenceParams,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<SceneRender> {
    let poses = 4u32;
    let total = 2 * reference.spp + poses + 5;
    let reference_out = render_reference(scene, reference, &|done, _| progress(done, total))?;
    let real = World::new(scene, Subset::RealOnly);
    let mut capture_params = CaptureParams::for_scene(scene, &real, poses as usize);
    capture_params.seed = params.seed;
    let start = Instant::now();
    let cap = capture(&real, &capture_params, |done, _| progress(2 * reference.spp + done as u32, total));
    let mut build = vec![Pass { pass: format!("capture ({poses} poses)"), ms: start.elapsed().as_secs_f64() * 1e3 }];
    let samples: Vec<_> = cap.grid.samples().copied().collect();
    let (rep, passes) = build_representation(scene, &real, &samples, capture_params.cell, params);
    build.extend(passes);
    let renderer = Coherent::new(scene, &real, &rep, *params);
    let frame =
        renderer.render(&reference_out.hdr_real, &|done, _| progress(2 * reference.spp + poses + done, total))?;
    let stimulus = crate::sensor::apply(&frame.composite, &scene.camera, &scene.sensor);
    let errors = stimulus_errors(
        &reference_out.ground_truth,
        &stimulus,
        &reference_out.affected_mask,
        &reference_out.virtual_mask,
    );
    Ok(SceneRender { reference: reference_out, capture: cap.report, build, frame, stimulus, errors })
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
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<Vec<String>> {
    let result = render_scene(scene, params, reference, progress)?;
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
    let value = |metric: &str, region: &str| {
        result.errors.values.iter().find(|v| v.metric == metric && v.region == region).map(|v| v.value)
    };
    for region in ["affected", "virtual"] {
        if let (Some(flip), Some(rmse)) = (value("flip_mean", region), value("rmse_display", region)) {
            lines
                .push(format!("  against the ground truth, {region} region: FLIP {flip:.4}, RMSE {rmse:.4} (display)"));
        }
    }
    for skipped in &result.errors.skipped {
        lines.push(format!("  errors skipped: {skipped}"));
    }
    lines.push(format!(
        "wrote {} (gi {} at quality {}): reference {:.1} s on the CPU, representation {:.0} ms, frame {:.0} ms",
        out.display(),
        params.method.name(),
        params.quality.name(),
        result.reference.stats.seconds,
        result.build.iter().map(|p| p.ms).sum::<f64>(),
        report.total_ms()
    ));
    Ok(lines)
}
