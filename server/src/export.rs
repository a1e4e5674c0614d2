//! Export: the trials CSV of docs/design.md and a fuller JSON, read from the database alone (the
//! study's definition is stored there), so `mrstudy export` works without the study files.
//!
//! Trials CSV: one row per answered paired-comparison trial (a judgment between two of the
//! study's conditions), participants in the order they joined, trials in schedule order.
//! Columns: `study,participant,trial,left,right,chosen,scene_left,scene_right,rt_ms,shown_at,
//! answered_at,catch_answered,catch_failed,viewport,device_pixel_ratio,display_css,display_device,
//! completed,status,completion_code,pilot,excluded,too_fast`, then one column per external id
//! (header = the parameter's name; see [`url_param_columns`]), then one column per demographic
//! field. `viewport` (`WxH`) and `device_pixel_ratio` are those the browser sent with the
//! response, else when the participant joined; `display_css` and `display_device` (`WxH`) the
//! size one image of the pair was shown at, in CSS and in device pixels, as the page measured it
//! (empty when the page did not say); `completed` is 1 when the participant finished the study;
//! `status` is the participant's (`completed`, `started`, `abandoned`: unfinished and no
//! activity for the study's `abandon_after_minutes`); `pilot`, `excluded` and the per-trial
//! `too_fast` are `true`/`false`. Text cells never start with `=`, `+`, `-`, `@`, TAB or CR: such
//! a cell gets a leading `'` (spreadsheet formula injection); numeric cells are untouched.
//!
//! Pilot participants (joined through a preview link) and participants the researcher excluded
//! are left out unless [`Include`] asks for them; [`LeftOut`] says how many were left out, for
//! the one line `mrstudy export` prints and the analysis's warning.
//!
//! Catch trials are not judgments between conditions, so they are not rows of the trials CSV
//! (whose `left`/`right`/`chosen` hold condition names only, as the analysis expects); each row
//! flags its participant instead: `catch_answered` and `catch_failed` count the participant's
//! answered and failed catch trials, so screening is one filter. The JSON export holds every
//! trial, catch trials included, with `catch_expected`, `chosen_by` (which posterior state chose
//! an actively chosen trial, `null` for planned ones) and the response.

use serde::Deserialize;
use serde_json::{Map, Value, json};
use sqlx::Row;

use crate::participant::model::ParticipantRecord;
use crate::storage::Pool;

use crate::study::Study;
use crate::study::rating::CATCH_TOLERANCE;

/// Export failures.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    #[error("there is no study \"{0}\" in the database")]
    UnknownStudy(String),
    #[error("database error: {0}")]
    Database(#[from] sqlx::Error),
    #[error("the stored definition of study \"{slug}\" cannot be read: {message}")]
    Definition { slug: String, message: String },
    #[error("{0}")]
    Internal(String),
}

/// The study as stored with its participants (the one schema of [`Study`]; a task study's
/// definition does not read as one and says so).
pub async fn definition(pool: &Pool, slug: &str) -> Result<Study, ExportError> {
    let text: Option<String> =
        sqlx::query_scalar("SELECT definition FROM studies WHERE slug = $1").bind(slug).fetch_optional(pool).await?;
    let text = text.ok_or_else(|| ExportError::UnknownStudy(slug.to_string()))?;
    serde_json::from_str(&text)
        .map_err(|error| ExportError::Definition { slug: slug.to_string(), message: error.to_string() })
}

fn value_text(value: Option<&Value>) -> String {
    match value {
        None | Some(Value::Null) => String::new(),
        Some(Value::String(text)) => text.clone(),
        Some(other) => other.to_string(),
    }
}

/// Which participants an export or analysis keeps besides the default ones.
/// Also `mrstudy export`'s flags (the binary holds their clap definitions).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
pub struct Include {
    /// Keep pilot participants (joined through an admin preview link); left out by default.
    #[serde(default, rename = "include_pilots")]
    pub pilots: bool,
    /// Keep participants the researcher excluded; left out by default.
    #[serde(default, rename = "include_excluded")]
    pub excluded: bool,
}

/// How many participants an export left out, and why. A participant both pilot and excluded
/// counts once, as a pilot when pilots are left out.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LeftOut {
    pub pilots: usize,
    pub excluded: usize,
}

