//! Router tests: every API call and its error paths, admin authentication and the security
//! properties, driven through `app(state)` with `oneshot` (no socket). Each test gets a fresh
//! data directory and database, loading the demo study and a survey it cannot render.

use std::path::{Path, PathBuf};

use axum::Router;
use axum::body::Body;
use axum::http::{Method, Request, StatusCode, header};
use mrstudy_server::app;
use mrstudy_server::serve::{Prepared, prepare_on};
use mrstudy_server::storage::Database;
use serde_json::{Value, json};

mod support;
use support::{
    Answer, Started, before_texts, call, copy_demo_study, demo_studies, demographics, repo_studies_dir, send, start,
    test_database,
};

/// The demo study and the thesis survey, whose first scene is a scene file that does not parse:
/// `serve` skips the survey (its stimuli cannot be rendered) without opening the GPU, where the
/// repository's survey would have its 48 stimuli rendered by `prepare`.
fn studies_dir(work: &Path, edit_demo: impl FnOnce(String) -> String) -> PathBuf {
    let dir = demo_studies(work, edit_demo);
    let survey = std::fs::read_to_string(repo_studies_dir().join("web-survey.toml")).unwrap();
    std::fs::write(
        dir.join("web-survey.toml"),
        survey.replacen("render = \"survey-1\"", "render = \"scenes/broken.toml\"", 1),
    )
    .unwrap();
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    std::fs::write(dir.join("scenes/broken.toml"), "this is not a scene file").unwrap();
    dir
}

struct Fixture {
    app: Router,
    admin_token: String,
    skipped: Vec<String>,
    database: Database,
    _data_dir: tempfile::TempDir,
}

async fn fixture() -> Fixture {
    fixture_with_demo(|text| text).await
}

/// The fixture with the demo study's text changed by `edit_demo`.
async fn fixture_with_demo(edit_demo: impl FnOnce(String) -> String) -> Fixture {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = studies_dir(data_dir.path(), edit_demo);
    let Started { app, admin_token, skipped, database, .. } = start(data_dir.path(), &studies).await;
    Fixture { app, admin_token, skipped, database, _data_dir: data_dir }
}

async fn join(app: &Router) -> (String, String) {
    let body = json!({"demographics": demographics(), "client": {"viewport": [1280, 800], "devicePixelRatio": 2, "userAgent": "test"}, "url_params": {"PROLIFIC_PID": "abc123", "other": "dropped"}});
    let (id, token, _) = support::join(app, "shadows-demo", body).await;
    (id, token)
}

/// Answers `trial` as a page would: it first gets the next trial (which the server records as
/// served), then posts the answer.
async fn answer_trial(app: &Router, id: &str, token: &str, trial: i64, chosen: &str) -> Answer {
    call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    call(
        app,
        Method::POST,
        &format!("/api/participants/{id}/responses"),
        Some(token),
        Some(json!({"trial": trial, "chosen": chosen, "rt_ms": 812.5, "client": {"viewport": [1280, 800]}})),
    )
    .await
}

async fn started(fixture: &Fixture) -> i64 {
    let answer =
        call(&fixture.app, Method::GET, "/api/admin/studies/shadows-demo", Some(&fixture.admin_token), None).await;
    assert_eq!(answer.status, StatusCode::OK);
    answer.json()["started"].as_i64().unwrap()
}

#[tokio::test]
async fn studies_lists_open_studies_and_skips_those_it_cannot_render() {
    let fixture = fixture().await;
    let answer = call(&fixture.app, Method::GET, "/api/studies", None, None).await;
    assert_eq!(answer.status, StatusCode::OK);
    assert_eq!(
        answer.json(),
        json!([{"slug": "shadows-demo", "title": "Does the sphere belong in the scene?", "kind": "paired-comparison", "trials": 7}])
    );
    assert_eq!(fixture.skipped.len(), 1, "{:?}", fixture.skipped);
    assert!(fixture.skipped[0].contains("\"web-survey\""), "{:?}", fixture.skipped);
    assert!(
        fixture.skipped[0].contains("scene configuration \"survey-1\"") && fixture.skipped[0].contains("broken.toml"),
        "{:?}",
        fixture.skipped
    );
}

#[tokio::test]
async fn join_gives_a_random_id_and_a_256_bit_token() {
    let fixture = fixture().await;
    let (id, token) = join(&fixture.app).await;
    assert_eq!(id.len(), 32, "128-bit id");
    assert_eq!(token.len(), 64, "256-bit token as hex");
    assert!(token.chars().all(|c| c.is_ascii_hexdigit()));
    let (other_id, other_token) = join(&fixture.app).await;
    assert_ne!(id, other_id);
    assert_ne!(token, other_token);
}

