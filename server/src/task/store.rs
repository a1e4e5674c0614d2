//! Storage of task studies (tables `task_participants` and `task_trials`, migration
//! `20261122000002_task_trials.sql`): the writes that go through the server's one writer with
//! group commit ([`crate::storage::Storage::task_write`]), and the reads of sessions, the admin
//! page and the export.
//!
//! A participant is stored with its seed, its condition order and every planned trial in one
//! transaction. A trial's result is stored only if the trial exists, is the participant's next
//! one and has no result yet; otherwise the write is refused with a sentence saying why and
//! nothing changes.

use std::sync::Arc;

use sqlx::{Row, SqliteConnection};

use super::plan::{self, Layout, PlannedTaskTrial, TASK_SCHEDULE_VERSION};
use super::study::TaskStudy;
use crate::error::AppError;
use crate::storage::{NOW, Storage};

/// A participant to create.
pub struct NewTaskParticipant {
    pub study: Arc<TaskStudy>,
    pub layout: Layout,
    pub id: String,
    pub label: String,
    pub token_sha256: Vec<u8>,
    /// Used when the study has no seed.
    pub random_seed: u64,
}

/// The result of one trial, as measured by the session.
#[derive(Debug, Clone)]
pub struct TrialResult {
    pub participant: String,
    pub trial: u32,
    pub answer_cm: Option<f64>,
    pub final_position: Option<[f64; 3]>,
    pub error_cm: f64,
    pub signed_error_cm: Option<f64>,
    /// Signed per-axis error (x, y, z) in cm.
    pub error_axes_cm: [f64; 3],
    pub completion_ms: f64,
    /// JSON array.
    pub key_log: String,
    pub frames: u32,
    pub frame_ms_mean: Option<f64>,
    pub frame_ms_max: Option<f64>,
    pub latency_ms_mean: Option<f64>,
    pub latency_ms_p95: Option<f64>,
    pub smoothing: bool,
    pub adapter: String,
    /// When the trial's first frame was sent (UTC, ISO 8601 with ms).
    pub started_at: String,
}

pub enum TaskWrite {
    Participant(NewTaskParticipant),
    Result(TrialResult),
}

#[derive(Debug)]
pub enum TaskWritten {
    Participant { ordinal: u64, trials: Vec<PlannedTaskTrial> },
    Result { answered: u32, completed: bool },
}

/// Runs one write inside the writer's transaction. `Ok(Err(_))`: refused, nothing written.
pub(crate) async fn execute(connection: &mut SqliteConnection, write: &TaskWrite) -> Result<Result<TaskWritten, AppError>, sqlx::Error> {
    match write {
        TaskWrite::Participant(participant) => insert_participant(connection, participant).await.map(Ok),
        TaskWrite::Result(result) => store_result(connection, result).await,
    }
}

async fn insert_participant(connection: &mut SqliteConnection, participant: &NewTaskParticipant) -> Result<TaskWritten, sqlx::Error> {
    let study = &participant.study;
    let ordinal: i64 = sqlx::query_scalar("SELECT COALESCE(MAX(ordinal) + 1, 0) FROM task_participants WHERE study = ?")
        .bind(&study.slug)
        .fetch_one(&mut *connection)
        .await?;
    let seed = match study.seed {
        Some(study_seed) => crate::schedule::derived_seed(study_seed, ordinal as u64),
        None => participant.random_seed,
    };
    let trials = plan::plan(study, &participant.layout, seed, ordinal as u64);
    let order: Vec<&str> = plan::condition_order(study, ordinal as u64).into_iter().map(|index| study.conditions[index].name()).collect();
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "INSERT INTO task_participants (id, study, ordinal, label, token_sha256, seed, schedule_version, file_sha256,
             condition_order, trials, created_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, {NOW})"
    )))
    .bind(&participant.id)
    .bind(&study.slug)
    .bind(ordinal)
    .bind(&participant.label)
    .bind(&participant.token_sha256)
    .bind(seed as i64)
    .bind(TASK_SCHEDULE_VERSION)
    .bind(&study.file_sha256)
    .bind(serde_json::to_string(&order).expect("JSON"))
    .bind(trials.len() as i64)
    .execute(&mut *connection)
    .await?;
    for trial in &trials {
        sqlx::query(
            "INSERT INTO task_trials (participant, trial, task, kind, condition, practice, start_x, start_y, start_z,
                 target_x, target_y, target_z) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(&participant.id)
        .bind(trial.trial as i64)
        .bind(&trial.task)
        .bind(trial.kind.as_str())
        .bind(trial.condition.name())
        .bind(trial.practice as i64)
        .bind(trial.start[0])
        .bind(trial.start[1])
        .bind(trial.start[2])
        .bind(trial.target[0])
        .bind(trial.target[1])
        .bind(trial.target[2])
        .execute(&mut *connection)
        .await?;
    }
    Ok(TaskWritten::Participant { ordinal: ordinal as u64, trials })
}

