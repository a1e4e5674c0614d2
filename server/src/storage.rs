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

use crate::prepared::PreparedStudy;
use crate::schedule;
use crate::trial::{ResponseOutcome, ResponseRefused, Side};

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
    Migrate { path: String, source: sqlx::migrate::MigrateError },
}

/// A failure of the database itself. What a write refuses (a trial not yet served, an unknown
/// participant, …) is not an error of storage: each write returns it as its own outcome.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StorageError {
    #[error("database error: {0}")]
    Database(#[from] sqlx::Error),
    #[error("the database writer has stopped")]
    WriterStopped,
    /// The batch this write was part of was rolled back.
    #[error("the database write failed")]
    WriteFailed,
    #[error("the WAL could not be truncated after {tries} tries (the database stayed busy)")]
    WalBusy { tries: usize },
}

/// A write's outcome: done (`Ok(Ok(_))`), refused with nothing written (`Ok(Err(_))`), or the
/// database failed.
pub type Written<T, R> = Result<Result<T, R>, StorageError>;

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

/// Why an admin write was refused; nothing was written.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum AdminRefused {
    /// No participant (or screen-out) has this id.
    UnknownParticipant {
        id: String,
    },
    UnknownStudy {
        slug: String,
    },
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

type Reply<T> = oneshot::Sender<Result<T, StorageError>>;

enum Job {
    Response(NewResponse, Reply<Result<ResponseOutcome, ResponseRefused>>),
    Shown {
        participant: String,
        trial: i64,
    },
    Participant(Box<NewParticipant>, Reply<JoinOutcome>),
    /// Records (or updates) a screen-out; `None` withdraws the row with this id.
    ScreenOut(String, Option<Box<ScreenOut>>, Reply<()>),
    SetOpen(String, bool, Reply<Result<(), AdminRefused>>),
    /// A write of a lab task study (participant with schedule, or a trial's result).
    Task(
        Box<crate::task::store::TaskWrite>,
        Reply<Result<crate::task::store::TaskWritten, crate::task::store::TaskRefused>>,
    ),
    /// A researcher's change to participants' data (exclude, include, delete, preview link).
    Admin(Box<AdminWrite>, Reply<Result<AdminWritten, AdminRefused>>),
}

