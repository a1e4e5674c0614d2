//! The database through sqlx: sqlite (embedded, the default) or PostgreSQL (`serve --database
//! postgres://…`), connections, migrations, the single writer with group commit, and the read
//! queries. Both run the same SQL through sqlx's `Any` driver, with `$1`-style parameters; the
//! PostgreSQL schema defines `strftime` and `julianday` for the two forms the queries use (its
//! migrations are in `migrations/postgres/`).
//!
//! Durability: sqlite runs in WAL mode with `synchronous = FULL`, so a commit returns only after
//! the WAL has been fsynced; PostgreSQL commits after its WAL is flushed (`synchronous_commit`
//! on, its default). All writes of a process go through one writer task that owns its only
//! write connection: it takes every job waiting in its queue (up to [`MAX_BATCH`]), runs them in
//! one transaction, commits, and only then answers each job. A response's `201` is therefore
//! sent after its row is durably on disk, while many concurrent participants share one commit
//! (group commit). If the commit fails, every job in the batch gets the error and nothing of the
//! batch is kept. Reads use a separate pool of connections beside the writer. Admin reads
//! (exports, the live analysis) have a pool of their own ([`Storage::admin`]), so however many
//! exports run, participants' reads never wait for a connection behind them.
//!
//! Several processes on one PostgreSQL: each batch first takes a transaction-scoped advisory
//! lock ([`WRITER_LOCK`]), so the batches of all processes run one after another, as sqlite's
//! single writer does, and every check a job makes before it writes (a trial already answered,
//! the next ordinal, the next judgment number) sees what every other process committed. The
//! primary keys and unique constraints back this up: a repeat is refused by the database, not by
//! a process's memory.
//!
//! sqlite's WAL is bounded: a background task checkpoints passively once a second, and when the
//! WAL file has grown past [`WAL_TRUNCATE_BYTES`] (readers that overlap keep a passive
//! checkpoint from ever restarting it) the writer, after its batch, runs a truncating
//! checkpoint, which waits for the readers of the old WAL to finish, copies everything back and
//! empties the file; `journal_size_limit` caps what a restarted WAL keeps on disk. The database
//! files are the owner's alone (mode 0600): they hold demographics.

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Duration;

use sqlx::any::{AnyConnectOptions, AnyPoolOptions};
use sqlx::{AnyConnection, AnyPool, ConnectOptions, Executor, Row};
use tokio::sync::{mpsc, oneshot};

/// A connection of either database (what a [`WriteJob`] runs on).
pub type Connection = AnyConnection;
/// A pool of either database's connections.
pub type Pool = AnyPool;

/// Most jobs committed together in one transaction.
pub const MAX_BATCH: usize = 512;

/// SQL expression for "now" as stored: UTC, ISO 8601, milliseconds.
pub const NOW: &str = "strftime('%Y-%m-%dT%H:%M:%fZ', 'now')";

static SQLITE_MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("../migrations");
static POSTGRES_MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("../migrations/postgres");

/// The advisory lock every PostgreSQL batch takes first, so that the writers of several
/// processes take turns (its key: "mrstudy" in ASCII).
pub const WRITER_LOCK: i64 = 0x6d_72_73_74_75_64_79;

/// Which database a server keeps its data in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Database {
    /// The embedded default: one file, `<data-dir>/mrstudy.db` unless named otherwise.
    Sqlite(PathBuf),
    /// A PostgreSQL server (`postgres://user:password@host:port/database`), which several
    /// `serve` processes may share.
    Postgres(String),
}

/// The two databases' kinds, for what differs between them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    Sqlite,
    Postgres,
}

/// Why `--database` was refused; the URL's password is never in it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ChooseError {
    #[error("--database (or MRSTUDY_DATABASE_URL) is empty; give a postgres:// URL or a sqlite file's path")]
    Empty,
    /// A `postgres://` URL that does not parse (`url` without its password).
    #[error("--database {url} is not a usable PostgreSQL URL: {reason}")]
    PostgresUrl { url: String, reason: String },
    /// A URL of another database (`url` without its password).
    #[error(
        "--database {url}: mrstudy keeps its data in sqlite (a file's path) or PostgreSQL (postgres://…), not {scheme}"
    )]
    Scheme { url: String, scheme: String },
}

