//! `mrstudy-server`: the study server — study files, trial scheduling, sqlite storage through
//! sqlx, the participant pages, the admin API and pages, export, and the `serve` entry point
//! the CLI calls (its load generator, `mrstudy bench server`, is in the `mrstudy-bench` crate).
//!
//! Invariant: only this crate and the CLI touch the network and the database.
//!
//! Map: [`study`] reads and checks study files; [`schedule`] makes a participant's trial
//! schedule from a stored seed; [`prepared`] copies stimuli into the content-addressed store;
//! [`storage`] is the database (migrations, the group-committing writer, reads); [`participant`]
//! and [`admin`] are the two areas of the HTTP API, each with its own `router()`, and [`pages`]
//! the HTML pages built on them; [`lab`] the lab runtime of task studies (live renderer, WebSocket
//! sessions, results); [`export`] writes the trials CSV and JSON; [`serve`] starts
//! everything from a data directory; [`simulate`] plans a study by running its scheduler and
//! analysis on simulated observers. [`app`] builds the router apart from any socket, so tests
//! drive it with `oneshot`. [`console`] prints what the CLI's commands say and draws their
//! progress bars.
//!
//! [`stimuli`] renders the stimuli of studies that name scenes for the renderer (photograph by
//! the path tracer, frame by the GPU renderer) into the store, only those that are missing;
//! `serve` does so in the background once listening, and [`preparing`] tracks those studies
//! (progress, estimate) until [`AppState::install`] serves them.
//! Task studies run in the lab against the live renderer ([`lab`]): `serve` starts them in the
//! background once listening.

// the live renderer's GPU types (wgpu-core's, through the renderer's pool of buffers and
// textures) nest deeper than the default limit when the compiler checks that the server's
// futures are Send
#![recursion_limit = "256"]

pub mod admin;
pub mod auth;
pub mod connections;
pub mod console;
pub mod error;
pub mod export;
pub mod lab;
pub mod limits;
pub mod live_analysis;
pub mod logs;
pub mod pages;
pub mod parse_errors;
pub mod participant;
pub mod prepared;
pub mod preparing;
pub mod rating;
pub mod render_queue;
pub mod schedule;
pub mod serve;
pub mod simulate;
pub mod stimuli;
pub mod storage;
pub mod study;
pub mod threshold;
pub mod trial;

#[cfg(test)]
#[path = "../tests/support/lab_study.rs"]
mod lab_study_fixture;

use std::path::PathBuf;
use std::sync::Arc;

use axum::Router;
use axum::extract::{DefaultBodyLimit, Request};
use axum::http::{HeaderValue, header};
use axum::middleware::{self, Next};
use axum::response::Response;

pub use error::AppError;
pub use prepared::{PreparedStudy, Studies};
pub use storage::Storage;

/// Largest request body accepted, in bytes.
pub const BODY_LIMIT_BYTES: usize = 16 * 1024;

/// Shared state of the HTTP handlers.
#[derive(Clone)]
pub struct AppState {
    inner: Arc<StateInner>,
}

struct StateInner {
    storage: Storage,
    /// Every study served or being prepared, by slug; a study is served once its slot holds it.
    studies: std::collections::HashMap<String, StudySlot>,
    /// Slugs in the order the studies were loaded (those being prepared last).
    order: Vec<String>,
    /// The studies whose stimuli are still being rendered, and the lab while it starts.
    preparation: preparing::Preparation,
    admin_token_sha256: [u8; 32],
    stimuli_dir: PathBuf,
    /// Participants' credentials by id, filled on first use (they never change).
    credentials: std::sync::Mutex<std::collections::HashMap<String, participant::Credentials>>,
    /// The lab (task studies and the live renderer), once started (see [`lab::start`]).
    lab: std::sync::OnceLock<Arc<lab::Lab>>,
    /// What one client address may do, and how much it has done.
    limits: limits::Limits,
    buckets: limits::Buckets,
    /// One admin API call at a time ([`limits::limit`]).
    admin_work: tokio::sync::Semaphore,
    /// Refusals counted per kind ([`logs`]).
    refusals: logs::Refusals,
    /// Levels of on-demand threshold studies rendered when first needed.
    render_queue: render_queue::RenderQueue,
}

/// A study served or being prepared: set once, when it is served ([`AppState::install`]).
#[derive(Default)]
struct StudySlot {
    prepared: std::sync::OnceLock<Arc<PreparedStudy>>,
    /// The shared posterior of a study with an active design (set before `prepared`).
    active: std::sync::OnceLock<Option<tokio::sync::Mutex<participant::active::ActiveState>>>,
}

impl StudySlot {
    fn served(prepared: Arc<PreparedStudy>) -> StudySlot {
        let slot = StudySlot::default();
        let _ = slot.active.set(participant::active::active_state(&prepared));
        let _ = slot.prepared.set(prepared);
        slot
    }
}

