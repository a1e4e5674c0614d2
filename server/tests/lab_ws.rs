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

/// `POST path` with a JSON body over a real socket to `http` (a `ws://host:port/…` URL's host):
/// (status, JSON answer).
async fn post_json(ws_url: &str, path: &str, body: Value) -> (u16, Value) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let host = ws_url.trim_start_matches("ws://").split('/').next().unwrap().to_string();
    let mut stream = tokio::net::TcpStream::connect(&host).await.unwrap();
    let body = body.to_string();
    let request = format!(
        "POST {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream.write_all(request.as_bytes()).await.unwrap();
    let mut answer = Vec::new();
    tokio::time::timeout(Duration::from_secs(30), stream.read_to_end(&mut answer)).await.unwrap().unwrap();
    let answer = String::from_utf8(answer).unwrap();
    let (head, body) = answer.split_once("\r\n\r\n").unwrap();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    (status, serde_json::from_str(body).unwrap_or_else(|_| panic!("not JSON: {answer}")))
}

/// Creates a lab participant over HTTP (`POST /api/lab/lab/participants`): (id, token).
async fn join_http(ws_url: &str, label: &str) -> (String, String) {
    let (status, joined) = post_json(ws_url, "/api/lab/lab/participants", json!({"label": label})).await;
    assert_eq!(status, 201, "{joined}");
    (joined["participant"].as_str().unwrap().to_string(), joined["token"].as_str().unwrap().to_string())
}

/// Creates a participant over HTTP and starts it on `socket`: (id, token, the session message).
async fn join_and_start(socket: &mut Socket, ws_url: &str, label: &str) -> (String, String, Value) {
    let (participant, token) = join_http(ws_url, label).await;
    send(socket, json!({"type": "start", "participant": participant, "token": token})).await;
    let session = json_of(socket, "session").await;
    assert_eq!(session["participant"], participant.as_str());
    (participant, token, session)
}

/// Serves `router` on a loopback socket, each request carrying its peer address as `serve`
/// gives it (so the limits per client address apply): the address.
async fn listen(state: mrstudy_server::AppState) -> std::net::SocketAddr {
    use axum::extract::{ConnectInfo, Request};
    use axum::middleware::Next;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    if let Some(lab) = state.lab() {
        lab.set_origins(vec![format!("http://{addr}")]);
    }
    let router = mrstudy_server::app(state).layer(axum::middleware::from_fn(
        |ConnectInfo(peer): ConnectInfo<std::net::SocketAddr>, mut request: Request, next: Next| async move {
            request.extensions_mut().insert(mrstudy_server::limits::ClientAddr(peer.ip()));
            next.run(request).await
        },
    ));
    tokio::spawn(async move {
        axum::serve(listener, router.into_make_service_with_connect_info::<std::net::SocketAddr>()).await.unwrap()
    });
    addr
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

    let storage = state.storage().clone();
    let addr = listen(state).await;
    let url = format!("ws://{addr}/api/lab/lab/ws");
    let (mut socket, _) = tokio_tungstenite::connect_async(&url).await.unwrap();

    // before a participant
    refused(&mut socket, json!({"type": "ready"}), "Start or resume").await;
    refused(&mut socket, json!({"type": "dance"}), "Unknown message type \"dance\"").await;
    refused(&mut socket, json!({"type": "start", "label": "x", "extra": 1}), "expected fields").await;
    let (participant, token, session) = join_and_start(&mut socket, &url, "P01").await;
    assert_eq!(session["trials"], 6);
    assert_eq!(session["smoothing"], false);
    assert!(session["token"].is_null(), "the token came over HTTP, not again over the socket");
    let (other, other_token) = join_http(&url, "P02").await;
    refused(
        &mut socket,
        json!({"type": "start", "participant": other, "token": other_token}),
        "already runs a participant",
    )
    .await;

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
    let csv = mrstudy_server::lab::results::task_csv(&storage.read, "lab").await.unwrap();
    assert!(csv.starts_with("participant,task,measure,condition,value,trials,label\n"), "{csv}");
    let analysis = mrstudy_analysis::task::analyze_task_csv(&csv, "lab-task.csv").unwrap();
    assert_eq!(analysis.grouped_by, vec!["task", "measure"]);
    let labels: Vec<String> = analysis.measures.iter().map(|m| m.group.label()).collect();
    assert!(labels.contains(&"task distance, measure error_cm".to_string()), "{labels:?}");
    assert!(labels.contains(&"task contact, measure signed_error_cm".to_string()), "{labels:?}");
    let trials = mrstudy_server::lab::results::trials_csv(&storage.read, "lab").await.unwrap();
    assert_eq!(trials.lines().count(), 7, "{trials}");
}

