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

fn active(design: &str) -> Result<Study, StudyError> {
    let dir = tempfile::tempdir().unwrap();
    let body = MINIMAL.replace(
        "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\nscenes = \"different\"\n",
        &format!("[design]\n{design}\nscenes = \"different\"\n"),
    );
    load_study(&write_study(dir.path(), &body))
}

#[test]
fn an_active_design_counts_its_warm_up_and_chosen_trials_and_names_each_bad_key() {
    let study = active("pairs = \"active\"\ntrials = 12\ntarget = \"worths\"").unwrap();
    let design = study.design.active.as_ref().unwrap();
    assert_eq!((design.trials, design.batch, design.target), (12, 5, ActiveTarget::Worths));
    assert!(study.design.pairs.is_empty());
    assert_eq!(study.trial_count(), 12);
    let study =
        active("pairs = \"active\"\ntrials = 6\nwarmup = \"anchored\"\nanchors = [\"LQ\"]\nrepetitions = 2").unwrap();
    assert_eq!(study.design.pairs, vec![(0, 1), (0, 2)]);
    assert_eq!(study.trial_count(), 2 * 2 + 6);
    for (design, key, says) in [
        ("pairs = \"active\"", "design.trials", "actively chosen trials"),
        ("pairs = \"active\"\ntrials = 0", "design.trials", "1 to 1000"),
        ("pairs = \"active\"\ntrials = 5\nbatch = 0", "design.batch", "1 to 100"),
        ("pairs = \"active\"\ntrials = 5\ntarget = \"ranks\"", "design.target", "\"ranks\""),
        ("pairs = \"active\"\ntrials = 5\nwarmup = \"some\"", "design.warmup", "\"some\""),
        ("pairs = \"active\"\ntrials = 5\nprior_sd = 0", "design.prior_sd", "0.05 to 10"),
        ("pairs = \"all\"\nrepetitions = 1\ntrials = 5", "design.trials", "only with pairs = \"active\""),
        ("pairs = \"all\"", "design.repetitions", "number of times"),
        ("pairs = \"sometimes\"\nrepetitions = 1", "design.pairs", "\"active\""),
    ] {
        let error = active(design).unwrap_err();
        assert_eq!(error.key, key, "{design}: {error}");
        assert!(error.expected.contains(says), "{design}: {error}");
    }
}

#[test]
fn an_active_design_the_posterior_cannot_learn_is_refused_naming_the_target() {
    // two conditions only
    let dir = tempfile::tempdir().unwrap();
    let body = MINIMAL.replace("[[conditions]]\nname = \"HQ\"\nlevels = { gi = 1, ca = 1 }\n", "").replace(
        "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\n",
        "[design]\npairs = \"active\"\ntrials = 4\n",
    );
    let error = load_study(&write_study(dir.path(), &body)).unwrap_err();
    assert_eq!(error.key, "design.target", "{error}");
    // factor effects when one factor never varies over the conditions (ca is 0 in all but HQ:
    // drop HQ's ca so it is constant)
    let body = MINIMAL.replace("levels = { gi = 1, ca = 1 }", "levels = { gi = 1, ca = 0 }").replace(
        "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\n",
        "[design]\npairs = \"active\"\ntrials = 4\ntarget = \"factors\"\nwarmup = \"all\"\n",
    );
    let error = load_study(&write_study(dir.path(), &body)).unwrap_err();
    assert_eq!(error.key, "design.target", "{error}");
    // factor effects without a warm-up that connects the conditions
    for warmup in ["", "warmup = \"list\"\nlist = [[\"LQ\", \"GI\"]]\n"] {
        let body = MINIMAL.replace(
            "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\n",
            &format!("[design]\npairs = \"active\"\ntrials = 4\ntarget = \"factors\"\n{warmup}"),
        );
        let error = load_study(&write_study(dir.path(), &body)).unwrap_err();
        assert_eq!(error.key, "design.warmup", "{error}");
        assert!(error.expected.contains("connects every condition"), "{error}");
    }
}

