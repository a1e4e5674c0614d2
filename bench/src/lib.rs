//! `mrstudy-bench`: every benchmark of `mrstudy bench` behind one call. [`run`] picks the
//! experiment by [`Target`] and [`Options`] — the renderer's (`mrstudy_renderer::bench`: GPU
//! frame time and error, the reference path tracer, ca and cm accuracy), the analysis's
//! (`mrstudy_analysis::bench`, `mrstudy_analysis::active::bench`) or the server's load
//! generator ([`server`]) — and returns a [`Measured`]: docs/design.md's bench JSON and the curves
//! drawn as SVG. Each experiment's typed report stays in the crate it measures.

pub mod server;

use mrstudy_analysis::plot::{LinePlot, LineSeries, line_plot};
use std::path::{Path, PathBuf};

use mrstudy_renderer::bench::{self as render, Observer, Plot};
use mrstudy_renderer::command::Said;

/// What `mrstudy bench` measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// Active pair selection: choice time against conditions × judgments, posterior updates against the refit.
    Active,
    /// Bradley–Terry analysis: time against data size and against convergence tolerance.
    Analysis,
    /// Rendering: the GPU renderer's frame time and error against the path-traced ground truth over VPL counts; with `--reference`, the CPU reference path tracer's samples/s and error against a high-spp render; with `--ca`, noise and blur on the virtual objects against the camera's, ca off/on; with `--gi-methods`, DIR against EM, DIT and VCT; with `--frame-rate`, the thesis's real-time settings frame after frame; with `--paper-tables`, Rohmer et al.'s Tables 2–4.
    Render,
    /// Web survey server: responses/s and latency percentiles with durable writes, concurrent simulated participants over loopback.
    Server,
}

/// How a benchmark runs: `mrstudy bench`'s flags (the doc comments are their help).
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct Options {
    /// Smaller sizes only (for a quick check).
    #[arg(long)]
    pub quick: bool,
    /// bench render: measure the CPU reference path tracer.
    #[arg(long)]
    pub reference: bool,
    /// bench render: the ca factor's accuracy — noise and blur on the virtual objects against
    /// the camera's (ground truth), ca off / scene / estimated parameters, per scene and preset.
    #[arg(long, conflicts_with_all = ["reference", "cm"])]
    pub ca: bool,
    /// bench render: each colour-mapping (cm) method's CIEDE2000 on the virtual objects against the ground truth through the known camera, over camera presets and settings.
    #[arg(long, conflicts_with = "reference")]
    pub cm: bool,
    /// bench render: the global-illumination methods a study can compare — DIR over VPL counts against Rohmer et al.'s EM, DIT and VCT at low/med/high and gi off: time per stage and FLIP/RMSE against the ground truth, every built-in scene.
    #[arg(long = "gi-methods", conflicts_with_all = ["reference", "ca", "cm"])]
    pub gi_methods: bool,
    /// bench render: the thesis's real-time settings at 1024×768 (256 VPLs, 128² ISMs, 4×4
    /// tiles, 512² caustic maps), 30 frames back to back per scene and condition: median and
    /// percentile frame times, fps and each pass's median — for a hardware GPU; no ground truth.
    #[arg(long = "frame-rate", conflicts_with_all = ["reference", "ca", "cm", "gi_methods"])]
    pub frame_rate: bool,
    /// bench render: Rohmer et al.'s Tables 2–4 (the rendering phase per quality setting, the
    /// queries over N with and without visibility, the differential background over N and the
    /// cache) at 640×360 on one scene (default survey-1), each cell beside the paper's GTX 980 number.
    #[arg(long = "paper-tables", conflicts_with_all = ["reference", "ca", "cm", "gi_methods", "frame_rate"])]
    pub paper_tables: bool,
    /// bench render: the scene (default: DIR scenes on the GPU, survey-1 with --reference, every built-in scene with --cm and --gi-methods).
    #[arg(long)]
    pub scene: Option<String>,
    /// bench server: the database — sqlite (a file in a temporary data directory), or
    /// postgres: the PostgreSQL server of MRSTUDY_DATABASE_URL, or of a postgres:// URL given
    /// here. The benchmark makes a database of its own there for each row and drops it after.
    #[arg(long, value_name = "sqlite|postgres|URL", default_value = "sqlite")]
    pub database: String,
    /// bench server: mrstudy serve processes on the one database (more than one needs
    /// PostgreSQL); every simulated participant sends its requests to them in turn.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=8))]
    pub processes: u16,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            quick: false,
            reference: false,
            ca: false,
            cm: false,
            gi_methods: false,
            frame_rate: false,
            paper_tables: false,
            scene: None,
            database: "sqlite".into(),
            processes: 1,
        }
    }
}

