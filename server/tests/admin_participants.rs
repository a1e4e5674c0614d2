//! The researcher's side of "trustworthy responses" through `app(state)` with `oneshot`, on a
//! real sqlite database: the participants list (status, progress, external ids, flags,
//! screen-outs), exclude/include and what they do to the analysis and the exports, deletion
//! that leaves nothing of the participant in the database file, preview links and pilots, and
//! the refusals. Each test gets a fresh data directory with the demo study (plus a free-text
//! demographic field, so deletion has a text of the participant's own to look for).

use std::path::{Path, PathBuf};

use axum::Router;
use axum::body::Body;
use axum::http::{Method, Request, StatusCode, header};
use mrstudy_server::AppState;
use mrstudy_server::storage::{Backend, Database};
use serde_json::{Value, json};

mod support;
use support::{Answer, Started, before_texts, call, demo_studies, demographics, join, send, start};

const STUDY: &str = "shadows-demo";

/// The demo study with a free-text demographic field `comment` appended, and `top_level` keys
/// (lines) before its `[texts]`.
fn studies_dir(work: &Path, top_level: &str) -> PathBuf {
    demo_studies(work, |text| {
        before_texts(&text, top_level)
            + "\n[[demographics]]\nname = \"comment\"\nlabel = \"Anything to add?\"\ntype = \"text\"\nrequired = false\n"
    })
}

struct Fixture {
    app: Router,
    state: AppState,
    admin_token: String,
    data: PathBuf,
    database: Database,
    _work: tempfile::TempDir,
}

async fn fixture() -> Fixture {
    fixture_with("").await
}

/// The fixture with `top_level` keys in the study file.
async fn fixture_with(top_level: &str) -> Fixture {
    let work = tempfile::tempdir().unwrap();
    let studies = studies_dir(work.path(), top_level);
    let Started { app, state, admin_token, skipped, database, data } = start(work.path(), &studies).await;
    assert!(skipped.is_empty(), "{skipped:?}");
    Fixture { app, state, admin_token, data, database, _work: work }
}

impl Fixture {
    async fn admin(&self, method: Method, uri: &str, body: Option<Value>) -> Answer {
        call(&self.app, method, uri, Some(&self.admin_token), body).await
    }

    /// Joins with `PROLIFIC_PID = pid` and `comment`; returns (id, token).
    async fn join(&self, pid: &str, comment: &str) -> (String, String) {
        let mut demographics = demographics();
        demographics["comment"] = json!(comment);
        let body = json!({
            "demographics": demographics,
            "client": {"viewport": [1280, 800], "devicePixelRatio": 2, "userAgent": "test"},
            "url_params": {"PROLIFIC_PID": pid},
        });
        let (id, token, _) = join(&self.app, STUDY, body).await;
        (id, token)
    }

    /// Serves and answers the participant's next `count` trials: the catch trial as expected
    /// unless `fail_catch`, every judgment for the condition with the shadow (then without
    /// camera artifacts), so that the data fit a Bradley–Terry model without separation only
    /// when `flip` participants answer the other way.
    async fn answer(&self, id: &str, token: &str, count: usize, fail_catch: bool, flip: bool) {
        for _ in 0..count {
            let next =
                call(&self.app, Method::GET, &format!("/api/participants/{id}/next"), Some(token), None).await.json();
            let trial = next["trial"].as_i64().unwrap_or_else(|| panic!("no next trial: {next}"));
            let row = sqlx::query_as::<_, (String, String, Option<String>)>(
                "SELECT left_condition, right_condition, catch_expected FROM trials WHERE participant = $1 AND trial = $2",
            )
            .bind(id)
            .bind(trial)
            .fetch_one(&self.state.storage().read)
            .await
            .unwrap();
            let chosen = match row {
                (_, _, Some(expected)) => {
                    if fail_catch {
                        if expected == "left" { "right" } else { "left" }
                    } else if expected == "left" {
                        "left"
                    } else {
                        "right"
                    }
                }
                (left, right, None) => {
                    let score = |condition: &str| condition.contains("SH") as i32 * 2 - condition.contains("CA") as i32;
                    if (score(&left) >= score(&right)) != flip { "left" } else { "right" }
                }
            };
            let answer = call(
                &self.app,
                Method::POST,
                &format!("/api/participants/{id}/responses"),
                Some(token),
                Some(json!({"trial": trial, "chosen": chosen, "rt_ms": 900.0, "client": {}})),
            )
            .await;
            assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
        }
    }

    /// SQL for the time `seconds` ago, as the database stores times.
    fn seconds_ago(&self, seconds: u32) -> String {
        match self.database.backend() {
            Backend::Postgres => format!(
                r#"to_char((now() - interval '{seconds} seconds') AT TIME ZONE 'UTC', 'YYYY-MM-DD"T"HH24:MI:SS.MS"Z"')"#
            ),
            Backend::Sqlite => format!("strftime('%Y-%m-%dT%H:%M:%fZ', 'now', '-{seconds} seconds')"),
        }
    }

    async fn sql(&self, statement: &str) {
        sqlx::query(sqlx::AssertSqlSafe(statement.to_string())).execute(&self.state.storage().read).await.unwrap();
    }

    async fn participants(&self) -> Vec<Value> {
        let answer = self.admin(Method::GET, &format!("/api/admin/studies/{STUDY}/participants"), None).await;
        assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        answer.json().as_array().unwrap().clone()
    }

    async fn export_csv(&self, query: &str) -> Answer {
        let answer = self.admin(Method::GET, &format!("/api/admin/studies/{STUDY}/export.csv{query}"), None).await;
        assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        answer
    }

