//! `mrstudy analyze`: its flags, run by `mrstudy_analysis::command::analyze_request` (a trials
//! or task CSV, optionally conditions and stimulus metrics) over the files, read and written here.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use mrstudy_analysis::analysis::{Options, Scale, Screening};
use mrstudy_analysis::command::{AnalyzeRequest, FileAccess, Format, analyze_request};

flags! {
    AnalyzeArgs => AnalyzeRequest {} {
        /// Trials CSV (`participant,left,right,chosen`, as `mrstudy export` writes) or a task CSV (`participant,condition,value`).
        #[arg(long)] trials: PathBuf,
        /// Conditions CSV (`condition,<factor>,…`) for the factor model.
        #[arg(long)] conditions: Option<PathBuf>,
        /// Stimulus metrics CSV (`stimulus,scene,condition,metric,region,value`, as `mrstudy stimuli --metrics` writes): which image error predicts preference.
        #[arg(long)] stimuli: Option<PathBuf>,
        #[arg(long, default_value = "table", value_parser = crate::values(Format::NAMES))] format: Format,
        /// Write the worth plot (SVG) here.
        #[arg(long)] plot: Option<PathBuf>,
        /// Write the factor-effect plot (SVG) here.
        #[arg(long)] effect_plot: Option<PathBuf>,
        /// With --stimuli: write one scatter plot per metric × region (`metric-<metric>-<region>.svg`) into this folder.
        #[arg(long)] plot_dir: Option<PathBuf>,
        #[command(flatten)] options: OptionsFlags,
    }
}

flags! {
    /// [`Options`]' flags; their defaults are its `Default`.
    OptionsFlags => Options { ..Options::default() } {
        /// Reference condition (log-worth 0); default: first of the conditions file, else first by name.
        #[arg(long)] reference: Option<String>,
        /// Factor-model formula, e.g. `gi+cm+ca+gi:ca` or `gi*ca+cm`; default: all factors, main effects.
        #[arg(long)] model: Option<String>,
        /// Fit everything per value of this column (e.g. `gender`) and test whether effects differ.
        #[arg(long)] group_by: Option<String>,
        /// Convergence tolerance (largest parameter change).
        #[arg(long, default_value_t = Options::default().tolerance)] tolerance: f64,
        /// Bootstrap replicates over participants for intervals (0: none; with --stimuli the metric correlations use 1000 unless given).
        #[arg(long, default_value_t = Options::default().bootstrap)] bootstrap: usize,
        /// Seed for the bootstrap and the agreement simulation.
        #[arg(long, default_value_t = Options::default().seed)] seed: u64,
        /// Observer screening (leave-one-out); `auto` runs it for up to 200 conditions.
        #[arg(long = "screen", default_value = "auto", value_parser = crate::values(Screening::NAMES))] screening: Screening,
        /// Use Firth's bias-reduced estimate for every model, not only under separation.
        #[arg(long = "firth")] always_firth: bool,
        /// Keep participants marked `pilot = true` in the trials CSV (default: left out, and said so).
        #[arg(long)] include_pilots: bool,
        /// Keep participants marked `excluded = true` in the trials CSV (default: left out, and said so).
        #[arg(long)] include_excluded: bool,
        /// `jod`: also pwcmp's JOD scale (Thurstone Case V, 1 JOD = 75 %) per condition, its outlier analysis and, with --bootstrap, its intervals; for a threshold export `log10`, `dB` or `linear` fits on that stimulus scale instead of the export's.
        #[arg(long, default_value = "bt", value_parser = crate::values(Scale::NAMES))] scale: Scale,
        /// Threshold exports: the psychometric function to fit (`weibull`, `logistic`, `normal`) instead of the export's `function`.
        #[arg(long)] function: Option<String>,
        /// Threshold exports: the guess rate to fit with (e.g. 0.5 for 2AFC) instead of the export's `guess`.
        #[arg(long)] guess: Option<f64>,
        /// Prior sd of each log-worth for `log_worth_map`, the centred MAP log-worths (a study's `prior_sd`; default 1).
        #[arg(long, default_value_t = Options::default().prior_sd)] prior_sd: f64,
    }
}

pub fn run(args: AnalyzeArgs) -> Result<()> {
    let read = |path: &Path| std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()));
    let write = |path: &Path, text: &str| {
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
    };
    let create_dir =
        |dir: &Path| std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()));
    print!("{}", analyze_request(&args.into(), FileAccess { read: &read, write: &write, create_dir: &create_dir })?);
    Ok(())
}