#[test]
fn target_effects_is_the_factor_target_also_spelt_factors_and_the_default_is_worths() {
    let target = |key: &str| {
        active(&format!("pairs = \"active\"\ntrials = 4\n{key}warmup = \"all\"")).unwrap().design.active.unwrap().target
    };
    assert_eq!(target("target = \"effects\"\n"), ActiveTarget::Factors);
    assert_eq!(target("target = \"factors\"\n"), ActiveTarget::Factors);
    assert_eq!(target("target = \"worths\"\n"), ActiveTarget::Worths);
    assert_eq!(target("target = \"both\"\n"), ActiveTarget::Both);
    let error = active("pairs = \"active\"\ntrials = 4\ntarget = \"all\"").unwrap_err();
    assert_eq!(error.key, "design.target", "{error}");
    assert!(
        error.expected.contains("\"worths\", \"effects\" (also spelt \"factors\") or \"both\", found \"all\""),
        "{error}"
    );
}

/// `prior = "spread"` (issue 48): the hierarchical prior on the log-worths' spread, with
/// `target = "worths"` only; `"fixed"` is the default; anything else, or the spread prior with
/// another target (given or by default), is refused naming the file and `design.prior`.
#[test]
fn prior_spread_is_taken_with_target_worths_only() {
    let prior = |design: &str| active(design).unwrap().design.active.unwrap().prior;
    assert_eq!(prior("pairs = \"active\"\ntrials = 4\ntarget = \"worths\"\nprior = \"spread\""), ActivePrior::Spread);
    assert_eq!(prior("pairs = \"active\"\ntrials = 4\ntarget = \"worths\"\nprior = \"fixed\""), ActivePrior::Fixed);
    assert_eq!(prior("pairs = \"active\"\ntrials = 4"), ActivePrior::Fixed);
    for (design, says) in [
        ("target = \"both\"\nprior = \"spread\"", "expected \"fixed\" with target = \"both\""),
        ("prior = \"spread\"", "expected \"fixed\" with target = \"both\""),
        ("target = \"effects\"\nwarmup = \"all\"\nprior = \"spread\"", "applies to target = \"worths\" only"),
        ("target = \"worths\"\nprior = \"hierarchical\"", "expected \"fixed\" or \"spread\", found \"hierarchical\""),
    ] {
        let error = active(&format!("pairs = \"active\"\ntrials = 4\n{design}")).unwrap_err();
        assert_eq!(error.key, "design.prior", "{design}: {error}");
        assert!(error.expected.contains(says), "{design}: {error}");
        assert!(error.to_string().contains("study.toml"), "{error}");
    }
    let error = active("pairs = \"all\"\nrepetitions = 1\nprior = \"spread\"").unwrap_err();
    assert_eq!(
        (error.key.as_str(), error.expected.as_str()),
        ("design.prior", "expected only with pairs = \"active\"")
    );
}

/// The default active design (issue 48, measured in docs/simulate/active-target/README.md):
/// target both, and a warm-up of the anchored pairs for about 60 % of the trials. Changing it
/// must change this test (and the measurement).
#[test]
fn the_default_active_design_is_both_after_an_anchored_warm_up() {
    // no anchors: the first and last condition (LQ, HQ); 1.5 × 12 / 3 pairs = 6 repetitions
    let study = active("pairs = \"active\"\ntrials = 12").unwrap();
    let design = study.design.active.as_ref().unwrap();
    assert_eq!((design.trials, design.target), (12, ActiveTarget::Both));
    assert_eq!((study.design.pairs.clone(), study.design.repetitions), (vec![(0, 2), (0, 1), (2, 1)], 6));
    assert_eq!(study.trial_count(), 6 * 3 + 12);
    // the study's anchors and repetitions when it gives them; `target = "both"` alike
    let study = active("pairs = \"active\"\ntrials = 2\ntarget = \"both\"\nanchors = [\"GI\"]").unwrap();
    assert_eq!((study.design.pairs.clone(), study.design.repetitions), (vec![(1, 0), (1, 2)], 2));
    let study = active("pairs = \"active\"\ntrials = 2\nrepetitions = 1").unwrap();
    assert_eq!((study.design.pairs.len(), study.design.repetitions), (3, 1));
    // an explicit warm-up, or an explicit worths or effects target, keeps its own (none by default)
    let study = active("pairs = \"active\"\ntrials = 2\nwarmup = \"none\"").unwrap();
    assert!(study.design.pairs.is_empty());
    assert_eq!(study.design.active.unwrap().target, ActiveTarget::Both);
    // where no factor the posterior can learn varies, the default target is the log-worths
    let dir = tempfile::tempdir().unwrap();
    let body = MINIMAL.replace("levels = { gi = 1, ca = 1 }", "levels = { gi = 1, ca = 0 }").replace(
        "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\n",
        "[design]\npairs = \"active\"\ntrials = 4\n",
    );
    let study = load_study(&write_study(dir.path(), &body)).unwrap();
    assert_eq!(study.design.active.unwrap().target, ActiveTarget::Worths);
    assert_eq!(study.design.pairs.len(), 3);
}

