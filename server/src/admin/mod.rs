//! The admin area: API and pages for the researcher — study list, progress and dropout, live
//! analysis, export, open/close, and the participants (issue 12): their list with status and
//! flags, exclude/include (kept, with the reason), deletion of every datum of one participant,
//! and preview links whose participants are pilots. Pilot and excluded participants are left out
//! of the analysis and the exports unless `?include_pilots=true` / `?include_excluded=true`,
//! and the analysis says so in a warning.
//!
//! Authentication: the admin token as `Authorization: Bearer <token>`, or the `mrstudy_admin`
//! cookie that `GET /admin/login?token=…` (the link `serve` prints) sets (HttpOnly,
//! SameSite=Strict). Without a token a call gets 401, with a wrong one 403; pages answer the same
//! codes with an HTML page. State-changing calls authenticated by the cookie must also carry
//! `X-Requested-With: mrstudy`, which a cross-site form cannot send.
//!
//! One concept per file: `stats` a study's progress and live analysis, `page` the HTML pages,
//! `participants` the participants' list and changes, `store` the admin's SQL (reads and the
//! write jobs of the writer's group commit); here the router, downloads, open/close and login.

mod page;
mod participants;
mod stats;
pub mod store;

use crate::AppState;
use crate::auth::{Admin, AdminChange};
use crate::error::{AppError, AppResult, Json};
use crate::export::{self, ExportError, Include, LeftOut};
use crate::pages::download;
use axum::Router;
use axum::extract::{FromRequestParts, Path, Query, State};
use axum::http::request::Parts;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::{delete, get, post};
use page::{admin_page, admin_study_page};
use participants::{
    create_preview, delete_participant, exclude_participant, include_participant, list_participants, revoke_previews,
};
use serde::{Deserialize, Serialize};
pub use stats::{StudyStats, stats};
use stats::{analysis, list_studies, metric_svg, study_stats, worth_svg};

pub fn router() -> Router<AppState> {
    Router::new()
        .route("/api/admin/studies", get(list_studies))
        .route("/api/admin/studies/{slug}", get(study_stats))
        .route("/api/admin/studies/{slug}/export.csv", get(export_csv))
        .route("/api/admin/studies/{slug}/export.json", get(export_json))
        .route("/api/admin/studies/{slug}/conditions.csv", get(conditions_csv))
        .route("/api/admin/studies/{slug}/stimuli.csv", get(stimuli_csv))
        .route("/api/admin/studies/{slug}/analysis", get(analysis))
        .route("/api/admin/studies/{slug}/worth.svg", get(worth_svg))
        .route("/api/admin/studies/{slug}/metric.svg", get(metric_svg))
        .route("/api/admin/studies/{slug}/open", post(open_study))
        .route("/api/admin/studies/{slug}/close", post(close_study))
        .route("/api/admin/studies/{slug}/participants", get(list_participants))
        .route("/api/admin/studies/{slug}/preview", post(create_preview).delete(revoke_previews))
        .route("/api/admin/participants/{id}/exclude", post(exclude_participant))
        .route("/api/admin/participants/{id}/include", post(include_participant))
        .route("/api/admin/participants/{id}", delete(delete_participant))
        .route("/admin/login", get(login))
        .route("/admin/logout", post(logout))
        .route("/admin", get(admin_page))
        .route("/admin/studies/{slug}", get(admin_study_page))
}

impl From<ExportError> for AppError {
    fn from(error: ExportError) -> Self {
        match error {
            ExportError::UnknownStudy(slug) => AppError::NotFound(format!("There is no study \"{slug}\".")),
            ExportError::Database(error) => AppError::Database(error),
            other => AppError::Internal(other.to_string()),
        }
    }
}

/// A handler's argument for an admin read of participants' data: the admin let in ([`Admin`]),
/// then whom the read includes, from the query ([`include_from_query`]).
pub(super) struct AdminInclude(pub Include);

impl FromRequestParts<AppState> for AdminInclude {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> AppResult<AdminInclude> {
        Admin::from_request_parts(parts, state).await?;
        include_from_query(parts.uri.query().map(str::to_string)).map(AdminInclude)
    }
}

/// `?include_pilots=true&include_excluded=true` (each `true` or `false`; other keys are ignored).
pub(super) fn include_from_query(query: Option<String>) -> AppResult<Include> {
    let mut include = Include::default();
    for pair in query.as_deref().unwrap_or_default().split('&').filter(|pair| !pair.is_empty()) {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        let slot = match key {
            "include_pilots" => &mut include.pilots,
            "include_excluded" => &mut include.excluded,
            _ => continue,
        };
        *slot = match value {
            "true" | "1" => true,
            "false" | "0" => false,
            other => {
                return Err(AppError::BadRequest(format!(
                    "`{key}` must be true or false, found \"{}\".",
                    other.chars().take(32).collect::<String>()
                )));
            }
        };
    }
    Ok(include)
}

/// The header saying whom a download left out (pilot and excluded participants), if anyone.
pub const LEFT_OUT_HEADER: &str = "x-mrstudy-left-out";

