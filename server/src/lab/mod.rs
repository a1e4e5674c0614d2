//! Lab task studies (`kind = "task"`, the thesis's Section 6.3 study in a browser): study files
//! (`crate::study::task`), counterbalanced condition orders ([`williams`]), per-participant schedules
//! ([`plan`]), the live renderer thread ([`live`]), the WebSocket session that runs trials
//! ([`session`]) and who may open one ([`admission`]), storage ([`store`]), and the export and
//! admin page ([`results`]).
//!
//! `serve` starts the lab when the studies directory has task studies: [`start`] opens the GPU
//! on the renderer thread, chooses each study's live size ([`size`]: measured on a software
//! adapter when `render.size` is not set), prepares its scene and photograph, measures the frame time
//! of every condition ([`timing`]), and says in one line per study whether every condition is
//! fast enough for interactive rates and whether the conditions' frame times are equal; when
//! they differ by more than 20 % it adds one line per condition with its frame time.
//! Without a GPU adapter the task studies are not served and one warning line says why; the
//! other studies are served as usual.

pub mod admission;
pub mod join;
pub mod live;
pub mod plan;
pub mod results;
pub mod session;
pub mod size;
pub mod store;
pub mod timing;
pub mod williams;

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};

use askama::Template;
use axum::Router;
use axum::extract::{Path as UrlPath, State};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;

use crate::AppState;
use crate::error::AppError;
use crate::storage::Storage;
use crate::study::task::{Pace, TaskStudy};
use live::{AdapterInfo, LabRenderer};
use plan::Layout;
use timing::{FrameTimes, PARITY_TOLERANCE};

/// A task study being served.
pub struct LabStudy {
    pub study: Arc<TaskStudy>,
    pub layout: Layout,
    /// Live frame size.
    pub size: [u32; 2],
    /// Frame times per condition: measured at start-up, then kept up to date by every live frame.
    pub frame_times: Mutex<FrameTimes>,
}

/// One condition's frame time for the admin page.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ConditionRate {
    pub condition: String,
    pub startup_ms: f64,
    pub current_ms: f64,
    pub live_frames: u64,
    pub live_mean_ms: Option<f64>,
    /// Whether the current frame time reaches `render.min_fps`.
    pub fast_enough: bool,
    /// How much slower than the fastest condition, percent (0 for the fastest).
    pub slower_than_fastest_pct: f64,
}

fn fps_text(ms: f64) -> String {
    if ms > 1.0 { format!("≈{:.1} frames/s", 1000.0 / ms) } else { "over 1000 frames/s".into() }
}

impl LabStudy {
    pub fn new(study: TaskStudy, layout: Layout, size: [u32; 2], frame_times: FrameTimes) -> LabStudy {
        LabStudy { study: Arc::new(study), layout, size, frame_times: Mutex::new(frame_times) }
    }

