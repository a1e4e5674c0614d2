//! Issue 46's connection guards of `serve_connections`, on real loopback sockets: a request
//! body that trickles in is cut off at its deadline however often its bytes come, a whole
//! request (slow headers, then a slow body) at `--request-timeout`, a client that never reads
//! its response is closed after `--write-timeout` (or, when the response fit in the socket's
//! buffers, once idle for `--header-timeout`), connections over the cap of one address are
//! refused while another address is served, and a full server makes room for a newcomer by
//! closing a connection of the address holding the most.
//!
//! `slow_body_attack_under_load` (ignored: it holds 2 000 connections for about 40 s) is the
//! measurement of docs/server.md; `scripts/slow-body.sh` runs it.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use mrstudy_server::limits::Limits;
use mrstudy_server::serve::{Connections, serve_connections};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

mod support;
use support::{Started, demo_studies, start_limited};

/// A server of the demo study on a free loopback port with `connections`, and no limits per
/// address on joins and answers (the slow clients below join, and must reach the body).
struct Served {
    address: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    _data_dir: tempfile::TempDir,
}

impl Drop for Served {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
    }
}

async fn serve_demo(connections: Connections) -> Served {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = demo_studies(data_dir.path(), |text| text);
    let limits = Limits { joins_per_minute: 0, responses_per_minute: 0, ..Limits::default() };
    let Started { app, .. } = start_limited(data_dir.path(), &studies, Some(limits)).await;
    serve_router(app, connections, data_dir).await
}

async fn serve_router(router: axum::Router, connections: Connections, data_dir: tempfile::TempDir) -> Served {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    tokio::spawn(serve_connections(listener, router, connections, async {
        let _ = stopped.await;
    }));
    Served { address, stop: Some(stop), _data_dir: data_dir }
}

/// A connection to `server` from the loopback address `from` (127.0.0.x).
async fn connect_from(from: &str, server: SocketAddr) -> TcpStream {
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.bind(format!("{from}:0").parse().unwrap()).unwrap();
    socket.connect(server).await.unwrap()
}

/// Reads until the server closes the connection or `limit` passes: what came, and whether it
/// was closed.
async fn read_until_closed(stream: &mut TcpStream, limit: Duration) -> (Vec<u8>, bool) {
    let mut received = Vec::new();
    let mut buffer = vec![0u8; 64 * 1024];
    let deadline = tokio::time::Instant::now() + limit;
    loop {
        match tokio::time::timeout_at(deadline, stream.read(&mut buffer)).await {
            Err(_) => return (received, false),
            Ok(Ok(0)) | Ok(Err(_)) => return (received, true),
            Ok(Ok(n)) => received.extend_from_slice(&buffer[..n]),
        }
    }
}

/// `GET /api/studies` on a new connection from `from`: the status line.
async fn studies_status(from: &str, server: SocketAddr) -> String {
    let mut stream = connect_from(from, server).await;
    stream.write_all(b"GET /api/studies HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").await.unwrap();
    let (received, _) = read_until_closed(&mut stream, Duration::from_secs(10)).await;
    String::from_utf8_lossy(&received).lines().next().unwrap_or_default().to_string()
}

const SLOW_JOIN: &[u8] = b"POST /api/studies/shadows-demo/participants HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 16000\r\n\r\n";

/// Sends `SLOW_JOIN` and then 10 bytes every `every` until the server closes the connection;
/// how long it was kept, or None if it was still open after `limit`.
async fn trickle(mut stream: TcpStream, every: Duration, limit: Duration) -> Option<Duration> {
    let started = Instant::now();
    if stream.write_all(SLOW_JOIN).await.is_err() {
        return Some(started.elapsed());
    }
    let (mut reader, mut writer) = stream.split();
    let writing = async {
        loop {
            tokio::time::sleep(every).await;
            if writer.write_all(b"{\"demograp").await.is_err() {
                return;
            }
        }
    };
    let reading = async {
        let mut buffer = [0u8; 4096];
        loop {
            match reader.read(&mut buffer).await {
                Ok(0) | Err(_) => return,
                Ok(_) => {}
            }
        }
    };
    tokio::select! {
        _ = writing => {}
        _ = reading => {}
        _ = tokio::time::sleep(limit) => return None,
    }
    Some(started.elapsed())
}

/// A body of 10 bytes every 300 ms never waits a second for its next bytes, so a timeout that
/// restarts at every chunk (tower-http's `TimeoutBody`, as `--body-timeout` was) never fires; the
/// whole body's deadline does. Fails on the code before issue 46 (kept past 10 s).
#[tokio::test]
async fn a_body_that_trickles_in_is_cut_off_at_its_deadline() {
    let connections = Connections { body_timeout: Duration::from_secs(2), ..Connections::default() };
    let server = serve_demo(connections).await;
    let stream = connect_from("127.0.0.1", server.address).await;
    let kept = trickle(stream, Duration::from_millis(300), Duration::from_secs(10)).await;
    let kept = kept.expect("the slow body was still open after 10 s");
    assert!(kept >= Duration::from_millis(1800) && kept < Duration::from_secs(4), "kept for {kept:?}");
    assert_eq!(studies_status("127.0.0.1", server.address).await, "HTTP/1.1 200 OK");
}

