//! Tests of the threshold module against questplus 2023.1 (fixture written by
//! `analysis/reference/questplus_reference.py`).

use serde::Deserialize;

use super::ThresholdError;
use super::quest::first_minimum;
use super::quest::*;

#[derive(Deserialize)]
struct Fixture {
    versions: serde_json::Value,
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    name: String,
    function: String,
    scale: String,
    x: Vec<f64>,
    thresholds: Vec<f64>,
    slopes: Vec<f64>,
    guess: f64,
    lapses: Vec<f64>,
    chosen: Vec<usize>,
    correct: Vec<bool>,
    mode: Vec<f64>,
    mean: Vec<f64>,
    posterior_max: f64,
}

fn fixture() -> Fixture {
    serde_json::from_str(include_str!("../../tests/reference/questplus_2023_1.json")).unwrap()
}

fn config(c: &Case) -> QuestPlusConfig {
    QuestPlusConfig {
        x: c.x.clone(),
        thresholds: c.thresholds.clone(),
        slopes: c.slopes.clone(),
        lapses: c.lapses.clone(),
        guess: c.guess,
        function: c.function.parse().unwrap(),
        scale: c.scale.parse().unwrap(),
    }
}

/// Every stimulus questplus chose, and its final mode and mean, for every case of the fixture.
#[test]
fn every_choice_and_estimate_equals_questplus() {
    let f = fixture();
    assert_eq!(f.versions["questplus"], "2023.1");
    assert!(f.cases.len() >= 20);
    for c in &f.cases {
        let mut q = QuestPlus::new(&config(c)).unwrap();
        for (k, (&chosen, &correct)) in c.chosen.iter().zip(&c.correct).enumerate() {
            assert_eq!(q.next_index(), chosen, "{}: trial {k}", c.name);
            q.update(chosen, correct).unwrap();
        }
        let mode = q.mode();
        assert_eq!([mode.threshold, mode.slope, mode.lapse], c.mode[..], "{}", c.name);
        let mean = q.mean();
        for (got, want) in [mean.threshold, mean.slope, mean.lapse].iter().zip(&c.mean) {
            assert!((got - want).abs() <= 1e-9 * want.abs().max(1.0), "{}: mean {got} vs {want}", c.name);
        }
        let max = q.posterior().iter().copied().fold(0.0, f64::max);
        assert!(
            (max - c.posterior_max).abs() < 1e-9 * c.posterior_max,
            "{}: posterior max {max} vs {}",
            c.name,
            c.posterior_max
        );
    }
}

/// Watson (2017) as questplus's tests/test_qp.py states it: Example 1 ends at threshold −20,
/// the threshold-and-slope example at −20 and 3, and the sequences start −18, −22.
#[test]
fn watson_examples_final_modes() {
    let f = fixture();
    let case = |name: &str| f.cases.iter().find(|c| c.name == name).unwrap();
    for (name, threshold, slope, n) in
        [("watson2017-example1", -20.0, 3.5, 32), ("watson2017-threshold-slope", -20.0, 3.0, 64)]
    {
        let c = case(name);
        assert_eq!(c.correct.len(), n);
        let q =
            QuestPlus::replay(&config(c), &c.chosen.iter().copied().zip(c.correct.iter().copied()).collect::<Vec<_>>())
                .unwrap();
        assert_eq!(q.mode().threshold, threshold);
        assert_eq!(q.mode().slope, slope);
        let x: Vec<f64> = c.chosen.iter().take(2).map(|&i| c.x[i]).collect();
        assert_eq!(x, [-18.0, -22.0]);
    }
}

#[test]
fn shipped_levels_map_to_the_fixtures_x() {
    let levels: Vec<f64> = (0..10).map(|k| f64::from(1 << k)).collect();
    let d = StimulusDomain::from_levels(&levels, IntensityRule::InverseKnob, StimScale::Log10).unwrap();
    assert_eq!(d.levels[0], 512.0);
    assert_eq!(d.levels[9], 1.0);
    assert_eq!(d.intensities[0], 1.0 / 512.0);
    let f = fixture();
    let c = f.cases.iter().find(|c| c.name == "vpls-weibull-0").unwrap();
    for (a, b) in d.x.iter().zip(&c.x) {
        assert!((a - b).abs() < 1e-14, "{a} vs {b}");
    }
    assert_eq!(d.index_of_level(64.0), Some(3));
    let db = StimulusDomain::from_levels(&levels, IntensityRule::InverseKnob, StimScale::Db).unwrap();
    assert!((db.x[0] - 20.0 * c.x[0]).abs() < 1e-12);
    let knob = StimulusDomain::from_levels(&levels, IntensityRule::Knob, StimScale::Linear).unwrap();
    assert_eq!(knob.x, levels);
}

