//! `mrstudy capture`: the simulated RGB-D capture of a scene's real objects (Rohmer et al.,
//! Sec. 5) evaluated by `mrstudy_renderer::coherent::evaluation`, with a progress bar; its
//! report printed and optionally written as JSON.

use std::path::PathBuf;

use anyhow::{Context, Result};
use mrstudy_renderer::coherent::evaluation::{CaptureSettings, evaluate_capture};
use mrstudy_renderer::scene;

use crate::progress::progress_bar;

flags! {
    CaptureArgs {
        /// A built-in scene name or a scene file (TOML).
        #[arg(long)] scene: String,
        /// Capture poses: the scene camera's, then swung 20°, 40°, … left and right about the point it looks at.
        #[arg(long, default_value_t = 4)] poses: usize,
        /// Depth image size WxH.
        #[arg(long, value_parser = scene::parse_size, default_value = "160x120")] size: (u32, u32),
        /// Axial depth noise σ at 1 m in metres (it grows with depth squared).
        #[arg(long, default_value_t = 0.0016)] noise: f32,
        /// Fraction of depth pixels measured.
        #[arg(long, default_value_t = 0.33)] density: f32,
        /// Samples per pixel of the colour camera's path-traced image.
        #[arg(long, default_value_t = 16)] spp: u32,
        /// The hash grid's virtual cell in metres (0.05 in the paper, for rooms; a table-top scene keeps more detail with a smaller one).
        #[arg(long, default_value_t = 0.05)] cell: f32,
        /// Texels per cube-map face of the distance impostor built from the capture.
        #[arg(long, default_value_t = 128)] impostor_size: u32,
        /// Random seed of the sensor's pattern and noise.
        #[arg(long, default_value_t = 1)] seed: u64,
        /// Also write the report as JSON here.
        #[arg(long)] json: Option<PathBuf>,
    }
}

pub fn run(args: CaptureArgs) -> Result<()> {
    let settings = CaptureSettings {
        poses: args.poses,
        size: args.size,
        noise: args.noise,
        density: args.density,
        spp: args.spp,
        cell: args.cell,
        impostor_size: args.impostor_size,
        seed: args.seed,
    };
    settings.check()?;
    let scene = scene::load(&args.scene).with_context(|| format!("loading scene `{}`", args.scene))?;
    let bar = progress_bar(args.poses as u64, "capture", "poses");
    let evaluation = evaluate_capture(&scene, &settings, |done, _| bar.set_position(done as u64));
    bar.finish_and_clear();
    let evaluation = evaluation?;
    evaluation.lines().iter().for_each(|line| println!("{line}"));
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&evaluation.json())? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
