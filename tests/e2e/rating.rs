//! A rating study (`kind = "rating"`, ITU-T P.910's ACR, issue 49) end to end in headless
//! Chromium against a real `mrstudy serve` and its sqlite database: the demo study's images
//! rated on the 5-point quality scale, with a catch trial (an obviously broken image, expected
//! "Bad"). A double click, a held number key and a reload mid-study each leave exactly the
//! ratings the participant gave; `mrstudy export` writes the rating columns, the catch row
//! flagged. Screenshots at 1280×800 and on an emulated 390×844 phone go to
//! `$CARGO_TARGET_TMPDIR` (`rating-desktop.png`, `rating-phone.png`).

use std::path::Path;
use std::time::Duration;

use super::browser::{
    Driver, answer_trials, browser_available, consent_and_demographics, consent_without_demographics, screenshot_path,
};
use super::rating_study::AcrStudy;
use super::support::{Server, column, copy_demo_study, export, split_csv, start_rendered};
use super::survey_input::{double_click, hold_key, phone, query};

const SLUG: &str = "rating-browser";

/// The demo study's texts, demographics, conditions and image files as an ACR rating study.
fn write_study(dir: &Path) {
    copy_demo_study(dir);
    let demo = std::fs::read_to_string(dir.join("shadows-demo.toml")).unwrap();
    std::fs::remove_file(dir.join("shadows-demo.toml")).unwrap();
    let study = AcrStudy {
        slug: SLUG,
        title: "Image quality",
        question: "How good is the quality of this image?",
        seed: 5,
        completion_code: "RATE-1",
        ..AcrStudy::default()
    };
    let study = study.toml(&demo);
    std::fs::write(dir.join(format!("{SLUG}.toml")), study).unwrap();
}

fn answered(data_dir: &Path) -> usize {
    query(data_dir, "SELECT COUNT(*) FROM responses")[0][0].parse().unwrap()
}

fn shown(driver: &Driver) -> String {
    driver.script("return document.getElementById('rated-stimulus').src;").as_str().unwrap_or_default().to_string()
}

