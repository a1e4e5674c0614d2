//! `mrstudy analyze`: reads a trials CSV (paired comparisons) or a task CSV (lab tasks), runs the
//! analysis crate and prints a table or the Analysis JSON, and optionally writes a worth plot.

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
    /// Bootstrap replicates over participants for intervals (0: none).
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
        if args.conditions.is_some() || args.model.is_some() || args.plot.is_some() || args.effect_plot.is_some() {
            bail!(
                "{trials_name} is a task CSV (participant,condition,value): --conditions, --model and --plot apply to paired comparisons only"
            );
        }
        let analysis = mrstudy_analysis::task::analyze_task_csv(&trials, &trials_name)?;
        match args.format {
            Format::Json => println!("{}", serde_json::to_string_pretty(&analysis)?),
            Format::Table => print!("{}", mrstudy_analysis::task::render_table(&analysis)),
        }
        return Ok(());
    }
    let conditions = args.conditions.as_ref().map(read).transpose()?;
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
    let analysis = mrstudy_analysis::analysis::analyze_named(
        &trials,
        &trials_name,
        conditions.as_deref().map(|text| (text, conditions_name.as_str())),
        &options,
    )?;
    // Render everything before writing anything: no partial output on error.
    let text = match args.format {
        Format::Json => serde_json::to_string_pretty(&analysis)? + "\n",
        Format::Table => mrstudy_analysis::table::render(&analysis),
    };
    let effects = match &args.effect_plot {
        Some(path) => Some((
            path,
            analysis.effect_plot().ok_or_else(|| {
                anyhow::anyhow!("--effect-plot needs a factor model: give --conditions with factor columns")
            })?,
        )),
        None => None,
    };
    if let Some(path) = &args.plot {
        std::fs::write(path, analysis.worth_plot()).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some((path, svg)) = effects {
        std::fs::write(path, svg).with_context(|| format!("cannot write {}", path.display()))?;
    }
    print!("{text}");
    Ok(())
}
