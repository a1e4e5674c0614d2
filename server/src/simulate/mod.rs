//! Planning a study by simulation (`mrstudy simulate`, `mrstudy power`): the study's **real**
//! scheduler ([`plan`](crate::schedule::plan) for fixed designs; for `pairs = "active"` the
//! planned warm-up and catch trials, then [`active_batch`](crate::schedule::active_batch)
//! batches from one [`Posterior`](mrstudy_analysis::active::Posterior) per run that
//! absorbs every simulated judgment in order, participants one after another) against simulated
//! observers, and the **real** analysis ([`analyze_judgments`](mrstudy_analysis::analysis::analyze_judgments) with the study's conditions and
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
//! those errors; `rmse_effects` of the factor effects' errors; `rmse_log_worth_map` of the
//! centred MAP log-worths (the analysis's `log_worth_map`, with the active design's `prior_sd`,
//! else 1) against the centred truth, the estimate `prior = "spread"` optimises; coverage is
//! the fraction of the 95 % intervals (Wald, estimate ± 1.96 se; the analysis's bootstrap
//! percentile intervals with `bootstrap` > 0) that hold the truth; power of a factor is whether
//! its p < 0.05. A run whose analysis fails (or whose comparison graph is disconnected, for the
//! log-worths) has no scores; it counts as *not significant* for power, whose denominator is
//! every run. Each row reports the mean over runs with its Monte-Carlo standard error
//! (sd / √runs; for a power √(p(1 − p)/runs)); a mean over no run is absent, never NaN.
//!
//! **Rating studies** (`kind = "rating"`) are simulated by `simulate::rating`: SUREAL's observers (bias,
//! inconsistency) rate the study's own plan, and each factor is tested within participants.
//!
//! **Reproducible.** Run r of design d at n participants has the seed
//! `derived_seed(derived_seed(derived_seed(seed, d), n), r)` (d: 0 study, 1 all, 2 anchored,
//! 3 active, 4 active-worths, 5 active-both, 6 active-spread); participant k's schedule seed is `derived_seed(run seed, k)` and their taste and
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
//! `rmse_log_worth`, `rmse_effects`, `rmse_log_worth_map`, `coverage_log_worth`, `coverage_effects`,
//! `coverage_log_worth_marginal`, `coverage_effects_marginal` (against the report's
//! `marginal_truth`, `simulate::marginal`); `power`: `[{factor, effect, power, mcse}]`; `bias_effects`
//! and `bias_log_worth`: `[{name, truth, bias {mean, mcse}, sd, mean_se}]` ([`Bias`]).

pub mod command;
mod compare;
mod design;
pub mod familiarity;
mod marginal;
mod observer;
mod power;
mod rating;
mod report;
mod run;
#[cfg(test)]
mod tests;
pub mod threshold;
mod ties;
mod truth;

pub use compare::{Comparison, Versus};
pub use design::{ACTIVE_BATCH, DesignChoice, design_variant};
pub use marginal::MarginalTruth;
pub use power::{PowerAt, PowerNeed, TargetError, parse_target, power_lines, power_needs, power_report};
pub use report::{Bias, Estimate, FactorPower, Report, Row, Settings};
pub use run::simulate;
pub use truth::{
    ConditionWorth, FactorEffect, THESIS_EFFECTS, Truth, choose_truth, default_truth, parse_effects,
    truth_from_effects, truth_from_worths_csv,
};

use crate::study::Study;
use mrstudy_analysis::active::ActiveError;
use thiserror::Error;

/// The significance level of the power.
pub const ALPHA: f64 = 0.05;

/// z of a two-sided 95 % Wald interval.
pub(super) const Z_95: f64 = 1.959_963_984_540_054;

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

/// What to simulate.
#[derive(Debug, Clone)]
pub struct Config {
    pub truth: Truth,
    pub participants: Vec<usize>,
    pub options: Options,
}

/// The simulated observers and runs: `mrstudy simulate`'s and `power`'s flags (the binary
/// holds their clap definitions and defaults).
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Designs side by side: `study` (the file's), `all`, `anchored`, `active` (at equal trials; target factors where a factor varies), `active-worths` (target worths), `active-both` (target both), `active-spread` (target worths, prior spread: optimises the centred MAP log-worths).
    pub designs: Vec<DesignChoice>,
    /// Per-participant taste noise: sd of each condition's log-worth.
    pub observer_sd: f64,
    /// Probability that an answer is a coin flip.
    pub lapse: f64,
    /// Probability that a participant stops after each trial.
    pub dropout: f64,
    /// Studies with `allow_tie = true`: Davidson's ν of the simulated observers ("not sure" is ν/(2 + ν) of the answers between equal conditions).
    pub tie_nu: f64,
    /// Simulated studies per design and participant count.
    pub runs: usize,
    pub seed: u64,
    /// Bootstrap replicates per analysis for the intervals (0: Wald intervals).
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
        if !(self.options.tie_nu >= 0.0 && self.options.tie_nu.is_finite()) {
            return Err(bad("--tie-nu", format!("must be finite and not negative, found {}", self.options.tie_nu)));
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