    /// A copy of the current frame times.
    pub fn frame_times(&self) -> FrameTimes {
        self.frame_times.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).clone()
    }

    /// Records a live frame's time.
    pub fn record_frame(&self, condition: crate::study::task::Condition, ms: f64) {
        self.frame_times.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).record(condition, ms);
    }

    /// The frame time every frame is held to (`pace = "equal"`), ms; None when not paced.
    pub fn pace_ms(&self) -> Option<f64> {
        (self.study.render.pace == Pace::Equal).then(|| self.frame_times().pace_ms())
    }

    fn budget_ms(&self) -> f64 {
        1000.0 / self.study.render.min_fps
    }

    /// Each condition's frame time, start-up and current, for the admin page.
    pub fn condition_rates(&self) -> Vec<ConditionRate> {
        let summary = self.frame_times().summary();
        let fastest = summary.iter().map(|c| c.current_ms).fold(f64::INFINITY, f64::min);
        summary
            .into_iter()
            .map(|c| ConditionRate {
                fast_enough: c.current_ms <= self.budget_ms(),
                slower_than_fastest_pct: if fastest > 0.0 && fastest.is_finite() {
                    (c.current_ms / fastest - 1.0) * 100.0
                } else {
                    0.0
                },
                condition: c.condition,
                startup_ms: c.startup_ms,
                current_ms: c.current_ms,
                live_frames: c.live_frames,
                live_mean_ms: c.live_mean_ms,
            })
            .collect()
    }

    /// Whether every condition reaches `render.min_fps`.
    pub fn interactive(&self) -> bool {
        self.condition_rates().iter().all(|c| c.fast_enough)
    }

    /// Whether the conditions' frame times differ by more than 20 %.
    pub fn unequal(&self) -> bool {
        self.frame_times().unequal()
    }

    /// One sentence on the frame rates, for `serve`'s output and the admin page.
    pub fn rate_line(&self, adapter: &AdapterInfo) -> String {
        let rates = self.condition_rates();
        let per_condition =
            rates.iter().map(|c| format!("{} {:.1} ms", c.condition, c.current_ms)).collect::<Vec<_>>().join(", ");
        let slowest = rates.iter().map(|c| c.current_ms).fold(0.0, f64::max);
        let slow: Vec<&str> = rates.iter().filter(|c| !c.fast_enough).map(|c| c.condition.as_str()).collect();
        let speed = if slow.is_empty() {
            format!(
                "fast enough for interactive use in every condition (minimum {} frames/s)",
                self.study.render.min_fps
            )
        } else {
            format!(
                "TOO SLOW for interactive rates in condition {} (minimum {} frames/s); participants will see the cube lag behind their keys — use a GPU or a smaller render.size",
                slow.join(", "),
                self.study.render.min_fps
            )
        };
        let spread = self.frame_times().spread() * 100.0;
        // Paced frames come no faster than the pace: say so when that is below the minimum.
        let paced_speed = |pace: f64| {
            let fps = 1000.0 / pace.max(1e-3);
            if fps < self.study.render.min_fps {
                format!(
                    " (≈{fps:.1} frames/s in every condition, below the minimum of {} frames/s: use a GPU or a smaller render.size)",
                    self.study.render.min_fps
                )
            } else {
                format!(" (≈{fps:.1} frames/s in every condition)")
            }
        };
        let parity = match (self.unequal(), self.pace_ms()) {
            (false, None) => {
                format!("the conditions' frame times are within {:.0} % of each other", PARITY_TOLERANCE * 100.0)
            }
            (false, Some(pace)) => format!(
                "the conditions' frame times are within {:.0} % of each other, and pace = \"equal\" sends every frame at {pace:.1} ms{}",
                PARITY_TOLERANCE * 100.0,
                paced_speed(pace)
            ),
            (true, Some(pace)) => format!(
                "the conditions differ by {spread:.0} % in frame time; pace = \"equal\" sends every condition's frames at {pace:.1} ms ({headroom}× the slowest condition's {quantile:.0}th-percentile frame time){}, so lag does not tell them apart",
                paced_speed(pace),
                headroom = timing::PACE_HEADROOM,
                quantile = timing::PACE_QUANTILE * 100.0
            ),
            (true, None) => format!(
                "the conditions differ by {spread:.0} % in frame time, so condition is confounded with lag — set pace = \"equal\" in the study file to send every condition's frames at the slowest's"
            ),
        };
        format!(
            "lab study \"{}\": adapter {} ({}) renders {}×{} frames in {per_condition} (slowest {}); {speed}; {parity}",
            self.study.slug,
            adapter.adapter,
            adapter.kind,
            self.size[0],
            self.size[1],
            fps_text(slowest)
        )
    }

    /// When the conditions' frame times differ by more than 20 %: one line per condition with
    /// its frame time; else none.
    pub fn condition_lines(&self) -> Vec<String> {
        if !self.unequal() {
            return Vec::new();
        }
        let rates = self.condition_rates();
        let fastest = rates
            .iter()
            .min_by(|a, b| a.current_ms.total_cmp(&b.current_ms))
            .map(|c| c.condition.clone())
            .unwrap_or_default();
        rates
            .iter()
            .map(|c| {
                let relative = if c.condition == fastest {
                    "the fastest condition".to_string()
                } else {
                    format!("{:.0} % slower than {fastest}", c.slower_than_fastest_pct)
                };
                format!(
                    "lab study \"{}\", condition \"{}\": {:.1} ms a frame ({}), {relative}",
                    self.study.slug,
                    c.condition,
                    c.current_ms,
                    fps_text(c.current_ms)
                )
            })
            .collect()
    }
}