impl Database {
    /// `serve --database`'s value: a `postgres://` (or `postgresql://`) URL, or a sqlite file's
    /// path (`sqlite://` in front optional); `None`: the sqlite file in the data directory.
    pub fn choose(flag: Option<&str>, data_dir: &Path) -> Result<Database, ChooseError> {
        let Some(text) = flag.map(str::trim) else { return Ok(Database::in_data_dir(data_dir)) };
        if text.is_empty() {
            return Err(ChooseError::Empty);
        }
        if text.starts_with("postgres://") || text.starts_with("postgresql://") {
            AnyConnectOptions::from_str(text)
                .map_err(|error| ChooseError::PostgresUrl { url: redact(text), reason: error.to_string() })?;
            return Ok(Database::Postgres(text.to_string()));
        }
        if let Some((scheme, _)) = text.split_once("://")
            && scheme != "sqlite"
        {
            return Err(ChooseError::Scheme { url: redact(text), scheme: scheme.to_string() });
        }
        Ok(Database::Sqlite(PathBuf::from(text.strip_prefix("sqlite://").unwrap_or(text))))
    }

    /// The sqlite file `<data-dir>/mrstudy.db`.
    pub fn in_data_dir(data_dir: &Path) -> Database {
        Database::Sqlite(data_dir.join("mrstudy.db"))
    }

    pub fn backend(&self) -> Backend {
        match self {
            Database::Sqlite(_) => Backend::Sqlite,
            Database::Postgres(_) => Backend::Postgres,
        }
    }

    /// The database for messages: the file's path, or the URL without its password.
    pub fn describe(&self) -> String {
        match self {
            Database::Sqlite(path) => path.display().to_string(),
            Database::Postgres(url) => redact(url),
        }
    }
}

/// Creates a new, empty database with a random name (`<prefix>_<32 hex digits>`) on the
/// PostgreSQL server of `server_url` (whose own database the connection uses, e.g. `postgres`)
/// and returns its URL: for benchmarks and tests, which each need a database of their own.
pub async fn new_postgres_database(server_url: &str, prefix: &str) -> Result<String, sqlx::Error> {
    use sqlx::Connection as _;
    let mut url = url::Url::parse(server_url).map_err(|error| sqlx::Error::Configuration(error.into()))?;
    let name = format!("{prefix}_{}", crate::random_hex(16));
    let mut connection = sqlx::PgConnection::connect(server_url).await?;
    connection.execute(sqlx::AssertSqlSafe(format!("CREATE DATABASE \"{name}\""))).await?;
    connection.close().await?;
    url.set_path(&name);
    Ok(url.to_string())
}

/// Drops the database of `database_url` (made by [`new_postgres_database`]) on the PostgreSQL
/// server of `server_url`, closing any connections still open to it (PostgreSQL 13 or later).
pub async fn drop_postgres_database(server_url: &str, database_url: &str) -> Result<(), sqlx::Error> {
    use sqlx::Connection as _;
    let url = url::Url::parse(database_url).map_err(|error| sqlx::Error::Configuration(error.into()))?;
    let name = url.path().trim_start_matches('/').replace('"', "\"\"");
    let mut connection = sqlx::PgConnection::connect(server_url).await?;
    connection.execute(sqlx::AssertSqlSafe(format!("DROP DATABASE IF EXISTS \"{name}\" WITH (FORCE)"))).await?;
    connection.close().await
}

/// How durable a commit is on the PostgreSQL server of `server_url`: its version and the
/// settings that decide it (`fsync`, `synchronous_commit`), for benchmark reports.
pub async fn postgres_durability(server_url: &str) -> Result<String, sqlx::Error> {
    use sqlx::Connection as _;
    let mut connection = sqlx::PgConnection::connect(server_url).await?;
    let (version, fsync, synchronous): (String, String, String) = sqlx::query_as(
        "SELECT current_setting('server_version'), current_setting('fsync'), current_setting('synchronous_commit')",
    )
    .fetch_one(&mut connection)
    .await?;
    connection.close().await?;
    Ok(format!("PostgreSQL {version}, fsync={fsync}, synchronous_commit={synchronous}"))
}

/// A URL with its password replaced by `***`.
fn redact(url: &str) -> String {
    match url::Url::parse(url) {
        Ok(mut parsed) if parsed.password().is_some() => {
            let _ = parsed.set_password(Some("***"));
            parsed.to_string()
        }
        Ok(_) => url.to_string(),
        Err(_) => "(a URL that does not parse)".to_string(),
    }
}

