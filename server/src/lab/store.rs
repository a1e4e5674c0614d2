//! Storage of task studies (tables `task_participants`, `task_trials` and `task_frame_times`,
//! migrations `20261122000002_task_trials.sql` and `20261123000002_lab_hygiene.sql`): the writes that go through the server's one writer with
//! group commit ([`Storage::write`]), and the reads of sessions, the admin
//! page and the export.
//!
//! A participant is stored with its seed, its condition order and every planned trial in one
//! transaction. A trial's result is stored only if the trial exists, is the participant's next
//! one and has no result yet; otherwise the write is refused with a sentence saying why and
//! nothing changes.
//!
//! Counterbalancing slots: a participant's condition order is the row `slot` of the design.
//! A new participant takes the lowest slot of a participant who has not finished and has been
//! inactive (no start, resume or answer) for longer than the study's `abandon_after_minutes`;
//! that participant is marked abandoned and can no longer resume or answer. Otherwise the new
//! participant takes the next unused slot. `ordinal` stays unique, in order of joining.

use sqlx::Row;

use crate::storage::Connection;

use super::plan::{self, Layout, TASK_SCHEDULE_VERSION};
use crate::error::AppError;
use crate::participant::model::{NewTaskParticipant, TaskParticipantRow};
use crate::storage::{NOW, OptionalF64, Storage, StudyRecord, WriteJob};
use crate::study::task::TaskStudy;
use crate::trial::{PlannedTaskTrial, TrialResult};

pub use crate::storage::iso;

/// The time before which a participant's last activity makes them abandoned.
fn abandon_cutoff(minutes: f64) -> String {
    let ago = std::time::Duration::try_from_secs_f64(minutes * 60.0).unwrap_or(std::time::Duration::ZERO);
    iso(std::time::SystemTime::now().checked_sub(ago).unwrap_or(std::time::UNIX_EPOCH))
}

pub enum TaskWrite {
    /// A new participant, their trials planned in the scene `layout` measured at start-up.
    Participant {
        participant: NewTaskParticipant,
        layout: Layout,
    },
    Result(TrialResult),
    /// A participant resumes: refused when their slot was given away, else their last activity
    /// is now.
    Resume {
        participant: String,
    },
}

#[derive(Debug)]
pub enum TaskWritten {
    /// `took_over`: the abandoned participant whose slot this one took.
    Participant {
        ordinal: u64,
        slot: u64,
        took_over: Option<String>,
        trials: Vec<PlannedTaskTrial>,
    },
    Result {
        answered: u32,
        completed: bool,
    },
    Resumed,
}

/// Why a task write was refused; nothing was written.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum TaskRefused {
    UnknownParticipant {
        id: String,
    },
    /// The participant's slot in the counterbalancing was given to another participant.
    Abandoned,
    /// The trial is not in the participant's schedule of `trials` trials.
    NoTrial {
        trial: i64,
        trials: i64,
    },
    AlreadyAnswered {
        trial: i64,
    },
    /// The trial is not the participant's next trial, `next`.
    NotNext {
        trial: i64,
        next: i64,
    },
}

impl WriteJob for TaskWrite {
    type Outcome = Result<TaskWritten, TaskRefused>;

    fn run(
        &self,
        connection: &mut Connection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send {
        execute(connection, self)
    }
}

/// Runs one write inside the writer's transaction. `Ok(Err(_))`: refused, nothing written.
async fn execute(
    connection: &mut Connection,
    write: &TaskWrite,
) -> Result<Result<TaskWritten, TaskRefused>, sqlx::Error> {
    match write {
        TaskWrite::Participant { participant, layout } => {
            insert_participant(connection, participant, layout).await.map(Ok)
        }
        TaskWrite::Result(result) => store_result(connection, result).await,
        TaskWrite::Resume { participant } => resume(connection, participant).await,
    }
}

async fn resume(
    connection: &mut Connection,
    participant: &str,
) -> Result<Result<TaskWritten, TaskRefused>, sqlx::Error> {
    let abandoned: Option<Option<String>> =
        sqlx::query_scalar("SELECT abandoned_at FROM task_participants WHERE id = $1")
            .bind(participant)
            .fetch_optional(&mut *connection)
            .await?;
    match abandoned {
        None => Ok(Err(TaskRefused::UnknownParticipant { id: participant.to_string() })),
        Some(Some(_)) => Ok(Err(TaskRefused::Abandoned)),
        Some(None) => {
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "UPDATE task_participants SET last_active_at = {NOW} WHERE id = $1"
            )))
            .bind(participant)
            .execute(&mut *connection)
            .await?;
            Ok(Ok(TaskWritten::Resumed))
        }
    }
}

