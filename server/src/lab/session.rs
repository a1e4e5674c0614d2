//! The live WebSocket session of a task study (`GET /api/lab/{slug}/ws`): one connection runs
//! one participant's trials. The participant is created over HTTP first ([`super::join`]); the
//! session starts with their id and token. The protocol is documented in `studies/README.md`
//! ("The live WebSocket API") and docs/lab.md; in short, the client sends JSON text messages
//! `start`, `resume`, `ready`,
//! `acknowledge`, `key`, `shown` and `answer`, and the server answers with `session`,
//! `instructions`, `trial`, `frame` (a JSON text message followed by one binary message: the
//! frame number as a big-endian u32, then the JPEG), `saved`, `done` and `error`.
//!
//! Trustworthy responses: before a task's first trial the server sends its `instructions` and
//! starts the trial only on `acknowledge`, sent no sooner than the study's `min_response_ms`
//! after them. The page reports each frame it has put on screen with `shown`; an answer is
//! refused (a sentence back, nothing stored) until the trial's first frame was shown and
//! `min_response_ms` has passed since, so a held key cannot answer a burst of trials. A
//! participant with an empty code is refused at `start`.
//!
//! Pacing: with `pace = "equal"` every frame is held until the slowest condition's frame time
//! (see [`super::timing`]) has passed since it was requested, so all conditions show the same
//! lag. That pace is fixed when the participant is created and kept for all their sessions; it is
//! never raised mid-session. A frame that reaches the participant more than [`LATE_TOLERANCE`]
//! later than the pace is counted late (`frames_late` per trial), and a participant with more
//! than [`LATE_SHARE`] of their frames late is flagged (export and admin page).
//!
//! Rendering: every accepted key moves the virtual cube at once; the session keeps at most one
//! frame job in flight on the renderer thread, and when keys arrive while it renders they are
//! coalesced into one next frame showing the latest position. Per frame the session measures the
//! renderer's time and the latency from the oldest input not yet shown to the frame being sent.
//!
//! Open to the internet: a browser's upgrade must come from a configured origin
//! ([`Lab::origin_allowed`]: `serve --origin` and the address serve listens on, never the
//! request's own `Host`, which a DNS-rebinding page controls; clients that send no `Origin` are
//! not browsers), at most [`MAX_SESSIONS`] sessions run at once (503 beyond) and at most
//! [`Lab::sessions_per_address`] from one client address (429 beyond), a session that has not
//! started a participant within [`START_TIMEOUT`] is closed, a session without activity for
//! [`Lab::idle_timeout`] ([`IDLE_TIMEOUT`] unless `serve --lab-idle-timeout` says otherwise) is
//! closed with an `error` saying so — activity is a message the session accepted: pings, pongs,
//! binary messages and refused messages do not count — and a message over
//! [`MAX_MESSAGE_BYTES`] gets an `error` before the connection is closed.
//!
//! Bad input — malformed or unknown messages, keys outside a key task, answers out of range, an
//! answer to another trial or a finished one — gets one `error` message with a sentence and
//! changes nothing. A trial's result is committed to the database before `saved` is sent.

use std::sync::Arc;
use std::time::Instant;