/// Serves `study` on a loopback socket: (WebSocket URL, storage, the served study), or None
/// (with a note) when no GPU adapter opens.
/// The tests of this file render on the one (software) adapter; run one at a time so that the
/// frame times one measures are not another's load (the pacing test compares them).
static RENDERING: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

type Served = (String, mrstudy_server::storage::Storage, mrstudy_server::AppState, tempfile::TempDir, String);

/// Serves `study` (see [`listen`]): (WebSocket URL, storage, state, data directory, admin token),
/// or None (with a note) when no GPU adapter opens.
async fn serve(study: &str) -> Option<Served> {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    std::fs::write(studies.path().join("lab.toml"), study).unwrap();
    let Prepared { state, tasks, admin_token, .. } =
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
    let storage = state.storage().clone();
    let app_state = state.clone();
    let addr = listen(state).await;
    Some((format!("ws://{addr}/api/lab/lab/ws"), storage, app_state, data_dir, admin_token))
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
    let Some((url, storage, _state, _data_dir, _)) = serve(&hygiene_study()).await else { return };
    let mut socket = connect(&url).await;
    // an empty participant code is refused with one sentence, and nobody is stored
    for label in ["", "   "] {
        let (status, refusal) = post_json(&url, "/api/lab/lab/participants", json!({"label": label})).await;
        assert_eq!(status, 422, "{refusal}");
        assert!(refusal["error"].as_str().unwrap().contains("The participant code is empty"), "{refusal}");
    }
    let participants: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM task_participants").fetch_one(&storage.read).await.unwrap();
    assert_eq!(participants, 0);
    let (participant, token, session) = join_and_start(&mut socket, &url, "H1").await;
    assert_eq!(session["min_response_ms"], 400);

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
    let Some((url, storage, state, _data_dir, _)) = serve(&study).await else { return };
    async fn join(url: &str, label: &str) -> (Socket, String, String) {
        let mut socket = connect(url).await;
        let (participant, token, _) = join_and_start(&mut socket, url, label).await;
        (socket, participant, token)
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
    let report = mrstudy_server::lab::results::report(&state, "lab").await.unwrap();
    let states: Vec<(i64, bool)> = report.participants.iter().map(|p| (p.slot, p.abandoned)).collect();
    assert_eq!(states, vec![(0, true), (1, false), (0, false), (2, false)]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_pace_equal_every_conditions_frames_reach_the_participant_after_the_same_time() {
    let _alone = RENDERING.lock().await;
    let study = hygiene_study()
        .replace("min_response_ms = 400", "min_response_ms = 0\npace = \"equal\"")
        .replace("trials_per_condition = 1", "trials_per_condition = 3");
    let Some((url, storage, state, _data_dir, _)) = serve(&study).await else { return };
    let startup: Vec<(String, f64)> =
        sqlx::query_as("SELECT condition, median_ms FROM task_frame_times ORDER BY condition")
            .fetch_all(&storage.read)
            .await
            .unwrap();
    eprintln!("start-up frame times (render + encode, unpaced): {startup:?}");
    assert_eq!(startup.len(), 2);
    let mut socket = connect(&url).await;
    let (_, _, session) = join_and_start(&mut socket, &url, "pace").await;
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
    // The pace is fixed at the session's start (issue 45): frames that cannot keep it (a machine
    // busier than at start-up) are never re-paced but flagged, so lag never tells the
    // conditions apart unnoticed: equal shown frame times, or a session flagged as not kept.
    let (frames, late): (i64, i64) =
        sqlx::query_as("SELECT SUM(frames), SUM(frames_late) FROM task_trials WHERE answered_at IS NOT NULL")
            .fetch_one(&storage.read)
            .await
            .unwrap();
    let kept = mrstudy_server::lab::results::pace_kept(Some(rows[0].3), frames, late);
    eprintln!("frames {frames}, late {late}: pace kept {kept:?}");
    assert!(
        slowest / fastest - 1.0 < PACE_PARITY || kept == Some(false),
        "shown frame times differ by {:.1} % and the session is not flagged ({late} of {frames} frames late): {rows:?}",
        (slowest / fastest - 1.0) * 100.0
    );
    for row in &rows {
        assert!(row.1 >= row.2, "a frame is never sent before it is rendered: {row:?}");
        assert!(row.1 >= 0.95 * row.3, "every frame is held to about the pace: {row:?}");
    }
    let report = mrstudy_server::lab::results::report(&state, "lab").await.unwrap();
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
    let Some((url, storage, _state, data_dir, _)) = serve(&study).await else { return };
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
    let (_, _, session) = join_and_start(&mut socket, &url, "coherent").await;
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
    let Some((url, _storage, _state, _data_dir, _)) = serve(&hygiene_study()).await else { return };
    let mut request = url.as_str().into_client_request().unwrap();
    request.headers_mut().insert("origin", "https://evil.example".parse().unwrap());
    match tokio_tungstenite::connect_async(request).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => assert_eq!(response.status(), 403),
        other => panic!("a foreign origin must be refused, got {:?}", other.map(|(_, response)| response.status())),
    }
    // issue 46: a DNS-rebinding page (its name now resolving to this server) sends an Origin
    // equal to the Host it addressed; only configured origins are accepted, never the Host's echo
    let host = url.trim_start_matches("ws://").split('/').next().unwrap().to_string();
    let port = host.rsplit(':').next().unwrap();
    let mut request = url.as_str().into_client_request().unwrap();
    request.headers_mut().insert("host", format!("rebind.example:{port}").parse().unwrap());
    request.headers_mut().insert("origin", format!("http://rebind.example:{port}").parse().unwrap());
    match tokio_tungstenite::connect_async(request).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => assert_eq!(response.status(), 403),
        other => {
            panic!("an Origin equal to the Host is no configured origin, got {:?}", other.map(|(_, r)| r.status()))
        }
    }
    // the server's own page (a configured origin) is welcome
    let mut request = url.as_str().into_client_request().unwrap();
    request.headers_mut().insert("origin", format!("http://{host}").parse().unwrap());
    let (mut socket, _) = tokio_tungstenite::connect_async(request).await.unwrap();
    send(&mut socket, json!({"type": "start", "label": "x".repeat(5000)})).await;
    let error = json_of(&mut socket, "error").await;
    assert!(error["message"].as_str().unwrap().contains("more than the limit of 4096"), "{error}");
    let closed = tokio::time::timeout(Duration::from_secs(10), socket.next()).await.unwrap();
    assert!(matches!(closed, None | Some(Ok(Message::Close(_))) | Some(Err(_))), "{closed:?}");
}

/// Issue 16 and issue 46: a session is closed with an `error` when it has shown no activity for
/// the lab's idle timeout, whatever pings, pongs, junk or refused messages it sent meanwhile; a
/// connection that starts no participant is closed as soon (at most 10 s after it opened).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_sessions_are_closed_whatever_pings_and_junk_they_send() {
    let _alone = RENDERING.lock().await;
    let Some((url, _storage, state, _data_dir, _)) = serve(&hygiene_study()).await else { return };
    state.lab().unwrap().set_idle_timeout(Duration::from_millis(600));
    /// Keeps sending pings and junk every 100 ms until an `error` comes: (its message, when).
    async fn keep_pinging(socket: &mut Socket) -> (String, Duration) {
        let started = std::time::Instant::now();
        loop {
            assert!(started.elapsed() < Duration::from_secs(5), "still open after 5 s of pings and junk");
            socket.send(Message::Ping(vec![1, 2, 3].into())).await.unwrap();
            socket.send(Message::Binary(vec![0; 8].into())).await.unwrap();
            send(socket, json!({"type": "dance"})).await;
            send(socket, json!({"type": "ready", "extra": 1})).await;
            let deadline = tokio::time::Instant::now() + Duration::from_millis(100);
            while let Ok(Some(Ok(message))) = tokio::time::timeout_at(deadline, socket.next()).await {
                if let Message::Text(text) = message {
                    let value: Value = serde_json::from_str(text.as_str()).unwrap();
                    let message = value["message"].as_str().unwrap_or_default().to_string();
                    if message.contains("closed") {
                        return (message, started.elapsed());
                    }
                }
            }
        }
    }
    // never started: closed after the idle timeout (shorter than 10 s here), pings or not
    let mut socket = connect(&url).await;
    let (message, after) = keep_pinging(&mut socket).await;
    assert!(message.contains("no participant was started within 0.6 s"), "{message}");
    assert!(after >= Duration::from_millis(550) && after < Duration::from_millis(2500), "{after:?}");
    // a running participant who only pings is closed too
    let mut socket = connect(&url).await;
    join_and_start(&mut socket, &url, "idle").await;
    let (message, after) = keep_pinging(&mut socket).await;
    assert!(message.contains("closed after 0.6 s without activity"), "{message}");
    assert!(after >= Duration::from_millis(500) && after < Duration::from_millis(2500), "{after:?}");
    let closed = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match socket.next().await {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                Some(Ok(_)) => continue,
            }
        }
    })
    .await;
    assert!(closed.is_ok(), "the connection is closed after the error");
}