impl LeftOut {
    pub fn total(&self) -> usize {
        self.pilots + self.excluded
    }

    /// One sentence naming how many were left out and why, ending in `hint` (which says how to
    /// keep them); `None` when nobody was left out.
    pub fn sentence(&self, hint: &str) -> Option<String> {
        self.clause(hint).map(|clause| format!("L{}.", &clause[1..]))
    }

    /// [`LeftOut::sentence`] as a clause to end another sentence with: lower case, no full stop.
    pub fn clause(&self, hint: &str) -> Option<String> {
        if self.total() == 0 {
            return None;
        }
        let count = |n: usize, what: &str| format!("{n} {what} participant{}", if n == 1 { "" } else { "s" });
        let mut parts = Vec::new();
        if self.pilots > 0 {
            parts.push(format!("{} (joined through a preview link)", count(self.pilots, "pilot")));
        }
        if self.excluded > 0 {
            parts.push(format!("{} (excluded by the researcher)", count(self.excluded, "excluded")));
        }
        Some(format!("left out {}; {hint}", parts.join(" and ")))
    }

    fn count(&mut self, record: &ParticipantRecord, include: Include) -> bool {
        if record.pilot && !include.pilots {
            self.pilots += 1;
            false
        } else if record.excluded && !include.excluded {
            self.excluded += 1;
            false
        } else {
            true
        }
    }
}

/// What an export wrote and whom it left out.
#[derive(Debug, Clone)]
pub struct Export<T> {
    pub content: T,
    pub left_out: LeftOut,
}

/// Every participant of a study in joining order, with status, external ids and flags.
pub async fn participant_records(
    pool: &Pool,
    slug: &str,
    definition: &Study,
) -> Result<Vec<ParticipantRecord>, ExportError> {
    let rows = sqlx::query(sqlx::AssertSqlSafe(format!(
        "SELECT *, (julianday('now') - julianday(last_activity)) * 1440.0 AS idle_minutes FROM (
             SELECT p.id, p.ordinal, p.trials, p.answered, p.completion_code, p.completed_at, p.created_at,
                    p.pilot, p.excluded, p.exclusion_reason, p.excluded_at, p.url_params,
                    (SELECT MAX(moment) FROM (
                        SELECT p.created_at AS moment
                        UNION ALL SELECT MAX(t.shown_at) FROM trials t WHERE t.participant = p.id
                        UNION ALL SELECT MAX(r.answered_at) FROM responses r WHERE r.participant = p.id) AS moments)
                        AS last_activity,
                    (SELECT COUNT(*) FROM responses r WHERE r.participant = p.id AND r.too_fast = 1) AS too_fast,
                    (SELECT COUNT(*) FROM responses r JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
                     WHERE r.participant = p.id AND (t.catch_expected IS NOT NULL OR t.catch_rating IS NOT NULL))
                        AS catch_answered,
                    (SELECT COUNT(*) FROM responses r JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
                     WHERE r.participant = p.id AND (r.chosen != t.catch_expected
                         OR ABS(r.rating - t.catch_rating) > {CATCH_TOLERANCE}))
                        AS catch_failed
             FROM participants p WHERE p.study = $1) AS activity
         ORDER BY ordinal"
    )))
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let abandon_after = f64::from(definition.participation.abandon_after_minutes);
    let mut records = Vec::with_capacity(rows.len());
    for row in rows {
        let completed_at: Option<String> = row.try_get("completed_at")?;
        let idle_minutes: Option<f64> = row.try_get("idle_minutes")?;
        let status = if completed_at.is_some() {
            "completed"
        } else if idle_minutes.is_some_and(|idle| idle >= abandon_after) {
            "abandoned"
        } else {
            "started"
        };
        records.push(ParticipantRecord {
            participant: row.try_get("id")?,
            ordinal: row.try_get("ordinal")?,
            status,
            trials: row.try_get("trials")?,
            answered: row.try_get("answered")?,
            completion_code: row.try_get("completion_code")?,
            pilot: row.try_get::<i64, _>("pilot")? == 1,
            excluded: row.try_get::<i64, _>("excluded")? == 1,
            exclusion_reason: row.try_get("exclusion_reason")?,
            excluded_at: row.try_get("excluded_at")?,
            external_ids: external_ids(definition, &row.try_get::<String, _>("url_params")?),
            joined_at: row.try_get("created_at")?,
            completed_at,
            last_activity_at: row.try_get("last_activity")?,
            too_fast: row.try_get("too_fast")?,
            catch_answered: row.try_get("catch_answered")?,
            catch_failed: row.try_get("catch_failed")?,
        });
    }
    Ok(records)
}

