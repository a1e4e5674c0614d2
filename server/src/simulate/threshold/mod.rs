//! Planning a threshold study (`kind = "threshold"`) by simulation: how precisely a
//! participant's threshold comes out of their trials, for the study's **own QUEST+ selection**
//! ([`crate::threshold::quest_config`] over [`crate::threshold::domain`], the choice the server
//! makes for each trial) against a **method of constant stimuli** on the same levels, each
//! analysed by the **real psychometric fit** ([`mrstudy_analysis::threshold::fit::fit`], as
//! `mrstudy analyze` fits a participant).
//!
//! **Observers.** A known psychometric function: the study's `function`, `scale` and `guess`,
//! a true threshold `t` and slope `β` (`--truth threshold=T,slope=B`, x units; defaults: the
//! middle of the levels' x range and the middle value of the study's slope grid) and the lapse
//! rate `--lapse`. Participant i's threshold is t + N(0, sd²) (`--observer-sd`, x units; on the
//! `linear` scale's Weibull, whose threshold must stay positive, t·exp(N(0, sd²))); each answer
//! is correct with the function's probability at the level's x.
//!
//! **Methods.** `quest+`: every trial's level is QUEST+'s minimum-expected-entropy choice from
//! the participant's answers so far (the study's grids; the server replays the same updates).
//! `constant-stimuli`: the trials spread evenly over the study's levels (⌊n / L⌋ each, the
//! remaining n mod L at distinct levels drawn at random).
//!
//! **Scores, per method × trials per participant**, over `--runs` simulated participants: the
//! threshold estimate's bias and RMSE against the participant's own true threshold (x units),
//! the coverage of its 95 % parametric-bootstrap interval (`--bootstrap N` replicates, 200 —
//! `analyze`'s default — when 0), the mean interval width, the share of participants whose
//! estimate lies within ±[`TOLERANCE_LOG10`] log10 units of their threshold (2 dB on the dB
//! scale, 0.1 x units on the linear scale), and the share whose fit is degenerate (all correct,
//! all wrong: no estimate, counted as not within the tolerance). Each with its Monte-Carlo
//! standard error.
//!
//! **Reproducible.** Participant r of method m at n trials has the seed
//! `derived_seed(derived_seed(derived_seed(seed, 10 + m), n), r)`; the observer draws from a
//! ChaCha8 stream of it and its fit's bootstrap from the same seed. Participants run in
//! parallel (rayon) and are collected in order.

mod report;

pub use report::{Method, ThresholdNeed, ThresholdReport, ThresholdRow, ThresholdSettings, ThresholdTruth};

use mrstudy_analysis::threshold::fit::{FitOptions, Model, aggregate, fit};
use mrstudy_analysis::threshold::quest::{Params, PsychFunction, QuestPlus, StimScale};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use thiserror::Error;

use super::observer::{normal, uniform};
use crate::schedule::derived_seed;
use crate::study::Study;

/// The precision a threshold study is planned for: ±0.1 log10 units (×20 on the dB scale).
pub const TOLERANCE_LOG10: f64 = 0.1;

/// Bootstrap replicates per fit when `--bootstrap` is 0 (as `mrstudy analyze`).
pub const DEFAULT_BOOTSTRAP: usize = 200;

/// Why a threshold simulation cannot run: one sentence naming the value.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ThresholdSimulateError {
    #[error("study \"{slug}\" is not a threshold study (kind = \"threshold\")")]
    NotThreshold { slug: String },
    #[error("the levels of study \"{slug}\" have no intensities to simulate: {reason}")]
    Intensities { slug: String, reason: String },
    #[error("--truth for a threshold study takes threshold=T,slope=B (x units); {message}")]
    BadTruth { message: String },
    #[error("{option} {message}")]
    BadOption { option: &'static str, message: String },
}

/// What to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct ThresholdConfig {
    /// Trials per participant, one row per count and method.
    pub trials: Vec<usize>,
    /// `--truth`'s text (`threshold=T,slope=B`), or the defaults.
    pub truth: Option<String>,
    /// Per-participant sd of the threshold (x units).
    pub threshold_sd: f64,
    /// The observers' lapse rate.
    pub lapse: f64,
    /// Simulated participants per method × trial count.
    pub runs: usize,
    pub seed: u64,
    /// Bootstrap replicates per fit (0: [`DEFAULT_BOOTSTRAP`]).
    pub bootstrap: usize,
}

