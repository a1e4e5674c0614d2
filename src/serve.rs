//! `mrstudy serve`, `mrstudy export` and `mrstudy bench server`: argument parsing and printing
//! around `mrstudy-server`, which does the work.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use serde_json::{Value, json};

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

/// `bench server`: prints the table and returns the bench JSON (DESIGN.md) of the server's load
/// generator.
pub fn bench_server(quick: bool) -> Result<Value> {
    let durations = if quick { 3 } else { 10 };
    let concurrency: &[usize] = if quick { &[64] } else { &[16, 64, 256] };
    println!(
        "{:>12} {:>8} {:>11} {:>9} {:>9} {:>9} {:>9} {:>10} {:>7}",
        "participants", "seconds", "responses/s", "p50 ms", "p90 ms", "p99 ms", "max ms", "next p99", "errors"
    );
    let mut rows = Vec::new();
    for &participants in concurrency {
        let report = mrstudy_server::bench::run(mrstudy_server::bench::BenchConfig {
            participants,
            duration: Duration::from_secs(durations),
        })
        .map_err(|message| anyhow::anyhow!("bench server failed: {message}"))?;
        println!(
            "{:>12} {:>8.1} {:>11.0} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>10.2} {:>7}",
            report.participants,
            report.seconds,
            report.responses_per_s,
            report.response_p50_ms,
            report.response_p90_ms,
            report.response_p99_ms,
            report.response_max_ms,
            report.next_p99_ms,
            report.errors
        );
        rows.push(json!({
            "bench": "server",
            "participants": report.participants,
            "ms": report.response_p50_ms,
            "responses_per_s": report.responses_per_s,
            "responses": report.responses,
            "seconds": report.seconds,
            "response_p50_ms": report.response_p50_ms,
            "response_p90_ms": report.response_p90_ms,
            "response_p99_ms": report.response_p99_ms,
            "response_max_ms": report.response_max_ms,
            "next_p50_ms": report.next_p50_ms,
            "next_p99_ms": report.next_p99_ms,
            "errors": report.errors,
            "durability": "sqlite WAL, synchronous=FULL, group commit",
        }));
    }
    Ok(json!({ "adapter": "none (server: HTTP/1.1 over loopback, sqlite on the local file system)", "rows": rows }))
}
