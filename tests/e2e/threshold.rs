//! A threshold study (`kind = "threshold"`, issue 48) end to end: `mrstudy serve` renders its
//! levels at start-up (the software adapter; skipped without one), a participant does it in
//! headless Chromium through the survey page — a reload mid-run continues at the same trial —
//! and `mrstudy export` writes the threshold columns.

use std::path::Path;
use std::time::Duration;

use serde_json::Value;

use super::browser::{Driver, browser_available, screenshot_path};
use super::support::{Server, client, demo_texts, export, repo_studies_dir};

const SLUG: &str = "vpls-browser";

fn write_study(dir: &Path) {
    for name in ["catch-good.png", "catch-bad.png"] {
        std::fs::copy(repo_studies_dir().join("shadows-demo").join(name), dir.join(name)).unwrap();
    }
    let texts = demo_texts();
    let study = format!(
        r#"slug = "{SLUG}"
title = "How many VPLs?"
kind = "threshold"
question = "In which image was nothing added afterwards?"

{texts}
[render]
size = [64, 48]
spp = 1

[[scenes]]
name = "one"
render = "survey-1"

[[scenes]]
name = "two"
render = "survey-2"

[[catch]]
name = "obvious"
better = "catch-good.png"
worse = "catch-bad.png"

[threshold]
knob = "vpls"
levels = [1, 4, 16, 64]
intensity = "inverse-knob"
scale = "log10"
function = "weibull"
threshold = [-2.0, -1.5, -1.0, -0.5, 0.0]
slope = [2.0, 3.5]
lapse = [0.0, 0.02]
guess = 0.5
trials = 6

[completion]
code = "VPLS-1"
"#
    );
    std::fs::write(dir.join(format!("{SLUG}.toml")), study).unwrap();
}

#[test]
fn a_participant_completes_a_threshold_study_in_chromium_and_a_reload_continues_it() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_study(studies.path());
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    match server.wait_open(SLUG, Duration::from_secs(300)) {
        Err(warning) if warning.contains("adapter") => {
            eprintln!("skipping: no GPU adapter ({warning})");
            return;
        }
        result => result.unwrap(),
    }
    let driver = Driver::start(1280, 900);
    driver.go(&format!("{}/studies/{SLUG}", server.base));
    driver.wait_visible("stage-welcome");
    driver.click("#consent");
    driver.click("#consent-continue");
    driver.wait_visible("stage-demographics");
    driver.click("#demographics-continue");
    driver.wait_visible("stage-instructions");
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
    for trial in 3..=7 {
        driver.wait_trial(&trial.to_string());
        let key = if trial % 2 == 0 { "\u{E012}" } else { "\u{E014}" }; // ArrowLeft, ArrowRight
        driver.type_into("body", key);
        let next = if trial == 7 { "done".to_string() } else { (trial + 1).to_string() };
        driver.wait_trial(&next);
    }
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
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("{name}: {header:?}"));
    let rows: Vec<Vec<&str>> = lines.map(|line| line.split(',').collect()).collect();
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
