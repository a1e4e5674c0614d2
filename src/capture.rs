//! `mrstudy capture`: its flags, run by `mrstudy_renderer::command::capture` (the simulated RGB-D
//! capture of a scene's real objects, Rohmer et al., Sec. 5, and its errors) on the console.

use std::path::PathBuf;

use crate::Say;
use anyhow::Result;
use mrstudy_renderer::coherent::evaluation::CaptureSettings;
use mrstudy_renderer::command::{CaptureRequest, capture};
use mrstudy_renderer::scene;

flags! {
    CaptureArgs => CaptureRequest {} {
        /// A built-in scene name or a scene file (TOML).
        #[arg(long)] scene: String,
        #[command(flatten)] settings: CaptureFlags,
        /// Also write the report as JSON here.
        #[arg(long)] json: Option<PathBuf>,
    }
}

flags! {
    CaptureFlags => CaptureSettings {} {
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
    }
}

pub fn run(args: CaptureArgs, say: Say) -> Result<()> {
    Ok(capture(&args.into(), say)?)
}