#[tokio::test]
async fn join_refuses_bad_input_without_changing_state() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let url = "/api/studies/shadows-demo/participants";
    let cases: Vec<(Value, StatusCode, &str)> = vec![
        (json!({}), StatusCode::UNPROCESSABLE_ENTITY, "demographics"),
        (json!({"demographics": {"gender": "female"}}), StatusCode::UNPROCESSABLE_ENTITY, "age"),
        (
            json!({"demographics": {"gender": "robot", "age": 30, "cg_experience": "none", "vision": "normal"}}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "gender",
        ),
        (
            json!({"demographics": {"gender": "female", "age": 7, "cg_experience": "none", "vision": "normal"}}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "16 to 110",
        ),
        (
            json!({"demographics": {"gender": "female", "age": "30", "cg_experience": "none", "vision": "normal"}}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "whole number",
        ),
        (
            json!({"demographics": {"gender": "female", "age": 30.5, "cg_experience": "none", "vision": "normal"}}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "whole number",
        ),
        (
            json!({"demographics": {"gender": "female", "age": 30, "cg_experience": "none", "vision": "normal", "name": "Ann"}}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "name",
        ),
        (json!({"demographics": demographics(), "extra": 1}), StatusCode::UNPROCESSABLE_ENTITY, "extra"),
        (
            json!({"demographics": demographics(), "client": {"nested": {"a": 1}}}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "client.nested",
        ),
        (
            json!({"demographics": demographics(), "url_params": {"PROLIFIC_PID": 5}}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "PROLIFIC_PID",
        ),
        (json!({"demographics": []}), StatusCode::UNPROCESSABLE_ENTITY, "demographics"),
    ];
    for (body, status, mentions) in cases {
        let answer = call(app, Method::POST, url, None, Some(body.clone())).await;
        assert_eq!(answer.status, status, "{body}: {}", answer.text());
        let error = answer.error();
        assert!(error.contains(mentions), "{body}: error {error:?} should mention {mentions:?}");
    }
    // Not JSON, no content type, too large, unknown study.
    let raw = |body: &str, content_type: Option<&str>| {
        let mut request = Request::builder().method(Method::POST).uri(url);
        if let Some(content_type) = content_type {
            request = request.header(header::CONTENT_TYPE, content_type);
        }
        request.body(Body::from(body.to_string())).unwrap()
    };
    let answer = send(app, raw("{not json", Some("application/json"))).await;
    assert_eq!(answer.status, StatusCode::BAD_REQUEST);
    answer.error();
    let answer = send(app, raw(&json!({"demographics": demographics()}).to_string(), None)).await;
    assert_eq!(answer.status, StatusCode::UNSUPPORTED_MEDIA_TYPE);
    assert!(answer.error().contains("Content-Type"));
    let huge = json!({"demographics": demographics(), "client": {"userAgent": "x".repeat(20_000)}}).to_string();
    let answer = send(app, raw(&huge, Some("application/json"))).await;
    assert_eq!(answer.status, StatusCode::PAYLOAD_TOO_LARGE);
    answer.error();
    let answer =
        call(app, Method::POST, "/api/studies/nope/participants", None, Some(json!({"demographics": demographics()})))
            .await;
    assert_eq!(answer.status, StatusCode::NOT_FOUND);
    answer.error();
    assert_eq!(started(&fixture).await, 0, "no refused request created a participant");
}

#[tokio::test]
async fn next_needs_the_participants_own_token() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let (id, token) = join(app).await;
    let (other_id, other_token) = join(app).await;
    let url = format!("/api/participants/{id}/next");
    let answer = call(app, Method::GET, &url, None, None).await;
    assert_eq!(answer.status, StatusCode::UNAUTHORIZED);
    answer.error();
    assert_eq!(answer.headers.get(header::WWW_AUTHENTICATE).unwrap(), "Bearer");
    let answer = call(app, Method::GET, &url, Some(&other_token), None).await;
    assert_eq!(answer.status, StatusCode::FORBIDDEN);
    answer.error();
    let answer = call(app, Method::GET, &url, Some("0000"), None).await;
    assert_eq!(answer.status, StatusCode::FORBIDDEN);
    let answer = call(app, Method::GET, "/api/participants/../next", Some(&token), None).await;
    assert_ne!(answer.status, StatusCode::OK);
    // Another participant's trials cannot be answered with one's own token either.
    let answer = answer_trial(app, &other_id, &token, 1, "left").await;
    assert_eq!(answer.status, StatusCode::FORBIDDEN);
    answer.error();

    let answer = call(app, Method::GET, &url, Some(&token), None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    let next = answer.json();
    assert_eq!(next["trial"], 1);
    assert_eq!(next["total"], 7);
    assert_eq!(
        next["question"],
        "Please click on the image where you think that the virtual objects fit better into the real world."
    );
    assert_eq!(next["preload"].as_array().unwrap().len(), 2);
    assert_eq!(answer.headers.get(header::CACHE_CONTROL).unwrap(), "no-store");
    // The stimuli are served, immutable, with their content type.
    for side in ["left", "right"] {
        let url = next[side]["url"].as_str().unwrap();
        assert!(url.starts_with("/stimuli/") && url.ends_with(".png"), "{url}");
        let image = call(app, Method::GET, url, None, None).await;
        assert_eq!(image.status, StatusCode::OK);
        assert_eq!(image.headers.get(header::CONTENT_TYPE).unwrap(), "image/png");
        assert_eq!(image.headers.get(header::CACHE_CONTROL).unwrap(), "public, max-age=31536000, immutable");
        assert_eq!(&image.bytes[1..4], b"PNG");
        assert_eq!(image.headers.get(header::VARY).unwrap(), "Accept");
        // A browser that accepts WebP gets the lossless WebP copy: the same pixels, fewer bytes,
        // made once and kept beside the PNG in the store.
        for _ in 0..2 {
            let request = Request::builder()
                .uri(url)
                .header(header::ACCEPT, "image/avif,image/webp,image/apng,image/*,*/*;q=0.8")
                .body(Body::empty())
                .unwrap();
            let webp = send(app, request).await;
            assert_eq!(webp.status, StatusCode::OK);
            assert_eq!(webp.headers.get(header::CONTENT_TYPE).unwrap(), "image/webp");
            assert_eq!(webp.headers.get(header::VARY).unwrap(), "Accept");
            assert_eq!(&webp.bytes[8..12], b"WEBP");
            assert!(webp.bytes.len() < image.bytes.len(), "{} >= {}", webp.bytes.len(), image.bytes.len());
            let png = image::load_from_memory_with_format(&image.bytes, image::ImageFormat::Png).unwrap();
            let decoded = image::load_from_memory_with_format(&webp.bytes, image::ImageFormat::WebP).unwrap();
            assert_eq!(decoded.to_rgba8(), png.to_rgba8(), "lossless: the same pixels");
        }
        let cached = fixture._data_dir.path().join("data").join(url.trim_start_matches('/').replace(".png", ".webp"));
        assert!(cached.is_file(), "{}", cached.display());
    }
}

#[tokio::test]
async fn responses_are_idempotent_conflicts_are_409_and_the_end_gives_the_code() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let (id, token) = join(app).await;
    let answer = answer_trial(app, &id, &token, 1, "left").await;
    assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    assert_eq!(answer.json(), json!({"trial": 1, "chosen": "left"}));
    let answer = answer_trial(app, &id, &token, 1, "left").await;
    assert_eq!(answer.status, StatusCode::OK, "the same answer again");
    let answer = answer_trial(app, &id, &token, 1, "right").await;
    assert_eq!(answer.status, StatusCode::CONFLICT, "a different answer");
    assert!(answer.error().contains("already answered"));
    let answer = answer_trial(app, &id, &token, 3, "left").await;
    assert_eq!(answer.status, StatusCode::CONFLICT, "skipping ahead");
    assert!(answer.error().contains("next trial is 2"));

    let url = format!("/api/participants/{id}/responses");
    let bad: Vec<(Value, StatusCode, &str)> = vec![
        (json!({"trial": 0, "chosen": "left", "rt_ms": 5}), StatusCode::UNPROCESSABLE_ENTITY, "trial"),
        (json!({"trial": 8, "chosen": "left", "rt_ms": 5}), StatusCode::UNPROCESSABLE_ENTITY, "trial"),
        (json!({"trial": 2, "chosen": "up", "rt_ms": 5}), StatusCode::UNPROCESSABLE_ENTITY, "chosen"),
        (json!({"trial": 2, "chosen": "left", "rt_ms": -1}), StatusCode::UNPROCESSABLE_ENTITY, "rt_ms"),
        (json!({"trial": 2, "chosen": "left", "rt_ms": 1e12}), StatusCode::UNPROCESSABLE_ENTITY, "rt_ms"),
        (json!({"trial": 2, "chosen": "left"}), StatusCode::UNPROCESSABLE_ENTITY, "rt_ms"),
        (json!({"trial": "2", "chosen": "left", "rt_ms": 5}), StatusCode::UNPROCESSABLE_ENTITY, "trial"),
        (json!({"trial": 2, "chosen": "left", "rt_ms": 5, "sneaky": true}), StatusCode::UNPROCESSABLE_ENTITY, "sneaky"),
    ];
    for (body, status, mentions) in bad {
        let answer = call(app, Method::POST, &url, Some(&token), Some(body.clone())).await;
        assert_eq!(answer.status, status, "{body}: {}", answer.text());
        let error = answer.error();
        assert!(error.contains(mentions), "{body}: {error:?} should mention {mentions:?}");
    }
    // None of that changed anything: trial 2 is still next.
    let next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(&token), None).await.json();
    assert_eq!(next["trial"], 2);

    for trial in 2..=7 {
        let answer = answer_trial(app, &id, &token, trial, if trial % 2 == 0 { "right" } else { "left" }).await;
        assert_eq!(answer.status, StatusCode::CREATED, "trial {trial}: {}", answer.text());
    }
    let done = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(&token), None).await;
    assert_eq!(done.status, StatusCode::OK);
    assert_eq!(done.json(), json!({"done": true, "completion_code": "DEMO-7F3A"}));
    let answer = answer_trial(app, &id, &token, 7, if 7 % 2 == 0 { "right" } else { "left" }).await;
    assert_eq!(answer.status, StatusCode::OK, "repeating the last answer after the end");

    // The export has one row per answer, with the kept crowdsourcing parameters as external-id
    // columns (the demo study declares no url_params: only the ids a participant brought, not
    // five empty ones) and in the JSON export.
    let csv =
        call(app, Method::GET, "/api/admin/studies/shadows-demo/export.csv", Some(&fixture.admin_token), None).await;
    assert_eq!(csv.status, StatusCode::OK);
    assert!(csv.headers.get(header::CONTENT_TYPE).unwrap().to_str().unwrap().starts_with("text/csv"));
    let text = csv.text();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "study,participant,trial,left,right,chosen,scene_left,scene_right,rt_ms,shown_at,answered_at,catch_answered,catch_failed,viewport,device_pixel_ratio,display_css,display_device,completed,status,completion_code,pilot,excluded,too_fast,PROLIFIC_PID,gender,age,cg_experience,vision"
    );
    assert_eq!(lines.len(), 7, "six judgments; the catch trial is not a row:\n{text}");
    assert!(!text.contains("catch:"));
    for line in &lines[1..] {
        assert!(
            line.contains(",1,0,1280x800,2,,,1,") || line.contains(",1,1,1280x800,2,,,1,"),
            "catch columns, client, display (not sent: empty), completed: {line}"
        );
        // answered within milliseconds of being served: too fast by the server's clock
        assert!(
            line.contains(",1,completed,DEMO-7F3A,false,false,true,abc123,female,31,"),
            "status, code, flags, external ids: {line}"
        );
    }
    let json = call(app, Method::GET, "/api/admin/studies/shadows-demo/export.json", Some(&fixture.admin_token), None)
        .await
        .json();
    let participant = &json["participants"][0];
    assert_eq!(participant["url_params"], json!({"PROLIFIC_PID": "abc123"}));
    assert_eq!(participant["client"]["devicePixelRatio"], 2);
    assert_eq!(participant["schedule"].as_array().unwrap().len(), 7);
    assert!(participant["schedule"][0]["shown_at"].is_string() || participant["schedule"][0]["shown_at"].is_null());
    assert!(json.to_string().find(&token).is_none(), "the token is not exported");
}

#[tokio::test]
async fn stimulus_and_static_paths_cannot_be_traversed() {
    let fixture = fixture().await;
    let app = &fixture.app;
    for path in [
        "/stimuli/..%2F..%2Fmrstudy.db",
        "/stimuli/../mrstudy.db",
        "/stimuli/admin-token",
        "/stimuli/%2e%2e%2fadmin-token",
        &format!("/stimuli/{}.png", "0".repeat(64)),
        &format!("/stimuli/{}.db", "a".repeat(64)),
        "/static/..%2F..%2FCargo.toml",
        "/static/style.css%00.js",
    ] {
        let answer = call(app, Method::GET, path, None, None).await;
        assert!(
            answer.status == StatusCode::NOT_FOUND || answer.status == StatusCode::BAD_REQUEST,
            "{path}: {}",
            answer.status
        );
        assert!(!answer.text().contains("SQLite"), "{path}");
    }
    let answer = call(app, Method::GET, "/static/survey.js", None, None).await;
    assert_eq!(answer.status, StatusCode::OK);
    assert!(answer.headers.get(header::CONTENT_TYPE).unwrap().to_str().unwrap().starts_with("text/javascript"));
}

#[tokio::test]
async fn every_response_carries_the_security_headers() {
    let fixture = fixture().await;
    for path in ["/", "/studies/shadows-demo", "/api/studies", "/api/nope", "/nope", "/admin", "/static/style.css"] {
        let answer = call(&fixture.app, Method::GET, path, None, None).await;
        let csp = answer
            .headers
            .get(header::CONTENT_SECURITY_POLICY)
            .unwrap_or_else(|| panic!("{path}: no CSP"))
            .to_str()
            .unwrap();
        assert!(csp.contains("frame-ancestors 'none'"), "{path}: {csp}");
        assert!(csp.contains("script-src 'self'"), "{path}: {csp}");
        assert_eq!(answer.headers.get(header::X_CONTENT_TYPE_OPTIONS).unwrap(), "nosniff", "{path}");
        assert_eq!(answer.headers.get(header::X_FRAME_OPTIONS).unwrap(), "DENY", "{path}");
        assert_eq!(answer.headers.get(header::REFERRER_POLICY).unwrap(), "no-referrer", "{path}");
    }
    let answer = call(&fixture.app, Method::GET, "/api/nope", None, None).await;
    assert_eq!(answer.status, StatusCode::NOT_FOUND);
    answer.error();
}

#[tokio::test]
async fn pages_render_with_the_study_texts_escaped() {
    let fixture = fixture().await;
    let page = call(&fixture.app, Method::GET, "/studies/shadows-demo", None, None).await;
    assert_eq!(page.status, StatusCode::OK);
    let html = page.text();
    assert!(html.contains("data-study=\"shadows-demo\""));
    assert!(html.contains("Experience with computer graphics"));
    assert!(html.contains("<script src=\"/static/survey.js\"></script>"));
    assert!(!html.contains("<script>"), "no inline script (CSP)");
    let index = call(&fixture.app, Method::GET, "/", None, None).await.text();
    assert!(index.contains("/studies/shadows-demo"));
    assert!(!index.contains("/studies/web-survey"), "skipped study not listed");
    let missing = call(&fixture.app, Method::GET, "/studies/web-survey", None, None).await;
    assert_eq!(missing.status, StatusCode::NOT_FOUND);
}

#[tokio::test]
async fn admin_api_and_pages_refuse_without_the_token() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let token = fixture.admin_token.as_str();
    let calls = [
        (Method::GET, "/api/admin/studies"),
        (Method::GET, "/api/admin/studies/shadows-demo"),
        (Method::GET, "/api/admin/studies/shadows-demo/export.csv"),
        (Method::GET, "/api/admin/studies/shadows-demo/export.json"),
        (Method::GET, "/api/admin/studies/shadows-demo/conditions.csv"),
        (Method::GET, "/api/admin/studies/shadows-demo/analysis"),
        (Method::GET, "/api/admin/studies/shadows-demo/worth.svg"),
        (Method::POST, "/api/admin/studies/shadows-demo/close"),
        (Method::POST, "/api/admin/studies/shadows-demo/open"),
    ];
    let (_, participant_token) = join(app).await;
    for (method, path) in &calls {
        let answer = call(app, method.clone(), path, None, None).await;
        assert_eq!(answer.status, StatusCode::UNAUTHORIZED, "{path}");
        answer.error();
        let answer = call(app, method.clone(), path, Some("wrong-token-wrong-token"), None).await;
        assert_eq!(answer.status, StatusCode::FORBIDDEN, "{path}");
        let answer = call(app, method.clone(), path, Some(&participant_token), None).await;
        assert_eq!(answer.status, StatusCode::FORBIDDEN, "{path}: a participant token is not an admin token");
    }
    for page in ["/admin", "/admin/studies/shadows-demo", "/admin/login", "/admin/login?token=nope"] {
        let answer = call(app, Method::GET, page, None, None).await;
        assert!(
            answer.status == StatusCode::UNAUTHORIZED || answer.status == StatusCode::FORBIDDEN,
            "{page}: {}",
            answer.status
        );
        assert!(!answer.text().contains("Started"), "{page}");
    }
    // With the token.
    let answer = call(app, Method::GET, "/api/admin/studies", Some(token), None).await;
    assert_eq!(answer.status, StatusCode::OK);
    let studies = answer.json();
    assert_eq!(studies[0]["slug"], "shadows-demo");
    assert_eq!(studies[0]["started"], 1);
    let conditions = call(app, Method::GET, "/api/admin/studies/shadows-demo/conditions.csv", Some(token), None).await;
    assert_eq!(conditions.text(), "condition,shadow,ca\nLQ,0,0\nSH,1,0\nCA,0,1\nSH+CA,1,1\n");
    let missing = call(app, Method::GET, "/api/admin/studies/nope", Some(token), None).await;
    assert_eq!(missing.status, StatusCode::NOT_FOUND);

    // The login link sets an HttpOnly, SameSite=Strict cookie that opens the pages.
    let login = call(app, Method::GET, &format!("/admin/login?token={token}"), None, None).await;
    assert_eq!(login.status, StatusCode::SEE_OTHER);
    let cookie = login.headers.get(header::SET_COOKIE).unwrap().to_str().unwrap().to_string();
    assert!(cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"), "{cookie}");
    let cookie_pair = cookie.split(';').next().unwrap().to_string();
    let with_cookie = |method: Method, uri: &str, extra: Option<(&str, &str)>| {
        let mut request = Request::builder().method(method).uri(uri).header(header::COOKIE, cookie_pair.clone());
        if let Some((name, value)) = extra {
            request = request.header(name, value);
        }
        request.body(Body::empty()).unwrap()
    };
    let page = send(app, with_cookie(Method::GET, "/admin", None)).await;
    assert_eq!(page.status, StatusCode::OK);
    assert!(page.text().contains("shadows-demo"));
    let page = send(app, with_cookie(Method::GET, "/admin/studies/shadows-demo", None)).await;
    assert_eq!(page.status, StatusCode::OK, "{}", page.text());
    assert!(page.text().contains("Dropout"));
    // A change by cookie needs X-Requested-With (no cross-site form can send it).
    let close = send(app, with_cookie(Method::POST, "/api/admin/studies/shadows-demo/close", None)).await;
    assert_eq!(close.status, StatusCode::FORBIDDEN);
    let close = send(
        app,
        with_cookie(Method::POST, "/api/admin/studies/shadows-demo/close", Some(("x-requested-with", "mrstudy"))),
    )
    .await;
    assert_eq!(close.status, StatusCode::OK);
    assert_eq!(close.json(), json!({"slug": "shadows-demo", "open": false}));

    // Closed: no new participants, not listed; reopened by bearer token.
    let answer = call(
        app,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(json!({"demographics": demographics()})),
    )
    .await;
    assert_eq!(answer.status, StatusCode::FORBIDDEN);
    assert!(answer.error().contains("closed"));
    assert_eq!(call(app, Method::GET, "/api/studies", None, None).await.json(), json!([]));
    let open = call(app, Method::POST, "/api/admin/studies/shadows-demo/open", Some(token), None).await;
    assert_eq!(open.status, StatusCode::OK);
    join(app).await;
}

#[tokio::test]
async fn admin_stats_show_dropout_and_catch_failures() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let (finisher, finisher_token) = join(app).await;
    let (dropout, dropout_token) = join(app).await;
    join(app).await; // joins and answers nothing
    for trial in 1..=7 {
        let next = call(app, Method::GET, &format!("/api/participants/{finisher}/next"), Some(&finisher_token), None)
            .await
            .json();
        assert_eq!(next["trial"], trial);
        answer_trial(app, &finisher, &finisher_token, trial, "left").await;
    }
    for trial in 1..=3 {
        answer_trial(app, &dropout, &dropout_token, trial, "right").await;
    }
    let stats =
        call(app, Method::GET, "/api/admin/studies/shadows-demo", Some(&fixture.admin_token), None).await.json();
    assert_eq!(stats["started"], 3);
    assert_eq!(stats["finished"], 1);
    assert_eq!(stats["reached"], json!([3, 2, 2, 2, 1, 1, 1, 1]));
    assert_eq!(stats["stopped_after"], json!([1, 0, 0, 1, 0, 0, 0, 0]));
    assert_eq!(stats["responses"], 10);
    assert_eq!(stats["median_rt_ms"], 812.5);
    assert!((stats["completion_rate"].as_f64().unwrap() - 1.0 / 3.0).abs() < 1e-12);
    // Catch trials answered and failed, counted from the stored schedules.
    let json = call(app, Method::GET, "/api/admin/studies/shadows-demo/export.json", Some(&fixture.admin_token), None)
        .await
        .json();
    let (mut catch_responses, mut failures, mut failing) = (0, 0, 0);
    for participant in json["participants"].as_array().unwrap() {
        let mut failed = false;
        for trial in participant["schedule"].as_array().unwrap() {
            if trial["catch_expected"].is_string() && trial["response"].is_object() {
                catch_responses += 1;
                if trial["response"]["chosen"] != trial["catch_expected"] {
                    failures += 1;
                    failed = true;
                }
            }
        }
        failing += failed as i64;
    }
    assert!(catch_responses >= 1, "the finisher answered the catch trial");
    assert_eq!(stats["catch_responses"], catch_responses);
    assert_eq!(stats["catch_failures"], failures);
    assert_eq!(stats["participants_failing_catch"], failing);
    let finisher_schedule = json["participants"][0]["schedule"].as_array().unwrap().clone();
    // Every shown trial has its shown_at.
    assert!(finisher_schedule.iter().all(|trial| trial["shown_at"].is_string()), "{finisher_schedule:?}");
}

#[tokio::test]
async fn schedules_are_stored_and_reproducible_from_the_stored_seed() {
    let fixture = fixture().await;
    let app = &fixture.app;
    join(app).await;
    join(app).await;
    let json = call(app, Method::GET, "/api/admin/studies/shadows-demo/export.json", Some(&fixture.admin_token), None)
        .await
        .json();
    let study = mrstudy_server::study::load_study(&repo_studies_dir().join("shadows-demo.toml")).unwrap();
    let data_dir = tempfile::tempdir().unwrap();
    let plan = mrstudy_server::stimuli::StimulusPlan::of(&study).unwrap();
    let prepared = mrstudy_server::PreparedStudy::prepare(study, &plan, data_dir.path()).unwrap();
    for participant in json["participants"].as_array().unwrap() {
        let seed: u64 = participant["seed"].as_str().unwrap().parse().unwrap();
        let replayed = prepared.schedule(seed);
        let stored = participant["schedule"].as_array().unwrap();
        assert_eq!(replayed.len(), stored.len());
        for (replayed, stored) in replayed.iter().zip(stored) {
            assert_eq!(stored["left"], replayed.left_condition.as_str());
            assert_eq!(stored["right"], replayed.right_condition.as_str());
            assert_eq!(stored["scene_left"], replayed.left_scene.as_str());
            assert_eq!(stored["left_stimulus"], replayed.left_stimulus.as_str());
            assert_eq!(stored["right_stimulus"], replayed.right_stimulus.as_str());
        }
    }
}

#[tokio::test]
async fn live_analysis_runs_the_analysis_crate_on_the_export() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let token = fixture.admin_token.as_str();
    // Before any judgment: a clear 4xx, no numbers.
    let empty = call(app, Method::GET, "/api/admin/studies/shadows-demo/analysis", Some(token), None).await;
    assert_eq!(empty.status, StatusCode::UNPROCESSABLE_ENTITY, "{}", empty.text());
    assert!(empty.error().contains("analysis"));
    // Participants who prefer the shadowed sphere, mostly.
    for participant in 0..6 {
        let (id, participant_token) = join(app).await;
        for trial in 1..=7 {
            let next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(&participant_token), None)
                .await
                .json();
            let _ = next;
            let json =
                call(app, Method::GET, "/api/admin/studies/shadows-demo/export.json", Some(token), None).await.json();
            let schedule = json["participants"][participant]["schedule"][trial as usize - 1].clone();
            let left = schedule["left"].as_str().unwrap();
            let right = schedule["right"].as_str().unwrap();
            let score = |condition: &str| condition.contains("SH") as i32 * 2 + condition.contains("CA") as i32;
            let chosen =
                if (score(left) >= score(right)) != (trial == 3 && participant % 3 == 0) { "left" } else { "right" };
            assert_eq!(answer_trial(app, &id, &participant_token, trial, chosen).await.status, StatusCode::CREATED);
        }
    }
    let analysis = call(app, Method::GET, "/api/admin/studies/shadows-demo/analysis", Some(token), None).await;
    assert_eq!(analysis.status, StatusCode::OK, "{}", analysis.text());
    let analysis = analysis.json();
    assert_eq!(analysis["participants"], 6);
    assert_eq!(analysis["judgments"], 36, "6 participants × 6 pairs; catch trials are not judgments");
    assert_eq!(analysis["conditions"], 4);
    assert_eq!(analysis["reference"], "LQ");
    let covariates: Vec<&str> =
        analysis["covariates"].as_array().unwrap().iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(covariates, ["shadow", "ca"]);
    assert!(analysis["agreement"]["u"].is_number());
    let svg = call(app, Method::GET, "/api/admin/studies/shadows-demo/worth.svg", Some(token), None).await;
    assert_eq!(svg.status, StatusCode::OK);
    assert_eq!(svg.headers.get(header::CONTENT_TYPE).unwrap(), "image/svg+xml");
    assert!(svg.text().contains("<svg"));
    let page = call(app, Method::GET, "/admin/studies/shadows-demo", Some(token), None).await;
    assert_eq!(page.status, StatusCode::OK);
    let html = page.text();
    assert!(html.contains("coefficient of agreement u ="), "{html}");
    assert!(html.contains("<td>shadow</td>"), "factor estimates table");
    // the page's conditions table has pwcmp's JOD beside the log-worths, as `mrstudy analyze
    // --scale jod` gives it on the export; the API's JSON stays the default analysis (no JOD)
    assert!(analysis["items"].as_array().unwrap().iter().all(|item| item.get("jod").is_none()), "{analysis}");
    let csv = call(app, Method::GET, "/api/admin/studies/shadows-demo/export.csv", Some(token), None).await.text();
    let conditions =
        call(app, Method::GET, "/api/admin/studies/shadows-demo/conditions.csv", Some(token), None).await.text();
    let options = mrstudy_analysis::analysis::Options {
        scale: mrstudy_analysis::analysis::Scale::Jod,
        ..mrstudy_analysis::analysis::Options::default()
    };
    let printed = mrstudy_analysis::command::analyze_files(
        (&csv, "trials.csv"),
        Some((&conditions, "conditions.csv")),
        None,
        &options,
        true,
        mrstudy_analysis::command::Drawings::default(),
    )
    .unwrap();
    let offline: serde_json::Value = serde_json::from_str(&printed.text).unwrap();
    assert!(html.contains("<th scope=\"col\">JOD</th>"), "{html}");
    for item in offline["items"].as_array().unwrap() {
        let condition = item["condition"].as_str().unwrap();
        let start = html.find(&format!("<tr><td>{condition}</td>")).unwrap_or_else(|| panic!("{condition}: {html}"));
        let row = &html[start..start + html[start..].find("</tr>").unwrap()];
        let jod = item["jod"].as_f64().unwrap_or_else(|| panic!("{item}"));
        let log_worth = item["log_worth"].as_f64().unwrap();
        assert!(row.contains(&format!("<td>{log_worth:.3}</td><td>{jod:.2}</td>")), "{condition}: {jod:.2} in {row}");
    }
    assert!(html.contains("id=\"jod-note\">pwcmp"), "pwcmp's outlier analysis beside the JOD: {html}");
}

