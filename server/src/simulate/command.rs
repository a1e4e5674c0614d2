//! `mrstudy simulate` and `mrstudy power` as functions over a plain [`StudyRequest`]: read the
//! study and the truth, simulate it (a threshold study by [`simulate_threshold`], every other
//! by [`simulate`]) with its progress, say the table or JSON (or `power`'s sentences) and
//! write the plots.

use std::path::{Path, PathBuf};

use mrstudy_analysis::plot::{LinePlot, line_plot};
use mrstudy_renderer::command::Said;
use thiserror::Error;

use super::threshold::{ThresholdConfig, ThresholdSimulateError, simulate_threshold};
use super::{Config, DesignChoice, Options, SimulateError, choose_truth, power_report, simulate};
use crate::study::{Study, StudyError, load_study};

/// What `simulate` and `power` share: the study, the truth, the observers, the runs.
#[derive(Debug, Clone)]
pub struct StudyRequest {
    /// The study file, whose scheduler and conditions are simulated.
    pub study: PathBuf,
    /// True factor effects (`gi=0.3,…`), or a threshold study's `threshold=T,slope=B`.
    pub truth: Option<String>,
    /// A CSV of true log-worths, `condition,log_worth`.
    pub truth_worth: Option<PathBuf>,
    pub options: Options,
    /// Threshold studies: trials per participant to simulate.
    pub trials_per_participant: Vec<u32>,
}

/// Why `simulate` or `power` did not report.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SimulateCommandError {
    #[error(transparent)]
    Study(#[from] StudyError),
    #[error("cannot read {}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Simulate(#[from] SimulateError),
    #[error(transparent)]
    Threshold(#[from] ThresholdSimulateError),
    /// An option a threshold study does not take, and what it takes instead.
    #[error("{0}")]
    NotForThreshold(&'static str),
    #[error("cannot create {}", path.display())]
    CreateDir { path: PathBuf, source: std::io::Error },
    #[error("cannot write {}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// `mrstudy simulate`: the table (or with `json` the report's JSON), and the plots into
/// `plot_dir`.
pub fn simulate_command(
    request: &StudyRequest,
    participants: &[u32],
    json: bool,
    plot_dir: Option<&Path>,
    say: &(dyn Fn(Said) + Sync),
) -> Result<(), SimulateCommandError> {
    let (text, plots) = match run(request, participants, say)? {
        Simulated::Threshold(report) => (text(&report, report.table(), json)?, report.plots()),
        Simulated::Study(report) => (text(&report, report.table(), json)?, report.plots()),
    };
    say(Said::Out(&text));
    plot_dir.map_or(Ok(()), |dir| write_plots(dir, plots))
}

/// `mrstudy power`: per factor (or for a threshold study, per method) the participants that
/// reach `target` power.
pub fn power_command(
    request: &StudyRequest,
    participants: &[u32],
    target: f64,
    say: &(dyn Fn(Said) + Sync),
) -> Result<(), SimulateCommandError> {
    let lines = match run(request, participants, say)? {
        Simulated::Threshold(report) => report.power_lines(target),
        Simulated::Study(report) => power_report(&report, target)?,
    };
    lines.iter().for_each(|line| say(Said::Out(&format!("{line}\n"))));
    Ok(())
}

enum Simulated {
    Study(super::Report),
    Threshold(super::threshold::ThresholdReport),
}

fn run(
    request: &StudyRequest,
    participants: &[u32],
    say: &(dyn Fn(Said) + Sync),
) -> Result<Simulated, SimulateCommandError> {
    let study = load_study(&request.study)?;
    if study.threshold.is_some() {
        return Ok(Simulated::Threshold(run_threshold(request, &study, say)?));
    }
    let worths = match &request.truth_worth {
        Some(path) => Some(
            std::fs::read_to_string(path)
                .map(|text| (text, path.display().to_string()))
                .map_err(|source| SimulateCommandError::Read { path: path.clone(), source })?,
        ),
        None => None,
    };
    let worths = worths.as_ref().map(|(text, name)| (text.as_str(), name.as_str()));
    let truth = choose_truth(&study, request.truth.as_deref(), worths)?;
    let participants = participants.iter().map(|&count| count as usize).collect();
    let config = Config { truth, participants, options: request.options.clone() };
    let progress = progress(say, "runs");
    Ok(Simulated::Study(simulate(&study, &config, &progress)?))
}

fn run_threshold(
    request: &StudyRequest,
    study: &Study,
    say: &(dyn Fn(Said) + Sync),
) -> Result<super::threshold::ThresholdReport, SimulateCommandError> {
    let refuse = |why| Err(SimulateCommandError::NotForThreshold(why));
    if request.truth_worth.is_some() {
        return refuse(
            "--truth-worth gives log-worths of conditions; a threshold study takes --truth threshold=T,slope=B",
        );
    }
    if request.options.dropout != 0.0 {
        return refuse(
            "--dropout does not apply to a threshold study (every simulated participant answers all trials)",
        );
    }
    if request.options.designs != [DesignChoice::Study] {
        return refuse(
            "--designs does not apply to a threshold study: QUEST+ and constant stimuli are always compared",
        );
    }
    let options = &request.options;
    let config = ThresholdConfig {
        trials: request.trials_per_participant.iter().map(|&n| n as usize).collect(),
        truth: request.truth.clone(),
        threshold_sd: options.observer_sd,
        lapse: options.lapse,
        runs: options.runs,
        seed: options.seed,
        bootstrap: options.bootstrap,
    };
    Ok(simulate_threshold(study, &config, &progress(say, "participants"))?)
}

/// Progress of the simulation in `unit`s (its bar shows from the start, its length unknown).
fn progress<'a>(say: &'a (dyn Fn(Said) + Sync), unit: &'a str) -> impl Fn(u64, u64) + Sync + 'a {
    say(Said::Progress { label: "simulating", unit, done: 0, total: 0 });
    move |done, total| say(Said::Progress { label: "simulating", unit, done, total })
}

/// The table, or the report as JSON (one line end after it).
fn text(report: &impl serde::Serialize, table: String, json: bool) -> Result<String, serde_json::Error> {
    Ok(if json { serde_json::to_string_pretty(report)? + "\n" } else { table })
}

fn write_plots(dir: &Path, plots: Vec<(String, LinePlot)>) -> Result<(), SimulateCommandError> {
    std::fs::create_dir_all(dir).map_err(|source| SimulateCommandError::CreateDir { path: dir.into(), source })?;
    plots.into_iter().try_for_each(|(name, plot)| {
        let path = dir.join(name);
        std::fs::write(&path, line_plot(&plot)).map_err(|source| SimulateCommandError::Write { path, source })
    })
}
