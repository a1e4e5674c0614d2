//! Issue 46, item 7: the request log (one line per request with method, route template, status,
//! latency and caller, never a token, an id of the path or the query string) and the refusals
//! counted per kind (status and route template) for the admin page and `GET /api/admin/refusals`.

use std::io::Write;
use std::net::IpAddr;
use std::sync::{Arc, Mutex};

use axum::Router;
use axum::body::Body;
use axum::http::{Method, Request, StatusCode, header};
use mrstudy_server::AppState;
use mrstudy_server::limits::{ClientAddr, Limits};
use mrstudy_server::logs::{DEFAULT_FILTER, LogFormat, Refusal};
use serde_json::{Value, json};

mod support;
use support::{Started, call, demo_studies, demographics, send, start_limited};

struct Fixture {
    app: Router,
    state: AppState,
    admin_token: String,
    _data_dir: tempfile::TempDir,
}

async fn fixture(limits: Limits) -> Fixture {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = demo_studies(data_dir.path(), |text| text);
    let Started { app, state, admin_token, .. } = start_limited(data_dir.path(), &studies, Some(limits)).await;
    Fixture { app, state, admin_token, _data_dir: data_dir }
}

async fn join(app: &Router) -> (String, String) {
    let body = json!({"demographics": demographics(), "url_params": {"PROLIFIC_PID": "pid-in-the-url"}});
    let (id, token, _) = support::join(app, "shadows-demo", body).await;
    (id, token)
}

/// The log's output, kept in memory.
#[derive(Clone, Default)]
struct Buffer(Arc<Mutex<Vec<u8>>>);

impl Buffer {
    fn text(&self) -> String {
        String::from_utf8(self.0.lock().unwrap().clone()).unwrap()
    }
}