/// An optional `f64` to bind. sqlx 0.9.0's `Any` driver hands a NULL `f64` to PostgreSQL as a
/// `float4` (its `Null(Double)` arm adds an `Option<f32>`, the `Null(Real)` arm the
/// `Option<f64>`), which PostgreSQL refuses for a `DOUBLE PRECISION` column ("incorrect binary
/// data format in bind parameter"); this binds NULL as an `Option<f32>`, which lands in the arm
/// that gives `float8`, and a number as the `f64` it is. Bind every `Option<f64>` through it
/// (sqlite takes either).
#[derive(Debug, Clone, Copy)]
pub struct OptionalF64(pub Option<f64>);

impl sqlx::Type<sqlx::Any> for OptionalF64 {
    fn type_info() -> sqlx::any::AnyTypeInfo {
        <f64 as sqlx::Type<sqlx::Any>>::type_info()
    }
}

impl<'q> sqlx::Encode<'q, sqlx::Any> for OptionalF64 {
    fn encode_by_ref(
        &self,
        buffer: &mut <sqlx::Any as sqlx::Database>::ArgumentBuffer,
    ) -> Result<sqlx::encode::IsNull, sqlx::error::BoxDynError> {
        match self.0 {
            Some(value) => <f64 as sqlx::Encode<'q, sqlx::Any>>::encode_by_ref(&value, buffer),
            None => <Option<f32> as sqlx::Encode<'q, sqlx::Any>>::encode_by_ref(&None, buffer),
        }
    }
}

/// Failure to open the database.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OpenError {
    #[error("cannot open the database {path}: {source}")]
    Connect { path: String, source: sqlx::Error },
    #[error(transparent)]
    Choose(ChooseError),
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
    pub read: Pool,
    /// The admin's reads (exports, analysis, lists): apart from `read`, so that exports cannot
    /// take the connections participants wait for.
    pub admin: Pool,
    write: Pool,
    jobs: mpsc::Sender<Box<dyn Queued>>,
    backend: Backend,
}

/// A write that runs in the writer's group commit. The area that owns the tables writes the
/// job; storage only runs it inside the batch's transaction and answers with its outcome after
/// the commit. A refusal is part of the outcome (nothing written, the transaction goes on); a
/// database error rolls back the whole batch.
pub trait WriteJob: Send + Sync + 'static {
    type Outcome: Send + 'static;
    fn run(
        &self,
        connection: &mut Connection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send;
}

