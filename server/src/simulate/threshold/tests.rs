//! Tests of the threshold simulation: the server's own QUEST+ choices, the constant stimuli's
//! spread, the scores' direction with more trials, reproducibility and refusals.

use super::*;
use crate::simulate::Estimate;
use crate::threshold::{Answer, next_level};

fn study() -> Study {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("t.toml");
    std::fs::write(&file, crate::study::threshold_tests::THRESHOLD).unwrap();
    crate::study::load_study(&file).unwrap()
}

fn config(trials: Vec<usize>, runs: usize) -> ThresholdConfig {
    ThresholdConfig {
        trials,
        truth: Some("threshold=-1.3,slope=3.5".into()),
        threshold_sd: 0.2,
        lapse: 0.02,
        runs,
        seed: 3,
        bootstrap: 20,
    }
}

#[test]
fn quest_plus_trials_are_the_levels_the_server_chooses() {
    let study = study();
    let setup = setup(&study, &config(vec![30], 1)).unwrap();
    let design = study.threshold.as_ref().unwrap();
    let intensities = crate::threshold::intensities(&study, None).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let trials = collect(&setup, Method::QuestPlus, 30, -1.3, &mut rng).unwrap();
    let x_of_level: Vec<f64> = intensities.iter().map(|&i| i.log10()).collect();
    let mut answers = Vec::new();
    for &(x, correct) in &trials {
        let level = next_level(design, &intensities, &answers).unwrap();
        assert!((x_of_level[level] - x).abs() < 1e-12, "trial {}: level {level}, x {x}", answers.len() + 1);
        answers.push(Answer { level, correct });
    }
}

#[test]
fn constant_stimuli_spread_the_trials_evenly_over_the_levels() {
    let study = study();
    let setup = setup(&study, &config(vec![23], 1)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let trials = collect(&setup, Method::ConstantStimuli, 23, -1.3, &mut rng).unwrap();
    assert_eq!(trials.len(), 23);
    let points = aggregate(trials);
    assert_eq!(points.len(), 10);
    assert!(points.iter().all(|point| point.n == 2 || point.n == 3), "{points:?}");
    assert_eq!(points.iter().filter(|point| point.n == 3).count(), 3);
}

#[test]
fn more_trials_give_a_more_precise_threshold_and_the_report_is_reproducible() {
    let study = study();
    let config = config(vec![12, 80], 24);
    let report = simulate_threshold(&study, &config, &|_, _| {}).unwrap();
    assert_eq!(report.rows.len(), 4);
    for method in Method::ALL {
        let rows: Vec<&ThresholdRow> = report.rows.iter().filter(|row| row.method == method).collect();
        let (few, many) = (rows[0].rmse.unwrap().mean, rows[1].rmse.unwrap().mean);
        assert!(many < few, "{}: RMSE {many} at 80 trials, {few} at 12", method.name());
        assert!(many < 0.2, "{}: RMSE {many} at 80 trials", method.name());
        assert!(rows[1].within_tolerance.mean > rows[0].within_tolerance.mean);
        assert_eq!(rows[1].failed, 0);
    }
    assert_eq!(simulate_threshold(&study, &config, &|_, _| {}).unwrap(), report, "the same seed, the same report");
    let table = report.table();
    assert!(table.contains("quest+") && table.contains("constant-stimuli") && !table.contains("NaN"), "{table}");
    let json = serde_json::to_string(&report).unwrap();
    assert!(json.contains("\"method\":\"quest+\"") && !json.contains("NaN"), "{json}");
    assert_eq!(report.plots().len(), 2);
    assert_eq!(report.power_lines(0.5).len(), 2);
}

#[test]
fn needs_interpolate_the_rmse_to_the_tolerance() {
    let study = study();
    let mut report = simulate_threshold(&study, &config(vec![10, 20], 2), &|_, _| {}).unwrap();
    for row in &mut report.rows {
        let rmse = if row.trials_per_participant == 10 { 0.2 } else { 0.05 };
        row.rmse = Some(Estimate { mean: rmse, mcse: None });
        row.within_tolerance = Estimate { mean: if rmse < 0.1 { 0.9 } else { 0.4 }, mcse: None };
    }
    let need = &report.needs(0.8)[0];
    // log-log: 0.2 → 0.05 is two halvings over one doubling; 0.1 is one halving: √2 · 10.
    assert!((need.rmse_at_tolerance.unwrap() - 10.0 * 2f64.sqrt()).abs() < 1e-9, "{need:?}");
    assert_eq!(need.within_target, Some(20));
}

#[test]
fn bad_truths_and_options_are_one_sentence() {
    let study = study();
    let refuse = |config: ThresholdConfig| simulate_threshold(&study, &config, &|_, _| {}).unwrap_err().to_string();
    let mut bad = config(vec![10], 1);
    bad.truth = Some("gi=0.3".into());
    assert!(refuse(bad.clone()).contains("`gi` is not one of threshold, slope"));
    bad.truth = Some("slope=-1".into());
    assert!(refuse(bad.clone()).contains("the slope must be positive"));
    bad.truth = Some("threshold=abc".into());
    assert!(refuse(bad.clone()).contains("`abc` of threshold is not a finite number"));
    let mut zero = config(vec![0], 1);
    assert!(refuse(zero.clone()).starts_with("--trials-per-participant"));
    zero.trials = vec![10];
    zero.runs = 0;
    assert!(refuse(zero).starts_with("--runs"));
}
