//! Input hygiene of the survey page in headless Chromium against a real `mrstudy serve` and its
//! sqlite database: every stored answer must be one a participant gave on purpose. Trusted
//! input events come through the DevTools protocol (a double click with its click count, a key
//! held down with auto-repeat, touches on an emulated phone), then the test counts what the
//! server stored. Screenshots at 1280×800 and 390×844 go to `$CARGO_TARGET_TMPDIR`.

use std::path::Path;
use std::time::Duration;

use serde_json::{Value, json};

use super::browser::{Driver, browser_available, consent_and_demographics, screenshot_path};
use super::support::{Server, client, copy_demo_study};

/// The demo study with extra top-level keys, in its own studies folder.
fn demo_with(dir: &Path, extra: &str) {
    copy_demo_study(dir);
    let file = dir.join("shadows-demo.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.replacen("\n[texts]", &format!("\n{extra}\n\n[texts]"), 1)).unwrap();
}

/// Rows of a query on the server's database (read-only), as text.
pub(super) fn query(data_dir: &Path, sql: &str) -> Vec<Vec<String>> {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    runtime.block_on(async {
        use sqlx::Row;
        let url = format!("sqlite://{}?mode=ro", data_dir.join("mrstudy.db").display());
        let pool = sqlx::SqlitePool::connect(&url).await.unwrap();
        let rows = sqlx::query(sqlx::AssertSqlSafe(sql.to_string())).fetch_all(&pool).await.unwrap();
        rows.iter()
            .map(|row| {
                (0..row.len())
                    .map(|index| {
                        row.try_get::<Option<String>, _>(index)
                            .map(|value| value.unwrap_or_default())
                            .or_else(|_| row.try_get::<i64, _>(index).map(|value| value.to_string()))
                            .or_else(|_| row.try_get::<f64, _>(index).map(|value| value.to_string()))
                            .unwrap()
                    })
                    .collect()
            })
            .collect()
    })
}

fn answered(data_dir: &Path) -> i64 {
    query(data_dir, "SELECT COUNT(*) FROM responses")[0][0].parse().unwrap()
}

/// Consent and demographics, up to the instructions.
pub(super) fn enter(driver: &Driver, base: &str, query: &str) {
    driver.go(&format!("{base}/studies/shadows-demo{query}"));
    driver.wait_visible("stage-welcome");
    consent_and_demographics(driver, "female", "34");
    driver.wait_visible("stage-instructions");
}

fn mouse_click(driver: &Driver, (x, y): (f64, f64), count: u32) {
    for kind in ["mousePressed", "mouseReleased"] {
        driver.cdp(
            "Input.dispatchMouseEvent",
            json!({"type": kind, "x": x, "y": y, "button": "left", "clickCount": count}),
        );
    }
}

pub(super) fn key(driver: &Driver, kind: &str, name: &str, code: u32, repeat: bool) {
    driver.cdp(
        "Input.dispatchKeyEvent",
        json!({"type": kind, "key": name, "code": name, "windowsVirtualKeyCode": code, "nativeVirtualKeyCode": code, "autoRepeat": repeat}),
    );
}

/// A key held down for `held`: one press, then auto-repeat keydowns every 33 ms (as an OS
/// sends them), then the release.
pub(super) fn hold_key(driver: &Driver, name: &str, code: u32, held: Duration) {
    key(driver, "keyDown", name, code, false);
    let until = std::time::Instant::now() + held;
    while std::time::Instant::now() < until {
        std::thread::sleep(Duration::from_millis(33));
        key(driver, "keyDown", name, code, true);
    }
    key(driver, "keyUp", name, code, false);
}

/// A double click at `at`: a click, and 120 ms later the second click of a double click.
pub(super) fn double_click(driver: &Driver, at: (f64, f64)) {
    mouse_click(driver, at, 1);
    std::thread::sleep(Duration::from_millis(120));
    mouse_click(driver, at, 2);
}

/// Waits for the trial, then longer than `min_response_ms` (300 ms), so a fresh press counts.
fn ready(driver: &Driver, trial: &str) {
    driver.wait_trial(trial);
    std::thread::sleep(Duration::from_millis(100));
}

#[test]
fn a_double_click_answers_one_trial_and_a_double_click_on_start_answers_none() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(1280, 800);
    enter(&driver, &server.base, "");
    driver.screenshot(&screenshot_path("survey-instructions-desktop.png"));

    // A double click on "Start": the first starts, the second (120 ms later, where the left
    // image appears) must not answer trial 1.
    let start = driver.centre("#start");
    double_click(&driver, start);
    driver.wait_for("document.body.dataset.trial === '1'");
    std::thread::sleep(Duration::from_millis(1000));
    assert_eq!(answered(data_dir.path()), 0, "a double click on Start answered a trial");
    assert_eq!(driver.script("return document.body.dataset.trial;"), json!("1"));
    driver.screenshot(&screenshot_path("survey-trial-desktop.png"));

    // A double click on the left image, 120 ms apart: one answer, to trial 1 only.
    ready(&driver, "1");
    let left = driver.centre("#image-left");
    double_click(&driver, left);
    driver.wait_for("document.body.dataset.trial === '2'");
    std::thread::sleep(Duration::from_millis(1000));
    assert_eq!(answered(data_dir.path()), 1, "the second click answered the next trial");
    assert_eq!(driver.script("return document.body.dataset.trial;"), json!("2"));
    let stored = query(data_dir.path(), "SELECT trial, chosen, too_fast FROM responses");
    assert_eq!(stored, vec![vec!["1".to_string(), "left".to_string(), "0".to_string()]]);

    // A deliberate click after the minimum time answers trial 2.
    ready(&driver, "2");
    driver.click("#choose-right");
    driver.wait_trial("3");
    assert_eq!(answered(data_dir.path()), 2);
}