/// A job in the writer's queue, its type erased.
trait Queued: Send {
    fn run<'a>(&'a mut self, connection: &'a mut Connection) -> BoxFuture<'a, Result<(), sqlx::Error>>;
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
    fn run<'a>(&'a mut self, connection: &'a mut Connection) -> BoxFuture<'a, Result<(), sqlx::Error>> {
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
    /// Opens (creating if needed) the database, applies the migrations and starts the writer
    /// task. Must be called inside a tokio runtime.
    pub async fn open(database: &Database) -> Result<Storage, OpenError> {
        sqlx::any::install_default_drivers();
        let name = database.describe();
        let connect = |source| OpenError::Connect { path: name.clone(), source };
        let (options, sizes, migrator) = match database {
            Database::Sqlite(path) => {
                owner_only(path).map_err(|source| OpenError::Permissions { path: name.clone(), source })?;
                let url =
                    sqlx::sqlite::SqliteConnectOptions::new().filename(path).create_if_missing(true).to_url_lossy();
                (AnyConnectOptions::from_url(&url).map_err(connect)?, (4, 2), &SQLITE_MIGRATOR)
            }
            Database::Postgres(url) => (AnyConnectOptions::from_str(url).map_err(connect)?, (8, 2), &POSTGRES_MIGRATOR),
        };
        let backend = database.backend();
        let pool = |connections: u32, acquire: Duration| {
            AnyPoolOptions::new()
                .max_connections(connections)
                .acquire_timeout(acquire)
                .after_connect(move |connection, _| Box::pin(async move { configure(connection, backend).await }))
        };
        let write =
            pool(1, Duration::from_secs(60)).min_connections(1).connect_with(options.clone()).await.map_err(connect)?;
        migrator.run(&write).await.map_err(|source| OpenError::Migrate { path: name.clone(), source })?;
        let read = pool(sizes.0, Duration::from_secs(60)).connect_with(options.clone()).await.map_err(connect)?;
        let admin = pool(sizes.1, Duration::from_secs(300)).connect_with(options).await.map_err(connect)?;
        let (sender, receiver) = mpsc::channel(4 * MAX_BATCH);
        let wal = match database {
            Database::Sqlite(path) => {
                tokio::spawn(checkpointer(read.clone()));
                Some(with_suffix(path, "-wal"))
            }
            Database::Postgres(_) => None,
        };
        tokio::spawn(writer(write.clone(), receiver, backend, wal));
        Ok(Storage { read, admin, write, jobs: sender, backend })
    }

    /// Which database this is.
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// Records or refreshes a study at start-up; a new study starts open or closed as its file
    /// says, a known one keeps the state the admin gave it.
    pub async fn upsert_study(&self, study: &StudyRecord<'_>) -> Result<(), sqlx::Error> {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "INSERT INTO studies (slug, title, kind, open, definition, file_sha256, first_loaded_at, loaded_at)
             VALUES ($1, $2, $3, $4, $5, $6, {NOW}, {NOW})
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

    /// Whether `token_sha256` is a preview link of the study, made less than
    /// [`PREVIEW_LINK_DAYS`] ago and not revoked.
    pub async fn is_preview(&self, study: &str, token_sha256: &[u8]) -> Result<bool, sqlx::Error> {
        let found: Option<String> =
            sqlx::query_scalar("SELECT created_at FROM previews WHERE study = $1 AND token_sha256 = $2")
                .bind(study)
                .bind(token_sha256)
                .fetch_optional(&self.read)
                .await?;
        // both ISO 8601 UTC with milliseconds: the text order is the time order
        Ok(found.is_some_and(|created_at| created_at > preview_cutoff(std::time::SystemTime::now())))
    }

    /// The write connection, for start-up writes before participants arrive.
    pub(crate) fn write_pool(&self) -> &Pool {
        &self.write
    }

    async fn send(&self, job: Box<dyn Queued>) -> Result<(), StorageError> {
        self.jobs.send(job).await.map_err(|_| writer_gone())
    }

    /// Whether the study is open, as stored.
    pub async fn is_open(&self, slug: &str) -> Result<bool, sqlx::Error> {
        let open: Option<i64> = sqlx::query_scalar("SELECT open FROM studies WHERE slug = $1")
            .bind(slug)
            .fetch_optional(&self.read)
            .await?;
        Ok(open == Some(1))
    }
}

fn writer_gone() -> StorageError {
    StorageError::WriterStopped
}

/// Sets up a new connection: sqlite's durability, locking and WAL settings (per connection), or
/// PostgreSQL's UTC session time zone.
async fn configure(connection: &mut Connection, backend: Backend) -> Result<(), sqlx::Error> {
    let statements = match backend {
        Backend::Sqlite => vec![
            "PRAGMA journal_mode = WAL".to_string(),
            "PRAGMA synchronous = FULL".to_string(),
            "PRAGMA foreign_keys = ON".to_string(),
            format!("PRAGMA busy_timeout = {}", BUSY_TIMEOUT.as_millis()),
            // A deleted participant's bytes are overwritten, not left in free pages (issue 12;
            // `Storage::delete` then truncates the WAL, which still holds the old pages).
            "PRAGMA secure_delete = ON".to_string(),
            // No checkpoint inside a participant's commit (it would stall that batch for the
            // copy and its fsync); a background task checkpoints instead, see `checkpointer`.
            "PRAGMA wal_autocheckpoint = 0".to_string(),
            // what a restarted WAL may keep on disk
            format!("PRAGMA journal_size_limit = {JOURNAL_SIZE_LIMIT_BYTES}"),
        ],
        Backend::Postgres => vec!["SET TIME ZONE 'UTC'".to_string()],
    };
    for statement in statements {
        connection.execute(sqlx::AssertSqlSafe(statement)).await?;
    }
    Ok(())
}

async fn writer(pool: Pool, mut receiver: mpsc::Receiver<Box<dyn Queued>>, backend: Backend, wal: Option<PathBuf>) {
    let mut batch: Vec<Box<dyn Queued>> = Vec::with_capacity(MAX_BATCH);
    while let Some(first) = receiver.recv().await {
        batch.push(first);
        while batch.len() < MAX_BATCH {
            match receiver.try_recv() {
                Ok(job) => batch.push(job),
                Err(_) => break,
            }
        }
        match run_batch(&pool, backend, &mut batch).await {
            Ok(()) => {
                for job in batch.drain(..) {
                    job.answer();
                }
            }
            Err(error) => {
                tracing::error!(jobs = batch.len(), %error, "a database write failed and was rolled back");
                for job in batch.drain(..) {
                    job.fail();
                }
            }
        }
        batch.clear();
        if let Some(wal) = &wal {
            bound_wal(&pool, wal).await;
        }
    }
}

/// After a batch: if the WAL file has grown past [`WAL_TRUNCATE_BYTES`], a truncating
/// checkpoint on the writer's own connection. A passive checkpoint cannot restart the WAL while
/// readers overlap (each holds a snapshot in it), so under steady reading the file would grow
/// without limit; this one waits (busy timeout) for the readers of the old WAL to finish (new
/// readers read the database file meanwhile), copies the WAL back and empties it. No write can
/// slip in while it waits, so it cannot be starved; the next batch waits for it instead (tens
/// of milliseconds, once per [`WAL_TRUNCATE_BYTES`] written).
async fn bound_wal(pool: &Pool, wal: &Path) {
    let size = std::fs::metadata(wal).map(|meta| meta.len()).unwrap_or(0);
    if size <= WAL_TRUNCATE_BYTES {
        return;
    }
    // Wait for readers briefly, not for the connection's busy timeout: participants' next
    // batch waits meanwhile; if readers still hold the old WAL, the next batch tries again.
    match try_truncate_wal(pool).await {
        Ok(0) => {}
        Ok(_) if size > WAL_WARN_BYTES => {
            tracing::warn!(megabytes = size >> 20, "the WAL has grown: readers keep it busy; will retry")
        }
        Ok(_) => {}
        Err(error) => tracing::warn!(%error, "WAL checkpoint failed (will retry)"),
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
async fn checkpointer(pool: Pool) {
    let mut interval = tokio::time::interval(CHECKPOINT_INTERVAL);
    loop {
        interval.tick().await;
        if let Err(error) = sqlx::query("PRAGMA wal_checkpoint(PASSIVE)").execute(&pool).await {
            tracing::warn!(%error, "WAL checkpoint failed (will retry)");
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
fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(suffix);
    PathBuf::from(name)
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
/// back and the jobs stay in `batch` to be failed. On PostgreSQL the transaction first waits for
/// [`WRITER_LOCK`], so the batches of several processes take turns.
async fn run_batch(pool: &Pool, backend: Backend, batch: &mut [Box<dyn Queued>]) -> Result<(), sqlx::Error> {
    let mut transaction = match backend {
        // sqlite: the write lock at the start, where a lock held elsewhere (an operator's
        // `sqlite3`, a backup) is waited for (busy timeout); a deferred transaction that has
        // read first cannot wait for it and fails at its first write ("database is locked")
        Backend::Sqlite => pool.begin_with("BEGIN IMMEDIATE").await?,
        Backend::Postgres => pool.begin().await?,
    };
    if backend == Backend::Postgres {
        sqlx::query("SELECT pg_advisory_xact_lock($1)").bind(WRITER_LOCK).execute(&mut *transaction).await?;
    }
    for job in batch.iter_mut() {
        job.run(&mut transaction).await?;
    }
    transaction.commit().await
}

/// `at` as UTC ISO 8601 with milliseconds, as the database stores times.
pub fn iso(at: std::time::SystemTime) -> String {
    let since = at.duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    let (secs, millis) = (since.as_secs() as i64, since.subsec_millis());
    let (days, rest) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // civil from days (Howard Hinnant's algorithm)
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + if month <= 2 { 1 } else { 0 };
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{millis:03}Z", rest / 3600, rest % 3600 / 60, rest % 60)
}

/// How long a preview link lets pilots join: 14 days from its making.
pub const PREVIEW_LINK_DAYS: u64 = 14;

/// The making time (ISO 8601, as stored) before which a preview link has expired at `now`.
pub fn preview_cutoff(now: std::time::SystemTime) -> String {
    let valid = Duration::from_secs(PREVIEW_LINK_DAYS * 86_400);
    iso(now.checked_sub(valid).unwrap_or(std::time::UNIX_EPOCH))
}

impl Storage {
    /// After a deletion ([`Storage::delete`]): rewrites the database and truncates the WAL so that
    /// no deleted row's bytes remain in its files. `secure_delete` zeroes the freed cells in the
    /// new page versions; `VACUUM` rewrites every page, which also drops copies of keys that
    /// b-tree interior pages may keep after their row is gone (the `WITHOUT ROWID` tables
    /// `trials` and `responses` keep whole rows there, the external-id index the external id);
    /// the truncating checkpoint copies the new pages over the old ones and empties the WAL.
    ///
    /// Both run on the writer's only connection, between its batches, never beside them: a
    /// checkpoint on another connection takes sqlite's write lock, and a batch that already
    /// began reading cannot wait for that lock (sqlite refuses at once, "database is locked"),
    /// so the whole group commit was rolled back (issue 46). Participants' writes wait for the
    /// `VACUUM` instead (about a second per 40 MB; deletions are rare).
    pub(crate) async fn forget_deleted(&self) -> Result<(), StorageError> {
        match self.backend {
            Backend::Sqlite => {
                sqlx::query("VACUUM").execute(&self.write).await?;
                truncate_wal_between_batches(&self.write).await?;
            }
            // A full vacuum rewrites the tables into new files without the dead rows (the old
            // files are removed); PostgreSQL's own WAL keeps the old rows until it is recycled.
            // `ANALYZE` replaces the tables' statistics (`pg_stats`: most common values and
            // histogram bounds are copies of column values), which still held the deleted
            // participant's from the last analyze, autovacuum's or anyone's (issue 46).
            Backend::Postgres => {
                sqlx::query(sqlx::AssertSqlSafe(format!("VACUUM (FULL, ANALYZE) {}", PERSONAL_TABLES.join(", "))))
                    .execute(&self.admin)
                    .await?;
                forget_statistics_of_empty_tables(&self.admin).await?;
            }
        }
        Ok(())
    }

    /// `PRAGMA wal_checkpoint(TRUNCATE)` between the writer's batches, retried while readers
    /// keep it busy (sqlite; nothing to do on PostgreSQL).
    pub async fn truncate_wal(&self) -> Result<(), StorageError> {
        if self.backend == Backend::Postgres {
            return Ok(());
        }
        truncate_wal_between_batches(&self.write).await
    }
}

/// The tables that hold a participant's data, which a deletion rewrites (PostgreSQL).
const PERSONAL_TABLES: [&str; 6] =
    ["responses", "trials", "participants", "screen_outs", "task_trials", "task_participants"];

/// PostgreSQL's `ANALYZE` of an empty table keeps the statistics it had (found by issue 46's
/// test: the last participant's answers deleted, `pg_stats` still showed their id): for each of
/// [`PERSONAL_TABLES`] that is now empty, every column with statistics is altered to its own
/// type, which drops the column's `pg_statistic` row (an empty table: no rewrite to speak of;
/// reading or writing `pg_statistic` directly needs a superuser).
async fn forget_statistics_of_empty_tables(pool: &Pool) -> Result<(), sqlx::Error> {
    for table in PERSONAL_TABLES {
        let empty: bool = sqlx::query_scalar(sqlx::AssertSqlSafe(format!("SELECT NOT EXISTS (SELECT 1 FROM {table})")))
            .fetch_one(pool)
            .await?;
        if !empty {
            continue;
        }
        let columns: Vec<(String, String)> = sqlx::query_as(
            "SELECT a.attname::text, format_type(a.atttypid, a.atttypmod)
             FROM pg_stats s JOIN pg_attribute a ON a.attrelid = $1::regclass AND a.attname = s.attname
             WHERE s.schemaname = current_schema() AND s.tablename = $1",
        )
        .bind(table)
        .fetch_all(pool)
        .await?;
        for (column, column_type) in columns {
            let column = column.replace('"', "\"\"");
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "ALTER TABLE {table} ALTER COLUMN \"{column}\" TYPE {column_type}"
            )))
            .execute(pool)
            .await?;
        }
    }
    Ok(())
}

/// How often [`Storage::truncate_wal`] tries before giving up (50 ms apart).
const WAL_TRUNCATE_TRIES: usize = 200;

/// `PRAGMA wal_checkpoint(TRUNCATE)` on the writer's connection (`write`, a pool of one), so
/// that it runs between group commits and never takes the write lock from a batch in flight.
/// Each try waits [`WAL_TRUNCATE_WAIT`] at most for readers of the old WAL and then gives the
/// connection back, so participants' batches go on between tries.
async fn truncate_wal_between_batches(write: &Pool) -> Result<(), StorageError> {
    for _ in 0..WAL_TRUNCATE_TRIES {
        if try_truncate_wal(write).await? == 0 {
            return Ok(());
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    Err(StorageError::WalBusy { tries: WAL_TRUNCATE_TRIES })
}

/// One try of `PRAGMA wal_checkpoint(TRUNCATE)` on a connection of `pool`, waiting
/// [`WAL_TRUNCATE_WAIT`] at most for readers of the old WAL (the connection's busy timeout is
/// set back afterwards, also when the checkpoint failed): its `busy` column, 0 when the WAL was
/// emptied. The connection goes back to the pool before this returns.
async fn try_truncate_wal(pool: &Pool) -> Result<i64, sqlx::Error> {
    let mut connection = pool.acquire().await?;
    sqlx::query(sqlx::AssertSqlSafe(format!("PRAGMA busy_timeout = {}", WAL_TRUNCATE_WAIT.as_millis())))
        .execute(&mut *connection)
        .await?;
    let busy = sqlx::query("PRAGMA wal_checkpoint(TRUNCATE)")
        .fetch_one(&mut *connection)
        .await
        .and_then(|row| row.try_get::<i64, _>(0));
    sqlx::query(sqlx::AssertSqlSafe(format!("PRAGMA busy_timeout = {}", BUSY_TIMEOUT.as_millis())))
        .execute(&mut *connection)
        .await?;
    busy
}

/// An admin session's row: started (with its expiry, the expired rows deleted) or ended.
enum AdminSession {
    Start { id_sha256: [u8; 32], expires_unix: i64, now_unix: i64 },
    End { id_sha256: [u8; 32] },
}

impl WriteJob for AdminSession {
    type Outcome = ();

    async fn run(&self, connection: &mut Connection) -> Result<(), sqlx::Error> {
        match self {
            AdminSession::Start { id_sha256, expires_unix, now_unix } => {
                sqlx::query("DELETE FROM admin_sessions WHERE expires_unix <= $1")
                    .bind(now_unix)
                    .execute(&mut *connection)
                    .await?;
                sqlx::query("INSERT INTO admin_sessions (id_sha256, expires_unix) VALUES ($1, $2)")
                    .bind(&id_sha256[..])
                    .bind(expires_unix)
                    .execute(&mut *connection)
                    .await?;
            }
            AdminSession::End { id_sha256 } => {
                sqlx::query("DELETE FROM admin_sessions WHERE id_sha256 = $1")
                    .bind(&id_sha256[..])
                    .execute(&mut *connection)
                    .await?;
            }
        }
        Ok(())
    }
}

impl Storage {
    /// Stores an admin session (the SHA-256 of its id) valid until `expires_unix` and deletes
    /// the sessions expired at `now_unix`; answers once it is durable, so that every server on
    /// the database accepts its cookie.
    pub async fn start_admin_session(
        &self,
        id_sha256: [u8; 32],
        expires_unix: i64,
        now_unix: i64,
    ) -> Result<(), StorageError> {
        self.write(AdminSession::Start { id_sha256, expires_unix, now_unix }).await
    }

    /// Ends the admin session (by the SHA-256 of its id), if there is one.
    pub async fn end_admin_session(&self, id_sha256: [u8; 32]) -> Result<(), StorageError> {
        self.write(AdminSession::End { id_sha256 }).await
    }

    /// Whether the admin session (by the SHA-256 of its id) exists and expires after `now_unix`.
    pub async fn is_admin_session(&self, id_sha256: &[u8; 32], now_unix: i64) -> Result<bool, sqlx::Error> {
        let found: Option<i64> =
            sqlx::query_scalar("SELECT 1 FROM admin_sessions WHERE id_sha256 = $1 AND expires_unix > $2")
                .bind(&id_sha256[..])
                .bind(now_unix)
                .fetch_optional(&self.read)
                .await?;
        Ok(found.is_some())
    }
}