/// Issue 46: a WebSocket alone creates no participant and takes no counterbalancing slot (an
/// unauthenticated `start` loop made 1 635 participants in 15 s); participants are created over
/// HTTP under the survey's join rules (a closed study refuses all but pilots of a preview link,
/// the joins per address are limited); one client address holds at most its cap of sessions.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_websocket_alone_creates_no_participant_and_one_address_holds_at_most_its_cap_of_sessions() {
    let _alone = RENDERING.lock().await;
    let Some((url, storage, state, _data_dir, admin_token)) = serve(&hygiene_study()).await else { return };
    for round in 0..20 {
        let mut socket = connect(&url).await;
        refused(&mut socket, json!({"type": "start", "label": format!("bot{round}")}), "created over HTTP first").await;
        refused(&mut socket, json!({"type": "start"}), "created over HTTP first").await;
        refused(
            &mut socket,
            json!({"type": "start", "participant": "0".repeat(32), "token": "0".repeat(64)}),
            "No participant",
        )
        .await;
    }
    let stored: (i64, Option<i64>) =
        sqlx::query_as("SELECT COUNT(*), MAX(slot) FROM task_participants").fetch_one(&storage.read).await.unwrap();
    assert_eq!(stored, (0, None), "no participant, no slot taken");

    // the HTTP join: a closed study accepts only pilots of a preview link
    storage.set_open("lab", false).await.unwrap().unwrap();
    let (status, refusal) = post_json(&url, "/api/lab/lab/participants", json!({"label": "late"})).await;
    assert_eq!(status, 403, "{refusal}");
    assert!(refusal["error"].as_str().unwrap().contains("closed"), "{refusal}");
    let app = mrstudy_server::app(state.clone());
    let preview =
        support::call(&app, axum::http::Method::POST, "/api/admin/studies/lab/preview", Some(&admin_token), None).await;
    assert_eq!(preview.status, 201, "{}", preview.text());
    let link = preview.json()["url"].as_str().unwrap().to_string();
    assert!(link.starts_with("/lab/lab?preview="), "{link}");
    let token = link.split("preview=").nth(1).unwrap();
    let (status, pilot) =
        post_json(&url, "/api/lab/lab/participants", json!({"label": "pilot", "preview": token})).await;
    assert_eq!((status, pilot["pilot"].as_bool()), (201, Some(true)), "{pilot}");
    let (status, _) = post_json(&url, "/api/lab/lab/participants", json!({"label": "x", "preview": "f00"})).await;
    assert_eq!(status, 403);
    storage.set_open("lab", true).await.unwrap().unwrap();
    // joins of one address are limited as the survey's (120 a minute, bursts of 240)
    let mut created = 1;
    let refused_at = loop {
        let (status, answer) =
            post_json(&url, "/api/lab/lab/participants", json!({"label": format!("p{created}")})).await;
        if status == 429 {
            assert!(answer["error"].as_str().unwrap().contains("Too many joins"), "{answer}");
            break created;
        }
        assert_eq!(status, 201, "{answer}");
        created += 1;
        assert!(created <= 300, "no join limit");
    };
    let stored: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM task_participants").fetch_one(&storage.read).await.unwrap();
    assert_eq!(stored, refused_at, "every accepted join, nothing more");

    // at most `sessions_per_address` open sessions from one address; a closed one frees its place
    state.lab().unwrap().set_sessions_per_address(3);
    let mut open = Vec::new();
    for _ in 0..3 {
        open.push(connect(&url).await);
    }
    match tokio_tungstenite::connect_async(&url).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => assert_eq!(response.status(), 429),
        other => panic!("a fourth session from one address must be refused, got {:?}", other.map(|(_, r)| r.status())),
    }
    open.pop().unwrap().close(None).await.unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    loop {
        match tokio_tungstenite::connect_async(&url).await {
            Ok(_) => break,
            Err(_) if std::time::Instant::now() < deadline => tokio::time::sleep(Duration::from_millis(50)).await,
            Err(error) => panic!("a closed session frees its place: {error}"),
        }
    }
}

