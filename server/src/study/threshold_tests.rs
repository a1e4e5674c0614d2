//! Tests of threshold study files: the study they resolve into, and one sentence naming the
//! file and the key for each kind of bad `[threshold]` table.

use std::path::{Path, PathBuf};

use super::threshold::{Function, Intensity, Scale, ThresholdDesign};
use super::*;

fn write_study(dir: &Path, body: &str) -> PathBuf {
    let file = dir.join("threshold.toml");
    std::fs::write(&file, body).unwrap();
    file
}

pub(crate) const THRESHOLD: &str = r#"
slug = "t"
title = "T"
kind = "threshold"
question = "Which image is the real scene?"
[texts]
welcome = "w"
consent = "c"
instructions = "i"
[[scenes]]
name = "a"
render = "survey-1"
[[scenes]]
name = "b"
render = "survey-2"
[render]
size = [48, 36]
spp = 2
[threshold]
knob = "vpls"
levels = [1, 2, 4, 8, 16, 32, 64, 128, 256, 512]
intensity = "inverse-knob"
scale = "log10"
function = "weibull"
threshold = [-3.0, -2.75, -2.5, -2.25, -2.0, -1.75, -1.5, -1.25, -1.0, -0.75, -0.5, -0.25, 0.0]
slope = [1.0, 2.0, 3.5, 5.0]
lapse = [0.0, 0.01, 0.02, 0.04]
guess = 0.5
trials = 40
reference = "ground-truth"
"#;

fn refusal(body: &str) -> StudyError {
    let dir = tempfile::tempdir().unwrap();
    let file = write_study(dir.path(), body);
    let error = load_study(&file).unwrap_err();
    // one sentence naming the file and the key
    let text = error.to_string();
    assert!(text.contains("threshold.toml") && !text.contains('\n'), "{text}");
    error
}

#[test]
fn a_threshold_study_is_a_detection_design_over_its_levels() {
    let dir = tempfile::tempdir().unwrap();
    let study = load_study(&write_study(dir.path(), THRESHOLD)).unwrap();
    assert_eq!(study.kind, StudyKind::Threshold);
    assert_eq!(study.conditions.len(), 10);
    assert_eq!(study.conditions[6].name, "vpls-64");
    assert_eq!(
        study.conditions[6].knob,
        Some(mrstudy_renderer::knob::KnobSetting { knob: mrstudy_renderer::knob::Knob::Vpls, value: 64 })
    );
    assert_eq!(study.design.reference, Some(DesignReference::GroundTruth));
    assert_eq!(study.design.scenes, SceneDraw::Same);
    let design = study.threshold.as_ref().unwrap();
    assert_eq!(design.intensity, Intensity::InverseKnob);
    assert_eq!(design.scale, Scale::Log10);
    assert_eq!(design.function, Function::Weibull);
    assert_eq!(design.level_of("vpls-64"), Some(6));
    assert_eq!(study.trial_count(), 40);
    // every level's stimulus has DIR's indirect light (the default condition gi = 1)
    assert!(study.conditions.iter().all(|c| c.factors.as_ref().unwrap().label() == "gi"));
    // the definition stored in the database reads back with its design and levels
    let stored: Study = serde_json::from_str(&serde_json::to_string(&study).unwrap()).unwrap();
    assert_eq!(stored.threshold, study.threshold);
    assert_eq!(stored.conditions[6].knob, study.conditions[6].knob);
    assert_eq!(stored.trial_count(), 40);
    assert_eq!(ThresholdDesign::condition_name(design.knob, 512), "vpls-512");
}

#[test]
fn an_unknown_knob_is_refused_with_the_knobs_listed() {
    let error = refusal(&THRESHOLD.replace("knob = \"vpls\"", "knob = \"vpl\""));
    assert_eq!(error.key, "threshold.knob");
    assert!(error.expected.contains("\"vpl\"") && error.expected.contains("ism_size, "), "{}", error.expected);
}

#[test]
fn levels_not_increasing_or_outside_the_knobs_range_are_refused() {
    let error = refusal(&THRESHOLD.replace("[1, 2, 4, 8,", "[1, 4, 2, 8,"));
    assert_eq!(error.key, "threshold.levels[2]");
    assert!(error.expected.contains("increasing"), "{}", error.expected);
    let error = refusal(&THRESHOLD.replace("[1, 2, 4, 8,", "[0, 2, 4, 8,"));
    assert_eq!(error.key, "threshold.levels[0]");
    assert!(error.expected.contains("from 1 to 65536"), "{}", error.expected);
    let error = refusal(&THRESHOLD.replace("levels = [1, 2, 4, 8, 16, 32, 64, 128, 256, 512]", "levels = [8]"));
    assert_eq!(error.key, "threshold.levels");
}

