//! The marginal truth (issue 48 item 6): what the analysis's pooled Bradley–Terry fit estimates
//! when the simulated participants have their own tastes and lapses.
//!
//! The analysis fits one logistic model to every participant's judgments. Each simulated
//! participant's log-worths are the truth + N(0, `observer_sd`²) per condition, and with
//! probability `lapse` an answer is a coin flip, so over the population condition i is
//! preferred to j with probability
//! P̄ᵢⱼ = (1 − lapse) · E σ(λᵢ − λⱼ + ε) + lapse / 2, ε ~ N(0, 2·observer_sd²),
//! which is flatter than σ(λᵢ − λⱼ). With many participants the pooled fit tends to the
//! parameters whose model probabilities match P̄ (the score equation
//! Σ (P̄ᵢⱼ − σ(zᵢⱼᵀθ))·zᵢⱼ = 0): the **marginal** (population-averaged) log-worths and factor
//! effects, smaller in size than the per-participant (conditional) truth the simulation draws
//! from. For the thesis survey's effects (observer sd 0.3, lapse 0.02) by 6.1 % whichever pairs
//! are compared (`analysis/reference/attenuation.py`: anchored, all pairs and one-factor pairs
//! alike, because σ's attenuation under a normal is nearly a constant factor for differences up
//! to 1). Here the pairs are every pair once, so the marginal truth does not depend on the
//! design. (With a truth not additive in the factors, `--truth-worth`, the marginal effects
//! are the factor model's limit over every pair, not the truth's least-squares projection,
//! even without taste or lapses.) Absent for studies with "not sure" answers (their Davidson observers are not this
//! model) and where the factors are collinear.

use mrstudy_analysis::active::quadrature::Rule;
use mrstudy_analysis::table::fixed;
use serde::Serialize;

use super::truth::{ConditionWorth, FactorEffect, Truth};
use crate::study::Study;

/// The marginal log-worths (differences to the reference, the first condition) and factor
/// effects of the simulated population.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarginalTruth {
    pub log_worths: Vec<ConditionWorth>,
    pub effects: Vec<FactorEffect>,
}

/// The marginal truth of `truth` under taste sd `observer_sd` and `lapse` (see the module).
pub(super) fn marginal_truth(study: &Study, truth: &Truth, observer_sd: f64, lapse: f64) -> Option<MarginalTruth> {
    if study.participation.allow_tie {
        return None;
    }
    let worths: Vec<f64> = truth.log_worths.iter().map(|w| w.log_worth).collect();
    let n = worths.len();
    let rule = Rule::gauss_hermite(40);
    let spread = std::f64::consts::SQRT_2 * observer_sd;
    let mut pairs = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let d = worths[i] - worths[j];
            let taste: f64 = rule.nodes.iter().zip(&rule.weights).map(|(z, w)| w * sigmoid(d + spread * z)).sum();
            pairs.push((i, j, (1.0 - lapse) * taste + lapse / 2.0));
        }
    }
    // The item model: a column per condition after the reference.
    let item_rows: Vec<Vec<f64>> = (0..n).map(|c| (1..n).map(|k| f64::from(u8::from(k == c))).collect()).collect();
    let start: Vec<f64> = worths[1..].iter().map(|w| w - worths[0]).collect();
    let items = fit_limit(&item_rows, &pairs, start)?;
    let log_worths = truth
        .log_worths
        .iter()
        .enumerate()
        .map(|(c, w)| ConditionWorth {
            condition: w.condition.clone(),
            log_worth: if c == 0 { 0.0 } else { items[c - 1] },
        })
        .collect();
    let effects = if truth.effects.is_empty() {
        Vec::new()
    } else {
        let factor_rows: Vec<Vec<f64>> = study.conditions.iter().map(|condition| condition.levels.clone()).collect();
        let start = truth.effects.iter().map(|e| e.effect).collect();
        let values = fit_limit(&factor_rows, &pairs, start)?;
        truth.effects.iter().zip(values).map(|(e, effect)| FactorEffect { factor: e.factor.clone(), effect }).collect()
    };
    Some(MarginalTruth { log_worths, effects })
}

