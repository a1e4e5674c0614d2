//! The trials CSV's external-id columns (issue 45 item 5): a column for every URL parameter the
//! study file declares, and for a study that declares none only for the default platform ids
//! that some exported participant arrived with, never a row of empty MTurk columns for a study
//! that did not ask for them. Through `app(state)` with `oneshot`, on a real sqlite database
//! (or PostgreSQL, as the other router tests); the analysis's CSV reader reads every file.

use std::path::Path;

use axum::Router;
use axum::http::{Method, StatusCode};
use serde_json::{Value, json};

mod support;
use support::{Started, before_texts, call, demo_studies, demographics, join, start};

const STUDY: &str = "shadows-demo";
const PLATFORM_IDS: [&str; 6] = ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID", "workerId", "assignmentId", "hitId"];

/// The demo study with `top_level` lines before its `[texts]`; the app and the admin token.
async fn server(work: &Path, top_level: &str) -> (Router, String) {
    let studies = demo_studies(work, |text| before_texts(&text, top_level));
    let Started { app, admin_token, skipped, .. } = start(work, &studies).await;
    assert!(skipped.is_empty(), "{skipped:?}");
    (app, admin_token)
}

/// Joins with `url_params` and answers `count` trials (the left image each time).
async fn take_part(app: &Router, url_params: Value, count: usize) {
    let body = json!({"demographics": demographics(), "url_params": url_params, "client": {}});
    let (id, token, _) = join(app, STUDY, body).await;
    let token = token.as_str();
    for _ in 0..count {
        let next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await.json();
        let trial = next["trial"].as_i64().unwrap_or_else(|| panic!("no next trial: {next}"));
        let answer = call(
            app,
            Method::POST,
            &format!("/api/participants/{id}/responses"),
            Some(token),
            Some(json!({"trial": trial, "chosen": "left", "rt_ms": 900.0, "client": {}})),
        )
        .await;
        assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    }
}

/// The trials CSV's header and rows, after checking that the analysis reads the file.
async fn export(app: &Router, admin_token: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let answer =
        call(app, Method::GET, &format!("/api/admin/studies/{STUDY}/export.csv"), Some(admin_token), None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    let csv = answer.text();
    let judgments = mrstudy_analysis::data::parse_trials(&csv, "export.csv", None, None)
        .unwrap_or_else(|error| panic!("the analysis refuses the export: {error}\n{csv}"));
    assert!(!judgments.rows.is_empty(), "{csv}");
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header = reader.headers().unwrap().iter().map(str::to_string).collect();
    let rows = reader.records().map(|record| record.unwrap().iter().map(str::to_string).collect()).collect();
    (header, rows)
}

fn url_columns(header: &[String]) -> Vec<&str> {
    header.iter().map(String::as_str).filter(|name| PLATFORM_IDS.contains(name)).collect()
}

/// The walkthrough's defect: the demo study declares no `url_params`, its participants came from
/// Prolific, and the CSV still carried empty `workerId`, `assignmentId`, `hitId` (and
/// `STUDY_ID`, `SESSION_ID`) columns.
#[tokio::test]
async fn a_study_that_declares_no_url_params_gets_columns_only_for_ids_participants_brought() {
    let work = tempfile::tempdir().unwrap();
    let (app, admin_token) = server(work.path(), "").await;
    take_part(&app, json!({"PROLIFIC_PID": "PID-1", "workerId": ""}), 2).await;
    take_part(&app, json!({}), 2).await;
    let (header, rows) = export(&app, &admin_token).await;
    // workerId arrived empty, the others never: only PROLIFIC_PID has a column.
    assert_eq!(url_columns(&header), ["PROLIFIC_PID"], "{header:?}");
    let pid = header.iter().position(|name| name == "PROLIFIC_PID").unwrap();
    let participant = header.iter().position(|name| name == "participant").unwrap();
    // One participant's rows carry the id, the other's are empty (a catch trial is no row).
    let mut values: Vec<(&str, &str)> = rows.iter().map(|row| (row[participant].as_str(), row[pid].as_str())).collect();
    values.dedup();
    assert_eq!(values.iter().map(|(_, value)| *value).collect::<Vec<_>>(), ["PID-1", ""], "{rows:?}");
    // The external ids sit between the fixed columns and the demographics, as designed.
    let too_fast = header.iter().position(|name| name == "too_fast").unwrap();
    assert_eq!(header[too_fast + 1], "PROLIFIC_PID");
    assert_eq!(header[too_fast + 2], "gender", "{header:?}");
}

#[tokio::test]
async fn a_study_whose_participants_bring_no_ids_has_no_external_id_columns() {
    let work = tempfile::tempdir().unwrap();
    let (app, admin_token) = server(work.path(), "").await;
    take_part(&app, json!({}), 2).await;
    let (header, _) = export(&app, &admin_token).await;
    assert!(url_columns(&header).is_empty(), "{header:?}");
    let too_fast = header.iter().position(|name| name == "too_fast").unwrap();
    assert_eq!(header[too_fast + 1], "gender", "{header:?}");
}

/// A study that asks for the MTurk ids gets exactly those columns, in its order, even where no
/// participant brought them (the researcher asked; an empty cell says the id was missing).
#[tokio::test]
async fn declared_url_params_are_the_columns_in_the_declared_order() {
    let work = tempfile::tempdir().unwrap();
    let (app, admin_token) = server(work.path(), r#"url_params = ["hitId", "workerId", "assignmentId"]"#).await;
    take_part(&app, json!({"workerId": "W-7", "PROLIFIC_PID": "not kept"}), 2).await;
    let (header, rows) = export(&app, &admin_token).await;
    assert_eq!(url_columns(&header), ["hitId", "workerId", "assignmentId"], "{header:?}");
    let worker = header.iter().position(|name| name == "workerId").unwrap();
    let hit = header.iter().position(|name| name == "hitId").unwrap();
    assert!(rows.iter().all(|row| row[worker] == "W-7" && row[hit].is_empty()), "{rows:?}");

    // Declared as none: no column at all.
    let work = tempfile::tempdir().unwrap();
    let (app, admin_token) = server(work.path(), "url_params = []").await;
    take_part(&app, json!({"PROLIFIC_PID": "PID-2"}), 2).await;
    let (header, _) = export(&app, &admin_token).await;
    assert!(url_columns(&header).is_empty(), "{header:?}");
}
