//! Tests of rating study files: the study they resolve into, the trials each participant gets,
//! and one sentence naming the file and the key for each kind of bad `[rating]` table.

use std::path::{Path, PathBuf};

use super::rating::{CatchSource, Layout, Method, RatingScale};
use super::*;

/// A rating study of the demo study's image files: `[rating]` and anything after it from `tail`.
pub(crate) fn image_study(dir: &Path, tail: &str) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies");
    let demo = std::fs::read_to_string(repo.join("shadows-demo.toml")).unwrap();
    let start = demo.find("[texts]").unwrap();
    let end = demo.find("[design]").unwrap();
    std::fs::create_dir_all(dir.join("shadows-demo")).unwrap();
    for entry in std::fs::read_dir(repo.join("shadows-demo")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, dir.join("shadows-demo").join(path.file_name().unwrap())).unwrap();
    }
    let text = format!(
        "slug = \"r\"\ntitle = \"R\"\nkind = \"rating\"\nquestion = \"How good is this image?\"\n{}\n{tail}\n",
        &demo[start..end]
    );
    let file = dir.join("r.toml");
    std::fs::write(&file, text).unwrap();
    file
}

/// A rating study of two rendered scene configurations and two conditions.
fn rendered_study(dir: &Path, rating: &str) -> PathBuf {
    let text = format!(
        r#"slug = "r"
title = "R"
kind = "rating"
question = "How good is this image?"
[texts]
welcome = "w"
consent = "c"
instructions = "i"
[[factors]]
name = "gi"
[[conditions]]
name = "LQ"
levels = {{ gi = 0 }}
[[conditions]]
name = "GI"
levels = {{ gi = 1 }}
[render]
size = [48, 36]
spp = 2
[[scenes]]
name = "a"
render = "survey-1"
[[scenes]]
name = "b"
render = "survey-2"
[rating]
{rating}
"#
    );
    let file = dir.join("r.toml");
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn an_acr_study_of_image_files_rates_every_stimulus_in_a_seeded_random_order() {
    let dir = tempfile::tempdir().unwrap();
    let file = image_study(
        dir.path(),
        "[rating]\nmethod = \"acr\"\nseed = 7\n[[rating.catch]]\nname = \"broken\"\nimage = \"shadows-demo/catch-bad.png\"\nexpected = 1\n",
    );
    let study = load_study(&file).unwrap();
    assert_eq!(study.kind, StudyKind::Rating);
    let design = study.rating.as_ref().unwrap();
    assert_eq!((design.method, design.method.scale()), (Method::Acr, RatingScale::Quality));
    assert_eq!(design.presentation.stimulus_ms, 0, "ACR shows the image until the vote by default");
    assert!(matches!(design.catch[0].source, CatchSource::Image { reference: None, .. }));
    // 3 scene configurations × 4 conditions, and the catch trial
    assert_eq!(study.trial_count(), 13);
    let plan = crate::rating::plan(&study, 11);
    assert_eq!(plan.len(), 13);
    assert_eq!(plan, crate::rating::plan(&study, 11), "the plan is the seed's");
    assert_ne!(plan, crate::rating::plan(&study, 12), "another seed, another order");
    let mut sorted = plan.clone();
    sorted.sort_by_key(|trial| format!("{trial:?}"));
    sorted.dedup();
    assert_eq!(sorted.len(), 13, "every stimulus once: {plan:?}");
    // the stored definition reads back with its rating design
    let stored: Study = serde_json::from_str(&serde_json::to_string(&study).unwrap()).unwrap();
    assert_eq!(stored.rating, study.rating);
}

#[test]
fn acr_hr_rates_each_ground_truth_once_more_and_dcr_shows_it_first() {
    let dir = tempfile::tempdir().unwrap();
    let study = load_study(&rendered_study(dir.path(), "method = \"acr-hr\"\nrepetitions = 2")).unwrap();
    assert_eq!(study.trial_count(), 2 * 2 * (2 + 1));
    let plan = crate::rating::plan(&study, 3);
    let hidden = plan.iter().filter(|trial| matches!(trial, crate::rating::RatedTrial::HiddenReference { .. })).count();
    assert_eq!(hidden, 4);
    assert!(plan.windows(2).all(|pair| pair[0] != pair[1]), "a stimulus twice in a row: {plan:?}");
    assert_eq!(study.design.reference, Some(DesignReference::GroundTruth), "the ground truths are rendered");

    let study = load_study(&rendered_study(
        dir.path(),
        "method = \"dcr\"\ngrey_ms = 1000\nvote_after = true\n[[rating.catch]]\nname = \"same\"\nscene = \"b\"\nexpected = 5",
    ))
    .unwrap();
    let design = study.rating.unwrap();
    assert_eq!(design.method.scale(), RatingScale::Impairment);
    assert_eq!(design.method.scale().labels()[0], "Imperceptible");
    assert_eq!(
        (design.presentation.stimulus_ms, design.presentation.grey_ms, design.presentation.layout),
        (5000, 1000, Layout::Sequential)
    );
    assert!(design.presentation.vote_after);
    assert_eq!(design.catch[0].source, CatchSource::GroundTruth { scene: 1 });
}

/// What a rating study shares with a threshold study (`checks::check_export_fits`): a
/// demographic field named like a column of the rating export is refused, naming them.
#[test]
fn a_demographic_field_named_like_a_column_of_the_rating_export_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = image_study(dir.path(), "[rating]\nmethod = \"acr\"\n");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.replacen("name = \"gender\"", "name = \"rating\"", 1)).unwrap();
    let error = load_study(&file).unwrap_err();
    assert_eq!(error.key, "demographics", "{error}");
    assert!(error.expected.contains("a column of the rating export (") && error.expected.ends_with("found \"rating\""));
}

