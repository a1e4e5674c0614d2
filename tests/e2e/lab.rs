//! Task studies through the binary: `mrstudy serve` with the shipped studies and no usable
//! adapter (one warning line, everything else served), and a small lab study run over the
//! WebSocket by three participants, exported with `mrstudy export --format task` and analysed by
//! `mrstudy analyze` (Friedman tests per task and measure).

use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

use super::serve::{Server, binary, client, copy_demo_study, export, repo_studies_dir};

/// A small, fast task study: 96×72 frames, one trial per condition, no practice.
pub const SMALL_STUDY: &str = r#"
slug = "lab"
title = "Cubes"
kind = "task"
[texts]
welcome = "Hello."
instructions = "Do the tasks."
[design]
conditions = ["none", "shadows", "gi"]
trials_per_condition = 1
practice = 0
seed = 11
[render]
size = [96, 72]
photo_spp = 2
vpls = 16
shadow_map_size = 128
env_lights = 4
[[tasks]]
kind = "distance"
[[tasks]]
kind = "placement"
step_cm = 1
"#;

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
    send(&mut socket, json!({"type": "start", "label": label}));
    let session = until(&mut socket, "session");
    let trials = session["trials"].as_u64().unwrap();
    for _ in 0..trials {
        send(&mut socket, json!({"type": "ready"}));
        let trial = until(&mut socket, "trial");
        until(&mut socket, "frame");
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
    let server = Server::try_start_with_env(data_dir.path(), "127.0.0.1:0", studies.path(), &[("MRSTUDY_ADAPTER", "no-such-kind")], Duration::from_secs(60)).unwrap();
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
    assert!(line.starts_with("warning: task study \"lab-task\" not served") && line.contains("GPU adapter") && line.contains("no-such-kind"), "{line}");
    // the web survey is served, the lab page is not
    let http = client();
    assert_eq!(http.get(format!("{}/studies/shadows-demo", server.base)).send().unwrap().status(), 200);
    assert_eq!(http.get(format!("{}/lab/lab-task", server.base)).send().unwrap().status(), 404);
}

#[test]
fn three_participants_run_the_lab_study_and_mrstudy_analyze_reads_the_task_export() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    std::fs::write(studies.path().join("lab.toml"), SMALL_STUDY).unwrap();
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
    assert!(page.contains("frames/s") && page.contains("Friedman") && page.contains("task distance, measure error_cm"), "{page}");
    assert!(page.contains("Targets are drawn within the camera's view"), "{page}");
    let overview = client().get(format!("{}/admin", server.base)).bearer_auth(&server.admin_token).send().unwrap().text().unwrap();
    assert!(overview.contains("/admin/lab/lab") && overview.contains("Lab task studies"), "{overview}");
    let csv = export(data_dir.path(), "lab", "task");
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "participant,task,measure,condition,value,trials,label");
    // 3 participants × (distance: 5 measures + placement: 4 measures) × 3 conditions
    assert_eq!(rows.len() - 1, 3 * (5 + 4) * 3, "{csv}");
    let file = data_dir.path().join("task.csv");
    std::fs::write(&file, &csv).unwrap();
    let output = std::process::Command::new(binary()).args(["analyze", "--trials"]).arg(&file).args(["--format", "json"]).output().unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let analysis: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(analysis["grouped_by"], json!(["task", "measure"]));
    let measures = analysis["measures"].as_array().unwrap();
    assert_eq!(measures.len(), 9);
    let distance_error = measures.iter().find(|m| m["group"] == json!({"task": "distance", "measure": "error_cm"})).unwrap();
    assert_eq!(distance_error["friedman"]["participants"], 3);
    assert_eq!(distance_error["friedman"]["conditions"], 3);
    let trials = export(data_dir.path(), "lab", "task-trials");
    assert_eq!(trials.lines().count(), 1 + 3 * 6);
}