/// The running lab: the renderer thread and the task studies it serves.
pub struct Lab {
    pub renderer: LabRenderer,
    pub adapter: AdapterInfo,
    pub studies: HashMap<String, Arc<LabStudy>>,
    /// Slugs in load order.
    pub order: Vec<String>,
    /// Live WebSocket sessions, at most [`admission::MAX_SESSIONS`].
    pub sessions: Arc<std::sync::atomic::AtomicUsize>,
    /// A session without a message for this long is closed, in ms (see [`Lab::idle_timeout`]).
    idle_timeout_ms: std::sync::atomic::AtomicU64,
    /// Open sessions per client address (see [`admission::SessionSlot`]).
    pub(crate) by_address: Mutex<HashMap<std::net::IpAddr, usize>>,
    /// At most this many open sessions per client address; 0: no cap.
    sessions_per_address: std::sync::atomic::AtomicUsize,
    /// The origins (`scheme://host[:port]`, lower case) whose pages may open a session.
    origins: std::sync::RwLock<Vec<String>>,
}

/// The lab's settings on the open internet: `mrstudy serve`'s flags (the binary holds their
/// clap definitions).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LabConfig {
    /// An origin (`https://lab.example.org`, `http://192.0.2.7:8080`) whose pages may open lab
    /// sessions, besides the address serve listens on (and, on a loopback or wildcard address,
    /// `http://localhost:PORT` and `http://127.0.0.1:PORT`); repeat for more. A browser's
    /// WebSocket from any other origin is refused (403), whatever its Host.
    pub origins: Vec<String>,
    /// Open lab sessions per client address; 0: no cap.
    pub sessions_per_address: usize,
}

impl Default for LabConfig {
    fn default() -> LabConfig {
        LabConfig { origins: Vec::new(), sessions_per_address: session::SESSIONS_PER_ADDRESS }
    }
}

/// An `--origin` value that is not an origin.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
#[error("`{text}` is not an origin: expected http:// or https://, a host, an optional port, and nothing after")]
pub struct OriginError {
    pub text: String,
}

/// `--origin`'s value, normalised ([`normalise_origin`]).
pub fn parse_origin(text: &str) -> Result<String, OriginError> {
    normalise_origin(text).ok_or_else(|| OriginError { text: text.to_string() })
}

/// `origin` as the lab compares origins: lower case, without a trailing slash; None when it is
/// not `http://…` or `https://…` with a host and nothing after it.
pub fn normalise_origin(origin: &str) -> Option<String> {
    let origin = origin.trim().trim_end_matches('/').to_ascii_lowercase();
    let (scheme, rest) = origin.split_once("://")?;
    let fine = matches!(scheme, "http" | "https")
        && !rest.is_empty()
        && !rest.contains(['/', '?', '#', '@'])
        && !rest.chars().any(|c| c.is_whitespace() || c.is_control());
    fine.then_some(origin)
}

impl LabConfig {
    /// The origins allowed when serve listens on `local`: the configured ones, the listening
    /// address's, and on a loopback or wildcard address `localhost` and `127.0.0.1` with its
    /// port.
    pub fn allowed_origins(&self, local: std::net::SocketAddr) -> Vec<String> {
        let mut origins: Vec<String> = self.origins.iter().filter_map(|origin| normalise_origin(origin)).collect();
        origins.push(format!("http://{local}"));
        if local.ip().is_loopback() || local.ip().is_unspecified() {
            origins.push(format!("http://localhost:{}", local.port()));
            origins.push(format!("http://127.0.0.1:{}", local.port()));
        }
        origins.sort();
        origins.dedup();
        origins
    }
}

