//! Rating studies (`kind = "rating"`, issue 49) through the router, on sqlite and (with
//! `MRSTUDY_TEST_DATABASE=postgres`) PostgreSQL: a rating trial as `…/next` serves it, a rating
//! stored once (the same again 200, another 409, a `chosen` or a rating out of 1–5 refused with
//! 422), a paired comparison refusing a rating, the export's rating columns with the catch
//! trial's row, catch failures counted, exclusion and deletion of a rating participant.

use std::path::Path;

use axum::Router;
use axum::http::{Method, StatusCode};
use mrstudy_server::app;
use mrstudy_server::serve::{Prepared, prepare_on};
use mrstudy_server::storage::Database;
use serde_json::{Value, json};

mod support;
use support::{call, connect, copy_demo_study, demographics, test_database};
#[path = "support/rating_study.rs"]
mod rating_study;
use rating_study::AcrStudy;

const SLUG: &str = "rating-demo";

/// The demo study (paired comparisons) and an ACR rating study of its images, with a catch
/// trial expecting "Bad".
fn studies_dir(work: &Path) -> std::path::PathBuf {
    let dir = work.join("studies");
    copy_demo_study(&dir);
    let demo = std::fs::read_to_string(dir.join("shadows-demo.toml")).unwrap();
    let study = AcrStudy { slug: SLUG, top_level: "min_response_ms = 0", ..AcrStudy::default() }.toml(&demo);
    std::fs::write(dir.join("rating-demo.toml"), study).unwrap();
    dir
}

struct Fixture {
    app: Router,
    admin_token: String,
    database: Database,
    _data_dir: tempfile::TempDir,
}

async fn fixture() -> Fixture {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = studies_dir(data_dir.path());
    let data = data_dir.path().join("data");
    let database = test_database(&data).await;
    let Prepared { state, admin_token, skipped, .. } = prepare_on(&database, &data, &studies).await.unwrap();
    assert!(skipped.is_empty(), "{skipped:?}");
    Fixture { app: app(state), admin_token, database, _data_dir: data_dir }
}

async fn join(app: &Router, slug: &str) -> (String, String) {
    let answer = call(
        app,
        Method::POST,
        &format!("/api/studies/{slug}/participants"),
        None,
        Some(json!({"demographics": demographics(), "client": {"viewport": [1280, 800]}})),
    )
    .await;
    assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    let json = answer.json();
    (json["participant"].as_str().unwrap().to_string(), json["token"].as_str().unwrap().to_string())
}

async fn next(app: &Router, id: &str, token: &str) -> Value {
    let answer = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    answer.json()
}

async fn respond(app: &Router, id: &str, token: &str, body: Value) -> (StatusCode, Value) {
    let answer = call(app, Method::POST, &format!("/api/participants/{id}/responses"), Some(token), Some(body)).await;
    let status = answer.status;
    (status, answer.json())
}

/// Rates every trial: the catch trial with `catch_rating`, the others `4`; returns the ratings.
async fn rate_all(app: &Router, id: &str, token: &str, catch_rating: i64) -> Vec<i64> {
    let mut given = Vec::new();
    loop {
        let trial = next(app, id, token).await;
        if trial["done"] == true {
            return given;
        }
        let is_catch = trial["stimulus"]["url"].as_str().unwrap().ends_with(CATCH_SUFFIX.get().unwrap());
        let rating = if is_catch { catch_rating } else { 4 };
        let (status, _) =
            respond(app, id, token, json!({"trial": trial["trial"], "rating": rating, "rt_ms": 900})).await;
        assert_eq!(status, StatusCode::CREATED);
        given.push(rating);
    }
}

/// The stimulus file name of the catch image (its content hash), set once it is known.
static CATCH_SUFFIX: std::sync::OnceLock<String> = std::sync::OnceLock::new();