impl Job {
    /// Answers the job with [`StorageError::WriteFailed`]: its batch was rolled back.
    fn fail(self) {
        let error = || StorageError::WriteFailed;
        match self {
            Job::Response(_, reply) => drop(reply.send(Err(error()))),
            Job::Participant(_, reply) => drop(reply.send(Err(error()))),
            Job::ScreenOut(_, _, reply) => drop(reply.send(Err(error()))),
            Job::SetOpen(_, _, reply) => drop(reply.send(Err(error()))),
            Job::Task(_, reply) => drop(reply.send(Err(error()))),
            Job::Shown { .. } => {}
            Job::Admin(_, reply) => drop(reply.send(Err(error()))),
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
            // A deleted participant's bytes are overwritten, not left in free pages (issue 12;
            // `Storage::delete` then truncates the WAL, which still holds the old pages).
            .pragma("secure_delete", "ON")
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
        MIGRATOR.run(&write).await.map_err(|source| OpenError::Migrate { path: path_text.clone(), source })?;
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

    pub async fn store_response(&self, response: NewResponse) -> Written<ResponseOutcome, ResponseRefused> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::Response(response, reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    pub async fn create_participant(&self, participant: NewParticipant) -> Result<JoinOutcome, StorageError> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::Participant(Box::new(participant), reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// Records a screen-out (`Some`), or withdraws the one with `id` (`None`); durable on return.
    pub async fn screen_out(&self, id: &str, screen_out: Option<ScreenOut>) -> Result<(), StorageError> {
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

    pub async fn set_open(&self, slug: &str, open: bool) -> Written<(), AdminRefused> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::SetOpen(slug.to_string(), open, reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// Records that a trial was served, if it had not been. It waits for a place in the
    /// writer's queue, not for the commit: the queue is first in, first out, so the record is
    /// committed no later than any response to the trial, which can only be sent after the
    /// trial was served (a response to a trial never served is refused).
    pub async fn mark_shown(&self, participant: &str, trial: i64) -> Result<(), StorageError> {
        self.send(Job::Shown { participant: participant.to_string(), trial }).await
    }

    /// Runs a task study write in the next group commit and answers after it is durable.
    pub async fn task_write(
        &self,
        write: crate::task::store::TaskWrite,
    ) -> Written<crate::task::store::TaskWritten, crate::task::store::TaskRefused> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::Task(Box::new(write), reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// The write connection, for start-up writes before participants arrive.
    pub(crate) fn write_pool(&self) -> &SqlitePool {
        &self.write
    }

    async fn send(&self, job: Job) -> Result<(), StorageError> {
        self.jobs.send(job).await.map_err(|_| writer_gone())
    }

    /// Whether the study is open, as stored.
    pub async fn is_open(&self, slug: &str) -> Result<bool, sqlx::Error> {
        let open: Option<i64> =
            sqlx::query_scalar("SELECT open FROM studies WHERE slug = ?").bind(slug).fetch_optional(&self.read).await?;
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
        let row =
            sqlx::query("SELECT trial, left_stimulus, right_stimulus FROM trials WHERE participant = ? AND trial = ?")
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

fn writer_gone() -> StorageError {
    StorageError::WriterStopped
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
                    job.fail();
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

type Answer = Box<dyn FnOnce() + Send>;

/// Runs the jobs in one transaction; returns the replies to send after the commit. On a
/// database error the transaction is rolled back and the jobs stay in `batch`.
async fn run_batch(pool: &SqlitePool, batch: &mut Vec<Job>) -> Result<Vec<Answer>, sqlx::Error> {
    let mut transaction = pool.begin().await?;
    let mut outcomes: Vec<Option<Outcome>> = Vec::with_capacity(batch.len());
    for job in batch.iter() {
        let outcome = match job {
            Job::Response(response, _) => Some(Outcome::Response(store_response(&mut transaction, response).await?)),
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
            Job::Participant(participant, _) => {
                Some(Outcome::Joined(insert_participant(&mut transaction, participant).await?))
            }
            Job::ScreenOut(id, screen_out, _) => {
                write_screen_out(&mut transaction, id, screen_out.as_deref()).await?;
                Some(Outcome::Done)
            }
            Job::Task(write, _) => Some(Outcome::Task(crate::task::store::execute(&mut transaction, write).await?)),
            Job::Admin(write, _) => Some(Outcome::Admin(execute_admin(&mut transaction, write).await?)),
            Job::SetOpen(slug, open, _) => {
                let result = sqlx::query("UPDATE studies SET open = ? WHERE slug = ?")
                    .bind(*open as i64)
                    .bind(slug)
                    .execute(&mut *transaction)
                    .await?;
                Some(Outcome::Opened(if result.rows_affected() == 1 {
                    Ok(())
                } else {
                    Err(AdminRefused::UnknownStudy { slug: slug.clone() })
                }))
            }
        };
        outcomes.push(outcome);
    }
    transaction.commit().await?;
    let mut answers: Vec<Answer> = Vec::with_capacity(batch.len());
    for (job, outcome) in batch.drain(..).zip(outcomes) {
        // Each job's outcome is the variant its job produced (see the match above).
        match (job, outcome) {
            (Job::Response(_, reply), Some(Outcome::Response(outcome))) => {
                answers.push(Box::new(move || drop(reply.send(Ok(outcome)))))
            }
            (Job::Participant(_, reply), Some(Outcome::Joined(joined))) => {
                answers.push(Box::new(move || drop(reply.send(Ok(joined)))))
            }
            (Job::ScreenOut(_, _, reply), Some(Outcome::Done)) => {
                answers.push(Box::new(move || drop(reply.send(Ok(())))))
            }
            (Job::SetOpen(_, _, reply), Some(Outcome::Opened(opened))) => {
                answers.push(Box::new(move || drop(reply.send(Ok(opened)))))
            }
            (Job::Task(_, reply), Some(Outcome::Task(written))) => {
                answers.push(Box::new(move || drop(reply.send(Ok(written)))))
            }
            (Job::Admin(_, reply), Some(Outcome::Admin(written))) => {
                answers.push(Box::new(move || drop(reply.send(Ok(written)))))
            }
            _ => {}
        }
    }
    Ok(answers)
}

enum Outcome {
    Response(Result<ResponseOutcome, ResponseRefused>),
    Joined(JoinOutcome),
    Task(Result<crate::task::store::TaskWritten, crate::task::store::TaskRefused>),
    Done,
    Opened(Result<(), AdminRefused>),
    Admin(Result<AdminWritten, AdminRefused>),
}

async fn store_response(
    connection: &mut SqliteConnection,
    response: &NewResponse,
) -> Result<Result<ResponseOutcome, ResponseRefused>, sqlx::Error> {
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
            return Ok(Err(ResponseRefused::NeverServed { trial: response.trial, next: answered + 1 }));
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
            Err(ResponseRefused::AlreadyAnswered { trial: response.trial, chosen: existing })
        });
    }
    let progress = sqlx::query("SELECT answered, trials FROM participants WHERE id = ?")
        .bind(&response.participant)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(progress) = progress else {
        return Ok(Err(ResponseRefused::UnknownParticipant));
    };
    let answered: i64 = progress.try_get("answered")?;
    let trials: i64 = progress.try_get("trials")?;
    if response.trial < 1 || response.trial > trials {
        return Ok(Err(ResponseRefused::OutOfRange { trial: response.trial, trials }));
    }
    Ok(Err(ResponseRefused::NotYet { trial: response.trial, next: answered + 1 }))
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
    let ordinal: i64 = sqlx::query_scalar("SELECT COALESCE(MAX(ordinal) + 1, 0) FROM participants WHERE study = ?")
        .bind(&study.slug)
        .fetch_one(&mut *connection)
        .await?;
    let seed = match study.design.seed {
        Some(study_seed) => schedule::derived_seed(study_seed, ordinal as u64),
        None => participant.random_seed,
    };
    let trials = participant.study.schedule(seed);
    let completion_code = study.completion.code.clone().unwrap_or_else(|| participant.random_completion_code.clone());
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

// ------------------------------------------------------------------------------------------
// The researcher's changes to participants' data (issue 12, "Trustworthy responses"): exclude
// and include (kept, with reason and time), delete (every datum of the participant, leaving an
// audit line without personal data), preview links. Each runs in the writer's group commit.

/// A researcher's change to participants' data.
#[derive(Debug)]
#[non_exhaustive]
pub enum AdminWrite {
    /// Exclude the participant with this reason, or (`None`) include them again.
    SetExcluded { participant: String, reason: Option<String> },
    /// Delete a participant and all their data, or a screen-out row, by id.
    Delete { id: String },
    /// Store a new preview link's token hash.
    Preview { study: String, token_sha256: Vec<u8> },
}

/// What an admin write did.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum AdminWritten {
    /// The participant is now excluded or included.
    Excluded {
        study: String,
        ordinal: i64,
        excluded: bool,
        reason: Option<String>,
        excluded_at: Option<String>,
    },
    /// A participant (with `trials` schedule rows and `responses` responses) or a screen-out
    /// row was deleted.
    Deleted(Deletion),
    PreviewStored,
}

/// A deletion, as the audit line records it (no personal data).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Deletion {
    pub study: String,
    /// `participant` or `screen-out`.
    pub kind: &'static str,
    /// The participant's ordinal within the study (absent for a screen-out).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ordinal: Option<i64>,
    pub trials: i64,
    pub responses: i64,
}

impl Storage {
    /// Runs an admin write in the next group commit and answers after it is durable.
    pub async fn admin_write(&self, write: AdminWrite) -> Written<AdminWritten, AdminRefused> {
        let (reply, answer) = oneshot::channel();
        self.send(Job::Admin(Box::new(write), reply)).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// Deletes a participant (or a screen-out row), then rewrites the database and truncates the
    /// WAL, so that none of their bytes remain in the database's files. `secure_delete` zeroes
    /// the freed cells in the new page versions; `VACUUM` rewrites every page, which also drops
    /// copies of keys that b-tree interior pages may keep after their row is gone (the
    /// `WITHOUT ROWID` tables `trials` and `responses` keep whole rows there, the external-id
    /// index the external id); the truncating checkpoint copies the new pages over the old ones
    /// in the main file and empties the WAL, which still held the old versions. The writer's
    /// connection runs the `VACUUM`, so participants' writes wait for it (deletions are rare).
    pub async fn delete(&self, id: &str) -> Written<Deletion, AdminRefused> {
        let deletion = match self.admin_write(AdminWrite::Delete { id: id.to_string() }).await? {
            Ok(AdminWritten::Deleted(deletion)) => deletion,
            Ok(_) => unreachable!("a deletion's outcome is a deletion"),
            Err(refused) => return Ok(Err(refused)),
        };
        sqlx::query("VACUUM").execute(&self.write).await?;
        self.truncate_wal().await?;
        Ok(Ok(deletion))
    }

    /// `PRAGMA wal_checkpoint(TRUNCATE)`, retried while readers or the writer keep it busy.
    pub async fn truncate_wal(&self) -> Result<(), StorageError> {
        for _ in 0..WAL_TRUNCATE_TRIES {
            let row = sqlx::query("PRAGMA wal_checkpoint(TRUNCATE)").fetch_one(&self.read).await?;
            let busy: i64 = row.try_get(0)?;
            if busy == 0 {
                return Ok(());
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        Err(StorageError::WalBusy { tries: WAL_TRUNCATE_TRIES })
    }
}

/// How often [`Storage::truncate_wal`] tries before giving up (50 ms apart).
const WAL_TRUNCATE_TRIES: usize = 200;

async fn audit(
    connection: &mut SqliteConnection,
    action: &str,
    study: &str,
    detail: serde_json::Value,
) -> Result<(), sqlx::Error> {
    sqlx::query(sqlx::AssertSqlSafe(format!("INSERT INTO audit (at, action, study, detail) VALUES ({NOW}, ?, ?, ?)")))
        .bind(action)
        .bind(study)
        .bind(detail.to_string())
        .execute(&mut *connection)
        .await?;
    Ok(())
}

async fn execute_admin(
    connection: &mut SqliteConnection,
    write: &AdminWrite,
) -> Result<Result<AdminWritten, AdminRefused>, sqlx::Error> {
    match write {
        AdminWrite::SetExcluded { participant, reason } => {
            let row = sqlx::query("SELECT study, ordinal FROM participants WHERE id = ?")
                .bind(participant)
                .fetch_optional(&mut *connection)
                .await?;
            let Some(row) = row else {
                return Ok(Err(AdminRefused::UnknownParticipant { id: participant.clone() }));
            };
            let study: String = row.try_get("study")?;
            let ordinal: i64 = row.try_get("ordinal")?;
            let excluded_at: Option<String> = match reason {
                Some(reason) => {
                    sqlx::query_scalar(sqlx::AssertSqlSafe(format!(
                        "UPDATE participants SET excluded = 1, exclusion_reason = ?, excluded_at = {NOW}
                     WHERE id = ? RETURNING excluded_at"
                    )))
                    .bind(reason)
                    .bind(participant)
                    .fetch_one(&mut *connection)
                    .await?
                }
                None => {
                    sqlx::query(
                        "UPDATE participants SET excluded = 0, exclusion_reason = NULL, excluded_at = NULL WHERE id = ?",
                    )
                    .bind(participant)
                    .execute(&mut *connection)
                    .await?;
                    None
                }
            };
            let action = if reason.is_some() { "exclude" } else { "include" };
            audit(connection, action, &study, serde_json::json!({ "ordinal": ordinal })).await?;
            Ok(Ok(AdminWritten::Excluded {
                study,
                ordinal,
                excluded: reason.is_some(),
                reason: reason.clone(),
                excluded_at,
            }))
        }
        AdminWrite::Delete { id } => {
            let row = sqlx::query("SELECT study, ordinal FROM participants WHERE id = ?")
                .bind(id)
                .fetch_optional(&mut *connection)
                .await?;
            if let Some(row) = row {
                let study: String = row.try_get("study")?;
                let ordinal: i64 = row.try_get("ordinal")?;
                let responses = sqlx::query("DELETE FROM responses WHERE participant = ?")
                    .bind(id)
                    .execute(&mut *connection)
                    .await?
                    .rows_affected() as i64;
                let trials = sqlx::query("DELETE FROM trials WHERE participant = ?")
                    .bind(id)
                    .execute(&mut *connection)
                    .await?
                    .rows_affected() as i64;
                sqlx::query("DELETE FROM participants WHERE id = ?").bind(id).execute(&mut *connection).await?;
                let deletion =
                    Deletion { study: study.clone(), kind: "participant", ordinal: Some(ordinal), trials, responses };
                audit(connection, "delete", &study, serde_json::to_value(&deletion).expect("serialises")).await?;
                return Ok(Ok(AdminWritten::Deleted(deletion)));
            }
            let study: Option<String> = sqlx::query_scalar("DELETE FROM screen_outs WHERE id = ? RETURNING study")
                .bind(id)
                .fetch_optional(&mut *connection)
                .await?;
            let Some(study) = study else {
                return Ok(Err(AdminRefused::UnknownParticipant { id: id.clone() }));
            };
            let deletion =
                Deletion { study: study.clone(), kind: "screen-out", ordinal: None, trials: 0, responses: 0 };
            audit(connection, "delete", &study, serde_json::to_value(&deletion).expect("serialises")).await?;
            Ok(Ok(AdminWritten::Deleted(deletion)))
        }
        AdminWrite::Preview { study, token_sha256 } => {
            let known: Option<String> = sqlx::query_scalar("SELECT slug FROM studies WHERE slug = ?")
                .bind(study)
                .fetch_optional(&mut *connection)
                .await?;
            if known.is_none() {
                return Ok(Err(AdminRefused::UnknownStudy { slug: study.clone() }));
            }
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "INSERT INTO previews (token_sha256, study, created_at) VALUES (?, ?, {NOW})"
            )))
            .bind(token_sha256)
            .bind(study)
            .execute(&mut *connection)
            .await?;
            Ok(Ok(AdminWritten::PreviewStored))
        }
    }
}
