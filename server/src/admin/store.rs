//! The admin's SQL: the write jobs that run in the writer's group commit (open/close, exclude and
//! include, delete, preview links, each with its audit line) and the reads of the statistics.

use sqlx::Row;

use crate::storage::{Connection, NOW, Pool, Storage, WriteJob, Written};

/// Why an admin write was refused; nothing was written.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum AdminRefused {
    /// No participant (or screen-out) has this id.
    UnknownParticipant {
        id: String,
    },
    UnknownStudy {
        slug: String,
    },
}

/// Opens or closes a study (the admin's open/close).
struct SetOpen {
    slug: String,
    open: bool,
}

impl WriteJob for SetOpen {
    type Outcome = Result<(), AdminRefused>;

    async fn run(&self, connection: &mut Connection) -> Result<Self::Outcome, sqlx::Error> {
        let result = sqlx::query("UPDATE studies SET open = $1 WHERE slug = $2")
            .bind(self.open as i64)
            .bind(&self.slug)
            .execute(&mut *connection)
            .await?;
        Ok(if result.rows_affected() == 1 {
            Ok(())
        } else {
            Err(AdminRefused::UnknownStudy { slug: self.slug.clone() })
        })
    }
}

// ------------------------------------------------------------------------------------------
// The researcher's changes to participants' data (issue 12, "Trustworthy responses"): exclude
// and include (kept, with reason and time), delete (every datum of the participant, leaving an
// audit line without personal data), preview links. Each runs in the writer's group commit.

/// A researcher's change to participants' data.
#[derive(Debug)]
#[non_exhaustive]
pub enum AdminWrite {
    /// Exclude the participant with this reason, or (`None`) include them again.
    SetExcluded { participant: String, reason: Option<String> },
    /// Delete a participant and all their data, or a screen-out row, by id.
    Delete { id: String },
    /// Store a new preview link's token hash.
    Preview { study: String, token_sha256: Vec<u8> },
    /// Revoke every preview link of the study.
    RevokePreviews { study: String },
}

/// What an admin write did.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum AdminWritten {
    /// The participant is now excluded or included.
    Excluded {
        study: String,
        ordinal: i64,
        excluded: bool,
        reason: Option<String>,
        excluded_at: Option<String>,
    },
    /// A participant (with `trials` schedule rows and `responses` responses) or a screen-out
    /// row was deleted.
    Deleted(Deletion),
    PreviewStored,
    /// This many preview links were revoked.
    PreviewsRevoked(u64),
}

/// A deletion, as the audit line records it (no personal data).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Deletion {
    pub study: String,
    /// `participant`, `lab-participant` or `screen-out`.
    pub kind: &'static str,
    /// The participant's ordinal within the study (absent for a screen-out).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ordinal: Option<i64>,
    pub trials: i64,
    pub responses: i64,
}

impl Storage {
    /// Runs an admin write in the next group commit and answers after it is durable.
    pub async fn admin_write(&self, write: AdminWrite) -> Written<AdminWritten, AdminRefused> {
        self.write(write).await
    }

    /// Deletes a participant (or a screen-out row), then rewrites the database and truncates the
    /// WAL so that none of their bytes remain in the database's files (`Storage::forget_deleted`).
    pub async fn delete(&self, id: &str) -> Written<Deletion, AdminRefused> {
        let deletion = match self.write(Delete { id: id.to_string() }).await? {
            Ok(deletion) => deletion,
            Err(refused) => return Ok(Err(refused)),
        };
        self.forget_deleted().await?;
        Ok(Ok(deletion))
    }

    /// Opens or closes a study.
    pub async fn set_open(&self, slug: &str, open: bool) -> Written<(), AdminRefused> {
        self.write(SetOpen { slug: slug.to_string(), open }).await
    }
}

async fn audit(
    connection: &mut Connection,
    action: &str,
    study: &str,
    detail: serde_json::Value,
) -> Result<(), sqlx::Error> {
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "INSERT INTO audit (at, action, study, detail) VALUES ({NOW}, $1, $2, $3)"
    )))
    .bind(action)
    .bind(study)
    .bind(detail.to_string())
    .execute(&mut *connection)
    .await?;
    Ok(())
}

impl WriteJob for AdminWrite {
    type Outcome = Result<AdminWritten, AdminRefused>;