fn catch_name() -> String {
    use sha2::Digest;
    let bytes = std::fs::read(support::repo_studies_dir().join("shadows-demo/catch-bad.png")).unwrap();
    format!("{}.png", hex::encode(sha2::Sha256::digest(bytes)))
}

#[tokio::test]
async fn a_rating_is_served_stored_once_and_exported_with_its_columns() {
    let _ = CATCH_SUFFIX.set(catch_name());
    let fixture = fixture().await;
    let app = &fixture.app;
    let (id, token) = join(app, SLUG).await;
    let trial = next(app, &id, &token).await;
    assert_eq!(trial["trial"], 1);
    assert_eq!(trial["total"], 13);
    assert!(trial["stimulus"]["url"].as_str().unwrap().starts_with("/stimuli/"), "{trial}");
    assert!(trial.get("reference").is_none() && trial.get("left").is_none(), "{trial}");
    assert_eq!(trial["rating"]["method"], "acr");
    assert_eq!(trial["rating"]["scale"], "quality");
    let labels: Vec<(i64, &str)> = trial["rating"]["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|point| (point["rating"].as_i64().unwrap(), point["label"].as_str().unwrap()))
        .collect();
    assert_eq!(labels, [(5, "Excellent"), (4, "Good"), (3, "Fair"), (2, "Poor"), (1, "Bad")]);
    assert_eq!(trial["rating"]["stimulus_ms"], 0);
    assert_eq!(trial["rating"]["vote_after"], false);
    // the next trial's image (ACR: no reference) is preloaded
    assert_eq!(trial["preload"].as_array().unwrap().len(), 1, "{trial}");

    // a paired comparison's answer, a rating out of range, trial 2 (never served): refused
    let (status, body) = respond(app, &id, &token, json!({"trial": 1, "chosen": "left", "rt_ms": 900})).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{body}");
    assert!(body["error"].as_str().unwrap().contains("rating study"), "{body}");
    for rating in [0, 6, -1] {
        let (status, body) = respond(app, &id, &token, json!({"trial": 1, "rating": rating, "rt_ms": 900})).await;
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{body}");
        assert!(body["error"].as_str().unwrap().contains("from 1 to 5"), "{body}");
    }
    let (status, _) = respond(app, &id, &token, json!({"trial": 2, "rating": 3, "rt_ms": 900})).await;
    assert_eq!(status, StatusCode::CONFLICT, "trial 2 was never served");
    // the rating, the same again (a double click that got through), another one
    let (status, body) = respond(app, &id, &token, json!({"trial": 1, "rating": 4, "rt_ms": 900})).await;
    assert_eq!((status, body), (StatusCode::CREATED, json!({"trial": 1, "rating": 4})));
    let (status, _) = respond(app, &id, &token, json!({"trial": 1, "rating": 4, "rt_ms": 950})).await;
    assert_eq!(status, StatusCode::OK);
    let (status, body) = respond(app, &id, &token, json!({"trial": 1, "rating": 2, "rt_ms": 950})).await;
    assert_eq!(status, StatusCode::CONFLICT, "{body}");
    assert!(body["error"].as_str().unwrap().contains("already answered with \"4\""), "{body}");
    // the demo study takes no rating
    let (paired, paired_token) = join(app, "shadows-demo").await;
    next(app, &paired, &paired_token).await;
    let (status, body) = respond(app, &paired, &paired_token, json!({"trial": 1, "rating": 3, "rt_ms": 900})).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{body}");

    // the rest: the catch trial rated 3 (two categories from Bad: failed)
    let mut given = vec![4];
    given.extend(rate_all(app, &id, &token, 3).await);
    assert_eq!(given.len(), 13);
    let pool = connect(&fixture.database).await;
    let stored: Vec<(i64, Option<i64>, Option<String>)> =
        sqlx::query_as("SELECT trial, rating, chosen FROM responses WHERE participant = $1 ORDER BY trial")
            .bind(&id)
            .fetch_all(&pool)
            .await
            .unwrap();
    let expected: Vec<(i64, Option<i64>, Option<String>)> =
        given.iter().enumerate().map(|(index, &rating)| (index as i64 + 1, Some(rating), None)).collect();
    assert_eq!(stored, expected);

    // the export: every rating a row, the catch trial's flagged, the participant's catch failure counted
    let csv =
        call(app, Method::GET, &format!("/api/admin/studies/{SLUG}/export.csv"), Some(&fixture.admin_token), None)
            .await
            .text();
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(str::to_string).collect();
    let column = |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("{name}: {header:?}"));
    let scene = column("scene");
    assert_eq!(
        header[scene..scene + 8],
        ["scene", "condition", "rating", "method", "reference", "scale", "catch", "expected"].map(String::from)
    );
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 13, "{csv}");
    let catch_rows: Vec<&csv::StringRecord> = rows.iter().filter(|row| &row[column("catch")] == "true").collect();
    assert_eq!(catch_rows.len(), 1, "{csv}");
    assert_eq!(
        (&catch_rows[0][column("condition")], &catch_rows[0][column("expected")], &catch_rows[0][column("rating")]),
        ("catch:broken", "1", "3")
    );
    for row in &rows {
        assert_eq!((&row[column("method")], &row[column("reference")], &row[column("scale")]), ("acr", "", "quality"));
        assert_eq!((&row[column("catch_answered")], &row[column("catch_failed")]), ("1", "1"), "{csv}");
        assert_eq!(&row[column("chosen")], "");
        assert_eq!(row[column("left")], row[column("condition")]);
    }
    let stats =
        call(app, Method::GET, &format!("/api/admin/studies/{SLUG}"), Some(&fixture.admin_token), None).await.json();
    assert_eq!(stats["finished"], 1, "{stats}");
    let json =
        call(app, Method::GET, &format!("/api/admin/studies/{SLUG}/export.json"), Some(&fixture.admin_token), None)
            .await
            .json();
    let schedule = json["participants"][0]["schedule"].as_array().unwrap();
    assert_eq!(schedule[0]["response"]["rating"], 4, "{}", schedule[0]);
    assert!(schedule.iter().any(|trial| trial["catch_rating"] == 1));
    let analysis =
        call(app, Method::GET, &format!("/api/admin/studies/{SLUG}/analysis"), Some(&fixture.admin_token), None).await;
    // the one participant rated everything 4 (straight-lining): screened, nothing left to analyse
    assert_eq!(analysis.status, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(
        analysis.error().contains("no rating is left to analyse (1 participant(s) screened"),
        "{}",
        analysis.text()
    );
    let cookie = support::admin_session_cookie(app, &fixture.admin_token).await;
    let request = axum::http::Request::builder()
        .uri(format!("/admin/studies/{SLUG}"))
        .header(axum::http::header::COOKIE, cookie)
        .body(axum::body::Body::empty())
        .unwrap();
    let page = support::send(app, request).await;
    assert_eq!(page.status, StatusCode::OK, "the admin page of a rating study");
}

