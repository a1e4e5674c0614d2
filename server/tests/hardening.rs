//! Issue 16's hardening, at the router (`oneshot`, a client address put on each request as
//! `serve` does): strict JSON object bodies, `{"error": …}` for every `/api/` error without the
//! server's type names, the bearer scheme in any case, limits per client address on joining,
//! answering and wrong admin tokens (429 with a sentence), admin sessions (the cookie holds a
//! random session id, never the token; logout; `Secure` behind TLS), spreadsheet formulas
//! neutralised in the export, and the strength rule for an admin token set by hand.

use std::net::IpAddr;

use axum::Router;
use axum::body::Body;
use axum::http::{Method, Request, StatusCode, header};
use mrstudy_server::auth::admin_token_strength;
use mrstudy_server::limits::{ClientAddr, Limits};
use mrstudy_server::serve::{Prepared, prepare_on};
use serde_json::{Value, json};

mod support;
use support::{
    Answer, Started, admin_session_cookie, call, copy_demo_study, demo_studies, demographics, send, start,
    start_limited, test_database,
};

struct Fixture {
    app: Router,
    admin_token: String,
    _data_dir: tempfile::TempDir,
}

async fn fixture(limits: Option<Limits>) -> Fixture {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = demo_studies(data_dir.path(), |text| text);
    let Started { app, admin_token, .. } = start_limited(data_dir.path(), &studies, limits).await;
    Fixture { app, admin_token, _data_dir: data_dir }
}

/// A request from `client` with an optional bearer token and JSON body.
async fn from(
    app: &Router,
    client: &str,
    method: Method,
    uri: &str,
    token: Option<&str>,
    body: Option<Value>,
) -> Answer {
    let mut request = Request::builder().method(method).uri(uri);
    if let Some(token) = token {
        request = request.header(header::AUTHORIZATION, format!("Bearer {token}"));
    }
    let mut request = match body {
        Some(body) => request.header(header::CONTENT_TYPE, "application/json").body(Body::from(body.to_string())),
        None => request.body(Body::empty()),
    }
    .unwrap();
    request.extensions_mut().insert(ClientAddr(client.parse::<IpAddr>().unwrap()));
    send(app, request).await
}

async fn join(app: &Router, client: &str) -> Answer {
    from(
        app,
        client,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(json!({"demographics": demographics()})),
    )
    .await
}

/// No sentence of the API names the server's Rust types or modules.
fn plain(sentence: &str) {
    for word in ["struct", "enum ", "::", "mrstudy_server", "Body", "Rejection"] {
        assert!(!sentence.contains(word), "{sentence:?} names {word:?}");
    }
}

#[tokio::test]
async fn bodies_must_be_json_objects_and_errors_name_the_field_not_the_type() {
    let fixture = fixture(None).await;
    let app = &fixture.app;
    // an array where an object is expected: serde would take it for a struct
    let joined =
        call(app, Method::POST, "/api/studies/shadows-demo/participants", None, Some(json!([{}, null, null]))).await;
    assert_eq!(joined.status, StatusCode::UNPROCESSABLE_ENTITY, "{}", joined.text());
    assert!(joined.error().contains("JSON object"), "{}", joined.error());
    let joined = join(app, "127.0.0.1").await.json();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    let url = format!("/api/participants/{id}/responses");
    let answer = call(app, Method::POST, &url, Some(token), Some(json!([1, "left", 500]))).await;
    assert_eq!(answer.status, StatusCode::UNPROCESSABLE_ENTITY, "{}", answer.text());
    plain(&answer.error());
    for (body, mentions) in [
        (json!({"trial": 1, "chosen": 0, "rt_ms": 500}), "chosen"),
        (json!({"trial": 1, "chosen": "up", "rt_ms": 500}), "chosen"),
        (json!({"trial": "one", "chosen": "left", "rt_ms": 500}), "trial"),
        (json!({"chosen": "left", "rt_ms": 500}), "trial"),
    ] {
        let answer = call(app, Method::POST, &url, Some(token), Some(body.clone())).await;
        assert_eq!(answer.status, StatusCode::UNPROCESSABLE_ENTITY, "{body}: {}", answer.text());
        let error = answer.error();
        assert!(error.contains(mentions) && !error.contains("not valid JSON"), "{body}: {error}");
        plain(&error);
    }
    // none of it was stored: trial 1 is still next
    let next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await.json();
    assert_eq!(next["trial"], 1);
    // the bearer scheme in any case (RFC 9110)
    let mut request = Request::builder().uri(format!("/api/participants/{id}/next"));
    request = request.header(header::AUTHORIZATION, format!("bearer {token}"));
    let answer = send(app, request.body(Body::empty()).unwrap()).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
}

