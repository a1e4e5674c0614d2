//! The load generator behind `mrstudy bench server`: drives the API of
//! `mrstudy-server` from loopback with many concurrent simulated participants and measures
//! responses per second and response latency, with the durable writes of a real server (WAL,
//! `synchronous = FULL`, group commit). [`run`] measures one concurrency, [`bench()`] the table
//! of DESIGN.md's bench (a typed [`Report`], its JSON by [`Report::to_json`]).
//!
//! In the bench crate so that its HTTP client and temporary directories are not dependencies
//! of the server.
//!
//! The server runs in this process on its own tokio runtime (two worker threads) on a fresh
//! data directory under `$TMPDIR`, serving a synthetic study shaped like the thesis survey
//! (8 conditions, 13 anchored pairs × 5 = 65 trials, 6 scene configurations, tiny images). The
//! simulated participants run on a second runtime and talk HTTP/1.1 over loopback: each joins,
//! then loops `GET next` → `POST response` (no think time) until its 65 trials are done, then
//! joins again, until the measured time is up. Only responses answered 201 count.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use serde::Serialize;
use serde_json::json;

use mrstudy_server::serve::prepare;

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
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig { participants: 64, duration: Duration::from_secs(10), exports: 0 }
    }
}

/// The measurements at one concurrency: a row of the bench JSON.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// Always `server`.
    pub bench: &'static str,
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
    /// The largest the WAL file was, sampled every 50 ms, in MB.
    pub wal_max_mb: f64,
    /// Where the database was (its file system decides what an fsync costs).
    pub data_dir: String,
    pub durability: &'static str,
}

/// `mrstudy bench server`: the rows (one per concurrency) and the adapter line of the bench JSON.
#[derive(Debug, Clone)]
pub struct Report {
    pub adapter: String,
    pub rows: Vec<BenchReport>,
}

impl Report {
    /// DESIGN.md's bench JSON: `{ "adapter": …, "rows": [...] }`.
    pub fn to_json(&self) -> serde_json::Value {
        json!({ "adapter": self.adapter, "rows": self.rows })
    }
}

/// The benchmark: 16, 64 and 256 participants for 10 s each, then 16 and 64 beside 8 admin
/// export loops (`quick`: 64 for 3 s); table lines
/// go to `line` as the rows are measured.
pub fn bench(quick: bool, line: &dyn Fn(&str)) -> Result<Report, String> {
    let seconds = if quick { 3 } else { 10 };
    let concurrency: &[(usize, usize)] =
        if quick { &[(64, 0)] } else { &[(16, 0), (64, 0), (256, 0), (16, 8), (64, 8)] };
    line(&format!(
        "{:>12} {:>7} {:>8} {:>11} {:>9} {:>9} {:>9} {:>9} {:>10} {:>7} {:>8}",
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
        let row = run(BenchConfig { participants, duration: Duration::from_secs(seconds), exports })?;
        line(&format!(
            "{:>12} {:>7} {:>8.1} {:>11.0} {:>9.2} {:>9.2} {:>9.2} {:>9.2} {:>10.2} {:>7} {:>8.1}",
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
            row.wal_max_mb
        ));
        rows.push(row);
    }
    Ok(Report { adapter: "none (server: HTTP/1.1 over loopback, sqlite on the local file system)".into(), rows })
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

fn percentile(sorted: &[f64], quantile: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = ((quantile * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
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

/// Runs the benchmark (blocking).
pub fn run(config: BenchConfig) -> Result<BenchReport, String> {
    let work = tempfile::Builder::new()
        .prefix("mrstudy-bench-")
        .tempdir()
        .map_err(|error| format!("cannot create a temporary directory: {error}"))?;
    let studies_dir = work.path().join("studies");
    let data_dir = work.path().join("data");
    write_bench_study(&studies_dir).map_err(|error| format!("cannot write the bench study: {error}"))?;

    let server_runtime = two_thread_runtime("server")?;
    let (address, admin_token) = server_runtime.block_on(async {
        let prepared = prepare(&data_dir, &studies_dir).await.map_err(|error| error.to_string())?;
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
        Ok::<_, String>((address, prepared.admin_token))
    })?;
    // the WAL's size, sampled until the run ends
    let sampling = Arc::new(AtomicBool::new(true));
    let sampler = {
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
    };

    let client_runtime = two_thread_runtime("client")?;
    let base = format!("http://{address}");
    let (tally, seconds) = client_runtime.block_on(async move {
        let client = reqwest::Client::builder()
            .pool_max_idle_per_host(config.participants)
            .build()
            .map_err(|error| error.to_string())?;
        let measuring = Arc::new(AtomicBool::new(false));
        let stop = Arc::new(AtomicBool::new(false));
        let mut tasks = Vec::new();
        for _ in 0..config.participants {
            let client = client.clone();
            let base = base.clone();
            let measuring = measuring.clone();
            let stop = stop.clone();
            tasks.push(tokio::spawn(async move { simulate(client, base, measuring, stop).await }));
        }
        let mut exporters = Vec::new();
        for _ in 0..config.exports {
            let (client, base, token) = (client.clone(), base.clone(), admin_token.clone());
            let (measuring, stop) = (measuring.clone(), stop.clone());
            exporters.push(tokio::spawn(async move {
                let mut done = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    let export = client
                        .get(format!("{base}/api/admin/studies/bench/export.csv"))
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
        tokio::time::sleep(config.duration).await;
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
    })?;
    drop(client_runtime);
    sampling.store(false, Ordering::Relaxed);
    let wal_largest = sampler.join().unwrap_or(0);
    server_runtime.shutdown_timeout(Duration::from_secs(5));

    let mut response_ms = tally.response_ms;
    response_ms.sort_by(f64::total_cmp);
    let mut next_ms = tally.next_ms;
    next_ms.sort_by(f64::total_cmp);
    Ok(BenchReport {
        bench: "server",
        participants: config.participants,
        ms: percentile(&response_ms, 0.50),
        seconds,
        responses: response_ms.len() as u64,
        responses_per_s: response_ms.len() as f64 / seconds,
        response_p50_ms: percentile(&response_ms, 0.50),
        response_p90_ms: percentile(&response_ms, 0.90),
        response_p99_ms: percentile(&response_ms, 0.99),
        response_max_ms: response_ms.last().copied().unwrap_or(0.0),
        next_p50_ms: percentile(&next_ms, 0.50),
        next_p99_ms: percentile(&next_ms, 0.99),
        joins: tally.joins,
        errors: tally.errors,
        exports: config.exports,
        exports_done: tally.exports_done,
        wal_max_mb: wal_largest as f64 / (1024.0 * 1024.0),
        data_dir: data_dir.display().to_string(),
        durability: "sqlite WAL, synchronous=FULL, group commit",
    })
}

async fn simulate(client: reqwest::Client, base: String, measuring: Arc<AtomicBool>, stop: Arc<AtomicBool>) -> Tally {
    let mut tally = Tally::default();
    let mut choice = 0u64;
    'participants: while !stop.load(Ordering::Relaxed) {
        let joined = client
            .post(format!("{base}/api/studies/bench/participants"))
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
            let next = client.get(format!("{base}/api/participants/{id}/next")).bearer_auth(&token).send().await;
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
                .post(format!("{base}/api/participants/{id}/responses"))
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