fn detection(design: &str) -> Result<Study, StudyError> {
    let dir = tempfile::tempdir().unwrap();
    let body = MINIMAL.replace(
        "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\nscenes = \"different\"\n",
        &format!("[design]\n{design}\n"),
    );
    load_study(&write_study(dir.path(), &body))
}

#[test]
fn a_detection_design_pairs_every_condition_with_the_ground_truth_and_names_each_bad_key() {
    let study = detection("reference = \"ground-truth\"\nrepetitions = 2\nscenes = \"same\"").unwrap();
    assert_eq!(study.design.reference, Some(DesignReference::GroundTruth));
    assert_eq!(study.design.pairs, vec![(0, 3), (1, 3), (2, 3)]);
    assert_eq!(study.trial_count(), 6);
    let refused = |design: &str, key: &str, words: &str| {
        let error = detection(design).unwrap_err();
        assert_eq!(error.key, key, "{error}");
        assert!(error.expected.contains(words), "{error}");
    };
    refused("reference = \"ground-truth\"\nrepetitions = 2\nscenes = \"different\"", "design.scenes", "\"same\"");
    refused("reference = \"photo\"\nrepetitions = 2\nscenes = \"same\"", "design.reference", "\"ground-truth\"");
    refused(
        "reference = \"ground-truth\"\npairs = \"all\"\nrepetitions = 2\nscenes = \"same\"",
        "design.pairs",
        "no pairing rule",
    );
    refused("reference = \"ground-truth\"\nscenes = \"same\"", "design.repetitions", "number of times");
    refused("repetitions = 2\nscenes = \"same\"", "design.pairs", "reference = \"ground-truth\"");
    // image files have no ground truth
    let dir = tempfile::tempdir().unwrap();
    for name in ["lq.png", "gi.png", "hq.png"] {
        std::fs::write(dir.path().join(name), b"not looked at before the design").unwrap();
    }
    let body = MINIMAL
        .replace("render = \"survey-1\"", "images = { LQ = \"lq.png\", GI = \"gi.png\", HQ = \"hq.png\" }")
        .replace(
            "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\nscenes = \"different\"\n",
            "[design]\nreference = \"ground-truth\"\nrepetitions = 1\nscenes = \"same\"\n",
        );
    if let Err(error) = load_study(&write_study(dir.path(), &body)) {
        assert!(error.key.starts_with("scenes[0]"), "{error}");
    } else {
        panic!("a detection design over image files was accepted");
    }
}

#[test]
fn a_detection_design_takes_realisations_and_a_reference_label_and_nothing_else_does() {
    let design = "reference = \"ground-truth\"\nrepetitions = 2\nscenes = \"same\"";
    let study = detection(design).unwrap();
    assert_eq!((study.design.realisations, study.design.reference_label.as_deref()), (1, None));
    let study = detection(&format!("{design}\nrealisations = 4\nreference_label = \"a path-traced render\"")).unwrap();
    assert_eq!((study.design.realisations, study.design.reference_label.as_deref()), (4, Some("a path-traced render")));
    for (extra, key, words) in [
        ("realisations = 0", "design.realisations", "1 to 16"),
        ("realisations = 17", "design.realisations", "1 to 16"),
        ("reference_label = \" \"", "design.reference_label", "non-empty"),
    ] {
        let error = detection(&format!("{design}\n{extra}")).unwrap_err();
        assert!(error.key == key && error.expected.contains(words), "{error}");
    }
    let error = detection("pairs = \"all\"\nrepetitions = 1\nscenes = \"different\"\nrealisations = 2").unwrap_err();
    assert!(error.key == "design.realisations" && error.expected.contains("detection design"), "{error}");
}

