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
//! Admin reads (exports, the live analysis) have a pool of their own ([`Storage::admin`]), so
//! however many exports run, participants' reads never wait for a connection behind them.
//!
//! The WAL is bounded: a background task checkpoints passively once a second, and when the WAL
//! file has grown past [`WAL_TRUNCATE_BYTES`] (readers that overlap keep a passive checkpoint
//! from ever restarting it) the writer, after its batch, runs a truncating checkpoint, which
//! waits for the readers of the old WAL to finish, copies everything back and empties the file;
//! `journal_size_limit` caps what a restarted WAL keeps on disk. The database files are the owner's alone (mode 0600):
//! they hold demographics.

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{Row, SqliteConnection, SqlitePool};
use tokio::sync::{mpsc, oneshot};

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
    #[error("cannot make the database {path} readable by its owner only: {source}")]
    Permissions { path: String, source: std::io::Error },
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

/// A study as the `studies` table records it.
#[derive(Debug)]
pub struct StudyRecord<'a> {
    pub slug: &'a str,
    pub title: &'a str,
    /// `paired-comparison` or `task`.
    pub kind: &'a str,
    /// Whether a study new to the database starts open.
    pub open: bool,
    /// The study as JSON.
    pub definition: String,
    pub file_sha256: &'a str,
}

/// The database: a read pool, the admin's read pool and the writer's queue.
#[derive(Clone)]
pub struct Storage {
    /// Participants' reads.
    pub read: SqlitePool,
    /// The admin's reads (exports, analysis, lists): apart from `read`, so that exports cannot
    /// take the connections participants wait for.
    pub admin: SqlitePool,
    write: SqlitePool,
    jobs: mpsc::Sender<Box<dyn Queued>>,
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

/// A write that runs in the writer's group commit. The area that owns the tables writes the
/// job; storage only runs it inside the batch's transaction and answers with its outcome after
/// the commit. A refusal is part of the outcome (nothing written, the transaction goes on); a
/// database error rolls back the whole batch.
pub trait WriteJob: Send + Sync + 'static {
    type Outcome: Send + 'static;
    fn run(
        &self,
        connection: &mut SqliteConnection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send;
}

/// A job in the writer's queue, its type erased.
trait Queued: Send {
    fn run<'a>(&'a mut self, connection: &'a mut SqliteConnection) -> BoxFuture<'a, Result<(), sqlx::Error>>;
    /// Sends the outcome, after the commit.
    fn answer(self: Box<Self>);
    /// Answers with [`StorageError::WriteFailed`]: the batch was rolled back.
    fn fail(self: Box<Self>);
}

type BoxFuture<'a, T> = std::pin::Pin<Box<dyn std::future::Future<Output = T> + Send + 'a>>;

struct Pending<J: WriteJob> {
    job: J,
    outcome: Option<J::Outcome>,
    /// `None` when the caller does not wait for the commit.
    reply: Option<oneshot::Sender<Result<J::Outcome, StorageError>>>,
}

impl<J: WriteJob> Queued for Pending<J> {
    fn run<'a>(&'a mut self, connection: &'a mut SqliteConnection) -> BoxFuture<'a, Result<(), sqlx::Error>> {
        Box::pin(async move {
            self.outcome = Some(self.job.run(connection).await?);
            Ok(())
        })
    }

    fn answer(self: Box<Self>) {
        if let (Some(reply), Some(outcome)) = (self.reply, self.outcome) {
            let _ = reply.send(Ok(outcome));
        }
    }

    fn fail(self: Box<Self>) {
        if let Some(reply) = self.reply {
            let _ = reply.send(Err(StorageError::WriteFailed));
        }
    }
}

impl Storage {
    /// Opens (creating if needed) the database file, applies the migrations and starts the
    /// writer task. Must be called inside a tokio runtime.
    pub async fn open(path: &Path) -> Result<Storage, OpenError> {
        let path_text = path.display().to_string();
        owner_only(path).map_err(|source| OpenError::Permissions { path: path_text.clone(), source })?;
        let options = SqliteConnectOptions::from_str("sqlite:")
            .map_err(|source| OpenError::Connect { path: path_text.clone(), source })?
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .foreign_keys(true)
            .busy_timeout(BUSY_TIMEOUT)
            // A deleted participant's bytes are overwritten, not left in free pages (issue 12;
            // `Storage::delete` then truncates the WAL, which still holds the old pages).
            .pragma("secure_delete", "ON")
            // No checkpoint inside a participant's commit (it would stall that batch for the
            // copy and its fsync); a background task checkpoints instead, see `checkpointer`.
            .pragma("wal_autocheckpoint", "0")
            // what a restarted WAL may keep on disk
            .pragma("journal_size_limit", JOURNAL_SIZE_LIMIT_BYTES.to_string());
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
            .connect_with(options.clone())
            .await
            .map_err(|source| OpenError::Connect { path: path_text.clone(), source })?;
        let admin = SqlitePoolOptions::new()
            .max_connections(2)
            .acquire_timeout(Duration::from_secs(300))
            .connect_with(options)
            .await
            .map_err(|source| OpenError::Connect { path: path_text, source })?;
        let (sender, receiver) = mpsc::channel(4 * MAX_BATCH);
        tokio::spawn(writer(write.clone(), receiver, with_suffix(path, "-wal")));
        tokio::spawn(checkpointer(read.clone()));
        Ok(Storage { read, admin, write, jobs: sender })
    }

