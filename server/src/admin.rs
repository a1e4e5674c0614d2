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

use askama::Template;
use axum::Router;
use axum::extract::{Path, Query, RawQuery, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::{delete, get, post};
use serde::{Deserialize, Serialize};
use sqlx::Row;

use crate::AppState;
use crate::auth::{authorize_admin_change as authorize_change, authorize_admin_via as authorize};
use crate::error::{AppError, AppResult, Json};
use crate::export::{self, ExportError, Include, LeftOut};
use crate::pages::download;

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

/// Progress of one study.
#[derive(Debug, Clone, Serialize)]
pub struct StudyStats {
    pub slug: String,
    pub title: String,
    pub kind: String,
    pub open: bool,
    /// Whether this server serves the study now (it may be in the database only).
    pub served: bool,
    /// Whether its stimuli have errors against a ground truth (`stimuli.csv`).
    pub has_stimulus_metrics: bool,
    pub trials: i64,
    /// Real participants who joined: neither pilots nor excluded (as every count below, apart
    /// from `pilots`, `pilots_finished`, `excluded` and `excluded_finished`).
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
    /// Visitors refused by the study's screen requirements (not participants: they never
    /// started), not counting those who came through a preview link.
    pub screened_out: i64,
    /// Participants who joined through a preview link (not counted in `started`), and of them
    /// those who finished.
    pub pilots: i64,
    pub pilots_finished: i64,
    /// Participants the researcher excluded, pilots not counted again (not counted in
    /// `started`), and of them those who finished.
    pub excluded: i64,
    pub excluded_finished: i64,
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let middle = values.len() / 2;
    Some(if values.len() % 2 == 1 { values[middle] } else { (values[middle - 1] + values[middle]) / 2.0 })
}

/// A study's progress. Pilots (preview links) and excluded participants are counted apart, as
/// the analysis and the exports leave them out: a participant both pilot and excluded counts as
/// a pilot.
pub async fn stats(state: &AppState, slug: &str) -> AppResult<StudyStats> {
    let pool = &state.storage().admin;
    let study = sqlx::query("SELECT slug, title, kind, open, definition FROM studies WHERE slug = $1")
        .bind(slug)
        .fetch_optional(pool)
        .await?
        .ok_or_else(|| AppError::NotFound(format!("There is no study \"{slug}\".")))?;
    let served = state.study(slug);
    let trials = match served {
        Some(prepared) => prepared.study.trial_count() as i64,
        None => {
            sqlx::query_scalar("SELECT COALESCE(MAX(trials), 0) FROM participants WHERE study = $1")
                .bind(slug)
                .fetch_one(pool)
                .await?
        }
    };
    let counts = sqlx::query(
        "SELECT answered, CASE WHEN completed_at IS NULL THEN 0 ELSE 1 END AS finished,
                CASE WHEN pilot <> 0 THEN 1 WHEN excluded <> 0 THEN 2 ELSE 0 END AS apart, COUNT(*) AS n
         FROM participants WHERE study = $1 GROUP BY answered, finished, apart",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let mut started = 0;
    let mut finished = 0;
    let mut responses = 0;
    let mut reached = vec![0i64; trials as usize + 1];
    let mut stopped_after = vec![0i64; trials as usize + 1];
    let [mut pilots, mut pilots_finished, mut excluded, mut excluded_finished] = [0i64; 4];
    for row in counts {
        let answered: i64 = row.try_get("answered")?;
        let n: i64 = row.try_get("n")?;
        let is_finished = row.try_get::<i64, _>("finished")? != 0;
        let apart = row.try_get::<i64, _>("apart")?;
        if apart != 0 {
            let (all, done) =
                if apart == 1 { (&mut pilots, &mut pilots_finished) } else { (&mut excluded, &mut excluded_finished) };
            *all += n;
            if is_finished {
                *done += n;
            }
            continue;
        }
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
        "SELECT r.rt_ms FROM responses r JOIN participants p ON p.id = r.participant
         WHERE p.study = $1 AND p.pilot = 0 AND p.excluded = 0",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let totals: Vec<f64> = sqlx::query_scalar(
        "SELECT (julianday(completed_at) - julianday(created_at)) * 86400.0 FROM participants
         WHERE study = $1 AND completed_at IS NOT NULL AND pilot = 0 AND excluded = 0",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let catch = sqlx::query(
        "SELECT COUNT(*) AS n, COALESCE(SUM(CASE WHEN r.chosen != t.catch_expected THEN 1 ELSE 0 END), 0) AS failures,
                COUNT(DISTINCT CASE WHEN r.chosen != t.catch_expected THEN r.participant END) AS failing
         FROM responses r JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
         JOIN participants p ON p.id = r.participant
         WHERE p.study = $1 AND p.pilot = 0 AND p.excluded = 0 AND t.catch_expected IS NOT NULL",
    )
    .bind(slug)
    .fetch_one(pool)
    .await?;
    let screened_out: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM screen_outs WHERE study = $1 AND pilot = 0")
        .bind(slug)
        .fetch_one(pool)
        .await?;
    Ok(StudyStats {
        slug: study.try_get("slug")?,
        title: study.try_get("title")?,
        kind: study.try_get("kind")?,
        open: study.try_get::<i64, _>("open")? == 1,
        served: served.is_some(),
        has_stimulus_metrics: served.is_some_and(|study| study.metrics_csv.is_some()),
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
        screened_out,
        pilots,
        pilots_finished,
        excluded,
        excluded_finished,
    })
}

async fn all_slugs(state: &AppState) -> AppResult<Vec<String>> {
    Ok(sqlx::query_scalar("SELECT slug FROM studies WHERE kind <> 'task' ORDER BY first_loaded_at, slug")
        .fetch_all(&state.storage().admin)
        .await?)
}

async fn list_studies(State(state): State<AppState>, headers: HeaderMap) -> AppResult<Json<Vec<StudyStats>>> {
    authorize(&state, &headers).await?;
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
    authorize(&state, &headers).await?;
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

/// `?include_pilots=true&include_excluded=true` (each `true` or `false`; other keys are ignored).
fn include_from_query(query: Option<String>) -> AppResult<Include> {
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

const QUERY_HINT: &str = "add ?include_pilots=true or ?include_excluded=true to keep them";

fn with_left_out(mut response: Response, left_out: LeftOut) -> Response {
    if let Some(sentence) = left_out.sentence(QUERY_HINT)
        && let Ok(value) = HeaderValue::from_str(&sentence)
    {
        response.headers_mut().insert(LEFT_OUT_HEADER, value);
    }
    response
}

async fn export_csv(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> AppResult<Response> {
    authorize(&state, &headers).await?;
    let include = include_from_query(query)?;
    let csv = export::trials_csv(&state.storage().admin, &slug, include).await?;
    Ok(with_left_out(download("text/csv; charset=utf-8", format!("{slug}-trials.csv"), csv.content), csv.left_out))
}

async fn export_json(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> AppResult<Response> {
    authorize(&state, &headers).await?;
    let include = include_from_query(query)?;
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

async fn conditions_csv(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Response> {
    authorize(&state, &headers).await?;
    let definition = export::definition(&state.storage().admin, &slug).await?;
    Ok(download("text/csv; charset=utf-8", format!("{slug}-conditions.csv"), definition.conditions_csv()))
}

/// The study's stimulus metrics CSV (docs/design.md): each rendered stimulus's errors against the
/// ground truth of its scene configuration. 404 with the reason when the study has none.
async fn stimuli_csv(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Response> {
    authorize(&state, &headers).await?;
    let study = state.study(&slug).ok_or_else(|| {
        AppError::NotFound(format!("study \"{slug}\" is not served by this server, so its stimuli are not known here"))
    })?;
    match &study.metrics_csv {
        Some(csv) => Ok(download("text/csv; charset=utf-8", format!("{slug}-stimuli.csv"), csv.clone())),
        None => Err(AppError::NotFound(format!(
            "study \"{slug}\" has no stimulus metrics: {}",
            if study.metrics_notes.is_empty() {
                "it has no rendered stimuli".to_string()
            } else {
                study.metrics_notes.join("; ")
            }
        ))),
    }
}

/// Whether the live analysis sets the study's stimulus metrics beside the preference.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metrics {
    Set,
    Skip,
}

/// The live analysis of a study: the analysis crate run on the trials CSV and the study's
/// conditions CSV — exactly what `mrstudy export` and `mrstudy analyze --conditions` give.
/// Pilot and excluded participants are left out unless `include` keeps them; a warning says how
/// many were left out and why.
///
/// With `Metrics::Set`, a served study's stimulus metrics are set beside the preference (the
/// `metrics` section, a bootstrap of its own); `Metrics::Skip` leaves that work out where only
/// the rest is read (the participants list's observer flags).
pub async fn analysis_json(
    state: &AppState,
    slug: &str,
    include: Include,
    metrics: Metrics,
) -> AppResult<serde_json::Value> {
    let pool = &state.storage().admin;
    let definition = export::definition(pool, slug).await?;
    let trials = export::trials_csv(pool, slug, include).await?;
    let left_out = trials.left_out.sentence(QUERY_HINT);
    let served = state.study(slug);
    let stimuli = served.and_then(|study| study.stimulus_metrics.as_ref()).filter(|_| metrics == Metrics::Set);
    let mut analysis =
        crate::analysis::run(&trials.content, &definition, include, stimuli).map_err(|error| {
            match (error, &left_out) {
                (AppError::Unprocessable(message), Some(_)) => AppError::Unprocessable(format!(
                    "{}; {}",
                    message.trim_end_matches('.'),
                    trials.left_out.clause(QUERY_HINT).unwrap_or_default()
                )),
                (error, _) => error,
            }
        })?;
    if let Some(sentence) = left_out
        && let Some(warnings) = analysis.get_mut("warnings").and_then(serde_json::Value::as_array_mut)
    {
        warnings.insert(0, serde_json::Value::String(sentence));
    }
    Ok(analysis)
}

async fn analysis(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> AppResult<Json<serde_json::Value>> {
    authorize(&state, &headers).await?;
    let include = include_from_query(query)?;
    Ok(Json(analysis_json(&state, &slug, include, Metrics::Set).await?))
}

async fn worth_svg(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> AppResult<Response> {
    authorize(&state, &headers).await?;
    let include = include_from_query(query)?;
    let pool = &state.storage().admin;
    let definition = export::definition(pool, &slug).await?;
    let trials = export::trials_csv(pool, &slug, include).await?;
    Ok(svg_response(crate::analysis::worth_svg(&trials.content, &definition, include)?))
}

/// The scatter plot of the image metric that predicts preference best.
async fn metric_svg(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> AppResult<Response> {
    authorize(&state, &headers).await?;
    let include = include_from_query(query)?;
    let served = state.study(&slug);
    let stimuli = served.as_ref().and_then(|study| study.stimulus_metrics.as_ref()).ok_or_else(|| {
        AppError::NotFound(format!("study \"{slug}\" has no stimulus metrics on this server (no ground truth)"))
    })?;
    let trials = export::trials_csv(&state.storage().admin, &slug, include).await?;
    Ok(svg_response(crate::analysis::best_metric_svg(&trials.content, include, stimuli)?))
}

fn svg_response(svg: String) -> Response {
    let mut response = (StatusCode::OK, svg).into_response();
    let response_headers = response.headers_mut();
    response_headers.insert(header::CONTENT_TYPE, HeaderValue::from_static("image/svg+xml"));
    // An SVG shown through <img> runs no scripts; its own inline styles are allowed.
    response_headers.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static("default-src 'none'; style-src 'unsafe-inline'; frame-ancestors 'none'"),
    );
    response
}

#[derive(Serialize)]
struct OpenState {
    slug: String,
    open: bool,
}

async fn set_open(state: AppState, slug: String, headers: HeaderMap, open: bool) -> AppResult<Json<OpenState>> {
    authorize_change(&state, &headers).await?;
    state.storage().set_open(&slug, open).await??;
    Ok(Json(OpenState { slug, open }))
}

async fn open_study(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<OpenState>> {
    set_open(state, slug, headers, true).await
}

async fn close_study(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<OpenState>> {
    set_open(state, slug, headers, false).await
}

// ------------------------------------------------------------------------------------------
// Pages.

/// Ends the admin session of the cookie and clears the cookie. A cross-site form cannot send
/// the SameSite=Strict cookie, so this needs no `X-Requested-With`.
async fn logout(State(state): State<AppState>, headers: HeaderMap) -> Response {
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
struct LoginQuery {
    token: Option<String>,
}

async fn login(State(state): State<AppState>, Query(query): Query<LoginQuery>) -> Response {
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

async fn page_authorize(state: &AppState, headers: &HeaderMap) -> Result<(), Box<Response>> {
    authorize(state, headers).await.map(|_| ()).map_err(|error| {
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
    /// Studies whose stimuli are still being rendered (or could not be).
    preparing: Vec<PreparingRow>,
    /// Task studies whose lab is still starting: (slug, title).
    lab_starting: Vec<(String, String)>,
    /// Seconds after which the page reloads itself: while something is being prepared.
    refresh: Option<u64>,
    /// Refusals counted per status and route template ([`crate::logs`]).
    refusals: Vec<crate::logs::Refusal>,
}

/// One study being prepared, as the admin page shows it ([`crate::preparing`]).
pub struct PreparingRow {
    pub slug: String,
    pub title: String,
    /// Done, in per cent (0 to 100).
    pub percent: u32,
    /// Counts and the estimate of the time left, or why it failed.
    pub summary: String,
    pub failed: bool,
}

impl AdminPage {
    fn new(state: &AppState, studies: Vec<StudyStats>) -> AdminPage {
        let now = std::time::Instant::now();
        let preparing: Vec<PreparingRow> = state
            .preparation()
            .studies()
            .iter()
            .map(|study| PreparingRow {
                slug: study.slug.clone(),
                title: study.title.clone(),
                percent: (study.fraction() * 100.0).floor() as u32,
                summary: study.summary(now),
                failed: matches!(study.stage, crate::preparing::Stage::Failed(_)),
            })
            .collect();
        let lab_starting = state.preparation().lab();
        let busy = preparing.iter().any(|row| !row.failed) || !lab_starting.is_empty();
        AdminPage {
            studies,
            lab: crate::task::results::overview(state),
            preparing,
            lab_starting,
            refresh: busy.then_some(10),
            refusals: state.refusals().kinds(),
        }
    }
}

async fn admin_page(State(state): State<AppState>, headers: HeaderMap) -> Response {
    if let Err(page) = page_authorize(&state, &headers).await {
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
        Ok(studies) => crate::pages::render(&AdminPage::new(&state, studies)),
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
    /// An active design: how many judgments its posterior has absorbed, and why it fell back to
    /// the fixed design if it did.
    active_note: Option<String>,
    active_warning: Option<String>,
    /// Every visitor: participants who started and visitors screened out (`stopped`).
    visitors_bar: FunnelBar,
    funnel: Vec<FunnelBar>,
    funnel_width: f64,
    funnel_top: i64,
    analysis_error: Option<String>,
    judgments: String,
    agreement_u: Option<String>,
    worth: Vec<WorthRow>,
    estimates: Vec<EstimateRow>,
    warnings: Vec<String>,
    participants: Vec<ParticipantLine>,
    /// A preference analysis exists (not only detection trials).
    has_preference: bool,
    /// Detection trials ("real or rendered?"): one row per condition.
    detection: Vec<DetectionRow>,
    detection_note: Option<String>,
    /// The image metrics against the preference, best predictor first.
    metric_rows: Vec<MetricRow>,
    metrics_note: Option<String>,
}

/// One condition of the detection analysis.
pub struct DetectionRow {
    pub condition: String,
    pub trials: String,
    pub rate: String,
    pub ci: String,
    pub p: String,
    pub d_prime: String,
    pub verdict: String,
}

/// One metric × region set beside the preference.
pub struct MetricRow {
    pub rank: String,
    pub metric: String,
    pub region: String,
    pub spearman: String,
    pub kendall: String,
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
    if let Err(page) = page_authorize(&state, &headers).await {
        return *page;
    }
    let stats = match stats(&state, &slug).await {
        Ok(stats) => stats,
        Err(AppError::NotFound(message)) => {
            return crate::pages::message_page(StatusCode::NOT_FOUND, "No such study", &message);
        }
        Err(error) => return error.into_response(),
    };
    // Bars share about 640 px, each 4 to 40 px wide; the first (grey) bar is every visitor,
    // those the screen requirements refused included, then one bar per number of trials answered.
    let visitors = stats.started + stats.screened_out;
    let bar_count = (stats.reached.len() + 1) as f64;
    let bar_width = (640.0 / bar_count).clamp(4.0, 40.0) - 2.0;
    let max_reached = visitors.max(1) as f64;
    let label_every = ((bar_count / 13.0).ceil() as usize).max(1);
    let visitors_height = 120.0 * visitors as f64 / max_reached;
    let visitors_bar = FunnelBar {
        trial: 0,
        reached: visitors,
        stopped: stats.screened_out,
        x: 50.0,
        width: bar_width,
        height: visitors_height,
        y: 140.0 - visitors_height,
        label: true,
    };
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
                x: 50.0 + (trial + 1) as f64 * (bar_width + 2.0),
                width: bar_width,
                height,
                y: 140.0 - height,
                label: trial % label_every == 0 || trial + 1 == stats.reached.len(),
            }
        })
        .collect();
    let funnel_width = 70.0 + bar_count * (bar_width + 2.0);
    let funnel_top = visitors;
    let mut page = AdminStudyPage {
        visitors_bar,
        funnel,
        funnel_width,
        funnel_top,
        analysis_error: None,
        judgments: String::new(),
        agreement_u: None,
        worth: Vec::new(),
        estimates: Vec::new(),
        warnings: Vec::new(),
        participants: Vec::new(),
        stats,
        active_note: None,
        active_warning: None,
        has_preference: false,
        detection: Vec::new(),
        detection_note: None,
        metric_rows: Vec::new(),
        metrics_note: None,
    };
    if let Some(active) = state.active(&slug) {
        let active = active.lock().await;
        page.active_note = Some(format!(
            "Active design: each participant's trials are chosen by expected information gain from every judgment so far ({} absorbed when a batch was last chosen).",
            active.judgments()
        ));
        page.active_warning = active.failure.clone();
    }
    let analysis = analysis_json(&state, &slug, Include::default(), Metrics::Set).await;
    page.participants = match participants(&state, &slug, analysis.as_ref().ok()).await {
        Ok(entries) => entries.iter().map(ParticipantLine::from).collect(),
        Err(error) => return error.into_response(),
    };
    match analysis {
        Ok(analysis) => {
            page.has_preference = analysis.get("items").is_some();
            if let Some(detection) = analysis.get("detection") {
                page.detection_note = Some(format!(
                    "{} detection trials: how often the ground truth was taken for real (chance {}); exact binomial test at α = {}, power against a true rate of {}.",
                    format_number(&detection["judgments"], 0),
                    format_number(&detection["chance"], 2),
                    format_number(&detection["alpha"], 2),
                    format_number(&detection["alternative_rate"], 2)
                ));
                for rate in detection["conditions"].as_array().into_iter().flatten() {
                    let verdict = rate["verdict"].as_str().unwrap_or_default();
                    page.detection.push(DetectionRow {
                        condition: rate["condition"].as_str().unwrap_or_default().to_string(),
                        trials: format!(
                            "{} of {}",
                            format_number(&rate["correct"], 0),
                            format_number(&rate["trials"], 0)
                        ),
                        rate: format_number(&rate["rate"], 3),
                        ci: format!("[{}, {}]", format_number(&rate["ci"][0], 3), format_number(&rate["ci"][1], 3)),
                        p: format_number(&rate["p"], 3),
                        d_prime: format!(
                            "{} ± {}",
                            format_number(&rate["d_prime"], 2),
                            format_number(&rate["d_prime_se"], 2)
                        ),
                        verdict: if verdict == "inconclusive" {
                            format!("inconclusive (power {})", format_number(&rate["power"], 2))
                        } else {
                            verdict.to_string()
                        },
                    });
                }
                for warning in detection["warnings"].as_array().into_iter().flatten() {
                    page.warnings.extend(warning.as_str().map(str::to_string));
                }
            }
            if let Some(metrics) = analysis.get("metrics") {
                let best = &metrics["best"];
                page.metrics_note = Some(format!(
                    "{}. {}",
                    metrics["level_reason"].as_str().unwrap_or_default().trim_end_matches('.'),
                    match best.get("metric") {
                        Some(metric) => format!(
                            "Best predictor of preference: {} in the {} region.",
                            metric.as_str().unwrap_or_default(),
                            best["region"].as_str().unwrap_or_default()
                        ),
                        None => "No metric could be set beside the preference yet.".to_string(),
                    }
                ));
                let interval = |ci: &serde_json::Value| match ci.as_array() {
                    Some(ci) if ci.len() == 2 => {
                        format!(" [{}, {}]", format_number(&ci[0], 2), format_number(&ci[1], 2))
                    }
                    _ => String::new(),
                };
                // The ranked image metrics, then the timings (costs, not image errors: unranked).
                let timings = metrics["timings"].as_array().into_iter().flatten();
                for row in metrics["correlations"].as_array().into_iter().flatten().chain(timings) {
                    page.metric_rows.push(MetricRow {
                        rank: match row.get("rank") {
                            Some(rank) => format_number(rank, 0),
                            None => "timing, not ranked".to_string(),
                        },
                        metric: row["metric"].as_str().unwrap_or_default().to_string(),
                        region: row["region"].as_str().unwrap_or_default().to_string(),
                        spearman: format!(
                            "{}{}",
                            format_number(&row["spearman_rho"], 2),
                            interval(&row["spearman_ci"])
                        ),
                        kendall: format!("{}{}", format_number(&row["kendall_tau_b"], 2), interval(&row["kendall_ci"])),
                    });
                }
            }
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
            page.warnings.extend(
                analysis["warnings"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .filter_map(|warning| warning.as_str().map(str::to_string)),
            );
        }
        Err(error) => page.analysis_error = Some(error.to_string()),
    }
    crate::pages::render(&page)
}

// ------------------------------------------------------------------------------------------
// Participants (issue 12): the list with status and flags, exclude/include, delete, preview.

/// A participant's progress: answered trials of their schedule.
#[derive(Debug, Clone, Serialize)]
pub struct Progress {
    pub answered: i64,
    pub trials: i64,
}

/// What the researcher should look at before trusting a participant's judgments.
#[derive(Debug, Clone, Serialize)]
pub struct Flags {
    /// Responses faster than the study's `min_response_ms`.
    pub too_fast: i64,
    pub catch_answered: i64,
    pub catch_failed: i64,
    /// Flagged by the analysis's leave-one-out observer screening (choices unlikely under the
    /// consensus of the others); absent when the participant was not screened (left out of the
    /// analysis, no judgments, or screening not possible on the data so far).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub observer_flagged: Option<bool>,
}

/// One row of `GET /api/admin/studies/{slug}/participants`: a participant, or a visitor who was
/// screened out (whose `participant` is the screen-out's id, deletable the same way).
#[derive(Debug, Clone, Serialize)]
pub struct ParticipantEntry {
    pub participant: String,
    /// `completed`, `started`, `abandoned` or `screened-out`.
    pub status: &'static str,
    pub progress: Progress,
    pub external_ids: serde_json::Map<String, serde_json::Value>,
    pub completion_code: Option<String>,
    pub pilot: bool,
    pub excluded: bool,
    pub flags: Flags,
    /// 0, 1, 2, … in joining order (absent for a screen-out).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ordinal: Option<i64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exclusion_reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub excluded_at: Option<String>,
    /// The sentence a screened-out visitor was shown.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub screen_out_reason: Option<String>,
    pub joined_at: String,
    pub last_activity_at: String,
}

/// The participants of a study and then its screened-out visitors. `analysis` (the default
/// analysis JSON, if it could be run) gives the observer-screening flags.
pub async fn participants(
    state: &AppState,
    slug: &str,
    analysis: Option<&serde_json::Value>,
) -> AppResult<Vec<ParticipantEntry>> {
    let pool = &state.storage().admin;
    let definition = export::definition(pool, slug).await?;
    let mut screened = std::collections::HashMap::new();
    if let Some(observers) = analysis.and_then(|analysis| analysis["observers"]["participants"].as_array()) {
        for observer in observers {
            if let (Some(name), Some(flagged)) = (observer["participant"].as_str(), observer["flagged"].as_bool()) {
                screened.insert(name.to_string(), flagged);
            }
        }
    }
    let mut entries: Vec<ParticipantEntry> = export::participant_records(pool, slug, &definition)
        .await?
        .into_iter()
        .map(|record| ParticipantEntry {
            status: record.status,
            progress: Progress { answered: record.answered, trials: record.trials },
            external_ids: record.external_ids,
            completion_code: Some(record.completion_code),
            pilot: record.pilot,
            excluded: record.excluded,
            flags: Flags {
                too_fast: record.too_fast,
                catch_answered: record.catch_answered,
                catch_failed: record.catch_failed,
                observer_flagged: screened.get(&record.participant).copied(),
            },
            ordinal: Some(record.ordinal),
            exclusion_reason: record.exclusion_reason,
            excluded_at: record.excluded_at,
            screen_out_reason: None,
            joined_at: record.joined_at,
            last_activity_at: record.last_activity_at,
            participant: record.participant,
        })
        .collect();
    let screen_outs = sqlx::query(
        "SELECT id, reason, url_params, pilot, created_at FROM screen_outs WHERE study = $1 ORDER BY created_at, id",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    for row in screen_outs {
        let created_at: String = row.try_get("created_at")?;
        entries.push(ParticipantEntry {
            participant: row.try_get("id")?,
            status: "screened-out",
            progress: Progress { answered: 0, trials: 0 },
            external_ids: export::external_ids(&definition, &row.try_get::<String, _>("url_params")?),
            completion_code: None,
            pilot: row.try_get::<i64, _>("pilot")? == 1,
            excluded: false,
            flags: Flags { too_fast: 0, catch_answered: 0, catch_failed: 0, observer_flagged: None },
            ordinal: None,
            exclusion_reason: None,
            excluded_at: None,
            screen_out_reason: Some(row.try_get("reason")?),
            joined_at: created_at.clone(),
            last_activity_at: created_at,
        });
    }
    Ok(entries)
}

async fn list_participants(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<Vec<ParticipantEntry>>> {
    authorize(&state, &headers).await?;
    // The observer flags come from the default analysis; a study whose data cannot be analysed
    // yet still lists its participants, without those flags.
    let analysis = match analysis_json(&state, &slug, Include::default(), Metrics::Skip).await {
        Ok(analysis) => Some(analysis),
        Err(AppError::Unprocessable(_)) => None,
        Err(error) => return Err(error),
    };
    Ok(Json(participants(&state, &slug, analysis.as_ref()).await?))
}

#[derive(Deserialize)]
struct ReasonBody {
    reason: Option<String>,
}

/// Longest exclusion reason kept, in characters.
pub const MAX_REASON_CHARS: usize = 500;

/// A refused admin write, as the researcher reads it.
impl From<crate::storage::AdminRefused> for AppError {
    fn from(refused: crate::storage::AdminRefused) -> Self {
        match refused {
            crate::storage::AdminRefused::UnknownParticipant { id } => {
                AppError::NotFound(format!("There is no participant \"{}\".", id.chars().take(64).collect::<String>()))
            }
            crate::storage::AdminRefused::UnknownStudy { slug } => {
                AppError::NotFound(format!("There is no study \"{slug}\"."))
            }
        }
    }
}

/// The participant after an exclude or include.
#[derive(Serialize)]
struct ExclusionState {
    participant: String,
    excluded: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    exclusion_reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    excluded_at: Option<String>,
}

async fn set_excluded(state: &AppState, id: String, reason: Option<String>) -> AppResult<Json<ExclusionState>> {
    let written = state
        .storage()
        .admin_write(crate::storage::AdminWrite::SetExcluded { participant: id.clone(), reason })
        .await??;
    match written {
        crate::storage::AdminWritten::Excluded { excluded, reason, excluded_at, .. } => {
            Ok(Json(ExclusionState { participant: id, excluded, exclusion_reason: reason, excluded_at }))
        }
        _ => Err(AppError::Internal("an exclusion had no exclusion outcome".into())),
    }
}

async fn exclude_participant(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    Json(body): Json<ReasonBody>,
) -> AppResult<Json<ExclusionState>> {
    authorize_change(&state, &headers).await?;
    let reason = body.reason.map(|reason| reason.trim().to_string()).unwrap_or_default();
    if reason.is_empty() {
        return Err(AppError::Unprocessable(
            "Excluding a participant needs a reason: send {\"reason\": \"…\"}.".into(),
        ));
    }
    if reason.chars().count() > MAX_REASON_CHARS {
        return Err(AppError::Unprocessable(format!(
            "The reason must be at most {MAX_REASON_CHARS} characters, found {}.",
            reason.chars().count()
        )));
    }
    set_excluded(&state, id, Some(reason)).await
}

/// Includes an excluded participant again; a body, if any, is not read.
async fn include_participant(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<ExclusionState>> {
    authorize_change(&state, &headers).await?;
    set_excluded(&state, id, None).await
}

async fn delete_participant(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<crate::storage::Deletion>> {
    authorize_change(&state, &headers).await?;
    let deletion = state.storage().delete(&id).await??;
    state.forget_credentials(&id);
    Ok(Json(deletion))
}

#[derive(Serialize)]
struct PreviewLink {
    url: String,
    /// When the link stops letting pilots join ([`crate::storage::PREVIEW_LINK_DAYS`] from now).
    expires_at: String,
}

/// A new preview link: a random 256-bit token, stored as its SHA-256 in `previews`; a participant
/// who joins with it (`preview` in the join body) is a pilot, for
/// [`crate::storage::PREVIEW_LINK_DAYS`] days or until the study's links are revoked.
async fn create_preview(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<(StatusCode, Json<PreviewLink>)> {
    authorize_change(&state, &headers).await?;
    let kind: Option<String> = sqlx::query_scalar("SELECT kind FROM studies WHERE slug = $1")
        .bind(&slug)
        .fetch_optional(&state.storage().admin)
        .await?;
    // a lab task study's preview opens its lab page; its participants are pilots too
    let page = match kind.as_deref() {
        None => return Err(AppError::NotFound(format!("There is no study \"{slug}\"."))),
        Some("task") => "lab",
        Some(_) => "studies",
    };
    let token = crate::random_hex(32);
    state
        .storage()
        .admin_write(crate::storage::AdminWrite::Preview {
            study: slug.clone(),
            token_sha256: crate::auth::sha256(token.as_bytes()).to_vec(),
        })
        .await??;
    let valid = std::time::Duration::from_secs(crate::storage::PREVIEW_LINK_DAYS * 86_400);
    let expires_at = crate::storage::iso(std::time::SystemTime::now() + valid);
    Ok((StatusCode::CREATED, Json(PreviewLink { url: format!("/{page}/{slug}?preview={token}"), expires_at })))
}

#[derive(Serialize)]
struct Revoked {
    revoked: u64,
}

/// Revokes every preview link of the study: joining with one is refused from now on (pilots who
/// joined keep their run).
async fn revoke_previews(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    headers: HeaderMap,
) -> AppResult<Json<Revoked>> {
    authorize_change(&state, &headers).await?;
    let known: Option<String> = sqlx::query_scalar("SELECT slug FROM studies WHERE slug = $1")
        .bind(&slug)
        .fetch_optional(&state.storage().admin)
        .await?;
    if known.is_none() {
        return Err(AppError::NotFound(format!("There is no study \"{slug}\".")));
    }
    match state.storage().admin_write(crate::storage::AdminWrite::RevokePreviews { study: slug }).await?? {
        crate::storage::AdminWritten::PreviewsRevoked(revoked) => Ok(Json(Revoked { revoked })),
        _ => Err(AppError::Internal("a revocation had no revocation outcome".into())),
    }
}

/// One row of the page's participants table, as text.
pub struct ParticipantLine {
    pub id: String,
    pub label: String,
    pub status: &'static str,
    pub progress: String,
    pub external_ids: String,
    pub completion_code: String,
    pub flags: Vec<String>,
    pub pilot: bool,
    pub excluded: bool,
    pub exclusion_reason: String,
    pub screened_out: bool,
}

impl From<&ParticipantEntry> for ParticipantLine {
    fn from(entry: &ParticipantEntry) -> Self {
        let mut flags = Vec::new();
        if entry.flags.too_fast > 0 {
            flags.push(format!("{} too fast", entry.flags.too_fast));
        }
        if entry.flags.catch_failed > 0 {
            flags.push(format!("catch failed {} of {}", entry.flags.catch_failed, entry.flags.catch_answered));
        }
        if entry.flags.observer_flagged == Some(true) {
            flags.push("unlike the others (observer screening)".into());
        }
        if let Some(reason) = &entry.screen_out_reason {
            flags.push(reason.clone());
        }
        ParticipantLine {
            id: entry.participant.clone(),
            label: match entry.ordinal {
                Some(ordinal) => format!("#{ordinal}"),
                None => "visitor".into(),
            },
            status: entry.status,
            progress: if entry.screen_out_reason.is_some() {
                "–".into()
            } else {
                format!("{}/{}", entry.progress.answered, entry.progress.trials)
            },
            external_ids: entry
                .external_ids
                .iter()
                .map(|(name, value)| {
                    format!("{name}={}", value.as_str().map(str::to_string).unwrap_or_else(|| value.to_string()))
                })
                .collect::<Vec<_>>()
                .join(", "),
            completion_code: entry.completion_code.clone().unwrap_or_default(),
            flags,
            pilot: entry.pilot,
            excluded: entry.excluded,
            exclusion_reason: entry.exclusion_reason.clone().unwrap_or_default(),
            screened_out: entry.screen_out_reason.is_some(),
        }
    }
}
