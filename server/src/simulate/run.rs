//! One run (one simulated study) and the runs of every design × participant count: the real
//! analysis on the simulated judgments, scored against the truth.

use crate::schedule::derived_seed;
use crate::study::Study;
use mrstudy_analysis::analysis::{self, Analysis, Screening, analyze_judgments_with_ties};
use mrstudy_analysis::data::{ConditionTable, Judgment, Judgments};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

use super::design::{DesignChoice, design_variant};
use super::marginal::{MarginalTruth, marginal_truth};
use super::observer::collect_judgments;
use super::report::{Report, RunOutcome, summarise};
use super::{ALPHA, Config, SimulateError, Z_95};

/// Whether the 95 % interval of `estimate` (`ci`, else the Wald one of `se`) holds `target`.
fn covers(estimate: f64, se: f64, ci: Option<[f64; 2]>, target: f64) -> bool {
    let [low, high] = ci.unwrap_or([estimate - Z_95 * se, estimate + Z_95 * se]);
    low <= target && target <= high
}

/// The fraction of `hits` that are true (absent for none).
fn fraction(hits: &[bool]) -> Option<f64> {
    (!hits.is_empty()).then(|| hits.iter().filter(|&&hit| hit).count() as f64 / hits.len() as f64)
}

/// Scores one analysis against the truth (and the coverage against the marginal truth).
pub(super) fn score(analysis: &Analysis, config: &Config, marginal: Option<&MarginalTruth>, outcome: &mut RunOutcome) {
    let truth = &config.truth;
    let reference = truth.log_worths[0].log_worth;
    // Disconnected: log-worths are relative to each component's reference (`component` set).
    // Under separation alone the analysis reports Firth's estimates, which count.
    if analysis.items.iter().all(|item| item.component.is_none()) {
        let mut squares = Vec::new();
        let (mut covered, mut covered_marginal) = (Vec::new(), Vec::new());
        outcome.log_worth_errors = vec![None; truth.log_worths.len().saturating_sub(1)];
        for (c, (item, true_worth)) in analysis.items.iter().zip(&truth.log_worths).enumerate().skip(1) {
            let (Some(estimate), Some(se)) = (item.log_worth, item.se) else { continue };
            let target = true_worth.log_worth - reference;
            outcome.log_worth_errors[c - 1] = Some((estimate - target, se));
            squares.push((estimate - target).powi(2));
            covered.push(covers(estimate, se, item.ci, target));
            if let Some(marginal) = marginal {
                covered_marginal.push(covers(estimate, se, item.ci, marginal.log_worths[c].log_worth));
            }
        }
        if squares.len() + 1 == truth.log_worths.len() && !squares.is_empty() {
            outcome.rmse_log_worth = Some((squares.iter().sum::<f64>() / squares.len() as f64).sqrt());
            outcome.coverage_log_worth = fraction(&covered);
            outcome.coverage_log_worth_marginal = fraction(&covered_marginal);
        }
    }
    // The centred MAP log-worths (`log_worth_map`) against the centred truth: what
    // `prior = "spread"` optimises.
    let map: Option<Vec<f64>> = analysis.items.iter().map(|item| item.log_worth_map).collect();
    if let Some(map) = map.filter(|map| map.len() == truth.log_worths.len()) {
        let true_worths: Vec<f64> = truth.log_worths.iter().map(|worth| worth.log_worth).collect();
        outcome.rmse_log_worth_map = Some(mrstudy_analysis::active::simulate::centred_rmse(&map, &true_worths));
    }
    if let Some(covariates) = &analysis.covariates {
        let mut squares = Vec::new();
        let (mut covered, mut covered_marginal) = (Vec::new(), Vec::new());
        for (k, effect) in truth.effects.iter().enumerate() {
            let Some(covariate) = covariates.iter().find(|c| c.name == effect.factor) else { continue };
            outcome.significant[k] = covariate.p.p < ALPHA;
            let (estimate, se) = (covariate.estimate, covariate.se);
            outcome.effect_errors[k] = Some((estimate - effect.effect, se));
            squares.push((estimate - effect.effect).powi(2));
            covered.push(covers(estimate, se, covariate.ci, effect.effect));
            if let Some(marginal) = marginal.and_then(|m| m.effects.get(k)) {
                covered_marginal.push(covers(estimate, se, covariate.ci, marginal.effect));
            }
        }
        if !squares.is_empty() {
            outcome.rmse_effects = Some((squares.iter().sum::<f64>() / squares.len() as f64).sqrt());
            outcome.coverage_effects = fraction(&covered);
            outcome.coverage_effects_marginal = fraction(&covered_marginal);
        }
    }
}

/// One simulated study and its analysis.
pub(super) fn run_once(
    study: &Study,
    table: Option<&ConditionTable>,
    config: &Config,
    marginal: Option<&MarginalTruth>,
    participants: usize,
    run_seed: u64,
) -> RunOutcome {
    let mut outcome = RunOutcome {
        participants,
        significant: vec![false; config.truth.effects.len()],
        effect_errors: vec![None; config.truth.effects.len()],
        ..Default::default()
    };
    let (rows, ties) = match collect_judgments(study, config, participants, run_seed) {
        Ok(collected) => collected,
        Err(message) => {
            outcome.failure = Some(message);
            return outcome;
        }
    };
    outcome.judgments = rows.len() + ties.len();
    // Participants with no judgment (a dropout before their first pair) are not in the data.
    let mut index = vec![u32::MAX; participants];
    let mut names = Vec::new();
    let mut renumber = |mut row: Judgment| {
        let slot = &mut index[row.participant as usize];
        if *slot == u32::MAX {
            *slot = names.len() as u32;
            names.push(format!("p{}", row.participant + 1));
        }
        row.participant = *slot;
        row
    };
    let rows: Vec<Judgment> = rows.into_iter().map(&mut renumber).collect();
    let ties: Vec<Judgment> = ties.into_iter().map(&mut renumber).collect();
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
        // `log_worth_map` with the active design's prior sd (what `prior = "spread"` optimises)
        prior_sd: study.design.active.as_ref().map_or(analysis::Options::default().prior_sd, |active| active.prior_sd),
        ..analysis::Options::default()
    };
    match analyze_judgments_with_ties(&judgments, &ties, table, &options) {
        Ok(analysis) => score(&analysis, config, marginal, &mut outcome),
        Err(error) => outcome.failure = Some(error.to_string()),
    }
    outcome
}

/// The conditions table of the study for the analysis (none without factors).
pub(super) fn condition_table(study: &Study) -> Option<ConditionTable> {
    (!study.factors.is_empty()).then(|| crate::live_analysis::condition_table(study))
}

/// Runs the simulation; `progress(done, total)` is called after each run, from any thread.
pub fn simulate(study: &Study, config: &Config, progress: &(dyn Fn(u64, u64) + Sync)) -> Result<Report, SimulateError> {
    if study.rating.is_some() {
        return super::rating::simulate(study, config, progress);
    }
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
    let marginal = marginal_truth(study, &config.truth, config.options.observer_sd, config.options.lapse);
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
            let outcome = run_once(variant, table.as_ref(), config, marginal.as_ref(), participants, seed);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            outcome
        })
        .collect();
    let mut rows = Vec::new();
    for (chunk, &(v, p, _)) in outcomes.chunks(config.options.runs).zip(jobs.iter().step_by(config.options.runs)) {
        rows.push(summarise(&variants[v], config.participants[p], chunk, config));
    }
    let mut report = Report::new(study, config, rows);
    report.marginal_truth = marginal;
    report.comparisons = report.compare_with_study();
    Ok(report)
}
