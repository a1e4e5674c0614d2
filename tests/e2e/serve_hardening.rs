//! Issue 16 on a real socket: idle, slow-header (slowloris) and slow-body connections are closed
//! after `--header-timeout` / `--body-timeout`; a weak `MRSTUDY_ADMIN_TOKEN` stops the start with
//! one sentence; the database files are the owner's alone.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::Command;
use std::time::{Duration, Instant};

use super::support::{Server, binary, studies_dir};

/// Reads until the server closes the connection (or `limit` passes); what it sent, and when.
fn read_until_closed(stream: &mut TcpStream, limit: Duration) -> (String, Duration) {
    let started = Instant::now();
    stream.set_read_timeout(Some(limit)).unwrap();
    let mut received = Vec::new();
    let mut buffer = [0u8; 4096];
    loop {
        match stream.read(&mut buffer) {
            Ok(0) => break,
            Ok(n) => received.extend_from_slice(&buffer[..n]),
            Err(error) if error.kind() == std::io::ErrorKind::ConnectionReset => break,
            Err(error) => panic!("the server kept the connection open for {:?}: {error}", started.elapsed()),
        }
    }
    (String::from_utf8_lossy(&received).into_owned(), started.elapsed())
}

#[test]
fn idle_slow_header_and_slow_body_connections_are_closed_after_their_timeouts() {
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::try_start_with_args(
        data_dir.path(),
        "127.0.0.1:0",
        &studies_dir(),
        &[],
        &["--header-timeout", "1", "--body-timeout", "1"],
        Duration::from_secs(60),
    )
    .unwrap();
    let addr = server.base.trim_start_matches("http://").to_string();

    // idle: connects and sends nothing
    let mut idle = TcpStream::connect(&addr).unwrap();
    let (_, after) = read_until_closed(&mut idle, Duration::from_secs(10));
    assert!(after < Duration::from_secs(5), "idle connection closed after {after:?}");

    // slowloris: a header line every 400 ms, never the end of the headers
    let mut slow = TcpStream::connect(&addr).unwrap();
    slow.write_all(b"GET /api/studies HTTP/1.1\r\nHost: x\r\n").unwrap();
    let started = Instant::now();
    let mut closed = false;
    for n in 0..25 {
        std::thread::sleep(Duration::from_millis(400));
        if slow.write_all(format!("X-Slow-{n}: 1\r\n").as_bytes()).is_err() {
            closed = true;
            break;
        }
    }
    if !closed {
        let (_, _) = read_until_closed(&mut slow, Duration::from_secs(5));
    }
    assert!(started.elapsed() < Duration::from_secs(10), "slow headers kept for {:?}", started.elapsed());

    // slow body: the headers promise 100 bytes, 10 come
    let mut body = TcpStream::connect(&addr).unwrap();
    body.write_all(
        b"POST /api/studies/shadows-demo/participants HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{\"demograp",
    )
    .unwrap();
    let (answer, after) = read_until_closed(&mut body, Duration::from_secs(10));
    assert!(after < Duration::from_secs(5), "slow body kept for {after:?}");
    assert!(answer.is_empty() || answer.starts_with("HTTP/1.1 4"), "{answer}");

    // a normal request still works
    let studies: serde_json::Value =
        super::support::client().get(format!("{}/api/studies", server.base)).send().unwrap().json().unwrap();
    assert_eq!(studies[0]["slug"], "shadows-demo");
}

#[test]
fn a_weak_admin_token_stops_the_start_with_one_sentence() {
    let data_dir = tempfile::tempdir().unwrap();
    let output = Command::new(binary())
        .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
        .arg(data_dir.path())
        .arg("--studies")
        .arg(studies_dir())
        .env("MRSTUDY_ADMIN_TOKEN", "aaaaaaaaaaaaaaaa")
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("MRSTUDY_ADMIN_TOKEN is too weak") && stderr.contains("128"), "{stderr}");
}

#[cfg(unix)]
#[test]
fn the_database_and_its_wal_are_readable_by_the_owner_only() {
    use std::os::unix::fs::PermissionsExt;
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", &studies_dir()).unwrap();
    for name in ["mrstudy.db", "mrstudy.db-wal", "admin-token"] {
        let mode = std::fs::metadata(data_dir.path().join(name)).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600, "{name}: {mode:o}");
    }
    drop(server);
}
