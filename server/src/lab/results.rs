//! Results of task studies: the two CSV exports and the admin page with the live analysis.
//!
//! - **Task CSV** (`/api/admin/lab/{slug}/task.csv`, `mrstudy export --format task`): the long
//!   CSV that `mrstudy analyze` reads, `participant,task,measure,condition,value,trials,label`,
//!   one row per participant, task, measure and condition, `value` the mean over that cell's
//!   answered non-practice trials (`trials` of them), of real participants only (pilots from
//!   preview links and excluded participants are left out, as in the survey's analysis). Measures: `time_s` (completion time),
//!   `error_cm` (total error: |answer − true distance| for `distance`, the Euclidean distance
//!   from the target for `placement` and `contact`), `abs_error_<axis>_cm` for each axis along
//!   which the task varies (x and z for distance and placement, y for contact), and
//!   `signed_error_cm` for distance (answer − truth) and contact (height left above the table).
//! - **Task trials CSV** (`/api/admin/lab/{slug}/trials.csv`, `--format task-trials`): one row
//!   per answered trial with every stored column (practice trials included, flagged), of every
//!   participant with `pilot` and `excluded`, the trial's `frames_late` and the participant's
//!   `pace_kept` (`false`: more than 5 % of their paced frames came late; empty when not paced).
//!
//! The admin page (`/admin/lab/{slug}`) shows the adapter and each condition's frame time, at
//! start-up and now (each condition fast enough or too slow, and a warning when the conditions
//! differ by more than 20 % without `pace = "equal"`), progress per participant (with the
//! counterbalancing slot and who abandoned theirs), the stored frame times, frames shown and
//! latencies per condition, and per task and measure the Friedman test, Kendall's W and
//! the Holm-corrected Wilcoxon post hoc tests of `mrstudy_analysis::task`.

use crate::export::text_cell;
use askama::Template;
use axum::Router;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use mrstudy_analysis::task::{TaskAnalysis, analyze_task_csv};
use sqlx::Row;

use crate::participant::model::ParticipantProgress;
use crate::storage::Pool;

use crate::AppState;
use crate::auth::Admin;
use crate::error::{AppError, AppResult, Json};
use crate::study::task::TaskKind;

pub fn router() -> Router<AppState> {
    Router::new()
        .route("/api/admin/lab/{slug}/task.csv", get(task_csv_download))
        .route("/api/admin/lab/{slug}/trials.csv", get(trials_csv_download))
        .route("/api/admin/lab/{slug}/analysis", get(analysis_json))
        .route("/admin/lab/{slug}", get(admin_lab_page))
}

/// The stored definition of a task study.
pub async fn definition(pool: &Pool, slug: &str) -> AppResult<serde_json::Value> {
    let row =
        sqlx::query("SELECT kind, definition FROM studies WHERE slug = $1").bind(slug).fetch_optional(pool).await?;
    let Some(row) = row else { return Err(AppError::NotFound(format!("There is no study \"{slug}\"."))) };
    let kind: String = row.try_get("kind")?;
    if kind != "task" {
        return Err(AppError::NotFound(format!("Study \"{slug}\" is a {kind} study, not a task study.")));
    }
    let text: String = row.try_get("definition")?;
    serde_json::from_str(&text)
        .map_err(|error| AppError::Internal(format!("the stored definition of \"{slug}\" is not JSON: {error}")))
}

fn measures(kind: TaskKind) -> Vec<&'static str> {
    let mut measures = vec!["time_s", "error_cm"];
    for axis in kind.axes() {
        measures.push(match axis {
            'x' => "abs_error_x_cm",
            'y' => "abs_error_y_cm",
            _ => "abs_error_z_cm",
        });
    }
    if kind != TaskKind::Placement {
        measures.push("signed_error_cm");
    }
    measures
}

