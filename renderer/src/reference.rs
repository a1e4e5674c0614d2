//! The reference renders a study needs from the CPU path tracer: (a) the photograph — the real
//! scene only, through the simulated camera; (b) the ground-truth composite — real and virtual
//! objects, through the same camera, with the same path-tracing random numbers and the same
//! sensor noise; (c) the linear HDR buffers of both and two masks: virtual coverage (fraction of
//! primary samples that saw a virtual object) and the affected region (virtual coverage, or a
//! radiance change between (a) and (b) above a relative threshold).

use crate::error::{RenderError, Result};
use crate::image::{Image, Mask};
use crate::math::luminance;
use crate::pathtracer::{Accumulator, Subset, TraceParams, World};
use crate::scene::Scene;
use crate::sensor;
use serde::Serialize;
use std::time::Instant;

/// How a reference render runs.
#[derive(Clone, Debug)]
pub struct ReferenceParams {
    pub spp: u32,
    pub seed: u64,
    pub max_depth: u32,
    /// A pixel is "affected" when its (3×3-smoothed) luminance changes by more than this
    /// fraction of the photograph's luminance there (floored at 5 % of the mean) and by more
    /// than three standard errors of the sampling noise.
    pub affected_threshold: f32,
    /// A firefly is a pixel whose brightest sample exceeds this multiple of the image mean and
    /// carries more than half of the pixel's value.
    pub firefly_factor: f32,
    /// Samples per progressive pass (the progress callback runs after each).
    pub pass_spp: u32,
}

impl Default for ReferenceParams {
    fn default() -> Self {
        ReferenceParams {
            spp: 64,
            seed: 1,
            max_depth: 64,
            affected_threshold: 0.02,
            firefly_factor: 100.0,
            pass_spp: 4,
        }
    }
}

/// Timings and counts of a reference render.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seconds: f64,
    /// Camera samples (paths) per second over both renders.
    pub samples_per_second: f64,
    pub fireflies_photo: usize,
    pub fireflies_ground_truth: usize,
    /// Non-finite samples dropped (should be 0).
    pub invalid_samples: u64,
    pub virtual_coverage: f32,
    pub affected_fraction: f32,
    /// Light paths traced for caustics from spot lights through mirrors or glass (both renders).
    pub light_paths: u64,
    /// Whether light tracing ran, or why it was skipped.
    pub light_tracing: String,
    /// How the photograph and the ground truth were traced: together, each path once until it
    /// meets a virtual object, or in two passes (and why); empty for a photograph alone.
    pub paths: String,
    pub warnings: Vec<String>,
}

/// Everything a reference render produces.
#[derive(Clone, Debug)]
pub struct ReferenceOutput {
    /// Linear radiance of the real scene.
    pub hdr_real: Image,
    /// Linear radiance of the composite (real and virtual).
    pub hdr_full: Image,
    /// The photograph: `hdr_real` through the simulated camera (display-encoded).
    pub photo: Image,
    /// The ground truth: `hdr_full` through the same camera and noise.
    pub ground_truth: Image,
    pub virtual_mask: Mask,
    pub affected_mask: Mask,
    pub stats: RenderStats,
}

impl ReferenceOutput {
    /// Writes every buffer into `dir`: photo.png, ground_truth.png, real.exr, full.exr,
    /// virtual_mask.png, affected_mask.png, and report.json with the stats and the photograph's
    /// error against the ground truth in the affected region.
    pub fn write_buffers(&self, dir: &std::path::Path, scene: &str) -> Result<()> {
        crate::image::create_buffers_dir(dir)?;
        self.photo.save_png(&dir.join("photo.png"))?;
        self.ground_truth.save_png(&dir.join("ground_truth.png"))?;
        self.hdr_real.save_exr(&dir.join("real.exr"))?;
        self.hdr_full.save_exr(&dir.join("full.exr"))?;
        self.virtual_mask.save_png(&dir.join("virtual_mask.png"))?;
        self.affected_mask.save_png(&dir.join("affected_mask.png"))?;
        let errors = crate::metrics::compare(
            &self.hdr_full,
            &self.hdr_real,
            &self.ground_truth,
            &self.photo,
            Some(&self.affected_mask),
        );
        crate::image::save_json(
            &dir.join("report.json"),
            &serde_json::json!({ "scene": scene, "stats": self.stats, "photo_vs_ground_truth_in_affected_region": errors }),
        )
    }
}