/// The study's model: the psychometric function's shape, scale, guess rate and the levels' x.
struct Setup {
    model: Model,
    quest: mrstudy_analysis::threshold::QuestPlusConfig,
    truth: ThresholdTruth,
}

fn setup(study: &Study, config: &ThresholdConfig) -> Result<Setup, ThresholdSimulateError> {
    let design =
        study.threshold.as_ref().ok_or_else(|| ThresholdSimulateError::NotThreshold { slug: study.slug.clone() })?;
    let intensities = |reason: String| ThresholdSimulateError::Intensities { slug: study.slug.clone(), reason };
    let levels = crate::threshold::intensities(study, None).map_err(|e| intensities(e.to_string()))?;
    let domain = crate::threshold::domain(design, &levels).map_err(|e| intensities(e.to_string()))?;
    let quest = crate::threshold::quest_config(design, &domain);
    let (low, high) = (domain.x[0].min(domain.x[domain.x.len() - 1]), domain.x[0].max(domain.x[domain.x.len() - 1]));
    let mut slopes = design.slope.clone();
    slopes.sort_by(f64::total_cmp);
    let (threshold, slope) = parse_truth(config.truth.as_deref(), (low + high) / 2.0, slopes[slopes.len() / 2])?;
    if quest.function == PsychFunction::Weibull && quest.scale == StimScale::Linear && threshold <= 0.0 {
        return Err(ThresholdSimulateError::BadTruth {
            message: format!("the linear Weibull needs a positive threshold, found {threshold}"),
        });
    }
    check(config)?;
    let model = Model { function: quest.function, scale: quest.scale, guess: quest.guess };
    let truth = ThresholdTruth {
        function: quest.function,
        scale: quest.scale,
        guess: quest.guess,
        threshold,
        slope,
        lapse: config.lapse,
        threshold_sd: config.threshold_sd,
        levels_x: [low, high],
    };
    Ok(Setup { model, quest, truth })
}

fn check(config: &ThresholdConfig) -> Result<(), ThresholdSimulateError> {
    let bad = |option: &'static str, message: String| ThresholdSimulateError::BadOption { option, message };
    if config.runs == 0 {
        return Err(bad("--runs", "must be at least 1, found 0".into()));
    }
    if config.trials.is_empty() || config.trials.contains(&0) {
        return Err(bad("--trials-per-participant", "must be counts of at least 1".into()));
    }
    if !(config.threshold_sd >= 0.0 && config.threshold_sd.is_finite()) {
        return Err(bad("--observer-sd", format!("must be finite and not negative, found {}", config.threshold_sd)));
    }
    if !(0.0..1.0).contains(&config.lapse) {
        return Err(bad("--lapse", format!("must be in [0, 1), found {}", config.lapse)));
    }
    Ok(())
}

/// `threshold=T,slope=B` (either may be left out: its default).
fn parse_truth(text: Option<&str>, threshold: f64, slope: f64) -> Result<(f64, f64), ThresholdSimulateError> {
    let (mut threshold, mut slope) = (threshold, slope);
    let bad = |message: String| ThresholdSimulateError::BadTruth { message };
    for part in text.unwrap_or("").split(',').map(str::trim).filter(|part| !part.is_empty()) {
        let (key, value) = part.split_once('=').ok_or_else(|| bad(format!("`{part}` is not KEY=VALUE")))?;
        let value: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|value: &f64| value.is_finite())
            .ok_or_else(|| bad(format!("`{}` of {} is not a finite number", value.trim(), key.trim())))?;
        match key.trim() {
            "threshold" => threshold = value,
            "slope" if value > 0.0 => slope = value,
            "slope" => return Err(bad(format!("the slope must be positive, found {value}"))),
            other => return Err(bad(format!("`{other}` is not one of threshold, slope"))),
        }
    }
    Ok((threshold, slope))
}

/// One simulated participant's scores.
#[derive(Debug, Clone, Default)]
struct Outcome {
    /// Estimate − truth, when the fit was not degenerate.
    error: Option<f64>,
    /// Whether the interval held the truth, and its width (with an interval).
    covered: Option<bool>,
    width: Option<f64>,
    failure: Option<String>,
}

