//! `mrstudy serve` and `mrstudy export`: argument parsing and printing
//! around `mrstudy-server`, which does the work.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use mrstudy_server::serve::ExportFormat;

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

#[derive(Args)]
pub struct ExportArgs {
    /// The study's slug.
    #[arg(long)]
    study: String,
    /// csv (the trials CSV of DESIGN.md), json (every participant with the whole schedule),
    /// conditions (the conditions CSV), task (a task study's long CSV), task-trials.
    #[arg(long, default_value = "csv", value_parser = crate::choice(ExportFormat::parse, ExportFormat::NAMES))]
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
    let include = mrstudy_server::export::Include { pilots: args.include_pilots, excluded: args.include_excluded };
    let output = match mrstudy_server::serve::export(&args.data_dir, &args.study, args.format, include) {
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