#[tokio::test]
async fn the_database_is_wal_with_full_sync() {
    let data_dir = tempfile::tempdir().unwrap();
    let storage =
        mrstudy_server::Storage::open(&mrstudy_server::storage::Database::in_data_dir(data_dir.path())).await.unwrap();
    let journal_mode: String = sqlx::query_scalar("PRAGMA journal_mode").fetch_one(&storage.read).await.unwrap();
    let synchronous: i64 = sqlx::query_scalar("PRAGMA synchronous").fetch_one(&storage.read).await.unwrap();
    let foreign_keys: i64 = sqlx::query_scalar("PRAGMA foreign_keys").fetch_one(&storage.read).await.unwrap();
    assert_eq!(journal_mode, "wal");
    assert_eq!(synchronous, 2, "synchronous = FULL");
    assert_eq!(foreign_keys, 1);
}

#[tokio::test]
async fn completion_redirect_fills_in_the_code_and_the_prolific_id() {
    // The demo study, with a crowdsourcing redirect, in a studies directory of its own.
    let work = tempfile::tempdir().unwrap();
    let studies = demo_studies(work.path(), |text| {
        let text = text.replace(
            "[completion]\ncode = \"DEMO-7F3A\"",
            "[completion]\ncode = \"DEMO-7F3A\"\nredirect = \"https://app.prolific.com/submissions/complete?cc={code}&pid={PROLIFIC_PID}\"",
        );
        assert!(text.contains("redirect ="));
        text
    });
    let Started { app, .. } = start(work.path(), &studies).await;
    let (id, token) = join(&app).await; // with PROLIFIC_PID = abc123
    for trial in 1..=7 {
        assert_eq!(answer_trial(&app, &id, &token, trial, "left").await.status, StatusCode::CREATED);
    }
    let done = call(&app, Method::GET, &format!("/api/participants/{id}/next"), Some(&token), None).await.json();
    assert_eq!(
        done,
        json!({"done": true, "completion_code": "DEMO-7F3A", "redirect": "https://app.prolific.com/submissions/complete?cc=DEMO-7F3A&pid=abc123"})
    );
}

