//! Planning a study by simulation (`mrstudy simulate`, `mrstudy power`): the study's **real**
//! scheduler ([`plan`] for fixed designs; for `pairs = "active"` the
//! planned warm-up and catch trials, then [`active_batch`]
//! batches from one [`Posterior`] per run that
//! absorbs every simulated judgment in order, participants one after another) against simulated
//! observers, and the **real** analysis ([`analyze_judgments`] with the study's conditions and
//! factors as its `ConditionTable`).
//!
//! **Observers.** Each participant has log-worths = truth + N(0, `observer_sd`²) per condition
//! (taste); each judgment is Bradley–Terry (logistic) on the difference of the two shown
//! conditions; with probability `lapse` the answer is a coin flip instead. Catch trials are
//! answered correctly unless lapsing and, as in the export, never enter the analysis. With
//! `dropout` P a participant stops after each trial with probability P.
//!
//! **Truth.** Factor effects (λ of a condition = Σ effect × level; a factor not named has
//! effect 0) or a log-worth per condition. Given log-worths, the true factor effects are their
//! least-squares projection on the factors (with an intercept), the quantity the analysis's
//! main-effects model estimates.
//!
//! **Scores, per run.** The analysis pins its reference condition (the study's first) at
//! log-worth 0, so log-worths are compared as **differences to the reference**: estimate λ̂ᵢ
//! against λᵢ − λ_ref over the other conditions. `rmse_log_worth` is the root mean square of
//! those errors; `rmse_effects` of the factor effects' errors; coverage is the fraction of the
//! 95 % intervals (Wald, estimate ± 1.96 se; the analysis's bootstrap percentile intervals with
//! `bootstrap` > 0) that hold the truth; power of a factor is whether its p < 0.05. A run whose
//! analysis fails (or whose comparison graph is disconnected, for the log-worths) has no
//! scores; it counts as *not significant* for power, whose denominator is every run. Each row
//! reports the mean over runs with its Monte-Carlo standard error (sd / √runs; for a power
//! √(p(1 − p)/runs)); a mean over no run is absent, never NaN.
//!
//! **Reproducible.** Run r of design d at n participants has the seed
//! `derived_seed(derived_seed(derived_seed(seed, d), n), r)` (d: 0 study, 1 all, 2 anchored,
//! 3 active, 4 active-worths); participant k's schedule seed is `derived_seed(run seed, k)` and their taste and
//! answers come from a ChaCha8 stream of `derived_seed(participant seed, 1)`. Runs go in
//! parallel (rayon) and are collected in order, so the report does not depend on the thread
//! count.
//!
//! **JSON** ([`Report`], `mrstudy simulate --format json`): `study`, `reference` (the
//! reference condition), `truth` (`log_worths`: `[{condition, log_worth}]`, `effects`:
//! `[{factor, effect}]`), `settings` (`observer_sd`, `lapse`, `dropout`, `runs`, `seed`,
//! `bootstrap`, `alpha`), and `rows`, one per design × participant count: `design` (`study`,
//! `all`, `anchored`, `active`, `active-worths`), `pairs` (the design's rule: `all`, `anchored`, `list`,
//! `active`), `participants`, `runs`, `failed` (runs whose analysis failed) and `failure` (the
//! first failure's sentence), `judgments_per_participant` and `trials` (participants × that
//! mean: judgments per study), and, each `{mean, mcse}` and absent when no run gave it,
//! `rmse_log_worth`, `rmse_effects`, `coverage_log_worth`, `coverage_effects`; `power`:
//! `[{factor, effect, power, mcse}]`.

pub mod familiarity;
#[cfg(test)]
mod tests;

use std::sync::atomic::{AtomicU64, Ordering};

use mrstudy_analysis::active::{ActiveError, DEFAULT_PRIOR_SD, Posterior};
use mrstudy_analysis::analysis::{self, Analysis, Screening, analyze_judgments};
use mrstudy_analysis::data::{ConditionTable, Judgment, Judgments};
use mrstudy_analysis::plot::{LinePlot, LineSeries};
use mrstudy_analysis::table::fixed;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;

use crate::schedule::{ActiveHistory, PlannedKind, active_batch, active_posterior, derived_seed, plan};
use crate::study::{ActiveDesign, ActiveTarget, PairsRule, Study, active_target};

/// The significance level of the power.
pub const ALPHA: f64 = 0.05;

/// z of a two-sided 95 % Wald interval.
const Z_95: f64 = 1.959_963_984_540_054;

/// The thesis's factor effects (Knecht 2013, Table 6.1, logit scale), the default truth of a
/// study whose factors are exactly `gi`, `cm`, `ca`.
pub const THESIS_EFFECTS: [(&str, f64); 3] = [("gi", 0.27), ("cm", -0.22), ("ca", 0.43)];

/// Active batches of the `active` design variant.
pub const ACTIVE_BATCH: u32 = 5;

