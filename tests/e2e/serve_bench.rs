//! `mrstudy bench server` end to end: its rows on sqlite, and with two `mrstudy serve`
//! processes on one PostgreSQL database (made for the run and dropped after it).

use std::process::Command;

use super::support::{binary, temp_dir};

/// Runs `mrstudy bench server --quick` with `args`; returns its JSON.
fn bench_server(name: &str, args: &[&str]) -> serde_json::Value {
    let dir = temp_dir("bench-server", name);
    let json = dir.join("server.json");
    let output = Command::new(binary())
        .args(["bench", "server", "--quick", "--json"])
        .arg(&json)
        .args(args)
        .env_remove("MRSTUDY_DATABASE_URL")
        .output()
        .unwrap();
    assert!(output.status.success(), "bench server failed: {}", String::from_utf8_lossy(&output.stderr));
    let table = String::from_utf8_lossy(&output.stdout);
    assert!(table.contains("responses/s"), "{table}");
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

/// The one row of a quick run: participants answered, none refused.
fn check_row(report: &serde_json::Value, database: &str, processes: u64) -> serde_json::Value {
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 1, "{report}");
    let row = rows[0].clone();
    assert_eq!(row["database"], database, "{row}");
    assert_eq!(row["processes"], processes, "{row}");
    assert_eq!(row["participants"], 64, "{row}");
    assert_eq!(row["errors"], 0, "{row}");
    assert!(row["responses"].as_u64().unwrap() > 100, "{row}");
    let p50 = row["response_p50_ms"].as_f64().unwrap();
    let p99 = row["response_p99_ms"].as_f64().unwrap();
    assert!(p50 > 0.0 && p50 <= p99, "{row}");
    row
}

#[test]
fn bench_server_on_sqlite_measures_answered_responses_and_the_wal() {
    let report = bench_server("sqlite", &[]);
    let row = check_row(&report, "sqlite", 1);
    assert!(row["wal_max_mb"].as_f64().unwrap() > 0.0, "{row}");
    assert!(report["adapter"].as_str().unwrap().contains("sqlite"), "{report}");
}

#[test]
fn bench_server_refuses_two_processes_on_sqlite_with_a_sentence() {
    let output = Command::new(binary()).args(["bench", "server", "--processes", "2"]).output().unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("--processes 2 needs PostgreSQL"), "{stderr}");
}

#[test]
fn bench_server_with_two_processes_on_one_postgres_database() {
    let Ok(server) = std::env::var("MRSTUDY_TEST_POSTGRES") else {
        eprintln!("skipped: MRSTUDY_TEST_POSTGRES is not set (scripts/test.sh starts a PostgreSQL and sets it)");
        return;
    };
    let report = bench_server("postgres-2", &["--database", &server, "--processes", "2"]);
    let row = check_row(&report, "postgres", 2);
    assert!(row.get("wal_max_mb").is_none(), "{row}");
    let durability = row["durability"].as_str().unwrap();
    assert!(durability.starts_with("PostgreSQL ") && durability.contains("fsync="), "{durability}");
    // the benchmark's own database is gone
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    let left: i64 = runtime.block_on(async {
        use sqlx::Connection as _;
        let mut connection = sqlx::PgConnection::connect(&server).await.unwrap();
        sqlx::query_scalar("SELECT count(*) FROM pg_database WHERE datname LIKE 'mrstudy\\_bench\\_%'")
            .fetch_one(&mut connection)
            .await
            .unwrap()
    });
    assert_eq!(left, 0, "the benchmark left its database on the server");
}