// ---------------------------------------------------------------------------------------------
// Trustworthy responses: only served trials can be answered, too-fast answers are flagged,
// preview links make pilots, one run per external id, screen requirements.

/// The demo study with extra top-level keys (participation keys), in a fresh data directory.
async fn fixture_with(extra: &str) -> Fixture {
    fixture_with_demo(|text| before_texts(&text, extra)).await
}

async fn database(fixture: &Fixture) -> sqlx::AnyPool {
    support::connect(&fixture.database).await
}

async fn post_response(app: &Router, id: &str, token: &str, trial: i64, rt_ms: f64) -> Answer {
    call(
        app,
        Method::POST,
        &format!("/api/participants/{id}/responses"),
        Some(token),
        Some(json!({"trial": trial, "chosen": "left", "rt_ms": rt_ms})),
    )
    .await
}

#[tokio::test]
async fn a_response_to_a_trial_never_served_is_refused_and_nothing_is_stored() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let (id, token) = join(app).await;
    let answer = post_response(app, &id, &token, 1, 900.0).await;
    assert_eq!(answer.status, StatusCode::CONFLICT, "{}", answer.text());
    assert!(answer.error().contains("never served"), "{}", answer.text());
    let db = database(&fixture).await;
    let stored: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM responses").fetch_one(&db).await.unwrap();
    assert_eq!(stored, 0, "a refused response stores nothing");
    let answered: i64 = sqlx::query_scalar("SELECT answered FROM participants").fetch_one(&db).await.unwrap();
    assert_eq!(answered, 0);
    // Once served, the same answer is taken.
    call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(&token), None).await;
    let answer = post_response(app, &id, &token, 1, 900.0).await;
    assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    // Trial 2 has not been served yet: refused too.
    let answer = post_response(app, &id, &token, 2, 900.0).await;
    assert_eq!(answer.status, StatusCode::CONFLICT);
    assert!(answer.error().contains("never served") && answer.error().contains("next trial is 2"));
}