#[tokio::test]
async fn a_passed_catch_an_excluded_and_a_deleted_rating_participant() {
    let _ = CATCH_SUFFIX.set(catch_name());
    let fixture = fixture().await;
    let app = &fixture.app;
    let admin = Some(fixture.admin_token.as_str());
    let (kept, kept_token) = join(app, SLUG).await;
    rate_all(app, &kept, &kept_token, 2).await; // one category from Bad: passed
    let (excluded, excluded_token) = join(app, SLUG).await;
    rate_all(app, &excluded, &excluded_token, 1).await;
    let (deleted, deleted_token) = join(app, SLUG).await;
    rate_all(app, &deleted, &deleted_token, 5).await;

    let answer = call(
        app,
        Method::POST,
        &format!("/api/admin/participants/{excluded}/exclude"),
        admin,
        Some(json!({"reason": "test"})),
    )
    .await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    let answer = call(app, Method::DELETE, &format!("/api/admin/participants/{deleted}"), admin, None).await;
    assert!(answer.status.is_success(), "{}", answer.text());
    let pool = connect(&fixture.database).await;
    let left: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM responses WHERE participant = $1")
        .bind(&deleted)
        .fetch_one(&pool)
        .await
        .unwrap();
    assert_eq!(left, 0, "the deleted participant's ratings are gone");

    let csv = call(app, Method::GET, &format!("/api/admin/studies/{SLUG}/export.csv"), admin, None).await.text();
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(str::to_string).collect();
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 13, "only the kept participant's ratings: {csv}");
    assert!(rows.iter().all(|row| &row[column("participant")] == kept.as_str()));
    assert!(rows.iter().all(|row| &row[column("catch_failed")] == "0"), "a rating one category off passes");
}

