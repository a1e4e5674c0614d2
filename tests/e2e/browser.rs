//! The participant pages in headless Chromium, driven over WebDriver (chromedriver): consent,
//! demographics, three trials answered by clicking, a reload that resumes at the right trial,
//! the rest by keyboard, and the completion code; screenshots are written for a person to look
//! at (`$CARGO_TARGET_TMPDIR/browser-*.png`).
//!
//! Needs Debian's `chromium` and `chromium-driver` (scripts/test.sh installs them). Without
//! them the test fails, unless MRSTUDY_SKIP_BROWSER_TESTS=1 says to skip it.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use super::support::{Server, client};

const CHROMIUM: &str = "/usr/bin/chromium";
const CHROMEDRIVER: &str = "/usr/bin/chromedriver";
const WAIT: Duration = Duration::from_secs(20);

pub(super) struct Driver {
    child: Child,
    base: String,
    session: String,
    http: reqwest::blocking::Client,
    _profile: tempfile::TempDir,
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.http.delete(format!("{}/session/{}", self.base, self.session)).send();
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Driver {
    pub(super) fn start(width: u32, height: u32) -> Driver {
        Driver::start_with(width, height, json!({}))
    }

    /// A session with extra `goog:chromeOptions` entries (e.g. `mobileEmulation`).
    pub(super) fn start_with(width: u32, height: u32, extra_options: Value) -> Driver {
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let child = Command::new(CHROMEDRIVER)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts");
        let base = format!("http://127.0.0.1:{port}");
        let http = reqwest::blocking::Client::builder().timeout(Duration::from_secs(60)).build().unwrap();
        let deadline = Instant::now() + WAIT;
        while http.get(format!("{base}/status")).send().is_err() {
            assert!(Instant::now() < deadline, "chromedriver did not start");
            std::thread::sleep(Duration::from_millis(100));
        }
        let profile = tempfile::tempdir().unwrap();
        let mut capabilities = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": CHROMIUM,
                "args": [
                    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                    "--disable-background-networking", "--disable-component-update", "--disable-sync",
                    "--disable-dev-shm-usage", format!("--user-data-dir={}", profile.path().display()),
                    format!("--window-size={width},{height}"),
                ]
            }
        }}});
        if let Value::Object(extra) = extra_options {
            for (key, value) in extra {
                capabilities["capabilities"]["alwaysMatch"]["goog:chromeOptions"][key] = value;
            }
        }
        let answer: Value = http.post(format!("{base}/session")).json(&capabilities).send().unwrap().json().unwrap();
        let session = answer["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no WebDriver session: {answer}"))
            .to_string();
        Driver { child, base, session, http, _profile: profile }
    }

    pub(super) fn command(&self, method: reqwest::Method, path: &str, body: Value) -> Value {
        let url = format!("{}/session/{}{path}", self.base, self.session);
        let request = self.http.request(method, url);
        let request = if body.is_null() { request } else { request.json(&body) };
        let answer: Value = request.send().unwrap().json().unwrap();
        if answer["value"].get("error").is_some() {
            panic!("WebDriver {path}: {}", answer["value"]);
        }
        answer["value"].clone()
    }

    pub(super) fn go(&self, url: &str) {
        self.command(reqwest::Method::POST, "/url", json!({"url": url}));
    }

    pub(super) fn refresh(&self) {
        self.command(reqwest::Method::POST, "/refresh", json!({}));
    }

    pub(super) fn script(&self, script: &str) -> Value {
        self.command(reqwest::Method::POST, "/execute/sync", json!({"script": script, "args": []}))
    }

    pub(super) fn element(&self, css: &str) -> String {
        let found = self.command(reqwest::Method::POST, "/element", json!({"using": "css selector", "value": css}));
        found.as_object().unwrap().values().next().unwrap().as_str().unwrap().to_string()
    }

    pub(super) fn click(&self, css: &str) {
        let element = self.element(css);
        self.command(reqwest::Method::POST, &format!("/element/{element}/click"), json!({}));
    }

    pub(super) fn type_into(&self, css: &str, text: &str) {
        let element = self.element(css);
        self.command(reqwest::Method::POST, &format!("/element/{element}/value"), json!({"text": text}));
    }

    pub(super) fn text(&self, css: &str) -> String {
        let element = self.element(css);
        self.command(reqwest::Method::GET, &format!("/element/{element}/text"), Value::Null)
            .as_str()
            .unwrap()
            .to_string()
    }

    /// Waits until the JavaScript expression is true.
    pub(super) fn wait_for(&self, expression: &str) {
        let deadline = Instant::now() + WAIT;
        loop {
            if self.script(&format!("return !!({expression});")) == json!(true) {
                return;
            }
            if Instant::now() > deadline {
                let state = self.script("return document.body ? document.body.outerHTML.slice(0, 3000) : 'no body';");
                panic!("timed out waiting for {expression}; page: {state}");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    pub(super) fn wait_visible(&self, id: &str) {
        self.wait_for(&format!("document.getElementById('{id}') && !document.getElementById('{id}').hidden"));
    }

    /// Waits until the trial is on screen and, for a trial, until the page takes answers: the
    /// demo study's `min_response_ms` (300 ms) after the pair appeared, and its `answer_lock_ms`
    /// (500 ms) after the previous answer, which came before the pair appeared.
    pub(super) fn wait_trial(&self, trial: &str) {
        self.wait_for(&format!("document.body.dataset.trial === '{trial}'"));
        if trial != "done" {
            std::thread::sleep(Duration::from_millis(550));
        }
    }

    /// A Chrome DevTools Protocol command (trusted input events: auto-repeated keys, clicks
    /// with a click count, touches).
    pub(super) fn cdp(&self, cmd: &str, params: Value) -> Value {
        let url = format!("{}/session/{}/goog/cdp/execute", self.base, self.session);
        let answer: Value =
            self.http.post(url).json(&json!({"cmd": cmd, "params": params})).send().unwrap().json().unwrap();
        if answer["value"].get("error").is_some() {
            panic!("CDP {cmd}: {}", answer["value"]);
        }
        answer["value"].clone()
    }

    /// The centre of an element in CSS pixels of the viewport.
    pub(super) fn centre(&self, css: &str) -> (f64, f64) {
        let centre = self.script(&format!(
            "const r = document.querySelector('{css}').getBoundingClientRect(); return [r.left + r.width / 2, r.top + r.height / 2];"
        ));
        (centre[0].as_f64().unwrap(), centre[1].as_f64().unwrap())
    }

    pub(super) fn screenshot(&self, path: &Path) {
        let data = self.command(reqwest::Method::GET, "/screenshot", Value::Null);
        std::fs::write(path, base64_decode(data.as_str().unwrap())).unwrap();
        eprintln!("screenshot: {}", path.display());
    }
}

fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| -> u32 {
        match c {
            b'A'..=b'Z' => (c - b'A') as u32,
            b'a'..=b'z' => (c - b'a' + 26) as u32,
            b'0'..=b'9' => (c - b'0' + 52) as u32,
            b'+' => 62,
            b'/' => 63,
            _ => 0,
        }
    };
    let bytes: Vec<u8> = text.bytes().filter(|c| !c.is_ascii_whitespace()).collect();
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let n = chunk.iter().take_while(|&&c| c != b'=').count();
        let word = chunk.iter().take(n).enumerate().fold(0u32, |acc, (i, &c)| acc | value(c) << (18 - 6 * i));
        for i in 0..n.saturating_sub(1) {
            out.push((word >> (16 - 8 * i)) as u8);
        }
    }
    out
}