#[tokio::test]
async fn a_too_fast_response_is_stored_and_flagged_by_the_client_or_the_server_clock() {
    let fixture = fixture_with("min_response_ms = 300").await;
    let app = &fixture.app;
    let (id, token) = join(app).await;
    let next = format!("/api/participants/{id}/next");
    // 1: 120 ms by the client's clock (and at once by the server's).
    call(app, Method::GET, &next, Some(&token), None).await;
    assert_eq!(post_response(app, &id, &token, 1, 120.0).await.status, StatusCode::CREATED);
    // 2: a plausible client time, but the server served the trial a moment ago.
    call(app, Method::GET, &next, Some(&token), None).await;
    assert_eq!(post_response(app, &id, &token, 2, 812.0).await.status, StatusCode::CREATED);
    // 3: slow enough by both clocks.
    call(app, Method::GET, &next, Some(&token), None).await;
    tokio::time::sleep(std::time::Duration::from_millis(400)).await;
    assert_eq!(post_response(app, &id, &token, 3, 812.0).await.status, StatusCode::CREATED);
    let db = database(&fixture).await;
    let rows: Vec<(i64, i64, f64)> =
        sqlx::query_as("SELECT trial, too_fast, served_ms FROM responses ORDER BY trial").fetch_all(&db).await.unwrap();
    assert_eq!(rows.len(), 3, "too-fast responses are stored, never dropped");
    assert_eq!((rows[0].1, rows[1].1, rows[2].1), (1, 1, 0), "{rows:?}");
    assert!(rows[2].2 >= 380.0, "the server's time from serving to answer: {rows:?}");
}