/// Why a simulation cannot run: one sentence naming the value.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum SimulateError {
    #[error("`{factor}` is not a factor of the study (factors: {factors})")]
    UnknownFactor { factor: String, factors: String },
    #[error("`{condition}` is not a condition of the study (conditions: {conditions})")]
    UnknownCondition { condition: String, conditions: String },
    #[error("the true log-worths give no value for condition `{condition}`; give one per condition")]
    MissingCondition { condition: String },
    #[error("{source_name}: {message}")]
    BadTruth { source_name: String, message: String },
    #[error(
        "the study's factors are {factors}, not the thesis's gi, cm, ca, so there is no default truth; give --truth FACTOR=EFFECT,… or --truth-worth FILE"
    )]
    NoDefaultTruth { factors: String },
    #[error("{option} {message}")]
    BadOption { option: &'static str, message: String },
    #[error("the active design needs at least 3 conditions and the study has {conditions}")]
    TooFewConditions { conditions: usize },
    #[error("the active design cannot be used on this study: {0}")]
    Active(ActiveError),
    /// A detection design ("real or rendered?") is not a paired comparison of conditions.
    #[error(
        "study \"{slug}\" is a detection design (reference = \"ground-truth\"); simulate models paired comparisons of conditions only"
    )]
    Detection { slug: String },
    /// `power` finds participants per factor, and the study varies none.
    #[error("the study has no factors, so there is no power per factor to find")]
    NoFactors,
}

/// The true log-worth of every condition (study order) and the true factor effects.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Truth {
    pub log_worths: Vec<ConditionWorth>,
    pub effects: Vec<FactorEffect>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConditionWorth {
    pub condition: String,
    pub log_worth: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FactorEffect {
    pub factor: String,
    pub effect: f64,
}

/// The truth of `mrstudy simulate` and `power`: factor effects (`--truth gi=0.3,…`), true
/// log-worths from a CSV (`--truth-worth`: its text and name), or else the thesis's default.
pub fn choose_truth(
    study: &Study,
    effects: Option<&str>,
    worths: Option<(&str, &str)>,
) -> Result<Truth, SimulateError> {
    match (effects, worths) {
        (Some(text), _) => truth_from_effects(study, &parse_effects(text)?),
        (None, Some((text, name))) => truth_from_worths_csv(study, text, name),
        (None, None) => default_truth(study),
    }
}

/// Parses `gi=0.3,cm=-0.2` into (factor, effect) pairs.
pub fn parse_effects(text: &str) -> Result<Vec<(String, f64)>, SimulateError> {
    let bad = |message: String| SimulateError::BadTruth { source_name: "--truth".into(), message };
    text.split(',')
        .filter(|part| !part.trim().is_empty())
        .map(|part| {
            let (name, value) =
                part.split_once('=').ok_or_else(|| bad(format!("expected FACTOR=EFFECT, found `{}`", part.trim())))?;
            let effect: f64 = value.trim().parse().map_err(|_| bad(format!("`{}` is not a number", value.trim())))?;
            if !effect.is_finite() {
                return Err(bad(format!("`{}` is not a finite number", value.trim())));
            }
            Ok((name.trim().to_string(), effect))
        })
        .collect()
}

/// The truth from factor effects; a factor the study lacks is refused, one not given is 0.
pub fn truth_from_effects(study: &Study, effects: &[(String, f64)]) -> Result<Truth, SimulateError> {
    let names = study.design_columns();
    let mut values = vec![0.0; names.len()];
    for (name, effect) in effects {
        let index = names.iter().position(|n| n == name).ok_or_else(|| SimulateError::UnknownFactor {
            factor: name.clone(),
            factors: if names.is_empty() { "none".into() } else { names.join(", ") },
        })?;
        values[index] = *effect;
    }
    let log_worths = study
        .conditions
        .iter()
        .map(|condition| ConditionWorth {
            condition: condition.name.clone(),
            log_worth: condition.levels.iter().zip(&values).map(|(level, effect)| level * effect).sum(),
        })
        .collect();
    let effects =
        names.iter().zip(values).map(|(name, effect)| FactorEffect { factor: name.to_string(), effect }).collect();
    Ok(Truth { log_worths, effects })
}

/// The thesis's effects when the study's factors are gi, cm, ca; else a refusal asking for a truth.
pub fn default_truth(study: &Study) -> Result<Truth, SimulateError> {
    let mut names = study.design_columns();
    names.sort_unstable();
    if names != ["ca", "cm", "gi"] {
        let factors = study.design_columns().join(", ");
        return Err(SimulateError::NoDefaultTruth {
            factors: if factors.is_empty() { "none".into() } else { factors },
        });
    }
    let effects: Vec<(String, f64)> = THESIS_EFFECTS.iter().map(|&(name, effect)| (name.to_string(), effect)).collect();
    truth_from_effects(study, &effects)
}

/// The truth from a CSV `condition,log_worth` (one row per condition of the study).
pub fn truth_from_worths_csv(study: &Study, text: &str, source_name: &str) -> Result<Truth, SimulateError> {
    let bad = |message: String| SimulateError::BadTruth { source_name: source_name.to_string(), message };
    let mut reader = csv::ReaderBuilder::new().has_headers(true).from_reader(text.as_bytes());
    let headers = reader.headers().map_err(|error| bad(error.to_string()))?.clone();
    let column = |name: &str| {
        headers.iter().position(|h| h.trim() == name).ok_or_else(|| {
            bad(format!(
                "expected a header `condition,log_worth`, found `{}`",
                headers.iter().collect::<Vec<_>>().join(",")
            ))
        })
    };
    let (condition_column, worth_column) = (column("condition")?, column("log_worth")?);
    let names: Vec<&str> = study.conditions.iter().map(|condition| condition.name.as_str()).collect();
    let mut values: Vec<Option<f64>> = vec![None; names.len()];
    for (row, record) in reader.records().enumerate() {
        let record = record.map_err(|error| bad(error.to_string()))?;
        let name = record.get(condition_column).unwrap_or("").trim();
        let text = record.get(worth_column).unwrap_or("").trim();
        let index = names.iter().position(|n| *n == name).ok_or_else(|| SimulateError::UnknownCondition {
            condition: name.to_string(),
            conditions: names.join(", "),
        })?;
        let value: f64 = text.parse().map_err(|_| bad(format!("line {}: `{text}` is not a number", row + 2)))?;
        if !value.is_finite() {
            return Err(bad(format!("line {}: `{text}` is not a finite number", row + 2)));
        }
        values[index] = Some(value);
    }
    let mut log_worths = Vec::with_capacity(names.len());
    for (name, value) in names.iter().zip(values) {
        let log_worth = value.ok_or_else(|| SimulateError::MissingCondition { condition: name.to_string() })?;
        log_worths.push(ConditionWorth { condition: name.to_string(), log_worth });
    }
    let worths: Vec<f64> = log_worths.iter().map(|w| w.log_worth).collect();
    let effects = projected_effects(study, &worths)
        .map(|values| {
            study
                .design_columns()
                .into_iter()
                .zip(values)
                .map(|(factor, effect)| FactorEffect { factor, effect })
                .collect()
        })
        .unwrap_or_default();
    Ok(Truth { log_worths, effects })
}

/// Least squares of the log-worths on [1, levels]: the factor effects (none when the factors
/// are collinear or absent).
fn projected_effects(study: &Study, worths: &[f64]) -> Option<Vec<f64>> {
    let p = study.design_columns().len() + 1;
    if p == 1 {
        return None;
    }
    let row = |c: usize| std::iter::once(1.0).chain(study.conditions[c].levels.iter().copied()).collect::<Vec<f64>>();
    let mut normal = vec![vec![0.0; p + 1]; p];
    for (c, &worth) in worths.iter().enumerate() {
        let x = row(c);
        for i in 0..p {
            for j in 0..p {
                normal[i][j] += x[i] * x[j];
            }
            normal[i][p] += x[i] * worth;
        }
    }
    // Gauss–Jordan with partial pivoting on the augmented normal equations.
    for col in 0..p {
        let pivot = (col..p).max_by(|&a, &b| normal[a][col].abs().total_cmp(&normal[b][col].abs()))?;
        if normal[pivot][col].abs() < 1e-9 {
            return None;
        }
        normal.swap(col, pivot);
        for r in 0..p {
            if r != col {
                let factor = normal[r][col] / normal[col][col];
                for k in col..=p {
                    normal[r][k] -= factor * normal[col][k];
                }
            }
        }
    }
    Some((1..p).map(|i| normal[i][p] / normal[i][i]).collect())
}

/// A design to simulate, each built from the study by changing only its `design`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DesignChoice {
    /// The study file's own design.
    Study,
    /// Every pair of conditions, the study's repetitions.
    All,
    /// The study's anchors if it has them, else the first and last condition; the study's repetitions.
    Anchored,
    /// `pairs = "active"` at the study's fixed design's pair trials per participant, batch 5,
    /// target factors when the study has a factor that varies, else worths. (On a 2³ factorial
    /// the factor target picks almost only complementary pairs, LQ–HQ, GI–CM+CA, …, whose
    /// item model the analysis then cannot fit: see `active-worths`.)
    Active,
    /// As `active`, with target worths whatever the factors (`active-worths`).
    ActiveWorths,
}

