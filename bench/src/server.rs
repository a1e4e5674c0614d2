//! The load generator behind `mrstudy bench server`: drives the API of
//! `mrstudy-server` from loopback with many concurrent simulated participants and measures
//! responses per second and response latency, with the durable writes of a real server. [`run`]
//! measures one concurrency, [`bench()`] the table of docs/design.md's bench (a typed [`Report`], its
//! JSON by [`Report::to_json`]).
//!
//! In the bench crate so that its HTTP client and temporary directories are not dependencies
//! of the server.
//!
//! The database ([`Backing`]) is a sqlite file in a fresh data directory under `$TMPDIR` (WAL,
//! `synchronous = FULL`, group commit), or a new database made for the run on a PostgreSQL
//! server and dropped after it. With one process the server runs in this process on its own
//! tokio runtime (two worker threads); with several ([`BenchConfig::processes`], PostgreSQL
//! only) each is a `mrstudy serve` child process of this binary on the one database, and every
//! simulated participant sends its requests to them in turn, as a load balancer without sticky
//! sessions would. The study is synthetic and shaped like the thesis survey (8 conditions,
//! 13 anchored pairs × 5 = 65 trials, 6 scene configurations, tiny images). The simulated
//! participants run on a second runtime and talk HTTP/1.1 over loopback: each joins, then loops
//! `GET next` → `POST response` (no think time) until its 65 trials are done, then joins again,
//! until the measured time is up. Only responses answered 201 count.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use serde::Serialize;
use serde_json::json;

use mrstudy_analysis::quantile::nearest_rank;
use mrstudy_server::serve::prepare_on;
use mrstudy_server::storage::{self, Database};

/// The database the benchmark's servers write to.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Backing {
    /// `mrstudy.db` in a fresh data directory under `$TMPDIR`.
    #[default]
    Sqlite,
    /// A new database, made for each row and dropped after it, on the PostgreSQL server of
    /// this URL (whose own database the connection uses, e.g. `postgres`).
    Postgres { server_url: String },
}

impl Backing {
    /// `mrstudy bench server --database`: `sqlite`, `postgres` (the server of
    /// `MRSTUDY_DATABASE_URL`, given as `environment`) or a `postgres://` URL.
    pub fn parse(flag: Option<&str>, environment: Option<&str>) -> Result<Backing, String> {
        let is_url = |text: &str| text.starts_with("postgres://") || text.starts_with("postgresql://");
        match flag {
            None | Some("sqlite") => Ok(Backing::Sqlite),
            Some("postgres" | "postgresql") => match environment {
                Some(url) if is_url(url) => Ok(Backing::Postgres { server_url: url.to_string() }),
                Some(_) => Err("--database postgres takes the server from MRSTUDY_DATABASE_URL, which is not a postgres:// URL.".into()),
                None => Err("--database postgres needs a PostgreSQL server: give its URL (--database postgres://user@host:port/postgres) or set MRSTUDY_DATABASE_URL.".into()),
            },
            Some(url) if is_url(url) => Ok(Backing::Postgres { server_url: url.to_string() }),
            Some(other) => Err(format!("--database must be sqlite, postgres or a postgres:// URL, not `{other}`.")),
        }
    }

    /// `sqlite` or `postgres`, as the rows name it.
    pub fn name(&self) -> &'static str {
        match self {
            Backing::Sqlite => "sqlite",
            Backing::Postgres { .. } => "postgres",
        }
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct BenchConfig {
    /// Concurrent simulated participants.
    pub participants: usize,
    /// Measured time (after a one-second warm-up).
    pub duration: Duration,
    /// Admin export loops running beside the participants (each downloads the trials CSV
    /// again as soon as it has it).
    pub exports: usize,
    pub database: Backing,
    /// Server processes on the one database (more than one: PostgreSQL only, each a
    /// `mrstudy serve` child process of the running binary).
    pub processes: usize,
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig {
            participants: 64,
            duration: Duration::from_secs(10),
            exports: 0,
            database: Backing::Sqlite,
            processes: 1,
        }
    }
}