#[tokio::test]
async fn a_preview_link_makes_a_pilot_also_while_the_study_is_closed() {
    let fixture = fixture().await;
    let app = &fixture.app;
    let closed =
        call(app, Method::POST, "/api/admin/studies/shadows-demo/close", Some(&fixture.admin_token), None).await;
    assert!(closed.status.is_success(), "{}", closed.text());
    // A preview token as the admin API stores it (SHA-256 of the token).
    let token = "preview-token-for-the-test-0123456789abcdef";
    let hash = {
        use sha2::Digest;
        sha2::Sha256::digest(token.as_bytes()).to_vec()
    };
    let writer = database(&fixture).await;
    sqlx::query(
        "INSERT INTO previews (token_sha256, study, created_at) VALUES ($1, 'shadows-demo', '2026-11-23T00:00:00.000Z')",
    )
    .bind(&hash)
    .execute(&writer)
    .await
    .unwrap();
    let body = |preview: &str| json!({"demographics": demographics(), "preview": preview});
    let refused =
        call(app, Method::POST, "/api/studies/shadows-demo/participants", None, Some(body("not-a-preview"))).await;
    assert_eq!(refused.status, StatusCode::FORBIDDEN);
    assert!(refused.error().contains("preview link"));
    let closed_join = call(
        app,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(json!({"demographics": demographics()})),
    )
    .await;
    assert_eq!(closed_join.status, StatusCode::FORBIDDEN, "closed to everybody else");
    let joined = call(app, Method::POST, "/api/studies/shadows-demo/participants", None, Some(body(token))).await;
    assert_eq!(joined.status, StatusCode::CREATED, "{}", joined.text());
    let pilots: Vec<(String, i64)> =
        sqlx::query_as("SELECT id, pilot FROM participants").fetch_all(&writer).await.unwrap();
    assert_eq!(pilots, vec![(joined.json()["participant"].as_str().unwrap().to_string(), 1)]);
}

/// A join to `app` with the given URL parameters and kept token (the page sends the token it kept
/// for the study link).
async fn join_with(app: &Router, url_params: Value, token: Option<&str>) -> Answer {
    call(
        app,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(match token {
            Some(token) => json!({"demographics": demographics(), "url_params": url_params, "token": token}),
            None => json!({"demographics": demographics(), "url_params": url_params}),
        }),
    )
    .await
}

/// With `unique_external_id`, a second join with the same external id resumes the run only
/// with that run's token (the page keeps it): without it the join is refused with 409 and one
/// sentence, and the first run keeps its token. Fails on the code that resumed anyone with the
/// id and gave them a new token (revoking the first run's).
#[tokio::test]
async fn one_run_per_external_id_resumes_only_with_the_runs_token() {
    let fixture = fixture_with("unique_external_id = true").await;
    let app = &fixture.app;
    let first = join_with(app, json!({"PROLIFIC_PID": "PID-1"}), None).await;
    assert_eq!(first.status, StatusCode::CREATED);
    let first = first.json();
    let (id, token) = (first["participant"].as_str().unwrap(), first["token"].as_str().unwrap());
    assert_eq!(answer_trial(app, id, token, 1, "left").await.status, StatusCode::CREATED);
    // someone else with the id: refused, one sentence, and the run is untouched
    for stranger in [None, Some("0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef")] {
        let again = join_with(app, json!({"PROLIFIC_PID": "PID-1"}), stranger).await;
        assert_eq!(again.status, StatusCode::CONFLICT, "{}", again.text());
        let sentence = again.error();
        assert!(sentence.contains("already started with this ID") && sentence.matches(". ").count() == 0, "{sentence}");
        assert!(again.json().get("participant").is_none() && again.json().get("token").is_none());
    }
    assert_eq!(answer_trial(app, id, token, 2, "left").await.status, StatusCode::CREATED, "the first run goes on");
    // the page that joined first resumes with its token, which stays the run's token
    let resumed = join_with(app, json!({"PROLIFIC_PID": "PID-1"}), Some(token)).await;
    assert_eq!(resumed.status, StatusCode::OK, "{}", resumed.text());
    let resumed = resumed.json();
    assert_eq!((resumed["participant"].as_str(), resumed["token"].as_str()), (Some(id), Some(token)));
    assert_eq!(resumed["resumed"], true);
    let next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    assert_eq!(next.json()["trial"], 3, "continues at its next unanswered trial");
    // another id is another run; a kept token of another run does not resume this one
    let other = join_with(app, json!({"PROLIFIC_PID": "PID-2"}), Some(token)).await;
    assert_eq!(other.status, StatusCode::CREATED, "{}", other.text());
    assert_ne!(other.json()["participant"], id);
    let db = database(&fixture).await;
    let count: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM participants").fetch_one(&db).await.unwrap();
    assert_eq!(count, 2);
}

/// External ids are compared after Unicode NFKC, without invisible characters, trimmed and in
/// lower case: each spelling below is the first run's id (409 without its token, resumed with
/// it). The key is the declared id parameter (`PROLIFIC_PID`, the first of `url_params`) only:
/// two people sharing a `STUDY_ID` without an id of their own are two runs. Fails on the code
/// that trimmed ASCII white space only and fell back to `STUDY_ID`.
#[tokio::test]
async fn external_ids_are_normalised_and_only_the_declared_parameter_is_the_key() {
    let fixture = fixture_with("unique_external_id = true").await;
    let app = &fixture.app;
    let first = join_with(app, json!({"PROLIFIC_PID": "5f1a2B3c"}), None).await;
    assert_eq!(first.status, StatusCode::CREATED);
    let first = first.json();
    let (id, token) = (first["participant"].as_str().unwrap(), first["token"].as_str().unwrap());
    for spelling in [
        "5f1a2B3c ",
        "\t5f1a2B3c",
        "5f1a2B3c\u{00A0}",
        "5F1A2B3C",
        "5f1a\u{200B}2B3c",
        "\u{FEFF}5f1a2B3c\u{200D}",
        "\u{FF15}\u{FF46}1a2B3c",
    ] {
        let refused = join_with(app, json!({"PROLIFIC_PID": spelling}), None).await;
        assert_eq!(refused.status, StatusCode::CONFLICT, "{spelling:?}: {}", refused.text());
        let resumed = join_with(app, json!({"PROLIFIC_PID": spelling}), Some(token)).await;
        assert_eq!(resumed.status, StatusCode::OK, "{spelling:?}: {}", resumed.text());
        assert_eq!(resumed.json()["participant"], id, "{spelling:?}");
    }
    // no fallback to another parameter: a shared STUDY_ID is no person's id
    let shared = json!({"STUDY_ID": "study-7", "SESSION_ID": "session-1"});
    let one = join_with(app, shared.clone(), None).await;
    let two = join_with(app, shared, None).await;
    assert_eq!((one.status, two.status), (StatusCode::CREATED, StatusCode::CREATED), "{}", two.text());
    assert_ne!(one.json()["participant"], two.json()["participant"]);
    // a blank or invisible id is no id
    let blank = join_with(app, json!({"PROLIFIC_PID": " \u{200B}\u{00A0}"}), None).await;
    assert_eq!(blank.status, StatusCode::CREATED, "{}", blank.text());
}

