//! A study's progress and dropout (`GET /api/admin/studies…`) and its live analysis, worth plot
//! and metric plot.

use super::{AdminInclude, QUERY_HINT, store};
use crate::AppState;
use crate::auth::Admin;
use crate::error::{AppError, AppResult, Json};
use crate::export::{self, Include};
use axum::extract::{Path, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use mrstudy_analysis::analysis::Scale;
use serde::Serialize;

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

/// A study's progress. Pilots (preview links) and excluded participants are counted apart, as
/// the analysis and the exports leave them out: a participant both pilot and excluded counts as
/// a pilot.
pub async fn stats(state: &AppState, slug: &str) -> AppResult<StudyStats> {
    let pool = &state.storage().admin;
    let study = store::study_row(pool, slug)
        .await?
        .ok_or_else(|| AppError::NotFound(format!("There is no study \"{slug}\".")))?;
    let served = state.study(slug);
    let trials = match served {
        Some(prepared) => prepared.study.trial_count() as i64,
        None => store::max_trials(pool, slug).await?,
    };
    let counts = store::participant_counts(pool, slug).await?;
    let mut started = 0;
    let mut finished = 0;
    let mut responses = 0;
    let mut reached = vec![0i64; trials as usize + 1];
    let mut stopped_after = vec![0i64; trials as usize + 1];
    let [mut pilots, mut pilots_finished, mut excluded, mut excluded_finished] = [0i64; 4];
    for store::ParticipantCount { answered, finished: is_finished, apart, n } in counts {
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
    let rts = store::response_times(pool, slug).await?;
    let totals = store::total_times(pool, slug).await?;
    let catch = store::catch_counts(pool, slug).await?;
    let screened_out = store::screened_out(pool, slug).await?;
    Ok(StudyStats {
        slug: study.slug,
        title: study.title,
        kind: study.kind,
        open: study.open,
        served: served.is_some(),
        has_stimulus_metrics: state.stimulus_metrics(slug).is_some_and(|now| now.csv.is_some()),
        trials,
        started,
        finished,
        completion_rate: (started > 0).then(|| finished as f64 / started as f64),
        reached,
        stopped_after,
        responses,
        median_rt_ms: mrstudy_analysis::quantile::median(rts),
        median_total_s: mrstudy_analysis::quantile::median(totals),
        catch_responses: catch.responses,
        catch_failures: catch.failures,
        participants_failing_catch: catch.failing,
        screened_out,
        pilots,
        pilots_finished,
        excluded,
        excluded_finished,
    })
}

pub(super) async fn all_slugs(state: &AppState) -> AppResult<Vec<String>> {
    Ok(store::survey_slugs(&state.storage().admin).await?)
}

pub(super) async fn list_studies(State(state): State<AppState>, _: Admin) -> AppResult<Json<Vec<StudyStats>>> {
    let mut all = Vec::new();
    for slug in all_slugs(&state).await? {
        all.push(stats(&state, &slug).await?);
    }
    Ok(Json(all))
}

pub(super) async fn study_stats(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: Admin,
) -> AppResult<Json<StudyStats>> {
    Ok(Json(stats(&state, &slug).await?))
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
    scale: Scale,
) -> AppResult<serde_json::Value> {
    let pool = &state.storage().admin;
    let definition = export::definition(pool, slug).await?;
    let trials = export::trials_csv(pool, slug, include).await?;
    let left_out = trials.left_out.sentence(QUERY_HINT);
    let now = state.stimulus_metrics(slug).filter(|_| metrics == Metrics::Set);
    let stimuli = now.as_ref().and_then(|now| now.metrics.as_ref());
    let mut analysis =
        crate::live_analysis::run(&trials.content, &definition, include, stimuli, scale).map_err(|error| {
            match (error, &left_out) {
                (AppError::Unprocessable(message), Some(_)) => AppError::Unprocessable(format!(
                    "{}; {}",
                    message.trim_end_matches('.'),
                    trials.left_out.clause(QUERY_HINT).unwrap_or_default()
                )),
                (error, _) => error,
            }
        })?;
    // a rating study's warnings are its `ratings` section's
    let warnings = match analysis.get("ratings") {
        Some(_) => analysis["ratings"].get_mut("warnings"),
        None => analysis.get_mut("warnings"),
    };
    if let Some(sentence) = left_out
        && let Some(warnings) = warnings.and_then(serde_json::Value::as_array_mut)
    {
        warnings.insert(0, serde_json::Value::String(sentence));
    }
    Ok(analysis)
}

pub(super) async fn analysis(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    AdminInclude(include): AdminInclude,
) -> AppResult<Json<serde_json::Value>> {
    Ok(Json(analysis_json(&state, &slug, include, Metrics::Set, Scale::Bt).await?))
}

pub(super) async fn worth_svg(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    AdminInclude(include): AdminInclude,
) -> AppResult<Response> {
    let pool = &state.storage().admin;
    let definition = export::definition(pool, &slug).await?;
    let trials = export::trials_csv(pool, &slug, include).await?;
    Ok(svg_response(crate::live_analysis::worth_svg(&trials.content, &definition, include)?))
}

/// The scatter plot of the image metric that predicts preference best.
pub(super) async fn metric_svg(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    AdminInclude(include): AdminInclude,
) -> AppResult<Response> {
    let now = state.stimulus_metrics(&slug);
    let stimuli = now.as_ref().and_then(|now| now.metrics.as_ref()).ok_or_else(|| {
        AppError::NotFound(format!("study \"{slug}\" has no stimulus metrics on this server (no ground truth)"))
    })?;
    let trials = export::trials_csv(&state.storage().admin, &slug, include).await?;
    Ok(svg_response(crate::live_analysis::best_metric_svg(&trials.content, include, stimuli)?))
}

pub(super) fn svg_response(svg: String) -> Response {
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