/// The study's external ids out of a stored `url_params` JSON object, in the study's order.
pub fn external_ids(definition: &Study, url_params: &str) -> Map<String, Value> {
    let stored: Map<String, Value> = serde_json::from_str(url_params).unwrap_or_default();
    definition
        .url_params
        .iter()
        .filter_map(|name| stored.get(name).map(|value| (name.clone(), value.clone())))
        .collect()
}

/// A text cell made safe for spreadsheets: one starting with `=`, `+`, `-`, `@`, TAB or CR
/// (a formula to Excel, LibreOffice, Google Sheets) gets a leading `'`, and so does one where
/// such a character follows leading white space or control characters (space, LF, NBSP, NUL,
/// VT, FF, a byte-order mark), which spreadsheets skip before reading a formula.
pub fn text_cell(text: &str) -> String {
    const FORMULA: [char; 6] = ['=', '+', '-', '@', '\t', '\r'];
    let skipped = text.trim_start_matches(|c: char| c.is_whitespace() || c.is_control() || c == '\u{feff}');
    if text.starts_with(FORMULA) || skipped.starts_with(FORMULA) { format!("'{text}") } else { text.to_string() }
}

/// A JSON value as a CSV cell: numbers and booleans as they are, text neutralised.
fn value_cell(value: Option<&Value>) -> String {
    match value {
        Some(Value::String(text)) => text_cell(text),
        Some(Value::Number(_)) | Some(Value::Bool(_)) | None | Some(Value::Null) => value_text(value),
        Some(other) => text_cell(&other.to_string()),
    }
}

fn true_false(value: bool) -> String {
    if value { "true" } else { "false" }.to_string()
}

const TRIAL_ROWS: &str = "
    SELECT p.id AS participant, p.demographics, p.completed_at, p.client AS participant_client, t.trial, t.left_condition, t.right_condition,
           t.left_scene, t.right_scene, t.left_stimulus, t.right_stimulus, t.catch_expected, t.shown_at, t.chosen_by,
           r.chosen, r.rt_ms, r.answered_at, r.client, r.too_fast, r.served_ms, r.display_css, r.display_device,
           r.rating, t.catch_rating
    FROM participants p
    JOIN trials t ON t.participant = p.id
    LEFT JOIN responses r ON r.participant = t.participant AND r.trial = t.trial
    WHERE p.study = $1";

/// The trials CSV of a study, leaving out pilot and excluded participants unless `include`
/// keeps them.
pub async fn trials_csv(pool: &Pool, slug: &str, include: Include) -> Result<Export<String>, ExportError> {
    let definition = definition(pool, slug).await?;
    let mut left_out = LeftOut::default();
    let mut kept: std::collections::HashMap<String, ParticipantRecord> = Default::default();
    for record in participant_records(pool, slug, &definition).await? {
        if left_out.count(&record, include) {
            kept.insert(record.participant.clone(), record);
        }
    }
    // a rating study's rows are its ratings, catch trials included (flagged `catch`)
    let answered = if definition.rating.is_some() {
        "r.rating IS NOT NULL"
    } else {
        "r.chosen IS NOT NULL AND t.catch_expected IS NULL"
    };
    let rows = sqlx::query(sqlx::AssertSqlSafe(format!("{TRIAL_ROWS} AND {answered} ORDER BY p.ordinal, t.trial")))
        .bind(slug)
        .fetch_all(pool)
        .await?;
    // Writing the rows is the export's long work: on a blocking thread, so the async workers
    // that serve participants stay free.
    let content = tokio::task::spawn_blocking(move || write_trial_rows(&definition, &kept, rows))
        .await
        .map_err(|error| ExportError::Internal(format!("the export's writer stopped: {error}")))??;
    Ok(Export { content, left_out })
}