impl Lab {
    /// How long a session may go without a message from its client before it is closed.
    pub fn idle_timeout(&self) -> std::time::Duration {
        std::time::Duration::from_millis(self.idle_timeout_ms.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// Sets [`Lab::idle_timeout`] (`serve --lab-idle-timeout`; at least a millisecond).
    pub fn set_idle_timeout(&self, timeout: std::time::Duration) {
        let ms = u64::try_from(timeout.as_millis()).unwrap_or(u64::MAX).max(1);
        self.idle_timeout_ms.store(ms, std::sync::atomic::Ordering::Relaxed);
    }

    /// At most `n` open sessions per client address (`serve --lab-sessions-per-address`); 0: no
    /// cap. Requests that did not come over a socket (the router driven in-process) have no
    /// address and are not capped.
    pub fn set_sessions_per_address(&self, n: usize) {
        self.sessions_per_address.store(n, std::sync::atomic::Ordering::Relaxed);
    }

    pub fn sessions_per_address(&self) -> usize {
        self.sessions_per_address.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// The origins whose pages may open a session ([`LabConfig::allowed_origins`]); until this
    /// is called none may (a client without `Origin`, not a browser, always may).
    pub fn set_origins(&self, origins: Vec<String>) {
        let origins = origins.iter().filter_map(|origin| normalise_origin(origin)).collect();
        *self.origins.write().unwrap_or_else(|poisoned| poisoned.into_inner()) = origins;
    }

    /// Whether a request's `Origin` (if it has one) may open a session: one of the configured
    /// origins exactly, never inferred from the request's own `Host` (DNS rebinding).
    pub fn origin_allowed(&self, origin: Option<&str>) -> bool {
        let Some(origin) = origin else { return true };
        let Some(origin) = normalise_origin(origin) else { return false };
        self.origins.read().unwrap_or_else(|poisoned| poisoned.into_inner()).contains(&origin)
    }
}

/// What starting the lab gave: the lab (if any study is served) and the lines to print.
pub struct LabStart {
    pub lab: Option<Lab>,
    /// Informational lines (frame rates of interactive studies).
    pub info: Vec<String>,
    /// Warning lines (no adapter, too slow, a study that could not be prepared).
    pub warnings: Vec<String>,
}

/// Frames rendered per condition when the lab starts (after one warm-up frame each).
pub const STARTUP_FRAMES: usize = 12;

/// Starts the renderer thread and prepares every task study (see the module doc). Never fails:
/// what cannot be served is reported in `warnings`.
pub async fn start(studies: Vec<TaskStudy>, data_dir: &Path, storage: &Storage) -> LabStart {
    let mut start = LabStart { lab: None, info: Vec::new(), warnings: Vec::new() };
    if studies.is_empty() {
        return start;
    }
    let names = studies.iter().map(|study| format!("\"{}\"", study.slug)).collect::<Vec<_>>().join(", ");
    let renderer = match tokio::task::spawn_blocking(LabRenderer::start).await {
        Ok(Ok(renderer)) => renderer,
        Ok(Err(reason)) => {
            start.warnings.push(format!("task study {names} not served: the live renderer needs a GPU adapter and none could be opened ({reason})"));
            return start;
        }
        Err(error) => {
            start
                .warnings
                .push(format!("task study {names} not served: the renderer thread failed to start ({error})"));
            return start;
        }
    };
    let adapter = renderer.adapter.clone();
    let cache = data_dir.join("lab");
    let mut served = HashMap::new();
    let mut order = Vec::new();
    for study in studies {
        let size = match study.render.size {
            Some(size) => size,
            None if adapter.is_software() => {
                match size::auto_size(&renderer, &study, &size::LADDER, size::LADDER_FRAMES).await {
                    Ok(auto) => {
                        let line = auto.line(&study.slug, &adapter, study.render.pace);
                        if auto.reached() {
                            start.info.push(line)
                        } else {
                            start.warnings.push(line)
                        }
                        auto.size
                    }
                    Err(reason) => {
                        start.warnings.push(format!(
                            "study \"{}\": the renderer cannot make the frames that choose its size ({reason}); not serving it",
                            study.slug
                        ));
                        continue;
                    }
                }
            }
            None => size::HARDWARE_SIZE,
        };
        let cache_dir = cache.clone();
        let prepared = tokio::task::spawn_blocking(move || {
            live::prepare_scene(&study, size, Some(&cache_dir)).map(|scene| (study, scene))
        })
        .await;
        let (study, scene) = match prepared {
            Ok(Ok(prepared)) => prepared,
            Ok(Err(reason)) => {
                start.warnings.push(format!("{reason}; not serving it"));
                continue;
            }
            Err(error) => {
                start.warnings.push(format!("a task study could not be prepared ({error}); not serving it"));
                continue;
            }
        };
        let layout = scene.layout;
        let size = [scene.scene.camera.width, scene.scene.camera.height];
        let centre = [layout.real_centre[0] + 0.12, layout.real_centre[1], layout.real_centre[2]];
        if let Err(reason) = renderer.register(scene) {
            start.warnings.push(format!("study \"{}\": {reason}; not serving it", study.slug));
            continue;
        }
        let measured = match live::measure(&renderer, &study, centre, STARTUP_FRAMES).await {
            Ok(measured) => measured,
            Err(reason) => {
                start.warnings.push(format!(
                    "study \"{}\": the renderer cannot make its frames ({reason}); not serving it",
                    study.slug
                ));
                continue;
            }
        };
        if let Err(error) = store::upsert_study(storage, &study).await {
            start
                .warnings
                .push(format!("study \"{}\": cannot record it in the database ({error}); not serving it", study.slug));
            continue;
        }
        let lab_study = LabStudy::new(study, layout, size, FrameTimes::new(measured));
        let medians = lab_study.frame_times().current();
        if let Err(error) =
            store::record_frame_times(storage, &lab_study.study.slug, &adapter.adapter, size, STARTUP_FRAMES, &medians)
                .await
        {
            start.warnings.push(format!(
                "study \"{}\": cannot record its frame times in the database ({error})",
                lab_study.study.slug
            ));
        }
        let mut lines = vec![lab_study.rate_line(&adapter)];
        lines.extend(lab_study.condition_lines());

        // unequal frame times are a warning unless frames are paced
        if lab_study.interactive() && (!lab_study.unequal() || lab_study.pace_ms().is_some()) {
            start.info.extend(lines);
        } else {
            start.warnings.extend(lines);
        }
        if !adapter.is_software() {
            let named: Vec<(String, f64)> =
                medians.iter().map(|(condition, ms)| (condition.to_string(), *ms)).collect();
            // below the display's rate is said, not warned: render.min_fps is the warnings' threshold
            start.info.push(size::display_rate_line(&lab_study.study.slug, &adapter, size, &named));
        }
        order.push(lab_study.study.slug.clone());
        served.insert(lab_study.study.slug.clone(), Arc::new(lab_study));
    }
    if !served.is_empty() {
        start.lab = Some(Lab {
            renderer,
            adapter,
            studies: served,
            order,
            sessions: Default::default(),
            idle_timeout_ms: std::sync::atomic::AtomicU64::new(session::IDLE_TIMEOUT.as_millis() as u64),
            by_address: Default::default(),
            sessions_per_address: std::sync::atomic::AtomicUsize::new(session::SESSIONS_PER_ADDRESS),
            origins: Default::default(),
        });
    }
    start
}

pub fn router() -> Router<AppState> {
    Router::new()
        .route("/lab/{slug}", get(lab_page))
        .route("/api/lab/{slug}/participants", axum::routing::post(join::create_participant))
        .route("/api/lab/{slug}/ws", get(session::websocket))
        .merge(results::router())
}

#[derive(Template)]
#[template(path = "lab.html")]
struct LabPage<'a> {
    slug: &'a str,
    title: &'a str,
    welcome: Vec<&'a str>,
    instructions: Vec<&'a str>,
}

fn paragraphs(text: &str) -> Vec<&str> {
    text.split("\n\n").map(str::trim).filter(|p| !p.is_empty()).collect()
}

async fn lab_page(State(state): State<AppState>, UrlPath(slug): UrlPath<String>, uri: axum::http::Uri) -> Response {
    if let Some(title) = state.preparation().lab_starting(&slug) {
        return crate::pages::opens_soon_page(&title, 30);
    }
    let Some(lab) = state.lab() else { return crate::pages::not_found(uri).await };
    let Some(study) = lab.studies.get(&slug) else { return crate::pages::not_found(uri).await };
    let page = LabPage {
        slug: &study.study.slug,
        title: &study.study.title,
        welcome: paragraphs(&study.study.texts.welcome),
        instructions: paragraphs(&study.study.texts.instructions),
    };
    match page.render() {
        Ok(html) => Html(html).into_response(),
        Err(error) => AppError::Internal(format!("lab page: {error}")).into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::{LabConfig, normalise_origin};

    #[test]
    fn origins_are_compared_in_lower_case_without_a_trailing_slash_and_nothing_else_passes() {
        assert_eq!(normalise_origin("HTTPS://Lab.Example.org/").as_deref(), Some("https://lab.example.org"));
        assert_eq!(normalise_origin("http://192.0.2.7:8080").as_deref(), Some("http://192.0.2.7:8080"));
        for bad in ["lab.example.org", "ftp://lab.example.org", "https://", "https://a/b", "https://u@a", "null", ""] {
            assert_eq!(normalise_origin(bad), None, "{bad}");
        }
    }

    #[test]
    fn the_allowed_origins_are_the_configured_ones_and_the_listening_address() {
        let config = LabConfig { origins: vec!["https://lab.example.org".into()], sessions_per_address: 8 };
        let loopback = config.allowed_origins("127.0.0.1:8080".parse().unwrap());
        assert_eq!(loopback, ["http://127.0.0.1:8080", "http://localhost:8080", "https://lab.example.org"]);
        let public = config.allowed_origins("192.0.2.7:80".parse().unwrap());
        assert_eq!(public, ["http://192.0.2.7:80", "https://lab.example.org"]);
    }
}
