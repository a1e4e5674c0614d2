//! `mrstudy`: the command line. Thin by design: it parses arguments, reads and writes files,
//! calls the library crates and turns one `anyhow::Result` into an exit code. Errors are printed
//! to stderr as one sentence.

use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use mrstudy_server::serve::ServeConfig;

mod analyze;
mod bench;
mod capture;
mod export;
mod progress;
mod render;
mod simulate;
mod stimuli;

#[derive(Parser)]
#[command(
    name = "mrstudy",
    version,
    about = "Perceptual studies of mixed-reality rendering: render stimuli, run studies, analyse judgments."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Analyse paired-comparison trials (Bradley–Terry worth, factor effects, agreement) or lab-task results (Friedman tests).
    Analyze(analyze::AnalyzeArgs),
    /// Measure speed (and error against a reference) of a part of mrstudy.
    Bench(bench::BenchArgs),
    /// Simulate an RGB-D capture of a scene's real objects (depth sensor, plane-fit normals, hash grid of environment samples) and report its error against the true geometry.
    Capture(capture::CaptureArgs),
    /// Render a scene: the reference photograph or ground-truth composite (CPU path tracer); `--list` names the built-in scenes.
    Render(render::RenderArgs),
    /// Run the web survey server: migrate the database, load the studies, print the participant and admin links.
    Serve(ServeConfig),
    /// Render every stimulus a study needs (the photograph by the path tracer, each condition on the GPU), with a progress bar.
    Stimuli(stimuli::StimuliArgs),
    /// Write a study's trials CSV (or JSON, or conditions CSV) from the database.
    Export(export::ExportArgs),
    /// Simulate a study (its real scheduler and analysis, simulated observers): RMSE, coverage and power per design and participant count.
    Simulate(simulate::SimulateArgs),
    /// The participants a study needs per factor for a target power, by simulation.
    Power(simulate::PowerArgs),
}

/// A clap value parser from a library's `parse` (the names it accepts are listed on refusal).
fn choice<T: Clone + Send + Sync + 'static>(
    parse: fn(&str) -> Option<T>,
    names: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    move |text| parse(text).ok_or_else(|| format!("`{text}` is not one of {names}"))
}

/// How `analyze` and `simulate` print their result.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Format {
    Table,
    Json,
}

/// A file's text, and its name for messages.
fn read_text(path: &Path) -> Result<(String, String)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok((text, path.display().to_string()))
}

/// Writes each (file name, text) into `dir`, creating it first.
fn write_into(dir: &Path, files: impl IntoIterator<Item = (String, String)>) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    files.into_iter().try_for_each(|(name, text)| write_file(&dir.join(name), &text))
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Analyze(args) => analyze::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Render(args) => render::run(args),
        Command::Capture(args) => capture::run(args),
        Command::Serve(config) => {
            let progress = Some(progress::stimulus_bars());
            mrstudy_server::serve::run(ServeConfig { progress, ..config }).map_err(Into::into)
        }
        Command::Export(args) => export::run(args),
        Command::Stimuli(args) => stimuli::run(args),
        Command::Simulate(args) => simulate::run_simulate(args),
        Command::Power(args) => simulate::run_power(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // One sentence: the outermost context, then its causes.
            let causes: Vec<String> = error.chain().map(|e| e.to_string()).collect();
            eprintln!("error: {}", causes.join(": "));
            ExitCode::FAILURE
        }
    }
}
