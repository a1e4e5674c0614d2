//! The `both` target's choice (issue 48): one posterior over the log-worths (updated as for
//! [`Target::Worths`](super::Target::Worths)), pairs chosen by an **A-optimal** criterion over
//! both quantities a paired-comparison study reports: the centred log-worths λ − λ̄ and the
//! factor effects β̂ = P·λ, P = (X̃ᵀX̃)⁻¹X̃ᵀ the least-squares effects of the log-worths
//! (X̃: the condition × factor matrix, centred per column).
//!
//! **Criterion.** A judgment of the pair (i, j) is expected to shrink the covariance Σ by
//! c·u·uᵀ (u = Σ·a, a = eᵢ − eⱼ, c = (v − E v′)/v² the outcome-averaged ADF drop of the
//! difference's variance v, as the fantasy update of the other targets). Each quantity's summed
//! posterior variance falls by c·‖C·u‖² (log-worths, C the centring) and c·‖P·u‖² (effects). The
//! score is the sum of the two drops **each divided by that quantity's current summed
//! variance** tr(CΣC) and tr(PΣPᵀ): the relative reductions, so neither quantity dominates
//! whatever their number or scale (n log-worths against k effects; the effects' variance is
//! about 4/n of a log-worth's in a 2ᵏ factorial). To first order it is the expected drop of
//! ln tr(CΣC) + ln tr(PΣPᵀ). As for the other targets, the mean difference enters c with the
//! weight ρ of [`Posterior::effective_mean_weight`](super::Posterior::effective_mean_weight),
//! a batch is chosen greedily with a fantasy update after each pair, and until the graph is
//! connected only pairs joining two components are candidates. O(n³·k) per pair of the batch.

use rand_chacha::ChaCha8Rng;

use super::best_pair::BestPair;
use super::quadrature::Rule;
use super::{ActiveError, Link, Result};
use crate::design::{find, union};

/// P = (X̃ᵀX̃)⁻¹X̃ᵀ (k × n, row-major per effect): the least-squares factor effects of the
/// log-worths, X̃ the design centred per column. Refused: collinear factors.
pub fn effect_projection(design: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
    let n = design.len();
    let k = design.first().map_or(0, Vec::len);
    let means: Vec<f64> = (0..k).map(|f| design.iter().map(|row| row[f]).sum::<f64>() / n as f64).collect();
    let centred: Vec<Vec<f64>> =
        design.iter().map(|row| row.iter().zip(&means).map(|(x, m)| x - m).collect()).collect();
    // Gauss–Jordan on [X̃ᵀX̃ | X̃ᵀ] with partial pivoting.
    let mut augmented: Vec<Vec<f64>> = (0..k)
        .map(|a| {
            let gram = (0..k).map(|b| centred.iter().map(|row| row[a] * row[b]).sum());
            gram.chain(centred.iter().map(|row| row[a])).collect()
        })
        .collect();
    let scale = (0..k).map(|a| augmented[a][a]).fold(0.0, f64::max);
    for column in 0..k {
        let pivot = (column..k)
            .max_by(|&a, &b| augmented[a][column].abs().total_cmp(&augmented[b][column].abs()))
            .expect("a non-empty range");
        if augmented[pivot][column].abs() <= 1e-10 * scale.max(f64::MIN_POSITIVE) {
            return Err(ActiveError::BadDesign {
                message: format!("factor {column} is a combination of the others, so its effect has no estimate"),
            });
        }
        augmented.swap(column, pivot);
        let divisor = augmented[column][column];
        augmented[column].iter_mut().for_each(|x| *x /= divisor);
        for row in 0..k {
            if row != column {
                let factor = augmented[row][column];
                let (source, target) = if row < column {
                    let (low, high) = augmented.split_at_mut(column);
                    (&high[0], &mut low[row])
                } else {
                    let (low, high) = augmented.split_at_mut(row);
                    (&low[column], &mut high[0])
                };
                target.iter_mut().zip(source.iter()).for_each(|(t, s)| *t -= factor * s);
            }
        }
    }
    Ok(augmented.into_iter().map(|row| row[k..].to_vec()).collect())
}

/// What the `both` batch needs of the posterior.
pub(super) struct BothBatch<'a> {
    pub link: Link,
    pub rule: &'a Rule,
    /// The log-worths' posterior mean and covariance (n, n × n row-major).
    pub mean: &'a [f64],
    pub covariance: &'a [f64],
    /// [`effect_projection`] of the study's design.
    pub projection: &'a [Vec<f64>],
    /// ρ, the weight of the mean difference.
    pub mean_weight: f64,
    /// Union–find parents and component count of the judged pairs.
    pub parent: Vec<usize>,
    pub components: usize,
}

/// The summed variances (tr CΣC, tr PΣPᵀ) of the centred log-worths and of the effects.
pub fn summed_variances(covariance: &[f64], projection: &[Vec<f64>]) -> (f64, f64) {
    let n = projection.first().map_or(0, Vec::len);
    let total: f64 = covariance.iter().sum();
    let worths = (0..n).map(|i| covariance[i * n + i]).sum::<f64>() - total / n as f64;
    let effects = projection
        .iter()
        .map(|p| (0..n).map(|i| p[i] * (0..n).map(|j| covariance[i * n + j] * p[j]).sum::<f64>()).sum::<f64>())
        .sum();
    (worths, effects)
}

