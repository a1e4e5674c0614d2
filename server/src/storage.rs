//! sqlite storage through sqlx: connections, migrations, the single writer with group commit,
//! and the read queries.
//!
//! Durability: the database runs in WAL mode with `synchronous = FULL`, so a commit returns only
//! after the WAL has been fsynced. All writes go through one writer task that owns the only
//! write connection: it takes every job waiting in its queue (up to [`MAX_BATCH`]), runs them in
//! one transaction, commits, and only then answers each job. A response's `201` is therefore
//! sent after its row is durably on disk, while many concurrent participants share one fsync
//! (group commit). If the commit fails, every job in the batch gets the error and nothing of the
//! batch is kept. Reads use a separate pool of connections; WAL lets them run beside the writer.

use std::path::Path;
use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{Row, SqliteConnection, SqlitePool};
use tokio::sync::{mpsc, oneshot};

use crate::error::AppError;
use crate::prepared::PreparedStudy;
use crate::schedule;

/// Most jobs committed together in one transaction.
pub const MAX_BATCH: usize = 512;

/// SQL expression for "now" as stored: UTC, ISO 8601, milliseconds.
pub const NOW: &str = "strftime('%Y-%m-%dT%H:%M:%fZ', 'now')";

static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("../migrations");

/// Failure to open the database.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OpenError {
    #[error("cannot open the database {path}: {source}")]
    Connect { path: String, source: sqlx::Error },
    #[error("cannot migrate the database {path}: {source}")]
    Migrate {
        path: String,
        source: sqlx::migrate::MigrateError,
    },
}

/// The database: a read pool and the writer's queue.
#[derive(Clone)]
pub struct Storage {
    pub read: SqlitePool,
    write: SqlitePool,
    jobs: mpsc::Sender<Job>,
}

/// A new response as received.
#[derive(Debug, Clone)]
pub struct NewResponse {
    pub participant: String,
    pub trial: i64,
    pub chosen: Side,
    pub rt_ms: f64,
    pub client: String,
    /// The study's `min_response_ms`: a faster response is stored flagged `too_fast`.
    pub min_response_ms: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Left,
    Right,
}

impl Side {
    pub fn as_str(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }
}

/// What storing a response did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResponseOutcome {
    /// Stored now (`201`).
    Created,
    /// The same answer was already stored (`200`).
    Repeated,
}

/// A participant to create, with the parts that do not depend on the seed.
#[derive(Debug)]
pub struct NewParticipant {
    pub study: Arc<PreparedStudy>,
    pub id: String,
    pub token_sha256: Vec<u8>,
    /// A random seed, used when the study has no study seed.
    pub random_seed: u64,
    pub demographics: String,
    pub client: String,
    pub url_params: String,
    /// Used when the study has no fixed completion code.
    pub random_completion_code: String,
    /// Joined through an admin preview link.
    pub pilot: bool,
    /// The external id when the study keeps one run per external id: a participant already
    /// stored with it is resumed (given this token) instead of created.
    pub external_key: Option<String>,
    /// A screen-out of this visitor to withdraw (they now meet the requirements and joined).
    pub withdraw_screen_out: Option<String>,
}

/// What joining did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum JoinOutcome {
    /// A new participant with the given id.
    Created,
    /// The study keeps one run per external id and this one had joined before: that
    /// participant (`id`) now answers to the new token.
    Resumed { id: String, trials: i64 },
}

/// A visitor who does not meet the study's screen requirements.
#[derive(Debug, Clone)]
pub struct ScreenOut {
    /// Random id; an existing row with this id (the same visitor checking again) is updated.
    pub id: String,
    pub study: String,
    pub reason: String,
    pub client: String,
    pub url_params: String,
    pub pilot: bool,
}

enum Job {
    Response(NewResponse, oneshot::Sender<Result<ResponseOutcome, AppError>>),
    Shown { participant: String, trial: i64 },
    Participant(Box<NewParticipant>, oneshot::Sender<Result<JoinOutcome, AppError>>),
    /// Records (or updates) a screen-out; `None` withdraws the row with this id.
    ScreenOut(String, Option<Box<ScreenOut>>, oneshot::Sender<Result<(), AppError>>),
    SetOpen(String, bool, oneshot::Sender<Result<(), AppError>>),
    /// A write of a lab task study (participant with schedule, or a trial's result).
    Task(Box<crate::task::store::TaskWrite>, oneshot::Sender<Result<crate::task::store::TaskWritten, AppError>>),
}