/// The measurements at one concurrency: a row of the bench JSON.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// Always `server`.
    pub bench: &'static str,
    /// `sqlite` or `postgres`.
    pub database: &'static str,
    /// Server processes; every participant's requests alternate between them.
    pub processes: usize,
    pub participants: usize,
    /// The row's headline time: the median latency of `POST …/responses`, in ms.
    pub ms: f64,
    pub seconds: f64,
    pub responses: u64,
    pub responses_per_s: f64,
    /// Latency of `POST …/responses` (201), in ms.
    pub response_p50_ms: f64,
    pub response_p90_ms: f64,
    pub response_p99_ms: f64,
    pub response_max_ms: f64,
    /// Latency of `GET …/next`, in ms.
    pub next_p50_ms: f64,
    pub next_p99_ms: f64,
    pub joins: u64,
    pub errors: u64,
    /// Concurrent admin export loops, and the exports they finished in the measured time.
    pub exports: usize,
    pub exports_done: u64,
    /// sqlite: the largest the WAL file was, sampled every 50 ms, in MB.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wal_max_mb: Option<f64>,
    /// Where the data directory was (on sqlite its file system decides what an fsync costs).
    pub data_dir: String,
    /// What makes a response durable before its 201.
    pub durability: String,
}

/// `mrstudy bench server`: the rows (one per concurrency) and the adapter line of the bench JSON.
#[derive(Debug, Clone)]
pub struct Report {
    pub adapter: String,
    pub rows: Vec<BenchReport>,
}

impl Report {
    /// docs/design.md's bench JSON: `{ "adapter": …, "rows": [...] }`.
    pub fn to_json(&self) -> serde_json::Value {
        json!({ "adapter": self.adapter, "rows": self.rows })
    }
}

/// The benchmark: 16, 64 and 256 participants for 10 s each, then 16 and 64 beside 8 admin
/// export loops (`quick`: 64 for 3 s), on `database` with `processes` servers; table lines go
/// to `line` as the rows are measured.
pub fn bench(quick: bool, database: &Backing, processes: usize, line: &dyn Fn(&str)) -> Result<Report, String> {
    check_processes(database, processes)?;
    let seconds = if quick { 3 } else { 10 };
    let concurrency: &[(usize, usize)] =
        if quick { &[(64, 0)] } else { &[(16, 0), (64, 0), (256, 0), (16, 8), (64, 8)] };
    line(&format!(
        "{:>8} {:>9} {:>12} {:>7} {:>8} {:>11} {:>9} {:>9} {:>9} {:>9} {:>10} {:>7} {:>8}",
        "database",
        "processes",
        "participants",
        "exports",
        "seconds",
        "responses/s",
        "p50 ms",
        "p90 ms",
        "p99 ms",
        "max ms",
        "next p99",
        "errors",
        "WAL MB"
    ));
    let mut rows = Vec::new();
    for &(participants, exports) in concurrency {
        let row = run(BenchConfig {
            participants,
            duration: Duration::from_secs(seconds),
            exports,
            database: database.clone(),
            processes,
        })?;
        line(&format!(
            "{:>8} {:>9} {:>12} {:>7} {:>8.1} {:>11.0} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>10.2} {:>7} {:>8}",
            row.database,
            row.processes,
            row.participants,
            format!("{}/{}", row.exports, row.exports_done),
            row.seconds,
            row.responses_per_s,
            row.response_p50_ms,
            row.response_p90_ms,
            row.response_p99_ms,
            row.response_max_ms,
            row.next_p99_ms,
            row.errors,
            row.wal_max_mb.map(|mb| format!("{mb:.1}")).unwrap_or_else(|| "-".into())
        ));
        rows.push(row);
    }
    let durability = rows.first().map(|row| row.durability.clone()).unwrap_or_default();
    let adapter = match database {
        Backing::Sqlite => format!("none (server: HTTP/1.1 over loopback; {durability} on the local file system)"),
        Backing::Postgres { .. } => format!(
            "none (server: HTTP/1.1 over loopback, {processes} {}; {durability}, over loopback)",
            if processes == 1 { "process" } else { "processes" }
        ),
    };
    Ok(Report { adapter, rows })
}

/// Several server processes share only a PostgreSQL database (sqlite has one writer process).
fn check_processes(database: &Backing, processes: usize) -> Result<(), String> {
    if processes > 1 && *database == Backing::Sqlite {
        return Err(format!(
            "--processes {processes} needs PostgreSQL (--database postgres): several servers cannot share a sqlite file."
        ));
    }
    Ok(())
}