impl DesignChoice {
    pub fn parse(text: &str) -> Option<DesignChoice> {
        Some(match text {
            "study" => DesignChoice::Study,
            "all" => DesignChoice::All,
            "anchored" => DesignChoice::Anchored,
            "active" => DesignChoice::Active,
            "active-worths" => DesignChoice::ActiveWorths,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            DesignChoice::Study => "study",
            DesignChoice::All => "all",
            DesignChoice::Anchored => "anchored",
            DesignChoice::Active => "active",
            DesignChoice::ActiveWorths => "active-worths",
        }
    }

    fn code(self) -> u64 {
        self as u64
    }
}

/// Pair trials per participant of a study's design (warm-up and active trials, no catch trials).
fn pair_trials(study: &Study) -> usize {
    study.design.pairs.len() * study.design.repetitions as usize
        + study.design.active.as_ref().map_or(0, |active| active.trials as usize)
}

/// The study with its design replaced by `choice` (the same scheduler runs every variant).
pub fn design_variant(study: &Study, choice: DesignChoice) -> Result<Study, SimulateError> {
    let mut variant = study.clone();
    let n = study.conditions.len();
    let repetitions = if study.design.active.is_some() { 1 } else { study.design.repetitions };
    match choice {
        DesignChoice::Study => {}
        DesignChoice::All => {
            variant.design.pairs = crate::study::survey::all_pairs(n);
            variant.design.pairs_rule = PairsRule::All;
            variant.design.repetitions = repetitions;
            variant.design.active = None;
        }
        DesignChoice::Anchored => {
            if study.design.pairs_rule != PairsRule::Anchored {
                variant.design.pairs = anchored_pairs(study);
                variant.design.repetitions = repetitions;
            }
            variant.design.pairs_rule = PairsRule::Anchored;
            variant.design.active = None;
        }
        DesignChoice::Active | DesignChoice::ActiveWorths => {
            if study.design.active.is_none() || choice == DesignChoice::ActiveWorths {
                if n < 3 {
                    return Err(SimulateError::TooFewConditions { conditions: n });
                }
                let varying = (0..study.design_columns().len()).any(|k| {
                    study.conditions.iter().any(|condition| condition.levels[k] != study.conditions[0].levels[k])
                });
                let mut active = ActiveDesign {
                    trials: pair_trials(study) as u32,
                    batch: ACTIVE_BATCH,
                    target: if varying && choice == DesignChoice::Active {
                        ActiveTarget::Factors
                    } else {
                        ActiveTarget::Worths
                    },
                    prior_sd: DEFAULT_PRIOR_SD,
                };
                if active_target(&active, &study.conditions).check().is_err() {
                    active.target = ActiveTarget::Worths;
                }
                active_target(&active, &study.conditions).check().map_err(SimulateError::Active)?;
                // The factor target needs a warm-up that connects the conditions (a study file
                // without one is refused): the anchored pairs once, within the same trials.
                variant.design.pairs = Vec::new();
                if active.target == ActiveTarget::Factors {
                    variant.design.pairs = anchored_pairs(study);
                    active.trials = (active.trials as usize).saturating_sub(variant.design.pairs.len()).max(1) as u32;
                }
                variant.design.pairs_rule = PairsRule::Active;
                variant.design.repetitions = 1;
                variant.design.active = Some(active);
            }
        }
    }
    Ok(variant)
}

/// The study's anchored pairs, or with another design the first and last condition as anchors.
fn anchored_pairs(study: &Study) -> Vec<(usize, usize)> {
    if study.design.pairs_rule == PairsRule::Anchored {
        return study.design.pairs.clone();
    }
    let (first, last) = (0, study.conditions.len() - 1);
    let mut pairs = vec![(first, last)];
    pairs.extend((1..last).flat_map(|c| [(first, c), (c, last)]));
    pairs
}

/// What to simulate.
#[derive(Debug, Clone)]
pub struct Config {
    pub truth: Truth,
    pub participants: Vec<usize>,
    pub options: Options,
}

/// The simulated observers and runs: `mrstudy simulate`'s and `power`'s flags (the doc
/// comments are their help).
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Options {
    /// Designs side by side: `study` (the file's), `all`, `anchored`, `active` (at equal trials; target factors where a factor varies), `active-worths` (target worths).
    #[arg(long, value_delimiter = ',', default_value = "study", value_parser = |text: &str| {
        DesignChoice::parse(text).ok_or_else(|| format!("`{text}` is not one of study, all, anchored, active, active-worths"))
    })]
    pub designs: Vec<DesignChoice>,
    /// Per-participant taste noise: sd of each condition's log-worth.
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    pub observer_sd: f64,
    /// Probability that an answer is a coin flip.
    #[arg(long, default_value_t = 0.02, allow_negative_numbers = true)]
    pub lapse: f64,
    /// Probability that a participant stops after each trial.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub dropout: f64,
    /// Simulated studies per design and participant count.
    #[arg(long, default_value_t = 200)]
    pub runs: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Bootstrap replicates per analysis for the intervals (0: Wald intervals).
    #[arg(long, default_value_t = 0)]
    pub bootstrap: usize,
}

