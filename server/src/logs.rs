//! The operator's log: one line per request through `tower-http`'s trace layer (method, route
//! template, status, latency in milliseconds and who made it — an admin, a participant or
//! anonymous — never the raw path, the query string, a token or personal data), the warnings
//! and errors of the running server with their cause ([`tracing`] events), `RUST_LOG` to
//! filter them ([`DEFAULT_FILTER`] when unset) and `serve --log-format json|text` ([`init`]).
//! The log goes to stderr; the start-up lines (links) stay on stdout as before.
//!
//! Refusals (every 4xx and 503 answer) are counted in memory per kind — status code and route
//! template — for the admin page and `GET /api/admin/refusals` ([`Refusals`]).

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::Duration;

use axum::Router;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderMap, StatusCode};
use axum::middleware::Next;
use axum::response::Response;
use axum::routing::get;
use serde::Serialize;

use crate::AppState;
use crate::error::{AppResult, Json};

/// What `RUST_LOG` is when it is unset: `info` for mrstudy's crates, `warn` for the others.
pub const DEFAULT_FILTER: &str =
    "warn,mrstudy=info,mrstudy_server=info,mrstudy_bench=info,mrstudy_renderer=info,mrstudy_analysis=info";

/// The route of a request that matched none: the raw path is never logged.
pub const NO_ROUTE: &str = "(no route)";

/// How the log is written (`serve --log-format`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LogFormat {
    /// One human-readable line per event.
    #[default]
    Text,
    /// One JSON object per line (for a log collector).
    Json,
}

impl LogFormat {
    /// `--log-format`'s values: (name, help, value).
    pub const NAMES: &[(&str, &str, LogFormat)] = &[
        ("text", "One human-readable line per event", LogFormat::Text),
        ("json", "One JSON object per line (for a log collector)", LogFormat::Json),
    ];
}

/// Why the log could not be set up.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LogFilterError {
    /// `RUST_LOG` holds `directives` that are no log filter.
    #[error("RUST_LOG=\"{directives}\" is not a log filter: {reason}")]
    RustLog { directives: String, reason: String },
}

/// The filter of `RUST_LOG`, or [`DEFAULT_FILTER`] when it is unset or empty; a `RUST_LOG` that
/// does not parse is an error naming it.
pub fn filter_from_env() -> Result<tracing_subscriber::EnvFilter, LogFilterError> {
    match std::env::var("RUST_LOG") {
        Ok(directives) if !directives.trim().is_empty() => tracing_subscriber::EnvFilter::try_new(&directives)
            .map_err(|error| LogFilterError::RustLog { directives: directives.clone(), reason: error.to_string() }),
        _ => Ok(tracing_subscriber::EnvFilter::new(DEFAULT_FILTER)),
    }
}

/// The log's subscriber: events that pass `filter`, in `format`, written to `writer` (ANSI
/// colours only when `ansi`).
pub fn subscriber<W>(
    format: LogFormat,
    filter: tracing_subscriber::EnvFilter,
    writer: W,
    ansi: bool,
) -> impl tracing::Subscriber + Send + Sync + 'static
where
    W: for<'writer> tracing_subscriber::fmt::MakeWriter<'writer> + Send + Sync + 'static,
{
    use tracing_subscriber::Layer;
    use tracing_subscriber::layer::SubscriberExt;
    let layer = match format {
        LogFormat::Text => tracing_subscriber::fmt::layer().with_writer(writer).with_ansi(ansi).boxed(),
        LogFormat::Json => tracing_subscriber::fmt::layer()
            .json()
            .flatten_event(true)
            .with_current_span(true)
            .with_span_list(false)
            .with_writer(writer)
            .boxed(),
    };
    tracing_subscriber::registry().with(layer).with(filter)
}

/// Installs the process's log on stderr (`RUST_LOG`, `format`); a second call changes nothing.
pub fn init(format: LogFormat) -> Result<(), LogFilterError> {
    use std::io::IsTerminal;
    use tracing_subscriber::util::SubscriberInitExt;
    let filter = filter_from_env()?;
    let ansi = format == LogFormat::Text && std::io::stderr().is_terminal();
    // already installed (a second server in one process): keep the first
    let _ = subscriber(format, filter, std::io::stderr, ansi).try_init();
    Ok(())
}

/// Who made a request, from the credential it carries (not whether it was accepted: a refused
/// one shows as 401 or 403 in the same line).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Caller {
    /// The admin area with a bearer token, the admin cookie or the login link's token.
    Admin,
    /// Elsewhere with a bearer token (a participant's), or the lab's WebSocket.
    Participant,
    Anonymous,
}

impl Caller {
    pub fn as_str(self) -> &'static str {
        match self {
            Caller::Admin => "admin",
            Caller::Participant => "participant",
            Caller::Anonymous => "anonymous",
        }
    }

    /// Who made a request to `route` (a template) with `headers` and `query`.
    pub fn of(route: &str, headers: &HeaderMap, query: Option<&str>) -> Caller {
        let bearer = crate::auth::bearer(headers).is_ok();
        let admin_area = route == "/admin" || route.starts_with("/admin/") || route.starts_with("/api/admin/");
        if admin_area {
            let login_token =
                route == "/admin/login" && query.unwrap_or_default().split('&').any(|pair| pair.starts_with("token="));
            let cookie = crate::auth::session_cookie(headers).is_some();
            return if bearer || cookie || login_token { Caller::Admin } else { Caller::Anonymous };
        }
        if bearer || route == "/api/lab/{slug}/ws" { Caller::Participant } else { Caller::Anonymous }
    }
}