#[test]
fn no_condition_may_be_named_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_study(dir.path(), &MINIMAL.replace("name = \"GI\"", "name = \"ground-truth\""));
    let error = load_study(&file).unwrap_err();
    assert_eq!(error.key, "conditions[1].name");
    assert!(error.expected.contains("ground truth"), "{error}");
}

/// MINIMAL with the gi factor's levels named: off, dir, dit.
fn named_gi() -> String {
    MINIMAL
        .replace("levels = { gi = 0, ca = 0 }", "levels = { gi = \"dit\", ca = 0 }")
        .replace("levels = { gi = 1, ca = 0 }", "levels = { gi = \"off\", ca = 0 }")
        .replace("levels = { gi = 1, ca = 1 }", "levels = { gi = \"dir\", ca = 1 }")
}

#[test]
fn named_gi_levels_are_coded_against_off_and_resolve_to_their_methods() {
    let dir = tempfile::tempdir().unwrap();
    let study = load_study(&write_study(dir.path(), &named_gi())).unwrap();
    // off first (the reference), then the others in the order the conditions use them
    assert_eq!(study.factors[0].levels, ["off", "dit", "dir"]);
    assert_eq!(study.design_columns(), ["gi_dit", "gi_dir", "ca"]);
    assert_eq!(study.conditions[0].levels, [1.0, 0.0, 0.0]);
    assert_eq!(study.conditions[1].levels, [0.0, 0.0, 0.0]);
    assert_eq!(study.conditions[2].levels, [0.0, 1.0, 1.0]);
    assert_eq!(study.conditions_csv(), "condition,gi_dit,gi_dir,ca\nLQ,1,0,0\nGI,0,0,0\nHQ,0,1,1\n");
    let factors: Vec<mrstudy_renderer::stimulus::Factors> =
        study.conditions.iter().map(|c| c.factors.clone().unwrap()).collect();
    assert_eq!(factors[0].label(), "dit");
    assert_eq!(factors[1].label(), "none");
    assert_eq!(factors[2].label(), "gi+ca");
    // the analysis reads the same columns
    let table = crate::live_analysis::condition_table(&study);
    assert_eq!(table.factors, study.design_columns());
    // a file's own order chooses the reference level; a quality suffix becomes `_` in the column
    let ordered = named_gi()
        .replace("name = \"gi\"\n", "name = \"gi\"\nlevels = [\"dir\", \"off\", \"dit-high\"]\n")
        .replace("gi = \"dit\"", "gi = \"dit-high\"");
    let study = load_study(&write_study(dir.path(), &ordered)).unwrap();
    assert_eq!(study.design_columns(), ["gi_off", "gi_dit_high", "ca"]);
    assert_eq!(study.conditions[2].levels, [0.0, 0.0, 1.0]);
    assert_eq!(study.conditions[0].factors.as_ref().unwrap().label(), "dit-high");
}