pub(super) const QUERY_HINT: &str = "add ?include_pilots=true or ?include_excluded=true to keep them";

pub(super) fn with_left_out(mut response: Response, left_out: LeftOut) -> Response {
    if let Some(sentence) = left_out.sentence(QUERY_HINT)
        && let Ok(value) = HeaderValue::from_str(&sentence)
    {
        response.headers_mut().insert(LEFT_OUT_HEADER, value);
    }
    response
}

pub(super) async fn export_csv(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    AdminInclude(include): AdminInclude,
) -> AppResult<Response> {
    let csv = export::trials_csv(&state.storage().admin, &slug, include).await?;
    Ok(with_left_out(download("text/csv; charset=utf-8", format!("{slug}-trials.csv"), csv.content), csv.left_out))
}

pub(super) async fn export_json(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    AdminInclude(include): AdminInclude,
) -> AppResult<Response> {
    let json = export::study_json(&state.storage().admin, &slug, include).await?;
    Ok(with_left_out(
        download(
            "application/json",
            format!("{slug}.json"),
            serde_json::to_string_pretty(&json.content).expect("JSON serialises"),
        ),
        json.left_out,
    ))
}

pub(super) async fn conditions_csv(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: Admin,
) -> AppResult<Response> {
    let definition = export::definition(&state.storage().admin, &slug).await?;
    Ok(download("text/csv; charset=utf-8", format!("{slug}-conditions.csv"), definition.conditions_csv()))
}

/// The study's stimulus metrics CSV (docs/design.md): each rendered stimulus's errors against the
/// ground truth of its scene configuration. 404 with the reason when the study has none.
pub(super) async fn stimuli_csv(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: Admin,
) -> AppResult<Response> {
    let now = state.stimulus_metrics(&slug).ok_or_else(|| {
        AppError::NotFound(format!("study \"{slug}\" is not served by this server, so its stimuli are not known here"))
    })?;
    match &now.csv {
        Some(csv) => Ok(download("text/csv; charset=utf-8", format!("{slug}-stimuli.csv"), csv.clone())),
        None => Err(AppError::NotFound(format!(
            "study \"{slug}\" has no stimulus metrics: {}",
            if now.notes.is_empty() { "it has no rendered stimuli".to_string() } else { now.notes.join("; ") }
        ))),
    }
}

#[derive(Serialize)]
pub(super) struct OpenState {
    slug: String,
    open: bool,
}

pub(super) async fn set_open(state: AppState, slug: String, open: bool) -> AppResult<Json<OpenState>> {
    state.storage().set_open(&slug, open).await??;
    Ok(Json(OpenState { slug, open }))
}

pub(super) async fn open_study(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: AdminChange,
) -> AppResult<Json<OpenState>> {
    set_open(state, slug, true).await
}

pub(super) async fn close_study(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: AdminChange,
) -> AppResult<Json<OpenState>> {
    set_open(state, slug, false).await
}

// ------------------------------------------------------------------------------------------
// Pages.

/// Ends the admin session of the cookie and clears the cookie. A cross-site form cannot send
/// the SameSite=Strict cookie, so this needs no `X-Requested-With`.
pub(super) async fn logout(State(state): State<AppState>, headers: HeaderMap) -> Response {
    if let Some(id) = crate::auth::session_cookie(&headers)
        && let Err(error) = crate::auth::end_session(&state, id).await
    {
        return error.into_response();
    }
    let mut response = crate::pages::message_page(
        StatusCode::OK,
        "Logged out",
        "The admin session has ended. Open the admin link that mrstudy serve printed to log in again.",
    );
    let cookie = crate::auth::session_set_cookie(None, state.limits().behind_tls);
    if let Ok(cookie) = HeaderValue::from_str(&cookie) {
        response.headers_mut().insert(header::SET_COOKIE, cookie);
    }
    response
}

#[derive(Deserialize)]
pub(super) struct LoginQuery {
    token: Option<String>,
}

pub(super) async fn login(State(state): State<AppState>, Query(query): Query<LoginQuery>) -> Response {
    match query.token {
        Some(token) if state.is_admin_token(&token) => {
            let session = match crate::auth::start_session(&state).await {
                Ok(session) => session,
                Err(error) => return error.into_response(),
            };
            let mut response = Redirect::to("/admin").into_response();
            let cookie = crate::auth::session_set_cookie(Some(&session), state.limits().behind_tls);
            if let Ok(cookie) = HeaderValue::from_str(&cookie) {
                response.headers_mut().insert(header::SET_COOKIE, cookie);
            }
            response
        }
        Some(_) => crate::pages::message_page(
            StatusCode::FORBIDDEN,
            "Wrong admin token",
            "The admin token in this link is wrong. Use the admin link that mrstudy serve printed.",
        ),
        None => crate::pages::message_page(
            StatusCode::UNAUTHORIZED,
            "Admin token needed",
            "Open the admin link that mrstudy serve printed; it carries the admin token.",
        ),
    }
}