/// The trials `(x, correct)` of one participant by `method`.
fn collect(
    setup: &Setup,
    method: Method,
    trials: usize,
    threshold: f64,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<(f64, bool)>, String> {
    let truth = Params { threshold, slope: setup.truth.slope, lapse: setup.truth.lapse };
    let quest = &setup.quest;
    let answer = |x: f64, rng: &mut ChaCha8Rng| uniform(rng) < quest.function.prob(quest.scale, x, truth, quest.guess);
    let mut out = Vec::with_capacity(trials);
    match method {
        Method::QuestPlus => {
            let mut posterior = QuestPlus::new(quest).map_err(|error| error.to_string())?;
            for _ in 0..trials {
                let index = posterior.next_index();
                let correct = answer(quest.x[index], rng);
                posterior.update(index, correct).map_err(|error| error.to_string())?;
                out.push((quest.x[index], correct));
            }
        }
        Method::ConstantStimuli => {
            let levels = quest.x.len();
            let mut counts = vec![trials / levels; levels];
            let mut order: Vec<usize> = (0..levels).collect();
            for k in 0..trials % levels {
                let pick = k + (uniform(rng) * (levels - k) as f64) as usize;
                order.swap(k, pick.min(levels - 1));
                counts[order[k]] += 1;
            }
            for (index, &count) in counts.iter().enumerate() {
                for _ in 0..count {
                    out.push((quest.x[index], answer(quest.x[index], rng)));
                }
            }
        }
    }
    Ok(out)
}

fn run_once(setup: &Setup, method: Method, trials: usize, bootstrap: usize, seed: u64) -> Outcome {
    let mut rng = ChaCha8Rng::seed_from_u64(derived_seed(seed, 1));
    let truth = &setup.truth;
    let z = normal(&mut rng);
    let threshold = if truth.function == PsychFunction::Weibull && truth.scale == StimScale::Linear {
        truth.threshold * (truth.threshold_sd * z).exp()
    } else {
        truth.threshold + truth.threshold_sd * z
    };
    let data = match collect(setup, method, trials, threshold, &mut rng) {
        Ok(data) => data,
        Err(message) => return Outcome { failure: Some(message), ..Outcome::default() },
    };
    let options = FitOptions { bootstrap, seed, ..FitOptions::default() };
    match fit(setup.model, &aggregate(data), &options) {
        Ok(fitted) => Outcome {
            error: Some(fitted.threshold - threshold),
            covered: fitted.threshold_ci.map(|[low, high]| low <= threshold && threshold <= high),
            width: fitted.threshold_ci.map(|[low, high]| high - low),
            failure: None,
        },
        Err(_) => Outcome::default(),
    }
}

/// Runs the threshold simulation; `progress(done, total)` after each simulated participant.
pub fn simulate_threshold(
    study: &Study,
    config: &ThresholdConfig,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<ThresholdReport, ThresholdSimulateError> {
    let setup = setup(study, config)?;
    let bootstrap = if config.bootstrap == 0 { DEFAULT_BOOTSTRAP } else { config.bootstrap };
    let mut trials = config.trials.clone();
    trials.sort_unstable();
    trials.dedup();
    let jobs: Vec<(Method, usize, u64)> = Method::ALL
        .iter()
        .flat_map(|&method| trials.iter().flat_map(move |&n| (0..config.runs as u64).map(move |r| (method, n, r))))
        .collect();
    let total = jobs.len() as u64;
    let done = AtomicU64::new(0);
    let outcomes: Vec<Outcome> = jobs
        .par_iter()
        .map(|&(method, n, run)| {
            let seed = derived_seed(derived_seed(derived_seed(config.seed, 10 + method.code()), n as u64), run);
            let outcome = run_once(&setup, method, n, bootstrap, seed);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            outcome
        })
        .collect();
    let tolerance = report::tolerance(setup.truth.scale);
    let rows = outcomes
        .chunks(config.runs)
        .zip(jobs.iter().step_by(config.runs))
        .map(|(chunk, &(method, n, _))| report::summarise(method, n, chunk, tolerance))
        .collect();
    Ok(ThresholdReport {
        study: study.slug.clone(),
        kind: "threshold",
        truth: setup.truth,
        settings: ThresholdSettings { runs: config.runs, seed: config.seed, bootstrap, tolerance },
        rows,
    })
}

#[cfg(test)]
mod tests;