#[test]
fn named_levels_are_refused_naming_the_key_when_mixed_unknown_or_unrenderable() {
    let dir = tempfile::tempdir().unwrap();
    let refused = |body: String| load_study(&write_study(dir.path(), &body)).unwrap_err();
    // numbers and names in one factor
    let error = refused(named_gi().replace("gi = \"off\"", "gi = 0"));
    assert_eq!(error.key, "conditions[1].levels.gi");
    assert!(error.expected.contains("all numbers or all names"), "{}", error.expected);
    // a name the renderer does not know
    let error = refused(named_gi().replace("gi = \"dit\"", "gi = \"pathtracing\""));
    assert_eq!(error.key, "conditions[0].levels");
    assert!(error.expected.contains("\"pathtracing\"") && error.expected.contains("\"vct\""), "{}", error.expected);
    // a name for a factor that takes numbers only
    let error = refused(named_gi().replace("gi = \"off\", ca = 0", "gi = \"off\", ca = \"on\""));
    assert_eq!(error.key, "conditions[1].levels.ca");
    // a name the file's list lacks, and a list for a numeric factor
    let listed = named_gi().replace("name = \"gi\"\n", "name = \"gi\"\nlevels = [\"off\", \"dir\"]\n");
    let error = refused(listed);
    assert_eq!(error.key, "conditions[0].levels.gi");
    assert!(error.expected.contains("off, dir"), "{}", error.expected);
    let error = refused(MINIMAL.replace("name = \"ca\"\n", "name = \"ca\"\nlevels = [\"off\"]\n"));
    assert_eq!(error.key, "factors[1].levels");
    // not a level name
    let error = refused(named_gi().replace("gi = \"dit\"", "gi = \"DIT!\""));
    assert_eq!(error.key, "conditions[0].levels.gi");
    // a column named twice: the factor gi_dit beside gi's level dit
    let clash = named_gi()
        .replace("[[factors]]\nname = \"ca\"", "[[factors]]\nname = \"gi_dit\"\n[[factors]]\nname = \"ca\"")
        .replace("ca = 0 }", "ca = 0, gi_dit = 0 }")
        .replace("ca = 1 }", "ca = 1, gi_dit = 0 }");
    let error = refused(clash);
    assert_eq!(error.key, "factors");
    assert!(error.expected.contains("gi_dit"), "{}", error.expected);
}

#[test]
fn answer_lock_ms_defaults_to_500_and_is_refused_outside_0_to_10000_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let study = load_study(&write_study(dir.path(), MINIMAL)).unwrap();
    assert_eq!(study.participation.answer_lock_ms, 500);
    let with = |line: &str| MINIMAL.replace("question = \"Q?\"", &format!("question = \"Q?\"\n{line}"));
    let study = load_study(&write_study(dir.path(), &with("answer_lock_ms = 800"))).unwrap();
    assert_eq!(study.participation.answer_lock_ms, 800);
    // the resolved study (the `definition` stored and the page's `data-answer-lock-ms`) carries it
    assert_eq!(serde_json::to_value(&study).unwrap()["participation"]["answer_lock_ms"], 800);
    for bad in ["answer_lock_ms = -1", "answer_lock_ms = 10001"] {
        let message = load_study(&write_study(dir.path(), &with(bad))).unwrap_err().to_string();
        assert!(message.contains("answer_lock_ms") && message.contains("0 to 10000"), "{message}");
    }
}

#[test]
fn allow_tie_is_off_by_default_and_refused_with_a_condition_named_tie_or_a_detection_design() {
    let dir = tempfile::tempdir().unwrap();
    let with = |body: &str, line: &str| body.replace("question = \"Q?\"", &format!("question = \"Q?\"\n{line}"));
    assert!(!load_study(&write_study(dir.path(), MINIMAL)).unwrap().participation.allow_tie);
    let study = load_study(&write_study(dir.path(), &with(MINIMAL, "allow_tie = true"))).unwrap();
    assert!(study.participation.allow_tie);
    assert_eq!(serde_json::to_value(&study).unwrap()["participation"]["allow_tie"], true);
    let named_tie = with(&MINIMAL.replace("name = \"GI\"", "name = \"tie\""), "allow_tie = true");
    let error = load_study(&write_study(dir.path(), &named_tie)).unwrap_err();
    assert_eq!(error.key, "conditions[1].name", "{error}");
    assert!(error.expected.contains("\"tie\""), "{error}");
    let detection = with(
        &MINIMAL.replace(
            "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 2\nscenes = \"different\"\n",
            "[design]\nreference = \"ground-truth\"\nrepetitions = 2\nscenes = \"same\"\n",
        ),
        "allow_tie = true",
    );
    let error = load_study(&write_study(dir.path(), &detection)).unwrap_err();
    assert_eq!(error.key, "allow_tie", "{error}");
    assert!(error.expected.contains("detection"), "{error}");
}