/// The database file and its WAL, as bytes.
fn database_bytes(data: &std::path::Path) -> Vec<u8> {
    let mut bytes = std::fs::read(data.join("mrstudy.db")).unwrap();
    if let Ok(wal) = std::fs::read(data.join("mrstudy.db-wal")) {
        bytes.extend(wal);
    }
    bytes
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|window| window == needle)
}

/// Issues 45 and 46: a lab participant can be excluded, included and deleted by the admin API
/// (`DELETE /api/admin/participants/{id}` answered 404 for them), and the deletion leaves none of
/// their bytes in the database files — code, id, token hash, key log — while another
/// participant's stay.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deleting_a_lab_participant_leaves_nothing_of_them_in_the_database_file() {
    let _alone = RENDERING.lock().await;
    let study = hygiene_study().replace("min_response_ms = 400", "min_response_ms = 0");
    let Some((url, storage, state, data_dir, admin_token)) = serve(&study).await else { return };
    let app = mrstudy_server::app(state.clone());
    let admin = |method: axum::http::Method, uri: String, body: Option<Value>| {
        let app = app.clone();
        let admin_token = admin_token.clone();
        async move { support::call(&app, method, &uri, Some(&admin_token), body).await }
    };
    let mut ids = Vec::new();
    let mut tokens = Vec::new();
    for (label, t) in [("LABCODE-UNIQUE-4711", 987654.321), ("LABCODE-KEEP-0042", 123456.789)] {
        let mut socket = connect(&url).await;
        let (participant, token, _) = join_and_start(&mut socket, &url, label).await;
        next_trial(&mut socket).await;
        frame_with_inputs(&mut socket, 0).await;
        send(&mut socket, json!({"type": "key", "key": "ArrowLeft", "t": t})).await;
        frame_with_inputs(&mut socket, 1).await;
        send(&mut socket, json!({"type": "answer", "trial": 1})).await;
        json_of(&mut socket, "saved").await;
        ids.push(participant);
        tokens.push(token);
    }
    let (gone, kept) = (ids[0].clone(), ids[1].clone());
    // exclude and include, as for survey participants
    let excluded = admin(
        axum::http::Method::POST,
        format!("/api/admin/participants/{gone}/exclude"),
        Some(json!({"reason": "asleep"})),
    )
    .await;
    assert_eq!(excluded.status, 200, "{}", excluded.text());
    assert_eq!(excluded.json()["excluded"], true);
    let row: (i64, Option<String>) =
        sqlx::query_as("SELECT excluded, exclusion_reason FROM task_participants WHERE id = $1")
            .bind(&gone)
            .fetch_one(&storage.read)
            .await
            .unwrap();
    assert_eq!(row, (1, Some("asleep".into())));
    let included = admin(axum::http::Method::POST, format!("/api/admin/participants/{gone}/include"), None).await;
    assert_eq!((included.status.as_u16(), included.json()["excluded"].as_bool()), (200, Some(false)));

    let token_hash = {
        use sha2::Digest;
        sha2::Sha256::digest(tokens[0].as_bytes()).to_vec()
    };
    let sqlite = std::env::var("MRSTUDY_TEST_DATABASE").as_deref() != Ok("postgres");
    if sqlite {
        let before = database_bytes(data_dir.path());
        assert!(contains(&before, b"LABCODE-UNIQUE-4711") && contains(&before, gone.as_bytes()));
        assert!(contains(&before, &token_hash) && contains(&before, b"987654.321"));
    }
    let deleted = admin(axum::http::Method::DELETE, format!("/api/admin/participants/{gone}"), None).await;
    assert_eq!(deleted.status, 200, "{}", deleted.text());
    let deletion = deleted.json();
    assert_eq!(
        (deletion["kind"].as_str(), deletion["responses"].as_i64()),
        (Some("lab-participant"), Some(1)),
        "{deletion}"
    );
    assert_eq!(deletion["trials"], 2, "{deletion}");
    let again = admin(axum::http::Method::DELETE, format!("/api/admin/participants/{gone}"), None).await;
    assert_eq!(again.status, 404);
    let left: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM task_trials WHERE participant = $1")
        .bind(&gone)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    assert_eq!(left, 0);
    if sqlite {
        let after = database_bytes(data_dir.path());
        for needle in [b"LABCODE-UNIQUE-4711".as_slice(), gone.as_bytes(), &token_hash, b"987654.321"] {
            assert!(!contains(&after, needle), "{:?} is still in the database file", String::from_utf8_lossy(needle));
        }
        assert!(
            contains(&after, b"LABCODE-KEEP-0042") && contains(&after, kept.as_bytes()),
            "the other participant is kept"
        );
        assert!(contains(&after, b"123456.789"), "the other participant's key log is kept");
    }
    // the deleted participant's token opens nothing any more
    let mut socket = connect(&url).await;
    refused(&mut socket, json!({"type": "start", "participant": gone, "token": tokens[0]}), "No participant").await;
}

