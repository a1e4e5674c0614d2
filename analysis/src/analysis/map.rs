//! `log_worth_map` (issue 48): every condition's centred MAP log-worth under the Bradley–Terry
//! model with the prior N(0, `prior_sd`²) per condition — the estimate that an active design with
//! `prior = "spread"` optimises and that ASAP and pwcmp-style scaling report, beside the
//! maximum-likelihood log-worths. One Laplace refit of every judgment
//! ([`crate::active::laplace::centred_map_log_worths`], the scorer of the `early_gap` example),
//! O(n³) per Newton step, so only up to [`MAP_CONDITION_LIMIT`] conditions.

use super::Analysis;
use crate::active::Link;
use crate::active::laplace::centred_map_log_worths;
use crate::data::Judgments;

/// Most conditions `log_worth_map` is computed for (a dense refit beyond would dominate the
/// analysis's time).
pub const MAP_CONDITION_LIMIT: usize = 200;

/// Sets each item's `log_worth_map` from every judgment (ties not among them), or says in the
/// warnings why it is absent (fewer than 3 conditions: absent without a word).
pub(super) fn fill_log_worth_map(judgments: &Judgments, prior_sd: f64, analysis: &mut Analysis) {
    let n = judgments.conditions.len();
    if n < 3 {
        return;
    }
    if n > MAP_CONDITION_LIMIT {
        analysis
            .warnings
            .push(format!("log_worth_map not computed: {n} conditions exceed its limit of {MAP_CONDITION_LIMIT}"));
        return;
    }
    let judged = judgments.rows.iter().map(|row| {
        let (winner, loser) = if row.left_chosen { (row.left, row.right) } else { (row.right, row.left) };
        (winner as usize, loser as usize, row.count)
    });
    match centred_map_log_worths(n, Link::Logit, prior_sd, judged) {
        Ok(map) => {
            for (item, value) in analysis.items.iter_mut().zip(map) {
                item.log_worth_map = Some(value);
            }
        }
        Err(error) => analysis.warnings.push(format!("log_worth_map not computed: {error}")),
    }
}

#[cfg(test)]
mod tests {
    use crate::analysis::{Options, analyze};

    #[derive(serde::Deserialize)]
    struct Fixture {
        cases: Vec<Case>,
    }

    #[derive(serde::Deserialize)]
    struct Case {
        name: String,
        prior_sd: f64,
        trials_csv: String,
        log_worth_map: std::collections::BTreeMap<String, f64>,
    }

    /// Against scipy's MAP fit of the same model and prior (analysis/reference/
    /// log_worth_map_reference.py), also where one condition was never beaten (no MLE).
    #[test]
    fn log_worth_map_is_scipys_centred_map_fit() {
        let fixture: Fixture =
            serde_json::from_str(include_str!("../../tests/reference/log_worth_map_scipy.json")).unwrap();
        assert_eq!(fixture.cases.len(), 2);
        for case in fixture.cases {
            let options = Options { prior_sd: case.prior_sd, ..Options::default() };
            let analysis = analyze(&case.trials_csv, None, &options).unwrap();
            assert_eq!(analysis.items.len(), case.log_worth_map.len(), "{}", case.name);
            for item in &analysis.items {
                let expected = case.log_worth_map[&item.condition];
                let got = item.log_worth_map.unwrap_or_else(|| panic!("{}: no log_worth_map", case.name));
                assert!(
                    (got - expected).abs() < 1e-6,
                    "{}, {}: {got} against scipy's {expected}",
                    case.name,
                    item.condition
                );
            }
        }
    }

    #[test]
    fn a_prior_sd_that_is_not_positive_is_refused_in_one_sentence() {
        let csv = "participant,left,right,chosen\np,A,B,A\np,B,C,B\np,C,A,A\n";
        for bad in [0.0, -1.0, f64::NAN] {
            let error = analyze(csv, None, &Options { prior_sd: bad, ..Options::default() }).unwrap_err();
            assert!(
                error.to_string().starts_with("--prior-sd: ") && error.to_string().contains("not a positive number"),
                "{error}"
            );
        }
        let analysis = analyze(csv, None, &Options::default()).unwrap();
        let map: Vec<f64> = analysis.items.iter().map(|item| item.log_worth_map.unwrap()).collect();
        assert!(map.iter().sum::<f64>().abs() < 1e-12, "centred: {map:?}");
    }
}
