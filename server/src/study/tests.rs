//! Tests of survey study files: refusals naming file and key, the design's pairs, conditions CSV.

use std::path::{Path, PathBuf};

use super::*;

fn write_study(dir: &Path, body: &str) -> PathBuf {
    let file = dir.join("study.toml");
    std::fs::write(&file, body).unwrap();
    file
}

const MINIMAL: &str = r#"
slug = "s"
title = "T"
kind = "paired-comparison"
question = "Q?"
[texts]
welcome = "w"
consent = "c"
instructions = "i"
[[factors]]
name = "gi"
[[factors]]
name = "ca"
[[conditions]]
name = "LQ"
levels = { gi = 0, ca = 0 }
[[conditions]]
name = "GI"
levels = { gi = 1, ca = 0 }
[[conditions]]
name = "HQ"
levels = { gi = 1, ca = 1 }
[[scenes]]
name = "a"
render = "survey-1"
[[scenes]]
name = "b"
render = "survey-2"
[design]
pairs = "anchored"
anchors = ["LQ", "HQ"]
repetitions = 2
scenes = "different"
"#;

#[test]
fn a_level_the_renderer_cannot_render_names_the_condition_and_factor() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_study(dir.path(), &MINIMAL.replace("levels = { gi = 1, ca = 1 }", "levels = { gi = 2, ca = 1 }"));
    let error = load_study(&file).unwrap_err();
    assert_eq!(error.key, "conditions[2].levels");
    assert!(error.expected.contains("`gi`") && error.expected.contains("level 2"), "{}", error.expected);
}

#[test]
fn anchored_pairs_are_anchor_pairs_then_others_with_each_anchor() {
    let dir = tempfile::tempdir().unwrap();
    let study = load_study(&write_study(dir.path(), MINIMAL)).unwrap();
    assert_eq!(study.design.pairs, vec![(0, 2), (0, 1), (2, 1)]);
    assert_eq!(study.trial_count(), 6);
    assert!(study.needs_renderer());
    assert_eq!(study.conditions_csv(), "condition,gi,ca\nLQ,0,0\nGI,1,0\nHQ,1,1\n");
}

#[test]
fn unknown_condition_in_anchors_names_file_key_and_expectation() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_study(dir.path(), &MINIMAL.replace("[\"LQ\", \"HQ\"]", "[\"LQ\", \"XX\"]"));
    let error = load_study(&file).unwrap_err();
    assert_eq!(error.key, "design.anchors[1]");
    let message = error.to_string();
    assert!(message.contains("study.toml"), "{message}");
    assert!(message.contains("found \"XX\""), "{message}");
}

#[test]
fn unknown_key_is_refused_with_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_study(dir.path(), &MINIMAL.replace("repetitions = 2", "repetitions = 2\nrepetition = 3"));
    let message = load_study(&file).unwrap_err().to_string();
    assert!(message.contains("repetition"), "{message}");
}

#[test]
fn wrong_type_is_refused_with_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_study(dir.path(), &MINIMAL.replace("repetitions = 2", "repetitions = \"two\""));
    let message = load_study(&file).unwrap_err().to_string();
    assert!(message.contains("repetitions"), "{message}");
}

#[test]
fn unknown_scene_for_the_renderer_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_study(dir.path(), &MINIMAL.replace("render = \"survey-2\"", "render = \"nowhere\""));
    let error = load_study(&file).unwrap_err();
    assert_eq!(error.key, "scenes[1].render");
    assert!(error.expected.contains("survey-1"), "{error}");
}

#[test]
fn missing_image_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let body =
        MINIMAL.replace("render = \"survey-1\"", "images = { LQ = \"lq.png\", GI = \"gi.png\", HQ = \"hq.png\" }");
    let error = load_study(&write_study(dir.path(), &body)).unwrap_err();
    assert_eq!(error.key, "scenes[0].images.LQ");
}