#[test]
fn a_held_arrow_key_answers_one_trial() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(1280, 800);
    enter(&driver, &server.base, "");
    driver.click("#start");
    ready(&driver, "1");
    // Held for one second, with auto-repeat.
    hold_key(&driver, "ArrowLeft", 37, Duration::from_secs(1));
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(answered(data_dir.path()), 1, "auto-repeat answered more trials");
    driver.wait_trial("2");
    // A fresh press answers the next one.
    std::thread::sleep(Duration::from_millis(400));
    key(&driver, "keyDown", "ArrowRight", 39, false);
    key(&driver, "keyUp", "ArrowRight", 39, false);
    driver.wait_trial("3");
    let stored = query(data_dir.path(), "SELECT trial, chosen FROM responses ORDER BY trial");
    assert_eq!(stored, vec![vec!["1".to_string(), "left".to_string()], vec!["2".to_string(), "right".to_string()]]);
}

#[test]
fn a_reload_on_the_instructions_shows_them_again_and_an_age_out_of_range_is_named() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(1280, 800);
    driver.go(&format!("{}/studies/shadows-demo", server.base));
    driver.wait_visible("stage-welcome");
    consent_and_demographics(&driver, "female", "12");
    driver.wait_for("!document.getElementById('demographics-error').hidden");
    let message = driver.text("#demographics-error");
    assert_eq!(message, "Age in years: please enter a whole number from 16 to 110.");
    driver.screenshot(&screenshot_path("survey-age-range-desktop.png"));
    driver.script("document.getElementById('field-age').value = '';");
    driver.type_into("#field-age", "34");
    driver.click("#demographics-continue");
    driver.wait_visible("stage-instructions");
    driver.refresh();
    driver.wait_visible("stage-instructions");
    assert_eq!(driver.script("return document.getElementById('stage-trial').hidden;"), json!(true));
    driver.click("#start");
    driver.wait_trial("1");
    // Once started, a reload resumes at the trial.
    driver.refresh();
    driver.wait_trial("1");
    assert_eq!(answered(data_dir.path()), 0);
}

const IPHONE: &str = "Mozilla/5.0 (iPhone; CPU iPhone OS 17_0 like Mac OS X) AppleWebKit/605.1.15 (KHTML, like Gecko) Version/17.0 Mobile/15E148 Safari/604.1";

pub(super) fn phone() -> Driver {
    Driver::start_with(
        390,
        844,
        json!({"mobileEmulation": {"deviceMetrics": {"width": 390, "height": 844, "pixelRatio": 3, "touch": true}, "userAgent": IPHONE}}),
    )
}