/// Rates every trial with `rating(trial number, is the catch trial)`.
async fn rate_with(app: &Router, id: &str, token: &str, rating: impl Fn(i64, bool) -> i64) {
    loop {
        let trial = next(app, id, token).await;
        if trial["done"] == true {
            return;
        }
        let is_catch = trial["stimulus"]["url"].as_str().unwrap().ends_with(CATCH_SUFFIX.get().unwrap());
        let number = trial["trial"].as_i64().unwrap();
        let body = json!({"trial": number, "rating": rating(number, is_catch), "rt_ms": 900});
        let (status, _) = respond(app, id, token, body).await;
        assert_eq!(status, StatusCode::CREATED);
    }
}

/// `mrstudy analyze --json` on a trials CSV: the analysis crate's own entry point.
fn analyze_export(csv: &str) -> Value {
    use mrstudy_analysis::analysis::Options;
    use mrstudy_analysis::command::{Drawings, analyze_files};
    let printed = analyze_files((csv, "export.csv"), None, None, &Options::default(), true, Drawings::default())
        .unwrap_or_else(|error| panic!("{error}\n{csv}"));
    serde_json::from_str(&printed.text).unwrap()
}

/// The export's rows as maps from column to cell.
fn export_rows(csv: &str) -> Vec<std::collections::HashMap<String, String>> {
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(str::to_string).collect();
    reader.records().map(|row| header.iter().cloned().zip(row.unwrap().iter().map(str::to_string)).collect()).collect()
}

/// Each condition's mean of `score` over `rows`, by direct computation.
fn means(rows: &[(String, f64)]) -> std::collections::BTreeMap<String, (f64, usize)> {
    let mut sums: std::collections::BTreeMap<String, (f64, usize)> = Default::default();
    for (condition, score) in rows {
        let entry = sums.entry(condition.clone()).or_default();
        entry.0 += score;
        entry.1 += 1;
    }
    sums.into_iter().map(|(condition, (sum, n))| (condition, (sum / n as f64, n))).collect()
}

