//! Task studies through the binary: `mrstudy serve` with the shipped studies and no usable
//! adapter (one warning line, everything else served), and a small lab study run over the
//! WebSocket by three participants, exported with `mrstudy export --format task` and analysed by
//! `mrstudy analyze` (Friedman tests per task and measure); and in headless Chromium, a held
//! Enter key (auto-repeated keydown events for a second) that skips no trial, stores no trial
//! without a frame shown and acknowledges no instructions, an empty code refused on the page,
//! and a reopened page that resumes at the next unanswered trial; with screenshots of the lab
//! page at 1280×800 and 390×844 (`$CARGO_TARGET_TMPDIR/lab-*.png`).

use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

use super::lab_study::LabStudy;
use super::support::{Server, binary, client, copy_demo_study, export, repo_studies_dir};

/// A small, fast task study: 96×72 frames, one trial per condition, no practice.
pub fn small_study() -> String {
    LabStudy { title: "Cubes", conditions: &["none", "shadows", "gi"], seed: 11, ..LabStudy::default() }.toml()
}

/// Starts `mrstudy serve` on `studies` and waits until the lab has started: Some(server) with
/// its `lab link:`, or None (with a note) when no GPU adapter could be opened.
pub fn lab_server(data_dir: &Path, studies: &Path) -> Option<Server> {
    let server = Server::try_start(data_dir, "127.0.0.1:0", studies).unwrap_or_else(|error| panic!("{error}"));
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        if let Ok(line) = server.stdout.recv_timeout(Duration::from_millis(100))
            && line.starts_with("lab link: ")
        {
            return Some(server);
        }
        if let Ok(line) = server.stderr.try_recv()
            && line.starts_with("warning: ")
        {
            // unequal frame times across conditions are warned about, and served
            if line.contains("frames/s") {
                eprintln!("{line}");
                continue;
            }
            assert!(line.contains("GPU adapter"), "unexpected warning: {line}");
            eprintln!("skipping: {line}");
            return None;
        }
        assert!(Instant::now() < deadline, "the lab did not start within 120 s");
    }
}

type Socket = WebSocket<MaybeTlsStream<TcpStream>>;

fn receive(socket: &mut Socket) -> Value {
    loop {
        match socket.read().expect("a message") {
            Message::Text(text) => return serde_json::from_str(text.as_str()).unwrap(),
            Message::Binary(_) => continue,
            _ => continue,
        }
    }
}

fn until(socket: &mut Socket, kind: &str) -> Value {
    loop {
        let message = receive(socket);
        assert_ne!(message["type"], "error", "{message}");
        if message["type"] == kind {
            return message;
        }
    }
}

fn send(socket: &mut Socket, value: Value) {
    socket.send(Message::Text(value.to_string().into())).unwrap();
}

/// One participant through every trial: distance answers and placement keys that depend on
/// `skill`, so the conditions differ.
fn run_participant(base: &str, label: &str, skill: f64) {
    let url = format!("{}/api/lab/lab/ws", base.replace("http://", "ws://"));
    let (mut socket, _) = tungstenite::connect(url).unwrap();
    if let MaybeTlsStream::Plain(stream) = socket.get_ref() {
        stream.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    }
    // the participant is created over HTTP first; the session starts with its id and token
    let joined: Value = reqwest::blocking::Client::new()
        .post(format!("{base}/api/lab/lab/participants"))
        .json(&json!({"label": label}))
        .send()
        .unwrap()
        .error_for_status()
        .unwrap()
        .json()
        .unwrap();
    send(&mut socket, json!({"type": "start", "participant": joined["participant"], "token": joined["token"]}));
    let session = until(&mut socket, "session");
    let trials = session["trials"].as_u64().unwrap();
    for _ in 0..trials {
        send(&mut socket, json!({"type": "ready"}));
        let mut trial = receive(&mut socket);
        if trial["type"] == "instructions" {
            send(&mut socket, json!({"type": "acknowledge"}));
            trial = until(&mut socket, "trial");
        }
        assert_eq!(trial["type"], "trial", "{trial}");
        let frame = until(&mut socket, "frame");
        send(&mut socket, json!({"type": "shown", "n": frame["n"]}));
        let number = trial["trial"].as_u64().unwrap();
        if trial["kind"] == "distance" {
            send(&mut socket, json!({"type": "answer", "trial": number, "cm": 10.0 + skill * number as f64}));
        } else {
            for _ in 0..(number as usize % 3 + 1) {
                send(&mut socket, json!({"type": "key", "key": "ArrowLeft"}));
            }
            send(&mut socket, json!({"type": "answer", "trial": number}));
        }
        until(&mut socket, "saved");
    }
    until(&mut socket, "done");
}

