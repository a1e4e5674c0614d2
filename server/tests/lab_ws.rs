//! The live WebSocket session of a task study, driven by a WebSocket client over a real socket:
//! a complete distance trial, a complete placement trial and a contact trial, bad input at
//! every step (each answered with an error and changing nothing), resume with the token, the
//! durable rows, and the task CSV read back by the analysis crate; input hygiene (instructions
//! acknowledged, answers before the first frame is shown or before `min_response_ms` refused
//! with nothing stored, empty codes refused, resume after a dropped connection), counterbalancing
//! slots of abandoned participants given to the next, and `pace = "equal"` frame-time parity.
//! Runs on the GPU (lavapipe where there is none) at 96×72; skips with a note when no adapter
//! can be opened. On sqlite, or on PostgreSQL with `MRSTUDY_TEST_DATABASE=postgres`
//! (scripts/test.sh runs it both ways).

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use mrstudy_server::serve::{Prepared, prepare_on, start_lab};
use serde_json::{Value, json};
use sqlx::Row;
use tokio_tungstenite::tungstenite::Message;

#[path = "support/lab_study.rs"]
mod lab_study;
use lab_study::LabStudy;
mod support;
use support::test_database;

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// The WebSocket tests' lab study: conditions none and gi, seed 5, all three tasks.
fn study() -> String {
    LabStudy {
        tasks: &["kind = \"distance\"", "kind = \"placement\"\nstep_cm = 1", "kind = \"contact\""],
        ..LabStudy::default()
    }
    .toml()
}

enum Incoming {
    Json(Value),
    Binary(Vec<u8>),
}

async fn recv(socket: &mut Socket) -> Incoming {
    loop {
        let message = tokio::time::timeout(Duration::from_secs(60), socket.next())
            .await
            .expect("a message within 60 s")
            .expect("the socket is open")
            .expect("no socket error");
        match message {
            Message::Text(text) => return Incoming::Json(serde_json::from_str(text.as_str()).unwrap()),
            Message::Binary(bytes) => return Incoming::Binary(bytes.to_vec()),
            _ => continue,
        }
    }
}

async fn json_of(socket: &mut Socket, kind: &str) -> Value {
    match recv(socket).await {
        Incoming::Json(value) => {
            assert_eq!(value["type"], kind, "{value}");
            value
        }
        Incoming::Binary(_) => panic!("expected a {kind} message, got binary"),
    }
}

async fn send(socket: &mut Socket, value: Value) {
    socket.send(Message::Text(value.to_string().into())).await.unwrap();
}

/// Reads frames until one includes `inputs` keys, reporting each as shown; returns (meta, jpeg)
/// of that frame and how many frames came.
async fn frame_with_inputs(socket: &mut Socket, inputs: usize) -> (Value, Vec<u8>, usize) {
    let mut count = 0;
    loop {
        let meta = json_of(socket, "frame").await;
        let Incoming::Binary(bytes) = recv(socket).await else {
            panic!("the frame's binary message must follow its meta")
        };
        count += 1;
        let number = u32::from_be_bytes(bytes[..4].try_into().unwrap());
        assert_eq!(number as u64, meta["n"].as_u64().unwrap());
        assert_eq!(&bytes[4..6], &[0xFF, 0xD8], "a JPEG");
        assert_eq!(meta["bytes"].as_u64().unwrap() as usize, bytes.len() - 4);
        send(socket, json!({"type": "shown", "n": number})).await;
        if meta["inputs"].as_u64().unwrap() as usize == inputs {
            return (meta, bytes[4..].to_vec(), count);
        }
    }
}

/// Asks for the next trial, acknowledging its task's instructions when they come first; the
/// trial's message.
async fn next_trial(socket: &mut Socket) -> Value {
    send(socket, json!({"type": "ready"})).await;
    let mut message = recv(socket).await;
    if let Incoming::Json(value) = &message
        && value["type"] == "instructions"
    {
        send(socket, json!({"type": "acknowledge"})).await;
        message = recv(socket).await;
    }
    let Incoming::Json(trial) = message else { panic!("expected the trial") };
    trial
}