/// A benchmark's result: docs/design.md's bench JSON (`{"adapter": ..., "rows": [...]}`) and its
/// curves as (SVG file name, SVG text).
#[derive(Clone, Debug)]
pub struct Measured {
    pub json: serde_json::Value,
    pub plots: Vec<(String, String)>,
}

/// Why a benchmark could not finish.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    #[error(transparent)]
    Render(#[from] mrstudy_renderer::RenderError),
    #[error(transparent)]
    Analysis(#[from] mrstudy_analysis::AnalysisError),
    #[error("bench server: {0}")]
    Server(String),
    #[error("cannot start the benchmark's thread pool: {0}")]
    Threads(#[from] rayon::ThreadPoolBuildError),
    #[error("cannot create {}", path.display())]
    CreateDir { path: PathBuf, source: std::io::Error },
    #[error("cannot write {}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
}

/// `mrstudy bench`'s command line: the benchmark, where its rows and curves go, its options.
#[derive(Clone, Debug, clap::Args)]
pub struct BenchArgs {
    #[arg(value_enum)]
    pub target: Target,
    /// Write the rows as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write SVG plots of the curves into this directory.
    #[arg(long)]
    pub plot_dir: Option<PathBuf>,
    #[command(flatten)]
    pub options: Options,
}

/// Runs the benchmark of `args` (as `mrstudy bench`): its table lines, notes and progress are
/// said as it runs; then its JSON (`{"adapter": ..., "rows": [...]}`, docs/design.md) is
/// written to `--json` and its curves as SVG into `--plot-dir`.
pub fn run_to_files(args: &BenchArgs, say: &(dyn Fn(Said) + Sync)) -> Result<(), BenchError> {
    let measured = run(args.target, &args.options, &Saying(say))?;
    let (json, plot_dir) = (args.json.as_deref(), args.plot_dir.as_deref());
    let write = |path: &Path, text: &str| {
        std::fs::write(path, text).map_err(|source| BenchError::Write { path: path.to_path_buf(), source })
    };
    if let Some(path) = json {
        write(path, &(serde_json::to_string_pretty(&measured.json).expect("a JSON value prints") + "\n"))?;
    }
    if let Some(dir) = plot_dir {
        std::fs::create_dir_all(dir).map_err(|source| BenchError::CreateDir { path: dir.to_path_buf(), source })?;
        measured.plots.iter().try_for_each(|(name, svg)| write(&dir.join(name), svg))?;
    }
    Ok(())
}

/// The renderer benchmarks' [`Observer`] over what a command says.
struct Saying<'a>(&'a (dyn Fn(Said) + Sync));

impl Observer for Saying<'_> {
    fn line(&self, text: &str) {
        (self.0)(Said::Out(&format!("{text}\n")));
    }
    fn note(&self, text: &str) {
        (self.0)(Said::Note(text));
    }
    fn progress(&self, label: &str, done: u32, total: u32) {
        (self.0)(Said::Progress { label, unit: "spp", done: done as u64, total: total as u64 });
    }
}

