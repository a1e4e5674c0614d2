//! Export: the trials CSV of DESIGN.md and a fuller JSON, read from the database alone (the
//! study's definition is stored there), so `mrstudy export` works without the study files.
//!
//! Trials CSV: one row per answered paired-comparison trial (a judgment between two of the
//! study's conditions), participants in the order they joined, trials in schedule order.
//! Columns: `study,participant,trial,left,right,chosen,scene_left,scene_right,rt_ms,shown_at,
//! answered_at,catch_answered,catch_failed,viewport,device_pixel_ratio,completed`, then one
//! column per demographic field. `viewport` (`WxH`) and `device_pixel_ratio` are those the
//! browser sent with the response, else when the participant joined; `completed` is 1 when the
//! participant finished the study.
//!
//! Catch trials are not judgments between conditions, so they are not rows of the trials CSV
//! (whose `left`/`right`/`chosen` hold condition names only, as the analysis expects); each row
//! flags its participant instead: `catch_answered` and `catch_failed` count the participant's
//! answered and failed catch trials, so screening is one filter. The JSON export holds every
//! trial, catch trials included, with `catch_expected` and the response.

use serde::Deserialize;
use serde_json::{Map, Value, json};
use sqlx::{Row, SqlitePool};

/// The parts of a stored study definition the export needs.
#[derive(Debug, Deserialize)]
pub struct StoredDefinition {
    pub slug: String,
    pub title: String,
    pub factors: Vec<StoredName>,
    pub conditions: Vec<StoredCondition>,
    pub demographics: Vec<StoredName>,
}

#[derive(Debug, Deserialize)]
pub struct StoredName {
    pub name: String,
}

#[derive(Debug, Deserialize)]
pub struct StoredCondition {
    pub name: String,
    pub levels: Vec<f64>,
}

impl StoredDefinition {
    /// The conditions CSV of DESIGN.md.
    pub fn conditions_csv(&self) -> String {
        crate::study::conditions_csv(
            self.factors.iter().map(|factor| factor.name.as_str()),
            self.conditions.iter().map(|condition| (condition.name.as_str(), condition.levels.as_slice())),
        )
    }
}

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
}

pub async fn definition(pool: &SqlitePool, slug: &str) -> Result<StoredDefinition, ExportError> {
    let text: Option<String> = sqlx::query_scalar("SELECT definition FROM studies WHERE slug = ?")
        .bind(slug)
        .fetch_optional(pool)
        .await?;
    let text = text.ok_or_else(|| ExportError::UnknownStudy(slug.to_string()))?;
    serde_json::from_str(&text).map_err(|error| ExportError::Definition {
        slug: slug.to_string(),
        message: error.to_string(),
    })
}

fn value_text(value: Option<&Value>) -> String {
    match value {
        None | Some(Value::Null) => String::new(),
        Some(Value::String(text)) => text.clone(),
        Some(other) => other.to_string(),
    }
}

const TRIAL_ROWS: &str = "
    SELECT p.id AS participant, p.demographics, p.completed_at, p.client AS participant_client, t.trial, t.left_condition, t.right_condition,
           t.left_scene, t.right_scene, t.left_stimulus, t.right_stimulus, t.catch_expected, t.shown_at,
           r.chosen, r.rt_ms, r.answered_at, r.client
    FROM participants p
    JOIN trials t ON t.participant = p.id
    LEFT JOIN responses r ON r.participant = t.participant AND r.trial = t.trial
    WHERE p.study = ?";

