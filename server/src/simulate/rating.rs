//! `mrstudy simulate` and `mrstudy power` for rating studies (`kind = "rating"`): the study's
//! real plan of rating trials ([`crate::rating::plan`]) answered by simulated observers of
//! SUREAL's subject model, and the power of each factor by a test within participants.
//!
//! **Truth.** The truth's factor effects (or log-worths) are read in **rating points**: a
//! condition's quality is ψ = 3 + λ − mean(λ) (λ its value under the truth), so the conditions
//! sit around the middle of the 5-point scale and an effect of 0.5 moves a condition half a
//! category. ACR-HR's hidden reference has ψ = min(5, max ψ + 0.5); a catch trial's ψ is its
//! expected rating.
//!
//! **Observers** (Li & Bampis's model, as Netflix's SUREAL fits it): participant i has a bias
//! Δᵢ ~ N(0, `observer_sd`²) and an inconsistency υᵢ, uniform on [0.5, 1.0] rating points (a
//! fixed assumption of this simulation, not a fitted value); their rating of a stimulus of
//! quality ψ is ψ + Δᵢ + υᵢ·X with X ~ N(0, 1), rounded to the nearest category and clamped to
//! 1…5 (votes are integers). With probability `lapse` the rating is uniform on 1…5 instead;
//! with `dropout` P the participant stops after each trial with probability P.
//!
//! **Power per factor.** Each participant's ratings of the conditions (not the hidden reference
//! nor catch trials) are regressed by least squares on the conditions' factor levels (an
//! intercept and the design matrix's columns), and each factor's coefficients over the
//! participants go into a one-sample t-test (two-sided, df = participants − 1): the factor is
//! significant when p < 0.05. `rmse_effects` is the root mean square error of the mean
//! coefficients against the true effects, `coverage_effects` the fraction of their 95 %
//! t-intervals that hold them; the log-worth scores are absent (the analysis of ratings has
//! none). A participant whose ratings cannot be regressed (too few conditions rated before
//! dropping out) is left out; a run with fewer than two left has no scores and counts as not
//! significant. Runs are seeded as the paired comparisons' (design code 0, `study`).

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rayon::prelude::*;
use statrs::distribution::{ContinuousCDF, StudentsT};
use std::sync::atomic::{AtomicU64, Ordering};

use super::design::DesignChoice;
use super::observer::{normal, uniform};
use super::report::{Report, RunOutcome, summarise};
use super::{ALPHA, Config, SimulateError};
use crate::rating::{RatedTrial, plan};
use crate::schedule::derived_seed;
use crate::study::Study;