#[test]
fn a_threshold_grid_that_excludes_the_levels_range_is_refused() {
    // inverse-knob on log10: x from log10(1/512) = −2.709 to 0; a grid from 0.5 up misses it
    let error = refusal(&THRESHOLD.replace(
        "threshold = [-3.0, -2.75, -2.5, -2.25, -2.0, -1.75, -1.5, -1.25, -1.0, -0.75, -0.5, -0.25, 0.0]",
        "threshold = [0.5, 1.0]",
    ));
    assert_eq!(error.key, "threshold.threshold");
    assert!(error.expected.contains("-2.7093 to 0") && error.expected.contains("0.5 to 1"), "{}", error.expected);
    // the same grid fits the knob itself on log10 (x from 0 to 2.709)
    let dir = tempfile::tempdir().unwrap();
    let fits = THRESHOLD
        .replace(
            "threshold = [-3.0, -2.75, -2.5, -2.25, -2.0, -1.75, -1.5, -1.25, -1.0, -0.75, -0.5, -0.25, 0.0]",
            "threshold = [0.5, 1.0]",
        )
        .replace("intensity = \"inverse-knob\"", "intensity = \"knob\"");
    assert!(load_study(&write_study(dir.path(), &fits)).is_ok());
    // a zero level has no x on a log scale
    let zero = THRESHOLD
        .replace("knob = \"vpls\"", "knob = \"ism_size\"")
        .replace("[1, 2, 4, 8,", "[0, 2, 4, 8,")
        .replace("intensity = \"inverse-knob\"", "intensity = \"knob\"");
    let error = refusal(&zero);
    assert_eq!(error.key, "threshold.levels[0]");
    assert!(error.expected.contains("positive intensity"), "{}", error.expected);
}

#[test]
fn bad_model_keys_name_their_key() {
    let cases = [
        ("scale = \"log10\"", "scale = \"ln\"", "threshold.scale"),
        ("function = \"weibull\"", "function = \"gumbel\"", "threshold.function"),
        ("intensity = \"inverse-knob\"", "intensity = \"metric:flip:affected\"", "threshold.intensity"),
        ("slope = [1.0, 2.0, 3.5, 5.0]", "slope = [0.0, 2.0]", "threshold.slope[0]"),
        ("slope = [1.0, 2.0, 3.5, 5.0]", "slope = [2.0, 1.0]", "threshold.slope[1]"),
        ("lapse = [0.0, 0.01, 0.02, 0.04]", "lapse = [0.0, 0.6]", "threshold.lapse[1]"),
        ("lapse = [0.0, 0.01, 0.02, 0.04]", "lapse = []", "threshold.lapse"),
        ("guess = 0.5", "guess = 1.0", "threshold.guess"),
        ("trials = 40", "trials = 0", "threshold.trials"),
        ("reference = \"ground-truth\"", "reference = \"vpls-512\"", "threshold.reference"),
        ("reference = \"ground-truth\"", "reference = \"ground-truth\"\nspeed = 1", "threshold"),
        ("reference = \"ground-truth\"", "reference = \"ground-truth\"\nrealisations = 40", "threshold.realisations"),
    ];
    for (from, to, key) in cases {
        let error = refusal(&THRESHOLD.replace(from, to));
        assert_eq!(error.key, key, "{to}: {}", error.expected);
    }
    let metric = THRESHOLD.replace("intensity = \"inverse-knob\"", "intensity = \"metric:flip_mean:affected\"");
    let dir = tempfile::tempdir().unwrap();
    let study = load_study(&write_study(dir.path(), &metric)).unwrap();
    assert_eq!(
        study.threshold.unwrap().intensity,
        Intensity::Metric { metric: "flip_mean".into(), region: "affected".into() }
    );
}

#[test]
fn a_knob_of_the_indirect_light_needs_gi_and_the_survey_tables_are_refused() {
    let error = refusal(
        &THRESHOLD
            .replace("reference = \"ground-truth\"", "reference = \"ground-truth\"\ncondition = { gi = 0, ca = 1 }"),
    );
    assert_eq!(error.key, "threshold.condition");
    assert!(error.expected.contains("gi = 1") && error.expected.contains("\"vpls\""), "{}", error.expected);
    let error = refusal(&format!("{THRESHOLD}\n[design]\npairs = \"all\"\n"));
    assert_eq!(error.key, "design");
    let error = refusal(&THRESHOLD.replace("[threshold]", "[thresholds]"));
    assert_eq!(error.key, "threshold");
    // the path tracer's knob takes any condition; a condition with ca keeps it
    let dir = tempfile::tempdir().unwrap();
    let spp = THRESHOLD
        .replace("knob = \"vpls\"", "knob = \"spp\"")
        .replace("reference = \"ground-truth\"", "reference = \"ground-truth\"\ncondition = { gi = 1, ca = 1 }");
    let study = load_study(&write_study(dir.path(), &spp)).unwrap();
    assert_eq!(study.conditions[0].factors.as_ref().unwrap().label(), "gi+ca");
}

#[test]
fn render_on_demand_is_refused_where_it_cannot_work() {
    let with = |lines: &str| {
        THRESHOLD.replace("reference = \"ground-truth\"", &format!("reference = \"ground-truth\"\n{lines}"))
    };
    let error = refusal(&with("render = \"later\""));
    assert_eq!(error.key, "threshold.render");
    let error = refusal(
        &with("render = \"on-demand\"")
            .replace("intensity = \"inverse-knob\"", "intensity = \"metric:flip_mean:affected\""),
    );
    assert!(error.key == "threshold.render" && error.to_string().contains("every level's stimulus record"), "{error}");
    let error = refusal(&with("render_ahead = 2"));
    assert_eq!(error.key, "threshold.render_ahead");
    let error = refusal(&with("render = \"on-demand\"\nrender_ahead = 0"));
    assert_eq!(error.key, "threshold.render_ahead");
    let dir = tempfile::tempdir().unwrap();
    let study = load_study(&write_study(dir.path(), &with("render = \"on-demand\""))).unwrap();
    let design = study.threshold.unwrap();
    assert_eq!((design.render, design.render_ahead), (super::threshold::RenderWhen::OnDemand, 3));
}