#[test]
fn ratings_survive_a_double_click_a_held_key_and_a_reload_and_export_with_their_columns() {
    if !browser_available() {
        return;
    }
    let (data_dir, studies) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    write_study(studies.path());
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    server.wait_open(SLUG, Duration::from_secs(60)).unwrap();
    let driver = Driver::start(1280, 800);
    driver.go(&format!("{}/studies/{SLUG}", server.base));
    driver.wait_visible("stage-welcome");
    consent_and_demographics(&driver, "female", "34");
    driver.wait_visible("stage-instructions");
    driver.click("#start");
    driver.wait_trial("1");
    assert_eq!(driver.text("#trial-progress"), "Trial 1 of 13");
    let labels = driver.script(
        "return [...document.querySelectorAll('#scale .rate')].map(b => b.textContent.replace(/\\s+/g, ' ').trim());",
    );
    assert_eq!(labels, serde_json::json!(["5Excellent", "4Good", "3Fair", "2Poor", "1Bad"]));
    let mut gave: Vec<u8> = Vec::new();

    // trial 1: a double click on "Good", 120 ms apart: one rating, to trial 1 only
    double_click(&driver, driver.centre("#rate-4"));
    gave.push(4);
    driver.wait_trial("2");
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(answered(data_dir.path()), 1, "the double click's second click rated trial 2");

    // trial 2: the key 3 held for a second and a half, with auto-repeat: one rating (the
    // repeats go on long after trial 3 takes answers)
    hold_key(&driver, "3", 51, Duration::from_millis(1500));
    gave.push(3);
    driver.wait_trial("3");
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(answered(data_dir.path()), 2, "auto-repeat rated more trials");

    // trial 3 by a click; a reload at trial 4 shows the same image again and rates nothing
    driver.click("#rate-5");
    gave.push(5);
    driver.wait_trial("4");
    let before = shown(&driver);
    driver.refresh();
    driver.wait_trial("4");
    assert_eq!(shown(&driver), before, "the reload showed another image as trial 4");
    assert_eq!(answered(data_dir.path()), 3, "the reload rated a trial");
    driver.screenshot(&screenshot_path("rating-desktop.png"));

    // the rest by clicks and keys, every rating once
    answer_trials(&driver, 4..=13, 13, |trial| {
        let rating = trial % 5 + 1;
        if trial % 2 == 0 {
            driver.click(&format!("#rate-{rating}"));
        } else {
            driver.type_into("body", &rating.to_string());
        }
        gave.push(rating);
    });
    driver.wait_visible("stage-done");
    assert_eq!(driver.text("#completion-code"), "RATE-1");

    // every stored answer is one the participant gave, in order, and nothing else
    let stored = query(data_dir.path(), "SELECT trial, rating, COALESCE(chosen, '') FROM responses ORDER BY trial");
    let expected: Vec<Vec<String>> = gave
        .iter()
        .enumerate()
        .map(|(i, rating)| vec![(i + 1).to_string(), rating.to_string(), String::new()])
        .collect();
    assert_eq!(stored, expected, "stored ratings against what the participant did");

    // the export: one row per rating, the catch trial's flagged with its expected rating
    let csv = export(data_dir.path(), SLUG, "csv");
    assert!(!csv.contains('"'), "{csv}");
    let (header, rows) = split_csv(&csv);
    let column = |name: &str| column(&header, name);
    let tail = &header[column("scene")..column("expected") + 1];
    assert_eq!(tail, ["scene", "condition", "rating", "method", "reference", "scale", "catch", "expected"]);
    assert_eq!(rows.len(), 13, "{csv}");
    let mut catch_rows = 0;
    for (row, rating) in rows.iter().zip(&gave) {
        assert_eq!(row[column("rating")], rating.to_string(), "{csv}");
        assert_eq!((row[column("method")], row[column("reference")], row[column("scale")]), ("acr", "", "quality"));
        if row[column("catch")] == "true" {
            catch_rows += 1;
            assert_eq!((row[column("condition")], row[column("expected")]), ("catch:broken", "1"), "{csv}");
        } else {
            assert_eq!(row[column("catch")], "false");
            assert!(["LQ", "SH", "CA", "SH+CA"].contains(&row[column("condition")]), "{csv}");
            assert!(["view-left", "view-centre", "view-right"].contains(&row[column("scene")]), "{csv}");
        }
    }
    assert_eq!(catch_rows, 1, "{csv}");

    // on a phone: the scale is a column of buttons under the image; a tap rates
    let phone = phone();
    phone.go(&format!("{}/studies/{SLUG}", server.base));
    phone.wait_visible("stage-welcome");
    consent_and_demographics(&phone, "male", "41");
    phone.wait_visible("stage-instructions");
    phone.click("#start");
    phone.wait_trial("1");
    assert_eq!(phone.text("#choice-hint"), "Tap a rating.");
    let (_, bad_y) = phone.centre("#rate-1");
    let fits = phone.script("return window.innerHeight;").as_f64().unwrap();
    assert!(bad_y < fits, "the scale's last button is below the screen ({bad_y} > {fits})");
    phone.screenshot(&screenshot_path("rating-phone.png"));
    phone.click("#rate-2");
    phone.wait_trial("2");
    assert_eq!(answered(data_dir.path()), 14);
}

/// A DCR study of two conditions on a rendered scene configuration, shown in sequence with
/// P.910's grey and the vote after the stimulus; its catch trial is the ground truth after itself.
fn write_dcr_study(dir: &Path, presentation: &str) {
    let texts = super::support::demo_texts();
    let study = format!(
        r#"slug = "dcr-browser"
title = "Impairments"
kind = "rating"
question = "How much is the second image impaired, compared with the first?"

{texts}
[[factors]]
name = "gi"

[[conditions]]
name = "LQ"
levels = {{ gi = 0 }}

[[conditions]]
name = "GI"
levels = {{ gi = 1 }}

[render]
size = [96, 72]
spp = 1
vpls = 16

[[scenes]]
name = "box"
render = "dir-lamp-box"

[rating]
method = "dcr"
{presentation}

[[rating.catch]]
name = "same"
scene = "box"
expected = 5

[completion]
code = "DCR-1"
"#
    );
    std::fs::write(dir.join("dcr-browser.toml"), study).unwrap();
}