/// Simulates a rating study: every participant count × `runs` runs of the study's own design.
pub(super) fn simulate(
    study: &Study,
    config: &Config,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Report, SimulateError> {
    config.check(study)?;
    if config.options.designs != [DesignChoice::Study] {
        return Err(SimulateError::BadOption {
            option: "--designs",
            message: "must be `study` for a rating study: every participant rates every stimulus".into(),
        });
    }
    let jobs: Vec<(usize, u64)> = config
        .participants
        .iter()
        .flat_map(|&participants| (0..config.options.runs as u64).map(move |run| (participants, run)))
        .collect();
    let total = jobs.len() as u64;
    let done = AtomicU64::new(0);
    let code = DesignChoice::Study.code();
    let outcomes: Vec<RunOutcome> = jobs
        .par_iter()
        .map(|&(participants, run)| {
            let seed = derived_seed(derived_seed(derived_seed(config.options.seed, code), participants as u64), run);
            let outcome = run_once(study, config, participants, seed);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            outcome
        })
        .collect();
    let variant = (DesignChoice::Study, study.clone());
    let rows = outcomes
        .chunks(config.options.runs)
        .zip(&config.participants)
        .map(|(chunk, &participants)| summarise(&variant, participants, chunk, config))
        .collect();
    Ok(Report::new(study, config, rows))
}

/// One simulated observer's rating of a stimulus of quality `quality`.
fn rate(rng: &mut ChaCha8Rng, quality: f64, (bias, inconsistency): (f64, f64), lapse: f64) -> f64 {
    if uniform(rng) < lapse {
        return (1.0 + (uniform(rng) * 5.0).floor()).min(5.0);
    }
    (quality + bias + inconsistency * normal(rng)).round().clamp(1.0, 5.0)
}

/// One simulated study: every participant's ratings, their regressions, the t-test per factor.
fn run_once(study: &Study, config: &Config, participants: usize, run_seed: u64) -> RunOutcome {
    let mut outcome =
        RunOutcome { participants, significant: vec![false; config.truth.effects.len()], ..Default::default() };
    let design = study.rating.as_ref().expect("a rating study");
    let lambda: Vec<f64> = config.truth.log_worths.iter().map(|worth| worth.log_worth).collect();
    let mean = lambda.iter().sum::<f64>() / lambda.len() as f64;
    let quality: Vec<f64> = lambda.iter().map(|value| 3.0 + value - mean).collect();
    let hidden = (quality.iter().copied().fold(f64::NEG_INFINITY, f64::max) + 0.5).min(5.0);
    let columns = study.design_columns();
    let mut coefficients: Vec<Vec<f64>> = Vec::new();
    for participant in 0..participants {
        let seed = derived_seed(run_seed, participant as u64);
        let mut rng = ChaCha8Rng::seed_from_u64(derived_seed(seed, 1));
        let observer = (config.options.observer_sd * normal(&mut rng), 0.5 + 0.5 * uniform(&mut rng));
        let mut rated: Vec<(usize, f64)> = Vec::new();
        for trial in plan(study, seed) {
            let shown = match trial {
                RatedTrial::Condition { condition, .. } => quality[condition],
                RatedTrial::HiddenReference { .. } => hidden,
                RatedTrial::Catch { index } => f64::from(design.catch[index].expected),
            };
            let rating = rate(&mut rng, shown, observer, config.options.lapse);
            if let RatedTrial::Condition { condition, .. } = trial {
                rated.push((condition, rating));
            }
            if config.options.dropout > 0.0 && uniform(&mut rng) < config.options.dropout {
                break;
            }
        }
        outcome.judgments += rated.len();
        let rows: Vec<(Vec<f64>, f64)> = rated
            .iter()
            .map(|&(condition, rating)| {
                let mut row = vec![1.0];
                row.extend(&study.conditions[condition].levels);
                (row, rating)
            })
            .collect();
        if let Some(beta) = least_squares(&rows, columns.len() + 1) {
            coefficients.push(beta[1..].to_vec());
        }
    }
    if coefficients.len() < 2 {
        outcome.failure =
            Some(format!("{} participants rated enough conditions for a regression; 2 are needed", coefficients.len()));
        return outcome;
    }
    let n = coefficients.len() as f64;
    let Ok(t) = StudentsT::new(0.0, 1.0, n - 1.0) else { return outcome };
    let t_975 = t.inverse_cdf(0.975);
    let mut squares = Vec::new();
    let mut covered = 0usize;
    for (k, effect) in config.truth.effects.iter().enumerate() {
        let Some(column) = columns.iter().position(|name| *name == effect.factor) else { continue };
        let values: Vec<f64> = coefficients.iter().map(|beta| beta[column]).collect();
        let mean = values.iter().sum::<f64>() / n;
        let sd = (values.iter().map(|value| (value - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let se = sd / n.sqrt();
        let p = if se > 0.0 {
            2.0 * t.sf((mean / se).abs())
        } else if mean != 0.0 {
            0.0
        } else {
            1.0
        };
        outcome.significant[k] = p < ALPHA;
        squares.push((mean - effect.effect).powi(2));
        covered += usize::from((mean - effect.effect).abs() <= t_975 * se);
    }
    if !squares.is_empty() {
        outcome.rmse_effects = Some((squares.iter().sum::<f64>() / squares.len() as f64).sqrt());
        outcome.coverage_effects = Some(covered as f64 / squares.len() as f64);
    }
    outcome
}

/// Least squares of `rows` ((x, y) with `width` columns of x): β solving XᵀX β = Xᵀy by Gaussian
/// elimination with partial pivoting; `None` when XᵀX is singular (too few distinct rows).
fn least_squares(rows: &[(Vec<f64>, f64)], width: usize) -> Option<Vec<f64>> {
    let mut system = vec![vec![0.0; width + 1]; width];
    for (x, y) in rows {
        for i in 0..width {
            for j in 0..width {
                system[i][j] += x[i] * x[j];
            }
            system[i][width] += x[i] * y;
        }
    }
    for column in 0..width {
        let pivot = (column..width).max_by(|&a, &b| system[a][column].abs().total_cmp(&system[b][column].abs()))?;
        if system[pivot][column].abs() < 1e-9 {
            return None;
        }
        system.swap(column, pivot);
        for row in 0..width {
            if row != column {
                let factor = system[row][column] / system[column][column];
                for entry in column..=width {
                    system[row][entry] -= factor * system[column][entry];
                }
            }
        }
    }
    Some((0..width).map(|i| system[i][width] / system[i][i]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{Options, truth_from_effects};

    fn study() -> (tempfile::TempDir, Study) {
        let dir = tempfile::tempdir().unwrap();
        let file = crate::study::rating_tests::image_study(dir.path(), "[rating]\nmethod = \"acr\"\n");
        let study = crate::study::load_study(&file).unwrap();
        (dir, study)
    }

    fn config(study: &Study, shadow: f64, participants: Vec<usize>) -> Config {
        Config {
            truth: truth_from_effects(study, &[("shadow".into(), shadow), ("ca".into(), 0.0)]).unwrap(),
            participants,
            options: Options {
                designs: vec![DesignChoice::Study],
                observer_sd: 0.3,
                lapse: 0.02,
                dropout: 0.0,
                tie_nu: 0.5,
                runs: 200,
                seed: 3,
                bootstrap: 0,
            },
        }
    }

    #[test]
    fn a_factor_of_half_a_category_is_found_and_a_null_factor_rejected_at_about_alpha() {
        let (_dir, study) = study();
        let report = simulate(&study, &config(&study, 0.5, vec![4, 16]), &|_, _| {}).unwrap();
        let power = |row: usize, factor: &str| {
            report.rows[row].power.iter().find(|power| power.factor == factor).unwrap().power
        };
        // 12 ratings of 4 conditions per participant
        assert_eq!(report.rows[0].judgments_per_participant.mean, 12.0);
        assert!(power(1, "shadow") > 0.95, "16 participants: {}", power(1, "shadow"));
        assert!(power(0, "shadow") < power(1, "shadow"), "power grows with participants");
        for row in 0..2 {
            let null = power(row, "ca");
            assert!(null < 0.1, "a factor without effect is significant in {null} of the runs");
            let coverage = report.rows[row].coverage_effects.unwrap().mean;
            assert!((0.88..=0.99).contains(&coverage), "95 % t-intervals cover {coverage}");
        }
        // the same seed, the same report
        let again = simulate(&study, &config(&study, 0.5, vec![4, 16]), &|_, _| {}).unwrap();
        assert_eq!(serde_json::to_string(&again).unwrap(), serde_json::to_string(&report).unwrap());
    }

    #[test]
    fn ratings_are_whole_categories_and_other_designs_are_refused() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..1000 {
            let rating = rate(&mut rng, 4.8, (0.6, 1.0), 0.1);
            assert!((1.0..=5.0).contains(&rating) && rating.fract() == 0.0, "{rating}");
        }
        let (_dir, study) = study();
        let mut config = config(&study, 0.5, vec![4]);
        config.options.designs = vec![DesignChoice::All];
        let error = simulate(&study, &config, &|_, _| {}).unwrap_err();
        assert!(error.to_string().contains("--designs must be `study` for a rating study"), "{error}");
    }
}
