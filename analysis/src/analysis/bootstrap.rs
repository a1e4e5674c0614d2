//! The bootstrap over participants: resamples refitted, percentile intervals widened for few
//! participants, set on the items and covariates.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

use crate::design::{self, ParticipantTallies};
use crate::fit::{self, FitOptions, ModelMatrix};

use super::{Analysis, Bootstrap, Options, Part, not_estimable_part};

/// The bootstrap interval at `level` for an estimate from `n_participants` participants: the
/// percentile interval with its ends' distances from `estimate` widened by
/// `c = √(n/(n−1)) · t_{n−1} / z`. A bootstrap over n participants estimates the variance with
/// the factor (n−1)/n and, from few participants, with the spread of a variance on n−1 degrees of
/// freedom; uncorrected, the percentile intervals of 30-participant studies covered the true
/// log-worths 93 % of the time instead of 95 % (c = 1.061 there; 1.0003 for 10 000 participants).
fn bootstrap_interval(mut values: Vec<f64>, level: f64, estimate: f64, n_participants: usize) -> Option<[f64; 2]> {
    if values.len() < 2 || n_participants < 2 {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let alpha = (1.0 - level) / 2.0;
    let n = n_participants as f64;
    let z = Normal::standard().inverse_cdf(1.0 - alpha);
    let t = StudentsT::new(0.0, 1.0, n - 1.0).map_or(z, |t| t.inverse_cdf(1.0 - alpha));
    let widen = (n / (n - 1.0)).sqrt() * t / z;
    let low = crate::quantile::type7(&values, alpha);
    let high = crate::quantile::type7(&values, 1.0 - alpha);
    Some([estimate - widen * (estimate - low), estimate + widen * (high - estimate)])
}

/// The bootstrap over participants: the item and factor models refitted on each resample of
/// the active participants (seeded per replicate), their intervals set on `analysis`.
pub(super) fn run_bootstrap(
    analysis: &mut Analysis,
    tallies: &ParticipantTallies,
    active: &[usize],
    n_conditions: usize,
    reference: usize,
    factor_x: Option<&ModelMatrix>,
    options: &Options,
) {
    const LEVEL: f64 = 0.95;
    let fit_options = FitOptions { tolerance: options.tolerance.max(1e-8), ..FitOptions::default() };
    let members: Vec<usize> = (0..n_conditions).filter(|&c| analysis.items[c].log_worth.is_some()).collect();
    let single_component = analysis.items.iter().all(|i| i.component.is_none());
    let x_items = ModelMatrix::items(n_conditions, &members, reference);
    let replicates: Vec<Option<(Vec<f64>, Option<Vec<f64>>)>> = (0..options.bootstrap)
        .into_par_iter()
        .map(|b| {
            let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
            rng.set_stream(b as u64 + 1);
            let rows = (0..active.len()).flat_map(|_| {
                let p = active[rng.random_range(0..active.len())];
                tallies.rows_of(p)
            });
            let rows: Vec<_> = rows.collect();
            let pairs = if n_conditions <= 512 { design::tally_dense(n_conditions, rows) } else { design::tally(rows) };
            let items = if single_component {
                let fit = fit::fit_ml(&pairs, &x_items, None, fit_options).ok()?;
                Some(members.iter().map(|&m| x_items.predict(m, &fit.beta)).collect::<Vec<f64>>())
            } else {
                None
            };
            let factors = match factor_x {
                Some(x) => Some(fit::fit_ml(&pairs, x, None, fit_options).ok()?.beta),
                None => None,
            };
            Some((items.unwrap_or_default(), factors))
        })
        .collect();
    let successful: Vec<&(Vec<f64>, Option<Vec<f64>>)> = replicates.iter().flatten().collect();
    let failed = replicates.len() - successful.len();
    if failed == replicates.len() {
        not_estimable_part(
            &mut analysis.warnings,
            &mut analysis.not_estimable,
            Part::Bootstrap,
            format!("none of its {failed} resamples had a finite fit (separation), so there are no intervals"),
        );
    } else if failed > 0 {
        analysis.warnings.push(format!(
            "bootstrap: {failed} of {} resamples had no finite fit (separation) and are left out of the intervals",
            replicates.len()
        ));
    }
    if single_component {
        for (k, &m) in members.iter().enumerate() {
            let estimate = analysis.items[m].log_worth.unwrap_or(0.0);
            analysis.items[m].ci =
                bootstrap_interval(successful.iter().map(|r| r.0[k]).collect(), LEVEL, estimate, active.len());
        }
    } else {
        analysis.warnings.push("bootstrap: no intervals for log-worth across a disconnected design".into());
    }
    if let Some(covariates) = analysis.covariates.as_mut() {
        for (k, covariate) in covariates.iter_mut().enumerate() {
            let values = successful.iter().filter_map(|r| r.1.as_ref().map(|f| f[k])).collect();
            covariate.ci = bootstrap_interval(values, LEVEL, covariate.estimate, active.len());
        }
    }
    analysis.bootstrap = Some(Bootstrap { replicates: options.bootstrap, seed: options.seed, failed, level: LEVEL });
}
