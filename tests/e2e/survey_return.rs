//! Coming back to a study (issue 45) in headless Chromium against a real `mrstudy serve`: a
//! preview link opened again in the same browser starts a fresh pilot (not the last pilot's
//! "Thank you" page), and a participant who finished and comes back with the same external id
//! (`unique_external_id`), in another browser, sees the completion page, not the demographics.

use std::time::Duration;

use serde_json::{Value, json};

use super::browser::{Driver, browser_available, consent_and_demographics, screenshot_path};
use super::support::{Server, client, copy_demo_study, demographics};

/// Which stage is on screen: the id of the one visible `main > section`, without "stage-".
fn stage(driver: &Driver) -> String {
    let shown = driver.script(
        "const s = [...document.querySelectorAll('main > section')].find((s) => !s.hidden);
         return s ? s.id.replace('stage-', '') : '';",
    );
    shown.as_str().unwrap_or_default().to_string()
}

/// Waits until a stage other than "loading" is on screen, and names it.
fn settled_stage(driver: &Driver) -> String {
    driver.wait_for(
        "[...document.querySelectorAll('main > section')].some((s) => !s.hidden && s.id !== 'stage-loading')",
    );
    // a stage that shows at once (the instructions of a kept session) may still be replaced
    std::thread::sleep(Duration::from_millis(500));
    stage(driver)
}

fn participants(server: &Server) -> Vec<Value> {
    client()
        .get(format!("{}/api/admin/studies/shadows-demo/participants", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json::<Vec<Value>>()
        .unwrap()
}

fn preview_link(server: &Server) -> String {
    let answer: Value = client()
        .post(format!("{}/api/admin/studies/shadows-demo/preview", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    format!("{}{}", server.base, answer["url"].as_str().unwrap())
}

/// Every trial answered with the left image, up to the completion page.
fn answer_all(driver: &Driver) {
    driver.click("#start");
    for trial in 1..=7 {
        driver.wait_trial(&trial.to_string());
        driver.click("#choose-left");
    }
    driver.wait_visible("stage-done");
}

#[test]
fn a_preview_link_opened_again_in_the_same_browser_starts_a_fresh_pilot() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let link = preview_link(&server);
    let driver = Driver::start(1280, 800);
    driver.go(&link);
    assert_eq!(settled_stage(&driver), "welcome");
    consent_and_demographics(&driver, "female", "34");
    driver.wait_visible("stage-instructions");
    answer_all(&driver);

    // The same link again, in the same browser: a new pilot from the start.
    driver.go(&link);
    let again = settled_stage(&driver);
    driver.screenshot(&screenshot_path("preview-again-desktop.png"));
    assert_eq!(again, "welcome", "the second preview showed the stage \"{again}\" of the first pilot");
    consent_and_demographics(&driver, "male", "40");
    driver.wait_visible("stage-instructions");
    // A new preview link in the same browser: also a new pilot.
    driver.go(&preview_link(&server));
    assert_eq!(settled_stage(&driver), "welcome");
    consent_and_demographics(&driver, "male", "41");
    driver.wait_visible("stage-instructions");
    let pilots: Vec<Value> = participants(&server).into_iter().filter(|p| p["pilot"] == true).collect();
    assert_eq!(pilots.len(), 3, "three previews, three pilots: {pilots:?}");
    assert_eq!(pilots.iter().filter(|p| p["status"] == "completed").count(), 1, "{pilots:?}");

    // A reload in the middle of a preview still resumes it (the link's fragment keeps it).
    driver.click("#start");
    driver.wait_trial("1");
    driver.refresh();
    driver.wait_trial("1");
    assert_eq!(participants(&server).into_iter().filter(|p| p["pilot"] == true).count(), 3);
}

#[test]
fn a_participant_who_finished_and_returns_sees_the_completion_page_not_the_demographics() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    copy_demo_study(studies.path());
    let file = studies.path().join("shadows-demo.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.replacen("\n[texts]", "\nunique_external_id = true\n\n[texts]", 1)).unwrap();
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();

    // Finished in this browser; the same link again in it shows the completion page.
    let link = format!("{}/studies/shadows-demo?PROLIFIC_PID=RETURNING-1", server.base);
    let driver = Driver::start(1280, 800);
    driver.go(&link);
    assert_eq!(settled_stage(&driver), "welcome");
    consent_and_demographics(&driver, "female", "34");
    driver.wait_visible("stage-instructions");
    answer_all(&driver);
    driver.go(&link);
    assert_eq!(settled_stage(&driver), "done");
    assert_eq!(driver.text("#completion-code"), "DEMO-7F3A");

    // Finished through the API (another device); back with the same external id in a browser
    // that never saw the study: the completion page, nothing asked again.
    let http = client();
    let joined: Value = http
        .post(format!("{}/api/studies/shadows-demo/participants", server.base))
        .json(&json!({"demographics": demographics(), "url_params": {"PROLIFIC_PID": "RETURNING-2"}}))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    for trial in 1..=7 {
        http.get(format!("{}/api/participants/{id}/next", server.base)).bearer_auth(token).send().unwrap();
        let stored = http
            .post(format!("{}/api/participants/{id}/responses", server.base))
            .bearer_auth(token)
            .json(&json!({"trial": trial, "chosen": "left", "rt_ms": 900}))
            .send()
            .unwrap();
        assert_eq!(stored.status(), 201);
    }
    let other = Driver::start(1280, 800);
    other.go(&format!("{}/studies/shadows-demo?PROLIFIC_PID=RETURNING-2", server.base));
    let shown = settled_stage(&other);
    other.screenshot(&screenshot_path("returning-finisher-desktop.png"));
    assert_eq!(shown, "done", "the returning finisher was shown the stage \"{shown}\"");
    assert_eq!(other.text("#completion-code"), "DEMO-7F3A");
    // Someone else (another id) still starts from the welcome page.
    other.go(&format!("{}/studies/shadows-demo?PROLIFIC_PID=NEW-3", server.base));
    assert_eq!(settled_stage(&other), "welcome");
    assert_eq!(participants(&server).len(), 2, "nobody joined again");
}