pub(super) fn browser_available() -> bool {
    if Path::new(CHROMIUM).exists() && Path::new(CHROMEDRIVER).exists() {
        return true;
    }
    if std::env::var("MRSTUDY_SKIP_BROWSER_TESTS").as_deref() == Ok("1") {
        eprintln!("skipping the browser test: MRSTUDY_SKIP_BROWSER_TESTS=1 and no {CHROMIUM} / {CHROMEDRIVER}");
        return false;
    }
    panic!(
        "the browser test needs {CHROMIUM} and {CHROMEDRIVER} (Debian packages chromium and chromium-driver; scripts/test.sh installs them), or MRSTUDY_SKIP_BROWSER_TESTS=1"
    );
}

/// Consents and answers the demo study's demographics with `gender` and `age`, then presses
/// Continue (the caller checks what follows).
pub(super) fn consent_and_demographics(driver: &Driver, gender: &str, age: &str) {
    driver.click("#consent");
    driver.click("#consent-continue");
    driver.wait_visible("stage-demographics");
    driver.click(&format!("#field-gender option[value='{gender}']"));
    driver.type_into("#field-age", age);
    driver.click("#field-cg_experience option[value='none']");
    driver.click("#field-vision option[value='normal']");
    driver.click("#demographics-continue");
}