/// Sequential DCR with `vote_after`: the reference, grey, the stimulus, grey, and only then the
/// scale takes a rating (a key pressed while the images are shown is no answer); the export has
/// the impairment scale and the ground truth as reference. Rendered on the software adapter
/// (skipped without one). Screenshots: `rating-dcr-reference.png`, `rating-dcr-vote.png`.
#[test]
fn sequential_dcr_shows_reference_grey_stimulus_grey_and_takes_the_vote_only_after() {
    if !browser_available() {
        return;
    }
    let (data_dir, studies) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    write_dcr_study(studies.path(), "stimulus_ms = 700\ngrey_ms = 500\nvote_after = true");
    let Some(server) = start_rendered(data_dir.path(), studies.path(), "dcr-browser") else { return };
    let driver = Driver::start(1280, 800);
    driver.go(&format!("{}/studies/dcr-browser", server.base));
    driver.wait_visible("stage-welcome");
    consent_without_demographics(&driver);
    // every phase the page shows, in order, with the trial on screen
    driver.script(
        "window.phases = []; new MutationObserver(() => window.phases.push(document.body.dataset.phase)).observe(document.body, {attributes: true, attributeFilter: ['data-phase']}); return null;",
    );
    driver.click("#start");
    driver.wait_for("document.body.dataset.phase === 'reference'");
    driver.screenshot(&screenshot_path("rating-dcr-reference.png"));
    driver.type_into("body", "2"); // while the reference is shown: no answer
    driver.wait_for("document.body.dataset.phase === 'stimulus'");
    driver.type_into("body", "2"); // while the stimulus is shown (vote_after): no answer
    driver.wait_trial("1");
    assert_eq!(answered(data_dir.path()), 0, "a key pressed before the vote answered");
    assert_eq!(
        driver.script("return window.phases;"),
        serde_json::json!(["reference", "grey", "stimulus", "grey"]),
        "P.910's sequence"
    );
    let labels = driver.script("return [...document.querySelectorAll('#scale .rate-label')].map(b => b.textContent);");
    assert_eq!(
        labels,
        serde_json::json!([
            "Imperceptible",
            "Perceptible but not annoying",
            "Slightly annoying",
            "Annoying",
            "Very annoying"
        ])
    );
    driver.screenshot(&screenshot_path("rating-dcr-vote.png"));
    let mut gave = Vec::new();
    answer_trials(&driver, 1..=3, 3, |trial| {
        let rating = 6 - trial;
        driver.click(&format!("#rate-{rating}"));
        gave.push(rating);
    });
    driver.wait_visible("stage-done");
    let stored = query(data_dir.path(), "SELECT rating FROM responses ORDER BY trial");
    assert_eq!(stored, gave.iter().map(|rating| vec![rating.to_string()]).collect::<Vec<_>>());

    let csv = export(data_dir.path(), "dcr-browser", "csv");
    let (header, rows) = split_csv(&csv);
    let column = |name: &str| column(&header, name);
    assert_eq!(rows.len(), 3, "{csv}");
    for row in &rows {
        assert_eq!(
            (row[column("method")], row[column("reference")], row[column("scale")]),
            ("dcr", "ground-truth", "impairment")
        );
        assert_eq!(row[column("scene")], "box", "{csv}");
        if row[column("catch")] == "true" {
            assert_eq!((row[column("condition")], row[column("expected")]), ("catch:same", "5"), "{csv}");
        } else {
            assert!(["LQ", "GI"].contains(&row[column("condition")]), "{csv}");
            assert_eq!(row[column("right")], "ground-truth", "{csv}");
        }
    }
}

/// DCR side by side on a phone: the reference (left) and the stimulus (right) at one size, both
/// on screen with the scale under them, and a tap rates. Screenshot: `rating-dcr-side-by-side-phone.png`.
#[test]
fn side_by_side_dcr_shows_both_images_at_one_size_on_a_phone() {
    if !browser_available() {
        return;
    }
    let (data_dir, studies) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    write_dcr_study(studies.path(), "layout = \"side-by-side\"");
    let Some(server) = start_rendered(data_dir.path(), studies.path(), "dcr-browser") else { return };
    let phone = phone();
    phone.go(&format!("{}/studies/dcr-browser", server.base));
    phone.wait_visible("stage-welcome");
    consent_without_demographics(&phone);
    phone.click("#start");
    phone.wait_trial("1");
    assert_eq!(phone.script("return document.body.dataset.phase;"), "both");
    let sizes = phone.script(
        "return ['rated-reference', 'rated-stimulus'].map(id => { const r = document.getElementById(id).getBoundingClientRect(); return [Math.round(r.width), Math.round(r.height), r.left < window.innerWidth / 2]; });",
    );
    let sizes = sizes.as_array().unwrap();
    assert_eq!(sizes[0][0], sizes[1][0], "one width: {sizes:?}");
    assert!(sizes[0][0].as_f64().unwrap() > 0.0, "{sizes:?}");
    assert_eq!((sizes[0][2].as_bool(), sizes[1][2].as_bool()), (Some(true), Some(false)), "reference left: {sizes:?}");
    let (_, bottom) = phone.centre("#rate-1");
    assert!(bottom < phone.script("return window.innerHeight;").as_f64().unwrap(), "the scale is below the screen");
    phone.screenshot(&screenshot_path("rating-dcr-side-by-side-phone.png"));
    phone.click("#rate-3");
    phone.wait_trial("2");
    assert_eq!(
        query(data_dir.path(), "SELECT trial, rating FROM responses"),
        vec![vec!["1".to_string(), "3".to_string()]]
    );
}