/// Writes the buffers of a photograph ([`render_photo`]) into `dir`: photo.png, real.exr and
/// report.json with the stats.
pub fn write_photo_buffers(
    dir: &std::path::Path,
    scene: &str,
    hdr: &Image,
    photo: &Image,
    stats: &RenderStats,
) -> Result<()> {
    crate::image::create_buffers_dir(dir)?;
    photo.save_png(&dir.join("photo.png"))?;
    hdr.save_exr(&dir.join("real.exr"))?;
    crate::image::save_json(&dir.join("report.json"), &serde_json::json!({ "scene": scene, "stats": stats }))
}

fn progressive(
    world: &World,
    scene: &Scene,
    params: &ReferenceParams,
    done: &mut u32,
    total: u32,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Accumulator {
    let tp = TraceParams { seed: params.seed, max_depth: params.max_depth, ..TraceParams::default() };
    let mut acc = Accumulator::new(scene.camera.width, scene.camera.height);
    while acc.spp < params.spp {
        let n = params.pass_spp.max(1).min(params.spp - acc.spp);
        acc.add_samples(world, &scene.camera, &tp, n);
        *done += n;
        progress(*done, total);
    }
    acc
}

/// [`progressive`] for the real-only and the full world at once
/// ([`Accumulator::add_samples_pair`]): (photograph's sums, ground truth's sums). Progress is
/// reported out of 2 × spp, as for two passes.
fn progressive_pair(
    full_world: &World,
    real_world: &World,
    scene: &Scene,
    params: &ReferenceParams,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> (Accumulator, Accumulator) {
    let tp = TraceParams { seed: params.seed, max_depth: params.max_depth, ..TraceParams::default() };
    let mut real = Accumulator::new(scene.camera.width, scene.camera.height);
    let mut full = Accumulator::new(scene.camera.width, scene.camera.height);
    while full.spp < params.spp {
        let n = params.pass_spp.max(1).min(params.spp - full.spp);
        full.add_samples_pair(&mut real, full_world, real_world, &scene.camera, &tp, n);
        // counted as two passes count: samples per pixel of both images
        progress(2 * full.spp, 2 * params.spp);
    }
    (real, full)
}

/// The photograph alone: (linear radiance, camera output, stats). A scene with a background
/// photograph returns that photograph.
pub fn render_photo(
    scene: &Scene,
    params: &ReferenceParams,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<(Image, Image, RenderStats)> {
    let start = Instant::now();
    if let Some(bg) = &scene.background {
        let display = bg.linear_to_srgb();
        let stats = stats_for(scene, params, 0.0, Counted::default());
        return Ok((bg.clone(), display, stats));
    }
    let world = World::new(scene, Subset::RealOnly);
    let mut done = 0;
    let acc = progressive(&world, scene, params, &mut done, params.spp, progress);
    let hdr = acc.image();
    let photo = sensor::apply(&hdr, &scene.camera, &scene.sensor);
    let secs = start.elapsed().as_secs_f64();
    let counted = Counted {
        fireflies_photo: acc.count_fireflies(params.firefly_factor),
        invalid: acc.invalid_samples,
        ..Counted::default()
    };
    let mut stats = stats_for(scene, params, secs, counted);
    stats.light_paths = acc.light_paths;
    Ok((hdr, photo, stats))
}

/// What a reference render counted, for its [`RenderStats`]: firefly pixels of the photograph
/// and of the ground truth, invalid samples, the virtual objects' coverage and the affected
/// region's fraction.
#[derive(Clone, Copy, Debug, Default)]
struct Counted {
    fireflies_photo: usize,
    fireflies_ground_truth: usize,
    invalid: u64,
    coverage: f32,
    affected: f32,
}

fn stats_for(scene: &Scene, params: &ReferenceParams, secs: f64, counted: Counted) -> RenderStats {
    let Counted { fireflies_photo: ff_photo, fireflies_ground_truth: ff_gt, invalid, coverage, affected } = counted;
    let renders = if ff_gt > 0 || coverage > 0.0 || affected > 0.0 { 2.0 } else { 1.0 };
    let samples = scene.camera.width as f64 * scene.camera.height as f64 * params.spp as f64 * renders;
    let mut warnings = scene.warnings.clone();
    if ff_photo + ff_gt > 0 {
        warnings.push(format!(
            "{} firefly pixels in the photograph and {} in the ground truth (counted, not clamped)",
            ff_photo, ff_gt
        ));
    }
    RenderStats {
        width: scene.camera.width,
        height: scene.camera.height,
        spp: params.spp,
        seconds: secs,
        samples_per_second: if secs > 0.0 { samples / secs } else { 0.0 },
        fireflies_photo: ff_photo,
        fireflies_ground_truth: ff_gt,
        invalid_samples: invalid,
        virtual_coverage: coverage,
        affected_fraction: affected,
        light_paths: 0,
        light_tracing: light_tracing(scene),
        paths: String::new(),
        warnings,
    }
}

/// Whether a scene needs light tracing (see `pathtracer`), in words.
fn light_tracing(scene: &Scene) -> String {
    match (scene.specular_object().is_some(), scene.spots.is_empty()) {
        (true, false) => "on: caustics from spot and point lights through mirrors or glass".into(),
        (false, _) => "skipped: no mirror or glass in the scene".into(),
        (true, true) => "skipped: no spot or point light (camera paths find caustics from area lights)".into(),
    }
}

/// Renders the photograph, the ground-truth composite, their HDR buffers and the masks.
pub fn render_reference(
    scene: &Scene,
    params: &ReferenceParams,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<ReferenceOutput> {
    if scene.background.is_some() {
        return Err(RenderError::Unsupported(format!(
            "scene `{}` uses a background photograph, so it has no synthesised ground truth; render it with --photo, or remove [background] to synthesise one",
            scene.name
        )));
    }
    let start = Instant::now();
    let real_world = World::new(scene, Subset::RealOnly);
    let full_world = World::new(scene, Subset::All);
    let paired = full_world.shares_lights_with(&real_world);
    let (acc_real, acc_full) = if paired {
        // no virtual light: each path is traced once for both images until it meets a
        // virtual object (the same images as two passes, bit for bit)
        progressive_pair(&full_world, &real_world, scene, params, progress)
    } else {
        let total = params.spp * 2;
        let mut done = 0;
        let acc_real = progressive(&real_world, scene, params, &mut done, total, progress);
        let acc_full = progressive(&full_world, scene, params, &mut done, total, progress);
        (acc_real, acc_full)
    };
    let hdr_real = acc_real.image();
    let hdr_full = acc_full.image();
    let photo = sensor::apply(&hdr_real, &scene.camera, &scene.sensor);
    let ground_truth = sensor::apply(&hdr_full, &scene.camera, &scene.sensor);
    let virtual_mask = Mask { width: hdr_full.width, height: hdr_full.height, values: acc_full.virtual_coverage() };
    let noise: Vec<f32> = acc_real
        .luminance_standard_error()
        .iter()
        .zip(acc_full.luminance_standard_error())
        .map(|(a, b)| a + b)
        .collect();
    let affected_mask = affected_region(&hdr_real, &hdr_full, &virtual_mask, params.affected_threshold, &noise);
    let secs = start.elapsed().as_secs_f64();
    let counted = Counted {
        fireflies_photo: acc_real.count_fireflies(params.firefly_factor),
        fireflies_ground_truth: acc_full.count_fireflies(params.firefly_factor),
        invalid: acc_real.invalid_samples + acc_full.invalid_samples,
        coverage: virtual_mask.coverage(),
        affected: 0.0,
    };
    let mut stats = stats_for(scene, params, secs, counted);
    stats.samples_per_second = (hdr_full.pixels.len() as f64 * params.spp as f64 * 2.0) / secs.max(1e-9);
    stats.affected_fraction = affected_mask.coverage();
    stats.light_paths = acc_real.light_paths + acc_full.light_paths;
    stats.paths = match paired {
        true => "together: each path traced once for both images until it meets a virtual object".into(),
        false => {
            "two passes: the scene has a virtual light or emitter, so the two images sample different lights".into()
        }
    };
    Ok(ReferenceOutput { hdr_real, hdr_full, photo, ground_truth, virtual_mask, affected_mask, stats })
}

/// The affected region: virtual coverage, or a smoothed (3×3) luminance change that is both
/// above `threshold` × the photograph's smoothed luminance (floored at 5 % of its mean) and
/// above three standard errors of the Monte Carlo noise, so that path-tracing noise does not
/// pass for a change. `noise` is the per-pixel sum of both renders' standard errors (may be
/// empty: no noise); averaging nine pixels divides it by three.
pub fn affected_region(real: &Image, full: &Image, coverage: &Mask, threshold: f32, noise: &[f32]) -> Mask {
    let (w, h) = (real.width as i64, real.height as i64);
    let yr: Vec<f32> = real.pixels.iter().map(|p| luminance(*p)).collect();
    let yd: Vec<f32> = real.pixels.iter().zip(&full.pixels).map(|(a, b)| luminance(*b) - luminance(*a)).collect();
    let box3 = |v: &[f32], x: i64, y: i64| -> f32 {
        let mut s = 0.0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let xx = (x + dx).clamp(0, w - 1);
                let yy = (y + dy).clamp(0, h - 1);
                s += v[(yy * w + xx) as usize];
            }
        }
        s / 9.0
    };
    let floor = 0.05 * yr.iter().sum::<f32>() / yr.len().max(1) as f32;
    let mut m = Mask::new(real.width, real.height);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let base = box3(&yr, x, y).max(floor);
            let d = box3(&yd, x, y).abs();
            let noise_floor = if noise.is_empty() { 0.0 } else { 3.0 * box3(noise, x, y) / 3.0 };
            m.values[i] = if coverage.values[i] > 0.0 || (d > threshold * base && d > noise_floor) { 1.0 } else { 0.0 };
        }
    }
    m
}