#[test]
fn a_phone_is_refused_when_the_study_wants_a_desktop_and_counted_as_screened_out() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    demo_with(studies.path(), "devices = [\"desktop\"]\nmin_viewport = [800, 500]");
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    let driver = phone();
    driver.go(&format!("{}/studies/shadows-demo?PROLIFIC_PID=phone-pid", server.base));
    driver.wait_visible("stage-screen");
    let reason = driver.text("#screen-reason");
    assert!(reason.contains("only be done on a desktop or laptop computer, not on a phone"), "{reason}");
    assert_eq!(driver.script("return document.getElementById('stage-welcome').hidden;"), json!(true));
    driver.screenshot(&screenshot_path("survey-screened-out-phone.png"));
    let screen_outs = query(data_dir.path(), "SELECT reason, url_params FROM screen_outs");
    assert_eq!(screen_outs.len(), 1, "{screen_outs:?}");
    assert!(screen_outs[0][1].contains("phone-pid"));
    // A reload is the same visitor: still one.
    driver.refresh();
    driver.wait_visible("stage-screen");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(query(data_dir.path(), "SELECT COUNT(*) FROM screen_outs")[0][0], "1");

    // A plain phone-sized window (no emulation) is refused the same way.
    let narrow = Driver::start(390, 844);
    narrow.go(&format!("{}/studies/shadows-demo", server.base));
    narrow.wait_visible("stage-screen");
    assert!(narrow.text("#screen-reason").contains("desktop or laptop computer"));
    assert_eq!(query(data_dir.path(), "SELECT COUNT(*) FROM screen_outs")[0][0], "2");

    // A desktop window of 1280×800 meets the requirements and shows the study.
    let desktop = Driver::start(1280, 800);
    desktop.go(&format!("{}/studies/shadows-demo", server.base));
    desktop.wait_visible("stage-welcome");
    desktop.screenshot(&screenshot_path("survey-welcome-desktop.png"));
    assert_eq!(query(data_dir.path(), "SELECT COUNT(*) FROM screen_outs")[0][0], "2");
}

#[test]
fn on_a_touch_screen_the_tapped_side_is_not_preselected_on_the_next_pair() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = phone();
    enter(&driver, &server.base, "");
    driver.screenshot(&screenshot_path("survey-instructions-phone.png"));
    driver.click("#start");
    ready(&driver, "1");
    driver.screenshot(&screenshot_path("survey-trial-phone.png"));
    let (x, y) = driver.centre("#image-left");
    for kind in ["touchStart", "touchEnd"] {
        let points: Value = if kind == "touchEnd" { json!([]) } else { json!([{"x": x, "y": y}]) };
        driver.cdp("Input.dispatchTouchEvent", json!({"type": kind, "touchPoints": points}));
    }
    driver.wait_trial("2");
    assert_eq!(answered(data_dir.path()), 1);
    let state = driver.script(
        "const l = document.getElementById('choose-left'), r = document.getElementById('choose-right');
         return [document.activeElement === l || document.activeElement === r,
                 l.classList.contains('chosen') || r.classList.contains('chosen'),
                 getComputedStyle(l).borderTopColor, getComputedStyle(r).borderTopColor];",
    );
    assert_eq!(state[0], json!(false), "a choice keeps the focus: {state}");
    assert_eq!(state[1], json!(false), "a choice keeps the chosen mark: {state}");
    assert_eq!(state[2], state[3], "both sides look the same on the new pair: {state}");
    assert_eq!(state[2], json!("rgba(0, 0, 0, 0)"), "{state}");
    let _ = client();
}

