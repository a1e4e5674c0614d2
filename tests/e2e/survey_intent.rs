//! One answer per intention (issue 45): slow double clicks and double taps, with the browser's
//! click count joined (2) and not joined (1, as a browser that does not join them reports), and
//! a triple click or tap on "Start", through the real page in headless Chromium against a real
//! `mrstudy serve` and its sqlite database. The presses are trusted input events sent through
//! the DevTools protocol with their own timestamps, so the gap the page sees is the gap the test
//! means however late an event is delivered; after each intended answer the test waits, then
//! compares what the server stored with what the participant meant.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use serde_json::json;

use super::browser::{Driver, browser_available, screenshot_path};
use super::support::Server;
use super::survey_input::{enter, phone, query};

/// How the presses are made.
#[derive(Clone, Copy, Debug)]
enum Pointer {
    Mouse,
    Touch,
}

/// Seconds since the Unix epoch, the clock of the DevTools protocol's `timestamp`.
fn epoch_now() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_secs_f64()
}

fn sleep_until_epoch(at: f64) {
    let left = at - epoch_now();
    if left > 0.0 {
        std::thread::sleep(Duration::from_secs_f64(left));
    }
}

/// Presses at `at`, the k-th `offsets_ms[k]` after the first, each held 20 ms. `joined`: the
/// browser counts them as one multi-click (click counts 1, 2, 3…; a touch screen's own tap
/// count); otherwise every press is a click of its own (click count 1).
fn presses(driver: &Driver, pointer: Pointer, (x, y): (f64, f64), offsets_ms: &[u64], joined: bool) {
    let start = epoch_now() + 0.05;
    for (index, offset) in offsets_ms.iter().enumerate() {
        let down = start + *offset as f64 / 1000.0;
        let up = down + 0.02;
        let count = if joined { index + 1 } else { 1 };
        for (kind, at) in [("down", down), ("up", up)] {
            sleep_until_epoch(at);
            match (pointer, joined) {
                (Pointer::Mouse, _) => {
                    let kind = if kind == "down" { "mousePressed" } else { "mouseReleased" };
                    driver.cdp(
                        "Input.dispatchMouseEvent",
                        json!({"type": kind, "x": x, "y": y, "button": "left", "buttons": (kind == "mousePressed") as u8,
                               "clickCount": count, "timestamp": at}),
                    );
                }
                // Real touches: the browser counts the taps itself (a second tap within its
                // double-tap time is a click with detail 2).
                (Pointer::Touch, true) => {
                    let (kind, points) = if kind == "down" {
                        ("touchStart", json!([{"x": x, "y": y}]))
                    } else {
                        ("touchEnd", json!([]))
                    };
                    driver
                        .cdp("Input.dispatchTouchEvent", json!({"type": kind, "touchPoints": points, "timestamp": at}));
                }
                // Touches made from mouse events with click count 1: taps a browser did not join.
                (Pointer::Touch, false) => {
                    let kind = if kind == "down" { "mousePressed" } else { "mouseReleased" };
                    // (this command takes whole pixels)
                    let (x, y) = (x.round() as i64, y.round() as i64);
                    driver.cdp(
                        "Input.emulateTouchFromMouseEvent",
                        json!({"type": kind, "x": x, "y": y, "button": "left", "clickCount": 1, "timestamp": at}),
                    );
                }
            }
        }
    }
}

/// The trial on screen (`body[data-trial]`: a number, "done", or absent).
fn shown_trial(driver: &Driver) -> String {
    driver.script("return document.body.dataset.trial || '';").as_str().unwrap_or_default().to_string()
}

/// Waits until the page shows something other than `before`, then lets any second answer
/// arrive (the last press is at most 480 ms after the first, a response takes milliseconds).
fn settle(driver: &Driver, before: &str) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while shown_trial(driver) == before {
        assert!(Instant::now() < deadline, "trial {before} was never answered");
        std::thread::sleep(Duration::from_millis(30));
    }
    std::thread::sleep(Duration::from_millis(1200));
}

/// The stored answers as (trial, side).
fn stored(data_dir: &std::path::Path) -> Vec<(String, String)> {
    query(data_dir, "SELECT trial, chosen FROM responses ORDER BY trial")
        .into_iter()
        .map(|row| (row[0].clone(), row[1].clone()))
        .collect()
}

/// A triple press on "Start" (240 ms apart: the third 480 ms after the first, where the pair
/// appears), then double presses on the images at gaps of 120, 250, 400 and 480 ms, one per
/// trial: the server must store exactly one answer per intended trial, the side pressed.
fn one_answer_per_intention(pointer: Pointer, joined: bool) {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let (driver, device) = match pointer {
        Pointer::Mouse => (Driver::start(1280, 800), "desktop"),
        Pointer::Touch => (phone(), "phone"),
    };
    enter(&driver, &server.base, "");
    let label = format!("{pointer:?} presses, click count {}", if joined { "joined" } else { "always 1" });

    // "Start": the first press starts; the two after it land where the pair appears.
    let start = driver.centre("#start");
    presses(&driver, pointer, start, &[0, 240, 480], joined);
    driver.wait_for("document.body.dataset.trial === '1'");
    std::thread::sleep(Duration::from_millis(1200));
    let on_image = driver.script(&format!(
        "const e = document.elementFromPoint({}, {}); return !!e && !!e.closest('.choice');",
        start.0, start.1
    ));
    assert_eq!(on_image, json!(true), "{label}: the presses on Start must land on an image of trial 1");
    let after_start = stored(data_dir.path());
    if joined {
        driver.screenshot(&screenshot_path(&format!("intent-trial-{device}.png")));
    }

    let mut given: Vec<(String, String)> = Vec::new();
    for (index, gap) in [120u64, 250, 400, 480].into_iter().enumerate() {
        let trial = shown_trial(&driver);
        if trial == "done" {
            break;
        }
        // Past the answer lock and `min_response_ms`, so the first press counts.
        std::thread::sleep(Duration::from_millis(700));
        let side = if index % 2 == 0 { "left" } else { "right" };
        let at = driver.centre(&format!("#image-{side}"));
        presses(&driver, pointer, at, &[0, gap], joined);
        given.push((trial.clone(), side.to_string()));
        settle(&driver, &trial);
    }
    let stored = stored(data_dir.path());
    eprintln!("{label}: given {given:?}; stored {stored:?} (after the triple press on Start: {after_start:?})");
    assert!(after_start.is_empty(), "{label}: the triple press on Start answered {after_start:?}");
    assert_eq!(stored, given, "{label}: stored answers against the ones given");
}

#[test]
fn slow_double_clicks_with_joined_click_counts_answer_one_trial_each() {
    one_answer_per_intention(Pointer::Mouse, true);
}

#[test]
fn slow_double_clicks_a_browser_does_not_join_answer_one_trial_each() {
    one_answer_per_intention(Pointer::Mouse, false);
}

#[test]
fn slow_double_taps_answer_one_trial_each() {
    one_answer_per_intention(Pointer::Touch, true);
}

#[test]
fn slow_double_taps_a_browser_does_not_join_answer_one_trial_each() {
    one_answer_per_intention(Pointer::Touch, false);
}