impl Job {
    fn fail(self, message: &str) {
        let error = || AppError::Internal(message.to_string());
        match self {
            Job::Response(_, reply) => drop(reply.send(Err(error()))),
            Job::Participant(_, reply) => drop(reply.send(Err(error()))),
            Job::SetOpen(_, _, reply) | Job::ScreenOut(_, _, reply) => drop(reply.send(Err(error()))),
            Job::Task(_, reply) => drop(reply.send(Err(error()))),
            Job::Shown { .. } => {}
        }
    }
}

impl Storage {
    /// Opens (creating if needed) the database file, applies the migrations and starts the
    /// writer task. Must be called inside a tokio runtime.
    pub async fn open(path: &Path) -> Result<Storage, OpenError> {
        let path_text = path.display().to_string();
        let options = SqliteConnectOptions::from_str("sqlite:")
            .map_err(|source| OpenError::Connect { path: path_text.clone(), source })?
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .foreign_keys(true)
            .busy_timeout(Duration::from_secs(10))
            // No checkpoint inside a participant's commit (it would stall that batch for the
            // copy and its fsync); a background task checkpoints instead, see `checkpointer`.
            .pragma("wal_autocheckpoint", "0");
        let write = SqlitePoolOptions::new()
            .max_connections(1)
            .min_connections(1)
            .acquire_timeout(Duration::from_secs(60))
            .connect_with(options.clone())
            .await
            .map_err(|source| OpenError::Connect { path: path_text.clone(), source })?;
        MIGRATOR
            .run(&write)
            .await
            .map_err(|source| OpenError::Migrate { path: path_text.clone(), source })?;
        let read = SqlitePoolOptions::new()
            .max_connections(4)
            .acquire_timeout(Duration::from_secs(60))
            .connect_with(options)
            .await
            .map_err(|source| OpenError::Connect { path: path_text, source })?;
        let (sender, receiver) = mpsc::channel(4 * MAX_BATCH);
        tokio::spawn(writer(write.clone(), receiver));
        tokio::spawn(checkpointer(read.clone()));
        Ok(Storage { read, write, jobs: sender })
    }