    fn run(
        &self,
        connection: &mut Connection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send {
        execute_admin(connection, self)
    }
}

async fn execute_admin(
    connection: &mut Connection,
    write: &AdminWrite,
) -> Result<Result<AdminWritten, AdminRefused>, sqlx::Error> {
    match write {
        AdminWrite::SetExcluded { participant, reason } => {
            // a survey participant, else a lab participant (task studies keep theirs apart)
            let mut set = None;
            for table in ["participants", "task_participants"] {
                set = set_excluded(connection, table, participant, reason.as_deref()).await?;
                if set.is_some() {
                    break;
                }
            }
            let Some((study, ordinal, excluded_at)) = set else {
                return Ok(Err(AdminRefused::UnknownParticipant { id: participant.clone() }));
            };
            let action = if reason.is_some() { "exclude" } else { "include" };
            audit(connection, action, &study, serde_json::json!({ "ordinal": ordinal })).await?;
            Ok(Ok(AdminWritten::Excluded {
                study,
                ordinal,
                excluded: reason.is_some(),
                reason: reason.clone(),
                excluded_at,
            }))
        }
        AdminWrite::Delete { id } => Ok(delete_rows(connection, id).await?.map(AdminWritten::Deleted)),
        AdminWrite::Preview { study, token_sha256 } => {
            let known: Option<String> = sqlx::query_scalar("SELECT slug FROM studies WHERE slug = $1")
                .bind(study)
                .fetch_optional(&mut *connection)
                .await?;
            if known.is_none() {
                return Ok(Err(AdminRefused::UnknownStudy { slug: study.clone() }));
            }
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "INSERT INTO previews (token_sha256, study, created_at) VALUES ($1, $2, {NOW})"
            )))
            .bind(token_sha256)
            .bind(study)
            .execute(&mut *connection)
            .await?;
            Ok(Ok(AdminWritten::PreviewStored))
        }
        AdminWrite::RevokePreviews { study } => {
            let revoked =
                sqlx::query("DELETE FROM previews WHERE study = $1").bind(study).execute(&mut *connection).await?;
            Ok(Ok(AdminWritten::PreviewsRevoked(revoked.rows_affected())))
        }
    }
}

/// Deletes a lab participant and every datum of theirs — their trials (schedule, answers, key
/// logs, frame times) and their row (code, token hash, seed) — inside the admin's write; the
/// participant who took an abandoned participant's slot is no longer named there
/// (`slot_taken_by`). None when no lab participant has this id. [`Storage::delete`] then
/// rewrites the database files, as for a survey participant.
async fn delete_lab_participant(connection: &mut Connection, id: &str) -> Result<Option<Deletion>, sqlx::Error> {
    let row = sqlx::query("SELECT study, ordinal FROM task_participants WHERE id = $1")
        .bind(id)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(row) = row else { return Ok(None) };
    let study: String = row.try_get("study")?;
    let ordinal: i64 = row.try_get("ordinal")?;
    let answered: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM task_trials WHERE participant = $1 AND answered_at IS NOT NULL")
            .bind(id)
            .fetch_one(&mut *connection)
            .await?;
    let trials =
        sqlx::query("DELETE FROM task_trials WHERE participant = $1").bind(id).execute(&mut *connection).await?;
    sqlx::query("UPDATE task_participants SET slot_taken_by = NULL WHERE slot_taken_by = $1")
        .bind(id)
        .execute(&mut *connection)
        .await?;
    sqlx::query("DELETE FROM task_participants WHERE id = $1").bind(id).execute(&mut *connection).await?;
    Ok(Some(Deletion {
        study,
        kind: "lab-participant",
        ordinal: Some(ordinal),
        trials: trials.rows_affected() as i64,
        responses: answered,
    }))
}

/// Excludes a participant of `table` (`participants` for surveys, `task_participants` for the
/// lab) with `reason`, or (None) includes them again, inside the admin's write:
/// (study, ordinal, excluded_at), or None when that table has no participant with this id.
async fn set_excluded(
    connection: &mut Connection,
    table: &'static str,
    id: &str,
    reason: Option<&str>,
) -> Result<Option<(String, i64, Option<String>)>, sqlx::Error> {
    let row = sqlx::query(sqlx::AssertSqlSafe(format!("SELECT study, ordinal FROM {table} WHERE id = $1")))
        .bind(id)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(row) = row else { return Ok(None) };
    let excluded_at: Option<String> = match reason {
        Some(reason) => {
            sqlx::query_scalar(sqlx::AssertSqlSafe(format!(
                "UPDATE {table} SET excluded = 1, exclusion_reason = $1, excluded_at = {NOW}
                 WHERE id = $2 RETURNING excluded_at"
            )))
            .bind(reason)
            .bind(id)
            .fetch_one(&mut *connection)
            .await?
        }
        None => {
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "UPDATE {table} SET excluded = 0, exclusion_reason = NULL, excluded_at = NULL WHERE id = $1"
            )))
            .bind(id)
            .execute(&mut *connection)
            .await?;
            None
        }
    };
    Ok(Some((row.try_get("study")?, row.try_get("ordinal")?, excluded_at)))
}

