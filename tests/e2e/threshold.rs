//! A threshold study (`kind = "threshold"`, issue 48) end to end: `mrstudy serve` renders its
//! levels at start-up (the software adapter; skipped without one), a participant does it in
//! headless Chromium through the survey page — a reload mid-run continues at the same trial —
//! and `mrstudy export` writes the threshold columns.

use std::path::Path;

use serde_json::Value;

use super::browser::{Driver, answer_trials, browser_available, consent_without_demographics, screenshot_path};
use super::support::{client, column, demo_texts, export, repo_studies_dir, split_csv, start_rendered};
use super::threshold_study::ThresholdStudy;

const SLUG: &str = "vpls-browser";

fn write_study(dir: &Path) {
    let texts = demo_texts();
    let study = ThresholdStudy {
        slug: SLUG,
        texts: &texts,
        size: [64, 48],
        trials: 6,
        after: "[completion]\ncode = \"VPLS-1\"\n",
        ..ThresholdStudy::default()
    };
    study.write(dir, &format!("{SLUG}.toml"), &repo_studies_dir());
}

#[test]
fn a_participant_completes_a_threshold_study_in_chromium_and_a_reload_continues_it() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_study(studies.path());
    let Some(server) = start_rendered(data_dir.path(), studies.path(), SLUG) else { return };
    let driver = Driver::start(1280, 900);
    driver.go(&format!("{}/studies/{SLUG}", server.base));
    driver.wait_visible("stage-welcome");
    consent_without_demographics(&driver);
    driver.click("#start");

    driver.wait_trial("1");
    assert_eq!(driver.text("#trial-progress"), "Trial 1 of 7");
    driver.click("#choose-left");
    driver.wait_trial("2");
    driver.click("#choose-right");
    driver.wait_trial("3");
    let shown_before = driver.script("return document.getElementById('image-left').src;");
    // a reload mid-run continues at the same trial, with the same level
    driver.refresh();
    driver.wait_trial("3");
    assert_eq!(driver.text("#trial-progress"), "Trial 3 of 7");
    assert_eq!(driver.script("return document.getElementById('image-left').src;"), shown_before);
    driver.screenshot(&screenshot_path("browser-threshold-trial.png"));
    answer_trials(&driver, 3..=7, 7, |trial| {
        let key = if trial % 2 == 0 { "\u{E012}" } else { "\u{E014}" }; // ArrowLeft, ArrowRight
        driver.type_into("body", key);
    });
    driver.wait_visible("stage-done");
    assert_eq!(driver.text("#completion-code"), "VPLS-1");

    // the admin sees one participant who answered every trial
    let participants: Value = client()
        .get(format!("{}/api/admin/studies/{SLUG}/participants", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(participants.as_array().unwrap().len(), 1, "{participants}");
    // the export: one row per threshold trial (the catch trial is no row), the model on each
    let csv = export(data_dir.path(), SLUG, "csv");
    // no cell of this study holds a comma or a quote: the lines split plainly
    assert!(!csv.contains('"'), "{csv}");
    let (header, rows) = split_csv(&csv);
    let column = |name: &str| column(&header, name);
    assert_eq!(rows.len(), 6, "{csv}");
    for row in &rows {
        assert!(["1", "4", "16", "64"].contains(&row[column("level")]), "{csv}");
        assert!(["true", "false"].contains(&row[column("correct")]), "{csv}");
        assert!(["one", "two"].contains(&row[column("scene")]), "{csv}");
        let x: f64 = row[column("x")].parse().unwrap();
        let intensity: f64 = row[column("intensity")].parse().unwrap();
        assert!((x - intensity.log10()).abs() < 1e-12, "{csv}");
        assert_eq!((row[column("function")], row[column("scale")], row[column("guess")]), ("weibull", "log10", "0.5"));
        assert!(!row[column("participant")].is_empty());
    }
}