    /// Records or refreshes a study at start-up; a new study starts open or closed as its file
    /// says, a known one keeps the state the admin gave it.
    pub async fn upsert_study(&self, study: &PreparedStudy) -> Result<(), sqlx::Error> {
        let definition = serde_json::to_string(&study.study).expect("study serialises");
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "INSERT INTO studies (slug, title, kind, open, definition, file_sha256, first_loaded_at, loaded_at)
             VALUES (?, ?, ?, ?, ?, ?, {NOW}, {NOW})
             ON CONFLICT (slug) DO UPDATE SET title = excluded.title, kind = excluded.kind,
                 definition = excluded.definition, file_sha256 = excluded.file_sha256,
                 loaded_at = excluded.loaded_at"
        )))
        .bind(&study.study.slug)
        .bind(&study.study.title)
        .bind(study.study.kind.as_str())
        .bind(study.study.open as i64)
        .bind(definition)
        .bind(&study.study.file_sha256)
        .execute(&self.write)
        .await?;
        Ok(())
    }

    pub async fn store_response(&self, response: NewResponse) -> Result<ResponseOutcome, AppError> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::Response(response, reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    pub async fn create_participant(&self, participant: NewParticipant) -> Result<JoinOutcome, AppError> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::Participant(Box::new(participant), reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// Records a screen-out (`Some`), or withdraws the one with `id` (`None`); durable on return.
    pub async fn screen_out(&self, id: &str, screen_out: Option<ScreenOut>) -> Result<(), AppError> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::ScreenOut(id.to_string(), screen_out.map(Box::new), reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// Whether `token_sha256` is a preview link of the study.
    pub async fn is_preview(&self, study: &str, token_sha256: &[u8]) -> Result<bool, sqlx::Error> {
        let found: Option<i64> = sqlx::query_scalar("SELECT 1 FROM previews WHERE study = ? AND token_sha256 = ?")
            .bind(study)
            .bind(token_sha256)
            .fetch_optional(&self.read)
            .await?;
        Ok(found.is_some())
    }

    pub async fn set_open(&self, slug: &str, open: bool) -> Result<(), AppError> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::SetOpen(slug.to_string(), open, reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// Records that a trial was served, if it had not been. It waits for a place in the
    /// writer's queue, not for the commit: the queue is first in, first out, so the record is
    /// committed no later than any response to the trial, which can only be sent after the
    /// trial was served (a response to a trial never served is refused).
    pub async fn mark_shown(&self, participant: &str, trial: i64) -> Result<(), AppError> {
        self.send(Job::Shown { participant: participant.to_string(), trial }).await
    }

    /// Runs a task study write in the next group commit and answers after it is durable.
    pub async fn task_write(&self, write: crate::task::store::TaskWrite) -> Result<crate::task::store::TaskWritten, AppError> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::Task(Box::new(write), reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// The write connection, for start-up writes before participants arrive.
    pub(crate) fn write_pool(&self) -> &SqlitePool {
        &self.write
    }

    async fn send(&self, job: Job) -> Result<(), AppError> {
        self.jobs.send(job).await.map_err(|_| writer_gone())
    }

    /// Whether the study is open, as stored.
    pub async fn is_open(&self, slug: &str) -> Result<bool, sqlx::Error> {
        let open: Option<i64> = sqlx::query_scalar("SELECT open FROM studies WHERE slug = ?")
            .bind(slug)
            .fetch_optional(&self.read)
            .await?;
        Ok(open == Some(1))
    }

    pub async fn participant(&self, id: &str) -> Result<Option<ParticipantRow>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT id, study, token_sha256, trials, answered, completion_code, completed_at, url_params
             FROM participants WHERE id = ?",
        )
        .bind(id)
        .fetch_optional(&self.read)
        .await?;
        row.map(|row| {
            Ok(ParticipantRow {
                id: row.try_get("id")?,
                study: row.try_get("study")?,
                token_sha256: row.try_get("token_sha256")?,
                trials: row.try_get("trials")?,
                answered: row.try_get("answered")?,
                completion_code: row.try_get("completion_code")?,
                completed: row.try_get::<Option<String>, _>("completed_at")?.is_some(),
                url_params: row.try_get("url_params")?,
            })
        })
        .transpose()
    }

    /// The participant with its next unanswered trial and the one after it (for preloading), in
    /// one query.
    pub async fn participant_with_next(
        &self,
        id: &str,
    ) -> Result<Option<(ParticipantRow, Vec<TrialRow>)>, sqlx::Error> {
        let rows = sqlx::query(
            "SELECT p.id, p.study, p.token_sha256, p.trials, p.answered, p.completion_code, p.completed_at,
                    p.url_params, t.trial, t.left_stimulus, t.right_stimulus
             FROM participants p
             LEFT JOIN trials t ON t.participant = p.id AND t.trial IN (p.answered + 1, p.answered + 2)
             WHERE p.id = ? ORDER BY t.trial",
        )
        .bind(id)
        .fetch_all(&self.read)
        .await?;
        let Some(first) = rows.first() else { return Ok(None) };
        let participant = ParticipantRow {
            id: first.try_get("id")?,
            study: first.try_get("study")?,
            token_sha256: first.try_get("token_sha256")?,
            trials: first.try_get("trials")?,
            answered: first.try_get("answered")?,
            completion_code: first.try_get("completion_code")?,
            completed: first.try_get::<Option<String>, _>("completed_at")?.is_some(),
            url_params: first.try_get("url_params")?,
        };
        let mut trials = Vec::new();
        for row in &rows {
            if let Some(trial) = row.try_get::<Option<i64>, _>("trial")? {
                trials.push(TrialRow {
                    trial,
                    left_stimulus: row.try_get("left_stimulus")?,
                    right_stimulus: row.try_get("right_stimulus")?,
                });
            }
        }
        Ok(Some((participant, trials)))
    }

    pub async fn trial(&self, participant: &str, trial: i64) -> Result<Option<TrialRow>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT trial, left_stimulus, right_stimulus FROM trials WHERE participant = ? AND trial = ?",
        )
        .bind(participant)
        .bind(trial)
        .fetch_optional(&self.read)
        .await?;
        row.map(|row| {
            Ok(TrialRow {
                trial: row.try_get("trial")?,
                left_stimulus: row.try_get("left_stimulus")?,
                right_stimulus: row.try_get("right_stimulus")?,
            })
        })
        .transpose()
    }
}

fn writer_gone() -> AppError {
    AppError::Internal("the database writer has stopped".into())
}

#[derive(Debug, Clone)]
pub struct ParticipantRow {
    pub id: String,
    pub study: String,
    pub token_sha256: Vec<u8>,
    pub trials: i64,
    pub answered: i64,
    pub completion_code: String,
    pub completed: bool,
    pub url_params: String,
}