impl Config {
    fn check(&self, study: &Study) -> Result<(), SimulateError> {
        let bad = |option: &'static str, message: String| SimulateError::BadOption { option, message };
        if self.options.runs == 0 {
            return Err(bad("--runs", "must be at least 1, found 0".into()));
        }
        if self.participants.is_empty() || self.participants.contains(&0) {
            return Err(bad("--participants", "must be counts of at least 1".into()));
        }
        if self.options.designs.is_empty() {
            return Err(bad("--designs", "must name at least one design".into()));
        }
        if !(self.options.observer_sd >= 0.0 && self.options.observer_sd.is_finite()) {
            return Err(bad(
                "--observer-sd",
                format!("must be finite and not negative, found {}", self.options.observer_sd),
            ));
        }
        if !(0.0..1.0).contains(&self.options.lapse) {
            return Err(bad("--lapse", format!("must be in [0, 1), found {}", self.options.lapse)));
        }
        if !(0.0..1.0).contains(&self.options.dropout) {
            return Err(bad("--dropout", format!("must be in [0, 1), found {}", self.options.dropout)));
        }
        if self.truth.log_worths.len() != study.conditions.len() {
            return Err(bad(
                "truth",
                format!("has {} log-worths for {} conditions", self.truth.log_worths.len(), study.conditions.len()),
            ));
        }
        Ok(())
    }
}

/// A mean over runs and its Monte-Carlo standard error (absent with fewer than two runs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    pub mean: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mcse: Option<f64>,
}