async fn store_result(connection: &mut SqliteConnection, result: &TrialResult) -> Result<Result<TaskWritten, AppError>, sqlx::Error> {
    let row = sqlx::query("SELECT trials, answered FROM task_participants WHERE id = ?")
        .bind(&result.participant)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(row) = row else {
        return Ok(Err(AppError::NotFound(format!("There is no task participant \"{}\".", result.participant))));
    };
    let (trials, answered): (i64, i64) = (row.try_get("trials")?, row.try_get("answered")?);
    let trial = result.trial as i64;
    if trial < 1 || trial > trials {
        return Ok(Err(AppError::NotFound(format!("There is no trial {trial}; the schedule has {trials}."))));
    }
    if trial <= answered {
        return Ok(Err(AppError::Conflict(format!("Trial {trial} is already answered."))));
    }
    if trial != answered + 1 {
        return Ok(Err(AppError::Conflict(format!("Trial {trial} is not the next trial; trial {} is.", answered + 1))));
    }
    let updated = sqlx::query(sqlx::AssertSqlSafe(format!(
        "UPDATE task_trials SET answer_cm = ?, final_x = ?, final_y = ?, final_z = ?, error_cm = ?, signed_error_cm = ?,
             error_x_cm = ?, error_y_cm = ?, error_z_cm = ?, completion_ms = ?, key_log = ?, frames = ?,
             frame_ms_mean = ?, frame_ms_max = ?, latency_ms_mean = ?, latency_ms_p95 = ?, smoothing = ?, adapter = ?,
             started_at = ?, answered_at = {NOW}
         WHERE participant = ? AND trial = ? AND answered_at IS NULL"
    )))
    .bind(result.answer_cm)
    .bind(result.final_position.map(|p| p[0]))
    .bind(result.final_position.map(|p| p[1]))
    .bind(result.final_position.map(|p| p[2]))
    .bind(result.error_cm)
    .bind(result.signed_error_cm)
    .bind(result.error_axes_cm[0])
    .bind(result.error_axes_cm[1])
    .bind(result.error_axes_cm[2])
    .bind(result.completion_ms)
    .bind(&result.key_log)
    .bind(result.frames as i64)
    .bind(result.frame_ms_mean)
    .bind(result.frame_ms_max)
    .bind(result.latency_ms_mean)
    .bind(result.latency_ms_p95)
    .bind(result.smoothing as i64)
    .bind(&result.adapter)
    .bind(&result.started_at)
    .bind(&result.participant)
    .bind(trial)
    .execute(&mut *connection)
    .await?;
    if updated.rows_affected() != 1 {
        return Ok(Err(AppError::Conflict(format!("Trial {trial} is already answered."))));
    }
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "UPDATE task_participants SET answered = answered + 1,
             completed_at = CASE WHEN answered + 1 = trials THEN {NOW} ELSE completed_at END WHERE id = ?"
    )))
    .bind(&result.participant)
    .execute(&mut *connection)
    .await?;
    Ok(Ok(TaskWritten::Result { answered: trial as u32, completed: trial == trials }))
}

/// Records or refreshes a task study at start-up (a known study keeps its open/closed state).
pub async fn upsert_study(storage: &Storage, study: &TaskStudy) -> Result<(), sqlx::Error> {
    let definition = serde_json::to_string(study).expect("study serialises");
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "INSERT INTO studies (slug, title, kind, open, definition, file_sha256, first_loaded_at, loaded_at)
         VALUES (?, ?, 'task', ?, ?, ?, {NOW}, {NOW})
         ON CONFLICT (slug) DO UPDATE SET title = excluded.title, kind = excluded.kind,
             definition = excluded.definition, file_sha256 = excluded.file_sha256, loaded_at = excluded.loaded_at"
    )))
    .bind(&study.slug)
    .bind(&study.title)
    .bind(study.open as i64)
    .bind(definition)
    .bind(&study.file_sha256)
    .execute(storage.write_pool())
    .await?;
    Ok(())
}

/// A stored task participant.
#[derive(Debug, Clone)]
pub struct TaskParticipantRow {
    pub id: String,
    pub study: String,
    pub ordinal: i64,
    pub label: String,
    pub token_sha256: Vec<u8>,
    pub trials: i64,
    pub answered: i64,
    pub completed: bool,
}

pub async fn participant(storage: &Storage, id: &str) -> Result<Option<TaskParticipantRow>, sqlx::Error> {
    let row = sqlx::query("SELECT id, study, ordinal, label, token_sha256, trials, answered, completed_at FROM task_participants WHERE id = ?")
        .bind(id)
        .fetch_optional(&storage.read)
        .await?;
    row.map(|row| {
        Ok(TaskParticipantRow {
            id: row.try_get("id")?,
            study: row.try_get("study")?,
            ordinal: row.try_get("ordinal")?,
            label: row.try_get("label")?,
            token_sha256: row.try_get("token_sha256")?,
            trials: row.try_get("trials")?,
            answered: row.try_get("answered")?,
            completed: row.try_get::<Option<String>, _>("completed_at")?.is_some(),
        })
    })
    .transpose()
}

/// The planned trials of a participant, in order.
pub async fn planned_trials(storage: &Storage, participant: &str) -> Result<Vec<PlannedTaskTrial>, sqlx::Error> {
    let rows = sqlx::query(
        "SELECT trial, task, kind, condition, practice, start_x, start_y, start_z, target_x, target_y, target_z
         FROM task_trials WHERE participant = ? ORDER BY trial",
    )
    .bind(participant)
    .fetch_all(&storage.read)
    .await?;
    rows.iter()
        .map(|row| {
            let kind: String = row.try_get("kind")?;
            let condition: String = row.try_get("condition")?;
            let decode = |what: &str| sqlx::Error::Decode(format!("task_trials.{what} holds an unknown value").into());
            Ok(PlannedTaskTrial {
                trial: row.try_get::<i64, _>("trial")? as u32,
                task: row.try_get("task")?,
                kind: serde_json::from_value(serde_json::Value::String(kind)).map_err(|_| decode("kind"))?,
                condition: mrstudy_renderer::gpu::GiLevel::parse(&condition).ok_or_else(|| decode("condition"))?,
                practice: row.try_get::<i64, _>("practice")? == 1,
                start: [row.try_get("start_x")?, row.try_get("start_y")?, row.try_get("start_z")?],
                target: [row.try_get("target_x")?, row.try_get("target_y")?, row.try_get("target_z")?],
            })
        })
        .collect()
}