#[derive(Debug, Clone)]
pub struct TrialRow {
    pub trial: i64,
    pub left_stimulus: String,
    pub right_stimulus: String,
}

async fn writer(pool: SqlitePool, mut receiver: mpsc::Receiver<Job>) {
    let mut batch: Vec<Job> = Vec::with_capacity(MAX_BATCH);
    while let Some(first) = receiver.recv().await {
        batch.push(first);
        while batch.len() < MAX_BATCH {
            match receiver.try_recv() {
                Ok(job) => batch.push(job),
                Err(_) => break,
            }
        }
        match run_batch(&pool, &mut batch).await {
            Ok(replies) => {
                for reply in replies {
                    reply();
                }
            }
            Err(error) => {
                eprintln!("error: a database write of {} jobs failed and was rolled back: {error}", batch.len());
                for job in batch.drain(..) {
                    job.fail("the database write failed");
                }
            }
        }
        batch.clear();
    }
}

/// Copies the WAL back into the database file once a second (a passive checkpoint: it never
/// blocks the writer or readers), so the WAL stays small without any commit paying for it.
async fn checkpointer(pool: SqlitePool) {
    let mut interval = tokio::time::interval(CHECKPOINT_INTERVAL);
    loop {
        interval.tick().await;
        if let Err(error) = sqlx::query("PRAGMA wal_checkpoint(PASSIVE)").execute(&pool).await {
            eprintln!("warning: WAL checkpoint failed (will retry): {error}");
        }
    }
}

/// How often the WAL is checkpointed.
pub const CHECKPOINT_INTERVAL: Duration = Duration::from_secs(1);

type Reply = Box<dyn FnOnce() + Send>;

/// Runs the jobs in one transaction; returns the replies to send after the commit. On a
/// database error the transaction is rolled back and the jobs stay in `batch`.
async fn run_batch(pool: &SqlitePool, batch: &mut Vec<Job>) -> Result<Vec<Reply>, sqlx::Error> {
    let mut transaction = pool.begin().await?;
    let mut outcomes: Vec<Option<Result<Outcome, AppError>>> = Vec::with_capacity(batch.len());
    for job in batch.iter() {
        let outcome = match job {
            Job::Response(response, _) => Some(store_response(&mut transaction, response).await?.map(Outcome::Response)),
            Job::Shown { participant, trial } => {
                sqlx::query(sqlx::AssertSqlSafe(format!(
                    "UPDATE trials SET shown_at = {NOW} WHERE participant = ? AND trial = ? AND shown_at IS NULL"
                )))
                .bind(participant)
                .bind(trial)
                .execute(&mut *transaction)
                .await?;
                None
            }
            Job::Participant(participant, _) => Some(Ok(Outcome::Joined(insert_participant(&mut transaction, participant).await?))),
            Job::ScreenOut(id, screen_out, _) => {
                write_screen_out(&mut transaction, id, screen_out.as_deref()).await?;
                Some(Ok(Outcome::Done))
            }
            Job::Task(write, _) => Some(crate::task::store::execute(&mut transaction, write).await?.map(Outcome::Task)),
            Job::SetOpen(slug, open, _) => {
                let result = sqlx::query("UPDATE studies SET open = ? WHERE slug = ?")
                    .bind(*open as i64)
                    .bind(slug)
                    .execute(&mut *transaction)
                    .await?;
                Some(if result.rows_affected() == 1 {
                    Ok(Outcome::Done)
                } else {
                    Err(AppError::NotFound(format!("There is no study \"{slug}\".")))
                })
            }
        };
        outcomes.push(outcome);
    }
    transaction.commit().await?;
    let mut replies: Vec<Reply> = Vec::with_capacity(batch.len());
    for (job, outcome) in batch.drain(..).zip(outcomes) {
        match (job, outcome) {
            (Job::Response(_, reply), Some(outcome)) => replies.push(Box::new(move || {
                let _ = reply.send(outcome.map(|outcome| match outcome {
                    Outcome::Response(outcome) => outcome,
                    _ => ResponseOutcome::Created,
                }));
            })),
            (Job::Participant(_, reply), Some(outcome)) => replies.push(Box::new(move || {
                let _ = reply.send(outcome.and_then(|outcome| match outcome {
                    Outcome::Joined(joined) => Ok(joined),
                    _ => Err(AppError::Internal("a join had no join outcome".into())),
                }));
            })),
            (Job::SetOpen(_, _, reply), Some(outcome)) | (Job::ScreenOut(_, _, reply), Some(outcome)) => {
                replies.push(Box::new(move || {
                    let _ = reply.send(outcome.map(|_| ()));
                }))
            }
            (Job::Task(_, reply), Some(outcome)) => replies.push(Box::new(move || {
                let _ = reply.send(outcome.and_then(|outcome| match outcome {
                    Outcome::Task(written) => Ok(written),
                    _ => Err(AppError::Internal("a task write had no task outcome".into())),
                }));
            })),
            _ => {}
        }
    }
    Ok(replies)
}