/// Deletes a participant and all their data, or a screen-out row, by id, with an audit line.
async fn delete_rows(connection: &mut Connection, id: &str) -> Result<Result<Deletion, AdminRefused>, sqlx::Error> {
    let row = sqlx::query("SELECT study, ordinal FROM participants WHERE id = $1")
        .bind(id)
        .fetch_optional(&mut *connection)
        .await?;
    if let Some(row) = row {
        let study: String = row.try_get("study")?;
        let ordinal: i64 = row.try_get("ordinal")?;
        let responses = sqlx::query("DELETE FROM responses WHERE participant = $1")
            .bind(id)
            .execute(&mut *connection)
            .await?
            .rows_affected() as i64;
        let trials = sqlx::query("DELETE FROM trials WHERE participant = $1")
            .bind(id)
            .execute(&mut *connection)
            .await?
            .rows_affected() as i64;
        sqlx::query("DELETE FROM participants WHERE id = $1").bind(id).execute(&mut *connection).await?;
        let deletion =
            Deletion { study: study.clone(), kind: "participant", ordinal: Some(ordinal), trials, responses };
        audit(connection, "delete", &study, serde_json::to_value(&deletion).expect("serialises")).await?;
        return Ok(Ok(deletion));
    }
    if let Some(deletion) = delete_lab_participant(connection, id).await? {
        audit(connection, "delete", &deletion.study, serde_json::to_value(&deletion).expect("serialises")).await?;
        return Ok(Ok(deletion));
    }
    let study: Option<String> = sqlx::query_scalar("DELETE FROM screen_outs WHERE id = $1 RETURNING study")
        .bind(id)
        .fetch_optional(&mut *connection)
        .await?;
    let Some(study) = study else {
        return Ok(Err(AdminRefused::UnknownParticipant { id: id.to_string() }));
    };
    let deletion = Deletion { study: study.clone(), kind: "screen-out", ordinal: None, trials: 0, responses: 0 };
    audit(connection, "delete", &study, serde_json::to_value(&deletion).expect("serialises")).await?;
    Ok(Ok(deletion))
}

/// [`AdminWrite::Delete`] with the deletion as its outcome, for [`Storage::delete`].
struct Delete {
    id: String,
}

impl WriteJob for Delete {
    type Outcome = Result<Deletion, AdminRefused>;

    async fn run(&self, connection: &mut Connection) -> Result<Self::Outcome, sqlx::Error> {
        delete_rows(connection, &self.id).await
    }
}

// ------------------------------------------------------------------------------------------
// The admin's reads, on the read pool (`Storage::admin`).

/// A study's row in `studies`.
pub(super) struct StudyRow {
    pub slug: String,
    pub title: String,
    pub kind: String,
    pub open: bool,
}

pub(super) async fn study_row(pool: &Pool, slug: &str) -> Result<Option<StudyRow>, sqlx::Error> {
    let Some(row) = sqlx::query("SELECT slug, title, kind, open, definition FROM studies WHERE slug = $1")
        .bind(slug)
        .fetch_optional(pool)
        .await?
    else {
        return Ok(None);
    };
    Ok(Some(StudyRow {
        slug: row.try_get("slug")?,
        title: row.try_get("title")?,
        kind: row.try_get("kind")?,
        open: row.try_get::<i64, _>("open")? == 1,
    }))
}

/// The study's `kind`, or `None` for an unknown study.
pub(super) async fn study_kind(pool: &Pool, slug: &str) -> Result<Option<String>, sqlx::Error> {
    sqlx::query_scalar("SELECT kind FROM studies WHERE slug = $1").bind(slug).fetch_optional(pool).await
}

/// The web-survey studies, in the order they were first loaded.
pub(super) async fn survey_slugs(pool: &Pool) -> Result<Vec<String>, sqlx::Error> {
    sqlx::query_scalar("SELECT slug FROM studies WHERE kind <> 'task' ORDER BY first_loaded_at, slug")
        .fetch_all(pool)
        .await
}

/// The most trials any participant of a study was scheduled (a study no longer served).
pub(super) async fn max_trials(pool: &Pool, slug: &str) -> Result<i64, sqlx::Error> {
    sqlx::query_scalar("SELECT COALESCE(MAX(trials), 0) FROM participants WHERE study = $1")
        .bind(slug)
        .fetch_one(pool)
        .await
}

/// `n` participants answered `answered` trials; `finished`; `apart`: 1 pilots, 2 excluded, 0 the rest.
pub(super) struct ParticipantCount {
    pub answered: i64,
    pub finished: bool,
    pub apart: i64,
    pub n: i64,
}