/// The trials CSV's text from the study's definition, the participants kept and the rows.
fn write_trial_rows(
    definition: &Study,
    kept: &std::collections::HashMap<String, ParticipantRecord>,
    rows: Vec<sqlx::any::AnyRow>,
) -> Result<String, ExportError> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = crate::study::TRIALS_CSV_COLUMNS.iter().map(|column| column.to_string()).collect();
    let url_columns = url_param_columns(definition, kept.values());
    if definition.threshold.is_some() {
        header.extend(crate::study::threshold::CSV_COLUMNS.iter().map(|column| column.to_string()));
    }
    if definition.rating.is_some() {
        header.extend(crate::study::rating::CSV_COLUMNS.iter().map(|column| column.to_string()));
    }
    header.extend(url_columns.iter().cloned());
    header.extend(definition.demographics.iter().map(|field| field.name.clone()));
    writer.write_record(&header).expect("writing to memory");
    for row in rows {
        let participant: String = row.try_get("participant")?;
        let Some(record) = kept.get(&participant) else { continue };
        let chosen_side: Option<String> = row.try_get("chosen")?;
        let left: String = row.try_get("left_condition")?;
        let right: String = row.try_get("right_condition")?;
        // a condition's name, or `tie` for "not sure" (allow_tie; no condition is named so);
        // empty for a rating
        let chosen = match chosen_side.as_deref() {
            Some("left") => left.clone(),
            Some("right") => right.clone(),
            Some(_) => "tie".to_string(),
            None => String::new(),
        };
        let demographics: Map<String, Value> =
            serde_json::from_str(&row.try_get::<String, _>("demographics")?).unwrap_or_default();
        // The client details sent with the response, else those sent when the participant joined.
        let mut client: Map<String, Value> =
            serde_json::from_str(&row.try_get::<String, _>("participant_client")?).unwrap_or_default();
        let response_client: Map<String, Value> =
            serde_json::from_str(&row.try_get::<String, _>("client")?).unwrap_or_default();
        client.extend(response_client);
        let viewport = match client.get("viewport") {
            Some(Value::Array(size)) if size.len() == 2 => {
                text_cell(&format!("{}x{}", value_text(Some(&size[0])), value_text(Some(&size[1]))))
            }
            _ => String::new(),
        };
        let mut record_cells = vec![
            text_cell(&definition.slug),
            text_cell(&participant),
            row.try_get::<i64, _>("trial")?.to_string(),
            text_cell(&left),
            text_cell(&right),
            text_cell(&chosen),
            text_cell(&row.try_get::<String, _>("left_scene")?),
            text_cell(&row.try_get::<String, _>("right_scene")?),
            crate::study::format_number(row.try_get::<f64, _>("rt_ms")?),
            row.try_get::<Option<String>, _>("shown_at")?.unwrap_or_default(),
            row.try_get("answered_at")?,
            record.catch_answered.to_string(),
            record.catch_failed.to_string(),
            viewport,
            value_cell(client.get("devicePixelRatio")),
            text_cell(&row.try_get::<Option<String>, _>("display_css")?.unwrap_or_default()),
            text_cell(&row.try_get::<Option<String>, _>("display_device")?.unwrap_or_default()),
            if row.try_get::<Option<String>, _>("completed_at")?.is_some() { "1" } else { "0" }.to_string(),
            record.status.to_string(),
            text_cell(&record.completion_code),
            true_false(record.pilot),
            true_false(record.excluded),
            true_false(row.try_get::<Option<i64>, _>("too_fast")?.unwrap_or(0) == 1),
        ];
        if let Some(design) = &definition.threshold {
            let scene: String = row.try_get("left_scene")?;
            record_cells.extend(crate::threshold::csv_cells(design, &left, &right, &chosen, &scene));
        }
        if let Some(design) = &definition.rating {
            let scene: String = row.try_get("left_scene")?;
            let rating: Option<i64> = row.try_get("rating")?;
            let catch_rating: Option<i64> = row.try_get("catch_rating")?;
            let cells = crate::rating::csv_cells(design, &scene, &left, rating.unwrap_or_default(), catch_rating);
            record_cells.extend(cells.iter().map(|cell| text_cell(cell)));
        }
        for name in &url_columns {
            record_cells.push(value_cell(record.external_ids.get(name)));
        }
        for field in &definition.demographics {
            record_cells.push(value_cell(demographics.get(&field.name)));
        }
        writer.write_record(&record_cells).expect("writing to memory");
    }
    Ok(String::from_utf8(writer.into_inner().expect("writing to memory")).expect("UTF-8"))
}