use axum::extract::ws::{Message, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::response::Response;
use glam::DVec3;
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::sync::oneshot;

use super::admission::{Full, MAX_SESSIONS, SessionSlot, client_address};
use super::live::{Frame, FrameJob, SessionRenderState};
use super::store::{self, TaskRefused, TaskWrite, TaskWritten};
use super::{Lab, LabStudy};
use crate::AppState;
use crate::error::AppError;
use crate::study::task::TaskKind;
use crate::trial::{PlannedTaskTrial, TrialResult};

/// Largest text message accepted from a client, in bytes.
pub const MAX_MESSAGE_BYTES: usize = 4096;
/// Largest message read at all: one between this and [`MAX_MESSAGE_BYTES`] is answered with an
/// `error` and the connection closed; a larger one closes it at once.
const MAX_READ_BYTES: usize = 1 << 20;
/// A session without any message from its client for this long is closed (the default of
/// [`Lab::idle_timeout`]).
pub const IDLE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(10 * 60);

/// Open sessions from one client address, by default (`serve --lab-sessions-per-address`).
pub const SESSIONS_PER_ADDRESS: usize = 8;
/// A session that has not started a participant this long after it opened is closed (or after
/// the idle timeout, if that is shorter).
pub const START_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(10);
/// A paced frame is late when it reaches the participant more than this fraction later than the
/// pace.
pub const LATE_TOLERANCE: f64 = 0.10;
/// A participant whose late frames are more than this fraction of their paced frames did not
/// keep the pace (flagged in the export and on the admin page).
pub const LATE_SHARE: f64 = 0.05;

/// Keys kept in one trial's key log; further keys are refused.
pub const MAX_KEYS_PER_TRIAL: usize = 5000;

pub async fn websocket(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: axum::http::HeaderMap,
    peer: Option<axum::Extension<crate::limits::ClientAddr>>,
    upgrade: WebSocketUpgrade,
) -> Result<Response, AppError> {
    let lab = state
        .lab()
        .ok_or_else(|| AppError::NotFound(format!("There is no task study \"{slug}\" (no lab studies are served).")))?;
    // a header that is not text is no configured origin
    let origin = headers.get(axum::http::header::ORIGIN).map(|origin| origin.to_str().unwrap_or("\u{0}"));
    if !lab.origin_allowed(origin) {
        return Err(AppError::Forbidden(
            "A lab session may only be opened from this server's own lab page (the Origin is not one of the server's configured origins; see serve --origin).".into(),
        ));
    }
    let study = lab
        .studies
        .get(&slug)
        .cloned()
        .ok_or_else(|| AppError::NotFound(format!("There is no task study \"{slug}\".")))?;
    let address = client_address(peer.map(|peer| peer.0), &headers, state.limits().behind_tls);
    let slot = SessionSlot::take(&lab, address).map_err(|full| match full {
        Full::Lab => AppError::Unavailable(format!(
            "The lab already runs {MAX_SESSIONS} sessions, its most at once; try again when one has finished."
        )),
        Full::Address(cap) => AppError::TooManyRequests(format!(
            "This address already has {cap} lab sessions open, its most at once; close one, or wait until it times out, and try again."
        )),
    })?;
    Ok(upgrade.max_message_size(MAX_READ_BYTES).max_frame_size(MAX_READ_BYTES).on_upgrade(move |socket| async move {
        let _slot = slot;
        let mut session = Session {
            state,
            lab,
            study,
            socket,
            participant: None,
            trials: Vec::new(),
            answered: 0,
            active: None,
            pending: None,
            render_state: SessionRenderState::default(),
            frame_number: 0,
            instructions_shown: None,
            acknowledged: None,
            pace_ms: None,
        };
        session.run().await;
    }))
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
enum ClientMessage {
    /// A participant created over HTTP ([`super::join`]) starts; `label` alone is the old
    /// protocol, refused with a sentence saying what to do.
    Start {
        #[serde(default)]
        participant: Option<String>,
        #[serde(default)]
        token: Option<String>,
        #[serde(default)]
        label: Option<String>,
    },
    Resume {
        participant: String,
        token: String,
    },
    Ready {},
    Acknowledge {},
    Shown {
        n: u32,
    },
    /// An arrow key: pressed (`held` false), or a step of a held key, which the page sends at
    /// the task's `held_steps_per_second` while the key stays down (`held` true).
    Key {
        key: String,
        #[serde(default)]
        t: Option<f64>,
        #[serde(default)]
        held: bool,
    },
    Answer {
        trial: u32,
        #[serde(default)]
        cm: Option<f64>,
    },
}

struct Participant {
    id: String,
    label: String,
}

/// The trial being worked on.
struct Active {
    planned: PlannedTaskTrial,
    position: DVec3,
    sent_at: Instant,
    first_frame: Option<(Instant, String)>,
    /// The number of the trial's first frame.
    first_frame_number: Option<u32>,
    /// When the page reported the trial's first frame shown (server clock).
    first_shown: Option<(Instant, String)>,
    frames_shown: u32,
    last_shown_number: u32,
    keys: Vec<Value>,
    frames: u32,
    frame_ms: Vec<f64>,
    /// Per frame, its request → sent (pacing included), ms.
    shown_frame_ms: Vec<f64>,
    /// The frame time frames were paced to, ms.
    paced_ms: Option<f64>,
    /// Frames sent more than [`LATE_TOLERANCE`] later than the pace.
    frames_late: u32,
    latencies: Vec<f64>,
    /// The oldest input not yet in a requested frame.
    unrendered_since: Option<Instant>,
    /// Whether the position changed since the last requested frame.
    dirty: bool,
}

struct Pending {
    trial: u32,
    /// Keys of the trial included in this frame.
    inputs: usize,
    input_at: Option<Instant>,
    condition: crate::study::task::Condition,
    requested_at: Instant,
    /// Not sent before this (pacing).
    release_at: Instant,
    answer: oneshot::Receiver<Result<Frame, String>>,
}

struct Session {
    state: AppState,
    lab: Arc<Lab>,
    study: Arc<LabStudy>,
    socket: WebSocket,
    participant: Option<Participant>,
    trials: Vec<PlannedTaskTrial>,
    answered: u32,
    active: Option<Active>,
    pending: Option<Pending>,
    render_state: SessionRenderState,
    frame_number: u32,
    /// The task whose instructions were sent and not yet acknowledged, and when.
    instructions_shown: Option<(String, Instant)>,
    /// The task whose instructions were acknowledged (its first trial may start).
    acknowledged: Option<String>,
    /// The frame time this session's frames are paced to (`pace = "equal"`), fixed when the
    /// participant starts or resumes.
    pace_ms: Option<f64>,
}

/// Why a message was refused: sent to the client, nothing changed.
struct Refusal(String);

impl From<AppError> for Refusal {
    fn from(error: AppError) -> Self {
        if error.status().is_server_error() {
            tracing::error!(%error, "a lab session message failed");
            Refusal("The server could not complete this; the error has been logged.".into())
        } else {
            Refusal(error.to_string())
        }
    }
}

impl From<crate::storage::StorageError> for Refusal {
    fn from(error: crate::storage::StorageError) -> Self {
        AppError::from(error).into()
    }
}

impl From<TaskRefused> for Refusal {
    fn from(refused: TaskRefused) -> Self {
        AppError::from(refused).into()
    }
}

impl From<sqlx::Error> for Refusal {
    fn from(error: sqlx::Error) -> Self {
        AppError::Database(error).into()
    }
}

impl Session {
    async fn run(&mut self) {
        let opened = Instant::now();
        // the last message the session accepted (pings, pongs, binary and refused messages are
        // no activity)
        let mut last_activity = opened;
        loop {
            let idle = self.lab.idle_timeout();
            let (deadline, limit) = if self.participant.is_some() {
                (last_activity + idle, idle)
            } else {
                let limit = idle.min(START_TIMEOUT);
                (opened + limit, limit)
            };
            let frame_ready = async {
                match self.pending.as_mut() {
                    Some(pending) => {
                        tokio::time::sleep_until(pending.release_at.into()).await;
                        (&mut pending.answer).await
                    }
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                () = tokio::time::sleep_until(deadline.into()) => {
                    let seconds = limit.as_secs_f64();
                    let after = if seconds >= 120.0 { format!("{:.0} minutes", seconds / 60.0) } else { format!("{seconds:.1} s") };
                    let message = if self.participant.is_some() {
                        format!("The session was closed after {after} without activity; reload the page to resume.")
                    } else {
                        format!("The session was closed: no participant was started within {after} of opening it; reload the page to try again.")
                    };
                    self.close_with_error(message).await;
                    return;
                }
                message = self.socket.recv() => {
                    let Some(Ok(message)) = message else { return };
                    if let Message::Text(text) = &message && text.len() > MAX_MESSAGE_BYTES {
                        self.close_with_error(format!("The message has {} bytes, more than the limit of {MAX_MESSAGE_BYTES}; the connection is closed.", text.len())).await;
                        return;
                    }
                    let outcome = match message {
                        Message::Text(text) => self.handle(text.as_str()).await,
                        Message::Binary(_) => Err(Refusal("Binary messages are not accepted; send JSON text messages.".into())),
                        Message::Close(_) => return,
                        Message::Ping(_) | Message::Pong(_) => Ok(false),
                    };
                    if let Ok(true) = outcome {
                        last_activity = Instant::now();
                    }
                    if let Err(Refusal(message)) = outcome
                        && self.send(json!({"type": "error", "message": message})).await.is_err()
                    {
                        return;
                    }
                }
                answer = frame_ready => {
                    let pending = self.pending.take().expect("a frame was pending");
                    let frame = match answer {
                        Ok(Ok(frame)) => frame,
                        Ok(Err(message)) => {
                            tracing::error!(study = %self.study.study.slug, %message, "a lab frame failed");
                            let _ = self.send(json!({"type": "error", "message": format!("The renderer could not make a frame: {message}")})).await;
                            continue;
                        }
                        Err(_) => {
                            let _ = self.send(json!({"type": "error", "message": "The renderer has stopped."})).await;
                            return;
                        }
                    };
                    if self.deliver(pending, frame).await.is_err() {
                        return;
                    }
                }
            }
        }
    }

    /// Sends an `error` with `message`, then closes the connection (the caller returns).
    async fn close_with_error(&mut self, message: String) {
        let _ = self.send(json!({"type": "error", "message": message})).await;
        let _ = self.socket.send(Message::Close(None)).await;
    }

    async fn send(&mut self, value: Value) -> Result<(), axum::Error> {
        self.socket.send(Message::Text(Utf8Bytes::from(value.to_string()))).await
    }

    /// Handles one text message: Ok(true) when it was activity (it changed the session), Ok(false)
    /// when it changed nothing (a stale `shown`).
    async fn handle(&mut self, text: &str) -> Result<bool, Refusal> {
        let value: Value = serde_json::from_str(text).map_err(|_| Refusal("The message is not valid JSON.".into()))?;
        let kind = value.get("type").and_then(Value::as_str).unwrap_or("").to_string();
        if !["start", "resume", "ready", "acknowledge", "shown", "key", "answer"].contains(&kind.as_str()) {
            return Err(Refusal(format!(
                "Unknown message type \"{kind}\"; expected start, resume, ready, acknowledge, shown, key or answer."
            )));
        }
        let message: ClientMessage = serde_json::from_value(value)
            .map_err(|error| Refusal(format!("The {kind} message does not have the expected fields: {error}.")))?;
        match message {
            ClientMessage::Start { participant: Some(participant), token: Some(token), label: None } => {
                self.resume(participant, token).await?
            }
            ClientMessage::Start { .. } => {
                return Err(Refusal(format!(
                    "A lab participant is created over HTTP first (POST /api/lab/{}/participants with {{\"label\": \"…\"}}); then send {{\"type\": \"start\", \"participant\": …, \"token\": …}} with the participant and token it answered.",
                    self.study.study.slug
                )));
            }
            ClientMessage::Resume { participant, token } => self.resume(participant, token).await?,
            ClientMessage::Ready {} => self.ready().await?,
            ClientMessage::Acknowledge {} => self.acknowledge().await?,
            ClientMessage::Shown { n } => return self.shown(n),
            ClientMessage::Key { key, t, held } => self.key(key, t, held)?,
            ClientMessage::Answer { trial, cm } => self.answer(trial, cm).await?,
        }
        Ok(true)
    }

    fn session_message(&self, token: Option<&str>) -> Value {
        let participant = self.participant.as_ref().expect("a participant");
        json!({
            "type": "session",
            "participant": participant.id,
            "token": token,
            "label": participant.label,
            "trials": self.trials.len(),
            "answered": self.answered,
            "adapter": self.lab.adapter.adapter,
            "adapter_kind": self.lab.adapter.kind,
            "smoothing": self.render_state.smoothing,
            "min_response_ms": self.study.study.min_response_ms,
            "pace": self.study.study.render.pace.as_str(),
        })
    }

    async fn resume(&mut self, id: String, token: String) -> Result<(), Refusal> {
        if self.participant.is_some() {
            return Err(Refusal(
                "This connection already runs a participant; open a new connection for another.".into(),
            ));
        }
        let refused = || Refusal("No participant of this study has that id and token.".into());
        let row = store::participant(self.state.storage(), &id).await?.ok_or_else(refused)?;
        if row.study != self.study.study.slug
            || !crate::auth::constant_time_eq(&crate::auth::sha256(token.as_bytes()), &row.token_sha256)
        {
            return Err(refused());
        }
        self.state.storage().write(TaskWrite::Resume { participant: id.clone() }).await??;
        self.trials = store::planned_trials(self.state.storage(), &id).await?;
        self.answered = row.answered as u32;
        self.participant = Some(Participant { id, label: row.label });
        // the participant's pace, fixed when they were created (a participant stored before
        // paces were kept per participant gets the study's pace now, fixed for this session)
        self.pace_ms = match (self.study.study.render.pace, row.pace_ms) {
            (crate::study::task::Pace::Equal, Some(pace)) => Some(pace),
            _ => self.study.pace_ms(),
        };
        let message = self.session_message(None);
        let _ = self.send(message).await;
        Ok(())
    }

    async fn ready(&mut self) -> Result<(), Refusal> {
        if self.participant.is_none() {
            return Err(Refusal("Start or resume a participant first.".into()));
        }
        if let Some(active) = &self.active {
            return Err(Refusal(format!("Trial {} is still running; answer it first.", active.planned.trial)));
        }
        if let Some((task, _)) = &self.instructions_shown {
            return Err(Refusal(format!(
                "The instructions of the {task} task are waiting to be acknowledged; acknowledge them to start its first trial."
            )));
        }
        if self.answered as usize >= self.trials.len() {
            let thanks = self.study.study.texts.thanks.clone();
            let _ = self.send(json!({"type": "done", "trials": self.trials.len(), "thanks": thanks})).await;
            return Ok(());
        }
        let planned = self.trials[self.answered as usize].clone();
        let task = self.study.study.task(&planned.task).ok_or_else(|| {
            AppError::Internal(format!(
                "the schedule names task \"{}\", which the study file no longer has",
                planned.task
            ))
        })?;
        let first_of_task = planned.trial == 1 || self.trials[planned.trial as usize - 2].task != planned.task;
        if first_of_task && self.acknowledged.as_deref() != Some(planned.task.as_str()) {
            // the task's instructions stay until acknowledged
            self.instructions_shown = Some((planned.task.clone(), Instant::now()));
            let message = json!({
                "type": "instructions",
                "task": planned.task,
                "kind": task.kind.as_str(),
                "trial": planned.trial,
                "of": self.trials.len(),
                "instructions": task.instructions,
            });
            let _ = self.send(message).await;
            return Ok(());
        }
        let answer = match task.kind {
            TaskKind::Distance => json!({"unit": "cm", "min": 0, "max": task.answer_max_cm}),
            _ => Value::Null,
        };
        let keys: &[&str] = match task.kind {
            TaskKind::Distance => &[],
            TaskKind::Placement => &["ArrowLeft", "ArrowRight", "ArrowUp", "ArrowDown"],
            TaskKind::Contact => &["ArrowUp", "ArrowDown"],
        };
        let message = json!({
            "type": "trial",
            "trial": planned.trial,
            "of": self.trials.len(),
            "task": planned.task,
            "kind": task.kind.as_str(),
            "practice": planned.practice,
            "first_of_task": first_of_task,
            "instructions": task.instructions,
            "answer": answer,
            "keys": keys,
            "held_steps_per_second": (task.kind != TaskKind::Distance).then_some(task.held_steps_per_second),
        });
        self.active = Some(Active {
            position: DVec3::from(planned.start),
            planned,
            sent_at: Instant::now(),
            first_frame: None,
            first_frame_number: None,
            first_shown: None,
            frames_shown: 0,
            last_shown_number: 0,
            keys: Vec::new(),
            frames: 0,
            frame_ms: Vec::new(),
            shown_frame_ms: Vec::new(),
            paced_ms: None,
            frames_late: 0,
            latencies: Vec::new(),
            unrendered_since: None,
            dirty: true,
        });
        let _ = self.send(message).await;
        self.request_frame()?;
        Ok(())
    }

    /// The participant read the instructions: the task's first trial starts.
    async fn acknowledge(&mut self) -> Result<(), Refusal> {
        let Some((task, at)) = self.instructions_shown.clone() else {
            return Err(Refusal("There are no instructions to acknowledge now.".into()));
        };
        let elapsed_ms = at.elapsed().as_secs_f64() * 1e3;
        let minimum = self.study.study.min_response_ms;
        if elapsed_ms < f64::from(minimum) {
            return Err(Refusal(format!(
                "The instructions were acknowledged {elapsed_ms:.0} ms after they appeared, sooner than the study's minimum of {minimum} ms; read them, then acknowledge again."
            )));
        }
        self.instructions_shown = None;
        self.acknowledged = Some(task);
        self.ready().await
    }

    /// The page put frame `n` on screen: Ok(true) when it is a frame of the running trial not
    /// reported before.
    fn shown(&mut self, n: u32) -> Result<bool, Refusal> {
        if n == 0 || n > self.frame_number {
            return Err(Refusal(format!(
                "Frame {n} was not sent on this connection; shown names a frame the server sent."
            )));
        }
        // a report that arrives after its trial ended changes nothing
        let Some(active) = self.active.as_mut() else { return Ok(false) };
        let Some(first) = active.first_frame_number else { return Ok(false) };
        if n < first || n <= active.last_shown_number {
            return Ok(false);
        }
        active.last_shown_number = n;
        active.frames_shown += 1;
        if active.first_shown.is_none() {
            active.first_shown = Some((Instant::now(), iso_now()));
        }
        Ok(true)
    }

    fn key(&mut self, key: String, client_t: Option<f64>, held: bool) -> Result<(), Refusal> {
        let Some(active) = self.active.as_mut() else {
            return Err(Refusal("There is no running trial to move the cube in; send ready first.".into()));
        };
        let task = self.study.study.task(&active.planned.task).expect("the task exists (checked by ready)");
        let step = task.step_cm / 100.0;
        let delta = match (task.kind, key.as_str()) {
            (TaskKind::Distance, _) => return Err(Refusal("The distance task takes a typed answer, not keys.".into())),
            (TaskKind::Placement, "ArrowLeft") => DVec3::new(-step, 0.0, 0.0),
            (TaskKind::Placement, "ArrowRight") => DVec3::new(step, 0.0, 0.0),
            (TaskKind::Placement, "ArrowUp") => DVec3::new(0.0, 0.0, -step),
            (TaskKind::Placement, "ArrowDown") => DVec3::new(0.0, 0.0, step),
            (TaskKind::Contact, "ArrowUp") => DVec3::new(0.0, step, 0.0),
            (TaskKind::Contact, "ArrowDown") => DVec3::new(0.0, -step, 0.0),
            (kind, other) => {
                return Err(Refusal(format!(
                    "Key \"{}\" does not move the cube in the {} task; use {}.",
                    other.chars().take(32).collect::<String>(),
                    kind.as_str(),
                    if kind == TaskKind::Contact { "ArrowUp and ArrowDown" } else { "the arrow keys" }
                )));
            }
        };
        if client_t.is_some_and(|t| !t.is_finite()) {
            return Err(Refusal("The key's time t must be a finite number of milliseconds.".into()));
        }
        if active.keys.len() >= MAX_KEYS_PER_TRIAL {
            return Err(Refusal(format!("This trial already has {MAX_KEYS_PER_TRIAL} keys; answer it.")));
        }
        // the cube stays in view (x, z within the layout's reach) and at most 2 cm into the table
        let layout = self.study.layout;
        let moved = layout.clamp(active.position + delta);
        active.position =
            DVec3::new(moved.x, moved.y.clamp(layout.half_height - 0.02, layout.half_height + 0.30), moved.z);
        let now = Instant::now();
        active.keys.push(json!({
            "key": key,
            "t_ms": round3(now.duration_since(active.sent_at).as_secs_f64() * 1e3),
            "client_t_ms": client_t,
            "held": held,
            "x": active.position.x, "y": active.position.y, "z": active.position.z,
        }));
        active.dirty = true;
        active.unrendered_since.get_or_insert(now);
        if self.pending.is_none() {
            self.request_frame()?;
        }
        Ok(())
    }

    /// Submits a frame of the active trial's current position when none is in flight.
    fn request_frame(&mut self) -> Result<(), Refusal> {
        let Some(active) = self.active.as_mut() else { return Ok(()) };
        if self.pending.is_some() || !active.dirty {
            return Ok(());
        }
        let (reply, answer) = oneshot::channel();
        let requested_at = Instant::now();
        // the participant's pace, fixed when they were created: never changed mid-session (a
        // frame that cannot keep it is counted late in `deliver`)
        let paced_ms = self.pace_ms;
        let release_at = requested_at + std::time::Duration::from_secs_f64(paced_ms.unwrap_or(0.0).max(0.0) / 1e3);
        active.paced_ms = paced_ms;
        self.lab
            .renderer
            .submit(FrameJob {
                study: self.study.study.slug.clone(),
                condition: active.planned.condition,
                trial: active.planned.trial,
                centre: active.position.to_array(),
                state: self.render_state.clone(),
                reply,
            })
            .map_err(|error| AppError::Internal(error.to_string()))?;
        active.dirty = false;
        self.pending = Some(Pending {
            trial: active.planned.trial,
            inputs: active.keys.len(),
            input_at: active.unrendered_since.take(),
            condition: active.planned.condition,
            requested_at,
            release_at,
            answer,
        });
        Ok(())
    }

    async fn deliver(&mut self, pending: Pending, frame: Frame) -> Result<(), axum::Error> {
        self.render_state = frame.state.clone();
        self.study.record_frame(pending.condition, frame.render_ms + frame.encode_ms);
        let Some(active) = self.active.as_mut().filter(|active| active.planned.trial == pending.trial) else {
            // the trial ended while this frame rendered: drop it, and render the next trial's
            // first frame if that trial started meanwhile
            if let Err(Refusal(message)) = self.request_frame() {
                self.send(json!({"type": "error", "message": message})).await?;
            }
            return Ok(());
        };
        self.frame_number += 1;
        let now = Instant::now();
        let latency = pending.input_at.map(|at| now.duration_since(at).as_secs_f64() * 1e3);
        let frame_ms = frame.render_ms + frame.encode_ms;
        active.frames += 1;
        active.frame_ms.push(frame_ms);
        if let Some(latency) = latency {
            active.latencies.push(latency);
        }
        let shown_ms = now.duration_since(pending.requested_at).as_secs_f64() * 1e3;
        active.shown_frame_ms.push(shown_ms);
        if active.paced_ms.is_some_and(|pace| shown_ms > pace * (1.0 + LATE_TOLERANCE)) {
            active.frames_late += 1;
        }
        if active.first_frame.is_none() {
            active.first_frame = Some((now, iso_now()));
            active.first_frame_number = Some(self.frame_number);
        }
        let trial = active.planned.trial;
        let meta = json!({
            "type": "frame",
            "n": self.frame_number,
            "trial": trial,
            "inputs": pending.inputs,
            "width": frame.width,
            "height": frame.height,
            "render_ms": round3(frame.render_ms),
            "encode_ms": round3(frame.encode_ms),
            "latency_ms": latency.map(round3),
            "smoothing": frame.state.smoothing,
            "bytes": frame.jpeg.len(),
        });
        self.send(meta).await?;
        let mut binary = Vec::with_capacity(4 + frame.jpeg.len());
        binary.extend_from_slice(&self.frame_number.to_be_bytes());
        binary.extend_from_slice(&frame.jpeg);
        self.socket.send(Message::Binary(binary.into())).await?;
        // inputs that arrived while this frame rendered: one frame for all of them
        if let Err(Refusal(message)) = self.request_frame() {
            self.send(json!({"type": "error", "message": message})).await?;
        }
        Ok(())
    }

    async fn answer(&mut self, trial: u32, cm: Option<f64>) -> Result<(), Refusal> {
        let Some(participant) = self.participant.as_ref() else {
            return Err(Refusal("Start or resume a participant first.".into()));
        };
        if trial as usize > self.trials.len() || trial == 0 {
            return Err(Refusal(format!("There is no trial {trial}; the schedule has {}.", self.trials.len())));
        }
        if trial <= self.answered {
            return Err(Refusal(format!("Trial {trial} is already answered.")));
        }
        let Some(active) = self.active.as_ref().filter(|active| active.planned.trial == trial) else {
            return Err(Refusal(match &self.active {
                Some(active) => format!("Trial {trial} is not the running trial; trial {} is.", active.planned.trial),
                None => format!("Trial {trial} has not started; send ready first."),
            }));
        };
        let task = self.study.study.task(&active.planned.task).expect("the task exists (checked by ready)");
        let real = DVec3::from(self.study.layout.real_centre);
        let start = DVec3::from(active.planned.start);
        let target = DVec3::from(active.planned.target);
        let (answer_cm, final_position, error_axes, signed) = match task.kind {
            TaskKind::Distance => {
                let Some(cm) = cm else {
                    return Err(Refusal("The distance task needs the answer in cm: {\"type\": \"answer\", \"trial\": N, \"cm\": number}.".into()));
                };
                if !cm.is_finite() || cm < 0.0 || cm > task.answer_max_cm {
                    return Err(Refusal(format!(
                        "The distance must be between 0 and {} cm, not {cm}.",
                        task.answer_max_cm
                    )));
                }
                let offset = start - real;
                let truth = offset.length() * 100.0;
                let signed = cm - truth;
                let axes = offset.normalize_or_zero() * signed;
                (Some(cm), None, axes, Some(signed))
            }
            TaskKind::Placement | TaskKind::Contact => {
                if cm.is_some() {
                    return Err(Refusal(format!(
                        "The {} task is answered by confirming the cube's position, without cm.",
                        task.kind.as_str()
                    )));
                }
                let error = (active.position - target) * 100.0;
                let signed = (task.kind == TaskKind::Contact).then_some(error.y);
                (None, Some(active.position.to_array()), error, signed)
            }
        };
        let error_cm = match task.kind {
            TaskKind::Distance => signed.unwrap_or(0.0).abs(),
            _ => error_axes.length(),
        };
        let now = Instant::now();
        // a response counts only after the participant saw the trial, and not sooner than
        // min_response_ms after its first frame appeared
        let Some((shown, shown_at)) = active.first_shown.clone() else {
            return Err(Refusal(format!("Trial {trial}'s picture has not been shown yet; wait for it, then answer.")));
        };
        let completion_ms = now.duration_since(shown).as_secs_f64() * 1e3;
        let minimum = self.study.study.min_response_ms;
        if completion_ms < f64::from(minimum) {
            return Err(Refusal(format!(
                "Trial {trial} was answered {completion_ms:.0} ms after its picture appeared, sooner than the study's minimum of {minimum} ms; look at the picture, then answer again."
            )));
        }
        let started_at = active.first_frame.as_ref().map(|(_, at)| at.clone()).unwrap_or_else(|| shown_at.clone());
        let mut latencies = active.latencies.clone();
        latencies.sort_by(f64::total_cmp);
        let result = TrialResult {
            participant: participant.id.clone(),
            trial,
            answer_cm,
            final_position,
            error_cm,
            signed_error_cm: signed,
            error_axes_cm: error_axes.to_array(),
            completion_ms,
            key_log: Value::Array(active.keys.clone()).to_string(),
            frames: active.frames,
            frame_ms_mean: mean(&active.frame_ms),
            frame_ms_max: active.frame_ms.iter().copied().reduce(f64::max),
            frames_shown: active.frames_shown,
            shown_frame_ms_mean: mean(&active.shown_frame_ms),
            paced_ms: active.paced_ms,
            frames_late: active.frames_late,
            shown_at,
            latency_ms_mean: mean(&latencies),
            latency_ms_p95: (!latencies.is_empty())
                .then(|| latencies[((latencies.len() as f64 * 0.95).ceil() as usize).clamp(1, latencies.len()) - 1]),
            smoothing: self.render_state.smoothing,
            adapter: self.lab.adapter.adapter.clone(),
            started_at,
        };
        let practice = active.planned.practice;
        let written = self.state.storage().write(TaskWrite::Result(result.clone())).await??;
        let TaskWritten::Result { answered, completed } = written else {
            return Err(AppError::Internal("storing a result wrote something else".into()).into());
        };
        self.answered = answered;
        self.active = None;
        self.acknowledged = None;
        let _ = self
            .send(json!({
                "type": "saved",
                "trial": trial,
                "answered": answered,
                "of": self.trials.len(),
                "completed": completed,
                "practice": practice,
                "error_cm": round3(result.error_cm),
                "error_x_cm": round3(result.error_axes_cm[0]),
                "error_y_cm": round3(result.error_axes_cm[1]),
                "error_z_cm": round3(result.error_axes_cm[2]),
                "completion_ms": round3(result.completion_ms),
                "frames": result.frames,
                "frames_shown": result.frames_shown,
                "frame_ms_mean": result.frame_ms_mean.map(round3),
                "latency_ms_mean": result.latency_ms_mean.map(round3),
            }))
            .await;
        if completed {
            let thanks = self.study.study.texts.thanks.clone();
            let _ = self.send(json!({"type": "done", "trials": self.trials.len(), "thanks": thanks})).await;
        }
        Ok(())
    }
}

fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

fn round3(value: f64) -> f64 {
    (value * 1000.0).round() / 1000.0
}

/// Now as UTC ISO 8601 with milliseconds, as the database stores times.
pub fn iso_now() -> String {
    store::iso(std::time::SystemTime::now())
}

#[cfg(test)]
mod tests {
    #[test]
    fn iso_now_looks_like_sqlite_time() {
        let now = super::iso_now();
        assert_eq!(now.len(), 24, "{now}");
        assert!(now.starts_with("20") && now.ends_with('Z') && &now[10..11] == "T", "{now}");
    }
}