#[test]
fn serve_without_a_gpu_adapter_warns_once_and_serves_the_rest() {
    let data_dir = tempfile::tempdir().unwrap();
    // the demo survey and the shipped lab study
    let studies = tempfile::tempdir().unwrap();
    std::fs::copy(repo_studies_dir().join("lab-task.toml"), studies.path().join("lab-task.toml")).unwrap();
    copy_demo_study(studies.path());
    let server = Server::try_start_with_env(
        data_dir.path(),
        "127.0.0.1:0",
        studies.path(),
        &[("MRSTUDY_ADAPTER", "no-such-kind")],
        Duration::from_secs(60),
    )
    .unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut lab_warnings = Vec::new();
    while Instant::now() < deadline && lab_warnings.is_empty() {
        if let Ok(line) = server.stderr.recv_timeout(Duration::from_millis(100))
            && line.contains("lab-task")
        {
            lab_warnings.push(line);
        }
    }
    std::thread::sleep(Duration::from_millis(300));
    lab_warnings.extend(server.stderr.try_iter().filter(|line| line.contains("lab-task")));
    assert_eq!(lab_warnings.len(), 1, "{lab_warnings:?}");
    let line = &lab_warnings[0];
    assert!(
        line.starts_with("warning: task study \"lab-task\" not served")
            && line.contains("GPU adapter")
            && line.contains("no-such-kind"),
        "{line}"
    );
    // the web survey is served, the lab page is not
    let http = client();
    assert_eq!(http.get(format!("{}/studies/shadows-demo", server.base)).send().unwrap().status(), 200);
    assert_eq!(http.get(format!("{}/lab/lab-task", server.base)).send().unwrap().status(), 404);
}