enum Outcome {
    Response(ResponseOutcome),
    Joined(JoinOutcome),
    Task(crate::task::store::TaskWritten),
    Done,
}

async fn store_response(
    connection: &mut SqliteConnection,
    response: &NewResponse,
) -> Result<Result<ResponseOutcome, AppError>, sqlx::Error> {
    // Only a trial that was served can be answered; the server's own time since serving it
    // (first serving, so a reload never shortens it) is stored beside the client's.
    let served = sqlx::query(
        "SELECT shown_at IS NOT NULL AS served,
                (julianday('now') - julianday(shown_at)) * 86400000.0 AS served_ms
         FROM trials WHERE participant = ? AND trial = ?",
    )
    .bind(&response.participant)
    .bind(response.trial)
    .fetch_optional(&mut *connection)
    .await?;
    let mut served_ms: Option<f64> = None;
    if let Some(served) = &served {
        if !served.try_get::<bool, _>("served")? {
            let answered: i64 = sqlx::query_scalar("SELECT answered FROM participants WHERE id = ?")
                .bind(&response.participant)
                .fetch_one(&mut *connection)
                .await?;
            return Ok(Err(AppError::Conflict(format!(
                "Trial {} was never served to this participant, so it cannot be answered (the next trial is {}; get it from …/next first).",
                response.trial,
                answered + 1
            ))));
        }
        served_ms = served.try_get::<Option<f64>, _>("served_ms")?.map(|ms| ms.max(0.0));
    }
    let floor = f64::from(response.min_response_ms);
    let too_fast = response.rt_ms < floor || served_ms.is_some_and(|ms| ms < floor);
    // The usual case in two statements: advance the participant's progress if this is the next
    // trial, then insert the response. Responses are answered in order, so `answered` is the
    // number of stored responses and trial `answered + 1` has none yet.
    let advanced = sqlx::query(sqlx::AssertSqlSafe(format!(
        "UPDATE participants SET answered = answered + 1,
             completed_at = CASE WHEN answered + 1 = trials THEN {NOW} ELSE completed_at END
         WHERE id = ? AND answered = ? AND ? <= trials"
    )))
    .bind(&response.participant)
    .bind(response.trial - 1)
    .bind(response.trial)
    .execute(&mut *connection)
    .await?;
    if advanced.rows_affected() == 1 {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "INSERT INTO responses (participant, trial, chosen, rt_ms, client, answered_at, too_fast, served_ms)
             VALUES (?, ?, ?, ?, ?, {NOW}, ?, ?)"
        )))
        .bind(&response.participant)
        .bind(response.trial)
        .bind(response.chosen.as_str())
        .bind(response.rt_ms)
        .bind(&response.client)
        .bind(too_fast as i64)
        .bind(served_ms)
        .execute(&mut *connection)
        .await?;
        return Ok(Ok(ResponseOutcome::Created));
    }
    // Not the next trial: a repeat, a changed answer, or out of order.
    let existing: Option<String> =
        sqlx::query_scalar("SELECT chosen FROM responses WHERE participant = ? AND trial = ?")
            .bind(&response.participant)
            .bind(response.trial)
            .fetch_optional(&mut *connection)
            .await?;
    if let Some(existing) = existing {
        return Ok(if existing == response.chosen.as_str() {
            Ok(ResponseOutcome::Repeated)
        } else {
            Err(AppError::Conflict(format!(
                "Trial {} was already answered with \"{existing}\"; an answer cannot be changed.",
                response.trial
            )))
        });
    }
    let progress = sqlx::query("SELECT answered, trials FROM participants WHERE id = ?")
        .bind(&response.participant)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(progress) = progress else {
        return Ok(Err(AppError::NotFound("There is no such participant.".into())));
    };
    let answered: i64 = progress.try_get("answered")?;
    let trials: i64 = progress.try_get("trials")?;
    if response.trial < 1 || response.trial > trials {
        return Ok(Err(AppError::Unprocessable(format!(
            "`trial` must be between 1 and {trials}, found {}.",
            response.trial
        ))));
    }
    Ok(Err(AppError::Conflict(format!(
        "Trial {} cannot be answered yet: the next trial is {}.",
        response.trial,
        answered + 1
    ))))
}