#[tokio::test]
async fn a_rating_export_is_analysed_with_its_catch_rows_as_golden_questions_and_shown_live() {
    let _ = CATCH_SUFFIX.set(catch_name());
    let fixture = fixture().await;
    let app = &fixture.app;
    let admin = Some(fixture.admin_token.as_str());
    // two attentive participants, one failing the golden question, one excluded
    let (first, first_token) = join(app, SLUG).await;
    rate_with(app, &first, &first_token, |trial, catch| if catch { 1 } else { trial % 5 + 1 }).await;
    let (second, second_token) = join(app, SLUG).await;
    rate_with(app, &second, &second_token, |trial, catch| if catch { 2 } else { (trial * 3) % 5 + 1 }).await;
    let (careless, careless_token) = join(app, SLUG).await;
    rate_with(app, &careless, &careless_token, |trial, catch| if catch { 5 } else { (trial + 2) % 5 + 1 }).await;
    let (excluded, excluded_token) = join(app, SLUG).await;
    rate_with(app, &excluded, &excluded_token, |_, catch| if catch { 1 } else { 5 }).await;
    let answer = call(
        app,
        Method::POST,
        &format!("/api/admin/participants/{excluded}/exclude"),
        admin,
        Some(json!({"reason": "test"})),
    )
    .await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());

    let csv = call(app, Method::GET, &format!("/api/admin/studies/{SLUG}/export.csv"), admin, None).await.text();
    let json = analyze_export(&csv);
    assert!(json.get("items").is_none(), "a rating export has no paired comparisons: {json}");
    let ratings = &json["ratings"];
    assert_eq!(ratings["method"], "acr");
    assert_eq!(ratings["scores"], "rating");
    // by direct computation from the export: the attentive participants' rows, catch rows left out
    let rows = export_rows(&csv);
    let data: Vec<(String, f64)> = rows
        .iter()
        .filter(|row| row["catch"] == "false" && (row["participant"] == first || row["participant"] == second))
        .map(|row| (row["condition"].clone(), row["rating"].parse().unwrap()))
        .collect();
    assert_eq!(data.len(), 24, "{csv}");
    assert_eq!(ratings["ratings"], 24, "{ratings}");
    let expected = means(&data);
    let conditions = ratings["conditions"].as_array().unwrap();
    let found: Vec<(String, f64, u64)> = conditions
        .iter()
        .map(|c| {
            (c["condition"].as_str().unwrap().to_string(), c["mos"].as_f64().unwrap(), c["ratings"].as_u64().unwrap())
        })
        .collect();
    assert_eq!(found.len(), expected.len(), "no `catch:` condition among the data: {found:?}");
    for ((condition, mos, n), (want, (mean, count))) in found.iter().zip(&expected) {
        assert!(!condition.starts_with("catch:"), "{condition}");
        assert_eq!((condition, *n as usize), (want, *count));
        assert!((mos - mean).abs() < 1e-12, "{condition}: {mos} against {mean}");
    }
    assert!(conditions.iter().all(|c| c["mos_ci"].as_array().is_some_and(|ci| ci.len() == 2)), "{ratings}");
    let participants: Vec<(&str, bool, u64, u64, u64)> = ratings["participants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["participant"].as_str().unwrap(),
                p["screened"].as_bool().unwrap(),
                p["golden_answered"].as_u64().unwrap(),
                p["golden_failed"].as_u64().unwrap(),
                p["ratings"].as_u64().unwrap(),
            )
        })
        .collect();
    let mut want = vec![
        (first.as_str(), false, 1, 0, 12),
        (second.as_str(), false, 1, 0, 12),
        (careless.as_str(), true, 1, 1, 12),
    ];
    want.sort();
    assert_eq!(participants, want, "the excluded participant is not exported: {ratings}");
    let careless_entry =
        ratings["participants"].as_array().unwrap().iter().find(|p| p["participant"] == careless.as_str()).unwrap();
    assert!(careless_entry["reason"].as_str().unwrap().contains("golden question"), "{careless_entry}");
    for entry in ratings["participants"].as_array().unwrap() {
        // MLE_CO is fitted to the kept participants only (two raters of one vote per stimulus:
        // where its likelihood has no maximum the model says so instead)
        let fitted = entry["participant"] != careless.as_str() && ratings["model"]["not_estimable"].is_null();
        assert_eq!(entry["bias"].is_number(), fitted, "MLE_CO fitted: {ratings}");
        assert_eq!(entry["inconsistency"].is_number(), fitted, "MLE_CO fitted: {ratings}");
    }

    // the live analysis is the same analysis of the same export
    let live = call(app, Method::GET, &format!("/api/admin/studies/{SLUG}/analysis"), admin, None).await;
    assert_eq!(live.status, StatusCode::OK, "{}", live.text());
    let live = live.json();
    assert_eq!(live["ratings"]["conditions"], ratings["conditions"]);
    assert_eq!(live["ratings"]["participants"], ratings["participants"]);
    // the admin page shows the MOS per condition and the screening per participant
    let cookie = support::admin_session_cookie(app, &fixture.admin_token).await;
    let request = axum::http::Request::builder()
        .uri(format!("/admin/studies/{SLUG}"))
        .header(axum::http::header::COOKIE, cookie)
        .body(axum::body::Body::empty())
        .unwrap();
    let page = support::send(app, request).await;
    assert_eq!(page.status, StatusCode::OK);
    let html = page.text();
    assert!(html.contains("id=\"mos-table\""), "{html}");
    for condition in conditions {
        let ci = condition["mos_ci"].as_array().unwrap();
        let row = format!(
            "<tr><td>{}</td><td>{}</td><td>{:.2}</td><td>[{:.2}, {:.2}]</td>",
            condition["condition"].as_str().unwrap(),
            condition["ratings"],
            condition["mos"].as_f64().unwrap(),
            ci[0].as_f64().unwrap(),
            ci[1].as_f64().unwrap()
        );
        assert!(html.contains(&row), "{row} in {html}");
    }
    assert!(html.contains("id=\"rating-screening\""), "{html}");
    assert!(html.contains(&format!("{careless}</td><td>screened")), "{html}");
    assert!(!html.contains("rating study's ratings are in its trials CSV"), "{html}");
}

