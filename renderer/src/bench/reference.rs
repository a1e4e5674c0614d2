//! `bench render --reference`: samples per second of the reference path tracer, and its error
//! against a high-spp render of the same scene as the sample count grows.

use std::time::Instant;

use serde::Serialize;

use super::{Observer, Plot, Report, Series, load_sized};
use crate::error::Result;
use crate::image::Image;
use crate::metrics;
use crate::pathtracer::{Accumulator, Subset, TraceParams, World};
use crate::reference::{ReferenceParams, render_reference};
use crate::sensor;

/// The path tracer at one sample count.
#[derive(Clone, Debug, Serialize)]
pub struct ReferenceRow {
    pub scene: String,
    /// `reference`: the ground truth alone at a growing sample count; `two passes` and
    /// `together`: the photograph and the ground truth at 16 spp (8 with `--quick`), rendered
    /// one world after the other or each path once for both
    /// ([`Accumulator::add_samples_pair`]; only in a scene without virtual lights). Their
    /// errors are the ground truth's, the same bit for bit.
    pub condition: &'static str,
    pub spp: u32,
    /// Cumulative time to this sample count.
    pub ms: f64,
    pub samples_per_s: f64,
    /// RMSE of linear radiance in the affected region.
    pub rmse: f64,
    /// RMSE of linear radiance over the whole image.
    pub rmse_all: f64,
    /// FLIP of the camera's output in the affected region.
    pub flip: f64,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
}

/// Runs the benchmark on `scene_name` (default `survey-1`); `quick` for small sizes.
pub fn run(scene_name: Option<&str>, quick: bool, observer: &dyn Observer) -> Result<Report<ReferenceRow>> {
    let name = scene_name.unwrap_or("survey-1");
    let (w, h, max_spp, ref_spp) = if quick { (48, 36, 64, 256) } else { (160, 120, 256, 2048) };
    let scene = load_sized(name, w, h)?;
    let threads = rayon::current_num_threads();
    let adapter = format!("cpu reference path tracer ({threads} threads)");
    observer.note(&format!("{name} at {w}x{h}: reference at {ref_spp} spp (seed 1000) …"));
    let total = 2 * ref_spp;
    let reference = render_reference(
        &scene,
        &ReferenceParams { spp: ref_spp, seed: 1000, pass_spp: 16, ..ReferenceParams::default() },
        &|d, _| observer.progress("reference", d, total),
    )?;
    observer.progress("reference", total, total);
    let affected = &reference.affected_mask;
    let world = World::new(&scene, Subset::All);
    let params = TraceParams { seed: 1, ..TraceParams::default() };
    let mut acc = Accumulator::new(w, h);
    let mut rows = Vec::new();
    let mut points_rmse = Vec::new();
    let mut points_flip = Vec::new();
    observer.line(&format!(
        "{:<10} {:>6} {:>10} {:>14} {:>12} {:>12} {:>8}",
        "scene", "spp", "ms", "samples/s", "rmse(aff)", "rmse(all)", "flip"
    ));
    // a row for `images` images of `spp` samples each, rendered in `ms`, the ground truth `img`
    let row = |condition: &'static str, spp: u32, images: f64, ms: f64, img: &Image| {
        let display = sensor::apply(img, &scene.camera, &scene.sensor);
        ReferenceRow {
            scene: name.to_string(),
            condition,
            spp,
            ms,
            samples_per_s: images * (w * h) as f64 * spp as f64 / (ms / 1e3),
            rmse: metrics::rmse(&reference.hdr_full, img, Some(affected)),
            rmse_all: metrics::rmse(&reference.hdr_full, img, None),
            flip: metrics::flip(&reference.ground_truth, &display, Some(affected)),
            width: w,
            height: h,
            reference_spp: ref_spp,
        }
    };
    let start = Instant::now();
    let mut spp = 1u32;
    while spp <= max_spp {
        acc.add_samples(&world, &scene.camera, &params, spp - acc.spp);
        let r = row("reference", spp, 1.0, start.elapsed().as_secs_f64() * 1e3, &acc.image());
        let (ms, rmse_aff, flip) = (r.ms, r.rmse, r.flip);
        observer.line(&format!(
            "{:<10} {:>6} {:>10.1} {:>14.0} {:>12.5} {:>12.5} {:>8.4}",
            name, spp, ms, r.samples_per_s, rmse_aff, r.rmse_all, flip
        ));
        rows.push(r);
        points_rmse.push((ms, rmse_aff));
        points_flip.push((ms, flip));
        spp *= 2;
    }
    // the 1/√t guide through the first point
    let guide: Vec<(f64, f64)> = points_rmse
        .first()
        .map(|&(t0, e0)| points_rmse.iter().map(|&(t, _)| (t, e0 * (t0 / t).sqrt())).collect())
        .unwrap_or_default();
    let plot = Plot {
        file: "render_reference.svg".into(),
        title: format!("Reference path tracer: error against time ({name}, {w}x{h}, {adapter})"),
        x_label: "time (ms)".into(),
        y_label: "error in the affected region".into(),
        x_log: true,
        y_log: true,
        series: vec![
            Series::new("RMSE (linear)", points_rmse),
            Series::new("1/sqrt(t)", guide),
            Series::new("FLIP", points_flip),
        ],
    };
    // the photograph and the ground truth: one world after the other, and together
    let real_world = World::new(&scene, Subset::RealOnly);
    let both_spp = if quick { 8 } else { 16 };
    let start = Instant::now();
    let _photo = crate::pathtracer::render(&real_world, &scene.camera, &params, both_spp);
    let full = crate::pathtracer::render(&world, &scene.camera, &params, both_spp);
    let apart = row("two passes", both_spp, 2.0, start.elapsed().as_secs_f64() * 1e3, &full.image());
    observer.line(&format!("photograph and ground truth at {both_spp} spp: two passes {:.1} ms", apart.ms));
    rows.push(apart);
    if world.shares_lights_with(&real_world) {
        let start = Instant::now();
        let (mut full, mut photo) = (Accumulator::new(w, h), Accumulator::new(w, h));
        full.add_samples_pair(&mut photo, &world, &real_world, &scene.camera, &params, both_spp);
        let together = row("together", both_spp, 2.0, start.elapsed().as_secs_f64() * 1e3, &full.image());
        observer.line(&format!(
            "photograph and ground truth at {both_spp} spp: together {:.1} ms ({:.2}x faster, the same images)",
            together.ms,
            rows.last().map_or(0.0, |r| r.ms) / together.ms.max(1e-9)
        ));
        rows.push(together);
    } else {
        observer
            .note("a virtual light: the photograph and the ground truth sample different lights, so no `together` row");
    }
    Ok(Report { adapter, rows, plots: vec![plot] })
}