impl Estimate {
    fn of(values: &[f64]) -> Option<Estimate> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let mcse = (n > 1)
            .then(|| (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64 / n as f64).sqrt());
        Some(Estimate { mean, mcse })
    }
}

/// Power of one factor: the fraction of runs with p < [`ALPHA`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FactorPower {
    pub factor: String,
    /// The true effect.
    pub effect: f64,
    pub power: f64,
    /// √(power (1 − power) / runs).
    pub mcse: f64,
}

/// One design × participant count.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    pub design: DesignChoice,
    pub pairs: PairsRule,
    pub participants: usize,
    pub runs: usize,
    pub failed: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    pub judgments_per_participant: Estimate,
    /// participants × mean judgments per participant.
    pub trials: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_log_worth: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_effects: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage_log_worth: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage_effects: Option<Estimate>,
    pub power: Vec<FactorPower>,
}

/// The simulation's settings as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Settings {
    pub observer_sd: f64,
    pub lapse: f64,
    pub dropout: f64,
    pub runs: usize,
    pub seed: u64,
    pub bootstrap: usize,
    pub alpha: f64,
}

/// Everything `mrstudy simulate` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    pub study: String,
    pub reference: String,
    pub truth: Truth,
    pub settings: Settings,
    pub rows: Vec<Row>,
}

/// One run's scores (absent where the analysis gave none).
#[derive(Debug, Clone, Default)]
struct RunOutcome {
    judgments: usize,
    participants: usize,
    failure: Option<String>,
    rmse_log_worth: Option<f64>,
    coverage_log_worth: Option<f64>,
    rmse_effects: Option<f64>,
    coverage_effects: Option<f64>,
    /// Per truth factor: p < α.
    significant: Vec<bool>,
}

/// Uniform in [0, 1) from 53 bits.
fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A standard normal draw (Box–Muller).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = 1.0 - uniform(rng);
    let u2 = uniform(rng);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A simulated participant: their log-worths and the stream of their answers and dropout.
struct Observer<'a> {
    worths: Vec<f64>,
    rng: ChaCha8Rng,
    config: &'a Config,
}

impl Observer<'_> {
    /// Whether the left condition is chosen.
    fn judge(&mut self, left: usize, right: usize) -> bool {
        if uniform(&mut self.rng) < self.config.options.lapse {
            return uniform(&mut self.rng) < 0.5;
        }
        uniform(&mut self.rng) < 1.0 / (1.0 + (self.worths[right] - self.worths[left]).exp())
    }

    /// A catch trial: right unless lapsing (nothing recorded).
    fn catch(&mut self) {
        if uniform(&mut self.rng) < self.config.options.lapse {
            uniform(&mut self.rng);
        }
    }

    fn drops_out(&mut self) -> bool {
        self.config.options.dropout > 0.0 && uniform(&mut self.rng) < self.config.options.dropout
    }
}

/// The judgments of one simulated study (each participant's pair trials in order).
fn collect_judgments(
    study: &Study,
    config: &Config,
    participants: usize,
    run_seed: u64,
) -> Result<Vec<Judgment>, String> {
    let truth: Vec<f64> = config.truth.log_worths.iter().map(|w| w.log_worth).collect();
    let mut posterior = match active_posterior(study) {
        Some(posterior) => Some(posterior.map_err(|error| error.to_string())?),
        None => None,
    };
    let mut judgments = Vec::new();
    for participant in 0..participants {
        let seed = derived_seed(run_seed, participant as u64);
        let mut rng = ChaCha8Rng::seed_from_u64(derived_seed(seed, 1));
        let worths = truth.iter().map(|w| w + config.options.observer_sd * normal(&mut rng)).collect();
        let mut observer = Observer { worths, rng, config };
        let mut shown: Vec<(usize, usize)> = Vec::new();
        let mut stopped = false;
        let mut answer = |left: usize, right: usize, observer: &mut Observer, posterior: &mut Option<Posterior>| {
            let left_chosen = observer.judge(left, right);
            judgments.push(Judgment {
                participant: participant as u32,
                left: left as u32,
                right: right as u32,
                left_chosen,
                count: 1,
                group: 0,
            });
            if let Some(posterior) = posterior {
                let (winner, loser) = if left_chosen { (left, right) } else { (right, left) };
                posterior.update(winner, loser).map_err(|error| error.to_string())?;
            }
            Ok::<_, String>(())
        };
        for trial in plan(study, seed) {
            match trial.kind {
                PlannedKind::Pair { left, right } => {
                    answer(left, right, &mut observer, &mut posterior)?;
                    shown.push((left, right));
                }
                PlannedKind::Catch { .. } => observer.catch(),
            }
            if observer.drops_out() {
                stopped = true;
                break;
            }
        }
        if let (Some(active), false) = (&study.design.active, stopped) {
            let mut history = ActiveHistory::of(study.conditions.len(), &shown, 0);
            let mut done = 0;
            'batches: while done < active.trials as usize {
                let count = (active.batch as usize).min(active.trials as usize - done);
                let batch = active_batch(
                    study,
                    posterior.as_ref().expect("an active design has a posterior"),
                    seed,
                    &mut history,
                    count,
                )
                .map_err(|error| error.to_string())?;
                for trial in batch {
                    let PlannedKind::Pair { left, right } = trial.kind else { continue };
                    answer(left, right, &mut observer, &mut posterior)?;
                    done += 1;
                    if observer.drops_out() {
                        break 'batches;
                    }
                }
            }
        }
    }
    Ok(judgments)
}