/// A study (`method` = `acr-hr` or `dcr`, slug the method) of one rendered scene configuration
/// under two conditions, each stimulus (ACR-HR: and the hidden reference, its ground truth)
/// twice, and the catch image.
fn rendered_studies(work: &Path, method: &str) -> std::path::PathBuf {
    let dir = work.join("studies");
    std::fs::create_dir_all(dir.join("img")).unwrap();
    std::fs::copy(support::repo_studies_dir().join("shadows-demo/catch-bad.png"), dir.join("img/broken.png")).unwrap();
    let study = r#"slug = "METHOD"
title = "Ratings"
kind = "rating"
question = "How good is this image?"
min_response_ms = 0
[texts]
welcome = "w"
consent = "c"
instructions = "i"
[[factors]]
name = "gi"
[[factors]]
name = "cm"
[[conditions]]
name = "LQ"
levels = { gi = 0, cm = 0 }
[[conditions]]
name = "HQ"
levels = { gi = 1, cm = 1 }
[render]
size = [32, 24]
spp = 1
[[scenes]]
name = "one"
render = "survey-1"
[rating]
method = "METHOD"
repetitions = 2
seed = 3
[[rating.catch]]
name = "broken"
image = "img/broken.png"
expected = 1
[completion]
code = "R-2"
"#;
    // DCR's catch trial shows an image before it: the demo's good catch image
    std::fs::copy(support::repo_studies_dir().join("shadows-demo/catch-good.png"), dir.join("img/good.png")).unwrap();
    let study = study.replace("METHOD", method);
    let study = match method {
        "dcr" => {
            study.replace("image = \"img/broken.png\"", "image = \"img/broken.png\"\nreference = \"img/good.png\"")
        }
        _ => study,
    };
    std::fs::write(dir.join(format!("{method}.toml")), study).unwrap();
    dir
}

/// A join's body for a study that asks no demographics.
fn no_demographics() -> Value {
    json!({"demographics": {}, "client": {"viewport": [1280, 800]}})
}

