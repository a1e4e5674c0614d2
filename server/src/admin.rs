//! The admin area: API and pages for the researcher — study list, progress and dropout, live
//! analysis, export, open/close.
//!
//! Authentication: the admin token as `Authorization: Bearer <token>`, or the `mrstudy_admin`
//! cookie that `GET /admin/login?token=…` (the link `serve` prints) sets (HttpOnly,
//! SameSite=Strict). Without a token a call gets 401, with a wrong one 403; pages answer the same
//! codes with an HTML page. State-changing calls authenticated by the cookie must also carry
//! `X-Requested-With: mrstudy`, which a cross-site form cannot send.

use askama::Template;
use axum::Router;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use serde::{Deserialize, Serialize};
use sqlx::Row;

use crate::error::{AppError, AppResult, Json};
use crate::export::{self, ExportError};
use crate::participant::bearer;
use crate::AppState;

pub const COOKIE: &str = "mrstudy_admin";

pub fn router() -> Router<AppState> {
    Router::new()
        .route("/api/admin/studies", get(list_studies))
        .route("/api/admin/studies/{slug}", get(study_stats))
        .route("/api/admin/studies/{slug}/export.csv", get(export_csv))
        .route("/api/admin/studies/{slug}/export.json", get(export_json))
        .route("/api/admin/studies/{slug}/conditions.csv", get(conditions_csv))
        .route("/api/admin/studies/{slug}/analysis", get(analysis))
        .route("/api/admin/studies/{slug}/worth.svg", get(worth_svg))
        .route("/api/admin/studies/{slug}/open", post(open_study))
        .route("/api/admin/studies/{slug}/close", post(close_study))
        .route("/admin/login", get(login))
        .route("/admin", get(admin_page))
        .route("/admin/studies/{slug}", get(admin_study_page))
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Via {
    Header,
    Cookie,
}

fn cookie_token(headers: &HeaderMap) -> Option<&str> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|value| value.to_str().ok())
        .flat_map(|value| value.split(';'))
        .filter_map(|pair| pair.trim().split_once('='))
        .find(|(name, _)| *name == COOKIE)
        .map(|(_, value)| value)
}

/// Checks the admin token (header or cookie), for read-only admin calls of other modules.
pub(crate) fn authorize_admin(state: &AppState, headers: &HeaderMap) -> AppResult<()> {
    authorize(state, headers).map(|_| ())
}

fn authorize(state: &AppState, headers: &HeaderMap) -> AppResult<Via> {
    let (token, via) = match bearer(headers) {
        Ok(token) => (token, Via::Header),
        Err(error) => match cookie_token(headers) {
            Some(token) => (token, Via::Cookie),
            None => {
                return Err(match error {
                    AppError::Unauthorized(_) => AppError::Unauthorized(
                        "This call needs the admin token: Authorization: Bearer <admin token>.".into(),
                    ),
                    other => other,
                });
            }
        },
    };
    if state.is_admin_token(token) {
        Ok(via)
    } else {
        Err(AppError::Forbidden("The admin token is wrong.".into()))
    }
}

fn authorize_change(state: &AppState, headers: &HeaderMap) -> AppResult<()> {
    if authorize(state, headers)? == Via::Cookie
        && headers.get("x-requested-with").and_then(|value| value.to_str().ok()) != Some("mrstudy")
    {
        return Err(AppError::Forbidden(
            "A change made with the admin cookie needs the header X-Requested-With: mrstudy.".into(),
        ));
    }
    Ok(())
}

/// Progress of one study.
#[derive(Debug, Clone, Serialize)]
pub struct StudyStats {
    pub slug: String,
    pub title: String,
    pub kind: String,
    pub open: bool,
    /// Whether this server serves the study now (it may be in the database only).
    pub served: bool,
    pub trials: i64,
    pub started: i64,
    pub finished: i64,
    /// finished / started; absent with no participants.
    pub completion_rate: Option<f64>,
    /// `reached[k]`: participants who answered at least `k` trials, k = 0..=trials.
    pub reached: Vec<i64>,
    /// `stopped_after[k]`: participants who have not finished and answered exactly `k` trials.
    pub stopped_after: Vec<i64>,
    pub responses: i64,
    pub median_rt_ms: Option<f64>,
    /// Median time from joining to the last answer of those who finished, in seconds.
    pub median_total_s: Option<f64>,
    pub catch_responses: i64,
    pub catch_failures: i64,
    pub participants_failing_catch: i64,
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let middle = values.len() / 2;
    Some(if values.len() % 2 == 1 {
        values[middle]
    } else {
        (values[middle - 1] + values[middle]) / 2.0
    })
}

