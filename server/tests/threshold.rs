//! Threshold studies (`kind = "threshold"`) through `app(state)` with `oneshot` on a real sqlite
//! database, their levels rendered by the renderer (the software adapter; skipped without one):
//! a participant's trials follow the seed's skeleton (sides and scene configurations balanced,
//! the catch trial placed), each stored level is QUEST+'s after the answers before it (replayed
//! from the database), a server restarted mid-run continues with the level the stored answers
//! give, and the export has the threshold columns. With `render = "on-demand"` only the first
//! trial's level is rendered at start-up, and a participant's `…/next` gets every later level
//! after the server's render queue renders it: the level QUEST+ chose, never another.

use std::path::Path;

use axum::Router;
use axum::http::{Method, StatusCode};
use mrstudy_server::AppState;
use mrstudy_server::export::{Include, trials_csv};
use mrstudy_server::threshold::{Answer, intensities, next_level};
use serde_json::json;
use sqlx::Row;

mod support;
use support::{Started, call, repo_studies_dir};
#[path = "support/threshold_study.rs"]
mod threshold_study;
use threshold_study::ThresholdStudy;

const STUDY: &str = "vpls-tiny";

fn write_study(studies: &Path) {
    write_study_rendered(studies, "");
}

/// The study, with `render` lines added to its `[threshold]` table.
fn write_study_rendered(studies: &Path, render: &str) {
    ThresholdStudy { slug: STUDY, render, ..ThresholdStudy::default() }.write(
        studies,
        "threshold.toml",
        &repo_studies_dir(),
    );
}

async fn start(work: &Path) -> Option<(Router, AppState)> {
    let Started { app, state, skipped, .. } = support::start(work, &work.join("studies")).await;
    if !skipped.is_empty() {
        assert!(skipped.iter().all(|line| line.contains("no adapter")), "{skipped:?}");
        eprintln!("skipped: no GPU adapter (not even a software one): {skipped:?}");
        return None;
    }
    Some((app, state))
}

async fn join(app: &Router) -> (String, String) {
    let body = json!({"demographics": {}, "client": {"viewport": [1280, 800], "devicePixelRatio": 1}});
    let (id, token, _) = support::join(app, STUDY, body).await;
    (id, token)
}

/// Asks for the next trial and returns its number and stored conditions (None when done).
async fn next(app: &Router, state: &AppState, id: &str, token: &str) -> Option<(i64, String, String, Option<String>)> {
    let mut next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    for _ in 0..60 {
        if next.status != StatusCode::SERVICE_UNAVAILABLE {
            break;
        }
        // an on-demand level still rendering after the server's wait: asked again, as the page does
        tokio::time::sleep(std::time::Duration::from_secs(2)).await;
        next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    }
    assert_eq!(next.status, StatusCode::OK, "{}", next.text());
    let next = next.json();
    if next["done"] == true {
        return None;
    }
    let trial = next["trial"].as_i64().unwrap();
    let row = sqlx::query(
        "SELECT left_condition, right_condition, catch_expected FROM trials WHERE participant = $1 AND trial = $2",
    )
    .bind(id)
    .bind(trial)
    .fetch_one(&state.storage().read)
    .await
    .unwrap();
    Some((trial, row.get("left_condition"), row.get("right_condition"), row.get("catch_expected")))
}

/// Answers the trial as an observer who sees 1 and 4 VPLs and guesses (left) above.
async fn answer(app: &Router, id: &str, token: &str, trial: (i64, String, String, Option<String>)) {
    let (number, left, right, catch) = trial;
    let chosen = match catch {
        Some(expected) => expected,
        None => {
            let shown = if left == "ground-truth" { &right } else { &left };
            if shown == "vpls-1" || shown == "vpls-4" {
                if left == "ground-truth" { "left" } else { "right" }.to_string()
            } else {
                "left".to_string()
            }
        }
    };
    let stored = call(
        app,
        Method::POST,
        &format!("/api/participants/{id}/responses"),
        Some(token),
        Some(json!({"trial": number, "chosen": chosen, "rt_ms": 900.0, "client": {"viewport": [1280, 800]}})),
    )
    .await;
    assert_eq!(stored.status, StatusCode::CREATED, "{}", stored.text());
}