/// Sends `message` and expects an error naming `needle`.
async fn refused(socket: &mut Socket, message: Value, needle: &str) {
    send(socket, message).await;
    let error = json_of(socket, "error").await;
    assert!(error["message"].as_str().unwrap().contains(needle), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_websocket_client_runs_distance_placement_and_contact_trials() {
    let _alone = RENDERING.lock().await;
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    std::fs::write(studies.path().join("lab.toml"), study()).unwrap();
    let Prepared { state, tasks, .. } =
        prepare_on(&test_database(data_dir.path()).await, data_dir.path(), studies.path()).await.unwrap();
    assert_eq!(tasks.len(), 1);
    let (info, warnings) = start_lab(&state, tasks, data_dir.path()).await;
    if state.lab().is_none() {
        assert!(warnings.iter().any(|w| w.contains("GPU adapter")), "{warnings:?}");
        eprintln!("skipping: {warnings:?}");
        return;
    }
    let lines: Vec<&String> = info.iter().chain(&warnings).collect();
    eprintln!("{lines:#?}");
    assert!(lines.iter().all(|line| line.contains("frames/s")), "{lines:?}");
    // one line per study, and one per condition when the conditions' frame times differ by > 20 %
    let per_condition = lines.iter().filter(|line| line.contains("condition \"")).count();
    assert!(lines.len() == 1 || (lines.len() == 3 && per_condition == 2), "{lines:?}");
    assert_eq!(lines.len() == 3, lines[0].contains("confounded with lag"), "{lines:?}");
    // the photograph (PNG) and its radiance (EXR, for coherent conditions) were cached in the data dir
    assert!(std::fs::read_dir(data_dir.path().join("lab")).unwrap().count() == 2);

    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let storage = state.storage().clone();
    tokio::spawn(async move { axum::serve(listener, mrstudy_server::app(state)).await.unwrap() });
    let url = format!("ws://{addr}/api/lab/lab/ws");
    let (mut socket, _) = tokio_tungstenite::connect_async(&url).await.unwrap();

    // before a participant
    refused(&mut socket, json!({"type": "ready"}), "Start or resume").await;
    refused(&mut socket, json!({"type": "dance"}), "Unknown message type \"dance\"").await;
    refused(&mut socket, json!({"type": "start", "label": "x", "extra": 1}), "expected fields").await;
    send(&mut socket, json!({"type": "start", "label": "P01"})).await;
    let session = json_of(&mut socket, "session").await;
    let participant = session["participant"].as_str().unwrap().to_string();
    let token = session["token"].as_str().unwrap().to_string();
    assert_eq!(session["trials"], 6);
    assert_eq!(session["smoothing"], false);
    refused(&mut socket, json!({"type": "start", "label": "P02"}), "already runs a participant").await;

    // trial 1: distance, after its instructions are acknowledged
    send(&mut socket, json!({"type": "ready"})).await;
    let instructions = json_of(&mut socket, "instructions").await;
    assert_eq!((instructions["task"].as_str(), instructions["trial"].as_u64()), (Some("distance"), Some(1)));
    refused(&mut socket, json!({"type": "ready"}), "waiting to be acknowledged").await;
    send(&mut socket, json!({"type": "acknowledge"})).await;
    let trial = json_of(&mut socket, "trial").await;
    assert_eq!(trial["trial"], 1);
    assert_eq!(trial["kind"], "distance");
    let (first, _, _) = frame_with_inputs(&mut socket, 0).await;
    assert_eq!(first["trial"], 1);
    assert!(first["latency_ms"].is_null(), "no input yet: {first}");
    refused(&mut socket, json!({"type": "key", "key": "ArrowLeft"}), "typed answer").await;
    refused(&mut socket, json!({"type": "answer", "trial": 1}), "needs the answer in cm").await;
    refused(&mut socket, json!({"type": "answer", "trial": 1, "cm": -3}), "between 0 and 200").await;
    refused(&mut socket, json!({"type": "answer", "trial": 1, "cm": 1e9}), "between 0 and 200").await;
    refused(&mut socket, json!({"type": "answer", "trial": 2, "cm": 10}), "not the running trial").await;
    refused(&mut socket, json!({"type": "answer", "trial": 99, "cm": 10}), "no trial 99").await;
    refused(&mut socket, json!({"type": "ready"}), "still running").await;
    send(&mut socket, json!({"type": "answer", "trial": 1, "cm": 12.5})).await;
    let saved = json_of(&mut socket, "saved").await;
    assert_eq!(saved["answered"], 1);
    // durable before `saved`: the row is there, with the truth from the stored start
    let row = sqlx::query("SELECT * FROM task_trials WHERE participant = $1 AND trial = 1")
        .bind(&participant)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    let start: [f64; 3] = [row.get("start_x"), row.get("start_y"), row.get("start_z")];
    let truth = ((start[0]).powi(2) + (start[2]).powi(2)).sqrt() * 100.0;
    assert!((start[1] - 0.025).abs() < 1e-6, "the virtual cube stands on the table");
    assert_eq!(row.get::<f64, _>("answer_cm"), 12.5);
    assert!((row.get::<f64, _>("error_cm") - (12.5 - truth).abs()).abs() < 1e-9);
    assert!((row.get::<f64, _>("signed_error_cm") - (12.5 - truth)).abs() < 1e-9);
    let axes = [row.get::<f64, _>("error_x_cm"), row.get::<f64, _>("error_y_cm"), row.get::<f64, _>("error_z_cm")];
    assert!(((axes[0].powi(2) + axes[2].powi(2)).sqrt() - (12.5 - truth).abs()).abs() < 1e-9, "{axes:?}");
    assert!(row.get::<i64, _>("frames") >= 1);
    assert!(row.get::<f64, _>("completion_ms") > 0.0);
    // answering a finished trial changes nothing
    refused(&mut socket, json!({"type": "answer", "trial": 1, "cm": 20}), "already answered").await;
    let again: f64 = sqlx::query_scalar("SELECT answer_cm FROM task_trials WHERE participant = $1 AND trial = 1")
        .bind(&participant)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    assert_eq!(again, 12.5);

    // trial 2: distance under the second condition; then trial 3: placement
    send(&mut socket, json!({"type": "ready"})).await;
    let trial = json_of(&mut socket, "trial").await;
    assert_eq!(trial["trial"], 2);
    frame_with_inputs(&mut socket, 0).await;
    send(&mut socket, json!({"type": "answer", "trial": 2, "cm": 10})).await;
    json_of(&mut socket, "saved").await;
    send(&mut socket, json!({"type": "ready"})).await;
    json_of(&mut socket, "instructions").await;
    send(&mut socket, json!({"type": "acknowledge"})).await;
    let trial = json_of(&mut socket, "trial").await;
    assert_eq!(trial["kind"], "placement");
    let (_, before, _) = frame_with_inputs(&mut socket, 0).await;
    refused(&mut socket, json!({"type": "key", "key": "PageUp"}), "does not move the cube").await;
    refused(&mut socket, json!({"type": "key", "key": "ArrowLeft", "t": "soon"}), "expected fields").await;
    // ten keys in a burst: coalesced into fewer frames, the last showing all of them
    let keys = [
        "ArrowLeft",
        "ArrowLeft",
        "ArrowLeft",
        "ArrowUp",
        "ArrowUp",
        "ArrowRight",
        "ArrowDown",
        "ArrowLeft",
        "ArrowLeft",
        "ArrowUp",
    ];
    for (index, key) in keys.iter().enumerate() {
        send(&mut socket, json!({"type": "key", "key": key, "t": index as f64 * 5.0})).await;
    }
    let (last, after, frames) = frame_with_inputs(&mut socket, keys.len()).await;
    assert!(frames < keys.len(), "keys arriving during a frame are coalesced: {frames} frames for {} keys", keys.len());
    assert!(last["latency_ms"].as_f64().unwrap() > 0.0);
    assert_ne!(before, after, "the frame changes when the cube moves");
    refused(&mut socket, json!({"type": "answer", "trial": 3, "cm": 4}), "without cm").await;
    send(&mut socket, json!({"type": "answer", "trial": 3})).await;
    let saved = json_of(&mut socket, "saved").await;
    assert_eq!(saved["answered"], 3);
    let row = sqlx::query("SELECT * FROM task_trials WHERE participant = $1 AND trial = 3")
        .bind(&participant)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    let start = [row.get::<f64, _>("start_x"), row.get::<f64, _>("start_z")];
    // 1 cm steps: x −1 −1 −1 +1 −1 −1 = −4 cm, z −1 −1 +1 −1 = −2 cm
    let final_position = [row.get::<f64, _>("final_x"), row.get::<f64, _>("final_z")];
    assert!((final_position[0] - (start[0] - 0.04)).abs() < 1e-9, "{final_position:?} from {start:?}");
    assert!((final_position[1] - (start[1] - 0.02)).abs() < 1e-9);
    assert!(
        (row.get::<f64, _>("error_x_cm") - final_position[0] * 100.0).abs() < 1e-6,
        "the target is the real cube at x = 0"
    );
    let total = (row.get::<f64, _>("error_x_cm").powi(2) + row.get::<f64, _>("error_z_cm").powi(2)).sqrt();
    assert!((row.get::<f64, _>("error_cm") - total).abs() < 1e-9);
    let log: Value = serde_json::from_str(&row.get::<String, _>("key_log")).unwrap();
    assert_eq!(log.as_array().unwrap().len(), keys.len());
    assert_eq!(log[0]["key"], "ArrowLeft");
    assert_eq!(log[9]["client_t_ms"], 45.0);
    assert!(row.get::<Option<f64>, _>("latency_ms_mean").unwrap() > 0.0);
    // temporal smoothing reuses the previous frame within a trial, where there is indirect light
    let smoothed = row.get::<String, _>("condition") == "gi" && row.get::<i64, _>("frames") > 1;
    assert_eq!(row.get::<i64, _>("smoothing"), smoothed as i64, "condition {}", row.get::<String, _>("condition"));

    // a second connection resumes the participant with the token (a wrong token is refused)
    drop(socket);
    let (mut socket, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
    refused(
        &mut socket,
        json!({"type": "resume", "participant": participant, "token": "0".repeat(64)}),
        "No participant",
    )
    .await;
    send(&mut socket, json!({"type": "resume", "participant": participant, "token": token})).await;
    let session = json_of(&mut socket, "session").await;
    assert_eq!(session["answered"], 3);
    assert!(session["token"].is_null());
    refused(&mut socket, json!({"type": "answer", "trial": 3}), "already answered").await;
    // trials 4–6; contact uses up and down only
    send(&mut socket, json!({"type": "ready"})).await;
    let trial = json_of(&mut socket, "trial").await;
    assert_eq!(trial["trial"], 4);
    frame_with_inputs(&mut socket, 0).await;
    // answer and start the next trial while a frame is still rendering: the stale frame is
    // dropped and the next trial still gets its first frame
    send(&mut socket, json!({"type": "key", "key": "ArrowRight"})).await;
    send(&mut socket, json!({"type": "answer", "trial": 4})).await;
    send(&mut socket, json!({"type": "ready"})).await;
    let mut saw = Vec::new();
    loop {
        match recv(&mut socket).await {
            Incoming::Json(value) if value["type"] == "instructions" => {
                saw.push("instructions");
                send(&mut socket, json!({"type": "acknowledge"})).await;
            }
            Incoming::Json(value) if value["type"] == "trial" => {
                saw.push("trial");
                break;
            }
            Incoming::Json(value) => saw.push(if value["type"] == "saved" { "saved" } else { "frame" }),
            Incoming::Binary(_) => {}
        }
    }
    assert!(saw.contains(&"saved") && saw.contains(&"instructions"), "{saw:?}");
    for number in 5..=6 {
        if number == 6 {
            send(&mut socket, json!({"type": "ready"})).await;
            let trial = json_of(&mut socket, "trial").await;
            assert_eq!(trial["kind"], "contact");
        }
        let (meta, _, _) = frame_with_inputs(&mut socket, 0).await;
        assert_eq!(meta["trial"], number);
        refused(&mut socket, json!({"type": "key", "key": "ArrowLeft"}), "ArrowUp and ArrowDown").await;
        send(&mut socket, json!({"type": "key", "key": "ArrowDown"})).await;
        frame_with_inputs(&mut socket, 1).await;
        send(&mut socket, json!({"type": "answer", "trial": number})).await;
        let saved = json_of(&mut socket, "saved").await;
        assert_eq!(saved["completed"], number == 6);
        let row = sqlx::query("SELECT * FROM task_trials WHERE participant = $1 AND trial = $2")
            .bind(&participant)
            .bind(number)
            .fetch_one(&storage.read)
            .await
            .unwrap();
        let height = row.get::<f64, _>("start_y") - 0.0025 - 0.025;
        assert!(
            (row.get::<f64, _>("signed_error_cm") - height * 100.0).abs() < 1e-6,
            "height left above the table after one 0.25 cm step down"
        );
        assert_eq!(row.get::<f64, _>("error_x_cm"), 0.0);
    }
    json_of(&mut socket, "done").await;
    refused(&mut socket, json!({"type": "answer", "trial": 6}), "already answered").await;
    let answered: i64 = sqlx::query_scalar("SELECT answered FROM task_participants WHERE id = $1")
        .bind(&participant)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    assert_eq!(answered, 6);

    // the task CSV is what the analysis reads
    let csv = mrstudy_server::task::results::task_csv(&storage.read, "lab").await.unwrap();
    assert!(csv.starts_with("participant,task,measure,condition,value,trials,label\n"), "{csv}");
    let analysis = mrstudy_analysis::task::analyze_task_csv(&csv, "lab-task.csv").unwrap();
    assert_eq!(analysis.grouped_by, vec!["task", "measure"]);
    let labels: Vec<String> = analysis.measures.iter().map(|m| m.group.label()).collect();
    assert!(labels.contains(&"task distance, measure error_cm".to_string()), "{labels:?}");
    assert!(labels.contains(&"task contact, measure signed_error_cm".to_string()), "{labels:?}");
    let trials = mrstudy_server::task::results::trials_csv(&storage.read, "lab").await.unwrap();
    assert_eq!(trials.lines().count(), 7, "{trials}");
}

/// Serves `study` on a loopback socket: (WebSocket URL, storage, the served study), or None
/// (with a note) when no GPU adapter opens.
/// The tests of this file render on the one (software) adapter; run one at a time so that the
/// frame times one measures are not another's load (the pacing test compares them).
static RENDERING: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

async fn serve(
    study: &str,
) -> Option<(String, mrstudy_server::storage::Storage, mrstudy_server::AppState, tempfile::TempDir)> {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    std::fs::write(studies.path().join("lab.toml"), study).unwrap();
    let Prepared { state, tasks, .. } =
        prepare_on(&test_database(data_dir.path()).await, data_dir.path(), studies.path()).await.unwrap();
    let (info, warnings) = start_lab(&state, tasks, data_dir.path()).await;
    if state.lab().is_none() {
        assert!(warnings.iter().any(|w| w.contains("GPU adapter")), "{warnings:?}");
        eprintln!("skipping: {warnings:?}");
        return None;
    }
    for line in info.iter().chain(&warnings) {
        eprintln!("{line}");
    }
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let storage = state.storage().clone();
    let app_state = state.clone();
    tokio::spawn(async move { axum::serve(listener, mrstudy_server::app(state)).await.unwrap() });
    Some((format!("ws://{addr}/api/lab/lab/ws"), storage, app_state, data_dir))
}

async fn connect(url: &str) -> Socket {
    tokio_tungstenite::connect_async(url).await.unwrap().0
}

/// The next frame's meta and number, without reporting it shown.
async fn next_frame(socket: &mut Socket) -> (Value, u32) {
    let meta = json_of(socket, "frame").await;
    let Incoming::Binary(bytes) = recv(socket).await else { panic!("the frame's binary message must follow its meta") };
    (meta, u32::from_be_bytes(bytes[..4].try_into().unwrap()))
}

/// A lab study with the default-like `min_response_ms` (400 ms) and one placement task.
fn hygiene_study() -> String {
    LabStudy {
        seed: 9,
        min_response_ms: Some(400),
        tasks: &["kind = \"placement\"\nstep_cm = 1"],
        ..LabStudy::default()
    }
    .toml()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn answers_before_the_first_frame_is_shown_or_before_min_response_ms_are_refused_and_nothing_is_stored() {
    let _alone = RENDERING.lock().await;
    let Some((url, storage, _state, _data_dir)) = serve(&hygiene_study()).await else { return };
    let mut socket = connect(&url).await;
    // an empty participant code is refused with one sentence, and nobody is stored
    refused(&mut socket, json!({"type": "start", "label": ""}), "The participant code is empty").await;
    refused(&mut socket, json!({"type": "start", "label": "   "}), "The participant code is empty").await;
    let participants: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM task_participants").fetch_one(&storage.read).await.unwrap();
    assert_eq!(participants, 0);
    send(&mut socket, json!({"type": "start", "label": "H1"})).await;
    let session = json_of(&mut socket, "session").await;
    assert_eq!(session["min_response_ms"], 400);
    let participant = session["participant"].as_str().unwrap().to_string();
    let token = session["token"].as_str().unwrap().to_string();

    // the task's instructions stay until acknowledged, and not sooner than min_response_ms
    send(&mut socket, json!({"type": "ready"})).await;
    json_of(&mut socket, "instructions").await;
    refused(&mut socket, json!({"type": "acknowledge"}), "sooner than the study's minimum of 400 ms").await;
    refused(&mut socket, json!({"type": "answer", "trial": 1}), "Trial 1 has not started").await;
    tokio::time::sleep(Duration::from_millis(450)).await;
    send(&mut socket, json!({"type": "acknowledge"})).await;
    json_of(&mut socket, "trial").await;
    refused(&mut socket, json!({"type": "acknowledge"}), "no instructions to acknowledge").await;
    // before the first frame was shown
    refused(&mut socket, json!({"type": "answer", "trial": 1}), "has not been shown yet").await;
    let (meta, number) = next_frame(&mut socket).await;
    assert_eq!(meta["trial"], 1);
    refused(&mut socket, json!({"type": "answer", "trial": 1}), "has not been shown yet").await;
    refused(&mut socket, json!({"type": "shown", "n": number + 100}), "was not sent on this connection").await;
    send(&mut socket, json!({"type": "shown", "n": number})).await;
    // a burst of answers right after the frame appeared (a held Enter): every one refused
    for _ in 0..5 {
        send(&mut socket, json!({"type": "answer", "trial": 1})).await;
    }
    for _ in 0..5 {
        let error = json_of(&mut socket, "error").await;
        assert!(error["message"].as_str().unwrap().contains("sooner than the study's minimum of 400 ms"), "{error}");
    }
    let stored: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM task_trials WHERE participant = $1 AND answered_at IS NOT NULL")
            .bind(&participant)
            .fetch_one(&storage.read)
            .await
            .unwrap();
    assert_eq!(stored, 0, "refused answers store nothing");
    let answered: i64 = sqlx::query_scalar("SELECT answered FROM task_participants WHERE id = $1")
        .bind(&participant)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    assert_eq!(answered, 0);
    tokio::time::sleep(Duration::from_millis(450)).await;
    send(&mut socket, json!({"type": "answer", "trial": 1})).await;
    let saved = json_of(&mut socket, "saved").await;
    assert_eq!(saved["frames_shown"], 1);
    let row = sqlx::query("SELECT * FROM task_trials WHERE participant = $1 AND trial = 1")
        .bind(&participant)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    assert_eq!(row.get::<i64, _>("frames_shown"), 1);
    assert!(row.get::<f64, _>("completion_ms") >= 400.0, "counted from the first frame shown");
    assert!(row.get::<Option<String>, _>("shown_at").is_some());
    assert!(row.get::<f64, _>("shown_frame_ms_mean") > 0.0);
    assert!(row.get::<Option<f64>, _>("paced_ms").is_none(), "not paced");

    // the tab closes during trial 2; a new connection resumes at trial 2, the next unanswered
    send(&mut socket, json!({"type": "ready"})).await;
    assert_eq!(json_of(&mut socket, "trial").await["trial"], 2, "not the task's first trial: no instructions");
    next_frame(&mut socket).await;
    drop(socket);
    let mut socket = connect(&url).await;
    send(&mut socket, json!({"type": "resume", "participant": participant, "token": token})).await;
    let session = json_of(&mut socket, "session").await;
    assert_eq!(session["answered"], 1);
    send(&mut socket, json!({"type": "ready"})).await;
    let trial = json_of(&mut socket, "trial").await;
    assert_eq!(trial["trial"], 2);
    frame_with_inputs(&mut socket, 0).await;
    tokio::time::sleep(Duration::from_millis(450)).await;
    send(&mut socket, json!({"type": "answer", "trial": 2})).await;
    assert_eq!(json_of(&mut socket, "saved").await["completed"], true);
    json_of(&mut socket, "done").await;
    let rows: Vec<(i64, i64)> =
        sqlx::query_as("SELECT trial, frames_shown FROM task_trials WHERE participant = $1 ORDER BY trial")
            .bind(&participant)
            .fetch_all(&storage.read)
            .await
            .unwrap();
    assert_eq!(rows, vec![(1, 1), (2, 1)]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_abandoned_participants_counterbalancing_slot_goes_to_the_next_participant() {
    let _alone = RENDERING.lock().await;
    // 0.005 minutes = 300 ms of inactivity
    let study = hygiene_study()
        .replace("min_response_ms = 400", "min_response_ms = 0\nabandon_after_minutes = 0.005")
        .replace("conditions = [\"none\", \"gi\"]", "conditions = [\"none\", \"shadows\", \"gi\"]");
    let Some((url, storage, state, _data_dir)) = serve(&study).await else { return };
    async fn join(url: &str, label: &str) -> (Socket, String, String) {
        let mut socket = connect(url).await;
        send(&mut socket, json!({"type": "start", "label": label})).await;
        let session = json_of(&mut socket, "session").await;
        (socket, session["participant"].as_str().unwrap().to_string(), session["token"].as_str().unwrap().to_string())
    }
    let (socket_a, a, token_a) = join(&url, "A").await;
    let (socket_b, b, token_b) = join(&url, "B").await;
    drop(socket_a);
    drop(socket_b);
    tokio::time::sleep(Duration::from_millis(600)).await;
    // B comes back (its slot stays); A does not
    let mut socket = connect(&url).await;
    send(&mut socket, json!({"type": "resume", "participant": b, "token": token_b})).await;
    json_of(&mut socket, "session").await;
    let (_c_socket, c, _) = join(&url, "C").await;
    let (_d_socket, d, _) = join(&url, "D").await;
    type Row = (String, i64, i64, String, Option<String>, Option<String>);
    let rows: Vec<Row> =
        sqlx::query_as("SELECT id, ordinal, slot, condition_order, abandoned_at, slot_taken_by FROM task_participants ORDER BY ordinal").fetch_all(&storage.read).await.unwrap();
    let ids: Vec<&str> = rows.iter().map(|row| row.0.as_str()).collect();
    assert_eq!(ids, vec![a.as_str(), b.as_str(), c.as_str(), d.as_str()]);
    let ordinals: Vec<i64> = rows.iter().map(|row| row.1).collect();
    assert_eq!(ordinals, vec![0, 1, 2, 3], "ordinals stay unique");
    let slots: Vec<i64> = rows.iter().map(|row| row.2).collect();
    assert_eq!(slots, vec![0, 1, 0, 2], "C takes A's slot, D the next unused one");
    assert_eq!(rows[2].3, rows[0].3, "C gets A's condition order");
    assert_ne!(rows[3].3, rows[0].3);
    assert!(
        rows[0].4.is_some() && rows[0].5.as_deref() == Some(c.as_str()),
        "A is abandoned, its slot taken by C: {:?}",
        rows[0]
    );
    assert!(rows[1].4.is_none() && rows[2].4.is_none() && rows[3].4.is_none());
    // A cannot come back into a slot that is now C's
    let mut socket = connect(&url).await;
    refused(&mut socket, json!({"type": "resume", "participant": a, "token": token_a}), "given to another participant")
        .await;
    // the admin report says so
    let report = mrstudy_server::task::results::report(&state, "lab").await.unwrap();
    let states: Vec<(i64, bool)> = report.participants.iter().map(|p| (p.slot, p.abandoned)).collect();
    assert_eq!(states, vec![(0, true), (1, false), (0, false), (2, false)]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_pace_equal_every_conditions_frames_reach_the_participant_after_the_same_time() {
    let _alone = RENDERING.lock().await;
    let study = hygiene_study()
        .replace("min_response_ms = 400", "min_response_ms = 0\npace = \"equal\"")
        .replace("trials_per_condition = 1", "trials_per_condition = 3");
    let Some((url, storage, state, _data_dir)) = serve(&study).await else { return };
    let startup: Vec<(String, f64)> =
        sqlx::query_as("SELECT condition, median_ms FROM task_frame_times ORDER BY condition")
            .fetch_all(&storage.read)
            .await
            .unwrap();
    eprintln!("start-up frame times (render + encode, unpaced): {startup:?}");
    assert_eq!(startup.len(), 2);
    let mut socket = connect(&url).await;
    send(&mut socket, json!({"type": "start", "label": "pace"})).await;
    let session = json_of(&mut socket, "session").await;
    assert_eq!(session["pace"], "equal");
    let trials = session["trials"].as_u64().unwrap();
    for number in 1..=trials {
        let trial = next_trial(&mut socket).await;
        assert_eq!(trial["trial"], number);
        frame_with_inputs(&mut socket, 0).await;
        // keys one at a time, each waiting for its frame: every frame is a paced frame
        for keys in 1..=4 {
            send(&mut socket, json!({"type": "key", "key": "ArrowLeft"})).await;
            frame_with_inputs(&mut socket, keys).await;
        }
        send(&mut socket, json!({"type": "answer", "trial": number})).await;
        json_of(&mut socket, "saved").await;
    }
    json_of(&mut socket, "done").await;
    let rows: Vec<(String, f64, f64, f64, i64)> =
        sqlx::query_as("SELECT condition, AVG(shown_frame_ms_mean), AVG(frame_ms_mean), AVG(paced_ms), SUM(frames) FROM task_trials GROUP BY condition ORDER BY condition")
            .fetch_all(&storage.read)
            .await
            .unwrap();
    eprintln!("per condition: (condition, shown frame ms, render + encode ms, paced to ms, frames) {rows:?}");
    assert_eq!(rows.len(), 2);
    let shown: Vec<f64> = rows.iter().map(|row| row.1).collect();
    let (slowest, fastest) =
        (shown.iter().copied().fold(0.0, f64::max), shown.iter().copied().fold(f64::INFINITY, f64::min));
    assert!(
        slowest / fastest - 1.0 < PACE_PARITY,
        "shown frame times differ by {:.1} %: {rows:?}",
        (slowest / fastest - 1.0) * 100.0
    );
    for row in &rows {
        assert!(row.1 >= row.2, "a frame is never sent before it is rendered: {row:?}");
        assert!(row.1 >= 0.95 * row.3, "every frame is held to about the pace: {row:?}");
    }
    let report = mrstudy_server::task::results::report(&state, "lab").await.unwrap();
    assert!(report.pace_ms.is_some() && report.frame_times.len() == 2);
}

/// Issue 18: a task study may name a coherent method as a condition (`dit-low` beside DIR's
/// `none`): the start-up captures the real scene and measures its frame time, the photograph's
/// radiance is cached beside the photograph, a participant's trials in it are rendered live
/// (each key moves the cube, and the frame with it) and stored under the method's name.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_coherent_method_runs_live_as_a_condition_and_its_frames_follow_the_cube() {
    let _alone = RENDERING.lock().await;
    let study = LabStudy {
        seed: 11,
        conditions: &["none", "dit-low"],
        tasks: &["kind = \"placement\"\nstep_cm = 2"],
        ..LabStudy::default()
    }
    .toml();
    let Some((url, storage, _state, data_dir)) = serve(&study).await else { return };
    let startup: Vec<(String, f64)> =
        sqlx::query_as("SELECT condition, median_ms FROM task_frame_times ORDER BY condition")
            .fetch_all(&storage.read)
            .await
            .unwrap();
    let names: Vec<&str> = startup.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names, ["dit-low", "none"], "{startup:?}");
    assert!(startup.iter().all(|(_, ms)| ms.is_finite() && *ms > 0.0), "{startup:?}");
    let mut cached: Vec<String> = std::fs::read_dir(data_dir.path().join("lab"))
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().rsplit('.').next().unwrap().to_string())
        .collect();
    cached.sort();
    assert_eq!(cached, ["exr", "png"], "the photograph and its radiance are cached");

    let mut socket = connect(&url).await;
    send(&mut socket, json!({"type": "start", "label": "coherent"})).await;
    let session = json_of(&mut socket, "session").await;
    let trials = session["trials"].as_u64().unwrap();
    assert_eq!(trials, 2);
    for number in 1..=trials {
        let trial = next_trial(&mut socket).await;
        let (_, first, _) = frame_with_inputs(&mut socket, 0).await;
        let mut last = Vec::new();
        for keys in 1..=3 {
            send(&mut socket, json!({"type": "key", "key": "ArrowRight"})).await;
            last = frame_with_inputs(&mut socket, keys).await.1;
        }
        let decode = |jpeg: &[u8]| image::load_from_memory(jpeg).unwrap().into_rgb8();
        let (first, last) = (decode(&first), decode(&last));
        assert_eq!((first.width(), first.height()), (96, 72));
        let changed = first
            .pixels()
            .zip(last.pixels())
            .filter(|(a, b)| a.0.iter().zip(b.0).any(|(x, y)| x.abs_diff(y) > 24))
            .count();
        assert!(changed > 30, "trial {number}: the cube moved 6 cm and {changed} pixels changed ({trial})");
        send(&mut socket, json!({"type": "answer", "trial": number})).await;
        json_of(&mut socket, "saved").await;
    }
    json_of(&mut socket, "done").await;
    let mut stored: Vec<(String, i64)> =
        sqlx::query_as("SELECT condition, frames FROM task_trials WHERE answered_at IS NOT NULL ORDER BY condition")
            .fetch_all(&storage.read)
            .await
            .unwrap();
    stored.sort();
    assert_eq!(stored.iter().map(|row| row.0.as_str()).collect::<Vec<_>>(), ["dit-low", "none"]);
    assert!(stored.iter().all(|row| row.1 >= 4), "{stored:?}");
}

/// With pace = "equal", the largest relative difference allowed between the conditions' mean
/// shown frame times.
const PACE_PARITY: f64 = 0.10;

/// Issue 16: an upgrade from another site's page is refused; an oversized message gets an
/// `error` before the connection is closed (it used to be dropped without a word).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_foreign_origin_is_refused_and_an_oversized_message_is_answered_before_closing() {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let _alone = RENDERING.lock().await;
    let Some((url, _storage, _state, _data_dir)) = serve(&hygiene_study()).await else { return };
    let mut request = url.as_str().into_client_request().unwrap();
    request.headers_mut().insert("origin", "https://evil.example".parse().unwrap());
    match tokio_tungstenite::connect_async(request).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => assert_eq!(response.status(), 403),
        other => panic!("a foreign origin must be refused, got {:?}", other.map(|(_, response)| response.status())),
    }
    // the server's own page is welcome
    let host = url.trim_start_matches("ws://").split('/').next().unwrap().to_string();
    let mut request = url.as_str().into_client_request().unwrap();
    request.headers_mut().insert("origin", format!("http://{host}").parse().unwrap());
    let (mut socket, _) = tokio_tungstenite::connect_async(request).await.unwrap();
    send(&mut socket, json!({"type": "start", "label": "x".repeat(5000)})).await;
    let error = json_of(&mut socket, "error").await;
    assert!(error["message"].as_str().unwrap().contains("more than the limit of 4096"), "{error}");
    let closed = tokio::time::timeout(Duration::from_secs(10), socket.next()).await.unwrap();
    assert!(matches!(closed, None | Some(Ok(Message::Close(_))) | Some(Err(_))), "{closed:?}");
}

/// Issue 16: a session that sends nothing for the lab's idle timeout is closed with an `error`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idle_session_is_closed_with_an_error_after_the_idle_timeout() {
    let _alone = RENDERING.lock().await;
    let Some((url, _storage, state, _data_dir)) = serve(&hygiene_study()).await else { return };
    state.lab().unwrap().set_idle_timeout(Duration::from_millis(500));
    let mut socket = connect(&url).await;
    let started = std::time::Instant::now();
    let error = json_of(&mut socket, "error").await;
    assert!(error["message"].as_str().unwrap().contains("closed after 0.5 s without a message"), "{error}");
    assert!(started.elapsed() >= Duration::from_millis(450), "{:?}", started.elapsed());
    let closed = tokio::time::timeout(Duration::from_secs(10), socket.next()).await.unwrap();
    assert!(matches!(closed, None | Some(Ok(Message::Close(_))) | Some(Err(_))), "{closed:?}");
}