/// On two servers of one database: a run's token goes on working on both after a stranger's
/// join with its id, and a participant deleted through one server is refused by the other at
/// once (403), though that one had the credentials in memory. Fails on the code that resumed
/// the stranger (the first run's token then still answered 201 on the server that had it in
/// memory) and trusted its memory of credentials.
#[tokio::test]
async fn on_two_servers_a_deleted_participants_token_is_refused_by_both() {
    let work = tempfile::tempdir().unwrap();
    let studies = studies_dir(work.path(), |text| text);
    let file = studies.join("shadows-demo.toml");
    let text =
        std::fs::read_to_string(&file).unwrap().replacen("\n[texts]", "\nunique_external_id = true\n\n[texts]", 1);
    std::fs::write(&file, text).unwrap();
    let data = work.path().join("data");
    let database = test_database(&data).await;
    let server = async || prepare_on(&database, &data, &studies).await.unwrap();
    let (first, second) = (server().await, server().await);
    let admin_token = first.admin_token.clone();
    let (one, two) = (app(first.state), app(second.state));
    let joined = join_with(&one, json!({"PROLIFIC_PID": "PID-9"}), None).await.json();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    // the second server learns the credentials (and keeps them in memory)
    assert_eq!(answer_trial(&two, id, token, 1, "left").await.status, StatusCode::CREATED);
    // a stranger's join on the first server changes nothing on either
    assert_eq!(join_with(&one, json!({"PROLIFIC_PID": "PID-9"}), None).await.status, StatusCode::CONFLICT);
    assert_eq!(answer_trial(&two, id, token, 2, "left").await.status, StatusCode::CREATED);
    assert_eq!(answer_trial(&one, id, token, 3, "left").await.status, StatusCode::CREATED);
    // deleted through the first server: refused by the second at once
    let deleted = call(&one, Method::DELETE, &format!("/api/admin/participants/{id}"), Some(&admin_token), None).await;
    assert!(deleted.status.is_success(), "{}", deleted.text());
    let after = post_response(&two, id, token, 4, 900.0).await;
    assert_eq!(after.status, StatusCode::FORBIDDEN, "{}", after.text());
    let next = call(&two, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    assert_eq!(next.status, StatusCode::FORBIDDEN, "{}", next.text());
    let db = support::connect(&database).await;
    let stored: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM responses").fetch_one(&db).await.unwrap();
    assert_eq!(stored, 0, "nothing of the participant is left, nor stored after the deletion");
}

#[tokio::test]
async fn screen_requirements_refuse_a_phone_and_a_small_window_and_count_the_screen_out() {
    let fixture =
        fixture_with("devices = [\"desktop\"]\nmin_viewport = [1000, 700]\norientation = \"landscape\"").await;
    let app = &fixture.app;
    let db = database(&fixture).await;
    let screen_outs =
        || async { sqlx::query_scalar::<_, i64>("SELECT COUNT(*) FROM screen_outs").fetch_one(&db).await.unwrap() };
    let check = |client: Value, screen_out: Option<String>| {
        call(
            app,
            Method::POST,
            "/api/studies/shadows-demo/screen",
            None,
            Some(json!({"client": client, "screen_out": screen_out})),
        )
    };
    let phone = json!({"device": "phone", "viewport": [390, 844]});
    let answer = check(phone.clone(), None).await;
    assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    let answer = answer.json();
    assert_eq!(answer["meets"], false);
    assert!(answer["reason"].as_str().unwrap().contains("desktop or laptop computer"), "{answer}");
    let id = answer["screen_out"].as_str().unwrap().to_string();
    assert_eq!(screen_outs().await, 1);
    // The same visitor checking again is not counted twice.
    check(phone.clone(), Some(id.clone())).await;
    assert_eq!(screen_outs().await, 1);
    // A small desktop window: the sentence names both sizes.
    let small = check(json!({"device": "desktop", "viewport": [800, 600]}), None).await.json();
    assert!(
        small["reason"].as_str().unwrap().contains("1000 × 700")
            && small["reason"].as_str().unwrap().contains("800 × 600"),
        "{small}"
    );
    let portrait = check(json!({"device": "desktop", "viewport": [1000, 1400]}), None).await.json();
    assert!(portrait["reason"].as_str().unwrap().contains("landscape"), "{portrait}");
    assert_eq!(screen_outs().await, 3);
    // A fitting screen meets them.
    let fits = check(json!({"device": "desktop", "viewport": [1280, 800]}), None).await;
    assert_eq!((fits.status, fits.json()["meets"].clone()), (StatusCode::OK, json!(true)));
    // Joining from a phone is refused by the server too, and counted.
    let refused = call(
        app,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(json!({"demographics": demographics(), "client": phone})),
    )
    .await;
    assert_eq!(refused.status, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(refused.error().contains("desktop"));
    assert_eq!(screen_outs().await, 4);
    let participants: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM participants").fetch_one(&db).await.unwrap();
    assert_eq!(participants, 0);
    // The first visitor moved to a computer and joined: their screen-out is withdrawn.
    let joined = call(
        app,
        Method::POST,
        "/api/studies/shadows-demo/participants",
        None,
        Some(json!({"demographics": demographics(), "client": {"device": "desktop", "viewport": [1280, 800]}, "screen_out": id})),
    )
    .await;
    assert_eq!(joined.status, StatusCode::CREATED, "{}", joined.text());
    assert_eq!(screen_outs().await, 3);
}

// ---------------------------------------------------------------------------------------------
// Listening at once (issue 47): a study whose stimuli are still to render is known but not
// served until they are.

/// A study of two conditions on a built-in scene, rendered tiny, with the demo study's texts.
fn write_rendered_mini(dir: &Path) {
    let demo = std::fs::read_to_string(repo_studies_dir().join("shadows-demo.toml")).unwrap();
    let texts = &demo[demo.find("[texts]").unwrap()..demo.find("[[demographics]]").unwrap()];
    let study = format!(
        "slug = \"rendered-mini\"\ntitle = \"Rendered\"\nkind = \"paired-comparison\"\nquestion = \"Which fits better?\"\n\n{texts}\n\
         [[factors]]\nname = \"gi\"\n\n[[conditions]]\nname = \"LQ\"\nlevels = {{ gi = 0 }}\n\n\
         [[conditions]]\nname = \"GI\"\nlevels = {{ gi = 1 }}\n\n[render]\nsize = [48, 36]\nspp = 2\nvpls = 16\n\n\
         [[scenes]]\nname = \"box\"\nrender = \"dir-lamp-box\"\n\n[design]\npairs = \"all\"\nrepetitions = 1\nscenes = \"same\"\n\n\
         [completion]\ncode = \"MINI\"\n"
    );
    std::fs::write(dir.join("rendered-mini.toml"), study).unwrap();
}

/// `serve::load` serves the demo study at once and leaves the rendered study pending: the list
/// of open studies answers without it, joining it (and its screen check) answers 503 "This study
/// opens in a few minutes." with `Retry-After`, its page says so with the same status, and the
/// admin page shows it with a progress bar. Once `prepare_pending` has rendered its stimuli the
/// same router serves it (no restart). Fails where `serve` renders before it serves (the study
/// is then either served at once or not at all).
#[tokio::test]
async fn a_study_still_being_prepared_opens_in_a_few_minutes_then_is_served_without_a_restart() {
    let work = tempfile::tempdir().unwrap();
    let studies = work.path().join("studies");
    copy_demo_study(&studies);
    write_rendered_mini(&studies);
    let data = work.path().join("data");
    let database = test_database(&data).await;
    let Prepared { state, admin_token, slugs, pending, skipped, .. } =
        mrstudy_server::serve::load(&database, &data, &studies, None).await.unwrap();
    assert_eq!((slugs, skipped), (vec!["shadows-demo".to_string()], Vec::<String>::new()));
    assert_eq!(pending.iter().map(|study| study.study.slug.as_str()).collect::<Vec<_>>(), ["rendered-mini"]);
    assert!(!data.join("stimuli/rendered").exists(), "load renders nothing");
    let app = app(state.clone());
    let open_slugs = async || -> Vec<String> {
        let listed = call(&app, Method::GET, "/api/studies", None, None).await;
        assert_eq!(listed.status, StatusCode::OK);
        listed.json().as_array().unwrap().iter().map(|study| study["slug"].as_str().unwrap().to_string()).collect()
    };
    assert_eq!(open_slugs().await, ["shadows-demo"]);
    for (uri, body) in [
        ("/api/studies/rendered-mini/participants", json!({"demographics": {}})),
        ("/api/studies/rendered-mini/screen", json!({"client": {}})),
    ] {
        let refused = call(&app, Method::POST, uri, None, Some(body)).await;
        assert_eq!(refused.status, StatusCode::SERVICE_UNAVAILABLE, "{uri}: {}", refused.text());
        assert_eq!(refused.error(), "This study opens in a few minutes.");
        let retry: u64 = refused.headers[header::RETRY_AFTER].to_str().unwrap().parse().unwrap();
        assert!((10..=120).contains(&retry), "{retry}");
    }
    let page = call(&app, Method::GET, "/studies/rendered-mini", None, None).await;
    assert_eq!(page.status, StatusCode::SERVICE_UNAVAILABLE);
    assert!(page.headers.contains_key(header::RETRY_AFTER));
    assert!(
        page.text().contains("This study opens in a few minutes.") && page.text().contains("http-equiv=\"refresh\"")
    );
    let cookie = support::admin_session_cookie(&app, &admin_token).await;
    let admin_page = async || {
        let request = Request::builder().uri("/admin").header(header::COOKIE, &cookie).body(Body::empty()).unwrap();
        send(&app, request).await.text()
    };
    let overview = admin_page().await;
    assert!(overview.contains("Being prepared") && overview.contains("<progress"), "{overview}");
    assert!(overview.contains("waiting to render its 2 stimuli"), "{overview}");
    // a study that is neither served nor prepared is still a 404
    let unknown =
        call(&app, Method::POST, "/api/studies/nope/participants", None, Some(json!({"demographics": {}}))).await;
    assert_eq!(unknown.status, StatusCode::NOT_FOUND);

    let mut outcomes = Vec::new();
    mrstudy_server::serve::prepare_pending(&state, pending, None, |outcome| {
        outcomes.push(outcome.map(str::to_string));
    })
    .await;
    if let [Err(warning)] = outcomes.as_slice()
        && warning.contains("adapter")
    {
        eprintln!("skipping the rest: no GPU adapter ({warning})");
        assert!(admin_page().await.contains("not served: "));
        return;
    }
    assert_eq!(outcomes, [Ok("rendered-mini".to_string())]);
    assert_eq!(open_slugs().await, ["shadows-demo", "rendered-mini"]);
    let joined =
        call(&app, Method::POST, "/api/studies/rendered-mini/participants", None, Some(json!({"demographics": {}})))
            .await;
    assert_eq!(joined.status, StatusCode::CREATED, "{}", joined.text());
    assert_eq!(call(&app, Method::GET, "/studies/rendered-mini", None, None).await.status, StatusCode::OK);
    assert!(!admin_page().await.contains("Being prepared"));
}

/// Bytes saved by serving lossless WebP: total PNG bytes against lossless WebP bytes over the
/// stimuli in `$MRSTUDY_STIMULI` (a data directory's `stimuli/`), checking every copy is exact.
/// `MRSTUDY_STIMULI=/path/to/data/stimuli cargo test -p mrstudy-server --test router -- --ignored webp_bytes --nocapture`
#[test]
#[ignore = "measurement over a data directory's stimuli"]
fn webp_bytes_saved_on_stored_stimuli() {
    let dir = PathBuf::from(std::env::var("MRSTUDY_STIMULI").expect("MRSTUDY_STIMULI"));
    let (mut count, mut png_bytes, mut webp_bytes) = (0, 0, 0);
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|extension| extension != "png") {
            continue;
        }
        let png = std::fs::read(&path).unwrap();
        let webp = mrstudy_server::pages::lossless_webp(&png).expect("an 8-bit PNG");
        let decoded = image::load_from_memory_with_format(&webp, image::ImageFormat::WebP).unwrap();
        let original = image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap();
        assert_eq!(decoded.to_rgba8(), original.to_rgba8(), "{}", path.display());
        count += 1;
        png_bytes += png.len();
        webp_bytes += webp.len();
    }
    assert!(count > 0, "no PNG in {}", dir.display());
    println!(
        "{count} stimuli: PNG {png_bytes} bytes, lossless WebP {webp_bytes} bytes ({:.1} % of the PNG bytes)",
        100.0 * webp_bytes as f64 / png_bytes as f64
    );
}