/// Scores one analysis against the truth.
fn score(analysis: &Analysis, config: &Config, outcome: &mut RunOutcome) {
    let truth = &config.truth;
    let reference = truth.log_worths[0].log_worth;
    // Disconnected: log-worths are relative to each component's reference (`component` set).
    // Under separation alone the analysis reports Firth's estimates, which count.
    if analysis.items.iter().all(|item| item.component.is_none()) {
        let mut squares = Vec::new();
        let mut covered = 0usize;
        for (item, true_worth) in analysis.items.iter().zip(&truth.log_worths).skip(1) {
            let (Some(estimate), Some(se)) = (item.log_worth, item.se) else { continue };
            let target = true_worth.log_worth - reference;
            squares.push((estimate - target).powi(2));
            let [low, high] = item.ci.unwrap_or([estimate - Z_95 * se, estimate + Z_95 * se]);
            covered += usize::from(low <= target && target <= high);
        }
        if squares.len() + 1 == truth.log_worths.len() && !squares.is_empty() {
            outcome.rmse_log_worth = Some((squares.iter().sum::<f64>() / squares.len() as f64).sqrt());
            outcome.coverage_log_worth = Some(covered as f64 / squares.len() as f64);
        }
    }
    if let Some(covariates) = &analysis.covariates {
        let mut squares = Vec::new();
        let mut covered = 0usize;
        for (k, effect) in truth.effects.iter().enumerate() {
            let Some(covariate) = covariates.iter().find(|c| c.name == effect.factor) else { continue };
            outcome.significant[k] = covariate.p.p < ALPHA;
            squares.push((covariate.estimate - effect.effect).powi(2));
            let [low, high] = covariate
                .ci
                .unwrap_or([covariate.estimate - Z_95 * covariate.se, covariate.estimate + Z_95 * covariate.se]);
            covered += usize::from(low <= effect.effect && effect.effect <= high);
        }
        if !squares.is_empty() {
            outcome.rmse_effects = Some((squares.iter().sum::<f64>() / squares.len() as f64).sqrt());
            outcome.coverage_effects = Some(covered as f64 / squares.len() as f64);
        }
    }
}

/// One simulated study and its analysis.
fn run_once(
    study: &Study,
    table: Option<&ConditionTable>,
    config: &Config,
    participants: usize,
    run_seed: u64,
) -> RunOutcome {
    let mut outcome =
        RunOutcome { participants, significant: vec![false; config.truth.effects.len()], ..Default::default() };
    let rows = match collect_judgments(study, config, participants, run_seed) {
        Ok(rows) => rows,
        Err(message) => {
            outcome.failure = Some(message);
            return outcome;
        }
    };
    outcome.judgments = rows.len();
    // Participants with no judgment (a dropout before their first pair) are not in the data.
    let mut index = vec![u32::MAX; participants];
    let mut names = Vec::new();
    let rows: Vec<Judgment> = rows
        .into_iter()
        .map(|mut row| {
            let slot = &mut index[row.participant as usize];
            if *slot == u32::MAX {
                *slot = names.len() as u32;
                names.push(format!("p{}", row.participant + 1));
            }
            row.participant = *slot;
            row
        })
        .collect();
    let judgments = Judgments {
        conditions: study.conditions.iter().map(|condition| condition.name.clone()).collect(),
        participants: names,
        groups: Vec::new(),
        rows,
    };
    let options = analysis::Options {
        bootstrap: config.options.bootstrap,
        seed: run_seed,
        screening: Screening::Off,
        agreement_simulations: 1,
        ..analysis::Options::default()
    };
    match analyze_judgments(&judgments, table, &options) {
        Ok(analysis) => score(&analysis, config, &mut outcome),
        Err(error) => outcome.failure = Some(error.to_string()),
    }
    outcome
}

/// The conditions table of the study for the analysis (none without factors).
fn condition_table(study: &Study) -> Option<ConditionTable> {
    (!study.factors.is_empty()).then(|| crate::analysis::condition_table(study))
}