/// The task CSV (see the module doc).
pub async fn task_csv(pool: &Pool, slug: &str) -> AppResult<String> {
    let definition = definition(pool, slug).await?;
    let condition_order: Vec<String> = definition["conditions"]
        .as_array()
        .map(|list| list.iter().filter_map(|c| c.as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    let task_order: Vec<String> = definition["tasks"]
        .as_array()
        .map(|list| list.iter().filter_map(|t| t["name"].as_str().map(str::to_string)).collect())
        .unwrap_or_default();
    let rows = sqlx::query(
        "SELECT p.id, p.label, p.ordinal, t.task, t.kind, t.condition, COUNT(*) AS n,
                AVG(t.completion_ms) / 1000.0 AS time_s, AVG(t.error_cm) AS error_cm,
                AVG(ABS(t.error_x_cm)) AS abs_error_x_cm, AVG(ABS(t.error_y_cm)) AS abs_error_y_cm,
                AVG(ABS(t.error_z_cm)) AS abs_error_z_cm, AVG(t.signed_error_cm) AS signed_error_cm
         FROM task_trials t JOIN task_participants p ON p.id = t.participant
         WHERE p.study = $1 AND t.practice = 0 AND t.answered_at IS NOT NULL AND p.pilot = 0 AND p.excluded = 0
         GROUP BY p.id, t.task, t.kind, t.condition",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    struct Cell {
        id: String,
        label: String,
        ordinal: i64,
        task: String,
        kind: TaskKind,
        condition: String,
        n: i64,
        values: Vec<(&'static str, Option<f64>)>,
    }
    let mut cells = Vec::new();
    for row in &rows {
        let kind_text: String = row.try_get("kind")?;
        let kind: TaskKind = serde_json::from_value(serde_json::Value::String(kind_text.clone()))
            .map_err(|_| AppError::Internal(format!("unknown task kind {kind_text} in the database")))?;
        let mut values = Vec::new();
        for measure in measures(kind) {
            values.push((measure, row.try_get::<Option<f64>, _>(measure)?));
        }
        cells.push(Cell {
            id: row.try_get("id")?,
            label: row.try_get("label")?,
            ordinal: row.try_get("ordinal")?,
            task: row.try_get("task")?,
            kind,
            condition: row.try_get("condition")?,
            n: row.try_get("n")?,
            values,
        });
    }
    let position = |list: &[String], name: &str| list.iter().position(|item| item == name).unwrap_or(usize::MAX);
    cells.sort_by_key(|cell| {
        (position(&task_order, &cell.task), cell.ordinal, position(&condition_order, &cell.condition))
    });
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(["participant", "task", "measure", "condition", "value", "trials", "label"]).expect("memory");
    // group by task, then measure, so each measure's rows are together
    let mut tasks: Vec<(String, TaskKind)> = Vec::new();
    for cell in &cells {
        if !tasks.iter().any(|(task, _)| *task == cell.task) {
            tasks.push((cell.task.clone(), cell.kind));
        }
    }
    for (task, kind) in &tasks {
        for measure in measures(*kind) {
            for cell in cells.iter().filter(|cell| cell.task == *task) {
                let Some((_, Some(value))) = cell.values.iter().find(|(name, _)| *name == measure) else { continue };
                if !value.is_finite() {
                    continue;
                }
                writer
                    .write_record([
                        &text_cell(&cell.id),
                        &text_cell(task),
                        measure,
                        &text_cell(&cell.condition),
                        &format!("{value}"),
                        &cell.n.to_string(),
                        &text_cell(&cell.label),
                    ])
                    .expect("memory");
            }
        }
    }
    Ok(String::from_utf8(writer.into_inner().expect("memory")).expect("UTF-8"))
}

/// Columns of the task trials CSV, in order.
pub const TRIAL_COLUMNS: [&str; 46] = [
    "participant",
    "label",
    "ordinal",
    "slot",
    "trial",
    "task",
    "kind",
    "condition",
    "practice",
    "start_x",
    "start_y",
    "start_z",
    "target_x",
    "target_y",
    "target_z",
    "answer_cm",
    "final_x",
    "final_y",
    "final_z",
    "error_cm",
    "signed_error_cm",
    "error_x_cm",
    "error_y_cm",
    "error_z_cm",
    "completion_ms",
    "keys",
    "key_log",
    "frames",
    "frames_shown",
    "frame_ms_mean",
    "frame_ms_max",
    "shown_frame_ms_mean",
    "paced_ms",
    "frames_late",
    "latency_ms_mean",
    "latency_ms_p95",
    "smoothing",
    "adapter",
    "started_at",
    "shown_at",
    "answered_at",
    "seed",
    "condition_order",
    "pilot",
    "excluded",
    "pace_kept",
];

/// The task trials CSV (see the module doc).
pub async fn trials_csv(pool: &Pool, slug: &str) -> AppResult<String> {
    definition(pool, slug).await?;
    let rows = sqlx::query(
        "SELECT p.id AS participant, p.label, p.ordinal, p.slot, p.seed, p.condition_order, p.pilot, p.excluded,
                p.pace_ms AS participant_pace_ms,
                (SELECT SUM(u.frames) FROM task_trials u WHERE u.participant = p.id AND u.answered_at IS NOT NULL) AS participant_frames,
                (SELECT SUM(u.frames_late) FROM task_trials u WHERE u.participant = p.id AND u.answered_at IS NOT NULL) AS participant_frames_late,
                t.* FROM task_trials t
         JOIN task_participants p ON p.id = t.participant
         WHERE p.study = $1 AND t.answered_at IS NOT NULL ORDER BY p.ordinal, t.trial",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(TRIAL_COLUMNS).expect("memory");
    for row in &rows {
        let mut record: Vec<String> = Vec::with_capacity(TRIAL_COLUMNS.len());
        for column in TRIAL_COLUMNS {
            let text = match column {
                "keys" => {
                    let log: Option<String> = row.try_get("key_log")?;
                    log.and_then(|log| serde_json::from_str::<serde_json::Value>(&log).ok())
                        .and_then(|v| v.as_array().map(Vec::len))
                        .unwrap_or(0)
                        .to_string()
                }
                "seed" => (row.try_get::<i64, _>("seed")? as u64).to_string(),
                "pilot" | "excluded" => (row.try_get::<i64, _>(column)? == 1).to_string(),
                "pace_kept" => pace_kept(
                    row.try_get("participant_pace_ms")?,
                    row.try_get::<Option<i64>, _>("participant_frames")?.unwrap_or(0),
                    row.try_get::<Option<i64>, _>("participant_frames_late")?.unwrap_or(0),
                )
                .map(|kept| kept.to_string())
                .unwrap_or_default(),
                "practice" | "smoothing" | "ordinal" | "slot" | "trial" | "frames" | "frames_shown" | "frames_late" => {
                    row.try_get::<Option<i64>, _>(column)?.map(|v| v.to_string()).unwrap_or_default()
                }
                "participant" | "label" | "task" | "kind" | "condition" | "key_log" | "adapter" | "started_at"
                | "shown_at" | "answered_at" | "condition_order" => {
                    text_cell(&row.try_get::<Option<String>, _>(column)?.unwrap_or_default())
                }
                _ => row.try_get::<Option<f64>, _>(column)?.map(|v| format!("{v}")).unwrap_or_default(),
            };
            record.push(text);
        }
        writer.write_record(&record).expect("memory");
    }
    Ok(String::from_utf8(writer.into_inner().expect("memory")).expect("UTF-8"))
}

async fn task_csv_download(State(state): State<AppState>, Path(slug): Path<String>, _: Admin) -> AppResult<Response> {
    let csv = task_csv(&state.storage().admin, &slug).await?;
    Ok(crate::pages::download("text/csv; charset=utf-8", format!("{slug}-task.csv"), csv))
}

async fn trials_csv_download(State(state): State<AppState>, Path(slug): Path<String>, _: Admin) -> AppResult<Response> {
    let csv = trials_csv(&state.storage().admin, &slug).await?;
    Ok(crate::pages::download("text/csv; charset=utf-8", format!("{slug}-task-trials.csv"), csv))
}

/// Progress, renderer and analysis of a task study.
#[derive(serde::Serialize)]
pub struct LabReport {
    pub slug: String,
    pub title: String,
    pub served: bool,
    pub adapter: Option<String>,
    pub adapter_kind: Option<String>,
    pub interactive: Option<bool>,
    pub rate: Option<String>,
    /// Each condition's frame time (start-up and now) while the study is served.
    pub frame_times: Vec<super::ConditionRate>,
    /// Whether the conditions' frame times differ by more than 20 % now.
    pub unequal: Option<bool>,
    /// `none` or `equal`.
    pub pace: String,
    /// The frame time every frame is paced to now (pace = "equal"), ms.
    pub pace_ms: Option<f64>,
    pub min_response_ms: Option<u64>,
    /// How far targets may lie from the real cube and stay in view, cm: [−x, +x, −z (away), +z (towards the camera)].
    pub reach_cm: Option<[f64; 4]>,
    pub smoothing: bool,
    /// Whether the study accepts new participants (pilots of a preview link always).
    pub open: bool,
    /// Progress counted as the survey's: real participants only, pilots and excluded beside.
    pub counts: LabCounts,
    pub participants: Vec<ParticipantProgress>,
    pub rendering: Vec<RenderingRow>,
    /// Absent while there is nothing to analyse.
    pub analysis: Option<TaskAnalysis>,
    pub analysis_error: Option<String>,
}

/// Progress of a task study, counted as the survey's: `started`, `finished` and the completion
/// rate count real participants only (neither pilots nor excluded); pilots and excluded
/// participants are counted beside them.
#[derive(Debug, Default, serde::Serialize)]
pub struct LabCounts {
    pub started: i64,
    pub finished: i64,
    pub completion_rate: Option<f64>,
    /// Real participants whose slot was given to another after a long pause.
    pub abandoned: i64,
    /// Participants from preview links (not in `started`).
    pub pilots: i64,
    /// Excluded participants who are not pilots (not in `started`).
    pub excluded: i64,
    /// Real participants who did not keep their pace (see [`ParticipantProgress::pace_kept`]).
    pub pace_not_kept: i64,
}

/// Whether a participant kept their pace: None when not paced or without frames.
pub fn pace_kept(pace_ms: Option<f64>, frames: i64, frames_late: i64) -> Option<bool> {
    (pace_ms.is_some() && frames > 0).then_some(frames_late as f64 <= super::session::LATE_SHARE * frames as f64)
}

/// Frame times and latencies of answered trials per condition.
#[derive(serde::Serialize)]
pub struct RenderingRow {
    pub condition: String,
    pub trials: i64,
    pub frames: i64,
    pub frame_ms_mean: Option<f64>,
    pub frame_ms_max: Option<f64>,
    /// Frames the page reported shown.
    pub frames_shown: i64,
    /// Request → sent per frame, pacing included (the frame time participants saw), mean.
    pub shown_frame_ms_mean: Option<f64>,
    pub latency_ms_mean: Option<f64>,
    pub latency_ms_p95_max: Option<f64>,
    pub smoothing_trials: i64,
}

pub async fn report(state: &AppState, slug: &str) -> AppResult<LabReport> {
    let pool = &state.storage().admin;
    let definition = definition(pool, slug).await?;
    let served = state.lab().and_then(|lab| {
        let study = lab.studies.get(slug).cloned()?;
        Some((lab, study))
    });
    let participants = sqlx::query(
        "SELECT p.id, p.label, p.ordinal, p.slot, p.condition_order, p.answered, p.trials, p.completed_at, p.abandoned_at,
                p.pilot, p.excluded, p.exclusion_reason, p.pace_ms,
                (SELECT SUM(t.frames) FROM task_trials t WHERE t.participant = p.id AND t.answered_at IS NOT NULL) AS frames,
                (SELECT SUM(t.frames_late) FROM task_trials t WHERE t.participant = p.id AND t.answered_at IS NOT NULL) AS frames_late
         FROM task_participants p WHERE p.study = $1 ORDER BY p.ordinal",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?
    .iter()
    .map(|row| {
        let pace_ms: Option<f64> = row.try_get("pace_ms")?;
        let frames = row.try_get::<Option<i64>, _>("frames")?.unwrap_or(0);
        let frames_late = row.try_get::<Option<i64>, _>("frames_late")?.unwrap_or(0);
        Ok(ParticipantProgress {
                participant: row.try_get("id")?,
                label: row.try_get("label")?,
                ordinal: row.try_get("ordinal")?,
                slot: row.try_get::<Option<i64>, _>("slot")?.unwrap_or(0),
                condition_order: row.try_get("condition_order")?,
                answered: row.try_get("answered")?,
                trials: row.try_get("trials")?,
                completed: row.try_get::<Option<String>, _>("completed_at")?.is_some(),
                abandoned: row.try_get::<Option<String>, _>("abandoned_at")?.is_some(),
                pilot: row.try_get::<i64, _>("pilot")? == 1,
                excluded: row.try_get::<i64, _>("excluded")? == 1,
                exclusion_reason: row.try_get("exclusion_reason")?,
                pace_ms,
                frames,
                frames_late,
                pace_kept: pace_kept(pace_ms, frames, frames_late),
            })
    })
    .collect::<Result<Vec<_>, sqlx::Error>>()?;
    let counts = counts(&participants);
    let open = state.storage().is_open(slug).await?;
    let rendering = sqlx::query(
        "SELECT t.condition, COUNT(*) AS n, SUM(t.frames) AS frames, SUM(t.frame_ms_mean * t.frames) / NULLIF(SUM(t.frames), 0) AS frame_ms_mean,
                MAX(t.frame_ms_max) AS frame_ms_max, SUM(t.frames_shown) AS frames_shown,
                SUM(t.shown_frame_ms_mean * t.frames) / NULLIF(SUM(CASE WHEN t.shown_frame_ms_mean IS NULL THEN 0 ELSE t.frames END), 0) AS shown_frame_ms_mean, AVG(t.latency_ms_mean) AS latency_ms_mean, MAX(t.latency_ms_p95) AS latency_ms_p95_max,
                SUM(t.smoothing) AS smoothing_trials
         FROM task_trials t JOIN task_participants p ON p.id = t.participant
         WHERE p.study = $1 AND t.answered_at IS NOT NULL GROUP BY t.condition ORDER BY t.condition",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?
    .iter()
    .map(|row| {
        Ok(RenderingRow {
            condition: row.try_get("condition")?,
            trials: row.try_get("n")?,
            frames: row.try_get::<Option<i64>, _>("frames")?.unwrap_or(0),
            frame_ms_mean: row.try_get("frame_ms_mean")?,
            frame_ms_max: row.try_get("frame_ms_max")?,
            frames_shown: row.try_get::<Option<i64>, _>("frames_shown")?.unwrap_or(0),
            shown_frame_ms_mean: row.try_get("shown_frame_ms_mean")?,
            latency_ms_mean: row.try_get("latency_ms_mean")?,
            latency_ms_p95_max: row.try_get("latency_ms_p95_max")?,
            smoothing_trials: row.try_get::<Option<i64>, _>("smoothing_trials")?.unwrap_or(0),
        })
    })
    .collect::<Result<Vec<_>, sqlx::Error>>()?;
    let csv = task_csv(pool, slug).await?;
    let (analysis, analysis_error) = if csv.lines().count() <= 1 {
        (None, None)
    } else {
        match analyze_task_csv(&csv, &format!("{slug}-task.csv")) {
            Ok(analysis) => (Some(analysis), None),
            Err(error) => (None, Some(error.to_string())),
        }
    };
    Ok(LabReport {
        slug: slug.to_string(),
        title: definition["title"].as_str().unwrap_or(slug).to_string(),
        served: served.is_some(),
        adapter: served.as_ref().map(|(lab, _)| lab.adapter.adapter.clone()),
        adapter_kind: served.as_ref().map(|(lab, _)| lab.adapter.kind.clone()),
        interactive: served.as_ref().map(|(_, study)| study.interactive()),
        rate: served.as_ref().map(|(lab, study)| study.rate_line(&lab.adapter)),
        frame_times: served.as_ref().map(|(_, study)| study.condition_rates()).unwrap_or_default(),
        unequal: served.as_ref().map(|(_, study)| study.unequal()),
        pace: definition["render"]["pace"].as_str().unwrap_or("none").to_string(),
        pace_ms: served.as_ref().and_then(|(_, study)| study.pace_ms()),
        min_response_ms: definition["min_response_ms"].as_u64(),
        reach_cm: served.as_ref().map(|(_, study)| study.layout.reach.map(|r| (r * 1000.0).round() / 10.0)),
        // every live frame of a task study goes through `render_display` (live.rs), smoothed
        smoothing: served.is_some(),
        open,
        counts,
        participants,
        rendering,
        analysis,
        analysis_error,
    })
}

/// The survey's counts for a task study's participants (see [`LabCounts`]).
pub fn counts(participants: &[ParticipantProgress]) -> LabCounts {
    let mut counts = LabCounts::default();
    for participant in participants {
        if participant.pilot {
            counts.pilots += 1;
            continue;
        }
        if participant.excluded {
            counts.excluded += 1;
            continue;
        }
        counts.started += 1;
        counts.finished += participant.completed as i64;
        counts.abandoned += participant.abandoned as i64;
        counts.pace_not_kept += (participant.pace_kept == Some(false)) as i64;
    }
    counts.completion_rate = (counts.started > 0).then(|| counts.finished as f64 / counts.started as f64);
    counts
}

async fn analysis_json(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: Admin,
) -> AppResult<Json<LabReport>> {
    Ok(Json(report(&state, &slug).await?))
}

#[derive(Template)]
#[template(path = "admin_lab.html")]
struct AdminLabPage {
    report: LabReport,
    measures: Vec<MeasureView>,
}

/// One measure's tests, formatted for the page.
struct MeasureView {
    label: String,
    participants: usize,
    conditions: Vec<(String, usize, String, String)>,
    friedman: Option<String>,
    posthoc: Vec<(String, String, String)>,
    warnings: Vec<String>,
}

fn fmt(value: f64) -> String {
    if value.abs() >= 100.0 { format!("{value:.1}") } else { format!("{value:.3}") }
}

fn measure_views(analysis: &TaskAnalysis) -> Vec<MeasureView> {
    analysis
        .measures
        .iter()
        .map(|measure| MeasureView {
            label: measure.group.label(),
            participants: measure.participants,
            conditions: measure
                .conditions
                .iter()
                .map(|c| (c.condition.clone(), c.n, fmt(c.mean), fmt(c.median)))
                .collect(),
            friedman: measure.friedman.as_ref().map(|f| {
                format!(
                    "χ²({}) = {}, p = {}, Kendall's W = {}, n = {}",
                    f.df,
                    fmt(f.statistic),
                    f.p.display(),
                    fmt(f.kendall_w),
                    f.participants
                )
            }),
            posthoc: measure
                .post_hoc
                .iter()
                .map(|pair| {
                    let (v, p) = match &pair.test {
                        Some(test) => (
                            format!("V = {}", test.v),
                            match (&test.p, &pair.not_estimable) {
                                (Some(p), _) => p.display(),
                                (None, Some(_)) => "not estimable (see the warning)".into(),
                                (None, None) => "–".into(),
                            },
                        ),
                        None => ("–".into(), "–".into()),
                    };
                    (
                        format!("{} – {}", pair.condition_a, pair.condition_b),
                        format!("{v}, n = {}", pair.n),
                        format!(
                            "p = {p}, Holm p = {}",
                            pair.p_holm.as_ref().map(|p| p.display()).unwrap_or_else(|| "–".into())
                        ),
                    )
                })
                .collect(),
            warnings: measure.warnings.clone(),
        })
        .collect()
}

async fn admin_lab_page(State(state): State<AppState>, Path(slug): Path<String>, headers: HeaderMap) -> Response {
    if let Err(error) = crate::auth::authorize_admin(&state, &headers).await {
        return crate::pages::message_page(
            error.status(),
            "Admin token needed",
            "Open the admin link that mrstudy serve printed; it carries the admin token.",
        );
    }
    match report(&state, &slug).await {
        Ok(report) => {
            let measures = report.analysis.as_ref().map(measure_views).unwrap_or_default();
            crate::pages::render(&AdminLabPage { report, measures })
        }
        Err(AppError::NotFound(message)) => {
            crate::pages::message_page(StatusCode::NOT_FOUND, "No such task study", &message)
        }
        Err(error) => error.into_response(),
    }
}

/// Lab studies for the admin overview: (slug, title, rate line, interactive).
pub fn overview(state: &AppState) -> Vec<(String, String, String, bool)> {
    let Some(lab) = state.lab() else { return Vec::new() };
    lab.order
        .iter()
        .filter_map(|slug| lab.studies.get(slug))
        .map(|study| {
            (
                study.study.slug.clone(),
                study.study.title.clone(),
                study.rate_line(&lab.adapter),
                study.interactive() && (!study.unequal() || study.pace_ms().is_some()),
            )
        })
        .collect()
}