    /// Distinct participants in a trials CSV.
    fn csv_participants(csv: &str) -> std::collections::BTreeSet<String> {
        let mut reader = csv::Reader::from_reader(csv.as_bytes());
        let column = reader.headers().unwrap().iter().position(|name| name == "participant").unwrap();
        reader.records().map(|record| record.unwrap()[column].to_string()).collect()
    }

    async fn analysis(&self) -> Value {
        let answer = self.admin(Method::GET, &format!("/api/admin/studies/{STUDY}/analysis"), None).await;
        assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        answer.json()
    }

    async fn audit(&self) -> Vec<(String, String, String)> {
        sqlx::query_as("SELECT action, study, detail FROM audit ORDER BY id")
            .fetch_all(&self.state.storage().read)
            .await
            .unwrap()
    }
}

fn entry<'a>(list: &'a [Value], id: &str) -> &'a Value {
    list.iter().find(|entry| entry["participant"] == id).unwrap_or_else(|| panic!("{id} not listed: {list:?}"))
}

#[tokio::test]
async fn participants_list_statuses_progress_external_ids_and_flags() {
    let fixture = fixture().await;
    let (done, done_token) = fixture.join("PID-DONE", "").await;
    fixture.answer(&done, &done_token, 7, true, false).await;
    let (going, going_token) = fixture.join("PID-GOING", "").await;
    fixture.answer(&going, &going_token, 2, false, false).await;
    let (gone, gone_token) = fixture.join("PID-GONE", "").await;
    fixture.answer(&gone, &gone_token, 1, false, false).await;
    // The last participant's activity two hours ago, beyond the default abandon_after_minutes (30).
    let ago = fixture.seconds_ago(7200);
    for statement in [
        format!("UPDATE participants SET created_at = {ago} WHERE id = '{gone}'"),
        format!("UPDATE trials SET shown_at = {ago} WHERE participant = '{gone}' AND shown_at IS NOT NULL"),
        format!("UPDATE responses SET answered_at = {ago} WHERE participant = '{gone}'"),
        // (answered at once here, so the server flagged every response too fast: set exactly two)
        format!(
            "UPDATE responses SET too_fast = CASE WHEN participant = '{done}' AND trial IN (1, 2) THEN 1 ELSE 0 END"
        ),
        "INSERT INTO screen_outs (id, study, reason, client, url_params, pilot, created_at)
         VALUES ('5c0ee0005c0ee0005c0ee0005c0ee000', 'shadows-demo', 'The window is too small for the images.',
                 '{\"viewport\": [320, 480]}', '{\"PROLIFIC_PID\": \"PID-SMALL\"}', 0, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))"
            .to_string(),
    ] {
        fixture.sql(&statement).await;
    }
    let list = fixture.participants().await;
    assert_eq!(list.len(), 4, "{list:?}");
    let done_entry = entry(&list, &done);
    assert_eq!(done_entry["status"], "completed");
    assert_eq!(done_entry["progress"], json!({"answered": 7, "trials": 7}));
    assert_eq!(done_entry["external_ids"], json!({"PROLIFIC_PID": "PID-DONE"}));
    assert_eq!(done_entry["completion_code"], "DEMO-7F3A");
    assert_eq!(done_entry["pilot"], false);
    assert_eq!(done_entry["excluded"], false);
    assert_eq!(done_entry["flags"]["too_fast"], 2);
    assert_eq!(done_entry["flags"]["catch_answered"], 1);
    assert_eq!(done_entry["flags"]["catch_failed"], 1);
    let going_entry = entry(&list, &going);
    assert_eq!(going_entry["status"], "started");
    assert_eq!(going_entry["progress"], json!({"answered": 2, "trials": 7}));
    assert_eq!(going_entry["flags"]["too_fast"], 0);
    assert_eq!(going_entry["flags"]["catch_failed"], 0);
    let gone_entry = entry(&list, &gone);
    assert_eq!(gone_entry["status"], "abandoned");
    assert_eq!(gone_entry["progress"], json!({"answered": 1, "trials": 7}));
    let screened = entry(&list, "5c0ee0005c0ee0005c0ee0005c0ee000");
    assert_eq!(screened["status"], "screened-out");
    assert_eq!(screened["external_ids"], json!({"PROLIFIC_PID": "PID-SMALL"}));
    assert_eq!(screened["screen_out_reason"], "The window is too small for the images.");
    assert_eq!(screened["completion_code"], Value::Null);

    // The export carries status, code, flags and the external id per row.
    let csv = fixture.export_csv("").await.text();
    let mut reader = csv::Reader::from_reader(csv.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(str::to_string).collect();
    let column = |name: &str| {
        header.iter().position(|column| column == name).unwrap_or_else(|| panic!("no column {name}: {header:?}"))
    };
    let mut too_fast_rows = 0;
    for record in reader.records() {
        let record = record.unwrap();
        let id = &record[column("participant")];
        let expected_status = if id == done {
            "completed"
        } else if id == going {
            "started"
        } else {
            "abandoned"
        };
        assert_eq!(&record[column("status")], expected_status);
        assert_eq!(&record[column("completion_code")], "DEMO-7F3A");
        assert_eq!(&record[column("pilot")], "false");
        assert_eq!(&record[column("excluded")], "false");
        let pid = &record[column("PROLIFIC_PID")];
        assert_eq!(
            pid,
            if id == done {
                "PID-DONE"
            } else if id == going {
                "PID-GOING"
            } else {
                "PID-GONE"
            }
        );
        too_fast_rows += (&record[column("too_fast")] == "true") as usize;
    }
    // Trials 1 and 2 of the finisher are flagged; the catch trial is no row of the CSV.
    let catch_trial: i64 = sqlx::query_scalar(sqlx::AssertSqlSafe(format!(
        "SELECT trial FROM trials WHERE participant = '{done}' AND catch_expected IS NOT NULL"
    )))
    .fetch_one(&fixture.state.storage().read)
    .await
    .unwrap();
    assert_eq!(too_fast_rows, 2 - [1, 2].contains(&catch_trial) as usize);

    // The funnel counts the screened-out visitor; the page shows the table and the buttons.
    let stats = fixture.admin(Method::GET, &format!("/api/admin/studies/{STUDY}"), None).await.json();
    assert_eq!(stats["screened_out"], 1);
    assert_eq!(stats["started"], 3);
    let page = fixture.admin(Method::GET, &format!("/admin/studies/{STUDY}"), None).await;
    assert_eq!(page.status, StatusCode::OK);
    let html = page.text();
    assert!(html.contains("PROLIFIC_PID=PID-GOING"), "{html}");
    assert!(html.contains("abandoned") && html.contains("screened-out"));
    assert!(html.contains("2 too fast") && html.contains("catch failed 1 of 1"));
    assert!(html.contains("of whom 1 were screened out"));
    assert!(
        html.contains(r#"data-action="exclude""#)
            && html.contains(r#"data-action="delete""#)
            && html.contains(r#"id="preview""#)
    );
}

#[tokio::test]
async fn a_short_abandon_timeout_marks_idle_participants_abandoned() {
    let fixture = fixture().await;
    let (idle, idle_token) = fixture.join("PID-IDLE", "").await;
    fixture.answer(&idle, &idle_token, 1, false, false).await;
    assert_eq!(entry(&fixture.participants().await, &idle)["status"], "started");
    // One minute (the shortest allowed) in the stored definition, and activity 90 s ago.
    let postgres = fixture.database.backend() == Backend::Postgres;
    fixture
        .sql(if postgres {
            "UPDATE studies SET definition = jsonb_set(definition::jsonb, '{participation,abandon_after_minutes}', '1')::text WHERE slug = 'shadows-demo'"
        } else {
            "UPDATE studies SET definition = json_set(definition, '$.participation.abandon_after_minutes', 1) WHERE slug = 'shadows-demo'"
        })
        .await;
    let ago = fixture.seconds_ago(90);
    assert_eq!(entry(&fixture.participants().await, &idle)["status"], "started", "activity just now");
    for statement in [
        format!("UPDATE participants SET created_at = {ago} WHERE id = '{idle}'"),
        format!("UPDATE trials SET shown_at = {ago} WHERE participant = '{idle}' AND shown_at IS NOT NULL"),
        format!("UPDATE responses SET answered_at = {ago} WHERE participant = '{idle}'"),
    ] {
        fixture.sql(&statement).await;
    }
    assert_eq!(entry(&fixture.participants().await, &idle)["status"], "abandoned");
}

#[tokio::test]
async fn excluding_changes_the_analysis_and_the_export_and_says_so_and_including_restores() {
    let fixture = fixture().await;
    let mut ids = Vec::new();
    for index in 0..6 {
        let (id, token) = fixture.join(&format!("PID-{index}"), "").await;
        // Two participants answer against the others, so the design has no separation.
        fixture.answer(&id, &token, 7, false, index % 3 == 0).await;
        ids.push(id);
    }
    let before = fixture.analysis().await;
    assert_eq!(before["participants"], 6);
    assert_eq!(before["judgments"], 36);
    assert!(!before["warnings"].to_string().contains("Left out"), "{}", before["warnings"]);
    let list = fixture.participants().await;
    assert!(
        list.iter().all(|entry| entry["flags"]["observer_flagged"].is_boolean()),
        "screened by the analysis: {list:?}"
    );

    let excluded = &ids[1];
    let answer = fixture
        .admin(
            Method::POST,
            &format!("/api/admin/participants/{excluded}/exclude"),
            Some(json!({"reason": "answered with one key throughout"})),
        )
        .await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    assert_eq!(answer.json()["excluded"], true);
    let after = fixture.analysis().await;
    assert_eq!(after["participants"], 5);
    assert_eq!(after["judgments"], 30);
    assert_eq!(
        after["warnings"][0],
        "Left out 1 excluded participant (excluded by the researcher); add ?include_pilots=true or ?include_excluded=true to keep them."
    );
    let csv = fixture.export_csv("").await;
    assert!(!Fixture::csv_participants(&csv.text()).contains(excluded));
    assert_eq!(Fixture::csv_participants(&csv.text()).len(), 5);
    assert!(csv.headers.get("x-mrstudy-left-out").unwrap().to_str().unwrap().contains("1 excluded participant"));
    let everyone = fixture.export_csv("?include_excluded=true").await;
    assert!(everyone.headers.get("x-mrstudy-left-out").is_none());
    let text = everyone.text();
    assert!(Fixture::csv_participants(&text).contains(excluded));
    assert!(
        text.lines().any(|line| line.contains(excluded.as_str()) && line.contains(",false,true,")),
        "excluded flag in the row"
    );
    let json = fixture.admin(Method::GET, &format!("/api/admin/studies/{STUDY}/export.json"), None).await.json();
    assert_eq!(json["participants"].as_array().unwrap().len(), 5);
    assert_eq!(json["left_out"], json!({"pilots": 0, "excluded": 1}));
    let json = fixture
        .admin(Method::GET, &format!("/api/admin/studies/{STUDY}/export.json?include_excluded=true"), None)
        .await
        .json();
    let kept = json["participants"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["participant"] == excluded.as_str())
        .unwrap()
        .clone();
    assert_eq!(kept["excluded"], true);
    assert_eq!(kept["exclusion_reason"], "answered with one key throughout");
    assert_eq!(kept["external_ids"], json!({"PROLIFIC_PID": "PID-1"}));
    let listed = fixture.participants().await;
    let listed = entry(&listed, excluded);
    assert_eq!(listed["excluded"], true);
    assert_eq!(listed["exclusion_reason"], "answered with one key throughout");
    assert!(listed["excluded_at"].as_str().unwrap().ends_with('Z'));

    let answer = fixture.admin(Method::POST, &format!("/api/admin/participants/{excluded}/include"), None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    assert_eq!(answer.json(), json!({"participant": excluded, "excluded": false}));
    let restored = fixture.analysis().await;
    assert_eq!(restored["participants"], 6);
    assert_eq!(restored["items"], before["items"], "the same fit as before the exclusion");
    assert!(!restored["warnings"].to_string().contains("Left out"));
    assert_eq!(Fixture::csv_participants(&fixture.export_csv("").await.text()).len(), 6);

    // The audit log has both, with the ordinal and without the reason.
    let audit = fixture.audit().await;
    assert_eq!(audit.len(), 2, "{audit:?}");
    assert_eq!((audit[0].0.as_str(), audit[0].1.as_str()), ("exclude", STUDY));
    assert_eq!(serde_json::from_str::<Value>(&audit[0].2).unwrap(), json!({"ordinal": 1}));
    assert_eq!(audit[1].0, "include");
    assert!(!audit.iter().any(|line| line.2.contains("one key") || line.2.contains(excluded.as_str())));
}

/// The database file and its WAL, as bytes.
fn database_bytes(data: &Path) -> Vec<u8> {
    let mut bytes = std::fs::read(data.join("mrstudy.db")).unwrap();
    if let Ok(wal) = std::fs::read(data.join("mrstudy.db-wal")) {
        bytes.extend(wal);
    }
    bytes
}

fn contains(haystack: &[u8], needle: &str) -> bool {
    haystack.windows(needle.len()).any(|window| window == needle.as_bytes())
}

#[tokio::test]
async fn deleting_a_participant_leaves_nothing_of_them_in_the_database_file() {
    let fixture = fixture().await;
    let (keep, keep_token) = fixture.join("PPID-KEEP-0042", "a comment that stays").await;
    fixture.answer(&keep, &keep_token, 3, false, false).await;
    let (gone, gone_token) = fixture.join("PPID-UNIQUE-4711", "my very own unique remark 9x7q").await;
    fixture.answer(&gone, &gone_token, 4, false, false).await;
    fixture
        .admin(
            Method::POST,
            &format!("/api/admin/participants/{gone}/exclude"),
            Some(json!({"reason": "asked to be removed"})),
        )
        .await;
    // The bytes of the database's files (sqlite; PostgreSQL's are the server's).
    let sqlite = fixture.database.backend() == Backend::Sqlite;
    if sqlite {
        // A checkpoint moves the rows into the main file too, so both copies must go.
        fixture.sql("PRAGMA wal_checkpoint(PASSIVE)").await;
        let before = database_bytes(&fixture.data);
        assert!(
            contains(&before, "PPID-UNIQUE-4711") && contains(&before, "my very own unique remark 9x7q"),
            "stored before"
        );
    }

    let answer = fixture.admin(Method::DELETE, &format!("/api/admin/participants/{gone}"), None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    assert_eq!(
        answer.json(),
        json!({"study": STUDY, "kind": "participant", "ordinal": 1, "trials": 7, "responses": 4})
    );

    if sqlite {
        let after = database_bytes(&fixture.data);
        for needle in ["PPID-UNIQUE-4711", "my very own unique remark 9x7q", "asked to be removed", gone.as_str()] {
            assert!(!contains(&after, needle), "\"{needle}\" is still in the database file");
        }
        assert!(contains(&after, "PPID-KEEP-0042"), "the other participant is kept");
        let wal = std::fs::metadata(fixture.data.join("mrstudy.db-wal")).map(|metadata| metadata.len()).unwrap_or(0);
        assert_eq!(wal, 0, "the WAL is truncated");
    }
    let list = fixture.participants().await;
    assert_eq!(list.len(), 1);
    assert_eq!(list[0]["participant"], keep.as_str());
    let json = fixture
        .admin(
            Method::GET,
            &format!("/api/admin/studies/{STUDY}/export.json?include_excluded=true&include_pilots=true"),
            None,
        )
        .await;
    assert!(!json.text().contains("PPID-UNIQUE-4711"));

    // The audit line: study, ordinal and counts, no personal data.
    let audit = fixture.audit().await;
    let delete = audit.iter().find(|line| line.0 == "delete").unwrap();
    assert_eq!(delete.1, STUDY);
    assert_eq!(
        serde_json::from_str::<Value>(&delete.2).unwrap(),
        json!({"study": STUDY, "kind": "participant", "ordinal": 1, "trials": 7, "responses": 4})
    );
    // The deleted participant's token no longer works, and the id is unknown.
    let next =
        call(&fixture.app, Method::GET, &format!("/api/participants/{gone}/next"), Some(&gone_token), None).await;
    assert!(next.status.is_client_error(), "{}", next.text());
    let again = fixture.admin(Method::DELETE, &format!("/api/admin/participants/{gone}"), None).await;
    assert_eq!(again.status, StatusCode::NOT_FOUND);
    again.error();

    // A screen-out row is deleted by its id the same way.
    fixture
        .sql(
            "INSERT INTO screen_outs (id, study, reason, client, url_params, pilot, created_at)
             VALUES ('5c0ee0005c0ee0005c0ee0005c0ee001', 'shadows-demo', 'The window is too small.', '{}',
                     '{\"PROLIFIC_PID\": \"PPID-SCREENED-5150\"}', 0, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))",
        )
        .await;
    let answer = fixture.admin(Method::DELETE, "/api/admin/participants/5c0ee0005c0ee0005c0ee0005c0ee001", None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    assert_eq!(answer.json()["kind"], "screen-out");
    if sqlite {
        assert!(!contains(&database_bytes(&fixture.data), "PPID-SCREENED-5150"));
    }
    assert_eq!(fixture.participants().await.len(), 1);
}

#[tokio::test]
async fn pilots_from_a_preview_link_never_reach_the_default_export_or_analysis() {
    let fixture = fixture().await;
    let answer = fixture.admin(Method::POST, &format!("/api/admin/studies/{STUDY}/preview"), None).await;
    assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.text());
    let url = answer.json()["url"].as_str().unwrap().to_string();
    let token = url.strip_prefix("/studies/shadows-demo?preview=").unwrap_or_else(|| panic!("{url}"));
    assert_eq!(token.len(), 64, "256 bits, hex");
    let stored: Vec<u8> = sqlx::query_scalar("SELECT token_sha256 FROM previews WHERE study = 'shadows-demo'")
        .fetch_one(&fixture.state.storage().read)
        .await
        .unwrap();
    use sha2::Digest;
    assert_eq!(stored, sha2::Sha256::digest(token.as_bytes()).to_vec(), "stored as its SHA-256, not in clear");
    let other = fixture.admin(Method::POST, &format!("/api/admin/studies/{STUDY}/preview"), None).await.json();
    assert_ne!(other["url"].as_str().unwrap(), url, "a new token each time");

    let mut ids = Vec::new();
    for index in 0..5 {
        let (id, token) = fixture.join(&format!("PID-{index}"), "").await;
        fixture.answer(&id, &token, 7, false, index % 2 == 0).await;
        ids.push(id);
    }
    // The pilot: joined through the preview link (the flag the join sets from the token).
    let pilot = &ids[4];
    fixture.sql(&format!("UPDATE participants SET pilot = 1 WHERE id = '{pilot}'")).await;
    let csv = fixture.export_csv("").await;
    let text = csv.text();
    assert!(!Fixture::csv_participants(&text).contains(pilot));
    assert!(!text.contains(",true,false,"), "no pilot rows: {text}");
    assert_eq!(
        csv.headers.get("x-mrstudy-left-out").unwrap(),
        "Left out 1 pilot participant (joined through a preview link); add ?include_pilots=true or ?include_excluded=true to keep them."
    );
    let with_pilots = fixture.export_csv("?include_pilots=true").await.text();
    assert!(Fixture::csv_participants(&with_pilots).contains(pilot));
    assert!(with_pilots.lines().filter(|line| line.contains(pilot.as_str())).all(|line| line.contains(",true,false,")));
    let analysis = fixture.analysis().await;
    assert_eq!(analysis["participants"], 4);
    assert!(analysis["warnings"][0].as_str().unwrap().contains("1 pilot participant"));
    let included = fixture
        .admin(Method::GET, &format!("/api/admin/studies/{STUDY}/analysis?include_pilots=true"), None)
        .await
        .json();
    assert_eq!(included["participants"], 5);
    assert_eq!(entry(&fixture.participants().await, pilot)["pilot"], true);
    // Excluded as well as pilot: counted once, as a pilot.
    fixture
        .admin(Method::POST, &format!("/api/admin/participants/{pilot}/exclude"), Some(json!({"reason": "test run"})))
        .await;
    let json = fixture.admin(Method::GET, &format!("/api/admin/studies/{STUDY}/export.json"), None).await.json();
    assert_eq!(json["left_out"], json!({"pilots": 1, "excluded": 0}));
    let json = fixture
        .admin(Method::GET, &format!("/api/admin/studies/{STUDY}/export.json?include_pilots=true"), None)
        .await
        .json();
    assert_eq!(json["left_out"], json!({"pilots": 0, "excluded": 1}));
}

#[tokio::test]
async fn bad_participant_management_requests_are_refused_with_one_sentence() {
    let fixture = fixture().await;
    let (id, _) = fixture.join("PID-1", "").await;
    let exclude = format!("/api/admin/participants/{id}/exclude");
    for body in [json!({}), json!({"reason": ""}), json!({"reason": "   "})] {
        let answer = fixture.admin(Method::POST, &exclude, Some(body.clone())).await;
        assert_eq!(answer.status, StatusCode::UNPROCESSABLE_ENTITY, "{body}");
        assert!(answer.error().contains("reason"));
    }
    let long = fixture.admin(Method::POST, &exclude, Some(json!({"reason": "x".repeat(501)}))).await;
    assert_eq!(long.status, StatusCode::UNPROCESSABLE_ENTITY);
    long.error();
    let answer = fixture.admin(Method::POST, &exclude, None).await;
    assert_eq!(answer.status, StatusCode::UNSUPPORTED_MEDIA_TYPE, "no JSON body");
    answer.error();
    let unknown = "00000000000000000000000000000000";
    for (method, path, body) in [
        (Method::POST, format!("/api/admin/participants/{unknown}/exclude"), Some(json!({"reason": "r"}))),
        (Method::POST, format!("/api/admin/participants/{unknown}/include"), None),
        (Method::DELETE, format!("/api/admin/participants/{unknown}"), None),
        (Method::POST, "/api/admin/studies/nope/preview".to_string(), None),
        (Method::GET, "/api/admin/studies/nope/participants".to_string(), None),
    ] {
        let answer = fixture.admin(method, &path, body).await;
        assert_eq!(answer.status, StatusCode::NOT_FOUND, "{path}");
        answer.error();
    }
    let bad_query =
        fixture.admin(Method::GET, &format!("/api/admin/studies/{STUDY}/export.csv?include_pilots=yes"), None).await;
    assert_eq!(bad_query.status, StatusCode::BAD_REQUEST);
    assert!(bad_query.error().contains("include_pilots"));
    // Without the admin token, or by cookie without X-Requested-With: refused, nothing changed.
    let cookie = support::admin_session_cookie(&fixture.app, &fixture.admin_token).await;
    for (method, path) in [
        (Method::GET, format!("/api/admin/studies/{STUDY}/participants")),
        (Method::POST, exclude.clone()),
        (Method::POST, format!("/api/admin/participants/{id}/include")),
        (Method::DELETE, format!("/api/admin/participants/{id}")),
        (Method::POST, format!("/api/admin/studies/{STUDY}/preview")),
    ] {
        let answer = call(&fixture.app, method.clone(), &path, None, Some(json!({"reason": "r"}))).await;
        assert_eq!(answer.status, StatusCode::UNAUTHORIZED, "{path}");
        answer.error();
        if method != Method::GET {
            let request = Request::builder()
                .method(method)
                .uri(&path)
                .header(header::COOKIE, &cookie)
                .header(header::CONTENT_TYPE, "application/json")
                .body(Body::from(json!({"reason": "r"}).to_string()))
                .unwrap();
            let answer = send(&fixture.app, request).await;
            assert_eq!(answer.status, StatusCode::FORBIDDEN, "{path}");
        }
    }
    let list = fixture.participants().await;
    assert_eq!(list.len(), 1);
    assert_eq!(list[0]["excluded"], false);
    assert!(fixture.audit().await.is_empty());
}

/// `mrstudy export` (the library function behind it) on a task study: one sentence naming
/// `--format task`, no internal error.
#[test]
fn export_of_a_task_study_as_trials_says_to_use_format_task() {
    let work = tempfile::tempdir().unwrap();
    let data = work.path().join("data");
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let database = runtime.block_on(async {
        let Started { state, database, .. } = start(work.path(), &studies_dir(work.path(), "")).await;
        sqlx::query(
            "INSERT INTO studies (slug, title, kind, open, definition, file_sha256, first_loaded_at, loaded_at)
             VALUES ('lab', 'Cubes', 'task', 1, '{\"slug\": \"lab\"}', '00', '2026-11-23T00:00:00.000Z', '2026-11-23T00:00:00.000Z')",
        )
        .execute(&state.storage().read)
        .await
        .unwrap();
        database
    });
    drop(runtime);
    let database = flag(&database);
    for format in [mrstudy_server::serve::ExportFormat::Csv, mrstudy_server::serve::ExportFormat::Json] {
        let error = mrstudy_server::serve::export(&data, database, "lab", format, Default::default()).unwrap_err();
        assert!(matches!(error, mrstudy_server::serve::ExportCommandError::TaskStudy { ref slug } if slug == "lab"));
        let error = error.to_string();
        assert!(error.contains("task study") && error.contains("--format task"), "{error}");
        assert!(!error.contains('\n') && !error.contains("internal"), "{error}");
    }
    let output = mrstudy_server::serve::export(
        &data,
        database,
        STUDY,
        mrstudy_server::serve::ExportFormat::Csv,
        Default::default(),
    )
    .unwrap();
    assert!(output.text.starts_with("study,participant,"));
    assert_eq!(output.left_out, None, "nobody left out");
}

/// `mrstudy export` (the library function behind it): a pilot is left out with one line saying
/// so, and `--include-pilots` brings them back.
#[test]
fn export_leaves_out_pilots_unless_include_pilots() {
    let work = tempfile::tempdir().unwrap();
    let data = work.path().join("data");
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let (kept, pilot, database) = runtime.block_on(async {
        let Started { app, state, admin_token, database, .. } = start(work.path(), &studies_dir(work.path(), "")).await;
        let fixture = Fixture {
            app,
            state,
            admin_token,
            data: data.clone(),
            database: database.clone(),
            _work: tempfile::tempdir().unwrap(),
        };
        let (kept, kept_token) = fixture.join("PID-KEPT", "").await;
        fixture.answer(&kept, &kept_token, 3, false, false).await;
        let (pilot, pilot_token) = fixture.join("PID-PILOT", "").await;
        fixture.answer(&pilot, &pilot_token, 3, false, false).await;
        fixture.sql(&format!("UPDATE participants SET pilot = 1 WHERE id = '{pilot}'")).await;
        (kept, pilot, database)
    });
    drop(runtime);
    let database = flag(&database);
    let csv = mrstudy_server::serve::ExportFormat::Csv;
    let default = mrstudy_server::serve::export(&data, database, STUDY, csv, Default::default()).unwrap();
    assert_eq!(
        default.left_out.as_deref(),
        Some(
            "Left out 1 pilot participant (joined through a preview link); pass --include-pilots or --include-excluded to keep them."
        )
    );
    assert!(default.text.contains(&kept) && !default.text.contains(&pilot) && !default.text.contains("PID-PILOT"));
    let include = mrstudy_server::export::Include { pilots: true, excluded: false };
    let with_pilots = mrstudy_server::serve::export(&data, database, STUDY, csv, include).unwrap();
    assert_eq!(with_pilots.left_out, None);
    assert!(with_pilots.text.contains(&pilot) && with_pilots.text.contains("PID-PILOT"));
}

/// `mrstudy export --database`'s value for a test's database (`None`: the data directory's sqlite).
fn flag(database: &Database) -> Option<&str> {
    match database {
        Database::Postgres(url) => Some(url),
        Database::Sqlite(_) => None,
    }
}

/// Progress, funnel and completion rate count only real participants (issue 45): a pilot and an
/// excluded participant who both finished, and a pilot screened out, are shown beside them.
#[tokio::test]
async fn progress_funnel_and_completion_rate_count_only_real_participants() {
    let fixture = fixture().await;
    let (done, done_token) = fixture.join("PID-REAL-DONE", "").await;
    fixture.answer(&done, &done_token, 7, false, false).await;
    let (going, going_token) = fixture.join("PID-REAL-GOING", "").await;
    fixture.answer(&going, &going_token, 2, false, false).await;
    // a pilot through a preview link, finished
    let url = fixture.admin(Method::POST, &format!("/api/admin/studies/{STUDY}/preview"), None).await.json()["url"]
        .as_str()
        .unwrap()
        .to_string();
    let preview = url.split("preview=").nth(1).unwrap().to_string();
    let joined = call(
        &fixture.app,
        Method::POST,
        &format!("/api/studies/{STUDY}/participants"),
        None,
        Some(json!({
            "demographics": {"gender": "female", "age": 31, "cg_experience": "none", "vision": "normal"},
            "url_params": {}, "preview": preview,
        })),
    )
    .await
    .json();
    let (pilot, pilot_token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    fixture.answer(pilot, pilot_token, 7, false, false).await;
    // an excluded participant, finished
    let (gone, gone_token) = fixture.join("PID-EXCLUDED", "").await;
    fixture.answer(&gone, &gone_token, 7, false, false).await;
    let excluded = fixture
        .admin(Method::POST, &format!("/api/admin/participants/{gone}/exclude"), Some(json!({"reason": "asleep"})))
        .await;
    assert_eq!(excluded.status, StatusCode::OK, "{}", excluded.text());
    // a pilot's phone screened out by the preview link, and a real visitor screened out
    for (id, pilot) in [("a".repeat(32), 1), ("b".repeat(32), 0)] {
        fixture
            .sql(&format!(
                "INSERT INTO screen_outs (id, study, reason, client, url_params, pilot, created_at)
                 VALUES ('{id}', '{STUDY}', 'too small', '{{}}', '{{}}', {pilot}, '2026-01-01T00:00:00.000Z')"
            ))
            .await;
    }

    let stats = fixture.admin(Method::GET, &format!("/api/admin/studies/{STUDY}"), None).await.json();
    assert_eq!(stats["started"], 2, "{stats}");
    assert_eq!(stats["finished"], 1, "{stats}");
    assert_eq!(stats["completion_rate"], 0.5, "{stats}");
    assert_eq!(stats["reached"], json!([2, 2, 2, 1, 1, 1, 1, 1]), "{stats}");
    assert_eq!(stats["stopped_after"], json!([0, 0, 1, 0, 0, 0, 0, 0]), "{stats}");
    assert_eq!(stats["responses"], 9, "{stats}");
    assert_eq!(stats["screened_out"], 1, "{stats}");
    assert_eq!(
        [&stats["pilots"], &stats["pilots_finished"], &stats["excluded"], &stats["excluded_finished"]],
        [&json!(1), &json!(1), &json!(1), &json!(1)],
        "{stats}"
    );
    let list = fixture.admin(Method::GET, "/api/admin/studies", None).await.json();
    assert_eq!((&list[0]["started"], &list[0]["finished"]), (&json!(2), &json!(1)), "{list}");

    // The pages say the same, with the pilots and the excluded beside.
    let html = fixture.admin(Method::GET, &format!("/admin/studies/{STUDY}"), None).await.text();
    assert!(html.contains(r#"<dd id="stat-started">2</dd>"#), "{html}");
    assert!(html.contains(r#"<dd id="stat-finished">1</dd>"#), "{html}");
    assert!(html.contains(r#"<dd id="stat-completion">50.0 %</dd>"#), "{html}");
    assert!(html.contains(r#"<dd id="stat-left-out">1 pilot (1 finished) · 1 excluded (1 finished)</dd>"#), "{html}");
    assert!(html.contains("visitors: 3, of whom 1 were screened out"), "{html}");
    let overview = fixture.admin(Method::GET, "/admin", None).await.text();
    assert!(overview.contains("<td>2</td>\n<td>1</td>\n<td>50 %</td>"), "{overview}");
}

/// The screen check's answer for a visitor with `PROLIFIC_PID = pid` on a 1280×800 screen.
async fn screen(fixture: &Fixture, pid: &str, preview: Option<&str>) -> Value {
    let body = json!({
        "client": {"viewport": [1280, 800], "devicePixelRatio": 1, "userAgent": "test"},
        "url_params": {"PROLIFIC_PID": pid}, "preview": preview,
    });
    let answer = call(&fixture.app, Method::POST, &format!("/api/studies/{STUDY}/screen"), None, Some(body)).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    answer.json()
}

/// With one run per external id, a participant who finished and comes back (another browser,
/// the same PROLIFIC_PID) is told so by the screen check, before anything is asked: the page
/// shows the completion page (issue 45). An unfinished run, another id and a preview are asked.
#[tokio::test]
async fn the_screen_check_sends_a_returning_finisher_to_the_completion_page() {
    let fixture = fixture_with("unique_external_id = true").await;
    let (done, done_token) = fixture.join("PID-BACK", "").await;
    fixture.answer(&done, &done_token, 7, false, false).await;
    let (half, half_token) = fixture.join("PID-HALF", "").await;
    fixture.answer(&half, &half_token, 3, false, false).await;
    let back = screen(&fixture, "PID-BACK", None).await;
    assert_eq!(back, json!({"meets": true, "completed": {"done": true, "completion_code": "DEMO-7F3A"}}));
    for pid in ["PID-HALF", "PID-NEW", ""] {
        assert_eq!(screen(&fixture, pid, None).await, json!({"meets": true}), "{pid}");
    }
    let url = fixture.admin(Method::POST, &format!("/api/admin/studies/{STUDY}/preview"), None).await.json()["url"]
        .as_str()
        .unwrap()
        .to_string();
    let preview = url.split("preview=").nth(1).unwrap().to_string();
    assert_eq!(screen(&fixture, "PID-BACK", Some(&preview)).await, json!({"meets": true}), "a preview is a new pilot");
}

/// Issue 46: a deletion's rewrite of the database (`VACUUM`, then a truncating checkpoint that
/// copies the new pages over the old) ran beside the writer, on another connection, and took
/// sqlite's write lock while participants' group commits were mid-transaction; those could not
/// wait for it ("database is locked") and were rolled back, so joins and answers got 500. Here
/// 8 participants join and answer without pause on a database of some megabytes while the
/// researcher deletes participants one after another: every join and answer must succeed.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn deletions_under_load_never_fail_a_participants_join_or_answer() {
    let fixture = fixture().await;
    if fixture.database.backend() == Backend::Sqlite {
        // megabytes for the rewrite and the checkpoint to copy, as a real study's database has
        fixture.sql("CREATE TABLE padding (bytes BLOB)").await;
        fixture.sql("WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < 2000) INSERT INTO padding SELECT randomblob(4000) FROM n").await;
    }
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut writers = Vec::new();
    for writer in 0..8 {
        let app = fixture.app.clone();
        let stop = stop.clone();
        writers.push(tokio::spawn(async move {
            let (mut done, mut failures) = (0usize, Vec::new());
            let mut round = 0;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                round += 1;
                let joined = join_quietly(&app, &format!("PID-LOAD-{writer}-{round}")).await;
                let Ok((id, token)) = joined else {
                    failures.push(joined.unwrap_err());
                    continue;
                };
                done += 1;
                for _ in 0..7 {
                    let next =
                        call(&app, Method::GET, &format!("/api/participants/{id}/next"), Some(&token), None).await;
                    let Some(trial) = next.json()["trial"].as_i64() else { break };
                    let answer = call(
                        &app,
                        Method::POST,
                        &format!("/api/participants/{id}/responses"),
                        Some(&token),
                        Some(json!({"trial": trial, "chosen": "left", "rt_ms": 900.0, "client": {}})),
                    )
                    .await;
                    if answer.status == StatusCode::CREATED {
                        done += 1;
                    } else {
                        failures.push(format!("answer: {} {}", answer.status, answer.text()));
                    }
                }
            }
            (done, failures)
        }));
    }
    let (mut deleted, mut deletion_ms) = (0, Vec::new());
    for round in 0..12 {
        let (id, token) = fixture.join(&format!("PID-DELETE-{round}"), "please delete me").await;
        fixture.answer(&id, &token, 2, false, false).await;
        let started = std::time::Instant::now();
        let answer = fixture.admin(Method::DELETE, &format!("/api/admin/participants/{id}"), None).await;
        assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        deletion_ms.push(started.elapsed().as_secs_f64() * 1000.0);
        deleted += 1;
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let (mut done, mut failures) = (0, Vec::new());
    for writer in writers {
        let (writer_done, writer_failures) = writer.await.unwrap();
        done += writer_done;
        failures.extend(writer_failures);
    }
    assert_eq!(deleted, 12);
    let slowest = deletion_ms.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "{done} joins and answers by 8 writers, {} failed; 12 deletions, slowest {slowest:.0} ms",
        failures.len()
    );
    assert!(done > 50, "the writers made progress: {done} joins and answers");
    assert!(
        failures.is_empty(),
        "{} of {} joins and answers failed: {:?}",
        failures.len(),
        done + failures.len(),
        &failures[..failures.len().min(5)]
    );
}

/// A join as [`Fixture::join`] makes it, with the failure as text instead of a panic.
async fn join_quietly(app: &Router, pid: &str) -> Result<(String, String), String> {
    let answer = call(
        app,
        Method::POST,
        &format!("/api/studies/{STUDY}/participants"),
        None,
        Some(json!({
            "demographics": demographics(),
            "client": {"viewport": [1280, 800], "devicePixelRatio": 2, "userAgent": "test"},
            "url_params": {"PROLIFIC_PID": pid},
        })),
    )
    .await;
    if answer.status != StatusCode::CREATED {
        return Err(format!("join: {} {}", answer.status, answer.text()));
    }
    let json = answer.json();
    Ok((json["participant"].as_str().unwrap().to_string(), json["token"].as_str().unwrap().to_string()))
}

/// Issue 46: on PostgreSQL a deleted participant stayed in the tables' statistics (`pg_stats`
/// keeps copies of column values: most common values, histogram bounds) until the next
/// analyze; the deletion now analyzes the tables it rewrote. (sqlite keeps no such copies.)
#[tokio::test]
async fn on_postgres_a_deleted_participant_leaves_nothing_in_the_table_statistics() {
    let fixture = fixture().await;
    if fixture.database.backend() != Backend::Postgres {
        return;
    }
    let (keep, _) = fixture.join("PPID-KEEP-STATS-1", "a comment that stays").await;
    let (gone, gone_token) = fixture.join("PPID-STATS-GONE-4711", "my own remark 4711zz").await;
    fixture.answer(&gone, &gone_token, 2, false, false).await;
    fixture.sql("ANALYZE").await;
    let statistics = || async {
        sqlx::query_scalar::<_, String>(
            "SELECT concat_ws(' ', tablename, attname, most_common_vals::text, histogram_bounds::text)
             FROM pg_stats WHERE schemaname = current_schema()",
        )
        .fetch_all(&fixture.state.storage().read)
        .await
        .unwrap()
        .join("\n")
    };
    let before = statistics().await;
    for needle in ["PPID-STATS-GONE-4711", "4711zz"] {
        assert!(before.contains(needle), "\"{needle}\" is in the statistics before: {before}");
    }
    let answer = fixture.admin(Method::DELETE, &format!("/api/admin/participants/{gone}"), None).await;
    assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
    let after = statistics().await;
    for needle in ["PPID-STATS-GONE-4711", "4711zz", gone.as_str()] {
        assert!(!after.contains(needle), "\"{needle}\" is still in pg_stats after the deletion: {after}");
    }
    // (the kept participant's 7 trials make their id the trials' most common value)
    assert!(after.contains(keep.as_str()), "the tables were analyzed again: {after}");
}
