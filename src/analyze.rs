//! `mrstudy analyze`: reads a trials CSV (paired comparisons, detection trials against the
//! ground truth, or both) or a task CSV (lab tasks), and optionally a stimulus metrics CSV; runs
//! the analysis crate and prints a table or the Analysis JSON, and optionally writes the worth,
//! factor-effect and metric scatter plots.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use mrstudy_analysis::analysis::{Options, Screening};

#[derive(Clone, Copy, ValueEnum)]
pub enum Format {
    Table,
    Json,
}

#[derive(Args)]
pub struct AnalyzeArgs {
    /// Trials CSV (`participant,left,right,chosen`, as `mrstudy export` writes) or a task CSV (`participant,condition,value`).
    #[arg(long)]
    trials: PathBuf,
    /// Conditions CSV (`condition,<factor>,…`) for the factor model.
    #[arg(long)]
    conditions: Option<PathBuf>,
    /// Stimulus metrics CSV (`stimulus,scene,condition,metric,region,value`, as `mrstudy stimuli --metrics` writes): which image error predicts preference.
    #[arg(long)]
    stimuli: Option<PathBuf>,
    /// Fit everything per value of this column (e.g. `gender`) and test whether effects differ.
    #[arg(long)]
    group_by: Option<String>,
    /// Reference condition (log-worth 0); default: first of the conditions file, else first by name.
    #[arg(long)]
    reference: Option<String>,
    /// Factor-model formula, e.g. `gi+cm+ca+gi:ca` or `gi*ca+cm`; default: all factors, main effects.
    #[arg(long)]
    model: Option<String>,
    #[arg(long, value_enum, default_value = "table")]
    format: Format,
    /// Write the worth plot (SVG) here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Write the factor-effect plot (SVG) here.
    #[arg(long)]
    effect_plot: Option<PathBuf>,
    /// With --stimuli: write one scatter plot per metric × region (`metric-<metric>-<region>.svg`) into this folder.
    #[arg(long)]
    plot_dir: Option<PathBuf>,
    /// Bootstrap replicates over participants for intervals (0: none; with --stimuli the metric correlations use 1000 unless given).
    #[arg(long, default_value_t = 0)]
    bootstrap: usize,
    /// Seed for the bootstrap and the agreement simulation.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Observer screening (leave-one-out); `auto` runs it for up to 200 conditions.
    #[arg(long, default_value = "auto", value_parser = crate::choice(Screening::parse, "auto, on, off"))]
    screen: Screening,
    /// Use Firth's bias-reduced estimate for every model, not only under separation.
    #[arg(long)]
    firth: bool,
    /// Convergence tolerance (largest parameter change).
    #[arg(long, default_value_t = 1e-10)]
    tolerance: f64,
    /// Keep participants marked `pilot = true` in the trials CSV (default: left out, and said so).
    #[arg(long)]
    include_pilots: bool,
    /// Keep participants marked `excluded = true` in the trials CSV (default: left out, and said so).
    #[arg(long)]
    include_excluded: bool,
}

fn read(path: &PathBuf) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}

/// Task CSVs have a `value` column and no `left`/`right`.
fn is_task_csv(text: &str) -> bool {
    let header = text.lines().next().unwrap_or("");
    let columns: Vec<&str> = header.split(',').map(|c| c.trim().trim_matches('"')).collect();
    columns.contains(&"value") && columns.contains(&"condition") && !columns.contains(&"left")
}

pub fn run(args: AnalyzeArgs) -> Result<()> {
    let trials = read(&args.trials)?;
    let trials_name = args.trials.display().to_string();
    if is_task_csv(&trials) {
        if args.conditions.is_some()
            || args.model.is_some()
            || args.plot.is_some()
            || args.effect_plot.is_some()
            || args.stimuli.is_some()
            || args.plot_dir.is_some()
        {
            bail!(
                "{trials_name} is a task CSV (participant,condition,value): --conditions, --model, --stimuli and the plots apply to paired comparisons only"
            );
        }
        let analysis = mrstudy_analysis::task::analyze_task_csv(&trials, &trials_name)?;
        match args.format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&analysis)?),
            Format::Table => print!("{}", mrstudy_analysis::task::render_table(&analysis)),
        }
        return Ok(());
    }
    if args.plot_dir.is_some() && args.stimuli.is_none() {
        bail!("--plot-dir holds the metric scatter plots: give --stimuli with a stimulus metrics CSV");
    }
    let conditions = args.conditions.as_ref().map(read).transpose()?;
    let stimuli = args.stimuli.as_ref().map(read).transpose()?;
    let stimuli_name = args.stimuli.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    let conditions_name = args.conditions.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    let options = Options {
        reference: args.reference,
        model: args.model,
        group_by: args.group_by,
        tolerance: args.tolerance,
        bootstrap: args.bootstrap,
        seed: args.seed,
        screening: args.screen,
        always_firth: args.firth,
        include_pilots: args.include_pilots,
        include_excluded: args.include_excluded,
        ..Options::default()
    };
    let report = mrstudy_analysis::report::analyze_named(
        &trials,
        &trials_name,
        conditions.as_deref().map(|text| (text, conditions_name.as_str())),
        stimuli.as_deref().map(|text| (text, stimuli_name.as_str())),
        &options,
    )?;
    // Render everything before writing anything: no partial output on error.
    let text = match args.format {
        Format::Json => serde_json::to_string_pretty(&report)? + "\n",
        Format::Table => mrstudy_analysis::table::render_report(&report),
    };
    let preference = || {
        report.preference.as_ref().ok_or_else(|| {
            anyhow::anyhow!(
                "{trials_name} has only detection trials (one side `ground-truth`): there is no worth or effect to plot"
            )
        })
    };
    let mut files: Vec<(PathBuf, String)> = Vec::new();
    if let Some(path) = &args.plot {
        files.push((path.clone(), preference()?.worth_plot()));
    }
    if let Some(path) = &args.effect_plot {
        let svg = preference()?.effect_plot().ok_or_else(|| {
            anyhow::anyhow!("--effect-plot needs a factor model: give --conditions with factor columns")
        })?;
        files.push((path.clone(), svg));
    }
    if let Some(folder) = &args.plot_dir {
        let metrics = report.metrics.as_ref().ok_or_else(|| {
            anyhow::anyhow!(
                "{trials_name} has no preference trials to set the stimulus metrics beside: no scatter plots"
            )
        })?;
        std::fs::create_dir_all(folder).with_context(|| format!("cannot create {}", folder.display()))?;
        files.extend(metrics.scatter_plots().into_iter().map(|(name, svg)| (folder.join(name), svg)));
    }
    for (path, svg) in files {
        std::fs::write(&path, svg).with_context(|| format!("cannot write {}", path.display()))?;
    }
    print!("{text}");
    Ok(())
}