#[test]
fn three_participants_run_the_lab_study_and_mrstudy_analyze_reads_the_task_export() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    std::fs::write(studies.path().join("lab.toml"), small_study()).unwrap();
    let Some(server) = lab_server(data_dir.path(), studies.path()) else { return };
    for (index, label) in ["A", "B", "C"].iter().enumerate() {
        run_participant(&server.base, label, 0.5 + index as f64);
    }
    // the admin page names the adapter and shows the tests
    let page = client()
        .get(format!("{}/admin/lab/lab", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .text()
        .unwrap();
    assert!(
        page.contains("frames/s") && page.contains("Friedman") && page.contains("task distance, measure error_cm"),
        "{page}"
    );
    assert!(page.contains("Targets are drawn within the camera's view"), "{page}");
    // each condition's frame time, with its own verdict (not one "fast enough" for the study)
    assert!(page.contains("id=\"lab-frame-times\""), "{page}");
    for condition in ["none", "shadows", "gi"] {
        assert!(page.contains(&format!("<tr><td>{condition}</td><td>")), "no frame-time row for {condition}: {page}");
    }
    let unequal = page.contains("id=\"lab-parity\"");
    assert_eq!(
        unequal,
        page.contains("confounded with lag"),
        "unpaced unequal conditions are called a confound: {page}"
    );
    let overview =
        client().get(format!("{}/admin", server.base)).bearer_auth(&server.admin_token).send().unwrap().text().unwrap();
    assert!(overview.contains("/admin/lab/lab") && overview.contains("Lab task studies"), "{overview}");
    let csv = export(data_dir.path(), "lab", "task");
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "participant,task,measure,condition,value,trials,label");
    // 3 participants × (distance: 5 measures + placement: 4 measures) × 3 conditions
    assert_eq!(rows.len() - 1, 3 * (5 + 4) * 3, "{csv}");
    let file = data_dir.path().join("task.csv");
    std::fs::write(&file, &csv).unwrap();
    let output = std::process::Command::new(binary())
        .args(["analyze", "--trials"])
        .arg(&file)
        .args(["--format", "json"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let analysis: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(analysis["grouped_by"], json!(["task", "measure"]));
    let measures = analysis["measures"].as_array().unwrap();
    assert_eq!(measures.len(), 9);
    let distance_error =
        measures.iter().find(|m| m["group"] == json!({"task": "distance", "measure": "error_cm"})).unwrap();
    assert_eq!(distance_error["friedman"]["participants"], 3);
    assert_eq!(distance_error["friedman"]["conditions"], 3);
    let trials = export(data_dir.path(), "lab", "task-trials");
    assert_eq!(trials.lines().count(), 1 + 3 * 6);
}

/// Two tasks of two trials each (so the second task's instructions come between), default
/// `min_response_ms` (300 ms), frames large enough to look at.
fn held_key_study() -> String {
    LabStudy {
        title: "Cubes",
        welcome: "Hello. You will see a table with a real and a virtual cube.",
        instructions: "There are two short tasks.",
        seed: 3,
        min_response_ms: None,
        size: [160, 120],
        photo_spp: 4,
        tasks: &["kind = \"placement\"", "kind = \"contact\""],
        ..LabStudy::default()
    }
    .toml()
}

/// One Enter key event through the DevTools protocol; `repeat` marks an auto-repeated keydown.
fn enter(driver: &super::browser::Driver, kind: &str, repeat: bool) {
    let mut params = json!({"type": kind, "key": "Enter", "code": "Enter", "windowsVirtualKeyCode": 13, "nativeVirtualKeyCode": 13, "autoRepeat": repeat});
    if kind == "keyDown" {
        params["text"] = json!("\r");
    }
    driver.cdp("Input.dispatchKeyEvent", params);
}

/// Holds ArrowLeft for `duration` as a system does: one keydown, auto-repeated keydowns every
/// 30 ms, one keyup.
fn hold_arrow_left(driver: &super::browser::Driver, duration: Duration) {
    let key = |kind: &str, repeat: bool| {
        driver.cdp(
            "Input.dispatchKeyEvent",
            json!({"type": kind, "key": "ArrowLeft", "code": "ArrowLeft", "windowsVirtualKeyCode": 37, "nativeVirtualKeyCode": 37, "autoRepeat": repeat}),
        );
    };
    key("keyDown", false);
    let until = Instant::now() + duration;
    while Instant::now() < until {
        std::thread::sleep(Duration::from_millis(30));
        key("keyDown", true);
    }
    key("keyUp", false);
}

/// Holds Enter for `duration`: one keydown, auto-repeated keydowns every 30 ms, one keyup.
fn hold_enter(driver: &super::browser::Driver, duration: Duration) {
    enter(driver, "keyDown", false);
    let until = Instant::now() + duration;
    let mut repeats = 0;
    while Instant::now() < until {
        std::thread::sleep(Duration::from_millis(30));
        enter(driver, "keyDown", true);
        repeats += 1;
    }
    enter(driver, "keyUp", false);
    assert!(repeats >= 10, "only {repeats} repeated keydowns in {duration:?}");
}

fn answered(server: &Server, label: &str) -> u64 {
    let stored: Value = client()
        .get(format!("{}/api/admin/lab/lab/analysis", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    stored["participants"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["label"] == label)
        .map(|p| p["answered"].as_u64().unwrap())
        .unwrap_or(0)
}

fn mode(driver: &super::browser::Driver) -> String {
    driver.script("return document.body.dataset.mode || '';").as_str().unwrap_or("").to_string()
}

/// Waits until trial `trial`'s first frame is on screen, then past min_response_ms.
fn wait_frame(driver: &super::browser::Driver, trial: u32) {
    driver.wait_for(&format!("document.body.dataset.mode === 'trial' && document.getElementById('lab-frame').dataset.trial === '{trial}' && document.getElementById('lab-frame').complete"));
    std::thread::sleep(Duration::from_millis(450));
}

#[test]
fn a_held_enter_key_skips_no_trial_and_acknowledges_no_instructions_in_chromium() {
    if !super::browser::browser_available() {
        return;
    }
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    std::fs::write(studies.path().join("lab.toml"), held_key_study()).unwrap();
    let Some(server) = lab_server(data_dir.path(), studies.path()) else { return };
    let shot = super::browser::screenshot_path;
    let driver = super::browser::Driver::start(1280, 800);
    let page = format!("{}/lab/lab", server.base);
    driver.go(&page);
    driver.wait_visible("lab-welcome");
    // an empty code is refused on the page with one sentence; nobody is stored
    driver.click("#lab-start-button");
    driver.wait_for("document.getElementById('lab-start-error').textContent.includes('participant code is empty')");
    driver.screenshot(&shot("lab-welcome-empty-code-1280x800.png"));
    assert_eq!(answered(&server, ""), 0);
    let stored: Value = client()
        .get(format!("{}/api/admin/lab/lab/analysis", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(stored["participants"].as_array().unwrap().len(), 0);

    driver.type_into("#lab-label", "held");
    driver.click("#lab-start-button");
    driver.wait_for("document.body.dataset.mode === 'instructions'");
    driver.screenshot(&shot("lab-instructions-1280x800.png"));
    std::thread::sleep(Duration::from_millis(400));
    driver.click("#lab-ack");
    wait_frame(&driver, 1);
    driver.screenshot(&shot("lab-trial-1280x800.png"));
    let hint_visible = driver
        .script("return document.getElementById('lab-keys').getBoundingClientRect().bottom <= window.innerHeight;");
    assert_eq!(hint_visible, json!(true), "the frame and the key hint fit the window without scrolling");

    // issue 45: a held arrow key moves the cube continuously at the task's fixed rate (10 steps
    // a second by default), whatever the system's auto-repeat (every 30 ms here) does
    hold_arrow_left(&driver, Duration::from_secs(1));
    std::thread::sleep(Duration::from_millis(300));
    // held on trial 1: the first keydown answers it, the repeats do nothing more
    hold_enter(&driver, Duration::from_secs(1));
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(answered(&server, "held"), 1);
    assert_eq!(mode(&driver), "next");
    assert_eq!(driver.text("#lab-error"), "", "no error after a valid answer");
    // held on the next-trial screen: the first keydown starts trial 2, the repeats do not answer it
    hold_enter(&driver, Duration::from_secs(1));
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(answered(&server, "held"), 1, "a held Enter answered trial 2");
    assert_eq!(mode(&driver), "trial");
    wait_frame(&driver, 2);
    enter(&driver, "keyDown", false);
    enter(&driver, "keyUp", false);
    driver.wait_for("document.body.dataset.mode === 'next'");
    assert_eq!(answered(&server, "held"), 2);
    // held into the contact task's instructions: they stay until a fresh key press
    hold_enter(&driver, Duration::from_secs(1));
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(mode(&driver), "instructions", "a held Enter acknowledged the instructions");
    assert!(driver.text("#lab-task-text").contains("table"), "the contact task's instructions are shown");
    assert_eq!(answered(&server, "held"), 2);

    // the tab is closed and opened again: the participant resumes at trial 3 (its instructions first)
    driver.go("about:blank");
    driver.go(&page);
    driver.wait_for("document.body.dataset.mode === 'instructions'");
    assert!(driver.text("#lab-progress").contains("trial 3 of 4"), "{}", driver.text("#lab-progress"));
    std::thread::sleep(Duration::from_millis(400));
    enter(&driver, "keyDown", false);
    enter(&driver, "keyUp", false);
    wait_frame(&driver, 3);
    enter(&driver, "keyDown", false);
    enter(&driver, "keyUp", false);
    driver.wait_for("document.body.dataset.mode === 'next'");
    driver.click("#lab-next");
    wait_frame(&driver, 4);
    enter(&driver, "keyDown", false);
    enter(&driver, "keyUp", false);
    driver.wait_visible("lab-done");
    assert_eq!(answered(&server, "held"), 4);

    // every stored trial had its frame shown, and took at least min_response_ms
    let trials = super::support::export(data_dir.path(), "lab", "task-trials");
    let mut records = parse_csv(&trials);
    let header = records.remove(0);
    let column = |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows = records;
    assert_eq!(rows.len(), 4);
    for row in &rows {
        let frames_shown: u64 = row[column("frames_shown")].parse().unwrap();
        let completion_ms: f64 = row[column("completion_ms")].parse().unwrap();
        assert!(frames_shown >= 1, "trial {} stored with no frame shown", &row[column("trial")]);
        assert!(completion_ms >= 300.0, "trial {} took {completion_ms} ms", &row[column("trial")]);
    }
    let numbers: Vec<&str> = rows.iter().map(|row| row[column("trial")].as_str()).collect();
    assert_eq!(numbers, vec!["1", "2", "3", "4"]);
    // trial 1's key log: one step when ArrowLeft went down, then about ten held steps in its second
    let log: Value = serde_json::from_str(&rows[0][column("key_log")]).unwrap();
    let log = log.as_array().unwrap();
    let held = log.iter().filter(|key| key["held"] == json!(true)).count();
    assert!(log.iter().all(|key| key["key"] == "ArrowLeft"), "{log:?}");
    assert_eq!(log.len() - held, 1, "one press: {log:?}");
    assert!((6..=14).contains(&held), "{held} held steps in 1 s at 10 a second: {log:?}");

    // the phone-sized page
    let phone = super::browser::Driver::start(390, 844);
    phone.go(&page);
    phone.wait_visible("lab-welcome");
    phone.screenshot(&shot("lab-welcome-390x844.png"));
    phone.type_into("#lab-label", "phone");
    phone.click("#lab-start-button");
    phone.wait_for("document.body.dataset.mode === 'instructions'");
    phone.screenshot(&shot("lab-instructions-390x844.png"));
    std::thread::sleep(Duration::from_millis(400));
    phone.click("#lab-ack");
    wait_frame(&phone, 1);
    let fits = phone.script("return document.documentElement.scrollWidth <= window.innerWidth && document.getElementById('lab-frame').getBoundingClientRect().right <= window.innerWidth;");
    phone.screenshot(&shot("lab-trial-390x844.png"));
    assert_eq!(fits, json!(true), "the lab page fits a phone's width");

    // issue 45: the lab's admin page opens and closes the study, makes preview links, lists the
    // participants with exclude / include / delete and counts progress as the survey does
    let wide = super::browser::Driver::start_with(
        1440,
        900,
        json!({"mobileEmulation": {"deviceMetrics": {"width": 1440, "height": 900, "pixelRatio": 2, "touch": false}}}),
    );
    for (browser, size) in [(&driver, "1280x800"), (&phone, "390x844"), (&wide, "1440x900-dpr2")] {
        browser.go(&format!("{}/admin/login?token={}", server.base, server.admin_token));
        browser.go(&format!("{}/admin/lab/lab", server.base));
        browser.wait_visible("lab-participants");
        let counts = browser.text("#lab-counts");
        assert!(counts.starts_with("Started 2, finished 1 (50 %)"), "{counts}");
        for control in ["#toggle-open", "#preview", "tr[data-participant] button[data-action='delete']"] {
            browser.element(control);
        }
        browser.screenshot(&shot(&format!("admin-lab-{size}.png")));
        browser.script("document.getElementById('lab-participants').scrollIntoView(); return null;");
        browser.screenshot(&shot(&format!("admin-lab-participants-{size}.png")));
    }
    // closing from the page: the study then takes pilots only
    driver.click("#toggle-open");
    driver.wait_for(
        "document.getElementById('lab-state') && document.getElementById('lab-state').textContent.includes('Closed')",
    );
    let refused = client()
        .post(format!("{}/api/lab/lab/participants", server.base))
        .json(&json!({"label": "late"}))
        .send()
        .unwrap();
    assert_eq!(refused.status(), 403);
}

/// RFC 4180 records (quoted fields with doubled quotes, commas and newlines inside).
fn parse_csv(text: &str) -> Vec<Vec<String>> {
    let mut records = Vec::new();
    let (mut record, mut field, mut quoted) = (Vec::new(), String::new(), false);
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (true, '"') if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            (true, '"') => quoted = false,
            (true, c) => field.push(c),
            (false, '"') => quoted = true,
            (false, ',') => record.push(std::mem::take(&mut field)),
            (false, '\n') => {
                record.push(std::mem::take(&mut field));
                records.push(std::mem::take(&mut record));
            }
            (false, '\r') => {}
            (false, c) => field.push(c),
        }
    }
    if !field.is_empty() || !record.is_empty() {
        record.push(field);
        records.push(record);
    }
    records
}