/// What `mrstudy render` path-traces into a file: the photograph (real objects only) or the
/// ground-truth composite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    Photo,
    GroundTruth,
}

impl Target {
    /// Samples per pixel the progress counts to: the ground truth renders twice (real, full).
    pub fn progress_total(self, params: &ReferenceParams) -> u32 {
        match self {
            Target::Photo => params.spp,
            Target::GroundTruth => 2 * params.spp,
        }
    }
}

/// Renders `target`, saves it to `out` (`.png` the camera output, `.exr` linear radiance) and,
/// with `buffers`, every buffer ([`ReferenceOutput::write_buffers`], [`write_photo_buffers`]).
pub fn render_to_file(
    scene: &Scene,
    params: &ReferenceParams,
    target: Target,
    out: &std::path::Path,
    buffers: Option<&std::path::Path>,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<RenderStats> {
    match target {
        Target::Photo => {
            let (hdr, photo, stats) = render_photo(scene, params, progress)?;
            crate::image::save_by_extension(out, &hdr, &photo)?;
            if let Some(dir) = buffers {
                write_photo_buffers(dir, &scene.name, &hdr, &photo, &stats)?;
            }
            Ok(stats)
        }
        Target::GroundTruth => {
            let result = render_reference(scene, params, progress)?;
            crate::image::save_by_extension(out, &result.hdr_full, &result.ground_truth)?;
            if let Some(dir) = buffers {
                result.write_buffers(dir, &scene.name)?;
            }
            Ok(result.stats)
        }
    }
}