pub async fn stats(state: &AppState, slug: &str) -> AppResult<StudyStats> {
    let pool = &state.storage().read;
    let study = sqlx::query("SELECT slug, title, kind, open, definition FROM studies WHERE slug = ?")
        .bind(slug)
        .fetch_optional(pool)
        .await?
        .ok_or_else(|| AppError::NotFound(format!("There is no study \"{slug}\".")))?;
    let served = state.study(slug);
    let trials = match served {
        Some(prepared) => prepared.study.trial_count() as i64,
        None => sqlx::query_scalar("SELECT COALESCE(MAX(trials), 0) FROM participants WHERE study = ?")
            .bind(slug)
            .fetch_one(pool)
            .await?,
    };
    let counts = sqlx::query(
        "SELECT answered, trials, completed_at IS NOT NULL AS finished, COUNT(*) AS n
         FROM participants WHERE study = ? GROUP BY answered, trials, finished",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let mut started = 0;
    let mut finished = 0;
    let mut responses = 0;
    let mut reached = vec![0i64; trials as usize + 1];
    let mut stopped_after = vec![0i64; trials as usize + 1];
    for row in counts {
        let answered: i64 = row.try_get("answered")?;
        let n: i64 = row.try_get("n")?;
        let is_finished: bool = row.try_get("finished")?;
        started += n;
        responses += answered * n;
        if is_finished {
            finished += n;
        } else if let Some(slot) = stopped_after.get_mut(answered as usize) {
            *slot += n;
        }
        for slot in reached.iter_mut().take((answered.max(0) as usize).min(trials as usize) + 1) {
            *slot += n;
        }
    }
    let rts: Vec<f64> = sqlx::query_scalar(
        "SELECT r.rt_ms FROM responses r JOIN participants p ON p.id = r.participant WHERE p.study = ?",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let totals: Vec<f64> = sqlx::query_scalar(
        "SELECT (julianday(completed_at) - julianday(created_at)) * 86400.0 FROM participants
         WHERE study = ? AND completed_at IS NOT NULL",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let catch = sqlx::query(
        "SELECT COUNT(*) AS n, COALESCE(SUM(r.chosen != t.catch_expected), 0) AS failures,
                COUNT(DISTINCT CASE WHEN r.chosen != t.catch_expected THEN r.participant END) AS failing
         FROM responses r JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
         JOIN participants p ON p.id = r.participant
         WHERE p.study = ? AND t.catch_expected IS NOT NULL",
    )
    .bind(slug)
    .fetch_one(pool)
    .await?;
    Ok(StudyStats {
        slug: study.try_get("slug")?,
        title: study.try_get("title")?,
        kind: study.try_get("kind")?,
        open: study.try_get::<i64, _>("open")? == 1,
        served: served.is_some(),
        trials,
        started,
        finished,
        completion_rate: (started > 0).then(|| finished as f64 / started as f64),
        reached,
        stopped_after,
        responses,
        median_rt_ms: median(rts),
        median_total_s: median(totals),
        catch_responses: catch.try_get("n")?,
        catch_failures: catch.try_get("failures")?,
        participants_failing_catch: catch.try_get("failing")?,
    })
}

async fn all_slugs(state: &AppState) -> AppResult<Vec<String>> {
    Ok(sqlx::query_scalar("SELECT slug FROM studies WHERE kind <> 'task' ORDER BY first_loaded_at, slug")
        .fetch_all(&state.storage().read)
        .await?)
}

async fn list_studies(State(state): State<AppState>, headers: HeaderMap) -> AppResult<Json<Vec<StudyStats>>> {
    authorize(&state, &headers)?;
    let mut all = Vec::new();
    for slug in all_slugs(&state).await? {
        all.push(stats(&state, &slug).await?);
    }
    Ok(Json(all))
}

async fn study_stats(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<StudyStats>> {
    authorize(&state, &headers)?;
    Ok(Json(stats(&state, &slug).await?))
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

pub(crate) fn download(content_type: &'static str, file_name: String, body: String) -> Response {
    let mut response = (StatusCode::OK, body).into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    if let Ok(value) = HeaderValue::from_str(&format!("attachment; filename=\"{file_name}\"")) {
        headers.insert(header::CONTENT_DISPOSITION, value);
    }
    response
}

async fn export_csv(State(state): State<AppState>, Path(slug): Path<String>, headers: HeaderMap) -> AppResult<Response> {
    authorize(&state, &headers)?;
    let csv = export::trials_csv(&state.storage().read, &slug).await?;
    Ok(download("text/csv; charset=utf-8", format!("{slug}-trials.csv"), csv))
}

async fn export_json(State(state): State<AppState>, Path(slug): Path<String>, headers: HeaderMap) -> AppResult<Response> {
    authorize(&state, &headers)?;
    let json = export::study_json(&state.storage().read, &slug).await?;
    Ok(download(
        "application/json",
        format!("{slug}.json"),
        serde_json::to_string_pretty(&json).expect("JSON serialises"),
    ))
}

async fn conditions_csv(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Response> {
    authorize(&state, &headers)?;
    let definition = export::definition(&state.storage().read, &slug).await?;
    Ok(download(
        "text/csv; charset=utf-8",
        format!("{slug}-conditions.csv"),
        definition.conditions_csv(),
    ))
}

/// The live analysis of a study: the analysis crate run on the trials CSV and the study's
/// conditions CSV — exactly what `mrstudy export` and `mrstudy analyze --conditions` give.
pub async fn analysis_json(state: &AppState, slug: &str) -> AppResult<serde_json::Value> {
    let pool = &state.storage().read;
    let definition = export::definition(pool, slug).await?;
    let trials = export::trials_csv(pool, slug).await?;
    crate::analysis::run(&trials, &definition.conditions_csv())
}

async fn analysis(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<serde_json::Value>> {
    authorize(&state, &headers)?;
    Ok(Json(analysis_json(&state, &slug).await?))
}

async fn worth_svg(State(state): State<AppState>, Path(slug): Path<String>, headers: HeaderMap) -> AppResult<Response> {
    authorize(&state, &headers)?;
    let pool = &state.storage().read;
    let definition = export::definition(pool, &slug).await?;
    let trials = export::trials_csv(pool, &slug).await?;
    let svg = crate::analysis::worth_svg(&trials, &definition.conditions_csv())?;
    let mut response = (StatusCode::OK, svg).into_response();
    let response_headers = response.headers_mut();
    response_headers.insert(header::CONTENT_TYPE, HeaderValue::from_static("image/svg+xml"));
    // An SVG shown through <img> runs no scripts; its own inline styles are allowed.
    response_headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static("default-src 'none'; style-src 'unsafe-inline'; frame-ancestors 'none'"),
    );
    Ok(response)
}

#[derive(Serialize)]
struct OpenState {
    slug: String,
    open: bool,
}

async fn set_open(state: AppState, slug: String, headers: HeaderMap, open: bool) -> AppResult<Json<OpenState>> {
    authorize_change(&state, &headers)?;
    state.storage().set_open(&slug, open).await?;
    Ok(Json(OpenState { slug, open }))
}

async fn open_study(State(state): State<AppState>, Path(slug): Path<String>, headers: HeaderMap) -> AppResult<Json<OpenState>> {
    set_open(state, slug, headers, true).await
}

async fn close_study(State(state): State<AppState>, Path(slug): Path<String>, headers: HeaderMap) -> AppResult<Json<OpenState>> {
    set_open(state, slug, headers, false).await
}

// ------------------------------------------------------------------------------------------
// Pages.

#[derive(Deserialize)]
struct LoginQuery {
    token: Option<String>,
}

async fn login(State(state): State<AppState>, Query(query): Query<LoginQuery>) -> Response {
    match query.token {
        Some(token) if state.is_admin_token(&token) => {
            let mut response = Redirect::to("/admin").into_response();
            if let Ok(cookie) = HeaderValue::from_str(&format!(
                "{COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/; Max-Age=2592000"
            )) {
                response.headers_mut().insert(header::SET_COOKIE, cookie);
            }
            response
        }
        Some(_) => crate::pages::message_page(StatusCode::FORBIDDEN, "Wrong admin token", "The admin token in this link is wrong. Use the admin link that mrstudy serve printed."),
        None => crate::pages::message_page(StatusCode::UNAUTHORIZED, "Admin token needed", "Open the admin link that mrstudy serve printed; it carries the admin token."),
    }
}

fn page_authorize(state: &AppState, headers: &HeaderMap) -> Result<(), Box<Response>> {
    authorize(state, headers).map(|_| ()).map_err(|error| {
        Box::new({
        let status = error.status();
        crate::pages::message_page(
            status,
            if status == StatusCode::UNAUTHORIZED { "Admin token needed" } else { "Wrong admin token" },
            "Open the admin link that mrstudy serve printed; it carries the admin token.",
        )
        })
    })
}

#[derive(Template)]
#[template(path = "admin.html")]
struct AdminPage {
    studies: Vec<StudyStats>,
    /// Lab task studies being served: (slug, title, frame-rate line, interactive).
    lab: Vec<(String, String, String, bool)>,
}

async fn admin_page(State(state): State<AppState>, headers: HeaderMap) -> Response {
    if let Err(page) = page_authorize(&state, &headers) {
        return *page;
    }
    let result: AppResult<Vec<StudyStats>> = async {
        let mut all = Vec::new();
        for slug in all_slugs(&state).await? {
            all.push(stats(&state, &slug).await?);
        }
        Ok(all)
    }
    .await;
    match result {
        Ok(studies) => crate::pages::render(&AdminPage { studies, lab: crate::task::results::overview(&state) }),
        Err(error) => error.into_response(),
    }
}

/// One bar of the dropout funnel.
pub struct FunnelBar {
    pub trial: usize,
    pub reached: i64,
    pub stopped: i64,
    pub x: f64,
    pub width: f64,
    pub height: f64,
    pub y: f64,
    /// Whether the trial number is written under the bar.
    pub label: bool,
}

/// One factor estimate row of the live analysis.
pub struct EstimateRow {
    pub name: String,
    pub estimate: String,
    pub se: String,
    pub p: String,
}

/// One condition row of the live analysis.
pub struct WorthRow {
    pub condition: String,
    pub worth: String,
    pub log_worth: String,
    pub wins: String,
    pub comparisons: String,
}

#[derive(Template)]
#[template(path = "admin_study.html")]
struct AdminStudyPage {
    stats: StudyStats,
    funnel: Vec<FunnelBar>,
    funnel_width: f64,
    funnel_top: i64,
    analysis_error: Option<String>,
    judgments: String,
    agreement_u: Option<String>,
    worth: Vec<WorthRow>,
    estimates: Vec<EstimateRow>,
    warnings: Vec<String>,
}

pub(crate) fn format_number(value: &serde_json::Value, digits: usize) -> String {
    match value.as_f64() {
        Some(number) if number != 0.0 && (number.abs() < 1e-3 || number.abs() >= 1e6) => format!("{number:.2e}"),
        Some(number) if number.fract() == 0.0 && digits == 0 => format!("{number:.0}"),
        Some(number) => format!("{number:.digits$}"),
        None => value.as_str().map(str::to_string).unwrap_or_default(),
    }
}

async fn admin_study_page(State(state): State<AppState>, Path(slug): Path<String>, headers: HeaderMap) -> Response {
    if let Err(page) = page_authorize(&state, &headers) {
        return *page;
    }
    let stats = match stats(&state, &slug).await {
        Ok(stats) => stats,
        Err(AppError::NotFound(message)) => {
            return crate::pages::message_page(StatusCode::NOT_FOUND, "No such study", &message);
        }
        Err(error) => return error.into_response(),
    };
    // Bars share about 640 px, each 4 to 40 px wide; the tallest is everyone who started.
    let bar_count = stats.reached.len().max(1) as f64;
    let bar_width = (640.0 / bar_count).clamp(4.0, 40.0) - 2.0;
    let max_reached = stats.reached.first().copied().unwrap_or(0).max(1) as f64;
    let label_every = ((bar_count / 13.0).ceil() as usize).max(1);
    let funnel = stats
        .reached
        .iter()
        .enumerate()
        .map(|(trial, &reached)| {
            let height = 120.0 * reached as f64 / max_reached;
            FunnelBar {
                trial,
                reached,
                stopped: stats.stopped_after.get(trial).copied().unwrap_or(0),
                x: 50.0 + trial as f64 * (bar_width + 2.0),
                width: bar_width,
                height,
                y: 140.0 - height,
                label: trial % label_every == 0 || trial + 1 == stats.reached.len(),
            }
        })
        .collect();
    let funnel_width = 70.0 + bar_count * (bar_width + 2.0);
    let funnel_top = stats.reached.first().copied().unwrap_or(0);
    let mut page = AdminStudyPage {
        funnel,
        funnel_width,
        funnel_top,
        analysis_error: None,
        judgments: String::new(),
        agreement_u: None,
        worth: Vec::new(),
        estimates: Vec::new(),
        warnings: Vec::new(),
        stats,
    };
    match analysis_json(&state, &slug).await {
        Ok(analysis) => {
            page.judgments = format_number(&analysis["judgments"], 0);
            page.agreement_u = analysis.get("agreement").map(|agreement| format_number(&agreement["u"], 3));
            for item in analysis["items"].as_array().into_iter().flatten() {
                page.worth.push(WorthRow {
                    condition: item["condition"].as_str().unwrap_or_default().to_string(),
                    worth: format_number(&item["worth"], 3),
                    log_worth: format_number(&item["log_worth"], 3),
                    wins: format_number(&item["wins"], 0),
                    comparisons: format_number(&item["comparisons"], 0),
                });
            }
            for covariate in analysis["covariates"].as_array().into_iter().flatten() {
                page.estimates.push(EstimateRow {
                    name: covariate["name"].as_str().unwrap_or_default().to_string(),
                    estimate: format_number(&covariate["estimate"], 3),
                    se: format_number(&covariate["se"], 3),
                    p: format_number(&covariate["p"], 3),
                });
            }
            page.warnings = analysis["warnings"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|warning| warning.as_str().map(str::to_string))
                .collect();
        }
        Err(error) => page.analysis_error = Some(error.to_string()),
    }
    crate::pages::render(&page)
}