/// Issue 45: with `pace = "equal"` a participant's pace is fixed when they are created and never
/// raised mid-session, even when the renderer's recent frames became slower (it used to rise from
/// 240 to 394 ms in one session); a participant whose frames come later than their pace is
/// flagged in the trials CSV and on the admin page, which also opens and closes the study, makes
/// preview links, lists participants with exclude / include / delete and counts progress as the
/// survey does (real participants only, pilots and excluded beside them).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_participants_pace_is_fixed_at_the_start_and_late_frames_are_flagged_on_the_admin_page() {
    let _alone = RENDERING.lock().await;
    let study = hygiene_study().replace("min_response_ms = 400", "min_response_ms = 0\npace = \"equal\"");
    let Some((url, storage, state, _data_dir, admin_token)) = serve(&study).await else { return };
    let lab_study = state.lab().unwrap().studies.get("lab").unwrap().clone();
    let mut socket = connect(&url).await;
    let (steady, _, _) = join_and_start(&mut socket, &url, "steady").await;
    let stored_pace: f64 = sqlx::query_scalar("SELECT pace_ms FROM task_participants WHERE id = $1")
        .bind(&steady)
        .fetch_one(&storage.read)
        .await
        .unwrap();
    assert_eq!(Some(stored_pace), lab_study.pace_ms(), "the pace is taken when the participant is created");
    // the renderer's recent frames become much slower: the study's pace for new participants
    // rises, the running participant's does not
    for condition in lab_study.study.conditions.clone() {
        for _ in 0..64 {
            lab_study.record_frame(condition, stored_pace * 3.0);
        }
    }
    assert!(lab_study.pace_ms().unwrap() > 2.0 * stored_pace);
    for number in 1..=2 {
        next_trial(&mut socket).await;
        frame_with_inputs(&mut socket, 0).await;
        send(&mut socket, json!({"type": "key", "key": "ArrowLeft"})).await;
        frame_with_inputs(&mut socket, 1).await;
        send(&mut socket, json!({"type": "answer", "trial": number})).await;
        json_of(&mut socket, "saved").await;
    }
    let paced: Vec<f64> = sqlx::query_scalar("SELECT paced_ms FROM task_trials WHERE participant = $1 ORDER BY trial")
        .bind(&steady)
        .fetch_all(&storage.read)
        .await
        .unwrap();
    assert_eq!(paced, vec![stored_pace, stored_pace], "never re-paced mid-session");

    // a participant whose frames cannot keep their pace (here a pace far below any frame time)
    let mut socket = connect(&url).await;
    let (late, late_token) = join_http(&url, "late").await;
    sqlx::query("UPDATE task_participants SET pace_ms = 0.001 WHERE id = $1")
        .bind(&late)
        .execute(&storage.read)
        .await
        .unwrap();
    send(&mut socket, json!({"type": "start", "participant": late, "token": late_token})).await;
    json_of(&mut socket, "session").await;
    next_trial(&mut socket).await;
    frame_with_inputs(&mut socket, 0).await;
    send(&mut socket, json!({"type": "answer", "trial": 1})).await;
    json_of(&mut socket, "saved").await;
    let row: (i64, i64) =
        sqlx::query_as("SELECT frames, frames_late FROM task_trials WHERE participant = $1 AND trial = 1")
            .bind(&late)
            .fetch_one(&storage.read)
            .await
            .unwrap();
    assert!(row.0 >= 1 && row.1 == row.0, "every frame of the late participant is late: {row:?}");
    let csv = mrstudy_server::lab::results::trials_csv(&storage.read, "lab").await.unwrap();
    let late_rows: Vec<&str> = csv.lines().filter(|line| line.starts_with(late.as_str())).collect();
    assert!(!late_rows.is_empty() && late_rows.iter().all(|line| line.ends_with(",false,false,false")), "{csv}");
    let header = csv.lines().next().unwrap();
    assert!(header.contains(",paced_ms,frames_late,") && header.ends_with(",pilot,excluded,pace_kept"), "{header}");
    // whether the steady participant's frames kept their pace depends on the machine's load
    // (a frame 10 % over the pace is late, and one late frame of its few is more than 5 %): the
    // admin page's count is every participant the export marks as not keeping the pace, the
    // late one among them
    let not_kept: std::collections::BTreeSet<&str> = csv
        .lines()
        .skip(1)
        .filter(|line| line.ends_with(",false"))
        .map(|line| line.split(',').next().unwrap())
        .collect();
    assert!(not_kept.contains(late.as_str()), "{csv}");

    // a pilot from a preview link, and an excluded participant: counted beside the real ones
    let app = mrstudy_server::app(state.clone());
    let preview =
        support::call(&app, axum::http::Method::POST, "/api/admin/studies/lab/preview", Some(&admin_token), None).await;
    let token = preview.json()["url"].as_str().unwrap().split("preview=").nth(1).unwrap().to_string();
    let (status, _) = post_json(&url, "/api/lab/lab/participants", json!({"label": "pilot", "preview": token})).await;
    assert_eq!(status, 201);
    let (excluded, _) = join_http(&url, "excluded").await;
    let answer = support::call(
        &app,
        axum::http::Method::POST,
        &format!("/api/admin/participants/{excluded}/exclude"),
        Some(&admin_token),
        Some(json!({"reason": "fell asleep"})),
    )
    .await;
    assert_eq!(answer.status, 200, "{}", answer.text());
    let report = mrstudy_server::lab::results::report(&state, "lab").await.unwrap();
    let counts = serde_json::to_value(&report.counts).unwrap();
    assert_eq!(counts["started"], 2, "steady and late: {counts}");
    assert_eq!(counts["finished"], 1, "{counts}");
    assert_eq!((counts["pilots"].as_i64(), counts["excluded"].as_i64()), (Some(1), Some(1)), "{counts}");
    assert_eq!(counts["pace_not_kept"], not_kept.len(), "{counts}");
    let page = support::call(&app, axum::http::Method::GET, "/admin/lab/lab", Some(&admin_token), None).await;
    let html = page.text();
    assert_eq!(page.status, 200, "{html}");
    let not_kept_line = format!("{} did not keep the pace", not_kept.len());
    for needle in [
        r#"id="toggle-open""#,
        r#"id="preview""#,
        r#"data-action="exclude""#,
        r#"data-action="include""#,
        r#"data-action="delete""#,
        "Started 2, finished 1 (50 %)",
        "1 pilots and 1 excluded",
        not_kept_line.as_str(),
        "not kept</strong> (",
        "fell asleep",
        "/static/admin.js",
    ] {
        assert!(html.contains(needle), "the admin page lacks {needle}: {html}");
    }
    assert!(html.contains(&format!(r#"data-participant="{late}""#)));
}

/// Issue 50, item 5: without `render.size`, the lab measures its slowest condition at start-up
/// on a software adapter and says on the console which size it chose and at what frame rate;
/// on a hardware adapter it says whether every condition reaches the display's 60 frames/s.
/// `min_fps = 240` keeps the measurement to the ladder's smallest size on lavapipe.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_render_size_the_lab_measures_its_size_at_start_up_and_says_so() {
    let _alone = RENDERING.lock().await;
    let text = study().replace("size = [96, 72]\n", "min_fps = 240\n");
    assert!(!text.contains("size = ["), "{text}");
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    std::fs::write(studies.path().join("lab.toml"), text).unwrap();
    let Prepared { state, tasks, .. } =
        prepare_on(&test_database(data_dir.path()).await, data_dir.path(), studies.path()).await.unwrap();
    let (info, warnings) = start_lab(&state, tasks, data_dir.path()).await;
    let Some(lab) = state.lab() else {
        assert!(warnings.iter().any(|w| w.contains("GPU adapter")), "{warnings:?}");
        eprintln!("skipping: {warnings:?}");
        return;
    };
    let lines: Vec<&String> = info.iter().chain(&warnings).collect();
    eprintln!("{lines:#?}");
    let served = lab.studies.get("lab").expect("the study is served");
    if lab.adapter.is_software() {
        let line = warnings.iter().find(|line| line.contains("render.size not set")).expect("the size line");
        assert!(line.contains(&lab.adapter.adapter), "{line}");
        assert!(line.contains("96×72") && line.contains("frames/s"), "{line}");
        assert!(line.contains("chose 96×72, the smallest size"), "{line}");
        assert_eq!(served.size, [96, 72]);
    } else {
        let line = info.iter().find(|line| line.contains("hardware adapter")).expect("the display-rate line");
        assert!(line.contains("320×240") && line.contains("none ") && line.contains("gi "), "{line}");
        assert_eq!(served.size, [320, 240]);
    }
    // the ladder's photographs are not cached: only the study's own (PNG and EXR)
    assert!(std::fs::read_dir(data_dir.path().join("lab")).unwrap().count() <= 2);
}
