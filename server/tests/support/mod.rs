//! What the router-level test binaries share: the demo study copied into a test's studies
//! folder (and changed), a server prepared on it ([`start`]), joining, and requests through
//! `app(state)` with `oneshot` with their answers read back. The lab study is in `lab_study.rs`.
// Each test binary includes this module and uses a different part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use axum::Router;
use axum::body::Body;
use axum::http::{HeaderMap, Method, Request, StatusCode, header};
use http_body_util::BodyExt;
use mrstudy_server::AppState;
use mrstudy_server::limits::Limits;
use mrstudy_server::serve::{Prepared, prepare_on};
use mrstudy_server::storage::Database;
use serde_json::Value;
use tower::ServiceExt;

/// The database a test's server keeps its data in: sqlite in `data_dir`, or, when the
/// environment says `MRSTUDY_TEST_DATABASE=postgres` (scripts/test.sh runs the router and
/// end-to-end suites a second time so), a new database on the PostgreSQL server of
/// `MRSTUDY_TEST_POSTGRES`.
pub async fn test_database(data_dir: &Path) -> mrstudy_server::storage::Database {
    use mrstudy_server::storage::Database;
    match std::env::var("MRSTUDY_TEST_DATABASE").as_deref() {
        Ok("postgres") => Database::Postgres(
            new_postgres().await.expect("MRSTUDY_TEST_DATABASE=postgres needs MRSTUDY_TEST_POSTGRES"),
        ),
        Ok("sqlite") | Err(_) => Database::in_data_dir(data_dir),
        Ok(other) => panic!("MRSTUDY_TEST_DATABASE={other}: expected sqlite or postgres"),
    }
}

/// A new database on the PostgreSQL server of `MRSTUDY_TEST_POSTGRES` (a URL of the server's
/// `postgres` database), or `None` when that is not set (scripts/test.sh sets it).
pub async fn new_postgres() -> Option<String> {
    let server = std::env::var("MRSTUDY_TEST_POSTGRES").ok()?;
    Some(mrstudy_server::storage::new_postgres_database(&server, "mrstudy_test").await.unwrap())
}

/// A pool on a test's database, for reading what the server stored.
pub async fn connect(database: &mrstudy_server::storage::Database) -> sqlx::AnyPool {
    use mrstudy_server::storage::Database;
    sqlx::any::install_default_drivers();
    let url = match database {
        Database::Sqlite(path) => format!("sqlite://{}", path.display()),
        Database::Postgres(url) => url.clone(),
    };
    sqlx::AnyPool::connect(&url).await.unwrap()
}

/// The repository's `studies/` folder.
pub fn repo_studies_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies")
}

/// Copies the demo study (its file and its images) into `dir`.
pub fn copy_demo_study(dir: &Path) {
    let repo = repo_studies_dir();
    std::fs::create_dir_all(dir.join("shadows-demo")).unwrap();
    std::fs::copy(repo.join("shadows-demo.toml"), dir.join("shadows-demo.toml")).unwrap();
    for entry in std::fs::read_dir(repo.join("shadows-demo")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, dir.join("shadows-demo").join(path.file_name().unwrap())).unwrap();
    }
}

/// The demo study copied into `work/studies`, its file's text changed by `edit`: the studies
/// folder.
pub fn demo_studies(work: &Path, edit: impl FnOnce(String) -> String) -> PathBuf {
    let dir = work.join("studies");
    copy_demo_study(&dir);
    let file = dir.join("shadows-demo.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, edit(text)).unwrap();
    dir
}

/// A study file's `text` with `lines` (top-level keys) put before its `[texts]` table.
pub fn before_texts(text: &str, lines: &str) -> String {
    text.replacen("\n[texts]", &format!("\n{lines}\n[texts]"), 1)
}

/// A server prepared on the studies in `studies`, its data in `work/data` on the test's
/// database ([`test_database`]): the router on its state and what `prepare_on` said.
pub struct Started {
    pub app: Router,
    pub state: AppState,
    pub admin_token: String,
    /// The studies not served, one line each.
    pub skipped: Vec<String>,
    pub database: Database,
    pub data: PathBuf,
}

/// [`Started`] under the default limits.
pub async fn start(work: &Path, studies: &Path) -> Started {
    start_limited(work, studies, None).await
}

/// [`Started`] under `limits` (the state's own when `None`).
pub async fn start_limited(work: &Path, studies: &Path, limits: Option<Limits>) -> Started {
    let data = work.join("data");
    let database = test_database(&data).await;
    let Prepared { state, admin_token, skipped, .. } = prepare_on(&database, &data, studies).await.unwrap();
    let state = match limits {
        Some(limits) => state.with_limits(limits),
        None => state,
    };
    Started { app: mrstudy_server::app(state.clone()), state, admin_token, skipped, database, data }
}

/// Joins study `slug` with the JSON `body` and expects 201: the participant's id and token and
/// the whole answer.
pub async fn join(app: &Router, slug: &str, body: Value) -> (String, String, Value) {
    let answer = call(app, Method::POST, &format!("/api/studies/{slug}/participants"), None, Some(body)).await;
    assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    let json = answer.json();
    (json["participant"].as_str().unwrap().to_string(), json["token"].as_str().unwrap().to_string(), json)
}

/// An answer of the router: status, headers and body.
pub struct Answer {
    pub status: StatusCode,
    pub headers: HeaderMap,
    pub bytes: Vec<u8>,
}

impl Answer {
    pub fn json(&self) -> Value {
        serde_json::from_slice(&self.bytes)
            .unwrap_or_else(|_| panic!("not JSON: {}", String::from_utf8_lossy(&self.bytes)))
    }
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.bytes).into_owned()
    }
    /// The sentence of a `{"error": "…"}` body (never empty).
    pub fn error(&self) -> String {
        let json = self.json();
        let message = json["error"].as_str().unwrap_or_else(|| panic!("no error field: {json}")).to_string();
        assert!(!message.is_empty());
        message
    }
}

pub async fn send(app: &Router, request: Request<Body>) -> Answer {
    let response = app.clone().oneshot(request).await.unwrap();
    let status = response.status();
    let headers = response.headers().clone();
    let bytes = response.into_body().collect().await.unwrap().to_bytes().to_vec();
    Answer { status, headers, bytes }
}

/// A request with an optional bearer token and JSON body.
pub async fn call(app: &Router, method: Method, uri: &str, token: Option<&str>, body: Option<Value>) -> Answer {
    let mut request = Request::builder().method(method).uri(uri);
    if let Some(token) = token {
        request = request.header(header::AUTHORIZATION, format!("Bearer {token}"));
    }
    let request = match body {
        Some(body) => {
            request.header(header::CONTENT_TYPE, "application/json").body(Body::from(body.to_string())).unwrap()
        }
        None => request.body(Body::empty()).unwrap(),
    };
    send(app, request).await
}

/// Logs in with the admin token (`GET /admin/login?token=…`) and returns the `Cookie` header
/// value of the admin session it starts.
pub async fn admin_session_cookie(app: &Router, admin_token: &str) -> String {
    let login = call(app, Method::GET, &format!("/admin/login?token={admin_token}"), None, None).await;
    assert_eq!(login.status, axum::http::StatusCode::SEE_OTHER, "{}", login.text());
    let set_cookie = login.headers.get(header::SET_COOKIE).expect("the login sets the cookie").to_str().unwrap();
    set_cookie.split(';').next().unwrap().to_string()
}

/// Demographics that pass the demo study's form.
pub fn demographics() -> Value {
    serde_json::json!({"gender": "female", "age": 31, "cg_experience": "none", "vision": "normal"})
}
