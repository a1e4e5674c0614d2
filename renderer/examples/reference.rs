//! Renders a built-in scene's photograph and ground truth with the reference path tracer:
//! `cargo run --release -p mrstudy-renderer --example reference -- survey-1 320x240 64 out/`
//! (the library alone, without the `mrstudy` CLI).

use mrstudy_renderer::reference::{ReferenceParams, render_reference};
use mrstudy_renderer::scene;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("survey-1");
    let size = args.get(2).map(String::as_str).unwrap_or("320x240");
    let spp: u32 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(32);
    let out = PathBuf::from(args.get(4).map(String::as_str).unwrap_or("."));
    let scene = scene::load_as(name, Some(scene::parse_size(size)?), None)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let r = render_reference(&scene, &ReferenceParams { spp, ..Default::default() }, &|_, _| {})?;
    std::fs::create_dir_all(&out)?;
    r.photo.save_png(&out.join(format!("{name}-photo.png")))?;
    r.ground_truth.save_png(&out.join(format!("{name}-gt.png")))?;
    r.affected_mask.save_png(&out.join(format!("{name}-affected.png")))?;
    println!(
        "{name}: {:.1} s, {:.0} samples/s, fireflies {}/{}, coverage {:.3}, affected {:.3}",
        r.stats.seconds,
        r.stats.samples_per_second,
        r.stats.fireflies_photo,
        r.stats.fireflies_ground_truth,
        r.stats.virtual_coverage,
        r.stats.affected_fraction
    );
    Ok(())
}