#[test]
fn the_researcher_previews_excludes_and_deletes_from_the_admin_page_in_chromium() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    // A participant through the API, answering every trial it was served.
    let http = client();
    let joined: Value = http
        .post(format!("{}/api/studies/shadows-demo/participants", server.base))
        .json(
            &json!({"demographics": super::support::demographics(), "url_params": {"PROLIFIC_PID": "PID-ADMIN-PAGE"}}),
        )
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

    let driver = Driver::start(1280, 800);
    driver.go(&format!("{}/admin/login?token={}", server.base, server.admin_token));
    driver.go(&format!("{}/admin/studies/shadows-demo", server.base));
    driver.wait_visible("participants");
    driver.click("#preview");
    driver.wait_visible("preview-link");
    let link = driver.script("return document.getElementById('preview-url').href;");
    let link = link.as_str().unwrap().to_string();
    assert!(link.contains("/studies/shadows-demo?preview="), "{link}");
    // The page opened the link in a new tab; close it and go on in this one (a background tab
    // runs no animation frames, so its trials would never start).
    let this_window = driver.command(reqwest::Method::GET, "/window", Value::Null);
    let handles = driver.command(reqwest::Method::GET, "/window/handles", Value::Null);
    for handle in handles.as_array().unwrap().iter().filter(|handle| **handle != this_window) {
        driver.command(reqwest::Method::POST, "/window", json!({"handle": handle}));
        driver.command(reqwest::Method::DELETE, "/window", Value::Null);
    }
    driver.command(reqwest::Method::POST, "/window", json!({"handle": this_window}));

    // The preview runs the study as a participant would, marked as a pilot.
    driver.go(&link);
    driver.wait_visible("preview-note");
    enter(&driver, &server.base, &link[link.find('?').unwrap()..]);
    driver.click("#start");
    for trial in 1..=7 {
        driver.wait_trial(&trial.to_string());
        driver.click("#choose-left");
    }
    driver.wait_visible("stage-done");

    let list = || -> Vec<Value> {
        http.get(format!("{}/api/admin/studies/shadows-demo/participants", server.base))
            .bearer_auth(&server.admin_token)
            .send()
            .unwrap()
            .json::<Vec<Value>>()
            .unwrap()
    };
    let participants = list();
    assert_eq!(participants.len(), 2, "{participants:?}");
    let pilot = participants.iter().find(|p| p["pilot"] == true).expect("the preview's participant is a pilot");
    let pilot_id = pilot["participant"].as_str().unwrap().to_string();
    assert_eq!(pilot["status"], "completed");

    // Exclude the other participant from the page: the prompt asks for the reason.
    driver.go(&format!("{}/admin/studies/shadows-demo", server.base));
    driver.wait_visible("participants");
    driver.screenshot(&screenshot_path("admin-participants-desktop.png"));
    driver.click(&format!("tr[data-participant='{id}'] button[data-action='exclude']"));
    driver.command(reqwest::Method::POST, "/alert/text", json!({"text": "fell asleep (observed)"}));
    driver.command(reqwest::Method::POST, "/alert/accept", json!({}));
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while list().iter().find(|p| p["participant"] == id).map(|p| p["excluded"] == true) != Some(true) {
        assert!(std::time::Instant::now() < deadline, "the exclusion did not arrive");
        std::thread::sleep(Duration::from_millis(100));
    }
    let excluded = list().into_iter().find(|p| p["participant"] == id).unwrap();
    assert_eq!(excluded["exclusion_reason"], "fell asleep (observed)");

    // Delete the pilot from the page, after confirming.
    driver.wait_visible("participants");
    driver.click(&format!("tr[data-participant='{pilot_id}'] button[data-action='delete']"));
    driver.command(reqwest::Method::POST, "/alert/accept", json!({}));
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while list().iter().any(|p| p["participant"] == pilot_id.as_str()) {
        assert!(std::time::Instant::now() < deadline, "the deletion did not arrive");
        std::thread::sleep(Duration::from_millis(100));
    }
    // With the only other participant excluded, the default export has no rows and says why.
    let export = super::support::export(data_dir.path(), "shadows-demo", "csv");
    assert_eq!(export.lines().count(), 1, "only the header: {export}");

    let phone = Driver::start(390, 844);
    phone.go(&format!("{}/admin/login?token={}", server.base, server.admin_token));
    phone.go(&format!("{}/admin/studies/shadows-demo", server.base));
    phone.wait_visible("participants");
    phone.screenshot(&screenshot_path("admin-participants-phone.png"));
}

