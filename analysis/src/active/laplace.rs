//! The reference the incremental update is measured against: the Laplace approximation refitted
//! from scratch on the whole judgment log — the exact MAP of the same model and prior by Newton's
//! method (the log-posterior is concave for both links), with covariance the inverse Hessian.
//! Cost O(pairs·p² + p³) per Newton step, so refitting per judgment is what the incremental
//! update avoids; the benchmark times it.

use super::{ActiveError, Link, Result, Target};
use crate::newton::{Settings, Stop, cholesky, inverse, maximise, solve};

/// A Laplace fit: MAP and the inverse Hessian there (row-major p × p).
#[derive(Debug, Clone)]
pub struct LaplaceFit {
    pub mean: Vec<f64>,
    pub covariance: Vec<f64>,
    pub iterations: usize,
}

/// The MAP and Laplace covariance of `target` under `link` and prior N(0, prior_sd²·I) given
/// the judgments `(winner, loser)`.
pub fn refit(target: &Target, link: Link, prior_sd: f64, judgments: &[(usize, usize)]) -> Result<LaplaceFit> {
    refit_counted(target, link, prior_sd, judgments.iter().map(|&(winner, loser)| (winner, loser, 1)))
}

/// The centred MAP log-worths of `conditions` conditions under `link` and prior
/// N(0, prior_sd²) per condition, given judgments `(winner, loser, count)`: the refit's mean
/// minus its average. The estimate the side-by-side with ASAP scores designs by
/// (docs/simulate/README.md; `early_gap`'s scorer), which `prior = "spread"` optimises and
/// `mrstudy analyze` reports as `log_worth_map`. Defined for any judgments (the prior
/// identifies every log-worth, also of a condition never compared or never beaten).
pub fn centred_map_log_worths(
    conditions: usize,
    link: Link,
    prior_sd: f64,
    judgments: impl IntoIterator<Item = (usize, usize, u64)>,
) -> Result<Vec<f64>> {
    let fit = refit_counted(&Target::Worths { conditions }, link, prior_sd, judgments)?;
    let mean = fit.mean.iter().sum::<f64>() / conditions.max(1) as f64;
    Ok(fit.mean.iter().map(|m| m - mean + 0.0).collect())
}

/// [`refit`] with judgments `(winner, loser, count)`: `count` identical judgments each.
pub fn refit_counted(
    target: &Target,
    link: Link,
    prior_sd: f64,
    judgments: impl IntoIterator<Item = (usize, usize, u64)>,
) -> Result<LaplaceFit> {
    target.check()?;
    if !(prior_sd > 0.0 && prior_sd.is_finite()) {
        return Err(ActiveError::BadOption {
            option: "prior_sd",
            message: format!("the prior sd must be positive and finite, got {prior_sd}"),
        });
    }
    let n = target.conditions();
    // Directed tallies: wins[w·n + l] = judgments of w over l.
    let mut wins = vec![0u64; n * n];
    let mut total = 0u64;
    for (winner, loser, count) in judgments {
        if winner >= n || loser >= n {
            return Err(ActiveError::UnknownCondition { condition: winner.max(loser), conditions: n });
        }
        if winner == loser {
            return Err(ActiveError::SameCondition { condition: winner });
        }
        wins[winner * n + loser] += count;
        total += count;
    }
    let observed: Vec<(usize, usize, f64)> =
        (0..n * n).filter(|&k| wins[k] > 0).map(|k| (k / n, k % n, wins[k] as f64)).collect();
    // Each observation's sparse direction a = x_w − x_l.
    let directions: Vec<Vec<(usize, f64)>> = observed
        .iter()
        .map(|&(w, l, _)| match target {
            Target::Worths { .. } | Target::Both { .. } => vec![(w, 1.0), (l, -1.0)],
            Target::Factors { design } => {
                design[w].iter().zip(&design[l]).map(|(a, b)| a - b).enumerate().filter(|(_, d)| *d != 0.0).collect()
            }
        })
        .collect();
    let p = match target {
        Target::Worths { .. } | Target::Both { .. } => n,
        Target::Factors { design } => design[0].len(),
    };
    let precision = 1.0 / (prior_sd * prior_sd);
    let objective = |theta: &[f64]| -> f64 {
        let prior: f64 = theta.iter().map(|t| -0.5 * precision * t * t).sum();
        prior
            + observed
                .iter()
                .zip(&directions)
                .map(|(&(_, _, count), a)| {
                    let d: f64 = a.iter().map(|&(k, x)| x * theta[k]).sum();
                    count * link.probability(d).ln()
                })
                .sum::<f64>()
    };
    let degenerate =
        |message: String| ActiveError::Degenerate { judgments: total, message: format!("Laplace refit: {message}") };
    let hessian_at = |theta: &[f64]| -> (Vec<f64>, Vec<f64>) {
        let mut gradient: Vec<f64> = theta.iter().map(|t| -precision * t).collect();
        let mut hessian = vec![0.0; p * p];
        for a in 0..p {
            hessian[a * p + a] = precision;
        }
        for (&(_, _, count), a) in observed.iter().zip(&directions) {
            let d: f64 = a.iter().map(|&(k, x)| x * theta[k]).sum();
            let (g, h) = link.log_derivatives(d);
            for &(r, xr) in a {
                gradient[r] += count * g * xr;
                for &(c, xc) in a {
                    hessian[r * p + c] += count * h * xr * xc;
                }
            }
        }
        (gradient, hessian)
    };
    let hessian_not_positive = || degenerate("the Hessian is not positive definite".into());
    let problem = Posterior {
        value: &objective,
        step: &|theta: &[f64]| {
            let (gradient, hessian) = hessian_at(theta);
            let l = cholesky(&hessian, p).ok_or_else(hessian_not_positive)?;
            Ok(solve(&l, &gradient))
        },
    };
    let settings = Settings { tolerance: 1e-11, max_iterations: 200, min_scale: 1e-8 };
    let maximum = maximise(&problem, vec![0.0; p], settings).map_err(|stop| match stop {
        Stop::Failed(error) => error,
        Stop::NotFinite => degenerate("the Newton step is not finite".into()),
        Stop::NotConverged { .. } => degenerate("Newton's method did not converge in 200 iterations".into()),
    })?;
    let (_, hessian) = hessian_at(&maximum.beta);
    let l = cholesky(&hessian, p).ok_or_else(hessian_not_positive)?;
    Ok(LaplaceFit { mean: maximum.beta, covariance: inverse(&l, p), iterations: maximum.iterations })
}

/// The log-posterior and its Newton step as [`crate::newton`]'s objective.
struct Posterior<'a> {
    value: &'a dyn Fn(&[f64]) -> f64,
    step: &'a dyn Fn(&[f64]) -> Result<Vec<f64>>,
}

impl crate::newton::Concave for Posterior<'_> {
    type Failure = ActiveError;

    fn value(&self, beta: &[f64]) -> f64 {
        (self.value)(beta)
    }

    fn step(&self, beta: &[f64]) -> Result<Vec<f64>> {
        (self.step)(beta)
    }
}