fn shipped_config(function: PsychFunction) -> QuestPlusConfig {
    let levels: Vec<f64> = (0..10).map(|k| f64::from(1 << k)).collect();
    let d = StimulusDomain::from_levels(&levels, IntensityRule::InverseKnob, StimScale::Log10).unwrap();
    QuestPlusConfig {
        x: d.x,
        thresholds: (0..=12).map(|k| -3.0 + 0.25 * f64::from(k)).collect(),
        slopes: vec![1.0, 2.0, 3.5, 5.0],
        lapses: vec![0.0, 0.01, 0.02, 0.04],
        guess: 0.5,
        function,
        scale: StimScale::Log10,
    }
}

#[test]
fn replay_is_bit_identical_and_serde_round_trips() {
    let cfg = shipped_config(PsychFunction::Weibull);
    let mut q = QuestPlus::new(&cfg).unwrap();
    let mut answers = Vec::new();
    for k in 0..30 {
        let i = q.next_index();
        let correct = k % 3 != 1;
        q.update(i, correct).unwrap();
        answers.push((i, correct));
    }
    let r = QuestPlus::replay(&cfg, &answers).unwrap();
    assert!(q.posterior().iter().zip(r.posterior()).all(|(a, b)| a.to_bits() == b.to_bits()));
    assert_eq!(q.next_index(), r.next_index());
    let json = serde_json::to_string(&q).unwrap();
    let back: QuestPlus = serde_json::from_str(&json).unwrap();
    // Exact: serde_json's float_roundtrip feature reads back every bit of the config's floats.
    assert!(back == q, "the round trip changed the state");
    // A stored posterior that the answers do not give is refused.
    let mut v: serde_json::Value = serde_json::from_str(&json).unwrap();
    v["posterior"][0] = serde_json::json!(0.5);
    let err = serde_json::from_value::<QuestPlus>(v).unwrap_err().to_string();
    assert!(err.contains("differs from the replay of its 30 answers"), "{err}");
}

#[test]
fn bad_grids_get_one_sentence() {
    let cfg = shipped_config(PsychFunction::Weibull);
    let err = StimulusDomain::from_levels(&[1.0, 4.0, 2.0], IntensityRule::Knob, StimScale::Log10).unwrap_err();
    assert_eq!(err, ThresholdError::NotIncreasing { grid: "levels", index: 2, value: 2.0, previous: 4.0 });
    assert_eq!(
        err.to_string(),
        "levels must be strictly increasing, but value 2 (2) does not exceed the one before it (4)"
    );
    let mut far = cfg.clone();
    far.thresholds = vec![1.0, 2.0];
    let err = QuestPlus::new(&far).unwrap_err();
    assert!(matches!(err, ThresholdError::GridOutsideStimuli { low: 1.0, high: 2.0, .. }), "{err}");
    let mut lapse = cfg.clone();
    lapse.lapses = vec![0.0, 0.6];
    assert!(matches!(QuestPlus::new(&lapse).unwrap_err(), ThresholdError::OutOfRange { what: "lapse", .. }));
    let mut slope = cfg.clone();
    slope.slopes = vec![0.0];
    assert!(matches!(QuestPlus::new(&slope).unwrap_err(), ThresholdError::NotPositive { what: "slope", .. }));
    assert_eq!(
        "probit".parse::<PsychFunction>().unwrap_err().to_string(),
        "function `probit` is not known (expected one of: weibull, logistic, normal)"
    );
    assert_eq!("dB".parse::<StimScale>().unwrap(), StimScale::Db);
    assert_eq!("inverse-knob".parse::<IntensityRule>().unwrap(), IntensityRule::InverseKnob);
    let mut q = QuestPlus::new(&cfg).unwrap();
    assert_eq!(q.update(10, true).unwrap_err(), ThresholdError::UnknownStimulus { index: 10, stimuli: 10 });
    assert!(StimulusDomain::from_levels(&[0.0, 1.0], IntensityRule::InverseKnob, StimScale::Linear).is_err());
    assert!(StimulusDomain::from_intensities(&[1.0, 2.0], &[0.1, 0.1], StimScale::Linear).is_err());
}

#[test]
fn serde_names_are_the_study_files() {
    let cfg = shipped_config(PsychFunction::Normal);
    let v = serde_json::to_value(&cfg).unwrap();
    assert_eq!(v["function"], "normal");
    assert_eq!(v["scale"], "log10");
    assert_eq!(serde_json::to_value(StimScale::Db).unwrap(), "dB");
    assert_eq!(serde_json::to_value(IntensityRule::InverseKnob).unwrap(), "inverse-knob");
}

/// Ties go to the first index, as numpy's `argmin` (the domain is sorted lowest intensity first).
#[test]
fn ties_go_to_the_lowest_intensity() {
    assert_eq!(first_minimum(&[0.3, 0.2, 0.2, 0.25]), 1);
    assert_eq!(first_minimum(&[0.2, 0.2]), 0);
    assert_eq!(first_minimum(&[0.5, 0.4, 0.3]), 2);
}