/// An active design (`pairs = "active"`, issue 14) through the real page: the next batch of
/// trials is chosen from the answers so far while the participant goes on, so a double click,
/// a held key and a reload land exactly where a fixed schedule's would. Every trial shown is
/// answered once, with the side the participant chose, a reload shows the same pair again,
/// and every chosen trial names the judgments it was chosen from.
#[test]
fn an_active_study_stores_the_side_chosen_once_per_trial_through_double_clicks_a_held_key_and_a_reload() {
    if !browser_available() {
        return;
    }
    let (data_dir, studies) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    copy_demo_study(studies.path());
    let file = studies.path().join("shadows-demo.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    let active = text.replace(
        "[design]\npairs = \"all\"\nrepetitions = 1\n",
        "[design]\npairs = \"active\"\ntrials = 8\nbatch = 2\ntarget = \"worths\"\nwarmup = \"none\"\n",
    );
    assert!(active.contains("pairs = \"active\""), "the demo study's design changed; update this test");
    std::fs::write(&file, active).unwrap();
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    let driver = Driver::start(1280, 800);
    enter(&driver, &server.base, "");
    driver.click("#start");
    let total: usize = {
        driver.wait_trial("1");
        let progress = driver.text("#trial-progress");
        progress.rsplit(' ').next().unwrap().parse().unwrap_or_else(|_| panic!("{progress}"))
    };
    assert!(total >= 8, "8 chosen trials (and the catch trial) expected, the page says {total}");
    let shown_pair = || {
        driver.script("return [document.getElementById('image-left').src, document.getElementById('image-right').src];")
    };
    let mut chose = Vec::new();

    // trial 1: a double click on the left image, 120 ms apart
    ready(&driver, "1");
    let left = driver.centre("#image-left");
    double_click(&driver, left);
    chose.push("left");
    driver.wait_trial("2");
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(answered(data_dir.path()), 1, "the double click's second click answered trial 2");

    // trial 2: the right arrow held for half a second, with auto-repeat
    ready(&driver, "2");
    hold_key(&driver, "ArrowRight", 39, Duration::from_millis(500));
    chose.push("right");
    driver.wait_trial("3");
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(answered(data_dir.path()), 2, "auto-repeat answered more trials");

    // trial 3 by a click; trial 4 comes from a batch chosen from the answers so far, and a
    // reload shows it again
    ready(&driver, "3");
    driver.click("#choose-left");
    chose.push("left");
    ready(&driver, "4");
    let before = shown_pair();
    driver.refresh();
    driver.wait_trial("4");
    assert_eq!(shown_pair(), before, "the reload showed another pair as trial 4");
    assert_eq!(answered(data_dir.path()), 3, "the reload answered a trial");

    // the rest by deliberate clicks, alternating sides
    for trial in 4..=total {
        ready(&driver, &trial.to_string());
        let side = if trial % 2 == 0 { "left" } else { "right" };
        driver.click(&format!("#choose-{side}"));
        chose.push(side);
        let next = if trial == total { "done".to_string() } else { (trial + 1).to_string() };
        driver.wait_trial(&next);
    }
    driver.wait_visible("stage-done");

    let stored = query(data_dir.path(), "SELECT trial, chosen FROM responses ORDER BY trial");
    let expected: Vec<Vec<String>> =
        chose.iter().enumerate().map(|(i, side)| vec![(i + 1).to_string(), side.to_string()]).collect();
    assert_eq!(stored, expected, "stored answers against what the participant did");
    let trials = query(
        data_dir.path(),
        "SELECT trial, COALESCE(chosen_by, ''), catch_expected IS NOT NULL FROM trials ORDER BY trial",
    );
    assert_eq!(trials.len(), total, "{trials:?}");
    // chosen_by = "<judgments absorbed>-<fingerprint>": 8 chosen trials in batches of two, the
    // first from the prior alone and each later one from more answers (trial 4's included)
    let chosen: Vec<(usize, u32)> = trials
        .iter()
        .filter(|t| t[2] == "0")
        .map(|t| {
            (t[0].parse().unwrap(), t[1].split('-').next().unwrap().parse().unwrap_or_else(|_| panic!("{trials:?}")))
        })
        .collect();
    assert_eq!(chosen.len(), 8, "{trials:?}");
    assert!(chosen.windows(2).all(|w| w[0].1 <= w[1].1) && chosen[0].1 == 0, "{trials:?}");
    assert!(chosen.iter().any(|&(trial, absorbed)| trial == 4 && absorbed > 0), "{trials:?}");
}