/// The external-id columns of the trials CSV, in the study's order: every `url_params` entry the
/// study file declares (empty cells where a participant arrived without it), and for a study that
/// declares none only those of the default platform ids that at least one exported participant
/// arrived with (a non-empty value), so a study that never asked for MTurk's `workerId` gets no empty column for it.
pub fn url_param_columns<'a>(
    definition: &Study,
    exported: impl IntoIterator<Item = &'a ParticipantRecord> + Clone,
) -> Vec<String> {
    definition
        .url_params
        .iter()
        .filter(|name| {
            definition.url_params_declared
                || exported.clone().into_iter().any(|record| {
                    record.external_ids.get(name.as_str()).is_some_and(|value| value.as_str() != Some(""))
                })
        })
        .cloned()
        .collect()
}

/// The JSON export: the study, and per participant their stored data, status, flags and whole
/// schedule, with the response of each answered trial; pilot and excluded participants only
/// when `include` keeps them.
pub async fn study_json(pool: &Pool, slug: &str, include: Include) -> Result<Export<Value>, ExportError> {
    let definition_text: Option<String> =
        sqlx::query_scalar("SELECT definition FROM studies WHERE slug = $1").bind(slug).fetch_optional(pool).await?;
    let definition_text = definition_text.ok_or_else(|| ExportError::UnknownStudy(slug.to_string()))?;
    let definition_json: Value = serde_json::from_str(&definition_text)
        .map_err(|error| ExportError::Definition { slug: slug.to_string(), message: error.to_string() })?;
    let stored = definition(pool, slug).await?;
    let mut left_out = LeftOut::default();
    let mut kept: std::collections::HashMap<String, ParticipantRecord> = Default::default();
    for record in participant_records(pool, slug, &stored).await? {
        if left_out.count(&record, include) {
            kept.insert(record.participant.clone(), record);
        }
    }
    let participants = sqlx::query(
        "SELECT id, ordinal, seed, schedule_version, file_sha256, demographics, client, url_params, trials,
                answered, completion_code, created_at, completed_at
         FROM participants WHERE study = $1 ORDER BY ordinal",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let trials = sqlx::query(sqlx::AssertSqlSafe(format!("{TRIAL_ROWS} ORDER BY p.ordinal, t.trial")))
        .bind(slug)
        .fetch_all(pool)
        .await?;
    let mut by_participant: std::collections::HashMap<String, Vec<Value>> = Default::default();
    for row in trials {
        let participant: String = row.try_get("participant")?;
        if !kept.contains_key(&participant) {
            continue;
        }
        let chosen: Option<String> = row.try_get("chosen")?;
        let rating: Option<i64> = row.try_get("rating")?;
        let left: String = row.try_get("left_condition")?;
        let right: String = row.try_get("right_condition")?;
        let answered = chosen.is_some() || rating.is_some();
        let response = match answered {
            true => json!({
                "chosen": chosen,
                "chosen_condition": match chosen.as_deref() {
                    Some("left") => Some(&left),
                    Some("right") => Some(&right),
                    _ => None,
                },
                "rating": rating,
                "rt_ms": row.try_get::<f64, _>("rt_ms")?,
                "answered_at": row.try_get::<String, _>("answered_at")?,
                "too_fast": row.try_get::<Option<i64>, _>("too_fast")?.unwrap_or(0) == 1,
                "served_ms": row.try_get::<Option<f64>, _>("served_ms")?.filter(|ms| ms.is_finite()),
                "display_css": row.try_get::<Option<String>, _>("display_css")?,
                "display_device": row.try_get::<Option<String>, _>("display_device")?,
                "client": serde_json::from_str::<Value>(&row.try_get::<String, _>("client")?).unwrap_or(Value::Null),
            }),
            false => Value::Null,
        };
        let mut response = response;
        if rating.is_none()
            && let Some(fields) = response.as_object_mut()
        {
            fields.remove("rating"); // a paired comparison's response as before
        }
        by_participant.entry(participant).or_default().push(json!({
            "trial": row.try_get::<i64, _>("trial")?,
            "left": left,
            "right": right,
            "scene_left": row.try_get::<String, _>("left_scene")?,
            "scene_right": row.try_get::<String, _>("right_scene")?,
            "left_stimulus": row.try_get::<String, _>("left_stimulus")?,
            "right_stimulus": row.try_get::<String, _>("right_stimulus")?,
            "catch_expected": row.try_get::<Option<String>, _>("catch_expected")?,
            "catch_rating": row.try_get::<Option<i64>, _>("catch_rating")?,
            "shown_at": row.try_get::<Option<String>, _>("shown_at")?,
            "chosen_by": row.try_get::<Option<String>, _>("chosen_by")?,
            "response": response,
        }));
    }
    let mut out = Vec::new();
    for row in participants {
        let id: String = row.try_get("id")?;
        let Some(record) = kept.get(&id) else { continue };
        let parse = |column: &str| -> Result<Value, sqlx::Error> {
            Ok(serde_json::from_str(&row.try_get::<String, _>(column)?).unwrap_or(Value::Null))
        };
        out.push(json!({
            "participant": id,
            "ordinal": row.try_get::<i64, _>("ordinal")?,
            "status": record.status,
            "pilot": record.pilot,
            "excluded": record.excluded,
            "exclusion_reason": record.exclusion_reason,
            "excluded_at": record.excluded_at,
            "external_ids": record.external_ids,
            "too_fast": record.too_fast,
            "catch_answered": record.catch_answered,
            "catch_failed": record.catch_failed,
            "seed": (row.try_get::<i64, _>("seed")? as u64).to_string(),
            "schedule_version": row.try_get::<i64, _>("schedule_version")?,
            "study_file_sha256": row.try_get::<String, _>("file_sha256")?,
            "demographics": parse("demographics")?,
            "client": parse("client")?,
            "url_params": parse("url_params")?,
            "trials": row.try_get::<i64, _>("trials")?,
            "answered": row.try_get::<i64, _>("answered")?,
            "completion_code": row.try_get::<String, _>("completion_code")?,
            "created_at": row.try_get::<String, _>("created_at")?,
            "completed_at": row.try_get::<Option<String>, _>("completed_at")?,
            "last_activity_at": record.last_activity_at,
            "schedule": by_participant.remove(&id).unwrap_or_default(),
        }));
    }
    Ok(Export { content: json!({ "study": definition_json, "participants": out, "left_out": left_out }), left_out })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_cells_that_a_spreadsheet_would_run_get_a_leading_quote() {
        for text in ["=HYPERLINK(\"x\")", "+1", "-2+3", "@SUM(A1)", "\tx", "\rx"] {
            assert_eq!(text_cell(text), format!("'{text}"));
        }
        for text in ["LQ", "SH+CA", "a=b", "", "PPID-1"] {
            assert_eq!(text_cell(text), text);
        }
        // Numbers stay numbers, even negative ones; text inside JSON is neutralised.
        assert_eq!(value_cell(Some(&json!(-3))), "-3");
        assert_eq!(value_cell(Some(&json!(2.5))), "2.5");
        assert_eq!(value_cell(Some(&json!("-3"))), "'-3");
        assert_eq!(value_cell(Some(&json!("=cmd|' /C calc'!A0"))), "'=cmd|' /C calc'!A0");
        assert_eq!(value_cell(None), "");
    }

    #[test]
    fn left_out_says_how_many_and_why_in_one_sentence() {
        assert_eq!(LeftOut::default().sentence("hint"), None);
        assert_eq!(
            LeftOut { pilots: 2, excluded: 1 }.sentence("pass --include-pilots to keep them").unwrap(),
            "Left out 2 pilot participants (joined through a preview link) and 1 excluded participant \
             (excluded by the researcher); pass --include-pilots to keep them."
        );
        assert_eq!(
            LeftOut { pilots: 0, excluded: 3 }.clause("h").unwrap(),
            "left out 3 excluded participants (excluded by the researcher); h"
        );
    }
}