pub(super) async fn participant_counts(pool: &Pool, slug: &str) -> Result<Vec<ParticipantCount>, sqlx::Error> {
    let rows = sqlx::query(
        "SELECT answered, CASE WHEN completed_at IS NULL THEN 0 ELSE 1 END AS finished,
                CASE WHEN pilot <> 0 THEN 1 WHEN excluded <> 0 THEN 2 ELSE 0 END AS apart, COUNT(*) AS n
         FROM participants WHERE study = $1 GROUP BY answered, finished, apart",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    rows.into_iter()
        .map(|row| {
            Ok(ParticipantCount {
                answered: row.try_get("answered")?,
                finished: row.try_get::<i64, _>("finished")? != 0,
                apart: row.try_get("apart")?,
                n: row.try_get("n")?,
            })
        })
        .collect()
}

/// Response times (ms) of the study's participants, pilots and excluded left out.
pub(super) async fn response_times(pool: &Pool, slug: &str) -> Result<Vec<f64>, sqlx::Error> {
    sqlx::query_scalar(
        "SELECT r.rt_ms FROM responses r JOIN participants p ON p.id = r.participant
         WHERE p.study = $1 AND p.pilot = 0 AND p.excluded = 0",
    )
    .bind(slug)
    .fetch_all(pool)
    .await
}

/// Seconds from joining to finishing of the study's finished participants (pilots and excluded left out).
pub(super) async fn total_times(pool: &Pool, slug: &str) -> Result<Vec<f64>, sqlx::Error> {
    sqlx::query_scalar(
        "SELECT (julianday(completed_at) - julianday(created_at)) * 86400.0 FROM participants
         WHERE study = $1 AND completed_at IS NOT NULL AND pilot = 0 AND excluded = 0",
    )
    .bind(slug)
    .fetch_all(pool)
    .await
}

/// Catch-trial responses, failures, and participants failing at least one.
pub(super) struct CatchCounts {
    pub responses: i64,
    pub failures: i64,
    pub failing: i64,
}

pub(super) async fn catch_counts(pool: &Pool, slug: &str) -> Result<CatchCounts, sqlx::Error> {
    // a rating catch trial fails more than CATCH_TOLERANCE categories from its expected rating
    let failed = format!(
        "(r.chosen != t.catch_expected OR ABS(r.rating - t.catch_rating) > {})",
        crate::study::rating::CATCH_TOLERANCE
    );
    let row = sqlx::query(sqlx::AssertSqlSafe(format!(
        "SELECT COUNT(*) AS n, COALESCE(SUM(CASE WHEN {failed} THEN 1 ELSE 0 END), 0) AS failures,
                COUNT(DISTINCT CASE WHEN {failed} THEN r.participant END) AS failing
         FROM responses r JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
         JOIN participants p ON p.id = r.participant
         WHERE p.study = $1 AND p.pilot = 0 AND p.excluded = 0
             AND (t.catch_expected IS NOT NULL OR t.catch_rating IS NOT NULL)"
    )))
    .bind(slug)
    .fetch_one(pool)
    .await?;
    Ok(CatchCounts {
        responses: row.try_get("n")?,
        failures: row.try_get("failures")?,
        failing: row.try_get("failing")?,
    })
}

/// Screen-outs of the study, pilots left out.
pub(super) async fn screened_out(pool: &Pool, slug: &str) -> Result<i64, sqlx::Error> {
    sqlx::query_scalar("SELECT COUNT(*) FROM screen_outs WHERE study = $1 AND pilot = 0")
        .bind(slug)
        .fetch_one(pool)
        .await
}

/// A screen-out row, as the participants list shows it.
pub(super) struct ScreenOut {
    pub id: String,
    pub reason: String,
    pub url_params: String,
    pub pilot: bool,
    pub created_at: String,
}

pub(super) async fn screen_outs(pool: &Pool, slug: &str) -> Result<Vec<ScreenOut>, sqlx::Error> {
    let rows = sqlx::query(
        "SELECT id, reason, url_params, pilot, created_at FROM screen_outs WHERE study = $1 ORDER BY created_at, id",
    )
    .bind(slug)
    .fetch_all(pool)
    .await?;
    rows.into_iter()
        .map(|row| {
            Ok(ScreenOut {
                id: row.try_get("id")?,
                reason: row.try_get("reason")?,
                url_params: row.try_get("url_params")?,
                pilot: row.try_get::<i64, _>("pilot")? == 1,
                created_at: row.try_get("created_at")?,
            })
        })
        .collect()
}