impl AppState {
    pub fn new(
        storage: Storage,
        studies: Vec<Arc<PreparedStudy>>,
        admin_token: &str,
        stimuli_dir: PathBuf,
    ) -> AppState {
        let order = studies.iter().map(|study| study.study.slug.clone()).collect();
        // on PostgreSQL every process of the database counts against the same buckets
        let buckets = match storage.backend() {
            storage::Backend::Postgres => limits::Buckets::shared(storage.read.clone()),
            storage::Backend::Sqlite => limits::Buckets::default(),
        };
        AppState {
            inner: Arc::new(StateInner {
                storage,
                studies: studies
                    .into_iter()
                    .map(|study| (study.study.slug.clone(), StudySlot::served(study)))
                    .collect(),
                order,
                preparation: Default::default(),
                admin_token_sha256: auth::sha256(admin_token.as_bytes()),
                stimuli_dir: stimuli_dir.clone(),
                credentials: Default::default(),
                lab: std::sync::OnceLock::new(),
                limits: limits::Limits::default(),
                buckets,
                admin_work: tokio::sync::Semaphore::new(1),
                refusals: Default::default(),
                render_queue: render_queue::RenderQueue::new(stimuli_dir.clone()),
            }),
        }
    }

    /// This state with other limits per client; only before it is shared (it panics after).
    pub fn with_limits(mut self, limits: limits::Limits) -> AppState {
        Arc::get_mut(&mut self.inner).expect("limits are set before the state is shared").limits = limits;
        self
    }

    /// This state with studies still to prepare: (slug, title, stimuli to render) each, served
    /// once [`AppState::install`] is given them; only before it is shared (it panics after).
    pub fn with_pending(mut self, pending: impl IntoIterator<Item = (String, String, usize)>) -> AppState {
        let inner = Arc::get_mut(&mut self.inner).expect("pending studies are added before the state is shared");
        for (slug, title, stimuli) in pending {
            inner.preparation.add(&slug, &title, stimuli);
            inner.studies.insert(slug.clone(), StudySlot::default());
            inner.order.push(slug);
        }
        self
    }

    /// Serves a study added by [`AppState::with_pending`], now that its stimuli are complete;
    /// false if it was not pending.
    pub fn install(&self, prepared: Arc<PreparedStudy>) -> bool {
        let slug = prepared.study.slug.clone();
        let Some(slot) = self.inner.studies.get(&slug) else { return false };
        if slot.prepared.get().is_some() {
            return false;
        }
        let _ = slot.active.set(participant::active::active_state(&prepared));
        let installed = slot.prepared.set(prepared).is_ok();
        self.inner.preparation.remove(&slug);
        installed
    }

    /// The render queue of on-demand threshold studies ([`render_queue`]).
    pub fn render_queue(&self) -> &render_queue::RenderQueue {
        &self.inner.render_queue
    }

    /// The studies being prepared (and the lab while it starts).
    pub fn preparation(&self) -> &preparing::Preparation {
        &self.inner.preparation
    }

    pub fn limits(&self) -> limits::Limits {
        self.inner.limits
    }

    pub(crate) fn buckets(&self) -> &limits::Buckets {
        &self.inner.buckets
    }

    /// Refusals (4xx, 503) counted per status and route template since the start.
    pub fn refusals(&self) -> &logs::Refusals {
        &self.inner.refusals
    }

    pub(crate) fn admin_work(&self) -> &tokio::sync::Semaphore {
        &self.inner.admin_work
    }

    pub fn storage(&self) -> &Storage {
        &self.inner.storage
    }

    /// The study `slug` if it is served (not while its stimuli are being prepared).
    pub fn study(&self, slug: &str) -> Option<&Arc<PreparedStudy>> {
        self.inner.studies.get(slug)?.prepared.get()
    }

    /// The stimulus metrics of served study `slug` as they are now: an on-demand threshold
    /// study's are read again from the store after each level rendered since it was prepared
    /// ([`render_queue::RenderQueue::metrics`]); the others' are those read when prepared.
    pub fn stimulus_metrics(&self, slug: &str) -> Option<Arc<stimuli::StimulusMetricsNow>> {
        let prepared = self.study(slug)?;
        self.render_queue().metrics(slug).or_else(|| {
            Some(Arc::new(stimuli::StimulusMetricsNow {
                csv: prepared.metrics_csv.clone(),
                notes: prepared.metrics_notes.clone(),
                metrics: prepared.stimulus_metrics.clone(),
            }))
        })
    }

    /// The served study `slug`: while its stimuli are being prepared a 503 saying it opens in
    /// a few minutes ([`AppError::OpensSoon`]), else (not served) a 404.
    pub fn served_study(&self, slug: &str) -> Result<Arc<PreparedStudy>, AppError> {
        if let Some(prepared) = self.study(slug) {
            return Ok(prepared.clone());
        }
        if self.inner.preparation.pending(slug).is_some() {
            return Err(AppError::OpensSoon { retry_after_seconds: self.inner.preparation.retry_after(slug) });
        }
        Err(AppError::NotFound(format!("There is no study \"{slug}\".")))
    }

    /// The shared state of a study with an active design.
    pub fn active(&self, slug: &str) -> Option<&tokio::sync::Mutex<participant::active::ActiveState>> {
        self.inner.studies.get(slug)?.active.get()?.as_ref()
    }