impl MarginalTruth {
    /// The line under `simulate`'s table: the marginal truth beside the truth, and the factor
    /// by which the log-worths shrink.
    pub(super) fn line(&self, truth: &Truth, observer_sd: f64, lapse: f64) -> String {
        let reference = truth.log_worths[0].log_worth;
        let (mut marginal, mut conditional) = (0.0, 0.0);
        for (m, t) in self.log_worths.iter().zip(&truth.log_worths).skip(1) {
            marginal += m.log_worth.abs();
            conditional += (t.log_worth - reference).abs();
        }
        let shrink = if conditional > 0.0 {
            format!(" (log-worths × {})", fixed(marginal / conditional, 3))
        } else {
            String::new()
        };
        let effects: Vec<String> = self
            .effects
            .iter()
            .zip(&truth.effects)
            .map(|(m, t)| format!("{} {} (truth {})", m.factor, fixed(m.effect, 3), fixed(t.effect, 3)))
            .collect();
        let effects = if effects.is_empty() { String::new() } else { format!(": {}", effects.join(", ")) };
        format!(
            "marginal truth, what the pooled analysis estimates under taste sd {observer_sd} and lapse {lapse}{shrink}{effects}; coverage (marginal) is of it\n"
        )
    }
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// θ solving Σ (p − σ(zᵀθ))·z = 0 over `pairs` (i, j, p), z = rows[i] − rows[j], by Newton's
/// method from `start`; `None` when the information is singular or it does not converge.
fn fit_limit(rows: &[Vec<f64>], pairs: &[(usize, usize, f64)], mut theta: Vec<f64>) -> Option<Vec<f64>> {
    let k = theta.len();
    for _ in 0..100 {
        let mut gradient = vec![0.0; k];
        let mut information = vec![vec![0.0; k]; k];
        for &(i, j, p) in pairs {
            let z: Vec<f64> = rows[i].iter().zip(&rows[j]).map(|(a, b)| a - b).collect();
            let q = sigmoid(z.iter().zip(&theta).map(|(z, t)| z * t).sum());
            for a in 0..k {
                gradient[a] += (p - q) * z[a];
                for b in 0..k {
                    information[a][b] += q * (1.0 - q) * z[a] * z[b];
                }
            }
        }
        let step = solve(information, gradient)?;
        theta.iter_mut().zip(&step).for_each(|(t, s)| *t += s);
        if step.iter().all(|s| s.abs() < 1e-13) {
            return Some(theta);
        }
    }
    None
}

/// A·x = b by Gauss–Jordan with partial pivoting; `None` for a singular A.
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let k = b.len();
    for column in 0..k {
        let pivot = (column..k).max_by(|&x, &y| a[x][column].abs().total_cmp(&a[y][column].abs()))?;
        if a[pivot][column].abs() < 1e-12 {
            return None;
        }
        a.swap(column, pivot);
        b.swap(column, pivot);
        for row in 0..k {
            if row != column {
                let factor = a[row][column] / a[column][column];
                for c in column..k {
                    a[row][c] -= factor * a[column][c];
                }
                b[row] -= factor * b[column];
            }
        }
    }
    Some((0..k).map(|r| b[r] / a[r][r]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::default_truth;

    fn survey() -> Study {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies/web-survey.toml");
        crate::study::load_study(&file).unwrap()
    }

    /// `analysis/reference/attenuation.py` (numpy 2.4.6, scipy 1.17.1): the pooled limit of the
    /// thesis effects under taste sd 0.3 and lapse 0.02 over every pair, and with neither the
    /// conditional truth itself.
    #[test]
    fn thesis_effects_attenuate_as_the_python_reference_says() {
        let study = survey();
        let truth = default_truth(&study).unwrap();
        let marginal = marginal_truth(&study, &truth, 0.3, 0.02).unwrap();
        let expected = [("gi", 0.2536), ("cm", -0.2066), ("ca", 0.4039)];
        for (effect, (name, value)) in marginal.effects.iter().zip(expected) {
            assert_eq!(effect.factor, name);
            assert!((effect.effect - value).abs() < 1e-4, "{name}: {}", effect.effect);
        }
        // the log-worths shrink by the same factor (an additive truth stays additive)
        for (m, t) in marginal.log_worths.iter().zip(&truth.log_worths).skip(1) {
            let conditional = t.log_worth - truth.log_worths[0].log_worth;
            assert!((m.log_worth - 0.9393 * conditional).abs() < 1e-3, "{}: {}", m.condition, m.log_worth);
        }
        let same = marginal_truth(&study, &truth, 0.0, 0.0).unwrap();
        for (m, t) in same.effects.iter().zip(&truth.effects) {
            assert!((m.effect - t.effect).abs() < 1e-10, "{}: {}", m.factor, m.effect);
        }
    }
}