/// A 1×1 PNG.
const TINY_PNG: &[u8] = &[
    0x89, 0x50, 0x4E, 0x47, 0x0D, 0x0A, 0x1A, 0x0A, 0x00, 0x00, 0x00, 0x0D, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00,
    0x01, 0x00, 0x00, 0x00, 0x01, 0x08, 0x02, 0x00, 0x00, 0x00, 0x90, 0x77, 0x53, 0xDE, 0x00, 0x00, 0x00, 0x0C, 0x49,
    0x44, 0x41, 0x54, 0x08, 0xD7, 0x63, 0xF8, 0xCF, 0xC0, 0x00, 0x00, 0x03, 0x01, 0x01, 0x00, 0x18, 0xDD, 0x8D, 0xB0,
    0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4E, 0x44, 0xAE, 0x42, 0x60, 0x82,
];

const CONDITIONS: [(&str, [u8; 3]); 8] = [
    ("LQ", [0, 0, 0]),
    ("GI", [1, 0, 0]),
    ("CM", [0, 1, 0]),
    ("CA", [0, 0, 1]),
    ("GI+CM", [1, 1, 0]),
    ("GI+CA", [1, 0, 1]),
    ("CM+CA", [0, 1, 1]),
    ("HQ", [1, 1, 1]),
];

fn write_bench_study(dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir.join("images"))?;
    std::fs::write(dir.join("images/tiny.png"), TINY_PNG)?;
    let mut toml = String::from(
        "slug = \"bench\"\ntitle = \"Bench\"\nkind = \"paired-comparison\"\nquestion = \"Which fits better?\"\n\
         [texts]\nwelcome = \"w\"\nconsent = \"c\"\ninstructions = \"i\"\n\
         [[demographics]]\nname = \"gender\"\nlabel = \"Gender\"\ntype = \"choice\"\noptions = [\"female\", \"male\"]\n\
         [[demographics]]\nname = \"age\"\nlabel = \"Age\"\ntype = \"integer\"\nmin = 16\nmax = 110\n\
         [[factors]]\nname = \"gi\"\n[[factors]]\nname = \"cm\"\n[[factors]]\nname = \"ca\"\n",
    );
    for (name, levels) in CONDITIONS {
        toml += &format!(
            "[[conditions]]\nname = \"{name}\"\nlevels = {{ gi = {}, cm = {}, ca = {} }}\n",
            levels[0], levels[1], levels[2]
        );
    }
    for scene in 1..=6 {
        let images: Vec<String> =
            CONDITIONS.iter().map(|(name, _)| format!("\"{name}\" = \"images/tiny.png\"")).collect();
        toml += &format!("[[scenes]]\nname = \"s{scene}\"\nimages = {{ {} }}\n", images.join(", "));
    }
    toml += "[design]\npairs = \"anchored\"\nanchors = [\"LQ\", \"HQ\"]\nrepetitions = 5\nscenes = \"different\"\n";
    std::fs::write(dir.join("bench.toml"), toml)
}

#[derive(Default)]
struct Tally {
    response_ms: Vec<f64>,
    next_ms: Vec<f64>,
    joins: u64,
    errors: u64,
    exports_done: u64,
}

/// A tokio runtime of two worker threads named `bench-{role}`: the server and the simulated
/// participants each get one.
fn two_thread_runtime(role: &str) -> Result<tokio::runtime::Runtime, String> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name(format!("bench-{role}"))
        .enable_all()
        .build()
        .map_err(|error| format!("cannot start the {role} runtime: {error}"))
}

/// The servers of one row: in this process, or `mrstudy serve` child processes (killed when
/// this is dropped).
struct Servers {
    bases: Vec<String>,
    admin_token: String,
    children: Vec<std::process::Child>,
}