/// Consents and continues past the demographics without answering them (a study that asks
/// none), then waits for the instructions.
pub(super) fn consent_without_demographics(driver: &Driver) {
    driver.click("#consent");
    driver.click("#consent-continue");
    driver.wait_visible("stage-demographics");
    driver.click("#demographics-continue");
    driver.wait_visible("stage-instructions");
}

/// Answers `trials` (numbered from 1; `last` the study's last) one by one with `answer(trial)`,
/// waiting after each for the next trial, or the end after the last.
pub(super) fn answer_trials(
    driver: &Driver,
    trials: std::ops::RangeInclusive<u8>,
    last: u8,
    mut answer: impl FnMut(u8),
) {
    for trial in trials {
        answer(trial);
        let next = if trial == last { "done".to_string() } else { (trial + 1).to_string() };
        driver.wait_trial(&next);
    }
}

pub(super) fn screenshot_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(name)
}

#[test]
fn a_participant_consents_answers_reloads_resumes_and_finishes_in_chromium() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(1280, 900);
    driver.go(&format!("{}/studies/shadows-demo?PROLIFIC_PID=browser-test-pid", server.base));

    driver.wait_visible("stage-welcome");
    driver.click("#consent");
    driver.click("#consent-continue");
    driver.wait_visible("stage-demographics");
    // Continuing with nothing filled in is refused on the page, with a message.
    driver.click("#demographics-continue");
    driver.wait_for("!document.getElementById('demographics-error').hidden");
    driver.click("#field-gender option[value='female']");
    driver.type_into("#field-age", "34");
    driver.click("#field-cg_experience option[value='none']");
    driver.click("#field-vision option[value='normal']");
    driver.click("#demographics-continue");
    driver.wait_visible("stage-instructions");
    driver.click("#start");

    driver.wait_trial("1");
    assert_eq!(driver.text("#trial-progress"), "Trial 1 of 7");
    driver.click("#choose-left");
    driver.wait_trial("2");
    assert_eq!(driver.text("#trial-progress"), "Trial 2 of 7");
    driver.click("#choose-right");
    driver.wait_trial("3");
    driver.click("#image-left");
    driver.wait_trial("4");

    // Reload mid-study: back at trial 4, not at the consent page.
    driver.refresh();
    driver.wait_trial("4");
    assert!(driver.script("return document.getElementById('stage-welcome').hidden;") == json!(true));
    assert_eq!(driver.text("#trial-progress"), "Trial 4 of 7");
    let both_images_shown = driver.script(
        "const l = document.getElementById('image-left'), r = document.getElementById('image-right');
         return l.complete && r.complete && l.naturalWidth > 0 && r.naturalWidth > 0 && l.getBoundingClientRect().width > 200;",
    );
    assert_eq!(both_images_shown, json!(true));
    driver.screenshot(&screenshot_path("browser-trial-desktop.png"));

    // The rest by keyboard.
    for trial in 4..=7 {
        driver.wait_trial(&trial.to_string());
        let key = if trial % 2 == 0 { "\u{E012}" } else { "\u{E014}" }; // ArrowLeft, ArrowRight
        driver.type_into("body", key);
        let next = if trial == 7 { "done".to_string() } else { (trial + 1).to_string() };
        driver.wait_trial(&next);
    }
    driver.wait_visible("stage-done");
    assert_eq!(driver.text("#completion-code"), "DEMO-7F3A");

    // What the server stored: seven answers with positive response times, the Prolific id, and
    // the browser's viewport, pixel ratio and user agent.
    let stored: Value = client()
        .get(format!("{}/api/admin/studies/shadows-demo/export.json", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    let participants = stored["participants"].as_array().unwrap();
    assert_eq!(participants.len(), 1, "the reload did not create a second participant");
    let participant = &participants[0];
    assert_eq!(participant["answered"], 7);
    assert_eq!(participant["url_params"]["PROLIFIC_PID"], "browser-test-pid");
    assert_eq!(
        participant["demographics"],
        json!({"gender": "female", "age": 34, "cg_experience": "none", "vision": "normal"})
    );
    assert!(participant["client"]["userAgent"].as_str().unwrap().contains("Chrome"));
    assert!(participant["client"]["devicePixelRatio"].as_f64().unwrap() > 0.0);
    assert_eq!(participant["client"]["viewport"].as_array().unwrap().len(), 2);
    for trial in participant["schedule"].as_array().unwrap() {
        let rt_ms = trial["response"]["rt_ms"].as_f64().unwrap();
        assert!(rt_ms > 0.0 && rt_ms < 60_000.0, "{trial}");
    }
}

#[test]
fn the_trial_page_fits_a_phone_screen() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let driver = Driver::start(844, 390); // a phone held sideways
    driver.go(&format!("{}/studies/shadows-demo", server.base));
    driver.wait_visible("stage-welcome");
    driver.screenshot(&screenshot_path("browser-welcome-phone.png"));
    consent_and_demographics(&driver, "male", "25");
    driver.wait_visible("stage-instructions");
    driver.click("#start");
    driver.wait_trial("1");
    // Both images side by side, inside the viewport, without horizontal scrolling.
    let fits = driver.script(
        "const l = document.getElementById('image-left').getBoundingClientRect();
         const r = document.getElementById('image-right').getBoundingClientRect();
         return l.right <= r.left && r.right <= window.innerWidth && l.bottom <= window.innerHeight + 1
             && r.bottom <= window.innerHeight + 1 && document.documentElement.scrollWidth <= window.innerWidth;",
    );
    driver.screenshot(&screenshot_path("browser-trial-phone.png"));
    assert_eq!(fits, json!(true));
}