async fn insert_participant(
    connection: &mut Connection,
    participant: &NewTaskParticipant,
    layout: &Layout,
) -> Result<TaskWritten, sqlx::Error> {
    let study = &participant.study;
    let ordinal: i64 =
        sqlx::query_scalar("SELECT COALESCE(MAX(ordinal) + 1, 0) FROM task_participants WHERE study = $1")
            .bind(&study.slug)
            .fetch_one(&mut *connection)
            .await?;
    let seed = match study.seed {
        Some(study_seed) => crate::schedule::derived_seed(study_seed, ordinal as u64),
        None => participant.random_seed,
    };
    // the slot of the longest-abandoned participant, else the next unused one
    let abandoned = sqlx::query(
        "SELECT id, slot FROM task_participants WHERE study = $1 AND completed_at IS NULL AND abandoned_at IS NULL
             AND last_active_at < $2 ORDER BY slot, ordinal LIMIT 1",
    )
    .bind(&study.slug)
    .bind(abandon_cutoff(study.abandon_after_minutes))
    .fetch_optional(&mut *connection)
    .await?;
    let (slot, took_over) = match abandoned {
        Some(row) => (row.try_get::<i64, _>("slot")?, Some(row.try_get::<String, _>("id")?)),
        None => {
            let next: i64 =
                sqlx::query_scalar("SELECT COALESCE(MAX(slot) + 1, 0) FROM task_participants WHERE study = $1")
                    .bind(&study.slug)
                    .fetch_one(&mut *connection)
                    .await?;
            (next, None)
        }
    };
    let trials = plan::plan(study, layout, seed, slot as u64);
    let order: Vec<String> =
        plan::condition_order(study, slot as u64).into_iter().map(|index| study.conditions[index].name()).collect();
    if let Some(previous) = &took_over {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "UPDATE task_participants SET abandoned_at = {NOW}, slot_taken_by = $1 WHERE id = $2"
        )))
        .bind(&participant.id)
        .bind(previous)
        .execute(&mut *connection)
        .await?;
    }
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "INSERT INTO task_participants (id, study, ordinal, slot, label, token_sha256, seed, schedule_version, file_sha256,
             condition_order, trials, pilot, pace_ms, created_at, last_active_at)
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, {NOW}, {NOW})"
    )))
    .bind(&participant.id)
    .bind(&study.slug)
    .bind(ordinal)
    .bind(slot)
    .bind(&participant.label)
    .bind(&participant.token_sha256)
    .bind(seed as i64)
    .bind(TASK_SCHEDULE_VERSION)
    .bind(&study.file_sha256)
    .bind(serde_json::to_string(&order).expect("JSON"))
    .bind(trials.len() as i64)
    .bind(participant.pilot as i64)
    .bind(OptionalF64(participant.pace_ms))
    .execute(&mut *connection)
    .await?;
    for trial in &trials {
        sqlx::query(
            "INSERT INTO task_trials (participant, trial, task, kind, condition, practice, start_x, start_y, start_z,
                 target_x, target_y, target_z) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12)",
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
    Ok(TaskWritten::Participant { ordinal: ordinal as u64, slot: slot as u64, took_over, trials })
}