/// The trials CSV of a study.
pub async fn trials_csv(pool: &SqlitePool, slug: &str) -> Result<String, ExportError> {
    let definition = definition(pool, slug).await?;
    let catch_counts = sqlx::query(
        "SELECT r.participant, COUNT(*) AS answered, COALESCE(SUM(r.chosen != t.catch_expected), 0) AS failed
         FROM responses r JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
         JOIN participants p ON p.id = r.participant
         WHERE p.study = ? AND t.catch_expected IS NOT NULL GROUP BY r.participant",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    let mut catch_by_participant: std::collections::HashMap<String, (i64, i64)> = Default::default();
    for row in catch_counts {
        catch_by_participant.insert(row.try_get("participant")?, (row.try_get("answered")?, row.try_get("failed")?));
    }
    let rows = sqlx::query(sqlx::AssertSqlSafe(format!("{TRIAL_ROWS} AND r.chosen IS NOT NULL AND t.catch_expected IS NULL ORDER BY p.ordinal, t.trial")))
        .bind(slug)
        .fetch_all(pool)
        .await?;
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = [
        "study", "participant", "trial", "left", "right", "chosen", "scene_left", "scene_right", "rt_ms",
        "shown_at", "answered_at", "catch_answered", "catch_failed", "viewport", "device_pixel_ratio", "completed",
    ]
    .iter()
    .map(|column| column.to_string())
    .collect();
    header.extend(definition.demographics.iter().map(|field| field.name.clone()));
    writer.write_record(&header).expect("writing to memory");
    for row in rows {
        let participant: String = row.try_get("participant")?;
        let (catch_answered, catch_failed) = catch_by_participant.get(&participant).copied().unwrap_or((0, 0));
        let chosen_side: String = row.try_get("chosen")?;
        let left: String = row.try_get("left_condition")?;
        let right: String = row.try_get("right_condition")?;
        let chosen = if chosen_side == "left" { left.clone() } else { right.clone() };
        let demographics: Map<String, Value> =
            serde_json::from_str(&row.try_get::<String, _>("demographics")?).unwrap_or_default();
        // The client details sent with the response, else those sent when the participant joined.
        let mut client: Map<String, Value> =
            serde_json::from_str(&row.try_get::<String, _>("participant_client")?).unwrap_or_default();
        let response_client: Map<String, Value> =
            serde_json::from_str(&row.try_get::<String, _>("client")?).unwrap_or_default();
        client.extend(response_client);
        let viewport = match client.get("viewport") {
            Some(Value::Array(size)) if size.len() == 2 => format!("{}x{}", size[0], size[1]),
            _ => String::new(),
        };
        let mut record = vec![
            definition.slug.clone(),
            participant,
            row.try_get::<i64, _>("trial")?.to_string(),
            left,
            right,
            chosen,
            row.try_get("left_scene")?,
            row.try_get("right_scene")?,
            crate::study::format_number(row.try_get::<f64, _>("rt_ms")?),
            row.try_get::<Option<String>, _>("shown_at")?.unwrap_or_default(),
            row.try_get("answered_at")?,
            catch_answered.to_string(),
            catch_failed.to_string(),
            viewport,
            value_text(client.get("devicePixelRatio")),
            if row.try_get::<Option<String>, _>("completed_at")?.is_some() { "1" } else { "0" }.to_string(),
        ];
        for field in &definition.demographics {
            record.push(value_text(demographics.get(&field.name)));
        }
        writer.write_record(&record).expect("writing to memory");
    }
    Ok(String::from_utf8(writer.into_inner().expect("writing to memory")).expect("UTF-8"))
}

/// The JSON export: the study, and per participant their stored data and whole schedule, with
/// the response of each answered trial.
pub async fn study_json(pool: &SqlitePool, slug: &str) -> Result<Value, ExportError> {
    let definition_text: Option<String> = sqlx::query_scalar("SELECT definition FROM studies WHERE slug = ?")
        .bind(slug)
        .fetch_optional(pool)
        .await?;
    let definition_text = definition_text.ok_or_else(|| ExportError::UnknownStudy(slug.to_string()))?;
    let definition: Value = serde_json::from_str(&definition_text).map_err(|error| ExportError::Definition {
        slug: slug.to_string(),
        message: error.to_string(),
    })?;
    let participants = sqlx::query(
        "SELECT id, ordinal, seed, schedule_version, file_sha256, demographics, client, url_params, trials,
                answered, completion_code, created_at, completed_at
         FROM participants WHERE study = ? ORDER BY ordinal",
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
        let chosen: Option<String> = row.try_get("chosen")?;
        let left: String = row.try_get("left_condition")?;
        let right: String = row.try_get("right_condition")?;
        let response = match &chosen {
            Some(side) => json!({
                "chosen": side,
                "chosen_condition": if side == "left" { &left } else { &right },
                "rt_ms": row.try_get::<f64, _>("rt_ms")?,
                "answered_at": row.try_get::<String, _>("answered_at")?,
                "client": serde_json::from_str::<Value>(&row.try_get::<String, _>("client")?).unwrap_or(Value::Null),
            }),
            None => Value::Null,
        };
        by_participant.entry(row.try_get("participant")?).or_default().push(json!({
            "trial": row.try_get::<i64, _>("trial")?,
            "left": left,
            "right": right,
            "scene_left": row.try_get::<String, _>("left_scene")?,
            "scene_right": row.try_get::<String, _>("right_scene")?,
            "left_stimulus": row.try_get::<String, _>("left_stimulus")?,
            "right_stimulus": row.try_get::<String, _>("right_stimulus")?,
            "catch_expected": row.try_get::<Option<String>, _>("catch_expected")?,
            "shown_at": row.try_get::<Option<String>, _>("shown_at")?,
            "response": response,
        }));
    }
    let mut out = Vec::new();
    for row in participants {
        let id: String = row.try_get("id")?;
        let parse = |column: &str| -> Result<Value, sqlx::Error> {
            Ok(serde_json::from_str(&row.try_get::<String, _>(column)?).unwrap_or(Value::Null))
        };
        out.push(json!({
            "participant": id,
            "ordinal": row.try_get::<i64, _>("ordinal")?,
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
            "schedule": by_participant.remove(&id).unwrap_or_default(),
        }));
    }
    Ok(json!({ "study": definition, "participants": out }))
}
