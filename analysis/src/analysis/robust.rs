//! The participant-cluster robust (sandwich) covariance of the factor model's maximum-likelihood
//! fit: the Bradley–Terry model takes every judgment as independent, but a participant's own
//! taste (their log-worths off the population's) makes their judgments correlated, and a design
//! that concentrates the comparisons on few pairs (the active designs) lets that taste into the
//! factor effects without the model's covariance seeing it.
//!
//! V = c · A⁻¹ (Σ_g s_g s_gᵀ) A⁻¹ with A the Fisher information at β̂ (the fit's covariance is
//! A⁻¹), s_g participant g's score Σ (wins_i − n·π_ij)(x_i − x_j) and c = G/(G−1) (G
//! participants; the "CR1" small-sample factor, as R's `sandwich::vcovCL` with `type = "HC0"`,
//! `cadjust = TRUE`). The analysis reports per effect the larger of this standard error and the
//! model's (Angrist & Pischke 2009, §8.2: with few clusters the sandwich alone is too small).

use crate::design::ParticipantTallies;
use crate::fit::{Fit, ModelMatrix};

/// The participant-cluster robust covariance of `fit` (a maximum-likelihood fit of `x` to the
/// pooled tallies of `participants`), as a dense p×p matrix; `None` with fewer than two
/// participants that have a judgment.
pub(crate) fn cluster_robust_covariance(
    fit: &Fit,
    x: &ModelMatrix,
    tallies: &ParticipantTallies,
    participants: &[usize],
) -> Option<Vec<Vec<f64>>> {
    let p = x.n_params;
    let lambda: Vec<f64> = (0..x.rows.len()).map(|c| x.predict(c, &fit.beta)).collect();
    let mut meat = vec![vec![0.0; p]; p];
    let mut clusters = 0usize;
    for &participant in participants {
        let pairs = tallies.of(participant);
        if pairs.is_empty() {
            continue;
        }
        clusters += 1;
        let mut score = vec![0.0; p];
        for pair in pairs {
            let probability = 1.0 / (1.0 + (lambda[pair.j] - lambda[pair.i]).exp());
            let residual = pair.wins_i as f64 - pair.n() as f64 * probability;
            for &(column, value) in &x.rows[pair.i] {
                score[column] += residual * value;
            }
            for &(column, value) in &x.rows[pair.j] {
                score[column] -= residual * value;
            }
        }
        for a in 0..p {
            for b in 0..p {
                meat[a][b] += score[a] * score[b];
            }
        }
    }
    if clusters < 2 {
        return None;
    }
    let factor = clusters as f64 / (clusters - 1) as f64;
    let bread = |a: usize, b: usize| fit.covariance[(a, b)];
    // bread · meat
    let left: Vec<Vec<f64>> =
        (0..p).map(|a| (0..p).map(|b| (0..p).map(|k| bread(a, k) * meat[k][b]).sum()).collect()).collect();
    Some(
        (0..p)
            .map(|a| (0..p).map(|b| factor * (0..p).map(|k| left[a][k] * bread(k, b)).sum::<f64>()).collect())
            .collect(),
    )
}

/// xᵀ·V·x of a sparse model-matrix row `x` ((column, value) pairs): the robust variance of
/// that linear combination of the parameters (a log-worth of the item model).
pub(crate) fn robust_variance_of(covariance: &[Vec<f64>], x: &[(usize, f64)]) -> f64 {
    x.iter().map(|&(a, xa)| x.iter().map(|&(b, xb)| xa * covariance[a][b] * xb).sum::<f64>()).sum()
}

#[cfg(test)]
mod tests {
    use crate::analysis::{Options, Screening, analyze_judgments};
    use crate::data::{ConditionTable, Judgment, Judgments};

    /// Six participants with their own tastes (sd 0.6 on four conditions), three of them mostly
    /// on one pair; the factor model's estimates and the item model's log-worths, each with
    /// model and cluster-robust standard errors, from R's `glm` and the sandwich by hand
    /// (`analysis/reference/cluster_robust.R`).
    const REFERENCE: &str = include_str!("../../tests/reference/cluster_robust.json");

    #[test]
    fn effects_and_log_worths_take_the_larger_of_the_model_and_the_cluster_robust_standard_error() {
        let reference: serde_json::Value = serde_json::from_str(REFERENCE).unwrap();
        let values = |key: &str| -> Vec<f64> {
            reference[key].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
        };
        let rows = reference["rows"]
            .as_array()
            .unwrap()
            .iter()
            .map(|row| {
                let row: Vec<u32> = row.as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as u32).collect();
                Judgment {
                    participant: row[0],
                    left: row[1],
                    right: row[2],
                    left_chosen: row[3] == 1,
                    count: 1,
                    group: 0,
                }
            })
            .collect();
        let conditions: Vec<String> = (0..4).map(|c| format!("C{c}")).collect();
        let judgments = Judgments {
            conditions: conditions.clone(),
            participants: (0..6).map(|p| format!("p{p}")).collect(),
            groups: Vec::new(),
            rows,
        };
        let table = ConditionTable {
            conditions,
            factors: vec!["a".into(), "b".into()],
            levels: vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0], vec![1.0, 1.0]],
        };
        let options = Options { screening: Screening::Off, agreement_simulations: 10, ..Options::default() };
        let analysis = analyze_judgments(&judgments, Some(&table), &options).unwrap();
        let covariates = analysis.covariates.unwrap();
        let (estimate, model_se, robust_se) = (values("estimate"), values("model_se"), values("robust_se"));
        for (k, covariate) in covariates.iter().enumerate() {
            assert!((covariate.estimate - estimate[k]).abs() < 1e-6, "{}: {}", covariate.name, covariate.estimate);
            let expected = model_se[k].max(robust_se[k]);
            assert!(
                (covariate.se - expected).abs() < 1e-6 * expected,
                "{}: se {} vs {expected}",
                covariate.name,
                covariate.se
            );
            assert!((covariate.z - covariate.estimate / expected).abs() < 1e-6);
        }
        // the fixture's tastes make the robust error the larger one for both effects
        assert!(robust_se.iter().zip(&model_se).all(|(robust, model)| robust > model));
        // the item model's log-worths (C0 the reference), the same rule
        let (worth, item_model_se, item_robust_se) =
            (values("item_log_worth"), values("item_model_se"), values("item_robust_se"));
        assert!(item_robust_se.iter().zip(&item_model_se).all(|(robust, model)| robust > model));
        assert_eq!(analysis.items[0].se, Some(0.0));
        for (c, item) in analysis.items.iter().enumerate().skip(1) {
            let (log_worth, se, model) = (item.log_worth.unwrap(), item.se.unwrap(), item.model_se.unwrap());
            assert!((log_worth - worth[c - 1]).abs() < 1e-6, "{}: {log_worth}", item.condition);
            assert!((model - item_model_se[c - 1]).abs() < 1e-6 * model, "{}: model se {model}", item.condition);
            let expected = item_model_se[c - 1].max(item_robust_se[c - 1]);
            assert!((se - expected).abs() < 1e-6 * expected, "{}: se {se} vs {expected}", item.condition);
        }
    }
}
