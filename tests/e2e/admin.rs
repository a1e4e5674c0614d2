//! The researcher's side of trustworthy responses through the binary: participants excluded and
//! deleted over a real socket, then `mrstudy export` leaving the excluded out (one line on
//! stderr saying so) unless `--include-excluded`, and nothing of the deleted participant left in
//! `mrstudy.db` once the server has stopped.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use serde_json::{Value, json};

use super::support::{Server, binary, client, demographics};

/// `mrstudy export` with extra flags: (stdout, stderr).
fn export_with(data_dir: &Path, flags: &[&str]) -> (String, String) {
    let output = Command::new(binary())
        .args(["export", "--study", "shadows-demo", "--data-dir"])
        .arg(data_dir)
        .args(super::support::database_args(super::support::test_database(data_dir).as_deref()))
        .args(flags)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "export failed: {stderr}");
    (String::from_utf8(output.stdout).unwrap(), stderr)
}

/// The participants of a trials CSV (the second column: hex ids, never quoted; only later
/// columns hold quoted text).
fn participants(csv: &str) -> BTreeSet<String> {
    assert!(csv.starts_with("study,participant,"), "{csv}");
    csv.lines().skip(1).map(|line| line.split(',').nth(1).unwrap().to_string()).collect()
}

#[test]
fn export_leaves_out_excluded_participants_and_says_so_and_deletion_leaves_no_trace() {
    let data_dir = tempfile::tempdir().unwrap();
    let mut server = Server::start(data_dir.path(), "127.0.0.1:0");
    let http = client();
    let base = server.base.clone();
    let mut ids = Vec::new();
    for participant in 0..4 {
        let joined: Value = http
            .post(format!("{base}/api/studies/shadows-demo/participants"))
            .json(&json!({"demographics": demographics(), "url_params": {"PROLIFIC_PID": format!("PPID-E2E-{participant}-4711")}}))
            .send()
            .unwrap()
            .json()
            .unwrap();
        let id = joined["participant"].as_str().unwrap().to_string();
        let token = joined["token"].as_str().unwrap().to_string();
        for trial in 1..=7 {
            http.get(format!("{base}/api/participants/{id}/next")).bearer_auth(&token).send().unwrap();
            let stored = http
                .post(format!("{base}/api/participants/{id}/responses"))
                .bearer_auth(&token)
                .json(&json!({"trial": trial, "chosen": if (trial + participant) % 3 == 0 { "right" } else { "left" }, "rt_ms": 700}))
                .send()
                .unwrap();
            assert_eq!(stored.status(), 201);
        }
        ids.push(id);
    }
    let admin = |request: reqwest::blocking::RequestBuilder| request.bearer_auth(&server.admin_token).send().unwrap();
    let excluded = admin(
        http.post(format!("{base}/api/admin/participants/{}/exclude", ids[0]))
            .json(&json!({"reason": "straight-lined"})),
    );
    assert_eq!(excluded.status(), 200);
    let deleted = admin(http.delete(format!("{base}/api/admin/participants/{}", ids[3])));
    assert_eq!(deleted.status(), 200);
    let list: Value = admin(http.get(format!("{base}/api/admin/studies/shadows-demo/participants"))).json().unwrap();
    assert_eq!(list.as_array().unwrap().len(), 3);

    let (csv, stderr) = export_with(data_dir.path(), &[]);
    assert_eq!(
        stderr.trim(),
        "Left out 1 excluded participant (excluded by the researcher); pass --include-pilots or --include-excluded to keep them."
    );
    assert_eq!(participants(&csv), BTreeSet::from([ids[1].clone(), ids[2].clone()]));
    assert!(csv.lines().next().unwrap().contains(",status,completion_code,pilot,excluded,too_fast,PROLIFIC_PID,"));
    let (everyone, stderr) = export_with(data_dir.path(), &["--include-excluded", "--include-pilots"]);
    assert_eq!(stderr, "", "nobody left out");
    assert_eq!(participants(&everyone).len(), 3);
    assert!(everyone.contains("PPID-E2E-0-4711") && !everyone.contains("PPID-E2E-3-4711"));
    let (json, _) = export_with(data_dir.path(), &["--format", "json", "--include-excluded"]);
    let json: Value = serde_json::from_str(&json).unwrap();
    assert_eq!(json["participants"][0]["exclusion_reason"], "straight-lined");

    server.kill();
    if super::support::test_database(data_dir.path()).is_some() {
        return; // PostgreSQL's files are its server's: the sqlite run checks the bytes on disk
    }
    let mut bytes = std::fs::read(data_dir.path().join("mrstudy.db")).unwrap();
    bytes.extend(std::fs::read(data_dir.path().join("mrstudy.db-wal")).unwrap_or_default());
    let contains = |needle: &str| bytes.windows(needle.len()).any(|window| window == needle.as_bytes());
    assert!(contains("PPID-E2E-1-4711"), "the kept participants are in the file");
    assert!(!contains("PPID-E2E-3-4711") && !contains(&ids[3]), "nothing of the deleted participant");
}
