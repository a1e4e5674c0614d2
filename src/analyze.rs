//! `mrstudy analyze`: reads a trials CSV (paired comparisons, detection trials against the
//! ground truth, or both) or a task CSV (lab tasks), and optionally a stimulus metrics CSV; runs
//! the analysis crate and prints a table or the Analysis JSON, and optionally writes the worth,
//! factor-effect and metric scatter plots.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use mrstudy_analysis::analysis::Options;
use mrstudy_analysis::command::{Drawings, analyze_files};

use crate::Format;

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
    #[command(flatten)]
    options: Options,
}

fn as_pair(file: &(String, String)) -> (&str, &str) {
    (&file.0, &file.1)
}

pub fn run(args: AnalyzeArgs) -> Result<()> {
    let (trials, trials_name) = crate::read_text(&args.trials)?;
    let conditions = args.conditions.as_ref().map(|path| crate::read_text(path)).transpose()?;
    let stimuli = args.stimuli.as_ref().map(|path| crate::read_text(path)).transpose()?;
    let drawings =
        Drawings { worth: args.plot.is_some(), effects: args.effect_plot.is_some(), scatter: args.plot_dir.is_some() };
    let printed = analyze_files(
        (&trials, &trials_name),
        conditions.as_ref().map(as_pair),
        stimuli.as_ref().map(as_pair),
        &args.options,
        args.format == Format::Json,
        drawings,
    )?;
    // everything was rendered before anything is written: no partial output on error
    for (path, svg) in
        args.plot.iter().zip(&printed.worth_plot).chain(args.effect_plot.iter().zip(&printed.effect_plot))
    {
        crate::write_file(path, svg)?;
    }
    if let Some(folder) = &args.plot_dir {
        crate::write_into(folder, printed.scatter_plots)?;
    }
    print!("{}", printed.text);
    Ok(())
}
