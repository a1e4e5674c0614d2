//! The reference the incremental update is measured against: the Laplace approximation refitted
//! from scratch on the whole judgment log — the exact MAP of the same model and prior by Newton's
//! method (the log-posterior is concave for both links), with covariance the inverse Hessian.
//! Cost O(pairs·p² + p³) per Newton step, so refitting per judgment is what the incremental
//! update avoids; the benchmark times it.

use super::{ActiveError, Link, Result, Target};

/// A Laplace fit: MAP and the inverse Hessian there (row-major p × p).
#[derive(Debug, Clone)]
pub struct LaplaceFit {
    pub mean: Vec<f64>,
    pub covariance: Vec<f64>,
    pub iterations: usize,
}

/// Cholesky factor L (row-major, lower) of a symmetric positive definite matrix, or `None`.
pub(crate) fn cholesky(a: &[f64], p: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; p * p];
    for i in 0..p {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|k| l[i * p + k] * l[j * p + k]).sum();
            if i == j {
                let d = a[i * p + i] - sum;
                if !(d > 0.0 && d.is_finite()) {
                    return None;
                }
                l[i * p + i] = d.sqrt();
            } else {
                l[i * p + j] = (a[i * p + j] - sum) / l[j * p + j];
            }
        }
    }
    Some(l)
}

/// Solves L·Lᵀ·x = b.
fn solve(l: &[f64], p: usize, b: &[f64]) -> Vec<f64> {
    let mut y = b.to_vec();
    for i in 0..p {
        let sum: f64 = (0..i).map(|k| l[i * p + k] * y[k]).sum();
        y[i] = (y[i] - sum) / l[i * p + i];
    }
    for i in (0..p).rev() {
        let sum: f64 = (i + 1..p).map(|k| l[k * p + i] * y[k]).sum();
        y[i] = (y[i] - sum) / l[i * p + i];
    }
    y
}

/// The MAP and Laplace covariance of `target` under `link` and prior N(0, prior_sd²·I) given
/// the judgments `(winner, loser)`.
pub fn refit(target: &Target, link: Link, prior_sd: f64, judgments: &[(usize, usize)]) -> Result<LaplaceFit> {
    target.check()?;
    let n = target.conditions();
    // Directed tallies: wins[w·n + l] = judgments of w over l.
    let mut wins = vec![0u64; n * n];
    for &(winner, loser) in judgments {
        if winner >= n || loser >= n {
            return Err(ActiveError::UnknownCondition { condition: winner.max(loser), conditions: n });
        }
        if winner == loser {
            return Err(ActiveError::SameCondition { condition: winner });
        }
        wins[winner * n + loser] += 1;
    }
    let observed: Vec<(usize, usize, f64)> =
        (0..n * n).filter(|&k| wins[k] > 0).map(|k| (k / n, k % n, wins[k] as f64)).collect();
    // Each observation's sparse direction a = x_w − x_l.
    let directions: Vec<Vec<(usize, f64)>> = observed
        .iter()
        .map(|&(w, l, _)| match target {
            Target::Worths { .. } => vec![(w, 1.0), (l, -1.0)],
            Target::Factors { design } => {
                design[w].iter().zip(&design[l]).map(|(a, b)| a - b).enumerate().filter(|(_, d)| *d != 0.0).collect()
            }
        })
        .collect();
    let p = match target {
        Target::Worths { conditions } => *conditions,
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
    let degenerate = |message: String| ActiveError::Degenerate {
        judgments: judgments.len() as u64,
        message: format!("Laplace refit: {message}"),
    };
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
    let mut theta = vec![0.0; p];
    let mut value = objective(&theta);
    for iteration in 1..=200 {
        let (gradient, hessian) = hessian_at(&theta);
        let l = cholesky(&hessian, p).ok_or_else(|| degenerate("the Hessian is not positive definite".into()))?;
        let step = solve(&l, p, &gradient);
        let mut scale = 1.0;
        loop {
            let candidate: Vec<f64> = theta.iter().zip(&step).map(|(t, s)| t + scale * s).collect();
            let candidate_value = objective(&candidate);
            if candidate_value >= value - 1e-12 * value.abs().max(1.0) || scale < 1e-8 {
                theta = candidate;
                value = candidate_value;
                break;
            }
            scale *= 0.5;
        }
        let change = step.iter().map(|s| (scale * s).abs()).fold(0.0, f64::max);
        if !change.is_finite() {
            return Err(degenerate("the Newton step is not finite".into()));
        }
        if change < 1e-11 {
            let (_, hessian) = hessian_at(&theta);
            let l = cholesky(&hessian, p).ok_or_else(|| degenerate("the Hessian is not positive definite".into()))?;
            let mut covariance = vec![0.0; p * p];
            for c in 0..p {
                let mut unit = vec![0.0; p];
                unit[c] = 1.0;
                for (r, x) in solve(&l, p, &unit).into_iter().enumerate() {
                    covariance[r * p + c] = x;
                }
            }
            return Ok(LaplaceFit { mean: theta, covariance, iterations: iteration });
        }
    }
    Err(degenerate("Newton's method did not converge in 200 iterations".into()))
}