/// Runs the simulation; `progress(done, total)` is called after each run, from any thread.
pub fn simulate(study: &Study, config: &Config, progress: &(dyn Fn(u64, u64) + Sync)) -> Result<Report, SimulateError> {
    if study.design.reference.is_some() {
        return Err(SimulateError::Detection { slug: study.slug.clone() });
    }
    config.check(study)?;
    let variants: Vec<(DesignChoice, Study)> = config
        .options
        .designs
        .iter()
        .map(|&choice| design_variant(study, choice).map(|variant| (choice, variant)))
        .collect::<Result<_, _>>()?;
    let table = condition_table(study);
    let jobs: Vec<(usize, usize, u64)> = (0..variants.len())
        .flat_map(|v| {
            config
                .participants
                .iter()
                .enumerate()
                .flat_map(move |(p, _)| (0..config.options.runs as u64).map(move |r| (v, p, r)))
        })
        .collect();
    let total = jobs.len() as u64;
    let done = AtomicU64::new(0);
    let outcomes: Vec<RunOutcome> = jobs
        .par_iter()
        .map(|&(v, p, run)| {
            let (choice, variant) = &variants[v];
            let participants = config.participants[p];
            let seed =
                derived_seed(derived_seed(derived_seed(config.options.seed, choice.code()), participants as u64), run);
            let outcome = run_once(variant, table.as_ref(), config, participants, seed);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            outcome
        })
        .collect();
    let mut rows = Vec::new();
    for (chunk, &(v, p, _)) in outcomes.chunks(config.options.runs).zip(jobs.iter().step_by(config.options.runs)) {
        rows.push(summarise(&variants[v], config.participants[p], chunk, config));
    }
    Ok(Report {
        study: study.slug.clone(),
        reference: study.conditions[0].name.clone(),
        truth: config.truth.clone(),
        settings: Settings {
            observer_sd: config.options.observer_sd,
            lapse: config.options.lapse,
            dropout: config.options.dropout,
            runs: config.options.runs,
            seed: config.options.seed,
            bootstrap: config.options.bootstrap,
            alpha: ALPHA,
        },
        rows,
    })
}

fn summarise(
    (choice, variant): &(DesignChoice, Study),
    participants: usize,
    runs: &[RunOutcome],
    config: &Config,
) -> Row {
    let values = |pick: fn(&RunOutcome) -> Option<f64>| Estimate::of(&runs.iter().filter_map(pick).collect::<Vec<_>>());
    let per_participant: Vec<f64> = runs.iter().map(|run| run.judgments as f64 / run.participants as f64).collect();
    let judgments_per_participant = Estimate::of(&per_participant).expect("at least one run");
    let n = runs.len() as f64;
    let power = config
        .truth
        .effects
        .iter()
        .enumerate()
        .map(|(k, effect)| {
            let power = runs.iter().filter(|run| run.significant[k]).count() as f64 / n;
            FactorPower {
                factor: effect.factor.clone(),
                effect: effect.effect,
                power,
                mcse: (power * (1.0 - power) / n).sqrt(),
            }
        })
        .collect();
    Row {
        design: *choice,
        pairs: variant.design.pairs_rule,
        participants,
        runs: runs.len(),
        failed: runs.iter().filter(|run| run.failure.is_some()).count(),
        failure: runs.iter().find_map(|run| run.failure.clone()),
        trials: participants as f64 * judgments_per_participant.mean,
        judgments_per_participant,
        rmse_log_worth: values(|run| run.rmse_log_worth),
        rmse_effects: values(|run| run.rmse_effects),
        coverage_log_worth: values(|run| run.coverage_log_worth),
        coverage_effects: values(|run| run.coverage_effects),
        power,
    }
}

/// A mean ± its Monte-Carlo standard error, or `—` when no run gave it.
fn cell(estimate: Option<Estimate>, digits: usize) -> String {
    match estimate {
        Some(Estimate { mean, mcse: Some(mcse) }) => format!("{} ± {}", fixed(mean, digits), fixed(mcse, digits)),
        Some(Estimate { mean, mcse: None }) => fixed(mean, digits),
        None => "—".into(),
    }
}

impl Report {
    /// The plain-text table: one line per design × participant count, then notes on failures.
    pub fn table(&self) -> String {
        let mut header = vec![
            "design".to_string(),
            "participants".into(),
            "trials/participant".into(),
            "trials".into(),
            "RMSE log-worth".into(),
            "RMSE effects".into(),
            "coverage log-worth".into(),
            "coverage effects".into(),
        ];
        header.extend(self.truth.effects.iter().map(|effect| format!("power {}", effect.factor)));
        let mut lines = vec![header];
        for row in &self.rows {
            let mut line = vec![
                row.design.name().to_string(),
                row.participants.to_string(),
                fixed(row.judgments_per_participant.mean, 1),
                fixed(row.trials, 0),
                cell(row.rmse_log_worth, 3),
                cell(row.rmse_effects, 3),
                cell(row.coverage_log_worth, 3),
                cell(row.coverage_effects, 3),
            ];
            line.extend(row.power.iter().map(|power| format!("{} ± {}", fixed(power.power, 2), fixed(power.mcse, 2))));
            lines.push(line);
        }
        let widths: Vec<usize> =
            (0..lines[0].len()).map(|c| lines.iter().map(|line| line[c].chars().count()).max().unwrap_or(0)).collect();
        let mut text = String::new();
        for line in &lines {
            let cells: Vec<String> = line.iter().zip(&widths).map(|(cell, &width)| format!("{cell:>width$}")).collect();
            text += cells.join("  ").trim_end();
            text.push('\n');
        }
        text += &format!(
            "log-worths as differences to {} (the analysis's reference); ± is the Monte-Carlo standard error over {} runs; power: p < {ALPHA}\n",
            self.reference, self.settings.runs
        );
        for row in &self.rows {
            if row.failed == row.runs {
                text += &format!(
                    "{} with {} participants: every run failed, so there is no RMSE, coverage or power ({})\n",
                    row.design.name(),
                    row.participants,
                    row.failure.as_deref().unwrap_or("no reason given")
                );
            } else if row.failed > 0 {
                text += &format!(
                    "{} with {} participants: {} of {} runs failed and have no scores, e.g. {}\n",
                    row.design.name(),
                    row.participants,
                    row.failed,
                    row.runs,
                    row.failure.as_deref().unwrap_or("no reason given")
                );
            }
        }
        text
    }