/// Issue 49, item 3: "not sure" is an answer only where the study says `allow_tie = true`; it
/// is stored and exported as `chosen = "tie"` (JSON: `chosen_condition` null), is an answer
/// like the others (a different one after it is a 409).
#[tokio::test]
async fn a_not_sure_answer_is_a_tie_only_where_the_study_allows_it() {
    let forced = fixture().await;
    let (id, token) = join(&forced.app).await;
    let refused = answer_trial(&forced.app, &id, &token, 1, "tie").await;
    assert_eq!(refused.status, StatusCode::UNPROCESSABLE_ENTITY, "{}", refused.text());
    assert!(refused.error().contains("no \"not sure\" answer"), "{}", refused.error());
    assert_eq!(answer_trial(&forced.app, &id, &token, 1, "left").await.status, StatusCode::CREATED);

    let fixture = fixture_with("allow_tie = true").await;
    let app = &fixture.app;
    let page = call(app, Method::GET, "/studies/shadows-demo", None, None).await.text();
    assert!(page.contains("id=\"choose-tie\""), "the page offers \"Not sure\"");
    assert!(!call(&forced.app, Method::GET, "/studies/shadows-demo", None, None).await.text().contains("choose-tie"));
    let (id, token) = join(app).await;
    let tie = answer_trial(app, &id, &token, 1, "tie").await;
    assert_eq!(tie.status, StatusCode::CREATED, "{}", tie.text());
    assert_eq!(tie.json(), json!({"trial": 1, "chosen": "tie"}));
    assert_eq!(answer_trial(app, &id, &token, 1, "tie").await.status, StatusCode::OK);
    assert_eq!(answer_trial(app, &id, &token, 1, "left").await.status, StatusCode::CONFLICT);
    // (one of the seven trials is a catch trial, which the CSV leaves out: three ties give rows)
    for trial in 2..=3 {
        assert_eq!(answer_trial(app, &id, &token, trial, "tie").await.status, StatusCode::CREATED);
    }
    assert_eq!(answer_trial(app, &id, &token, 4, "right").await.status, StatusCode::CREATED);
    let csv = call(app, Method::GET, "/api/admin/studies/shadows-demo/export.csv", Some(&fixture.admin_token), None)
        .await
        .text();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let chosen = header.iter().position(|column| *column == "chosen").unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|line| line.split(',').collect()).collect();
    let ties = rows.iter().filter(|row| row[chosen] == "tie").count();
    let trial_of = |row: &Vec<&str>| row[header.iter().position(|column| *column == "trial").unwrap()].to_string();
    assert!(ties >= 2, "{csv}");
    assert!(rows.iter().all(|row| (row[chosen] == "tie") == (trial_of(row) != "4")), "{csv}");
    let json = call(app, Method::GET, "/api/admin/studies/shadows-demo/export.json", Some(&fixture.admin_token), None)
        .await
        .json();
    let first = &json["participants"][0]["schedule"][0]["response"];
    assert_eq!(first["chosen"], "tie", "{json}");
    assert_eq!(first["chosen_condition"], Value::Null);
}
