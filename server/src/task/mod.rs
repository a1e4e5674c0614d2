//! Lab task studies (`kind = "task"`, the thesis's Section 6.3 study in a browser): study files
//! ([`study`]), counterbalanced condition orders ([`williams`]), per-participant schedules
//! ([`plan`]), the live renderer thread ([`live`]), the WebSocket session that runs trials
//! ([`session`]), storage ([`store`]), and the export and admin page ([`results`]).
//!
//! `serve` starts the lab when the studies directory has task studies: [`start`] opens the GPU
//! on the renderer thread, prepares each study's scene and photograph, measures the frame time,
//! and says in one line per study whether the adapter is fast enough for interactive rates.
//! Without a GPU adapter the task studies are not served and one warning line says why; the
//! other studies are served as usual.

pub mod live;
pub mod plan;
pub mod results;
pub mod session;
pub mod store;
pub mod study;
pub mod williams;

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use askama::Template;
use axum::Router;
use axum::extract::{Path as UrlPath, State};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;

use crate::AppState;
use crate::error::AppError;
use crate::storage::Storage;
use live::{AdapterInfo, LabRenderer};
use plan::Layout;
use study::TaskStudy;

/// A task study being served.
pub struct LabStudy {
    pub study: Arc<TaskStudy>,
    pub layout: Layout,
    /// Live frame size.
    pub size: [u32; 2],
    /// Median frame time (render + encode, condition gi) measured at start-up, ms.
    pub frame_ms: f64,
    /// Whether that reaches the study's `render.min_fps`.
    pub interactive: bool,
}

impl LabStudy {
    /// One sentence on the frame rate, for `serve`'s output and the admin page.
    pub fn rate_line(&self, adapter: &AdapterInfo) -> String {
        let fps = if self.frame_ms > 0.0 { 1000.0 / self.frame_ms } else { f64::INFINITY };
        if self.interactive {
            format!(
                "lab study \"{}\": adapter {} ({}) renders {}×{} frames in {:.1} ms (≈{:.0} frames/s), fast enough for interactive use (minimum {} frames/s)",
                self.study.slug, adapter.adapter, adapter.kind, self.size[0], self.size[1], self.frame_ms, fps, self.study.render.min_fps
            )
        } else {
            format!(
                "lab study \"{}\": adapter {} ({}) renders {}×{} frames in {:.1} ms (≈{:.1} frames/s), TOO SLOW for interactive rates (minimum {} frames/s); participants will see the cube lag behind their keys — use a GPU or a smaller render.size",
                self.study.slug, adapter.adapter, adapter.kind, self.size[0], self.size[1], self.frame_ms, fps, self.study.render.min_fps
            )
        }
    }
}

/// The running lab: the renderer thread and the task studies it serves.
pub struct Lab {
    pub renderer: LabRenderer,
    pub adapter: AdapterInfo,
    pub studies: HashMap<String, Arc<LabStudy>>,
    /// Slugs in load order.
    pub order: Vec<String>,
}

/// What starting the lab gave: the lab (if any study is served) and the lines to print.
pub struct LabStart {
    pub lab: Option<Lab>,
    /// Informational lines (frame rates of interactive studies).
    pub info: Vec<String>,
    /// Warning lines (no adapter, too slow, a study that could not be prepared).
    pub warnings: Vec<String>,
}

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
            start.warnings.push(format!("task study {names} not served: the renderer thread failed to start ({error})"));
            return start;
        }
    };
    let adapter = renderer.adapter.clone();
    let cache = data_dir.join("lab");
    let mut served = HashMap::new();
    let mut order = Vec::new();
    for study in studies {
        let software = adapter.is_software();
        let cache_dir = cache.clone();
        let prepared = tokio::task::spawn_blocking(move || live::prepare_scene(&study, software, &cache_dir).map(|scene| (study, scene))).await;
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
        let frame_ms = match live::measure(&renderer, &study, centre, 4).await {
            Ok(ms) => ms,
            Err(reason) => {
                start.warnings.push(format!("study \"{}\": the renderer cannot make its frames ({reason}); not serving it", study.slug));
                continue;
            }
        };
        if let Err(error) = store::upsert_study(storage, &study).await {
            start.warnings.push(format!("study \"{}\": cannot record it in the database ({error}); not serving it", study.slug));
            continue;
        }
        let interactive = frame_ms <= 1000.0 / study.render.min_fps;
        let lab_study = LabStudy { study: Arc::new(study), layout, size, frame_ms, interactive };
        let line = lab_study.rate_line(&adapter);
        if interactive {
            start.info.push(line);
        } else {
            start.warnings.push(line);
        }
        order.push(lab_study.study.slug.clone());
        served.insert(lab_study.study.slug.clone(), Arc::new(lab_study));
    }
    if !served.is_empty() {
        start.lab = Some(Lab { renderer, adapter, studies: served, order });
    }
    start
}

pub fn router() -> Router<AppState> {
    Router::new()
        .route("/lab/{slug}", get(lab_page))
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
    interactive: bool,
    rate_line: String,
}

fn paragraphs(text: &str) -> Vec<&str> {
    text.split("\n\n").map(str::trim).filter(|p| !p.is_empty()).collect()
}

async fn lab_page(State(state): State<AppState>, UrlPath(slug): UrlPath<String>, uri: axum::http::Uri) -> Response {
    let Some(lab) = state.lab() else { return crate::pages::not_found(uri).await };
    let Some(study) = lab.studies.get(&slug) else { return crate::pages::not_found(uri).await };
    let page = LabPage {
        slug: &study.study.slug,
        title: &study.study.title,
        welcome: paragraphs(&study.study.texts.welcome),
        instructions: paragraphs(&study.study.texts.instructions),
        interactive: study.interactive,
        rate_line: study.rate_line(&lab.adapter),
    };
    match page.render() {
        Ok(html) => Html(html).into_response(),
        Err(error) => AppError::Internal(format!("lab page: {error}")).into_response(),
    }
}