/// Runs the benchmark `target` with `options`; its table lines, notes and progress go to
/// `observer` as it runs.
pub fn run(target: Target, options: &Options, observer: &dyn Observer) -> Result<Measured, BenchError> {
    let scene = options.scene.as_deref();
    let quick = options.quick;
    let line = |text: &str| observer.line(text);
    if target != Target::Server && (options.database != "sqlite" || options.processes != 1) {
        return Err(BenchError::Server("--database and --processes are flags of bench server only.".into()));
    }
    let drawn =
        |plots: &[(String, LinePlot)]| plots.iter().map(|(file, plot)| (file.clone(), line_plot(plot))).collect();
    Ok(match target {
        Target::Analysis => {
            // one core, as the targets are stated for one core of the 2-core machine
            let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
            let report = pool.install(|| mrstudy_analysis::bench::run(quick, &line))?;
            Measured { json: report.to_json(), plots: drawn(&report.plots) }
        }
        Target::Active => {
            let report = mrstudy_analysis::active::bench::run(quick, &line)?;
            Measured { json: report.to_json(), plots: drawn(&report.plots) }
        }
        Target::Render if options.reference => rendered(render::reference::run(scene, quick, observer)?),
        Target::Render if options.ca => rendered(render::ca::run(scene, quick, observer)?),
        Target::Render if options.cm => rendered(render::cm::run(scene, quick, observer)?),
        Target::Render if options.gi_methods => rendered(render::methods::run(scene, quick, observer)?),
        Target::Render if options.frame_rate => rendered(render::frame_rate::run(scene, quick, observer)?),
        Target::Render if options.paper_tables => rendered(render::paper_tables::run(scene, quick, observer)?),
        Target::Render => rendered(render::gpu::run(scene, quick, observer)?),
        Target::Server => {
            let environment = std::env::var("MRSTUDY_DATABASE_URL").ok();
            let database =
                server::Backing::parse(Some(&options.database), environment.as_deref()).map_err(BenchError::Server)?;
            let report =
                server::bench(quick, &database, options.processes.into(), &line).map_err(BenchError::Server)?;
            Measured { json: report.to_json(), plots: Vec::new() }
        }
    })
}

/// A renderer benchmark's report with its plots drawn.
fn rendered<R: serde::Serialize>(report: render::Report<R>) -> Measured {
    Measured { json: report.to_json(), plots: report.plots.iter().map(svg).collect() }
}

/// The renderer's plot as an SVG file name and text.
fn svg(plot: &Plot) -> (String, String) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Command {
        #[command(flatten)]
        options: Options,
    }

    #[test]
    fn an_empty_command_line_gives_the_default_options() {
        assert_eq!(Command::try_parse_from(["bench"]).unwrap().options, Options::default());
    }

    #[test]
    fn database_names_a_backing_or_says_what_is_wrong() {
        use server::Backing;
        assert_eq!(Backing::parse(Some("sqlite"), Some("postgres://x@h/postgres")), Ok(Backing::Sqlite));
        assert_eq!(
            Backing::parse(Some("postgres"), Some("postgres://x@h:5/postgres")),
            Ok(Backing::Postgres { server_url: "postgres://x@h:5/postgres".into() })
        );
        assert_eq!(
            Backing::parse(Some("postgresql://y@h/postgres"), None),
            Ok(Backing::Postgres { server_url: "postgresql://y@h/postgres".into() })
        );
        let unset = Backing::parse(Some("postgres"), None).unwrap_err();
        assert!(unset.contains("MRSTUDY_DATABASE_URL"), "{unset}");
        let wrong = Backing::parse(Some("mysql://h"), None).unwrap_err();
        assert!(wrong.contains("`mysql://h`"), "{wrong}");
    }

    #[test]
    fn two_processes_on_sqlite_are_refused_with_a_sentence() {
        let refused = server::bench(true, &server::Backing::Sqlite, 2, &|_| {}).unwrap_err();
        assert!(refused.contains("needs PostgreSQL"), "{refused}");
    }

    struct Quiet;

    impl Observer for Quiet {
        fn line(&self, _: &str) {}
        fn note(&self, _: &str) {}
        fn progress(&self, _: &str, _: u32, _: u32) {}
    }

    #[test]
    fn server_flags_on_another_benchmark_are_refused() {
        let options = Options { processes: 2, ..Options::default() };
        let refused = run(Target::Analysis, &options, &Quiet).unwrap_err().to_string();
        assert!(refused.contains("bench server only"), "{refused}");
    }
}