async fn store_result(
    connection: &mut Connection,
    result: &TrialResult,
) -> Result<Result<TaskWritten, TaskRefused>, sqlx::Error> {
    let row = sqlx::query("SELECT trials, answered, abandoned_at FROM task_participants WHERE id = $1")
        .bind(&result.participant)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(row) = row else {
        return Ok(Err(TaskRefused::UnknownParticipant { id: result.participant.clone() }));
    };
    if row.try_get::<Option<String>, _>("abandoned_at")?.is_some() {
        return Ok(Err(TaskRefused::Abandoned));
    }
    let (trials, answered): (i64, i64) = (row.try_get("trials")?, row.try_get("answered")?);
    let trial = result.trial as i64;
    if trial < 1 || trial > trials {
        return Ok(Err(TaskRefused::NoTrial { trial, trials }));
    }
    if trial <= answered {
        return Ok(Err(TaskRefused::AlreadyAnswered { trial }));
    }
    if trial != answered + 1 {
        return Ok(Err(TaskRefused::NotNext { trial, next: answered + 1 }));
    }
    let updated = sqlx::query(sqlx::AssertSqlSafe(format!(
        "UPDATE task_trials SET answer_cm = $1, final_x = $2, final_y = $3, final_z = $4, error_cm = $5, signed_error_cm = $6,
             error_x_cm = $7, error_y_cm = $8, error_z_cm = $9, completion_ms = $10, key_log = $11, frames = $12,
             frame_ms_mean = $13, frame_ms_max = $14, latency_ms_mean = $15, latency_ms_p95 = $16, smoothing = $17, adapter = $18,
             started_at = $19, frames_shown = $20, shown_frame_ms_mean = $21, paced_ms = $22, shown_at = $23, frames_late = $24,
             answered_at = {NOW}
         WHERE participant = $25 AND trial = $26 AND answered_at IS NULL"
    )))
    .bind(OptionalF64(result.answer_cm))
    .bind(OptionalF64(result.final_position.map(|p| p[0])))
    .bind(OptionalF64(result.final_position.map(|p| p[1])))
    .bind(OptionalF64(result.final_position.map(|p| p[2])))
    .bind(result.error_cm)
    .bind(OptionalF64(result.signed_error_cm))
    .bind(result.error_axes_cm[0])
    .bind(result.error_axes_cm[1])
    .bind(result.error_axes_cm[2])
    .bind(result.completion_ms)
    .bind(&result.key_log)
    .bind(result.frames as i64)
    .bind(OptionalF64(result.frame_ms_mean))
    .bind(OptionalF64(result.frame_ms_max))
    .bind(OptionalF64(result.latency_ms_mean))
    .bind(OptionalF64(result.latency_ms_p95))
    .bind(result.smoothing as i64)
    .bind(&result.adapter)
    .bind(&result.started_at)
    .bind(result.frames_shown as i64)
    .bind(OptionalF64(result.shown_frame_ms_mean))
    .bind(OptionalF64(result.paced_ms))
    .bind(&result.shown_at)
    .bind(result.frames_late as i64)
    .bind(&result.participant)
    .bind(trial)
    .execute(&mut *connection)
    .await?;
    if updated.rows_affected() != 1 {
        return Ok(Err(TaskRefused::AlreadyAnswered { trial }));
    }
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "UPDATE task_participants SET answered = answered + 1, last_active_at = {NOW},
             completed_at = CASE WHEN answered + 1 = trials THEN {NOW} ELSE completed_at END WHERE id = $1"
    )))
    .bind(&result.participant)
    .execute(&mut *connection)
    .await?;
    Ok(Ok(TaskWritten::Result { answered: trial as u32, completed: trial == trials }))
}

/// Records or refreshes a task study at start-up (a known study keeps its open/closed state).
pub async fn upsert_study(storage: &Storage, study: &TaskStudy) -> Result<(), sqlx::Error> {
    storage
        .upsert_study(&StudyRecord {
            slug: &study.slug,
            title: &study.title,
            kind: "task",
            open: study.open,
            definition: serde_json::to_string(study).expect("study serialises"),
            file_sha256: &study.file_sha256,
        })
        .await
}