async fn write_screen_out(
    connection: &mut SqliteConnection,
    id: &str,
    screen_out: Option<&ScreenOut>,
) -> Result<(), sqlx::Error> {
    match screen_out {
        None => {
            sqlx::query("DELETE FROM screen_outs WHERE id = ?").bind(id).execute(&mut *connection).await?;
        }
        Some(screen_out) => {
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "INSERT INTO screen_outs (id, study, reason, client, url_params, pilot, created_at)
                 VALUES (?, ?, ?, ?, ?, ?, {NOW})
                 ON CONFLICT (id) DO UPDATE SET reason = excluded.reason, client = excluded.client"
            )))
            .bind(id)
            .bind(&screen_out.study)
            .bind(&screen_out.reason)
            .bind(&screen_out.client)
            .bind(&screen_out.url_params)
            .bind(screen_out.pilot as i64)
            .execute(&mut *connection)
            .await?;
        }
    }
    Ok(())
}

async fn insert_participant(
    connection: &mut SqliteConnection,
    participant: &NewParticipant,
) -> Result<JoinOutcome, sqlx::Error> {
    let study = &participant.study.study;
    if let Some(withdraw) = &participant.withdraw_screen_out {
        sqlx::query("DELETE FROM screen_outs WHERE id = ? AND study = ?")
            .bind(withdraw)
            .bind(&study.slug)
            .execute(&mut *connection)
            .await?;
    }
    if let Some(external_key) = &participant.external_key {
        let existing = sqlx::query("SELECT id, trials FROM participants WHERE study = ? AND external_key = ?")
            .bind(&study.slug)
            .bind(external_key)
            .fetch_optional(&mut *connection)
            .await?;
        if let Some(existing) = existing {
            let id: String = existing.try_get("id")?;
            sqlx::query("UPDATE participants SET token_sha256 = ? WHERE id = ?")
                .bind(&participant.token_sha256)
                .bind(&id)
                .execute(&mut *connection)
                .await?;
            return Ok(JoinOutcome::Resumed { id, trials: existing.try_get("trials")? });
        }
    }
    let ordinal: i64 = sqlx::query_scalar(
        "SELECT COALESCE(MAX(ordinal) + 1, 0) FROM participants WHERE study = ?",
    )
    .bind(&study.slug)
    .fetch_one(&mut *connection)
    .await?;
    let seed = match study.design.seed {
        Some(study_seed) => schedule::derived_seed(study_seed, ordinal as u64),
        None => participant.random_seed,
    };
    let trials = participant.study.schedule(seed);
    let completion_code = study
        .completion
        .code
        .clone()
        .unwrap_or_else(|| participant.random_completion_code.clone());
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "INSERT INTO participants (id, study, ordinal, token_sha256, seed, schedule_version, file_sha256,
             demographics, client, url_params, trials, completion_code, created_at, pilot, external_key)
         VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, {NOW}, ?, ?)"
    )))
    .bind(&participant.id)
    .bind(&study.slug)
    .bind(ordinal)
    .bind(&participant.token_sha256)
    .bind(seed as i64)
    .bind(schedule::SCHEDULE_VERSION)
    .bind(&study.file_sha256)
    .bind(&participant.demographics)
    .bind(&participant.client)
    .bind(&participant.url_params)
    .bind(trials.len() as i64)
    .bind(completion_code)
    .bind(participant.pilot as i64)
    .bind(&participant.external_key)
    .execute(&mut *connection)
    .await?;
    for (index, trial) in trials.iter().enumerate() {
        sqlx::query(
            "INSERT INTO trials (participant, trial, left_condition, right_condition, left_scene, right_scene,
                 left_stimulus, right_stimulus, catch_expected) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(&participant.id)
        .bind(index as i64 + 1)
        .bind(&trial.left_condition)
        .bind(&trial.right_condition)
        .bind(&trial.left_scene)
        .bind(&trial.right_scene)
        .bind(&trial.left_stimulus)
        .bind(&trial.right_stimulus)
        .bind(trial.catch_expected.map(Side::as_str))
        .execute(&mut *connection)
        .await?;
    }
    Ok(JoinOutcome::Created)
}