impl Drop for Servers {
    fn drop(&mut self) {
        for child in &mut self.children {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Starts a `mrstudy serve` child process of the running binary on `database_url`, without
/// limits per client (every participant comes from 127.0.0.1); returns it with its base URL
/// and admin token once it serves.
fn spawn_server(
    data_dir: &Path,
    studies_dir: &Path,
    database_url: &str,
) -> Result<(std::process::Child, String, String), String> {
    let binary = std::env::current_exe().map_err(|error| format!("cannot find the running binary: {error}"))?;
    let mut child = Command::new(&binary)
        .args(["serve", "--addr", "127.0.0.1:0", "--join-limit", "0", "--response-limit", "0", "--data-dir"])
        .arg(data_dir)
        .arg("--studies")
        .arg(studies_dir)
        .arg("--database")
        .arg(database_url)
        .env_remove("MRSTUDY_DATABASE_URL")
        .env_remove("MRSTUDY_ADMIN_TOKEN")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|error| format!("cannot start {} serve: {error}", binary.display()))?;
    let (lines, received) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().expect("piped");
    let stderr = child.stderr.take().expect("piped");
    let stdout_lines = lines.clone();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = stdout_lines.send(Ok(line));
        }
    });
    // stderr is read to its end (so the child never blocks on it); its lines explain a failure
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = lines.send(Err(line));
        }
    });
    let deadline = Instant::now() + Duration::from_secs(120);
    let (mut base, mut complaint) = (None, String::new());
    loop {
        match received.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            Ok(Ok(line)) => {
                if let Some(rest) = line.strip_prefix("mrstudy serving on ") {
                    base = rest.split_whitespace().next().map(str::to_string);
                }
                if let (Some(link), Some(base)) = (line.strip_prefix("admin link: "), &base) {
                    let token = link.split("token=").nth(1).unwrap_or_default().to_string();
                    let base = base.clone();
                    // the rest of its output is read and dropped
                    std::thread::spawn(move || for _ in received {});
                    return Ok((child, base, token));
                }
            }
            Ok(Err(line)) => complaint = line,
            Err(_) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!(
                    "{} serve did not start serving{} (bench server --processes runs the mrstudy binary's serve)",
                    binary.display(),
                    if complaint.is_empty() { String::new() } else { format!(": {complaint}") }
                ));
            }
        }
    }
}

/// Runs the benchmark (blocking).
pub fn run(config: BenchConfig) -> Result<BenchReport, String> {
    let work = tempfile::Builder::new()
        .prefix("mrstudy-bench-")
        .tempdir()
        .map_err(|error| format!("cannot create a temporary directory: {error}"))?;
    let studies_dir = work.path().join("studies");
    let data_dir = work.path().join("data");
    write_bench_study(&studies_dir).map_err(|error| format!("cannot write the bench study: {error}"))?;
    check_processes(&config.database, config.processes)?;

    let server_runtime = two_thread_runtime("server")?;
    let (database, durability) = server_runtime.block_on(async {
        match &config.database {
            Backing::Sqlite => Ok::<_, String>((
                Database::in_data_dir(&data_dir),
                "sqlite WAL, synchronous=FULL, group commit".to_string(),
            )),
            Backing::Postgres { server_url } => {
                let at = redacted(server_url);
                let durability = storage::postgres_durability(server_url)
                    .await
                    .map_err(|error| format!("cannot reach PostgreSQL at {at}: {error}"))?;
                let url = storage::new_postgres_database(server_url, "mrstudy_bench")
                    .await
                    .map_err(|error| format!("cannot make a database on PostgreSQL at {at}: {error}"))?;
                Ok((Database::Postgres(url), format!("{durability}, one advisory-locked writer batch at a time")))
            }
        }
    })?;
    let measured = measure(&config, &server_runtime, &database, &data_dir, &studies_dir);
    server_runtime.shutdown_timeout(Duration::from_secs(5));
    if let (Backing::Postgres { server_url }, Database::Postgres(url)) = (&config.database, &database) {
        let dropping = two_thread_runtime("cleanup")?;
        dropping
            .block_on(storage::drop_postgres_database(server_url, url))
            .map_err(|error| format!("cannot drop the benchmark's database {}: {error}", redacted(url)))?;
    }
    let (tally, seconds, wal_largest) = measured?;

    let mut response_ms = tally.response_ms;
    response_ms.sort_by(f64::total_cmp);
    let mut next_ms = tally.next_ms;
    next_ms.sort_by(f64::total_cmp);
    Ok(BenchReport {
        bench: "server",
        database: config.database.name(),
        processes: config.processes,
        participants: config.participants,
        ms: nearest_rank(&response_ms, 0.50),
        seconds,
        responses: response_ms.len() as u64,
        responses_per_s: response_ms.len() as f64 / seconds,
        response_p50_ms: nearest_rank(&response_ms, 0.50),
        response_p90_ms: nearest_rank(&response_ms, 0.90),
        response_p99_ms: nearest_rank(&response_ms, 0.99),
        response_max_ms: response_ms.last().copied().unwrap_or(0.0),
        next_p50_ms: nearest_rank(&next_ms, 0.50),
        next_p99_ms: nearest_rank(&next_ms, 0.99),
        joins: tally.joins,
        errors: tally.errors,
        exports: config.exports,
        exports_done: tally.exports_done,
        wal_max_mb: wal_largest.map(|bytes| bytes as f64 / (1024.0 * 1024.0)),
        data_dir: data_dir.display().to_string(),
        durability,
    })
}