#[tokio::test]
async fn an_acr_hr_export_gives_dmos_against_the_hidden_reference_pilots_and_excluded_left_out() {
    let _ = CATCH_SUFFIX.set(catch_name());
    let work = tempfile::tempdir().unwrap();
    let studies = rendered_studies(work.path(), "acr-hr");
    let support::Started { app, admin_token, skipped, database, .. } = support::start(work.path(), &studies).await;
    if !skipped.is_empty() {
        assert!(skipped.iter().all(|line| line.contains("no adapter")), "{skipped:?}");
        eprintln!("skipped: no GPU adapter (not even a software one): {skipped:?}");
        return;
    }
    let app = &app;
    let admin = Some(admin_token.as_str());
    let slug = "acr-hr";
    let (first, first_token, _) = support::join(app, slug, no_demographics()).await;
    rate_with(app, &first, &first_token, |trial, catch| if catch { 1 } else { trial % 5 + 1 }).await;
    let (second, second_token, _) = support::join(app, slug, no_demographics()).await;
    rate_with(app, &second, &second_token, |trial, catch| if catch { 2 } else { (trial * 3) % 5 + 1 }).await;
    let (pilot, pilot_token, _) = support::join(app, slug, no_demographics()).await;
    rate_with(app, &pilot, &pilot_token, |trial, catch| if catch { 1 } else { (trial + 1) % 5 + 1 }).await;
    let (excluded, excluded_token, _) = support::join(app, slug, no_demographics()).await;
    rate_with(app, &excluded, &excluded_token, |trial, catch| if catch { 1 } else { (trial + 3) % 5 + 1 }).await;
    // the pilot as a preview link's join marks it
    sqlx::query("UPDATE participants SET pilot = 1 WHERE id = $1")
        .bind(&pilot)
        .execute(&connect(&database).await)
        .await
        .unwrap();
    let answer = call(
        app,
        Method::POST,
        &format!("/api/admin/participants/{excluded}/exclude"),
        admin,
        Some(json!({"reason": "test"})),
    )
    .await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());

    // the export with every participant, flagged; the analysis leaves the pilot and the excluded out
    let csv = call(
        app,
        Method::GET,
        &format!("/api/admin/studies/{slug}/export.csv?include_pilots=true&include_excluded=true"),
        admin,
        None,
    )
    .await
    .text();
    let rows = export_rows(&csv);
    assert_eq!(rows.len(), 4 * 7, "{csv}");
    assert!(rows.iter().any(|row| row["pilot"] == "true") && rows.iter().any(|row| row["excluded"] == "true"));
    assert!(rows.iter().all(|row| row["reference"] == "ground-truth" && row["method"] == "acr-hr"), "{csv}");
    let json = analyze_export(&csv);
    let ratings = &json["ratings"];
    assert_eq!((&ratings["method"], &ratings["scores"]), (&json!("acr-hr"), &json!("dv")), "{ratings}");
    assert!(
        ratings["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("left out 1 pilot and 1 excluded")),
        "{ratings}"
    );
    // DMOS by direct computation: DV = rating − the participant's mean hidden-reference rating + 5
    let mut data = Vec::new();
    for participant in [&first, &second] {
        let own: Vec<_> =
            rows.iter().filter(|row| &row["participant"] == participant && row["catch"] == "false").collect();
        let references: Vec<f64> = own
            .iter()
            .filter(|row| row["condition"] == "ground-truth")
            .map(|row| row["rating"].parse().unwrap())
            .collect();
        assert_eq!(references.len(), 2, "the hidden reference rated twice: {csv}");
        let reference = references.iter().sum::<f64>() / 2.0;
        for row in own.iter().filter(|row| row["condition"] != "ground-truth") {
            data.push((row["condition"].clone(), row["rating"].parse::<f64>().unwrap() - reference + 5.0));
        }
    }
    assert_eq!(ratings["ratings"], 8, "{ratings}");
    let expected = means(&data);
    let found: Vec<(String, f64)> = ratings["conditions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["condition"].as_str().unwrap().to_string(), c["mos"].as_f64().unwrap()))
        .collect();
    assert_eq!(found.len(), 2, "the hidden reference and the catch trial are not conditions: {found:?}");
    for ((condition, dmos), (want, (mean, _))) in found.iter().zip(&expected) {
        assert_eq!(condition, want);
        assert!((dmos - mean).abs() < 1e-12, "{condition}: {dmos} against {mean}");
    }
    let mut participants: Vec<&str> =
        ratings["participants"].as_array().unwrap().iter().map(|p| p["participant"].as_str().unwrap()).collect();
    participants.sort();
    let mut want = vec![first.as_str(), second.as_str()];
    want.sort();
    assert_eq!(participants, want);
    assert!(
        ratings["participants"].as_array().unwrap().iter().all(|p| p["golden_answered"] == 1 && p["screened"] == false)
    );
    // the live analysis (default: pilots and excluded left out by the export) agrees
    let live = call(app, Method::GET, &format!("/api/admin/studies/{slug}/analysis"), admin, None).await;
    assert_eq!(live.status, StatusCode::OK, "{}", live.text());
    assert_eq!(live.json()["ratings"]["conditions"], ratings["conditions"]);
    // the admin page says the MOS are DMOS against the hidden reference
    let cookie = support::admin_session_cookie(app, &admin_token).await;
    let request = axum::http::Request::builder()
        .uri(format!("/admin/studies/{slug}"))
        .header(axum::http::header::COOKIE, cookie)
        .body(axum::body::Body::empty())
        .unwrap();
    let html = support::send(app, request).await.text();
    assert!(html.contains("8 differential viewer scores against the hidden reference (DMOS, ACR-HR)"), "{html}");
    assert!(!html.contains("<tr><td>ground-truth</td>"), "the hidden reference is no condition: {html}");
}

#[tokio::test]
async fn a_dcr_export_gives_the_mos_of_its_impairment_ratings() {
    let _ = CATCH_SUFFIX.set(catch_name());
    let work = tempfile::tempdir().unwrap();
    let studies = rendered_studies(work.path(), "dcr");
    let support::Started { app, admin_token, skipped, .. } = support::start(work.path(), &studies).await;
    if !skipped.is_empty() {
        assert!(skipped.iter().all(|line| line.contains("no adapter")), "{skipped:?}");
        eprintln!("skipped: no GPU adapter (not even a software one): {skipped:?}");
        return;
    }
    let app = &app;
    let slug = "dcr";
    for step in [1, 3] {
        let (id, token, _) = support::join(app, slug, no_demographics()).await;
        rate_with(app, &id, &token, |trial, catch| if catch { 1 } else { (trial * step) % 5 + 1 }).await;
    }
    let csv =
        call(app, Method::GET, &format!("/api/admin/studies/{slug}/export.csv"), Some(&admin_token), None).await.text();
    let rows = export_rows(&csv);
    assert_eq!(rows.len(), 2 * 5, "two conditions twice and the catch trial each: {csv}");
    let data: Vec<(String, f64)> = rows
        .iter()
        .filter(|row| row["catch"] == "false")
        .inspect(|row| {
            assert_eq!((row["reference"].as_str(), row["right"].as_str()), ("ground-truth", "ground-truth"), "{csv}")
        })
        .map(|row| (row["condition"].clone(), row["rating"].parse().unwrap()))
        .collect();
    let ratings = &analyze_export(&csv)["ratings"];
    assert_eq!(
        (&ratings["method"], &ratings["scale"], &ratings["scores"]),
        (&json!("dcr"), &json!("impairment"), &json!("rating"))
    );
    assert_eq!(ratings["ratings"], 8, "{ratings}");
    let found: Vec<(String, f64)> = ratings["conditions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["condition"].as_str().unwrap().to_string(), c["mos"].as_f64().unwrap()))
        .collect();
    let expected = means(&data);
    assert_eq!(found.len(), expected.len(), "{found:?}");
    for ((condition, mos), (want, (mean, _))) in found.iter().zip(&expected) {
        assert_eq!(condition, want);
        assert!((mos - mean).abs() < 1e-12, "{condition}: {mos} against {mean}");
    }
}