#[test]
fn each_bad_rating_key_is_one_sentence_naming_the_file_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str, &str)] = &[
        ("method = \"mos\"", "rating.method", "\"acr\", \"dcr\" or \"acr-hr\""),
        ("method = \"acr\"\nrepetitions = 0", "rating.repetitions", "1 to 20"),
        ("method = \"acr\"\nstimulus_ms = 100", "rating.stimulus_ms", "500 to 60000"),
        ("method = \"acr\"\ngrey_ms = 500", "rating.grey_ms", "only with method = \"dcr\""),
        ("method = \"acr\"\nvote_after = true", "rating.vote_after", "stimulus_ms"),
        ("method = \"acr\"\nlayout = \"side-by-side\"", "rating.layout", "only with method = \"dcr\""),
        ("method = \"dcr\"\nstimulus_ms = 0", "rating.stimulus_ms", "the reference must give way"),
        ("method = \"dcr\"\ngrey_ms = 20000", "rating.grey_ms", "0 to 10000"),
        ("method = \"dcr\"\nlayout = \"overlay\"", "rating.layout", "\"sequential\" or \"side-by-side\""),
        ("method = \"acr\"\nspeed = 1", "rating", "unknown field `speed`"),
        (
            "method = \"acr\"\n[[rating.catch]]\nname = \"x\"\nscene = \"a\"\nexpected = 6",
            "rating.catch[0].expected",
            "from 1 to 5",
        ),
        (
            "method = \"acr\"\n[[rating.catch]]\nname = \"x\"\nscene = \"nowhere\"\nexpected = 5",
            "rating.catch[0].scene",
            "one of the scene configurations (a, b)",
        ),
        ("method = \"acr\"\n[[rating.catch]]\nname = \"x\"\nexpected = 5", "rating.catch[0]", "exactly one of"),
        (
            "method = \"dcr\"\n[[rating.catch]]\nname = \"x\"\nscene = \"a\"\nreference = \"r.png\"\nexpected = 5",
            "rating.catch[0].reference",
            "its own reference",
        ),
    ];
    for (rating, key, expected) in cases {
        let error = load_study(&rendered_study(dir.path(), rating)).unwrap_err();
        assert_eq!(error.key, *key, "{rating}: {error}");
        assert!(error.expected.contains(expected), "{rating}: {error}");
        let sentence = error.to_string();
        assert!(sentence.contains("r.toml") && !sentence.contains('\n'), "{sentence}");
    }
    // image files have no ground truth: DCR and ACR-HR need rendered scene configurations
    for method in ["dcr", "acr-hr"] {
        let error = load_study(&image_study(dir.path(), &format!("[rating]\nmethod = \"{method}\""))).unwrap_err();
        assert_eq!(error.key, "scenes[0]", "{error}");
        assert!(error.expected.contains("ground truth"), "{error}");
    }
    // a [design] or [[catch]] of a paired comparison is refused: [rating] makes them
    let file = image_study(
        dir.path(),
        "[rating]\nmethod = \"acr\"\n[design]\npairs = \"all\"\nrepetitions = 1\nscenes = \"same\"",
    );
    assert_eq!(load_study(&file).unwrap_err().key, "design");
    let file = image_study(
        dir.path(),
        "[rating]\nmethod = \"acr\"\n[[rating.catch]]\nname = \"x\"\nimage = \"shadows-demo/catch-bad.png\"\nreference = \"shadows-demo/catch-good.png\"\nexpected = 1",
    );
    assert_eq!(load_study(&file).unwrap_err().key, "rating.catch[0].reference");
}

#[test]
fn the_shipped_rating_example_renders_nothing_the_other_shipped_studies_do_not() {
    use crate::stimuli::StimulusPlan;
    let studies = Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies");
    let keys = |file: &str| -> std::collections::BTreeSet<String> {
        let study = load_study(&studies.join(file)).unwrap();
        let plan = StimulusPlan::of(&study).unwrap();
        let mut keys: std::collections::BTreeSet<String> =
            plan.stimuli().map(|stimulus| stimulus.key.clone()).collect();
        for planned in plan.scenes.iter().flatten() {
            keys.extend(planned.ground_truth_key.iter().cloned());
        }
        keys
    };
    let example = keys("rating-acr.toml");
    let study = load_study(&studies.join("rating-acr.toml")).unwrap();
    assert_eq!(study.trial_count(), 16);
    assert_eq!(example.len(), 3 * 4 + 3, "four conditions and the ground truth of three scene configurations");
    let mut others = keys("web-survey.toml");
    others.extend(keys("real-or-rendered.toml"));
    let missing: Vec<&String> = example.difference(&others).collect();
    assert!(missing.is_empty(), "the rating example renders stimuli of its own: {missing:?}");
    // and `serve` loads it beside the others (its catch image inside the folder)
    let loaded = load_studies(&studies).unwrap();
    assert!(loaded.iter().any(|study| study.slug() == "rating-acr"));
}

#[test]
fn a_catch_image_outside_the_studies_folder_is_refused() {
    let root = tempfile::tempdir().unwrap();
    let studies = root.path().join("studies");
    std::fs::create_dir_all(&studies).unwrap();
    let file = image_study(
        &studies,
        "[rating]\nmethod = \"acr\"\n[[rating.catch]]\nname = \"out\"\nimage = \"../outside.png\"\nexpected = 1\n",
    );
    std::fs::copy(studies.join("shadows-demo/catch-bad.png"), root.path().join("outside.png")).unwrap();
    assert!(load_study(&file).is_ok(), "the file alone is fine");
    let error = load_studies(&studies).unwrap_err();
    assert_eq!(error.key, "rating.catch[0].image", "{error}");
}