/// A URL without its password, for messages.
fn redacted(url: &str) -> String {
    Database::Postgres(url.to_string()).describe()
}

/// Starts the servers, drives them with the simulated participants for the measured time and
/// returns the tally, the measured seconds and (sqlite) the largest WAL in bytes.
fn measure(
    config: &BenchConfig,
    server_runtime: &tokio::runtime::Runtime,
    database: &Database,
    data_dir: &Path,
    studies_dir: &Path,
) -> Result<(Tally, f64, Option<u64>), String> {
    let servers = match database {
        Database::Postgres(url) if config.processes > 1 => {
            let mut servers = Servers { bases: Vec::new(), admin_token: String::new(), children: Vec::new() };
            // one after another, so that the first has migrated the new database
            for _ in 0..config.processes {
                let (child, base, token) = spawn_server(data_dir, studies_dir, url)?;
                servers.children.push(child);
                servers.bases.push(base);
                servers.admin_token = token;
            }
            servers
        }
        _ => server_runtime.block_on(async {
            let prepared = prepare_on(database, data_dir, studies_dir).await.map_err(|error| error.to_string())?;
            let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.map_err(|error| error.to_string())?;
            let address = listener.local_addr().map_err(|error| error.to_string())?;
            // the server's own connection loop; every participant comes from 127.0.0.1: no limits
            let no_limits =
                mrstudy_server::limits::Limits { joins_per_minute: 0, responses_per_minute: 0, ..Default::default() };
            let app = mrstudy_server::app(prepared.state.with_limits(no_limits));
            tokio::spawn(mrstudy_server::serve::serve_connections(
                listener,
                app,
                mrstudy_server::serve::Connections::default(),
                std::future::pending(),
            ));
            Ok::<_, String>(Servers {
                bases: vec![format!("http://{address}")],
                admin_token: prepared.admin_token,
                children: Vec::new(),
            })
        })?,
    };
    // the WAL's size, sampled until the run ends
    let sampling = Arc::new(AtomicBool::new(true));
    let sampler = matches!(database, Database::Sqlite(_)).then(|| {
        let sampling = sampling.clone();
        let wal = data_dir.join("mrstudy.db-wal");
        std::thread::spawn(move || {
            let mut largest = 0u64;
            while sampling.load(Ordering::Relaxed) {
                largest = largest.max(std::fs::metadata(&wal).map(|meta| meta.len()).unwrap_or(0));
                std::thread::sleep(Duration::from_millis(50));
            }
            largest
        })
    });

    let client_runtime = two_thread_runtime("client")?;
    let bases = Arc::new(servers.bases.clone());
    let admin_token = servers.admin_token.clone();
    let (participants, exports, duration) = (config.participants, config.exports, config.duration);
    let measured = client_runtime.block_on(async move {
        let client = reqwest::Client::builder()
            .pool_max_idle_per_host(participants)
            .build()
            .map_err(|error| error.to_string())?;
        let measuring = Arc::new(AtomicBool::new(false));
        let stop = Arc::new(AtomicBool::new(false));
        let mut tasks = Vec::new();
        for first in 0..participants {
            let client = client.clone();
            let bases = Rotation::new(&bases, first);
            let measuring = measuring.clone();
            let stop = stop.clone();
            tasks.push(tokio::spawn(async move { simulate(client, bases, measuring, stop).await }));
        }
        let mut exporters = Vec::new();
        for first in 0..exports {
            let (client, mut bases, token) = (client.clone(), Rotation::new(&bases, first), admin_token.clone());
            let (measuring, stop) = (measuring.clone(), stop.clone());
            exporters.push(tokio::spawn(async move {
                let mut done = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    let export = client
                        .get(format!("{}/api/admin/studies/bench/export.csv", bases.next()))
                        .bearer_auth(&token)
                        .send()
                        .await;
                    if let Ok(export) = export
                        && export.status().is_success()
                        && export.bytes().await.is_ok()
                        && measuring.load(Ordering::Relaxed)
                    {
                        done += 1;
                    }
                }
                done
            }));
        }
        tokio::time::sleep(Duration::from_secs(1)).await;
        measuring.store(true, Ordering::SeqCst);
        let start = Instant::now();
        tokio::time::sleep(duration).await;
        measuring.store(false, Ordering::SeqCst);
        let seconds = start.elapsed().as_secs_f64();
        stop.store(true, Ordering::SeqCst);
        let mut total = Tally::default();
        for task in tasks {
            let tally = task.await.map_err(|error| error.to_string())?;
            total.response_ms.extend(tally.response_ms);
            total.next_ms.extend(tally.next_ms);
            total.joins += tally.joins;
            total.errors += tally.errors;
        }
        for exporter in exporters {
            total.exports_done += exporter.await.map_err(|error| error.to_string())?;
        }
        Ok::<_, String>((total, seconds))
    });
    drop(client_runtime);
    sampling.store(false, Ordering::Relaxed);
    let wal_largest = sampler.map(|sampler| sampler.join().unwrap_or(0));
    drop(servers);
    let (tally, seconds) = measured?;
    Ok((tally, seconds, wal_largest))
}