/// The participant's stored threshold trials in order: (level, ground truth on the left,
/// answered correctly if answered), and their scene configurations.
async fn stored(state: &AppState, id: &str) -> Vec<(usize, bool, Option<bool>, String)> {
    let prepared = state.study(STUDY).unwrap();
    let design = prepared.study.threshold.as_ref().unwrap();
    let rows = sqlx::query(
        "SELECT t.left_condition, t.right_condition, t.left_scene, r.chosen FROM trials t
         LEFT JOIN responses r ON r.participant = t.participant AND r.trial = t.trial
         WHERE t.participant = $1 AND t.catch_expected IS NULL ORDER BY t.trial",
    )
    .bind(id)
    .fetch_all(&state.storage().read)
    .await
    .unwrap();
    rows.iter()
        .map(|row| {
            let (left, right): (String, String) = (row.get("left_condition"), row.get("right_condition"));
            let truth_left = left == "ground-truth";
            let level = design.level_of(if truth_left { &right } else { &left }).unwrap();
            let chosen: Option<String> = row.get("chosen");
            let correct = chosen.map(|chosen| (chosen == "left") == truth_left);
            (level, truth_left, correct, row.get("left_scene"))
        })
        .collect()
}

/// Every stored level is QUEST+'s next one after the answers before it.
fn assert_levels_replay(state: &AppState, trials: &[(usize, bool, Option<bool>, String)]) {
    let prepared = state.study(STUDY).unwrap();
    let study = &prepared.study;
    let design = study.threshold.as_ref().unwrap();
    let intensities = intensities(study, None).unwrap();
    let mut answers = Vec::new();
    for (index, (level, _, correct, _)) in trials.iter().enumerate() {
        assert_eq!(*level, next_level(design, &intensities, &answers).unwrap(), "trial {index} of {trials:?}");
        if let Some(correct) = correct {
            answers.push(Answer { level: *level, correct: *correct });
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restart_mid_run_continues_with_the_level_the_stored_answers_give() {
    let work = tempfile::tempdir().unwrap();
    write_study(&work.path().join("studies"));
    let Some((app_one, state_one)) = start(work.path()).await else { return };
    let (id, token) = join(&app_one).await;
    for _ in 0..5 {
        let trial = next(&app_one, &state_one, &id, &token).await.unwrap();
        answer(&app_one, &id, &token, trial).await;
    }
    let before = stored(&state_one, &id).await;
    drop(app_one);
    drop(state_one);
    // a new server on the same database and store: the next level is chosen by it
    let (app, state) = start(work.path()).await.unwrap();
    let mut total = 5;
    while let Some(trial) = next(&app, &state, &id, &token).await {
        answer(&app, &id, &token, trial).await;
        total += 1;
    }
    assert_eq!(total, 11, "10 threshold trials and 1 catch trial");
    let trials = stored(&state, &id).await;
    assert_eq!(trials.len(), 10);
    assert_eq!(&trials[..before.len()], &before[..], "the trials before the restart are kept");
    assert_levels_replay(&state, &trials);
    // the observer tells 1 and 4 VPLs apart: QUEST+ moves between levels
    let levels: std::collections::BTreeSet<usize> = trials.iter().map(|t| t.0).collect();
    assert!(levels.len() >= 2, "{trials:?}");
    // the skeleton: ground truth on the left in half the trials, each scene configuration 5 times
    assert_eq!(trials.iter().filter(|t| t.1).count(), 5, "{trials:?}");
    assert_eq!(trials.iter().filter(|t| t.3 == "one").count(), 5, "{trials:?}");
    // the export: the threshold columns on every row, the catch trial not a row
    let csv = trials_csv(&state.storage().read, STUDY, Include::default()).await.unwrap().content;
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    for column in ["participant", "scene", "level", "intensity", "x", "correct", "function", "scale", "guess"] {
        assert!(header.iter().any(|h| h == column), "{column} missing from {header:?}");
    }
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 10);
    for (row, trial) in rows.iter().zip(&trials) {
        let level = [1, 4, 16, 64][trial.0];
        assert_eq!(&row[column("level")], level.to_string());
        assert_eq!(&row[column("correct")], trial.2.unwrap().to_string());
        let x: f64 = row[column("x")].parse().unwrap();
        assert!((x - (1.0 / f64::from(level)).log10()).abs() < 1e-12, "{x}");
        assert_eq!(&row[column("function")], "weibull");
        assert_eq!(&row[column("scale")], "log10");
        assert_eq!(&row[column("guess")], "0.5");
        assert_eq!(&row[column("scene")], trial.3);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_on_demand_level_missing_from_the_store_is_rendered_for_the_participant_who_needs_it() {
    let work = tempfile::tempdir().unwrap();
    write_study_rendered(&work.path().join("studies"), "render = \"on-demand\"\nrender_ahead = 1");
    let Started { app, state, skipped, admin_token, .. } =
        support::start(work.path(), &work.path().join("studies")).await;
    if !skipped.is_empty() {
        assert!(skipped.iter().all(|line| line.contains("no adapter")), "{skipped:?}");
        return;
    }
    let prepared = state.study(STUDY).unwrap().clone();
    // start-up rendered the first trial's level only (and every ground truth)
    let rendered_at_start: Vec<usize> =
        (0..4).filter(|&level| prepared.stimuli.iter().all(|names| !names[level].is_empty())).collect();
    assert_eq!(rendered_at_start.len(), 1, "{:?}", prepared.stimuli);
    let (id, token) = join(&app).await;
    while let Some(trial) = next(&app, &state, &id, &token).await {
        answer(&app, &id, &token, trial).await;
    }
    let trials = stored(&state, &id).await;
    assert_eq!(trials.len(), 10);
    // every level shown is QUEST+'s after the answers before it
    assert_levels_replay(&state, &trials);
    let levels: std::collections::BTreeSet<usize> = trials.iter().map(|t| t.0).collect();
    assert!(levels.iter().any(|level| !rendered_at_start.contains(level)), "{trials:?}");
    // the queue rendered the others and the levels queued ahead of need (the two a trial can
    // show after each answer), each once
    let queue = state.render_queue();
    for _ in 0..600 {
        if queue.summary().contains("idle; 0 waiting") {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    let on_demand: std::collections::BTreeSet<(usize, &str)> =
        trials.iter().filter(|t| !rendered_at_start.contains(&t.0)).map(|t| (t.0, t.3.as_str())).collect();
    assert!(queue.rendered() >= on_demand.len(), "{}", queue.summary());
    assert!(queue.summary().contains("queued ahead of need") && !queue.summary().contains(" 0 queued ahead"));
    assert_eq!(queue.refused(), 0);
    // the stimulus metrics (the admin's download) hold every level rendered so far, once each
    let cookie = support::admin_session_cookie(&app, &admin_token).await;
    let request = axum::http::Request::builder()
        .uri(format!("/api/admin/studies/{STUDY}/stimuli.csv"))
        .header(axum::http::header::COOKIE, cookie.clone())
        .body(axum::body::Body::empty())
        .unwrap();
    let metrics = support::send(&app, request).await;
    assert_eq!(metrics.status, StatusCode::OK, "{}", metrics.text());
    let rows: Vec<(String, String)> = metrics
        .text()
        .lines()
        .filter(|line| line.contains(",render_ms,"))
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            (fields[1].to_string(), fields[2].to_string())
        })
        .collect();
    let distinct: std::collections::BTreeSet<&(String, String)> = rows.iter().collect();
    assert_eq!(distinct.len(), rows.len(), "{rows:?}");
    assert_eq!(rows.len(), 2 * rendered_at_start.len() + queue.rendered(), "{rows:?} {}", queue.summary());
    // the admin page shows the queue
    let request = axum::http::Request::builder()
        .uri("/admin")
        .header(axum::http::header::COOKIE, cookie)
        .body(axum::body::Body::empty())
        .unwrap();
    let page = support::send(&app, request).await;
    assert_eq!(page.status, StatusCode::OK);
    let line = format!("{} rendered", queue.rendered());
    assert!(page.text().contains("Render queue") && page.text().contains(&line), "{}", page.text());
    let names = sqlx::query("SELECT left_stimulus, right_stimulus FROM trials WHERE participant = $1")
        .bind(&id)
        .fetch_all(&state.storage().read)
        .await
        .unwrap();
    for row in names {
        for column in ["left_stimulus", "right_stimulus"] {
            let name: String = row.get(column);
            assert!(!name.is_empty() && state.stimuli_dir().join(&name).is_file(), "{column} {name:?}");
        }
    }
}