/// Records the frame time per condition measured at start-up (table `task_frame_times`).
pub async fn record_frame_times(
    storage: &Storage,
    study: &str,
    adapter: &str,
    size: [u32; 2],
    frames: usize,
    medians: &[(crate::study::task::Condition, f64)],
) -> Result<(), sqlx::Error> {
    let measured_at = iso(std::time::SystemTime::now());
    for (condition, median_ms) in medians {
        sqlx::query("INSERT INTO task_frame_times (study, measured_at, adapter, condition, width, height, frames, median_ms) VALUES ($1, $2, $3, $4, $5, $6, $7, $8) ON CONFLICT (study, measured_at, condition) DO UPDATE SET adapter = excluded.adapter, width = excluded.width, height = excluded.height, frames = excluded.frames, median_ms = excluded.median_ms")
            .bind(study)
            .bind(&measured_at)
            .bind(adapter)
            .bind(condition.name())
            .bind(size[0] as i64)
            .bind(size[1] as i64)
            .bind(frames as i64)
            .bind(median_ms)
            .execute(storage.write_pool())
            .await?;
    }
    Ok(())
}

pub async fn participant(storage: &Storage, id: &str) -> Result<Option<TaskParticipantRow>, sqlx::Error> {
    let row = sqlx::query("SELECT id, study, ordinal, slot, label, token_sha256, trials, answered, completed_at, abandoned_at, pilot, pace_ms FROM task_participants WHERE id = $1")
        .bind(id)
        .fetch_optional(&storage.read)
        .await?;
    row.map(|row| {
        Ok(TaskParticipantRow {
            id: row.try_get("id")?,
            study: row.try_get("study")?,
            ordinal: row.try_get("ordinal")?,
            slot: row.try_get::<Option<i64>, _>("slot")?.unwrap_or(0),
            label: row.try_get("label")?,
            token_sha256: row.try_get("token_sha256")?,
            trials: row.try_get("trials")?,
            answered: row.try_get("answered")?,
            completed: row.try_get::<Option<String>, _>("completed_at")?.is_some(),
            abandoned: row.try_get::<Option<String>, _>("abandoned_at")?.is_some(),
            pilot: row.try_get::<i64, _>("pilot")? == 1,
            pace_ms: row.try_get("pace_ms")?,
        })
    })
    .transpose()
}

/// The planned trials of a participant, in order.
pub async fn planned_trials(storage: &Storage, participant: &str) -> Result<Vec<PlannedTaskTrial>, sqlx::Error> {
    let rows = sqlx::query(
        "SELECT trial, task, kind, condition, practice, start_x, start_y, start_z, target_x, target_y, target_z
         FROM task_trials WHERE participant = $1 ORDER BY trial",
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
                condition: crate::study::task::Condition::parse(&condition).ok_or_else(|| decode("condition"))?,
                practice: row.try_get::<i64, _>("practice")? == 1,
                start: [row.try_get("start_x")?, row.try_get("start_y")?, row.try_get("start_z")?],
                target: [row.try_get("target_x")?, row.try_get("target_y")?, row.try_get("target_z")?],
            })
        })
        .collect()
}

/// A refused task write, as the experimenter reads it.
impl From<TaskRefused> for AppError {
    fn from(refused: TaskRefused) -> Self {
        match refused {
            TaskRefused::UnknownParticipant { id } => {
                AppError::NotFound(format!("There is no task participant \"{id}\"."))
            }
            TaskRefused::Abandoned => AppError::Conflict(
                "This participant's place in the counterbalancing was given to another participant after a long pause; ask the experimenter to start a new session.".into(),
            ),
            TaskRefused::NoTrial { trial, trials } => {
                AppError::NotFound(format!("There is no trial {trial}; the schedule has {trials}."))
            }
            TaskRefused::AlreadyAnswered { trial } => AppError::Conflict(format!("Trial {trial} is already answered.")),
            TaskRefused::NotNext { trial, next } => {
                AppError::Conflict(format!("Trial {trial} is not the next trial; trial {next} is."))
            }
        }
    }
}
