//! MLE_CO against `sureal` 0.9.0 (`analysis/reference/sureal_reference.py`): subsets of the
//! NFLX public and VQEG FR-TV Phase I (525 line, low) data sets SUREAL ships, and simulated
//! sets with missing cells and repetitions; equal within 1e-6.

use super::sureal::{Degenerate, Observation, fit_content_oblivious};
use super::sureal_full::{FullData, fit_full};

const REFERENCE: &str = include_str!("../../tests/reference/sureal_mle_co.json");
const TOLERANCE: f64 = 1e-6;

fn set(name: &str) -> serde_json::Value {
    let reference: serde_json::Value = serde_json::from_str(REFERENCE).expect("the fixture is JSON");
    reference["sets"][name].clone()
}

fn numbers(value: &serde_json::Value) -> Vec<f64> {
    value.as_array().expect("an array").iter().map(|v| v.as_f64().expect("a number")).collect()
}

fn observations(set: &serde_json::Value) -> (usize, usize, Vec<Observation>) {
    let ratings = set["ratings"]
        .as_array()
        .expect("ratings")
        .iter()
        .map(|row| {
            let row = numbers(row);
            Observation { stimulus: row[0] as usize, subject: row[1] as usize, score: row[2] }
        })
        .collect();
    (set["stimuli"].as_u64().unwrap() as usize, set["subjects"].as_u64().unwrap() as usize, ratings)
}

fn assert_close(name: &str, what: &str, ours: &[f64], theirs: &[f64]) {
    assert_eq!(ours.len(), theirs.len(), "{name} {what}: lengths");
    for (index, (a, b)) in ours.iter().zip(theirs).enumerate() {
        assert!((a - b).abs() <= TOLERANCE, "{name} {what}[{index}]: ours {a}, sureal {b}");
    }
}

#[test]
fn mle_co_equals_sureal_on_its_data_sets_and_simulated_ones() {
    for name in ["nflx_subset", "vqeg_525_low_subset", "simulated"] {
        let reference = set(name);
        let (stimuli, subjects, ratings) = observations(&reference);
        let fit = fit_content_oblivious(stimuli, subjects, &ratings).unwrap_or_else(|e| panic!("{name}: {e:?}"));
        assert!(fit.converged, "{name}");
        assert_close(name, "quality", &fit.quality, &numbers(&reference["quality"]));
        assert_close(name, "quality_se", &fit.quality_se, &numbers(&reference["quality_se"]));
        assert_close(name, "bias", &fit.bias, &numbers(&reference["bias"]));
        assert_close(name, "bias_se", &fit.bias_se, &numbers(&reference["bias_se"]));
        assert_close(name, "inconsistency", &fit.inconsistency, &numbers(&reference["inconsistency"]));
        assert_close(name, "inconsistency_se", &fit.inconsistency_se, &numbers(&reference["inconsistency_se"]));
    }
}

/// The full model's quality, bias and their standard errors (which depend on v_s² + a_c²
/// only) equal SUREAL's `MaximumLikelihoodEstimationModel`'s within 1e-6.
#[test]
fn the_full_model_s_identifiable_part_equals_sureal() {
    for name in ["nflx_subset", "vqeg_525_low_subset", "simulated"] {
        let reference = set(name);
        let (stimuli, subjects, ratings) = observations(&reference);
        let content: Vec<usize> = numbers(&reference["content"]).iter().map(|&c| c as usize).collect();
        let data = FullData { stimuli, subjects, content: &content, observations: &ratings };
        let fit = fit_full(data).unwrap_or_else(|e| panic!("{name}: {e:?}"));
        let full = &reference["full"];
        assert!(fit.converged, "{name}");
        assert_close(name, "full quality", &fit.quality, &numbers(&full["quality"]));
        assert_close(name, "full quality_se", &fit.quality_se, &numbers(&full["quality_se"]));
        assert_close(name, "full bias", &fit.bias, &numbers(&full["bias"]));
        assert_close(name, "full bias_se", &fit.bias_se, &numbers(&full["bias_se"]));
    }
}

#[test]
fn an_inconsistency_going_to_zero_is_degenerate_as_sureal_finds_it() {
    let reference = set("simulated_degenerate");
    let (stimuli, subjects, ratings) = observations(&reference);
    let inconsistency = numbers(&reference["inconsistency"]);
    let collapsed = (0..subjects).min_by(|&a, &b| inconsistency[a].total_cmp(&inconsistency[b])).unwrap();
    assert!(inconsistency[collapsed] < 1e-12);
    match fit_content_oblivious(stimuli, subjects, &ratings) {
        Err(Degenerate::Unbounded { subject, .. }) => assert_eq!(subject, collapsed),
        other => panic!("expected the subject's inconsistency to collapse, got {other:?}"),
    }
}

#[test]
fn too_few_ratings_are_refused() {
    let one =
        [Observation { stimulus: 0, subject: 0, score: 3.0 }, Observation { stimulus: 0, subject: 1, score: 4.0 }];
    assert!(matches!(fit_content_oblivious(1, 2, &one), Err(Degenerate::TooFew { .. })));
    assert!(matches!(fit_content_oblivious(1, 1, &one[..1]), Err(Degenerate::TooFew { .. })));
}