#[test]
fn arrow_keys_move_the_virtual_cube_in_the_live_lab_page_in_chromium() {
    if !browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    // larger frames than the other lab tests, so the screenshot shows something
    let study = super::lab::small_study()
        .replace("size = [96, 72]", "size = [320, 240]")
        .replace("photo_spp = 2", "photo_spp = 8");
    std::fs::write(studies.path().join("lab.toml"), study).unwrap();
    let Some(server) = super::lab::lab_server(data_dir.path(), studies.path()) else { return };
    let driver = Driver::start(1000, 900);
    driver.go(&format!("{}/lab/lab", server.base));
    driver.type_into("#lab-label", "chromium");
    driver.click("#lab-start-button");
    // three distance trials first, after their instructions
    driver.wait_visible("lab-task");
    driver.click("#lab-ack");
    for trial in 1..=3 {
        driver.wait_for(&format!("document.getElementById('lab-progress').textContent.includes('Trial {trial} of 6')"));
        driver.wait_for(&format!("document.getElementById('lab-frame').dataset.trial === '{trial}'"));
        if trial == 1 {
            driver.screenshot(&screenshot_path("lab-distance.png"));
        }
        driver.type_into("#lab-cm", "15");
        driver.click("#lab-distance button");
        driver.wait_visible("lab-next");
        driver.click("#lab-next");
    }
    // the placement task's instructions stay until acknowledged
    driver.wait_visible("lab-task");
    driver.click("#lab-ack");
    // placement: the first frame, then arrow keys
    driver.wait_for("document.getElementById('lab-progress').textContent.includes('Trial 4 of 6')");
    driver.wait_for(
        "document.getElementById('lab-frame').dataset.trial === '4' && !document.getElementById('lab-keys').hidden",
    );
    driver.wait_for("document.getElementById('lab-frame').complete");
    let before = driver.script("return document.getElementById('lab-frame').src;");
    let shown_before =
        driver.script("return Number(document.getElementById('lab-frame').dataset.shown);").as_u64().unwrap();
    driver.screenshot(&screenshot_path("lab-placement-before.png"));
    for _ in 0..8 {
        driver.type_into("body", "\u{E012}"); // ArrowLeft
    }
    driver.type_into("body", "\u{E013}\u{E013}"); // ArrowUp
    driver.wait_for(&format!("Number(document.getElementById('lab-frame').dataset.shown) > {shown_before} && document.getElementById('lab-frame').complete"));
    // let the last coalesced frame arrive
    std::thread::sleep(Duration::from_millis(800));
    let after = driver.script("return document.getElementById('lab-frame').src;");
    assert_ne!(before, after, "the frame changed after the arrow keys");
    driver.screenshot(&screenshot_path("lab-placement-after.png"));
    driver.type_into("body", "\u{E007}"); // Enter confirms
    driver.wait_visible("lab-next");
    let stored: Value = client()
        .get(format!("{}/api/admin/lab/lab/analysis", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(stored["participants"][0]["answered"], 4, "{stored}");
    assert_eq!(stored["participants"][0]["label"], "chromium");
    let trials = super::support::export(data_dir.path(), "lab", "task-trials");
    let placement = trials.lines().nth(4).unwrap();
    assert!(placement.contains("ArrowLeft") && placement.contains("ArrowUp"), "{placement}");
}
