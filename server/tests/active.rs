//! Active designs in the web survey (`pairs = "active"`), through `app(state)` with `oneshot` on
//! a real sqlite database: participants interleaved get every trial they are owed, no pair twice
//! in a row, sides balanced; each stored batch replays from the database (the first N judgments
//! in commit order, the participant's history, their seed) to the same trials; many
//! participants asking at once each get valid trials, and two requests of one participant get
//! the same trial.

use std::collections::BTreeMap;
use std::path::Path;

use axum::Router;
use axum::http::{Method, StatusCode};
use mrstudy_server::AppState;
use mrstudy_server::schedule::{self, ActiveHistory, PlannedKind};
use serde_json::json;
use sqlx::Row;

mod support;
use support::{Started, call, demo_studies, demographics, start};

const STUDY: &str = "shadows-demo";

/// The demo study (four conditions, six scene configurations, a catch trial) with an active
/// design of `trials` trials in batches of `batch` after the warm-up that the TOML lines
/// `warmup` give.
async fn fixture(work: &Path, target: &str, warmup: &str, trials: u32, batch: u32) -> (Router, AppState) {
    let (app, state, _) = fixture_with_admin(work, target, warmup, trials, batch).await;
    (app, state)
}

/// [`fixture`], with the admin token.
async fn fixture_with_admin(
    work: &Path,
    target: &str,
    warmup: &str,
    trials: u32,
    batch: u32,
) -> (Router, AppState, String) {
    let design = format!(
        "[design]\npairs = \"active\"\ntrials = {trials}\nbatch = {batch}\ntarget = \"{target}\"\n{warmup}\nscenes = \"different\"\n"
    );
    let studies = demo_studies(work, |text| {
        let text = text.replace("[design]\npairs = \"all\"\nrepetitions = 1\nscenes = \"different\"\n", &design);
        assert!(text.contains("pairs = \"active\""), "the demo study's design changed; update this fixture");
        text
    });
    let Started { app, state, skipped, admin_token, .. } = start(work, &studies).await;
    assert!(skipped.is_empty(), "{skipped:?}");
    (app, state, admin_token)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_admin_page_says_what_the_active_design_optimises() {
    for (target, prior, chosen, optimises) in [
        (
            "effects",
            "fixed",
            "the expected drop of the posterior entropy of the factor effects",
            "the factor effects (not the individual log-worths)",
        ),
        (
            "worths",
            "fixed",
            "the expected drop of the posterior entropy of every condition&#39;s log-worth",
            "every condition&#39;s log-worth;",
        ),
        (
            "both",
            "fixed",
            "the expected drop of the summed posterior variance of the log-worths and of the factor effects",
            "the log-worths and the factor effects together",
        ),
        (
            "worths",
            "spread",
            "under a hierarchical prior on their spread (prior = &#34;spread&#34;, the spread&#39;s prior mean 1) for \
             the study&#39;s first 15 trials per condition (all participants together), then as with the fixed prior",
            "every condition&#39;s log-worth as the centred MAP estimate with prior sd 1 (`log_worth_map` of \
             `mrstudy analyze`), not the maximum-likelihood log-worths",
        ),
    ] {
        let work = tempfile::tempdir().unwrap();
        let warmup = format!("warmup = \"anchored\"\nanchors = [\"LQ\"]\nprior = \"{prior}\"");
        let (app, _, admin_token) = fixture_with_admin(work.path(), target, &warmup, 6, 2).await;
        let page = call(&app, Method::GET, &format!("/admin/studies/{STUDY}"), Some(&admin_token), None).await;
        assert_eq!(page.status, StatusCode::OK, "{}", page.text());
        let text = page.text();
        let note = text.lines().find(|line| line.contains("Active design")).unwrap_or_default();
        assert!(
            note.contains(&format!("target = &#34;{target}&#34;, prior = &#34;{prior}&#34;"))
                && note.contains(chosen)
                && note.contains(&format!("it optimises {optimises}")),
            "target {target}: {note}"
        );
        // the demo study's 4 conditions anchored on LQ: 3 warm-up pairs, once
        assert!(note.contains("after a warm-up of 3 fixed pair trials per participant"), "{note}");
    }
}

async fn join(app: &Router) -> (String, String, i64) {
    let body = json!({"demographics": demographics(), "client": {"viewport": [1280, 800], "devicePixelRatio": 1}});
    let (id, token, json) = support::join(app, STUDY, body).await;
    (id, token, json["trials"].as_i64().unwrap())
}

/// Serves and answers one trial (the shadow preferred, camera artifacts disliked; the catch
/// trial as expected); returns false when the participant is done.
async fn answer_one(app: &Router, state: &AppState, id: &str, token: &str) -> bool {
    let next = call(app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await;
    assert_eq!(next.status, StatusCode::OK, "{}", next.text());
    let next = next.json();
    if next["done"] == true {
        return false;
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
    let (left, right): (String, String) = (row.get("left_condition"), row.get("right_condition"));
    let chosen = match row.get::<Option<String>, _>("catch_expected") {
        Some(expected) => expected,
        None => {
            let score = |condition: &str| condition.contains("SH") as i32 * 2 - condition.contains("CA") as i32;
            (if score(&left) >= score(&right) { "left" } else { "right" }).to_string()
        }
    };
    let stored = call(
        app,
        Method::POST,
        &format!("/api/participants/{id}/responses"),
        Some(token),
        Some(json!({"trial": trial, "chosen": chosen, "rt_ms": 900.0, "client": {"viewport": [1280, 800]}})),
    )
    .await;
    assert_eq!(stored.status, StatusCode::CREATED, "{}", stored.text());
    true
}

/// Every stored batch is what `schedule::active_batch` gives for the posterior after the
/// first N judgments (commit order), the participant's seed and history.
async fn assert_batches_replay(state: &AppState) -> usize {
    let prepared = state.study(STUDY).unwrap();
    let (replayed, differing) = replay_batches(state, &prepared.study).await;
    assert!(differing.is_empty(), "stored trials the replay does not give: {differing:?}");
    replayed
}

/// Replays every stored batch through `study`'s posterior (`schedule::active_posterior`) after
/// the first N judgments (commit order), the participant's seed and history: the trials
/// replayed, and those whose conditions or scene configurations differ from the stored ones.
async fn replay_batches(state: &AppState, study: &mrstudy_server::study::Study) -> (usize, Vec<String>) {
    let pool = &state.storage().read;
    let index = |name: &str| study.conditions.iter().position(|c| c.name == name);
    let judgments: Vec<(usize, usize)> = sqlx::query(
        "SELECT t.left_condition, t.right_condition, r.chosen FROM responses r
         JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
         WHERE t.catch_expected IS NULL ORDER BY r.seq",
    )
    .fetch_all(pool)
    .await
    .unwrap()
    .iter()
    .map(|row| {
        let (left, right) = (index(row.get("left_condition")).unwrap(), index(row.get("right_condition")).unwrap());
        if row.get::<String, _>("chosen") == "left" { (left, right) } else { (right, left) }
    })
    .collect();
    let participants = sqlx::query("SELECT id, seed FROM participants").fetch_all(pool).await.unwrap();
    let (mut replayed, mut differing) = (0, Vec::new());
    for participant in participants {
        let (id, seed): (String, i64) = (participant.get("id"), participant.get("seed"));
        let rows = sqlx::query(
            "SELECT left_condition, right_condition, left_scene, right_scene, catch_expected, chosen_by, active_batch
             FROM trials WHERE participant = $1 ORDER BY trial",
        )
        .bind(&id)
        .fetch_all(pool)
        .await
        .unwrap();
        let mut batches: BTreeMap<i64, Vec<&sqlx::any::AnyRow>> = BTreeMap::new();
        for row in &rows {
            if let Some(batch) = row.get::<Option<i64>, _>("active_batch") {
                batches.entry(batch).or_default().push(row);
            }
        }
        for (batch, trials) in batches {
            let chosen_by: String = trials[0].get("chosen_by");
            let absorbed: usize = chosen_by.split('-').next().unwrap().parse().unwrap();
            let mut posterior = schedule::active_posterior(study).unwrap().unwrap();
            for &(winner, loser) in &judgments[..absorbed] {
                posterior.update(winner, loser).unwrap();
            }
            assert_eq!(posterior.state_id().to_string(), chosen_by, "the state that chose batch {batch} of {id}");
            // the participant's pairs before this batch
            let before: Vec<(usize, usize)> = rows
                .iter()
                .take_while(|row| row.get::<Option<i64>, _>("active_batch").is_none_or(|b| b < batch))
                .filter(|row| row.get::<Option<String>, _>("catch_expected").is_none())
                .map(|row| (index(row.get("left_condition")).unwrap(), index(row.get("right_condition")).unwrap()))
                .collect();
            let mut history = ActiveHistory::of(study.conditions.len(), &before, batch as u64);
            let planned = schedule::active_batch(study, &posterior, seed as u64, &mut history, trials.len()).unwrap();
            for (planned, stored) in planned.iter().zip(&trials) {
                let PlannedKind::Pair { left, right } = planned.kind else { panic!("an active trial is a pair") };
                let replay = [
                    &study.conditions[left].name,
                    &study.conditions[right].name,
                    &study.scenes[planned.left_scene].name,
                    &study.scenes[planned.right_scene].name,
                ];
                let kept: [String; 4] = ["left_condition", "right_condition", "left_scene", "right_scene"]
                    .map(|column| stored.get::<String, _>(column));
                if replay.iter().zip(&kept).any(|(a, b)| *a != b) {
                    differing.push(format!("batch {batch} of {id}: replayed {replay:?}, stored {kept:?}"));
                }
                replayed += 1;
            }
        }
    }
    (replayed, differing)
}

/// Stored active trials that `study`'s posterior would have chosen otherwise.
async fn differing_batches(state: &AppState, study: &mrstudy_server::study::Study) -> usize {
    replay_batches(state, study).await.1.len()
}

#[tokio::test]
async fn interleaved_participants_get_every_trial_and_every_batch_replays_from_the_database() {
    let work = tempfile::tempdir().unwrap();
    let (_, state) = interleaved(work.path(), "factors", "warmup = \"anchored\"\nanchors = [\"LQ\"]").await;
    // the admin page says the design is active and has absorbed judgments
    let judgments = state.active(STUDY).unwrap().lock().await.judgments();
    assert!(judgments > 0 && state.active(STUDY).unwrap().lock().await.failure.is_none());
}

/// `prior = "spread"` (issue 48): the hierarchical prior on the log-worths' spread chooses the
/// batches, and every batch replays from the stored answers through `schedule::active_posterior`
/// — which a posterior with the fixed prior would not reproduce.
#[tokio::test]
async fn with_the_spread_prior_every_batch_replays_and_the_prior_chose_them() {
    let work = tempfile::tempdir().unwrap();
    let (_, state) =
        interleaved(work.path(), "worths", "warmup = \"anchored\"\nanchors = [\"LQ\"]\nprior = \"spread\"").await;
    let prepared = state.study(STUDY).unwrap();
    assert_eq!(prepared.study.design.active.as_ref().unwrap().prior, mrstudy_server::study::ActivePrior::Spread);
    assert!(state.active(STUDY).unwrap().lock().await.failure.is_none());
    // the same study with the fixed prior replays some batch differently
    let mut fixed = prepared.study.clone();
    fixed.design.active.as_mut().unwrap().prior = mrstudy_server::study::ActivePrior::Fixed;
    assert!(differing_batches(&state, &fixed).await > 0, "the spread prior chose no batch the fixed prior would not");
}

/// `prior = "spread"` past its switch (15 judgments per condition: 60 for the demo study's 4
/// conditions): six participants judge 78 pairs, the later batches are chosen on the ADF
/// posterior, and every batch — before and after the switch — replays from the stored answers.
#[tokio::test]
async fn with_the_spread_prior_batches_after_the_switch_replay_too() {
    let work = tempfile::tempdir().unwrap();
    let warmup = "warmup = \"anchored\"\nanchors = [\"LQ\"]\nprior = \"spread\"";
    let (_, state, _) = interleaved_with_admin(work.path(), "worths", warmup, 6).await;
    let chosen_by: Vec<String> = sqlx::query("SELECT DISTINCT chosen_by FROM trials WHERE active_batch IS NOT NULL")
        .fetch_all(&state.storage().read)
        .await
        .unwrap()
        .iter()
        .map(|row| row.get("chosen_by"))
        .collect();
    let absorbed = |state: &String| state.split('-').next().unwrap().parse::<f64>().unwrap();
    let switch = mrstudy_analysis::active::SPREAD_SWITCH * 4.0;
    assert!(chosen_by.iter().any(|s| absorbed(s) < switch), "no batch before the switch: {chosen_by:?}");
    assert!(chosen_by.iter().any(|s| absorbed(s) >= switch), "no batch after the switch: {chosen_by:?}");
}

/// Three participants, interleaved, answer every trial of an active design of 10 trials in
/// batches of 3 after `warmup`; every stored batch replays. The app and state afterwards.
async fn interleaved(work: &Path, target: &str, warmup: &str) -> (Router, AppState) {
    let (app, state, _) = interleaved_with_admin(work, target, warmup, 3).await;
    (app, state)
}

/// [`interleaved`] with `count` participants, and the admin token.
async fn interleaved_with_admin(work: &Path, target: &str, warmup: &str, count: usize) -> (Router, AppState, String) {
    let (app, state, admin_token) = fixture_with_admin(work, target, warmup, 10, 3).await;
    let mut participants = Vec::new();
    for _ in 0..count {
        participants.push(join(&app).await);
    }
    // warm-up: the anchor with each of the 3 others, 1 catch trial, then 10 chosen trials
    assert!(participants.iter().all(|p| p.2 == 3 + 1 + 10), "{participants:?}");
    let mut running = vec![true; participants.len()];
    while running.iter().any(|&r| r) {
        for (index, (id, token, _)) in participants.iter().enumerate() {
            if running[index] {
                running[index] = answer_one(&app, &state, id, token).await;
            }
        }
    }
    let pool = &state.storage().read;
    for (id, _, trials) in &participants {
        let row = sqlx::query(
            "SELECT answered, CASE WHEN completed_at IS NULL THEN 0 ELSE 1 END AS done FROM participants WHERE id = $1",
        )
        .bind(id)
        .fetch_one(pool)
        .await
        .unwrap();
        assert_eq!(row.get::<i64, _>("answered"), *trials);
        assert_eq!(row.get::<i64, _>("done"), 1);
        let pairs = sqlx::query("SELECT left_condition, right_condition FROM trials WHERE participant = $1 AND active_batch IS NOT NULL ORDER BY trial")
            .bind(id)
            .fetch_all(pool)
            .await
            .unwrap();
        assert_eq!(pairs.len(), 10);
        let unordered = |row: &sqlx::any::AnyRow| {
            let (a, b): (String, String) = (row.get("left_condition"), row.get("right_condition"));
            if a < b { (a, b) } else { (b, a) }
        };
        for window in pairs.windows(2) {
            assert_ne!(unordered(&window[0]), unordered(&window[1]), "a pair twice in a row for {id}");
        }
    }
    let replayed = assert_batches_replay(&state).await;
    assert_eq!(replayed, 10 * count);
    (app, state, admin_token)
}

/// The admin page's analysis reports `log_worth_map` with the study's `prior_sd` (what
/// `prior = "spread"` scores under), as `mrstudy analyze --prior-sd` of the export does — not
/// with the default 1.
#[tokio::test]
async fn the_live_analysis_reports_the_map_log_worths_with_the_studys_prior_sd() {
    let work = tempfile::tempdir().unwrap();
    let warmup = "warmup = \"anchored\"\nanchors = [\"LQ\"]\nprior = \"spread\"\nprior_sd = 0.4";
    let (app, _, admin_token) = interleaved_with_admin(work.path(), "worths", warmup, 3).await;
    let live = call(&app, Method::GET, &format!("/api/admin/studies/{STUDY}/analysis"), Some(&admin_token), None).await;
    assert_eq!(live.status, StatusCode::OK, "{}", live.text());
    let export =
        call(&app, Method::GET, &format!("/api/admin/studies/{STUDY}/export.csv"), Some(&admin_token), None).await;
    assert_eq!(export.status, StatusCode::OK, "{}", export.text());
    // by condition: the export lists the conditions in another order than the study
    let maps = |json: &serde_json::Value| -> Vec<f64> {
        let mut items: Vec<(String, f64)> = json["items"]
            .as_array()
            .unwrap()
            .iter()
            .map(|item| (item["condition"].as_str().unwrap().to_owned(), item["log_worth_map"].as_f64().unwrap()))
            .collect();
        items.sort_by(|a, b| a.0.cmp(&b.0));
        items.into_iter().map(|(_, map)| map).collect()
    };
    let offline = |prior_sd: f64| {
        let options = mrstudy_analysis::analysis::Options { prior_sd, ..Default::default() };
        let analysis = mrstudy_analysis::analysis::analyze(&export.text(), None, &options).unwrap();
        maps(&serde_json::to_value(&analysis).unwrap())
    };
    let (live, at_study, at_one) = (maps(&live.json()), offline(0.4), offline(1.0));
    assert_eq!(live.len(), 4);
    let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);
    assert!(close(&live, &at_study), "live {live:?}, analyze --prior-sd 0.4 {at_study:?}");
    assert!(!close(&live, &at_one), "the prior sd made no difference: {live:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn many_participants_at_once_get_valid_trials_and_one_participant_asking_twice_gets_one_trial() {
    let work = tempfile::tempdir().unwrap();
    let (app, state) = fixture(work.path(), "worths", "warmup = \"none\"", 6, 2).await;
    let mut joined = Vec::new();
    for _ in 0..12 {
        joined.push(join(&app).await);
    }
    // without a warm-up the only trial planned at join is the catch trial; once it is answered,
    // every participant's next trial is chosen at once, two requests each
    for (id, token, _) in &joined {
        assert!(answer_one(&app, &state, id, token).await);
    }
    let mut tasks = Vec::new();
    for (id, token, _) in &joined {
        for _ in 0..2 {
            let (app, id, token) = (app.clone(), id.clone(), token.clone());
            tasks.push(tokio::spawn(async move {
                call(&app, Method::GET, &format!("/api/participants/{id}/next"), Some(&token), None).await
            }));
        }
    }
    let mut firsts: BTreeMap<String, Vec<serde_json::Value>> = BTreeMap::new();
    for (task, (id, _, _)) in tasks.into_iter().zip(joined.iter().flat_map(|p| [p.clone(), p.clone()])) {
        let answer = task.await.unwrap();
        assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        firsts.entry(id).or_default().push(answer.json());
    }
    for (id, answers) in &firsts {
        assert_eq!(answers[0]["trial"], 2, "{id}");
        assert_eq!(answers[0]["left"], answers[1]["left"], "two requests of {id} got different trials");
    }
    let pool = &state.storage().read;
    let batches: i64 = sqlx::query_scalar(
        "SELECT COUNT(DISTINCT participant || ':' || active_batch) FROM trials WHERE active_batch IS NOT NULL",
    )
    .fetch_one(pool)
    .await
    .unwrap();
    assert_eq!(batches, 12, "one batch per participant");
    for (id, token, _) in &joined {
        while answer_one(&app, &state, id, token).await {}
    }
    assert_eq!(assert_batches_replay(&state).await, 12 * 6);
    let sides =
        sqlx::query("SELECT participant, left_condition, right_condition FROM trials").fetch_all(pool).await.unwrap();
    // per participant, no condition is on one side more than 3 times more often than the other
    let mut balance: BTreeMap<(String, String), i64> = BTreeMap::new();
    for row in &sides {
        let participant: String = row.get("participant");
        *balance.entry((participant.clone(), row.get("left_condition"))).or_default() += 1;
        *balance.entry((participant, row.get("right_condition"))).or_default() -= 1;
    }
    assert!(balance.values().all(|b| b.abs() <= 3), "{balance:?}");
}

#[tokio::test]
async fn a_response_to_a_trial_not_chosen_yet_is_refused_and_nothing_is_stored() {
    let work = tempfile::tempdir().unwrap();
    let (app, state) = fixture(work.path(), "worths", "warmup = \"none\"", 4, 2).await;
    let (id, token, _) = join(&app).await;
    let answer = call(
        &app,
        Method::POST,
        &format!("/api/participants/{id}/responses"),
        Some(&token),
        Some(json!({"trial": 2, "chosen": "left", "rt_ms": 900.0, "client": {}})),
    )
    .await;
    assert_eq!(answer.status, StatusCode::CONFLICT, "{}", answer.text());
    let stored: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM responses").fetch_one(&state.storage().read).await.unwrap();
    assert_eq!(stored, 0);
}