impl Write for Buffer {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(bytes);
        Ok(bytes.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl<'writer> tracing_subscriber::fmt::MakeWriter<'writer> for Buffer {
    type Writer = Buffer;
    fn make_writer(&'writer self) -> Buffer {
        self.clone()
    }
}

/// `GET /api/participants/{id}/next` with the token in the header and in the query string, as
/// the log (default filter, `format`) writes it: the lines about requests, and all its text.
async fn logged_next_trial(format: LogFormat) -> (Vec<String>, String, String, String) {
    let fixture = fixture(Limits::default()).await;
    let (id, token) = join(&fixture.app).await;
    let buffer = Buffer::default();
    let subscriber = mrstudy_server::logs::subscriber(
        format,
        tracing_subscriber::EnvFilter::new(DEFAULT_FILTER),
        buffer.clone(),
        false,
    );
    // this test's runtime has one thread: the request is served on it, under this subscriber
    let answer = {
        let _guard = tracing::subscriber::set_default(subscriber);
        let request = Request::builder()
            .uri(format!("/api/participants/{id}/next?token={token}&PROLIFIC_PID=pid-in-the-url"))
            .header(header::AUTHORIZATION, format!("Bearer {token}"))
            .body(Body::empty())
            .unwrap();
        send(&fixture.app, request).await
    };
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    let text = buffer.text();
    let lines = text.lines().filter(|line| line.contains("answered")).map(str::to_string).collect();
    (lines, text, id, token)
}

/// No token, participant id, query string or personal datum of the request is in the log.
fn assert_nothing_personal(text: &str, id: &str, token: &str) {
    assert!(!text.contains(token), "the token is in the log:\n{text}");
    assert!(!text.contains(&token[..16]), "part of the token is in the log:\n{text}");
    assert!(!text.contains(id), "the participant id of the path is in the log:\n{text}");
    assert!(!text.contains("pid-in-the-url") && !text.contains("PROLIFIC_PID"), "the query is in the log:\n{text}");
}

#[tokio::test]
async fn a_request_makes_one_json_line_with_method_route_status_latency_and_caller_and_no_token() {
    let (lines, text, id, token) = logged_next_trial(LogFormat::Json).await;
    assert_eq!(lines.len(), 1, "one line per request:\n{text}");
    let line: Value = serde_json::from_str(&lines[0]).unwrap_or_else(|_| panic!("not JSON: {}", lines[0]));
    assert_eq!(line["level"], "INFO", "{line}");
    assert_eq!(line["span"]["method"], "GET", "{line}");
    assert_eq!(line["span"]["route"], "/api/participants/{id}/next", "{line}");
    assert_eq!(line["span"]["caller"], "participant", "{line}");
    assert_eq!(line["status"], 200, "{line}");
    let latency = line["latency_ms"].as_f64().unwrap_or_else(|| panic!("no latency_ms: {line}"));
    assert!(latency > 0.0 && latency < 60_000.0, "{line}");
    assert_nothing_personal(&text, &id, &token);
}

#[tokio::test]
async fn a_request_makes_one_text_line_with_method_route_status_latency_and_caller_and_no_token() {
    let (lines, text, id, token) = logged_next_trial(LogFormat::Text).await;
    assert_eq!(lines.len(), 1, "one line per request:\n{text}");
    let line = &lines[0];
    for part in
        ["INFO", "method=GET", "route=/api/participants/{id}/next", "caller=participant", "status=200", "latency_ms="]
    {
        assert!(line.contains(part), "{part} is not in the line: {line}");
    }
    assert_nothing_personal(&text, &id, &token);
}

/// The admin area's requests are the admin's; a join carries no credential: anonymous.
#[test]
fn the_caller_is_told_by_the_credential_it_carries() {
    use axum::http::HeaderMap;
    use mrstudy_server::logs::Caller;
    let mut bearer = HeaderMap::new();
    bearer.insert(header::AUTHORIZATION, "Bearer abc".parse().unwrap());
    let mut cookie = HeaderMap::new();
    cookie.insert(header::COOKIE, "mrstudy_admin=abc".parse().unwrap());
    let none = HeaderMap::new();
    assert_eq!(Caller::of("/api/admin/studies", &bearer, None), Caller::Admin);
    assert_eq!(Caller::of("/admin", &cookie, None), Caller::Admin);
    assert_eq!(Caller::of("/admin/login", &none, Some("token=x")), Caller::Admin);
    assert_eq!(Caller::of("/api/admin/studies", &none, None), Caller::Anonymous);
    assert_eq!(Caller::of("/api/participants/{id}/next", &bearer, None), Caller::Participant);
    assert_eq!(Caller::of("/api/studies/{slug}/participants", &none, None), Caller::Anonymous);
}

fn refusal(status: u16, route: &str, count: u64) -> Refusal {
    Refusal { status, route: route.to_string(), count }
}

#[tokio::test]
async fn refusals_are_counted_per_status_and_route_template() {
    // joins: a burst of 2 per address, then 429
    let fixture = fixture(Limits { joins_per_minute: 1, ..Limits::default() }).await;
    let app = &fixture.app;
    let (id, _) = join(app).await;
    let (other, _) = join(app).await;
    // 401 twice and 403 once on the admin list
    for _ in 0..2 {
        assert_eq!(call(app, Method::GET, "/api/admin/studies", None, None).await.status, StatusCode::UNAUTHORIZED);
    }
    let wrong = call(app, Method::GET, "/api/admin/studies", Some("wrong-token"), None).await;
    assert_eq!(wrong.status, StatusCode::FORBIDDEN);
    // a participant's call with another token, on two participants' paths: one kind
    for participant in [&id, &other] {
        let path = format!("/api/participants/{participant}/next");
        assert_eq!(call(app, Method::GET, &path, Some(&"0".repeat(64)), None).await.status, StatusCode::FORBIDDEN);
    }
    // 413: a body over the limit
    let big = json!({"demographics": demographics(), "padding": "x".repeat(mrstudy_server::BODY_LIMIT_BYTES)});
    let answer = call(app, Method::POST, "/api/studies/shadows-demo/participants", None, Some(big)).await;
    assert_eq!(answer.status, StatusCode::PAYLOAD_TOO_LARGE);
    // 429: the third join from one address in a minute
    let client: IpAddr = "192.0.2.7".parse().unwrap();
    let mut statuses = Vec::new();
    for _ in 0..3 {
        let body = json!({"demographics": demographics()});
        let mut request = Request::builder()
            .method(Method::POST)
            .uri("/api/studies/shadows-demo/participants")
            .header(header::CONTENT_TYPE, "application/json")
            .body(Body::from(body.to_string()))
            .unwrap();
        request.extensions_mut().insert(ClientAddr(client));
        statuses.push(send(app, request).await.status.as_u16());
    }
    assert_eq!(statuses, [201, 201, 429]);
    // 404 of no route: the raw path is not a kind
    assert_eq!(call(app, Method::GET, "/api/no/such/thing", None, None).await.status, StatusCode::NOT_FOUND);
    // successes are not refusals
    assert_eq!(call(app, Method::GET, "/api/studies", None, None).await.status, StatusCode::OK);

    let mut expected = vec![
        refusal(401, "/api/admin/studies", 2),
        refusal(403, "/api/admin/studies", 1),
        refusal(403, "/api/participants/{id}/next", 2),
        refusal(413, "/api/studies/{slug}/participants", 1),
        refusal(429, "/api/studies/{slug}/participants", 1),
        refusal(404, "(no route)", 1),
    ];
    expected.sort_by(|a, b| (a.status, &a.route).cmp(&(b.status, &b.route)));
    // connections refused at the door are counted per process (another test here makes one)
    let kinds: Vec<Refusal> =
        fixture.state.refusals().kinds().into_iter().filter(|kind| !kind.route.starts_with("(connection")).collect();
    assert_eq!(kinds, expected);

    // the admin's JSON and page show them
    let listed = call(app, Method::GET, "/api/admin/refusals", Some(&fixture.admin_token), None).await;
    assert_eq!(listed.status, StatusCode::OK, "{}", listed.text());
    let listed = listed.json();
    assert!(
        listed
            .as_array()
            .unwrap()
            .contains(&json!({"status": 429, "route": "/api/studies/{slug}/participants", "count": 1})),
        "{listed}"
    );
    let page = call(app, Method::GET, "/admin", Some(&fixture.admin_token), None).await;
    assert_eq!(page.status, StatusCode::OK);
    let page = page.text();
    assert!(page.contains("Refusals"), "{page}");
    assert!(
        page.contains("<td>429</td><td><code>/api/studies/{slug}/participants</code></td><td>1</td>"),
        "the admin page has no row for the 429s:\n{page}"
    );
}

/// A connection refused before any request is read (the cap per address: 503 written straight
/// to the socket) is counted too, as a kind of its own.
#[tokio::test]
async fn connections_refused_at_the_door_are_counted() {
    use mrstudy_server::serve::{Connections, serve_connections};
    use tokio::io::AsyncReadExt;
    let fixture = fixture(Limits::default()).await;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    let connections = Connections { max_connections_per_address: 1, ..Connections::default() };
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(serve_connections(listener, fixture.app.clone(), connections, async {
        let _ = stopped.await;
    }));
    let held = tokio::net::TcpStream::connect(address).await.unwrap();
    let mut over = tokio::net::TcpStream::connect(address).await.unwrap();
    let mut answer = Vec::new();
    tokio::time::timeout(std::time::Duration::from_secs(10), over.read_to_end(&mut answer)).await.unwrap().unwrap();
    assert!(answer.starts_with(b"HTTP/1.1 503"), "{}", String::from_utf8_lossy(&answer));
    let kinds = fixture.state.refusals().kinds();
    assert!(kinds.contains(&refusal(503, mrstudy_server::logs::CONNECTION_PER_ADDRESS, 1)), "{kinds:?}");
    drop(held);
    stop.send(()).unwrap();
    server.await.unwrap();
}

/// What a request line costs: `GET /api/studies` in-process, one after another, with the log on
/// (JSON and text, written to a sink) and off. Prints the time per request; run by hand.
#[tokio::test]
#[ignore]
async fn cost_of_a_request_line() {
    let fixture = fixture(Limits::default()).await;
    const REQUESTS: u32 = 4000;
    let mut timings = Vec::new();
    for (name, format, filter) in [
        ("off", LogFormat::Text, "off"),
        ("text", LogFormat::Text, DEFAULT_FILTER),
        ("json", LogFormat::Json, DEFAULT_FILTER),
        ("off again", LogFormat::Text, "off"),
    ] {
        let subscriber =
            mrstudy_server::logs::subscriber(format, tracing_subscriber::EnvFilter::new(filter), std::io::sink, false);
        let _guard = tracing::subscriber::set_default(subscriber);
        let start = std::time::Instant::now();
        for _ in 0..REQUESTS {
            assert_eq!(call(&fixture.app, Method::GET, "/api/studies", None, None).await.status, StatusCode::OK);
        }
        timings
            .push(format!("{name}: {:.1} µs per request", start.elapsed().as_secs_f64() * 1e6 / f64::from(REQUESTS)));
    }
    println!("{}", timings.join("\n"));
}
