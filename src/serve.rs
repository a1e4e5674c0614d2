//! `mrstudy serve`, `mrstudy export` and `mrstudy bench server`: argument parsing and printing
//! around `mrstudy-server`, which does the work.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};

#[derive(Args)]
pub struct ServeArgs {
    /// Address to listen on (port 0: any free port).
    #[arg(long, default_value = "127.0.0.1:8080")]
    addr: String,
    /// Data directory: mrstudy.db, stimuli/, admin-token.
    #[arg(long, default_value = "./mrstudy-data")]
    data_dir: PathBuf,
    /// Directory of study files (*.toml).
    #[arg(long, default_value = "./studies")]
    studies: PathBuf,
}

pub fn run_serve(args: ServeArgs) -> Result<()> {
    mrstudy_server::serve::run(mrstudy_server::serve::ServeConfig {
        addr: args.addr,
        data_dir: args.data_dir,
        studies_dir: args.studies,
        progress: Some(crate::stimuli::progress_bars()),
    })?;
    Ok(())
}

#[derive(Clone, Copy, ValueEnum)]
enum ExportFormat {
    /// The trials CSV (DESIGN.md): one row per answered trial.
    Csv,
    /// Every participant with demographics, client, URL parameters and the whole schedule.
    Json,
    /// The conditions CSV (DESIGN.md) of the study, for `mrstudy analyze --conditions`.
    Conditions,
    /// Task study: the long CSV participant,task,measure,condition,value,… for `mrstudy analyze`.
    Task,
    /// Task study: one row per answered trial with every stored column.
    TaskTrials,
}

#[derive(Args)]
pub struct ExportArgs {
    /// The study's slug.
    #[arg(long)]
    study: String,
    #[arg(long, value_enum, default_value = "csv")]
    format: ExportFormat,
    /// Write here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Data directory that `mrstudy serve` used.
    #[arg(long, default_value = "./mrstudy-data")]
    data_dir: PathBuf,
    /// Keep pilot participants (joined through an admin preview link); left out by default.
    #[arg(long)]
    include_pilots: bool,
    /// Keep participants the researcher excluded; left out by default.
    #[arg(long)]
    include_excluded: bool,
}

pub fn run_export(args: ExportArgs) -> Result<()> {
    let format = match args.format {
        ExportFormat::Csv => mrstudy_server::serve::ExportFormat::Csv,
        ExportFormat::Json => mrstudy_server::serve::ExportFormat::Json,
        ExportFormat::Conditions => mrstudy_server::serve::ExportFormat::Conditions,
        ExportFormat::Task => mrstudy_server::serve::ExportFormat::Task,
        ExportFormat::TaskTrials => mrstudy_server::serve::ExportFormat::TaskTrials,
    };
    let include = mrstudy_server::export::Include { pilots: args.include_pilots, excluded: args.include_excluded };
    let output = match mrstudy_server::serve::export(&args.data_dir, &args.study, format, include) {
        Ok(output) => output,
        Err(message) => bail!("{message}"),
    };
    if let Some(line) = &output.left_out {
        eprintln!("{line}");
    }
    let text = output.text;
    match &args.out {
        Some(path) => std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?,
        None => {
            use std::io::Write;
            std::io::stdout().write_all(text.as_bytes()).context("cannot write to stdout")?;
        }
    }
    Ok(())
}