#[tokio::test]
async fn every_api_error_is_a_json_sentence() {
    let fixture = fixture(None).await;
    let app = &fixture.app;
    let raw = |method: Method, uri: &str, content_type: Option<&str>, body: String| {
        let mut request = Request::builder().method(method).uri(uri);
        if let Some(content_type) = content_type {
            request = request.header(header::CONTENT_TYPE, content_type);
        }
        request.body(Body::from(body)).unwrap()
    };
    let cases = [
        (raw(Method::DELETE, "/api/studies", None, String::new()), StatusCode::METHOD_NOT_ALLOWED),
        (
            raw(Method::GET, "/api/studies/shadows-demo/participants", None, String::new()),
            StatusCode::METHOD_NOT_ALLOWED,
        ),
        (
            raw(Method::POST, "/api/studies/shadows-demo/participants", Some("text/plain"), "{}".into()),
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
        ),
        (
            raw(
                Method::POST,
                "/api/studies/shadows-demo/participants",
                Some("application/json"),
                format!("{{\"demographics\": {{}}, \"pad\": \"{}\"}}", "x".repeat(40_000)),
            ),
            StatusCode::PAYLOAD_TOO_LARGE,
        ),
        (raw(Method::GET, "/api/no/such/route", None, String::new()), StatusCode::NOT_FOUND),
        (
            raw(Method::POST, "/api/studies/shadows-demo/participants", Some("application/json"), "{".into()),
            StatusCode::BAD_REQUEST,
        ),
    ];
    for (request, status) in cases {
        let what = format!("{} {}", request.method(), request.uri());
        let answer = send(app, request).await;
        assert_eq!(answer.status, status, "{what}: {}", answer.text());
        assert!(
            answer.headers.get(header::CONTENT_TYPE).unwrap().to_str().unwrap().starts_with("application/json"),
            "{what}"
        );
        let error = answer.error();
        assert!(error.ends_with('.'), "{what}: {error}");
        plain(&error);
    }
}