    /// The served studies in load order.
    pub fn studies(&self) -> impl Iterator<Item = &Arc<PreparedStudy>> {
        self.inner.order.iter().filter_map(|slug| self.study(slug))
    }

    /// The lab, once it has started and serves at least one task study.
    pub fn lab(&self) -> Option<Arc<lab::Lab>> {
        self.inner.lab.get().cloned()
    }

    /// Installs the started lab; false if one was installed before.
    pub fn set_lab(&self, lab: lab::Lab) -> bool {
        self.inner.lab.set(Arc::new(lab)).is_ok()
    }

    pub fn stimuli_dir(&self) -> &std::path::Path {
        &self.inner.stimuli_dir
    }

    pub(crate) fn cached_credentials(&self, id: &str) -> Option<participant::Credentials> {
        self.inner.credentials.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).get(id).cloned()
    }

    pub(crate) fn cache_credentials(&self, credentials: participant::Credentials) {
        let mut cache = self.inner.credentials.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        // Bounded: a study server with more live participants than this just reads the database.
        if cache.len() >= 1_000_000 {
            cache.clear();
        }
        cache.insert(credentials.id.clone(), credentials);
    }

    /// Drops a deleted participant's credentials from the cache.
    pub(crate) fn forget_credentials(&self, id: &str) {
        self.inner.credentials.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).remove(id);
    }

    /// Whether `token` is the admin token (compared by hash, in constant time).
    pub fn is_admin_token(&self, token: &str) -> bool {
        auth::constant_time_eq(&auth::sha256(token.as_bytes()), &self.inner.admin_token_sha256)
    }
}

/// An `/api/` error that did not come from [`AppError`] (axum's own 405, 413, 408, a 404 of a
/// route that does not exist) gets the API's body too: `{"error": sentence}`.
fn api_error_as_json(response: Response, method: &axum::http::Method) -> Response {
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|value| value.to_str().ok())
        .is_some_and(|value| value.starts_with("application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return response;
    }
    use axum::http::StatusCode;
    let sentence = match status {
        StatusCode::METHOD_NOT_ALLOWED => format!("This address does not accept {method} requests."),
        StatusCode::PAYLOAD_TOO_LARGE => error::body_too_large(),
        StatusCode::UNSUPPORTED_MEDIA_TYPE => error::NEEDS_JSON.into(),
        StatusCode::REQUEST_TIMEOUT => "The request body did not arrive in time.".into(),
        StatusCode::TOO_MANY_REQUESTS => "Too many requests from this address; try again in a minute.".into(),
        StatusCode::NOT_FOUND => "There is no such API address.".into(),
        status if status.is_server_error() => "The server could not complete the request.".into(),
        status => format!("The request was refused ({}).", status.canonical_reason().unwrap_or("client error")),
    };
    let (mut parts, _) = response.into_parts();
    parts.headers.remove(header::CONTENT_LENGTH);
    parts.headers.insert(header::CONTENT_TYPE, HeaderValue::from_static("application/json"));
    Response::from_parts(parts, axum::body::Body::from(serde_json::json!({ "error": sentence }).to_string()))
}

/// `n` random bytes from the operating system, hex-encoded.
pub(crate) fn random_hex(n: usize) -> String {
    let mut bytes = vec![0u8; n];
    getrandom::fill(&mut bytes).expect("the operating system's random number generator works");
    hex::encode(bytes)
}

/// The whole application: participant API and pages, admin API and pages, static files and
/// stimuli, with security headers, the body size limit, the limits per client ([`limits`]),
/// refusals counted and one log line per request ([`logs`]).
pub fn app(state: AppState) -> Router {
    let router = Router::new()
        .merge(participant::router())
        .merge(admin::router())
        .merge(pages::router())
        .merge(lab::router())
        .merge(logs::router())
        .fallback(pages::not_found)
        .layer(DefaultBodyLimit::max(BODY_LIMIT_BYTES))
        .layer(middleware::from_fn_with_state(state.clone(), limits::limit))
        .layer(middleware::from_fn(security_headers))
        .layer(middleware::from_fn_with_state(state.clone(), logs::count_refusals));
    logs::trace(router).with_state(state)
}

/// Content-Security-Policy of every response: only this origin's scripts, styles and images,
/// no framing, no plugins.
pub const CONTENT_SECURITY_POLICY: &str = "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'";

async fn security_headers(request: Request, next: Next) -> Response {
    let is_api = request.uri().path().starts_with("/api/");
    let method = request.method().clone();
    let mut response = next.run(request).await;
    if is_api {
        response = api_error_as_json(response, &method);
    }
    let headers = response.headers_mut();
    headers.entry(header::CONTENT_SECURITY_POLICY).or_insert(HeaderValue::from_static(CONTENT_SECURITY_POLICY));
    headers.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    headers.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    headers.insert(header::REFERRER_POLICY, HeaderValue::from_static("no-referrer"));
    headers.insert("cross-origin-opener-policy", HeaderValue::from_static("same-origin"));
    if is_api || !headers.contains_key(header::CACHE_CONTROL) {
        headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    }
    response
}