/// The whole request, headers and body together, by `--request-timeout` from the connection's
/// start: headers sent slowly (each line within the header timeout) and then a slow body are
/// cut off at the request's deadline, not the body's own.
#[tokio::test]
async fn slow_headers_then_a_slow_body_are_cut_off_at_the_whole_requests_deadline() {
    let connections = Connections {
        header_timeout: Duration::from_secs(20),
        body_timeout: Duration::from_secs(20),
        request_timeout: Duration::from_secs(3),
        ..Connections::default()
    };
    let server = serve_demo(connections).await;
    let mut stream = connect_from("127.0.0.1", server.address).await;
    let started = Instant::now();
    let (head, end) = SLOW_JOIN.split_at(SLOW_JOIN.len() - 2);
    for line in head.split_inclusive(|byte| *byte == b'\n') {
        stream.write_all(line).await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    stream.write_all(end).await.unwrap();
    let closed = trickle_after_headers(stream, Duration::from_millis(300), Duration::from_secs(10)).await;
    assert!(closed.is_some(), "the slow request was still open after {:?}", started.elapsed());
    let kept = started.elapsed();
    assert!(kept >= Duration::from_millis(2800) && kept < Duration::from_secs(5), "kept for {kept:?}");
}

/// [`trickle`] for a connection whose headers are already sent.
async fn trickle_after_headers(mut stream: TcpStream, every: Duration, limit: Duration) -> Option<Duration> {
    let started = Instant::now();
    let (mut reader, mut writer) = stream.split();
    let writing = async {
        loop {
            if writer.write_all(b"{\"demograp").await.is_err() {
                return;
            }
            tokio::time::sleep(every).await;
        }
    };
    let reading = async {
        let mut buffer = [0u8; 4096];
        while let Ok(n) = reader.read(&mut buffer).await {
            if n == 0 {
                return;
            }
        }
    };
    tokio::select! {
        _ = writing => {}
        _ = reading => {}
        _ = tokio::time::sleep(limit) => return None,
    }
    Some(started.elapsed())
}

/// A client that asks for 32 MB and reads nothing is closed after `--write-timeout`: when it
/// finally reads, the response stops short. Fails on the code before issue 46 (the server waited
/// for it as long as it liked, and the whole body came).
#[tokio::test]
async fn a_client_that_never_reads_is_closed_after_the_write_timeout() {
    const SIZE: usize = 32 << 20;
    let router = axum::Router::new().route("/big", axum::routing::get(|| async { vec![b'x'; SIZE] }));
    let connections = Connections { write_timeout: Duration::from_secs(1), ..Connections::default() };
    let server = serve_router(router, connections, tempfile::tempdir().unwrap()).await;
    let mut stream = connect_from("127.0.0.1", server.address).await;
    stream.write_all(b"GET /big HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
    tokio::time::sleep(Duration::from_secs(3)).await;
    let (received, closed) = read_until_closed(&mut stream, Duration::from_secs(10)).await;
    assert!(closed, "still open");
    assert!(
        received.starts_with(b"HTTP/1.1 200"),
        "{:?}",
        String::from_utf8_lossy(&received[..received.len().min(64)])
    );
    assert!(received.len() < SIZE, "the whole response came ({} bytes): the server waited", received.len());
}

/// A client that sends a request and never reads the (small) answer, which the socket's buffers
/// take whole, is closed once it has been idle for `--header-timeout` after that response. (This
/// held before issue 46 too, by hyper's header timeout; kept so the watchdog cannot lose it.)
#[tokio::test]
async fn a_client_idle_after_its_response_is_closed_after_the_header_timeout() {
    let connections = Connections { header_timeout: Duration::from_secs(1), ..Connections::default() };
    let server = serve_demo(connections).await;
    let mut stream = connect_from("127.0.0.1", server.address).await;
    stream.write_all(b"GET /api/studies HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
    let started = Instant::now();
    tokio::time::sleep(Duration::from_millis(2500)).await;
    let (received, closed) = read_until_closed(&mut stream, Duration::from_secs(5)).await;
    assert!(received.starts_with(b"HTTP/1.1 200"), "{}", String::from_utf8_lossy(&received));
    assert!(closed && started.elapsed() < Duration::from_secs(4), "still open after {:?}", started.elapsed());
}

/// Over `--max-connections-per-address`, a connection from that address is refused (503 with a
/// sentence, then closed) while another address is served; a connection that closes frees its
/// place.
#[tokio::test]
async fn connections_over_the_cap_of_one_address_are_refused_while_another_is_served() {
    let connections = Connections { max_connections_per_address: 3, ..Connections::default() };
    let server = serve_demo(connections).await;
    let mut held = Vec::new();
    for _ in 0..3 {
        held.push(connect_from("127.0.0.3", server.address).await);
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut over = connect_from("127.0.0.3", server.address).await;
    let (received, closed) = read_until_closed(&mut over, Duration::from_secs(5)).await;
    let received = String::from_utf8_lossy(&received).into_owned();
    assert!(closed, "the fourth connection of the address was kept");
    assert!(
        received.starts_with("HTTP/1.1 503") && received.contains("Too many connections from this address"),
        "{received}"
    );
    assert_eq!(studies_status("127.0.0.4", server.address).await, "HTTP/1.1 200 OK", "another address is served");
    drop(held.pop());
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(studies_status("127.0.0.3", server.address).await, "HTTP/1.1 200 OK", "a freed place is taken");
}

/// A full server (`--max-connections`) takes a newcomer from another address by closing the
/// oldest connection of the address holding the most. Fails on the code before issue 46 (the
/// newcomer waited in the listen queue until a connection ended: here, the header timeout).
#[tokio::test]
async fn a_full_server_makes_room_for_another_address() {
    let connections = Connections { max_connections: 4, max_connections_per_address: 0, ..Connections::default() };
    let server = serve_demo(connections).await;
    let mut flood = Vec::new();
    for _ in 0..4 {
        flood.push(connect_from("127.0.0.5", server.address).await);
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let started = Instant::now();
    let status = tokio::time::timeout(Duration::from_secs(5), studies_status("127.0.0.6", server.address)).await;
    assert_eq!(status.as_deref().ok(), Some("HTTP/1.1 200 OK"), "after {:?}", started.elapsed());
    let (_, closed) = read_until_closed(&mut flood[0], Duration::from_secs(2)).await;
    assert!(closed, "the flood's oldest connection made room");
}

/// The measurement of docs/server.md (`scripts/slow-body.sh`): `SLOW_CONNECTIONS` (default
/// 2 000) connections from `SLOW_ADDRESSES` (default 20) loopback addresses each send a join
/// with `Content-Length: 16000` and then 10 bytes every 2 s; meanwhile a control client from
/// 127.0.0.1 asks `GET /api/studies` on a new connection every 20 ms. Prints the control
/// client's latencies and how long the slow connections were kept, and asserts that every one
/// was closed within the deadline (`--request-timeout`, default 30 s, plus 1 s) or refused.
#[test]
#[ignore = "a measurement: holds 2 000 connections for about 40 s (scripts/slow-body.sh)"]
fn slow_body_attack_under_load() {
    let count: usize = std::env::var("SLOW_CONNECTIONS").ok().and_then(|n| n.parse().ok()).unwrap_or(2000);
    let addresses: usize = std::env::var("SLOW_ADDRESSES").ok().and_then(|n| n.parse().ok()).unwrap_or(20);
    let connections = Connections::default();
    let deadline = connections.request_timeout;
    // the server on a runtime of its own, two workers as on a small machine
    let (ready, address) = std::sync::mpsc::channel();
    let server = std::thread::spawn(move || {
        let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
        runtime.block_on(async {
            let served = serve_demo(connections).await;
            ready.send(served.address).unwrap();
            tokio::time::sleep(deadline + Duration::from_secs(20)).await;
            drop(served);
        });
    });
    let address = address.recv().unwrap();
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(1).enable_all().build().unwrap();
    let (kept, latencies, refused) = runtime.block_on(async move {
        let opened = Instant::now();
        let mut slow = tokio::task::JoinSet::new();
        for n in 0..count {
            let from = format!("127.0.0.{}", 2 + n % addresses);
            slow.spawn(async move {
                let stream = connect_from(&from, address).await;
                trickle(stream, Duration::from_secs(2), deadline + Duration::from_secs(10)).await
            });
            if n % 100 == 99 {
                tokio::task::yield_now().await;
            }
        }
        eprintln!("{count} slow connections opened in {:?}", opened.elapsed());
        let control = tokio::spawn(async move {
            let mut latencies = Vec::new();
            let until = Instant::now() + deadline + Duration::from_secs(2);
            while Instant::now() < until {
                let started = Instant::now();
                let status = studies_status("127.0.0.1", address).await;
                assert_eq!(status, "HTTP/1.1 200 OK");
                latencies.push(started.elapsed());
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            latencies
        });
        let mut kept = Vec::new();
        let mut refused = 0;
        while let Some(result) = slow.join_next().await {
            match result.unwrap() {
                Some(time) if time < Duration::from_millis(500) => refused += 1,
                time => kept.push(time),
            }
        }
        (kept, control.await.unwrap(), refused)
    });
    server.join().unwrap();
    let mut latencies = latencies;
    latencies.sort();
    let quantile = |q: f64| latencies[((latencies.len() - 1) as f64 * q).round() as usize];
    let still_open = kept.iter().filter(|time| time.is_none()).count();
    let longest = kept.iter().flatten().max().copied().unwrap_or_default();
    eprintln!(
        "control GET /api/studies: {} requests, p50 {:?}, p99 {:?}, max {:?}",
        latencies.len(),
        quantile(0.5),
        quantile(0.99),
        latencies.last().unwrap()
    );
    eprintln!(
        "slow connections: {} held, closed after at most {longest:?} (deadline {deadline:?}), {still_open} still open, {refused} refused at once",
        kept.len()
    );
    assert_eq!(still_open, 0);
    assert!(longest <= deadline + Duration::from_secs(1), "a slow connection was kept {longest:?}");
}