/// The criterion at one posterior covariance: the pair's score
/// c(ρ·m, v) · (‖C·u‖²/tr CΣC + ‖P·u‖²/tr PΣPᵀ).
pub struct Criterion<'a> {
    link: Link,
    rule: &'a Rule,
    projection: &'a [Vec<f64>],
    covariance: &'a [f64],
    /// tr CΣC and tr PΣPᵀ.
    totals: (f64, f64),
}

impl<'a> Criterion<'a> {
    /// The criterion at `covariance` (the log-worths', n × n row-major) with `projection`
    /// ([`effect_projection`] of the design, k × n). Refused: a summed variance not positive.
    pub fn new(link: Link, rule: &'a Rule, projection: &'a [Vec<f64>], covariance: &'a [f64]) -> Result<Self> {
        let (worths_total, effects_total) = summed_variances(covariance, projection);
        if !(worths_total > 0.0 && effects_total > 0.0 && worths_total.is_finite() && effects_total.is_finite()) {
            return Err(degenerate(format!("summed variances {worths_total:e} and {effects_total:e}")));
        }
        Ok(Criterion { link, rule, projection, covariance, totals: (worths_total, effects_total) })
    }

    /// The score of the pair (i, j) whose weighted mean difference is `mean_difference`
    /// (ρ·(mᵢ − mⱼ)); with it the variance v of the pair's difference.
    pub fn score(&self, (i, j): (usize, usize), mean_difference: f64) -> Result<(f64, f64)> {
        let n = self.projection.first().map_or(0, Vec::len);
        let (worths_total, effects_total) = self.totals;
        let u: Vec<f64> = (0..n).map(|r| self.covariance[r * n + i] - self.covariance[r * n + j]).collect();
        let v = u[i] - u[j];
        if !(v > 0.0 && v.is_finite()) {
            return Err(degenerate(format!("variance {v:e} of the pair ({i}, {j})")));
        }
        let u_mean = u.iter().sum::<f64>() / n as f64;
        let worths_drop: f64 = u.iter().map(|x| (x - u_mean) * (x - u_mean)).sum();
        let effects_drop: f64 = self.projection.iter().map(|p| dot(p, &u).powi(2)).sum();
        let c = expected_drop(self.link, self.rule, mean_difference, v);
        Ok((c * (worths_drop / worths_total + effects_drop / effects_total), v))
    }
}

fn degenerate(message: String) -> ActiveError {
    ActiveError::Degenerate { judgments: 0, message }
}

/// c = (v − E v′)/v²: the outcome-averaged ADF drop of the difference's variance per unit of
/// its squared variance (the rank-one coefficient of Σ′ = Σ − c·u·uᵀ).
fn expected_drop(link: Link, rule: &Rule, m: f64, v: f64) -> f64 {
    let (z, _, v_won) = link.tilted(m, v, rule);
    let (_, _, v_lost) = link.tilted(-m, v, rule);
    (v - (z * v_won + (1.0 - z) * v_lost)) / (v * v)
}

/// The batch for the `both` target: `trials` pairs, best first, never `last` back to back.
pub(super) fn best_pairs(
    mut input: BothBatch,
    trials: usize,
    mut last: Option<(usize, usize)>,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<(usize, usize)>> {
    let n = input.mean.len();
    let mut covariance = input.covariance.to_vec();
    let mut batch = Vec::with_capacity(trials);
    while batch.len() < trials {
        let criterion = Criterion::new(input.link, input.rule, input.projection, &covariance)?;
        let mut best = BestPair::new();
        for i in 0..n {
            for j in i + 1..n {
                if last == Some((i, j))
                    || (input.components > 1 && find(&mut input.parent, i) == find(&mut input.parent, j))
                {
                    continue;
                }
                let (score, _) = criterion.score((i, j), input.mean_weight * (input.mean[i] - input.mean[j]))?;
                best.offer((i, j), score, rng);
            }
        }
        let (i, j) = best.pair.expect("at least 3 conditions leave a pair besides the last one");
        batch.push((i, j));
        last = Some((i, j));
        if union(&mut input.parent, i, j) {
            input.components -= 1;
        }
        if batch.len() == trials {
            break;
        }
        // Fantasy update: Σ −= c·u·uᵀ with the mean unchanged (c at the full mean difference).
        let u: Vec<f64> = (0..n).map(|r| covariance[r * n + i] - covariance[r * n + j]).collect();
        let v = u[i] - u[j];
        let c = expected_drop(input.link, input.rule, input.mean[i] - input.mean[j], v);
        if !(c.is_finite() && c >= 0.0) {
            return Err(degenerate(format!("fantasy update of the pair ({i}, {j}) with variance {v:e}")));
        }
        for r in 0..n {
            for s in 0..n {
                covariance[r * n + s] -= c * u[r] * u[s];
            }
        }
    }
    Ok(batch)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