    /// Records or refreshes a study at start-up; a new study starts open or closed as its file
    /// says, a known one keeps the state the admin gave it.
    pub async fn upsert_study(&self, study: &StudyRecord<'_>) -> Result<(), sqlx::Error> {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "INSERT INTO studies (slug, title, kind, open, definition, file_sha256, first_loaded_at, loaded_at)
             VALUES (?, ?, ?, ?, ?, ?, {NOW}, {NOW})
             ON CONFLICT (slug) DO UPDATE SET title = excluded.title, kind = excluded.kind,
                 definition = excluded.definition, file_sha256 = excluded.file_sha256,
                 loaded_at = excluded.loaded_at"
        )))
        .bind(study.slug)
        .bind(study.title)
        .bind(study.kind)
        .bind(study.open as i64)
        .bind(&study.definition)
        .bind(study.file_sha256)
        .execute(&self.write)
        .await?;
        Ok(())
    }

    /// Runs `job` in the next group commit and answers with its outcome after it is durable.
    pub async fn write<J: WriteJob>(&self, job: J) -> Result<J::Outcome, StorageError> {
        let (reply, answer) = oneshot::channel();
        self.send(Box::new(Pending { job, outcome: None, reply: Some(reply) })).await?;
        answer.await.map_err(|_| writer_gone())?
    }

    /// Queues `job` without waiting for its commit: the queue is first in, first out, so it is
    /// committed no later than any job queued after it.
    pub async fn submit<J: WriteJob>(&self, job: J) -> Result<(), StorageError> {
        self.send(Box::new(Pending { job, outcome: None, reply: None })).await
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
        self.write(SetOpen { slug: slug.to_string(), open }).await
    }

    /// The write connection, for start-up writes before participants arrive.
    pub(crate) fn write_pool(&self) -> &SqlitePool {
        &self.write
    }

    async fn send(&self, job: Box<dyn Queued>) -> Result<(), StorageError> {
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

async fn writer(pool: SqlitePool, mut receiver: mpsc::Receiver<Box<dyn Queued>>, wal: std::path::PathBuf) {
    let mut batch: Vec<Box<dyn Queued>> = Vec::with_capacity(MAX_BATCH);
    while let Some(first) = receiver.recv().await {
        batch.push(first);
        while batch.len() < MAX_BATCH {
            match receiver.try_recv() {
                Ok(job) => batch.push(job),
                Err(_) => break,
            }
        }
        match run_batch(&pool, &mut batch).await {
            Ok(()) => {
                for job in batch.drain(..) {
                    job.answer();
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
        bound_wal(&pool, &wal).await;
    }
}

/// After a batch: if the WAL file has grown past [`WAL_TRUNCATE_BYTES`], a truncating
/// checkpoint on the writer's own connection. A passive checkpoint cannot restart the WAL while
/// readers overlap (each holds a snapshot in it), so under steady reading the file would grow
/// without limit; this one waits (busy timeout) for the readers of the old WAL to finish (new
/// readers read the database file meanwhile), copies the WAL back and empties it. No write can
/// slip in while it waits, so it cannot be starved; the next batch waits for it instead (tens
/// of milliseconds, once per [`WAL_TRUNCATE_BYTES`] written).
async fn bound_wal(pool: &SqlitePool, wal: &Path) {
    let size = std::fs::metadata(wal).map(|meta| meta.len()).unwrap_or(0);
    if size <= WAL_TRUNCATE_BYTES {
        return;
    }
    // Wait for readers briefly, not for the connection's busy timeout: participants' next
    // batch waits meanwhile; if readers still hold the old WAL, the next batch tries again.
    let checkpoint = async {
        let mut connection = pool.acquire().await?;
        sqlx::query(sqlx::AssertSqlSafe(format!("PRAGMA busy_timeout = {}", WAL_TRUNCATE_WAIT.as_millis())))
            .execute(&mut *connection)
            .await?;
        let busy = sqlx::query("PRAGMA wal_checkpoint(TRUNCATE)")
            .fetch_one(&mut *connection)
            .await
            .map(|row| row.try_get::<i64, _>(0));
        sqlx::query(sqlx::AssertSqlSafe(format!("PRAGMA busy_timeout = {}", BUSY_TIMEOUT.as_millis())))
            .execute(&mut *connection)
            .await?;
        busy?
    };
    match checkpoint.await {
        Ok(0) => {}
        Ok(_) if size > WAL_WARN_BYTES => {
            eprintln!("warning: the WAL has grown to {} MB: readers keep it busy; will retry", size >> 20)
        }
        Ok(_) => {}
        Err(error) => eprintln!("warning: WAL checkpoint failed (will retry): {error}"),
    }
}

/// How long [`bound_wal`] waits for readers of the old WAL.
const WAL_TRUNCATE_WAIT: Duration = Duration::from_millis(250);
/// Past this size a WAL that could not be emptied is worth a warning.
const WAL_WARN_BYTES: u64 = 4 * WAL_TRUNCATE_BYTES;
/// How long a connection waits for a lock before giving up.
const BUSY_TIMEOUT: Duration = Duration::from_secs(10);

/// Copies the WAL back into the database file once a second (a passive checkpoint: it never
/// blocks the writer or readers), so the WAL stays small without any commit paying for it;
/// [`bound_wal`] empties it when overlapping readers keep it from restarting.
async fn checkpointer(pool: SqlitePool) {
    let mut interval = tokio::time::interval(CHECKPOINT_INTERVAL);
    loop {
        interval.tick().await;
        if let Err(error) = sqlx::query("PRAGMA wal_checkpoint(PASSIVE)").execute(&pool).await {
            eprintln!("warning: WAL checkpoint failed (will retry): {error}");
        }
    }
}

/// How often the WAL is checkpointed passively.
pub const CHECKPOINT_INTERVAL: Duration = Duration::from_secs(1);
/// Past this size the WAL is emptied by a truncating checkpoint.
pub const WAL_TRUNCATE_BYTES: u64 = 16 * 1024 * 1024;
/// `journal_size_limit`: the most a restarted WAL keeps on disk.
pub const JOURNAL_SIZE_LIMIT_BYTES: u64 = 8 * 1024 * 1024;

/// The path of a file sqlite keeps beside the database: `<database><suffix>` (`-wal`, `-shm`).
fn with_suffix(path: &Path, suffix: &str) -> std::path::PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(suffix);
    std::path::PathBuf::from(name)
}

/// Creates the database file readable and writable by its owner only, or makes an existing
/// one (and its WAL and shared-memory files) so. sqlite gives the files it creates beside the
/// database the database file's mode.
fn owner_only(path: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
        if let Some(parent) = path.parent().filter(|parent| !parent.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::OpenOptions::new().write(true).create(true).truncate(false).mode(0o600).open(path)?;
        for suffix in ["", "-wal", "-shm", "-journal"] {
            match std::fs::set_permissions(with_suffix(path, suffix), std::fs::Permissions::from_mode(0o600)) {
                Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
                other => other?,
            }
        }
    }
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
}

/// Runs the jobs in one transaction and commits. On a database error the transaction is rolled
/// back and the jobs stay in `batch` to be failed.
async fn run_batch(pool: &SqlitePool, batch: &mut [Box<dyn Queued>]) -> Result<(), sqlx::Error> {
    let mut transaction = pool.begin().await?;
    for job in batch.iter_mut() {
        job.run(&mut transaction).await?;
    }
    transaction.commit().await
}

/// Opens or closes a study (the admin's open/close).
struct SetOpen {
    slug: String,
    open: bool,
}

impl WriteJob for SetOpen {
    type Outcome = Result<(), AdminRefused>;

    async fn run(&self, connection: &mut SqliteConnection) -> Result<Self::Outcome, sqlx::Error> {
        let result = sqlx::query("UPDATE studies SET open = ? WHERE slug = ?")
            .bind(self.open as i64)
            .bind(&self.slug)
            .execute(&mut *connection)
            .await?;
        Ok(if result.rows_affected() == 1 {
            Ok(())
        } else {
            Err(AdminRefused::UnknownStudy { slug: self.slug.clone() })
        })
    }
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
        self.write(write).await
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
        let deletion = match self.write(Delete { id: id.to_string() }).await? {
            Ok(deletion) => deletion,
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

impl WriteJob for AdminWrite {
    type Outcome = Result<AdminWritten, AdminRefused>;

    fn run(
        &self,
        connection: &mut SqliteConnection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send {
        execute_admin(connection, self)
    }
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
        AdminWrite::Delete { id } => Ok(delete_rows(connection, id).await?.map(AdminWritten::Deleted)),
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

/// Deletes a participant and all their data, or a screen-out row, by id, with an audit line.
async fn delete_rows(
    connection: &mut SqliteConnection,
    id: &str,
) -> Result<Result<Deletion, AdminRefused>, sqlx::Error> {
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
        return Ok(Ok(deletion));
    }
    let study: Option<String> = sqlx::query_scalar("DELETE FROM screen_outs WHERE id = ? RETURNING study")
        .bind(id)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(study) = study else {
        return Ok(Err(AdminRefused::UnknownParticipant { id: id.to_string() }));
    };
    let deletion = Deletion { study: study.clone(), kind: "screen-out", ordinal: None, trials: 0, responses: 0 };
    audit(connection, "delete", &study, serde_json::to_value(&deletion).expect("serialises")).await?;
    Ok(Ok(deletion))
}

/// [`AdminWrite::Delete`] with the deletion as its outcome, for [`Storage::delete`].
struct Delete {
    id: String,
}

impl WriteJob for Delete {
    type Outcome = Result<Deletion, AdminRefused>;

    async fn run(&self, connection: &mut SqliteConnection) -> Result<Self::Outcome, sqlx::Error> {
        delete_rows(connection, &self.id).await
    }
}
