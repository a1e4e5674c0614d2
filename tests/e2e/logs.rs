//! The operator's log of `mrstudy serve` (issue 46, item 7): with `--log-format json` and
//! `RUST_LOG` unset, each request is one JSON line on stderr with its method, route template,
//! status, latency and caller, and neither the participant's token and id nor the admin token
//! (which the login link carries in its query) is in the log.

use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::support::{Server, client, demographics, studies_dir};

#[test]
fn serve_logs_one_json_line_per_request_on_stderr_without_tokens() {
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::try_start_with_args(
        data_dir.path(),
        "127.0.0.1:0",
        &studies_dir(),
        &[("RUST_LOG", "")],
        &["--log-format", "json"],
        Duration::from_secs(60),
    )
    .unwrap();
    let http = client();
    let joined: Value = http
        .post(format!("{}/api/studies/shadows-demo/participants", server.base))
        .json(&json!({"demographics": demographics(), "url_params": {"PROLIFIC_PID": "pid-e2e-secret"}}))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    let next = http
        .get(format!("{}/api/participants/{id}/next?token={token}", server.base))
        .bearer_auth(token)
        .send()
        .unwrap();
    assert_eq!(next.status(), 200);
    let login = reqwest::blocking::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap()
        .get(format!("{}/admin/login?token={}", server.base, server.admin_token))
        .send()
        .unwrap();
    assert_eq!(login.status(), 303);

    let mut lines = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    while lines.iter().filter(|line: &&String| line.contains("\"answered\"")).count() < 3 && Instant::now() < deadline {
        if let Ok(line) = server.stderr.recv_timeout(Duration::from_millis(100)) {
            lines.push(line);
        }
    }
    let log = lines.join("\n");
    let requests: Vec<Value> = lines
        .iter()
        .filter(|line| line.contains("\"answered\""))
        .map(|line| serde_json::from_str(line).unwrap_or_else(|_| panic!("not one JSON object: {line}")))
        .collect();
    let seen: Vec<(String, String, u64, String)> = requests
        .iter()
        .map(|line| {
            assert!(line["latency_ms"].as_f64().is_some_and(|ms| ms >= 0.0), "{line}");
            (
                line["span"]["method"].as_str().unwrap().to_string(),
                line["span"]["route"].as_str().unwrap().to_string(),
                line["status"].as_u64().unwrap(),
                line["span"]["caller"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let expected = [
        ("POST", "/api/studies/{slug}/participants", 201, "anonymous"),
        ("GET", "/api/participants/{id}/next", 200, "participant"),
        ("GET", "/admin/login", 303, "admin"),
    ]
    .map(|(method, route, status, caller)| (method.to_string(), route.to_string(), status, caller.to_string()));
    assert_eq!(seen, expected, "{log}");
    for secret in [token, id, server.admin_token.as_str(), "pid-e2e-secret"] {
        assert!(!log.contains(secret), "{secret} is in the log:\n{log}");
    }
}