/// The route template of a request (axum's [`MatchedPath`]), or [`NO_ROUTE`].
fn route_of<B>(request: &axum::http::Request<B>) -> &str {
    request.extensions().get::<MatchedPath>().map_or(NO_ROUTE, MatchedPath::as_str)
}

/// `router` with the request log: one `INFO` line per request when its response starts (status
/// and latency), inside a span holding the method, route template and caller (so a warning or
/// an error logged while serving it names its route too).
pub fn trace<S: Clone + Send + Sync + 'static>(router: Router<S>) -> Router<S> {
    use tower_http::trace::TraceLayer;
    router.layer(
        TraceLayer::new_for_http()
            .make_span_with(|request: &Request| {
                let route = route_of(request);
                let caller = Caller::of(route, request.headers(), request.uri().query());
                tracing::info_span!("request", method = %request.method(), route = %route, caller = %caller.as_str())
            })
            .on_request(())
            .on_response(|response: &Response<_>, latency: Duration, _span: &tracing::Span| {
                let status = response.status().as_u16();
                let latency_ms = latency.as_micros() as f64 / 1000.0;
                tracing::info!(status, latency_ms, "answered");
            })
            .on_body_chunk(())
            .on_eos(())
            .on_failure(()),
    )
}

/// Whether an answer is a refusal: every 4xx, and 503 (full, or opening soon).
pub fn is_refusal(status: StatusCode) -> bool {
    status.is_client_error() || status == StatusCode::SERVICE_UNAVAILABLE
}

/// The route of a connection refused before any request was read because its address holds
/// `--max-connections-per-address` already (503).
pub const CONNECTION_PER_ADDRESS: &str = "(connection: cap per address)";
/// The route of a connection refused because the server was full (503).
pub const CONNECTION_FULL: &str = "(connection: server full)";

/// Connections refused before any request was read, in this process: (per address, full).
static REFUSED_CONNECTIONS: [std::sync::atomic::AtomicU64; 2] =
    [std::sync::atomic::AtomicU64::new(0), std::sync::atomic::AtomicU64::new(0)];

/// Counts a connection refused with 503 before any request was read ([`crate::serve`]'s
/// accept loop has no state); every [`Refusals`] of the process shows them.
pub fn count_refused_connection(refused: crate::connections::Refused) {
    let index = match refused {
        crate::connections::Refused::PerAddress => 0,
        crate::connections::Refused::Full => 1,
    };
    REFUSED_CONNECTIONS[index].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
}

/// Refusals counted per kind since the server started (per process).
#[derive(Debug, Default)]
pub struct Refusals {
    counts: Mutex<BTreeMap<(u16, String), u64>>,
}

/// One kind of refusal and how often it was answered.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Refusal {
    pub status: u16,
    /// The route template, or [`NO_ROUTE`].
    pub route: String,
    pub count: u64,
}

impl Refusals {
    /// Counts one refusal `status` of `route` (a template: the kinds stay few).
    pub fn count(&self, status: StatusCode, route: &str) {
        let mut counts = self.counts.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        match counts.get_mut(&(status.as_u16(), route.to_string())) {
            Some(count) => *count += 1,
            None => {
                counts.insert((status.as_u16(), route.to_string()), 1);
            }
        }
    }

    /// Every kind counted so far, by status code, then route; with the connections of the
    /// process refused before any request was read ([`count_refused_connection`]).
    pub fn kinds(&self) -> Vec<Refusal> {
        let mut counts = self.counts.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).clone();
        for (route, refused) in [CONNECTION_PER_ADDRESS, CONNECTION_FULL].iter().zip(&REFUSED_CONNECTIONS) {
            let count = refused.load(std::sync::atomic::Ordering::Relaxed);
            if count > 0 {
                counts.insert((503, route.to_string()), count);
            }
        }
        counts
            .iter()
            .map(|((status, route), count)| Refusal { status: *status, route: route.clone(), count: *count })
            .collect()
    }
}

/// Middleware: counts the request's answer in [`AppState::refusals`] if it is a refusal.
pub async fn count_refusals(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let route = route_of(&request).to_string();
    let response = next.run(request).await;
    if is_refusal(response.status()) {
        state.refusals().count(response.status(), &route);
    }
    response
}

/// `GET /api/admin/refusals`: the refusals counted so far, `[{status, route, count}]`.
pub fn router() -> Router<AppState> {
    Router::new().route("/api/admin/refusals", get(refusals))
}

async fn refusals(State(state): State<AppState>, headers: HeaderMap) -> AppResult<Json<Vec<Refusal>>> {
    crate::auth::authorize_admin(&state, &headers).await?;
    Ok(Json(state.refusals().kinds()))
}
