//! `mrstudy bench`: runs a benchmark of `mrstudy_renderer::bench`, `mrstudy_analysis::bench`
//! (`bench active`: `mrstudy_analysis::active::bench`) or the server's load generator, prints
//! its table as it goes and, with `--json FILE`, writes `{"adapter": ..., "rows": [...]}`
//! (DESIGN.md); `--plot-dir DIR` draws its curves as SVG.

use std::path::PathBuf;
use std::sync::Mutex;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use indicatif::ProgressBar;
use mrstudy_analysis::plot::{LinePlot, LineSeries, line_plot};
use mrstudy_renderer::bench::{self, Observer, Plot};
use serde_json::Value;

#[derive(Clone, Copy, ValueEnum)]
pub enum Target {
    /// Active pair selection: choice time against conditions × judgments, posterior updates against the refit.
    Active,
    /// Bradley–Terry analysis: time against data size and against convergence tolerance.
    Analysis,
    /// Rendering: the GPU renderer's frame time and error against the path-traced ground truth over VPL counts; with `--reference`, the CPU reference path tracer's samples/s and error against a high-spp render; with `--ca`, noise and blur on the virtual objects against the camera's, ca off/on.
    Render,
    /// Web survey server: responses/s and latency percentiles with durable writes, concurrent simulated participants over loopback.
    Server,
}

#[derive(Args)]
pub struct BenchArgs {
    target: Target,
    /// Write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write SVG plots of the curves into this directory.
    #[arg(long)]
    plot_dir: Option<PathBuf>,
    /// Smaller sizes only (for a quick check).
    #[arg(long)]
    quick: bool,
    /// bench render: measure the CPU reference path tracer.
    #[arg(long)]
    reference: bool,
    /// bench render: the ca factor's accuracy — noise and blur on the virtual objects against
    /// the camera's (ground truth), ca off / scene / estimated parameters, per scene and preset.
    #[arg(long, conflicts_with_all = ["reference", "cm"])]
    ca: bool,
    /// bench render: each colour-mapping (cm) method's CIEDE2000 on the virtual objects against the ground truth through the known camera, over camera presets and settings.
    #[arg(long, conflicts_with = "reference")]
    cm: bool,
    /// bench render: the scene (default: DIR scenes on the GPU, survey-1 with --reference, every built-in scene with --cm).
    #[arg(long)]
    scene: Option<String>,
}

/// Prints a renderer benchmark's table to stdout, its notes to stderr, and a progress bar for
/// each reference render.
#[derive(Default)]
struct Printer {
    bar: Mutex<Option<ProgressBar>>,
}

impl Observer for Printer {
    fn line(&self, text: &str) {
        println!("{text}");
    }
    fn note(&self, text: &str) {
        eprintln!("{text}");
    }
    fn progress(&self, label: &str, done: u32, total: u32) {
        let mut bar = self.bar.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if done >= total {
            if let Some(bar) = bar.take() {
                bar.finish_and_clear();
            }
        } else {
            bar.get_or_insert_with(|| crate::render::progress_bar(total as u64, label)).set_position(done as u64);
        }
    }
}

/// The renderer's plot as an SVG file name and text.
fn drawn(plot: &Plot) -> (String, String) {
    let series = plot.series.iter().map(|s| LineSeries { name: s.name.clone(), points: s.points.clone() }).collect();
    let line = LinePlot {
        title: plot.title.clone(),
        x_label: plot.x_label.clone(),
        y_label: plot.y_label.clone(),
        x_log: plot.x_log,
        y_log: plot.y_log,
        series,
    };
    (plot.file.clone(), line_plot(&line))
}

pub fn run(args: BenchArgs) -> Result<()> {
    let printer = Printer::default();
    let scene = args.scene.as_deref();
    let (document, plots): (Value, Vec<(String, String)>) =
        match args.target {
            Target::Analysis => {
                // one core, as the targets are stated for one core of the 2-core machine
                let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
                let report = pool.install(|| mrstudy_analysis::bench::run(args.quick, &|line| println!("{line}")))?;
                (report.to_json(), report.plots.iter().map(|(file, plot)| (file.clone(), line_plot(plot))).collect())
            }
            Target::Active => {
                let report = mrstudy_analysis::active::bench::run(args.quick, &|line| println!("{line}"))?;
                (report.to_json(), report.plots.iter().map(|(file, plot)| (file.clone(), line_plot(plot))).collect())
            }
            Target::Render if args.reference => bench::reference::run(scene, args.quick, &printer)
                .map(|r| (r.to_json(), r.plots.iter().map(drawn).collect()))?,
            Target::Render if args.ca => bench::ca::run(scene, args.quick, &printer)
                .map(|r| (r.to_json(), r.plots.iter().map(drawn).collect()))?,
            Target::Render if args.cm => bench::cm::run(scene, args.quick, &printer)
                .map(|r| (r.to_json(), r.plots.iter().map(drawn).collect()))?,
            Target::Render => bench::gpu::run(scene, args.quick, &printer)
                .map(|r| (r.to_json(), r.plots.iter().map(drawn).collect()))?,
            Target::Server => mrstudy_loadgen::bench(args.quick, &|line| println!("{line}"))
                .map(|r| (r.to_json(), Vec::new()))
                .map_err(|message| anyhow::anyhow!("bench server failed: {message}"))?,
        };
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&document)? + "\n")
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(dir) = &args.plot_dir {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for (name, svg) in plots {
            let path = dir.join(name);
            std::fs::write(&path, svg).with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    Ok(())
}