    /// The plots: RMSE of the log-worths against trials per study, one series per design; and,
    /// where the study has factors, power per factor against participants.
    pub fn plots(&self) -> Vec<(String, LinePlot)> {
        let mut designs: Vec<DesignChoice> = Vec::new();
        for row in &self.rows {
            if !designs.contains(&row.design) {
                designs.push(row.design);
            }
        }
        let series =
            |pick: &dyn Fn(&Row) -> Option<(f64, f64)>, name: &dyn Fn(DesignChoice) -> String| -> Vec<LineSeries> {
                designs
                    .iter()
                    .map(|&design| LineSeries {
                        name: name(design),
                        points: self.rows.iter().filter(|row| row.design == design).filter_map(pick).collect(),
                    })
                    .collect()
            };
        let mut plots = vec![(
            "simulate-rmse.svg".to_string(),
            LinePlot {
                title: format!("{}: RMSE of the log-worths against trials per study", self.study),
                x_label: "trials per study (participants × judgments per participant)".into(),
                y_label: format!("RMSE of log-worths (differences to {})", self.reference),
                x_log: true,
                y_log: true,
                series: series(&|row| Some((row.trials, row.rmse_log_worth?.mean)), &|design| design.name().into()),
            },
        )];
        if !self.truth.effects.is_empty() {
            let mut power_series = Vec::new();
            for (k, effect) in self.truth.effects.iter().enumerate() {
                power_series.extend(series(&|row| Some((row.participants as f64, row.power[k].power)), &|design| {
                    format!("{} {}", design.name(), effect.factor)
                }));
            }
            plots.push((
                "simulate-power.svg".to_string(),
                LinePlot {
                    title: format!("{}: power per factor (p < {ALPHA}) against participants", self.study),
                    x_label: "participants".into(),
                    y_label: "power".into(),
                    x_log: true,
                    y_log: false,
                    series: power_series,
                },
            ));
        }
        plots
    }
}

/// The smallest simulated participant count at which a factor's power reaches the target, for
/// one design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PowerNeed {
    pub design: DesignChoice,
    pub factor: String,
    pub effect: f64,
    /// The smallest count that reached the target, with its power and Monte-Carlo error.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reached: Option<PowerAt>,
    /// The highest power seen over the counts.
    pub best: PowerAt,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PowerAt {
    pub participants: usize,
    pub power: f64,
    pub mcse: f64,
}

/// A target power, strictly between 0 and 1 (`mrstudy power --target`).
pub fn parse_target(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(target) if target > 0.0 && target < 1.0 => Ok(target),
        _ => Err(format!("`{text}` is not a power between 0 and 1 (e.g. 0.8)")),
    }
}

/// `mrstudy power`'s answer: one sentence per design and factor ([`power_needs`],
/// [`power_lines`]); refused when the study varies no factor.
pub fn power_report(report: &Report, target: f64) -> Result<Vec<String>, SimulateError> {
    if report.truth.effects.is_empty() {
        return Err(SimulateError::NoFactors);
    }
    Ok(power_lines(&power_needs(report, target), target))
}

/// Per design and factor, the smallest participant count whose power reaches `target`.
pub fn power_needs(report: &Report, target: f64) -> Vec<PowerNeed> {
    let mut needs = Vec::new();
    let mut designs: Vec<DesignChoice> = Vec::new();
    for row in &report.rows {
        if !designs.contains(&row.design) {
            designs.push(row.design);
        }
    }
    for design in designs {
        let mut rows: Vec<&Row> = report.rows.iter().filter(|row| row.design == design).collect();
        rows.sort_by_key(|row| row.participants);
        for (k, effect) in report.truth.effects.iter().enumerate() {
            let at = |row: &Row| PowerAt {
                participants: row.participants,
                power: row.power[k].power,
                mcse: row.power[k].mcse,
            };
            let reached = rows.iter().find(|row| row.power[k].power >= target).map(|row| at(row));
            let best =
                rows.iter().map(|row| at(row)).max_by(|a, b| a.power.total_cmp(&b.power)).expect("a row per design");
            needs.push(PowerNeed { design, factor: effect.factor.clone(), effect: effect.effect, reached, best });
        }
    }
    needs
}

/// One sentence per [`PowerNeed`].
pub fn power_lines(needs: &[PowerNeed], target: f64) -> Vec<String> {
    needs
        .iter()
        .map(|need| match need.reached {
            Some(at) => format!(
                "{} {} (effect {}): {} participants reach power {} ± {} (target {})",
                need.design.name(),
                need.factor,
                fixed(need.effect, 2),
                at.participants,
                fixed(at.power, 2),
                fixed(at.mcse, 2),
                fixed(target, 2)
            ),
            None => format!(
                "{} {} (effect {}): none of the participant counts reached power {}; the highest was {} ± {} at {} participants",
                need.design.name(),
                need.factor,
                fixed(need.effect, 2),
                fixed(target, 2),
                fixed(need.best.power, 2),
                fixed(need.best.mcse, 2),
                need.best.participants
            ),
        })
        .collect()
}