/// Issue 46: an answer refused with 429 (a limit: many people behind one address) is sent again
/// after the server's `Retry-After`, the same answer, and stored once; the page shows a notice
/// meanwhile instead of an error. The 429 is the page's first answer POST, made by the browser
/// (a wrapped `fetch`), so the test needs no limit small enough to reach.
#[test]
fn an_answer_refused_with_429_is_sent_again_after_retry_after_and_stored_once() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(1280, 800);
    enter(&driver, &server.base, "");
    driver.script(
        "const real = window.fetch; window.refusedAt = null;
         window.fetch = (url, options) => {
           if (String(url).endsWith('/responses') && window.refusedAt === null) {
             window.refusedAt = performance.now();
             const body = JSON.stringify({error: 'Too many answers from this participant (at most 120 in a minute); wait a little and try again.'});
             return Promise.resolve(new Response(body, {status: 429, headers: {'Retry-After': '2', 'Content-Type': 'application/json'}}));
           }
           return real(url, options);
         };
         return true;",
    );
    driver.click("#start");
    driver.wait_trial("1");
    driver.click("#choose-right");
    driver.wait_for("window.refusedAt !== null");
    // the notice while it waits; nothing stored yet
    driver.wait_for("!document.getElementById('trial-error').hidden");
    assert!(driver.text("#trial-error").contains("nothing is lost"), "{}", driver.text("#trial-error"));
    assert_eq!(answered(data_dir.path()), 0);
    driver.wait_trial("2");
    let waited = driver.script("return performance.now() - window.refusedAt;").as_f64().unwrap();
    assert!(waited >= 1900.0, "sent again after Retry-After (2 s), not before: {waited} ms");
    let rows = query(data_dir.path(), "SELECT trial, chosen FROM responses");
    assert_eq!(rows, vec![vec!["1".to_string(), "right".to_string()]], "the answer given, stored once");
    assert!(
        driver.script("return document.getElementById('trial-error').hidden;") == json!(true),
        "the notice is gone"
    );
}

/// Issue 49, item 3: in a study with `allow_tie = true` the page offers "Not sure" under the
/// pair; its button and ↓ (held: one answer) store `tie`, an image still stores its side; the
/// forced-choice demo has no such button, and ↓ answers nothing there.
#[test]
fn not_sure_is_answered_by_its_button_or_the_down_arrow_only_where_the_study_allows_it() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    demo_with(studies.path(), "allow_tie = true");
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    let driver = Driver::start(1280, 800);
    enter(&driver, &server.base, "");
    driver.click("#start");
    // each press after the answer lock (500 ms) and `min_response_ms` (300 ms) have passed
    let past_the_lock = || std::thread::sleep(Duration::from_millis(700));
    ready(&driver, "1");
    past_the_lock();
    driver.screenshot(&screenshot_path("survey-not-sure-desktop.png"));
    driver.click("#choose-tie");
    ready(&driver, "2");
    past_the_lock();
    hold_key(&driver, "ArrowDown", 40, Duration::from_millis(600));
    ready(&driver, "3");
    past_the_lock();
    driver.click("#choose-left");
    driver.wait_trial("4");
    std::thread::sleep(Duration::from_millis(600));
    let stored = query(data_dir.path(), "SELECT trial, chosen FROM responses ORDER BY trial");
    let expected = [("1", "tie"), ("2", "tie"), ("3", "left")];
    assert_eq!(stored, expected.map(|(trial, chosen)| vec![trial.to_string(), chosen.to_string()]).to_vec());

    // the forced-choice demo: no button, and ↓ is no answer
    let forced_dir = tempfile::tempdir().unwrap();
    let forced = Server::start(forced_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(1280, 800);
    enter(&driver, &forced.base, "");
    driver.click("#start");
    ready(&driver, "1");
    past_the_lock();
    assert_eq!(driver.script("return document.getElementById('choose-tie') === null;"), json!(true));
    key(&driver, "keyDown", "ArrowDown", 40, false);
    key(&driver, "keyUp", "ArrowDown", 40, false);
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(answered(forced_dir.path()), 0, "↓ answered a forced-choice trial");
}