#[tokio::test]
async fn joining_and_answering_are_limited_per_client_address_with_429() {
    let limits = Limits { joins_per_minute: 2, responses_per_minute: 3, admin_failures: 0, behind_tls: false };
    let fixture = fixture(Some(limits)).await;
    let app = &fixture.app;
    // a burst of twice the rate per minute, then 429 with a sentence and a Retry-After
    let mut joined = Vec::new();
    for _ in 0..4 {
        let answer = join(app, "192.0.2.7").await;
        assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
        joined.push(answer.json());
    }
    let refused = join(app, "192.0.2.7").await;
    assert_eq!(refused.status, StatusCode::TOO_MANY_REQUESTS);
    assert!(refused.error().contains("Too many joins"), "{}", refused.error());
    assert!(refused.headers.contains_key(header::RETRY_AFTER));
    // another address has its own allowance; a request from inside the process none at all
    assert_eq!(join(app, "192.0.2.8").await.status, StatusCode::CREATED);
    let inside = call(
        app,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(json!({"demographics": demographics()})),
    )
    .await;
    assert_eq!(inside.status, StatusCode::CREATED);
    let stats =
        call(app, Method::GET, "/api/admin/studies/shadows-demo", Some(&fixture.admin_token), None).await.json();
    assert_eq!(stats["started"], 6, "the refused join stored nobody: {stats}");

    // answers: 6 in a burst from one address, the 7th is refused and not stored
    let (id, token) = (joined[0]["participant"].as_str().unwrap(), joined[0]["token"].as_str().unwrap());
    for trial in 1..=6 {
        from(app, "192.0.2.7", Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
        let body = json!({"trial": trial, "chosen": "left", "rt_ms": 900});
        let answer =
            from(app, "192.0.2.7", Method::POST, &format!("/api/participants/{id}/responses"), Some(token), Some(body))
                .await;
        assert_eq!(answer.status, StatusCode::CREATED, "trial {trial}: {}", answer.text());
    }
    from(app, "192.0.2.7", Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    let body = json!({"trial": 7, "chosen": "left", "rt_ms": 900});
    let answer =
        from(app, "192.0.2.7", Method::POST, &format!("/api/participants/{id}/responses"), Some(token), Some(body))
            .await;
    assert_eq!(answer.status, StatusCode::TOO_MANY_REQUESTS);
    assert!(answer.error().contains("Too many answers from this participant"), "{}", answer.error());
    let retry_after: u64 = answer.headers[header::RETRY_AFTER].to_str().unwrap().parse().unwrap();
    assert!((1..=20).contains(&retry_after), "a token every 20 s: {retry_after}");
    let next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await.json();
    assert_eq!(next["trial"], 7, "the refused answer was not stored: {next}");

    // the answers' bucket is the participant's (issue 46): another person behind the same
    // address answers on
    let (other, other_token) = (joined[1]["participant"].as_str().unwrap(), joined[1]["token"].as_str().unwrap());
    from(app, "192.0.2.7", Method::GET, &format!("/api/participants/{other}/next"), Some(other_token), None).await;
    let body = json!({"trial": 1, "chosen": "left", "rt_ms": 900});
    let answer = from(
        app,
        "192.0.2.7",
        Method::POST,
        &format!("/api/participants/{other}/responses"),
        Some(other_token),
        Some(body),
    )
    .await;
    assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    // a stranger guessing tokens for that participant's id is limited per address and never
    // drains the participant's own bucket
    for guess in 0..6 {
        let body = json!({"trial": 2, "chosen": "left", "rt_ms": 900});
        let answer = from(
            app,
            "198.51.100.66",
            Method::POST,
            &format!("/api/participants/{other}/responses"),
            Some(&format!("guess-{guess}")),
            Some(body),
        )
        .await;
        assert!(
            answer.status == StatusCode::FORBIDDEN || answer.status == StatusCode::UNAUTHORIZED,
            "{}",
            answer.text()
        );
    }
    let body = json!({"trial": 2, "chosen": "left", "rt_ms": 900});
    let answer = from(
        app,
        "198.51.100.66",
        Method::POST,
        &format!("/api/participants/{other}/responses"),
        Some("guess-7"),
        Some(body),
    )
    .await;
    assert_eq!(answer.status, StatusCode::TOO_MANY_REQUESTS);
    assert!(answer.error().contains("without a valid participant token"), "{}", answer.error());
}

/// Issue 46: 200 people behind one address (a lab, a university's NAT) join and answer under
/// the default limits without a single 429 (before, the 61st join was refused).
#[tokio::test]
async fn two_hundred_people_behind_one_address_join_and_answer_under_the_default_limits() {
    let fixture = fixture(Some(Limits::default())).await;
    let app = &fixture.app;
    let mut people = Vec::new();
    for person in 0..200 {
        let answer = join(app, "203.0.113.50").await;
        assert_eq!(answer.status, StatusCode::CREATED, "person {person}: {}", answer.text());
        people.push(answer.json());
    }
    for (person, joined) in people.iter().enumerate() {
        let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
        for trial in 1..=2 {
            from(app, "203.0.113.50", Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
            let body = json!({"trial": trial, "chosen": "left", "rt_ms": 900});
            let answer = from(
                app,
                "203.0.113.50",
                Method::POST,
                &format!("/api/participants/{id}/responses"),
                Some(token),
                Some(body),
            )
            .await;
            assert_eq!(answer.status, StatusCode::CREATED, "person {person}, trial {trial}: {}", answer.text());
        }
    }
}

#[tokio::test]
async fn wrong_admin_tokens_are_throttled_per_address() {
    let limits = Limits { joins_per_minute: 0, responses_per_minute: 0, admin_failures: 3, behind_tls: false };
    let fixture = fixture(Some(limits)).await;
    let app = &fixture.app;
    for _ in 0..2 {
        let answer = from(app, "198.51.100.1", Method::GET, "/api/admin/studies", Some("guess"), None).await;
        assert_eq!(answer.status, StatusCode::FORBIDDEN);
    }
    let login = from(app, "198.51.100.1", Method::GET, "/admin/login?token=guess", None, None).await;
    assert_eq!(login.status, StatusCode::FORBIDDEN);
    // the fourth wrong try is refused before the token is looked at, with the wait
    let answer = from(app, "198.51.100.1", Method::GET, "/api/admin/studies", Some("guess"), None).await;
    assert_eq!(answer.status, StatusCode::TOO_MANY_REQUESTS);
    assert!(answer.error().contains("wrong admin tokens"));
    let retry_after: u64 = answer.headers[header::RETRY_AFTER].to_str().unwrap().parse().unwrap();
    assert!((1..=300).contains(&retry_after), "a try every 5 minutes: {retry_after}");
    let page = from(app, "198.51.100.1", Method::GET, "/admin/login?token=guess", None, None).await;
    assert_eq!(page.status, StatusCode::TOO_MANY_REQUESTS);
    assert!(page.text().contains("<html") || page.text().contains("<!DOCTYPE"), "a page, not JSON");
    // ... but the right token is never locked out (issue 46): header, login link, and the
    // session's change refused for a missing X-Requested-With is not counted as a wrong token
    let answer = from(app, "198.51.100.1", Method::GET, "/api/admin/studies", Some(&fixture.admin_token), None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    let login =
        from(app, "198.51.100.1", Method::GET, &format!("/admin/login?token={}", fixture.admin_token), None, None)
            .await;
    assert!(login.status.is_redirection() || login.status == StatusCode::OK, "{}", login.status);
    let other = from(app, "198.51.100.2", Method::GET, "/api/admin/studies", Some(&fixture.admin_token), None).await;
    assert_eq!(other.status, StatusCode::OK);
}

#[tokio::test]
async fn the_admin_cookie_is_a_server_side_session_that_logout_ends() {
    let fixture = fixture(None).await;
    let app = &fixture.app;
    let login = call(app, Method::GET, &format!("/admin/login?token={}", fixture.admin_token), None, None).await;
    let set_cookie = login.headers.get(header::SET_COOKIE).unwrap().to_str().unwrap().to_string();
    assert!(!set_cookie.contains(&fixture.admin_token), "the cookie must not hold the admin token: {set_cookie}");
    assert!(set_cookie.contains("HttpOnly") && set_cookie.contains("SameSite=Strict"), "{set_cookie}");
    assert!(set_cookie.contains("Max-Age=43200") && !set_cookie.contains("Secure"), "{set_cookie}");
    let cookie = admin_session_cookie(app, &fixture.admin_token).await;
    let with_cookie = |cookie: String, method: Method, uri: &str| {
        Request::builder().method(method).uri(uri).header(header::COOKIE, cookie).body(Body::empty()).unwrap()
    };
    let studies = send(app, with_cookie(cookie.clone(), Method::GET, "/api/admin/studies")).await;
    assert_eq!(studies.status, StatusCode::OK);
    // the admin token itself is no session
    let token_cookie = format!("mrstudy_admin={}", fixture.admin_token);
    assert_eq!(
        send(app, with_cookie(token_cookie, Method::GET, "/api/admin/studies")).await.status,
        StatusCode::UNAUTHORIZED
    );
    // logout ends the session and clears the cookie
    let logout = send(app, with_cookie(cookie.clone(), Method::POST, "/admin/logout")).await;
    assert_eq!(logout.status, StatusCode::OK);
    assert!(logout.headers.get(header::SET_COOKIE).unwrap().to_str().unwrap().contains("Max-Age=0"));
    let after = send(app, with_cookie(cookie, Method::GET, "/api/admin/studies")).await;
    assert_eq!(after.status, StatusCode::UNAUTHORIZED);
    assert!(after.error().contains("log in again"));

    // behind a TLS proxy the cookie is Secure
    let behind = crate::fixture(Some(Limits { behind_tls: true, ..Limits::default() })).await;
    let login = call(&behind.app, Method::GET, &format!("/admin/login?token={}", behind.admin_token), None, None).await;
    assert!(login.headers.get(header::SET_COOKIE).unwrap().to_str().unwrap().contains("; Secure"));
}

#[tokio::test]
async fn an_admin_session_holds_on_every_server_of_the_database_and_across_a_restart() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = data_dir.path().join("studies");
    copy_demo_study(&studies);
    let data = data_dir.path().join("data");
    let database = test_database(&data).await;
    let server = async || mrstudy_server::app(prepare_on(&database, &data, &studies).await.unwrap().state);
    let (first, second) = (server().await, server().await);
    let token = std::fs::read_to_string(data.join("admin-token")).unwrap();
    let cookie = admin_session_cookie(&first, token.trim()).await;
    let with_cookie = |method: Method, uri: &str| {
        Request::builder().method(method).uri(uri).header(header::COOKIE, cookie.clone()).body(Body::empty()).unwrap()
    };
    // a login on the first server is a session on the second
    assert_eq!(send(&second, with_cookie(Method::GET, "/api/admin/studies")).await.status, StatusCode::OK);
    // and on a server started after both are gone
    drop((first, second));
    let restarted = server().await;
    assert_eq!(send(&restarted, with_cookie(Method::GET, "/api/admin/studies")).await.status, StatusCode::OK);
    // logout on one server ends the session on every other
    let other = server().await;
    assert_eq!(send(&restarted, with_cookie(Method::POST, "/admin/logout")).await.status, StatusCode::OK);
    let after = send(&other, with_cookie(Method::GET, "/api/admin/studies")).await;
    assert_eq!(after.status, StatusCode::UNAUTHORIZED, "{}", after.text());
}

#[tokio::test]
async fn an_expired_admin_session_is_refused_and_a_login_deletes_the_expired_ones() {
    let data_dir = tempfile::tempdir().unwrap();
    let database = test_database(data_dir.path()).await;
    let storage = mrstudy_server::storage::Storage::open(&database).await.unwrap();
    let (old, new) = ([1u8; 32], [2u8; 32]);
    storage.start_admin_session(old, 1_000, 500).await.unwrap();
    assert!(storage.is_admin_session(&old, 999).await.unwrap());
    assert!(!storage.is_admin_session(&old, 1_000).await.unwrap(), "a session is over at its expiry");
    assert!(!storage.is_admin_session(&new, 999).await.unwrap(), "an unknown id is no session");
    storage.start_admin_session(new, 5_000, 2_000).await.unwrap();
    assert!(storage.is_admin_session(&new, 2_000).await.unwrap());
    let rows: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM admin_sessions")
        .fetch_one(&support::connect(&database).await)
        .await
        .unwrap();
    assert_eq!(rows, 1, "the expired session's row is deleted at the next login");
    storage.end_admin_session(new).await.unwrap();
    assert!(!storage.is_admin_session(&new, 2_000).await.unwrap());
}

#[tokio::test]
async fn spreadsheet_formulas_from_participants_are_neutralised_in_the_export() {
    let fixture = fixture(None).await;
    let app = &fixture.app;
    let payload = "=HYPERLINK(\"http://evil.example/\",\"x\")";
    let joined = call(
        app,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(json!({
            "demographics": demographics(),
            "client": {"viewport": "=1+1", "devicePixelRatio": payload, "userAgent": "+cmd"},
            "url_params": {"PROLIFIC_PID": "-2+3", "STUDY_ID": "\t=1", "SESSION_ID": "\r@x"}
        })),
    )
    .await;
    assert_eq!(joined.status, StatusCode::CREATED, "{}", joined.text());
    let joined = joined.json();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    // every trial (the export leaves out catch trials, which any trial may be)
    for trial in 1..=7 {
        call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
        let body = json!({"trial": trial, "chosen": "left", "rt_ms": 900, "client": {"devicePixelRatio": "@SUM(A1)"}});
        let answer =
            call(app, Method::POST, &format!("/api/participants/{id}/responses"), Some(token), Some(body)).await;
        assert_eq!(answer.status, StatusCode::CREATED, "trial {trial}: {}", answer.text());
    }
    let csv = call(app, Method::GET, "/api/admin/studies/shadows-demo/export.csv", Some(&fixture.admin_token), None)
        .await
        .text();
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header = reader.headers().unwrap().clone();
    let mut cells = 0;
    for record in reader.records() {
        for (name, cell) in header.iter().zip(record.unwrap().iter()) {
            cells += 1;
            if name == "rt_ms" {
                continue; // a number
            }
            assert!(
                !cell.starts_with(['=', '+', '-', '@', '\t', '\r']),
                "column {name}: {cell:?} would run as a formula"
            );
        }
    }
    assert!(cells > 20);
    assert!(csv.contains("'@SUM(A1)") && csv.contains("'-2+3"), "{csv}");
}

#[test]
fn an_admin_token_set_by_hand_needs_128_bits() {
    for weak in [
        "aaaaaaaaaaaaaaaa",
        "a".repeat(64).as_str(),
        "0123456789abcdef",
        "abababababababababababababababababab",
        "short-but-Mixed-99",
        "bad token with spaces 0123456789abcdef",
    ] {
        assert!(admin_token_strength(weak).is_err(), "{weak} should be refused");
    }
    for strong in ["3f9c2a7be14d5608f1c2e3d4a5b6c7d8", "Zq8kP2mW9xT4vN7rB3yL6h", "c81e728d9d4c2f636f067f89cc14862c"] {
        assert!(admin_token_strength(strong).is_ok(), "{strong}: {:?}", admin_token_strength(strong));
    }
    let why = admin_token_strength("aaaaaaaaaaaaaaaa").unwrap_err();
    assert!(matches!(why, mrstudy_server::auth::WeakToken::Bits { characters: 16, .. }), "{why:?}");
    assert!(why.to_string().contains("16 characters of 16 kinds hold at most 64 bits"), "{why}");
}

/// Issue 46: repeated halves, runs along the alphabet, the digits or the keyboard, and few
/// different characters are refused although their length holds 128 bits; random tokens pass
/// (`openssl rand -hex 16`, and 32 letters and digits).
#[test]
fn an_admin_token_with_a_pattern_is_refused_and_random_ones_pass() {
    for weak in [
        "Password1Password1",
        "Password1Password1Password1",
        "0123456789abcdef0123456789abcdef",
        "qwertyuiopasdfghjklzxcvbnm1234567890",
        "1qaz2wsx3edc4rfv5tgb6yhn7ujm8ik9ol",
        "zyxwvutsrqponmlkjihgfedcba9876543210",
        "abcdefghijklmnopqrstuvwxyz-Secret7",
        "aabbaabbaabbccddaabbccddaabbccdd",
    ] {
        assert!(admin_token_strength(weak).is_err(), "{weak} should be refused");
    }
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = move || {
        // splitmix64: fixed seed, so the test does the same every time
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let alphanumeric = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
    for _ in 0..2000 {
        let hex: String = (0..32).map(|_| char::from(b"0123456789abcdef"[(next() % 16) as usize])).collect();
        assert!(admin_token_strength(&hex).is_ok(), "{hex}: {:?}", admin_token_strength(&hex));
        let text: String = (0..32).map(|_| char::from(alphanumeric[(next() % 62) as usize])).collect();
        assert!(admin_token_strength(&text).is_ok(), "{text}: {:?}", admin_token_strength(&text));
    }
}

/// Issue 46: a formula character after leading white space or control characters (space, LF,
/// NBSP, NUL, VT, FF) is a formula to spreadsheets too, so the cell is neutralised.
#[test]
fn a_formula_after_leading_white_space_or_controls_is_neutralised() {
    use mrstudy_server::export::text_cell;
    for lead in [" ", "\n", "\u{a0}", "\0", "\u{b}", "\u{c}", "  \n\u{a0}", "\u{feff}"] {
        for formula in ["=1+1", "+1", "-1", "@SUM(A1)", "\t=1", "\r=1"] {
            let text = format!("{lead}{formula}");
            assert_eq!(text_cell(&text), format!("'{text}"), "{text:?}");
        }
    }
    for safe in ["plain", " plain", "a=b", "\u{a0}x-1", ""] {
        assert_eq!(text_cell(safe), safe, "{safe:?}");
    }
}

/// Issue 46: a refused study file's sentence is said once: the error carries it, not also as its
/// source (which `anyhow` prints after it).
#[tokio::test]
async fn a_refused_study_file_is_said_once() {
    let dir = tempfile::tempdir().unwrap();
    let studies = dir.path().join("studies");
    std::fs::create_dir_all(&studies).unwrap();
    std::fs::write(studies.join("broken.toml"), "slug = \"broken\"\nbogus = 1\n").unwrap();
    let data = dir.path().join("data");
    let Err(error) = prepare_on(&test_database(&data).await, &data, &studies).await else {
        panic!("a study file with an unknown key was accepted")
    };
    let mut said = error.to_string();
    let mut source = std::error::Error::source(&error);
    while let Some(cause) = source {
        said.push_str(&format!(": {cause}"));
        source = cause.source();
    }
    assert_eq!(said.matches("unknown field").count(), 1, "{said}");
    assert!(said.contains("broken.toml"), "{said}");
}

/// Issue 46: an `rt_ms` out of range is refused with a short sentence (1e308 was echoed with
/// its 309 digits).
#[tokio::test]
async fn an_absurd_response_time_is_refused_in_a_short_sentence() {
    let fixture = fixture(None).await;
    let app = &fixture.app;
    let joined = join(app, "192.0.2.1").await.json();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    for rt in [json!(1e308), json!(-1e-300), json!(-1), json!(3_600_001.0)] {
        let body = json!({"trial": 1, "chosen": "left", "rt_ms": rt});
        let answer =
            call(app, Method::POST, &format!("/api/participants/{id}/responses"), Some(token), Some(body)).await;
        assert_eq!(answer.status, StatusCode::UNPROCESSABLE_ENTITY, "{rt}: {}", answer.text());
        let sentence = answer.error();
        assert!(sentence.len() < 120 && sentence.contains("rt_ms"), "{rt}: {sentence}");
    }
}

/// Issue 46: a study's image must be a regular image file inside the studies folder: a symbolic
/// link to `/etc/passwd`, a link to a real image outside, a `../` path out of the folder and a
/// text file named `.png` are each refused at load with one sentence naming the study file, the
/// key and the path (all were served before, `/etc/passwd` as `image/png`).
#[tokio::test]
async fn a_study_image_must_be_an_image_file_inside_the_studies_folder() {
    let refusal = |prepare: &dyn Fn(&std::path::Path, &std::path::Path)| {
        let dir = tempfile::tempdir().unwrap();
        let studies = dir.path().join("studies");
        copy_demo_study(&studies);
        prepare(dir.path(), &studies);
        async move {
            let data = dir.path().join("data");
            let prepared = prepare_on(&test_database(&data).await, &data, &studies).await;
            let Err(error) = prepared else { panic!("the study was accepted") };
            let sentence = error.to_string();
            assert!(std::error::Error::source(&error).is_none(), "{sentence}");
            assert!(sentence.contains("shadows-demo.toml") && sentence.contains("scenes[0].images.LQ"), "{sentence}");
            sentence
        }
    };
    let demo = |studies: &std::path::Path, from: &str, to: &str| {
        let file = studies.join("shadows-demo.toml");
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(text.contains(from));
        std::fs::write(&file, text.replacen(from, to, 1)).unwrap();
    };
    #[cfg(unix)]
    {
        let sentence = refusal(&|_, studies| {
            let link = studies.join("shadows-demo/view-left-LQ.png");
            std::fs::remove_file(&link).unwrap();
            std::os::unix::fs::symlink("/etc/passwd", &link).unwrap();
        })
        .await;
        assert!(sentence.contains("view-left-LQ.png") && sentence.contains("does not read as one"), "{sentence}");
        // a real image, but outside the folder: refused however the link reaches it
        let sentence = refusal(&|dir, studies| {
            let link = studies.join("shadows-demo/view-left-LQ.png");
            std::fs::rename(&link, dir.join("outside.png")).unwrap();
            std::os::unix::fs::symlink(dir.join("outside.png"), &link).unwrap();
        })
        .await;
        assert!(sentence.contains("view-left-LQ.png") && sentence.contains("inside the studies folder"), "{sentence}");
    }
    let sentence = refusal(&|dir, studies| {
        std::fs::copy(studies.join("shadows-demo/view-left-LQ.png"), dir.join("outside.png")).unwrap();
        demo(studies, "shadows-demo/view-left-LQ.png", "../outside.png");
    })
    .await;
    assert!(sentence.contains("outside.png") && sentence.contains("inside the studies folder"), "{sentence}");
    let sentence = refusal(&|_, studies| {
        std::fs::write(studies.join("shadows-demo/view-left-LQ.png"), "root:x:0:0:root:/root:/bin/bash\n").unwrap();
    })
    .await;
    assert!(sentence.contains("view-left-LQ.png") && sentence.contains("does not read as one"), "{sentence}");
}

/// What a real server answers on a raw socket to `request`, read until it closes (5 s at most).
async fn raw_answer(server: std::net::SocketAddr, request: Vec<u8>) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut stream = tokio::net::TcpStream::connect(server).await.unwrap();
    // hyper may answer and close before taking all of an oversized request
    let _ = stream.write_all(&request).await;
    let mut answer = Vec::new();
    let _ = tokio::time::timeout(std::time::Duration::from_secs(5), stream.read_to_end(&mut answer)).await;
    String::from_utf8_lossy(&answer).into_owned()
}

/// Issue 46: the 414 and 431 hyper gives by itself (an address over 64 KiB, headers over its
/// buffer or more than 100 of them), and its 400 for what is not HTTP, have the JSON error shape
/// with one sentence (their body was empty), on a real socket through `serve_connections`.
#[tokio::test]
async fn answers_hyper_gives_by_itself_have_the_json_error_shape() {
    let fixture = fixture(None).await;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let server = listener.local_addr().unwrap();
    let serving = tokio::spawn(mrstudy_server::serve::serve_connections(
        listener,
        fixture.app.clone(),
        mrstudy_server::serve::Connections::default(),
        std::future::pending(),
    ));
    let long_uri = format!("GET /api/studies/{} HTTP/1.1\r\nHost: x\r\n\r\n", "a".repeat(70_000)).into_bytes();
    // never ended: hyper parses a whole head that came in one read whatever its size
    let big_header = format!("GET /api/studies HTTP/1.1\r\nHost: x\r\nX-Big: {}", "b".repeat(500_000)).into_bytes();
    let many_headers = format!(
        "GET /api/studies HTTP/1.1\r\nHost: x\r\n{}\r\n",
        (0..150).map(|i| format!("X-{i}: 1\r\n")).collect::<String>()
    )
    .into_bytes();
    for (request, status) in [
        (long_uri, "414"),
        (big_header, "431"),
        (many_headers, "431"),
        (b"G@T /api/studies HTTP/1.1\r\n\r\n".to_vec(), "400"),
    ] {
        let answer = raw_answer(server, request).await;
        let (head, body) = answer.split_once("\r\n\r\n").unwrap_or_else(|| panic!("no answer: {answer:?}"));
        assert!(head.starts_with(&format!("HTTP/1.1 {status} ")), "expected {status}: {answer}");
        assert!(head.to_ascii_lowercase().contains("content-type: application/json"), "{answer}");
        let error: Value = serde_json::from_str(body).unwrap_or_else(|_| panic!("not JSON: {answer:?}"));
        let sentence = error["error"].as_str().unwrap();
        assert!(sentence.ends_with('.') && sentence.len() < 80, "{sentence}");
        plain(sentence);
    }
    // an ordinary answer is untouched
    let answer =
        raw_answer(server, b"GET /api/studies HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n".to_vec()).await;
    assert!(answer.starts_with("HTTP/1.1 200 "), "{answer}");
    serving.abort();
}

/// Issue 46: a preview link expires (`PREVIEW_LINK_DAYS` after it was made; the answer says
/// when) and `DELETE /api/admin/studies/{slug}/preview` revokes the study's links; both are
/// refused at the join with 403 (links were valid for ever, and could not be revoked).
#[tokio::test]
async fn preview_links_expire_and_can_be_revoked() {
    use mrstudy_server::storage::PREVIEW_LINK_DAYS;
    use mrstudy_server::storage::iso;
    let dir = tempfile::tempdir().unwrap();
    let studies = demo_studies(dir.path(), |text| text);
    let Started { app, admin_token, database, .. } = start(dir.path(), &studies).await;
    let app = &app;
    let admin = Some(admin_token.as_str());
    let link = || async {
        let made = call(app, Method::POST, "/api/admin/studies/shadows-demo/preview", admin, None).await;
        assert_eq!(made.status, StatusCode::CREATED, "{}", made.text());
        let made = made.json();
        let token = made["url"].as_str().unwrap().split("preview=").nth(1).unwrap().to_string();
        (token, made["expires_at"].as_str().unwrap().to_string())
    };
    let join_with = |token: String| async move {
        let body = json!({"demographics": demographics(), "preview": token});
        call(app, Method::POST, "/api/studies/shadows-demo/participants", None, Some(body)).await
    };
    let days = |n: u64| std::time::Duration::from_secs(n * 86_400);
    let now = std::time::SystemTime::now();

    let (token, expires_at) = link().await;
    assert!(expires_at > iso(now + days(PREVIEW_LINK_DAYS) - days(1)), "{expires_at}");
    assert!(expires_at < iso(now + days(PREVIEW_LINK_DAYS + 1)), "{expires_at}");
    let joined = join_with(token.clone()).await;
    assert_eq!(joined.status, StatusCode::CREATED, "{}", joined.text());

    // made a day less than the validity ago: still valid; a day more: expired
    let pool = support::connect(&database).await;
    let made_at = |ago: std::time::Duration| {
        let pool = pool.clone();
        async move {
            sqlx::query("UPDATE previews SET created_at = $1").bind(iso(now - ago)).execute(&pool).await.unwrap();
        }
    };
    made_at(days(PREVIEW_LINK_DAYS - 1)).await;
    assert_eq!(join_with(token.clone()).await.status, StatusCode::CREATED);
    made_at(days(PREVIEW_LINK_DAYS + 1)).await;
    let refused = join_with(token.clone()).await;
    assert_eq!(refused.status, StatusCode::FORBIDDEN, "{}", refused.text());
    assert!(refused.error().contains("preview link"), "{}", refused.text());

    // revoking: every link of the study, the answer counts them
    let (first, _) = link().await;
    let (second, _) = link().await;
    assert_eq!(join_with(first.clone()).await.status, StatusCode::CREATED);
    let revoked = call(app, Method::DELETE, "/api/admin/studies/shadows-demo/preview", admin, None).await;
    assert_eq!(revoked.status, StatusCode::OK, "{}", revoked.text());
    assert_eq!(revoked.json(), json!({"revoked": 3}));
    for token in [first, second] {
        assert_eq!(join_with(token).await.status, StatusCode::FORBIDDEN);
    }
    // the admin page has the control
    let page = call(app, Method::GET, "/admin/studies/shadows-demo", admin, None).await;
    assert_eq!(page.status, StatusCode::OK, "{}", page.text());
    assert!(page.text().contains(r#"id="revoke-previews""#));
    // only the admin revokes, and only a known study's links
    let anonymous = call(app, Method::DELETE, "/api/admin/studies/shadows-demo/preview", None, None).await;
    assert_eq!(anonymous.status, StatusCode::UNAUTHORIZED, "{}", anonymous.text());
    let unknown = call(app, Method::DELETE, "/api/admin/studies/nope/preview", admin, None).await;
    assert_eq!(unknown.status, StatusCode::NOT_FOUND, "{}", unknown.text());
}

/// Issue 46: `GET …/next` answers only once the "served" record is committed, so a kill right
/// after a trial was sent cannot leave its answer "never served" (409). Deterministic: a second
/// connection holds sqlite's write lock, and the trial must not come while it does (before, the
/// record was queued and the trial sent at once; 71 answers got 409 after kills).
#[tokio::test]
async fn a_trial_is_sent_only_after_its_served_record_is_durable() {
    let dir = tempfile::tempdir().unwrap();
    let studies = dir.path().join("studies");
    copy_demo_study(&studies);
    let data = dir.path().join("data");
    let database = mrstudy_server::storage::Database::in_data_dir(&data);
    let Prepared { state, .. } = prepare_on(&database, &data, &studies).await.unwrap();
    let app = mrstudy_server::app(state);
    let joined = join(&app, "192.0.2.7").await.json();
    let (id, token) =
        (joined["participant"].as_str().unwrap().to_string(), joined["token"].as_str().unwrap().to_string());
    let pool = support::connect(&database).await;
    let mut lock = pool.acquire().await.unwrap();
    sqlx::query("BEGIN IMMEDIATE").execute(&mut *lock).await.unwrap();
    let next = tokio::spawn({
        let (app, id, token) = (app.clone(), id.clone(), token.clone());
        async move { call(&app, Method::GET, &format!("/api/participants/{id}/next"), Some(&token), None).await }
    });
    tokio::time::sleep(std::time::Duration::from_millis(500)).await;
    assert!(!next.is_finished(), "the trial was sent before its served record could be committed");
    sqlx::query("ROLLBACK").execute(&mut *lock).await.unwrap();
    drop(lock);
    let next = tokio::time::timeout(std::time::Duration::from_secs(20), next).await.unwrap().unwrap();
    assert_eq!(next.status, StatusCode::OK, "{}", next.text());
    assert_eq!(next.json()["trial"], json!(1));
    let shown: Option<String> = sqlx::query_scalar("SELECT shown_at FROM trials WHERE participant = $1 AND trial = 1")
        .bind(&id)
        .fetch_one(&pool)
        .await
        .unwrap();
    assert!(shown.is_some(), "trial 1 was sent but is not recorded as served");
}

/// Issue 46, with the default limits: after 10 wrong admin tokens from an address the right one
/// still works (before, it was refused for up to 15 minutes), and the 11th wrong one is refused.
#[tokio::test]
async fn after_ten_wrong_admin_tokens_the_right_one_still_works() {
    let fixture = fixture(Some(Limits::default())).await;
    let app = &fixture.app;
    for guess in 0..10 {
        let answer =
            from(app, "198.51.100.9", Method::GET, "/api/admin/studies", Some(&format!("g{guess}")), None).await;
        assert_eq!(answer.status, StatusCode::FORBIDDEN);
    }
    let right = from(app, "198.51.100.9", Method::GET, "/api/admin/studies", Some(&fixture.admin_token), None).await;
    assert_eq!(right.status, StatusCode::OK, "{}", right.text());
    let wrong = from(app, "198.51.100.9", Method::GET, "/api/admin/studies", Some("g10"), None).await;
    assert_eq!(wrong.status, StatusCode::TOO_MANY_REQUESTS);
}

/// Issue 46: screen checks (each a screen-out row when the screen does not fit) are limited
/// per client address like joins, in a bucket of their own; before, one address made 300
/// screen-outs in 0.9 s.
#[tokio::test]
async fn screen_checks_are_limited_per_client_address() {
    let limits = Limits { joins_per_minute: 2, responses_per_minute: 0, admin_failures: 0, behind_tls: false };
    let fixture = fixture(Some(limits)).await;
    let app = &fixture.app;
    // a window too small for the study: each check stores a screen-out
    let body =
        json!({"client": {"viewport": [200, 150], "devicePixelRatio": 1, "userAgent": "test"}, "url_params": {}});
    for _ in 0..4 {
        let answer =
            from(app, "192.0.2.30", Method::POST, "/api/studies/shadows-demo/screen", None, Some(body.clone())).await;
        assert!(answer.status.is_success(), "{}", answer.text());
    }
    let refused =
        from(app, "192.0.2.30", Method::POST, "/api/studies/shadows-demo/screen", None, Some(body.clone())).await;
    assert_eq!(refused.status, StatusCode::TOO_MANY_REQUESTS);
    assert!(refused.error().contains("Too many screen checks"), "{}", refused.error());
    // the joins' bucket is apart: the same address still joins
    assert_eq!(join(app, "192.0.2.30").await.status, StatusCode::CREATED);
}

/// Issue 46, item 4: on PostgreSQL the limits are the database's, so two server processes of
/// one database allow one address the numbers once, not twice; the buckets hold digests, never
/// the address. On sqlite (one process per database) each process keeps its own.
#[tokio::test]
async fn limits_hold_across_the_servers_of_one_database() {
    use mrstudy_server::storage::Database;
    let data_dir = tempfile::tempdir().unwrap();
    let studies = data_dir.path().join("studies");
    copy_demo_study(&studies);
    let data = data_dir.path().join("data");
    let database = test_database(&data).await;
    let limits = Limits { joins_per_minute: 2, responses_per_minute: 0, admin_failures: 0, behind_tls: false };
    let server =
        async || mrstudy_server::app(prepare_on(&database, &data, &studies).await.unwrap().state.with_limits(limits));
    let servers = [server().await, server().await];
    // joins from one address, alternating between the two servers, until each refuses
    let mut created = 0;
    for attempt in 0..12 {
        let answer = join(&servers[attempt % 2], "192.0.2.44").await;
        match answer.status {
            StatusCode::CREATED => created += 1,
            StatusCode::TOO_MANY_REQUESTS => assert!(answer.error().contains("Too many joins"), "{}", answer.text()),
            other => panic!("join {attempt}: {other} {}", answer.text()),
        }
    }
    match &database {
        Database::Postgres(_) => {
            assert_eq!(created, 4, "a burst of 4 joins in all, whichever server takes them");
            let pool = support::connect(&database).await;
            let rows: Vec<(String, Vec<u8>)> =
                sqlx::query_as("SELECT bucket, key FROM rate_limit_buckets").fetch_all(&pool).await.unwrap();
            assert_eq!(rows.len(), 1, "{rows:?}");
            assert_eq!(rows[0].0, "joins");
            assert_eq!(rows[0].1.len(), 32, "a SHA-256 digest");
            assert!(!rows[0].1.windows(4).any(|bytes| bytes == [192, 0, 2, 44]), "the address is not stored");
        }
        Database::Sqlite(_) => assert_eq!(created, 8, "each process of a sqlite database has its own buckets"),
    }
}