/// The servers' base URLs in turn, starting at one of them: each participant's next request
/// goes to the next server.
struct Rotation {
    bases: Arc<Vec<String>>,
    at: usize,
}

impl Rotation {
    fn new(bases: &Arc<Vec<String>>, first: usize) -> Rotation {
        Rotation { bases: bases.clone(), at: first }
    }

    fn next(&mut self) -> &str {
        let base = &self.bases[self.at % self.bases.len()];
        self.at += 1;
        base
    }
}

async fn simulate(
    client: reqwest::Client,
    mut bases: Rotation,
    measuring: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
) -> Tally {
    let mut tally = Tally::default();
    let mut choice = 0u64;
    'participants: while !stop.load(Ordering::Relaxed) {
        let joined = client
            .post(format!("{}/api/studies/bench/participants", bases.next()))
            .json(&json!({"demographics": {"gender": "female", "age": 30}, "client": {"viewport": [1280, 800]}}))
            .send()
            .await;
        let Ok(joined) = joined else {
            tally.errors += 1;
            continue;
        };
        if joined.status() != reqwest::StatusCode::CREATED {
            tally.errors += 1;
            continue;
        }
        let Ok(joined) = joined.json::<serde_json::Value>().await else {
            tally.errors += 1;
            continue;
        };
        if measuring.load(Ordering::Relaxed) {
            tally.joins += 1;
        }
        let id = joined["participant"].as_str().unwrap_or_default().to_string();
        let token = joined["token"].as_str().unwrap_or_default().to_string();
        loop {
            if stop.load(Ordering::Relaxed) {
                break 'participants;
            }
            let started = Instant::now();
            let next =
                client.get(format!("{}/api/participants/{id}/next", bases.next())).bearer_auth(&token).send().await;
            let next = match next {
                Ok(next) if next.status().is_success() => next.json::<serde_json::Value>().await,
                _ => {
                    tally.errors += 1;
                    continue 'participants;
                }
            };
            let next_ms = started.elapsed().as_secs_f64() * 1e3;
            let Ok(next) = next else {
                tally.errors += 1;
                continue 'participants;
            };
            if next["done"] == true {
                continue 'participants;
            }
            if measuring.load(Ordering::Relaxed) {
                tally.next_ms.push(next_ms);
            }
            choice = choice.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let started = Instant::now();
            let stored = client
                .post(format!("{}/api/participants/{id}/responses", bases.next()))
                .bearer_auth(&token)
                .json(&json!({"trial": next["trial"], "chosen": if choice >> 63 == 1 { "left" } else { "right" }, "rt_ms": 900.0}))
                .send()
                .await;
            let response_ms = started.elapsed().as_secs_f64() * 1e3;
            match stored {
                Ok(stored) if stored.status() == reqwest::StatusCode::CREATED => {
                    let _ = stored.bytes().await;
                    if measuring.load(Ordering::Relaxed) {
                        tally.response_ms.push(response_ms);
                    }
                }
                _ => {
                    tally.errors += 1;
                    continue 'participants;
                }
            }
        }
    }
    tally
}
