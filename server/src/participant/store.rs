//! Storage of paired-comparison participants (tables `participants`, `trials`, `responses` and
//! `screen_outs`): the writes that go through the server's one writer with group commit
//! ([`Storage::write`]), and the participant API's reads of a participant and their next trials. A participant is stored with its whole schedule in one transaction; a
//! response only to a served trial that is the participant's next one (a repeat of the same
//! answer is reported, a different one refused).

use sqlx::Row;

use crate::storage::Connection;

use super::model::{NewParticipant, ParticipantRow};
use crate::error::{AppError, AppResult};
use crate::schedule;
use crate::storage::{NOW, OptionalF64, Storage, WriteJob};
use crate::trial::{Answer, ResponseOutcome, ResponseRefused, ScheduledTrial, Side, TrialRow};

/// Where a participant stands in their schedule, as stored.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Position {
    /// The seed their schedule (and a threshold study's levels) come from.
    pub seed: u64,
    /// Trials in their schedule.
    pub trials: i64,
    /// Trials they answered.
    pub answered: i64,
}

impl Position {
    /// The participant's position; a database error becomes `internal(error)`, a participant
    /// not found an internal error saying so.
    pub(crate) async fn read(
        read: &crate::storage::Pool,
        participant: &str,
        internal: fn(sqlx::Error) -> AppError,
    ) -> AppResult<Position> {
        let row = sqlx::query("SELECT seed, trials, answered FROM participants WHERE id = $1")
            .bind(participant)
            .fetch_optional(read)
            .await
            .map_err(internal)?
            .ok_or_else(|| AppError::Internal(format!("participant {participant} is gone")))?;
        Ok(Position {
            seed: row.try_get::<i64, _>("seed").map_err(internal)? as u64,
            trials: row.try_get("trials").map_err(internal)?,
            answered: row.try_get("answered").map_err(internal)?,
        })
    }
}

/// A new response as received.
#[derive(Debug, Clone)]
pub struct NewResponse {
    pub participant: String,
    /// SHA-256 of the token the response came with: checked against the participant's row in
    /// the same transaction, so a deleted participant's token is refused by every server.
    pub token_sha256: Vec<u8>,
    pub trial: i64,
    pub answer: Answer,
    pub rt_ms: f64,
    pub client: String,
    /// The size one image of the pair was shown at, `WxH` in CSS pixels and in device pixels
    /// (as the page measured it), if the page said.
    pub display_css: Option<String>,
    pub display_device: Option<String>,
    /// The study's `min_response_ms`: a faster response is stored flagged `too_fast`.
    pub min_response_ms: u32,
}

/// Reads of the participant API (`participants`, `trials`) on the read pool.
impl Storage {
    pub async fn participant(&self, id: &str) -> Result<Option<ParticipantRow>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT id, study, token_sha256, trials, answered, completion_code, completed_at, url_params
             FROM participants WHERE id = $1",
        )
        .bind(id)
        .fetch_optional(&self.read)
        .await?;
        row.as_ref().map(participant_row).transpose()
    }

    /// The participant with its next unanswered trial and the one after it (for preloading), in
    /// one query.
    pub async fn participant_with_next(
        &self,
        id: &str,
    ) -> Result<Option<(ParticipantRow, Vec<TrialRow>)>, sqlx::Error> {
        let rows = sqlx::query(
            "SELECT p.id, p.study, p.token_sha256, p.trials, p.answered, p.completion_code, p.completed_at,
                    p.url_params, t.trial, t.left_stimulus, t.right_stimulus, t.shown_at
             FROM participants p
             LEFT JOIN trials t ON t.participant = p.id AND t.trial IN (p.answered + 1, p.answered + 2)
             WHERE p.id = $1 ORDER BY t.trial",
        )
        .bind(id)
        .fetch_all(&self.read)
        .await?;
        let Some(first) = rows.first() else { return Ok(None) };
        let participant = participant_row(first)?;
        let mut trials = Vec::new();
        for row in &rows {
            if let Some(trial) = row.try_get::<Option<i64>, _>("trial")? {
                trials.push(TrialRow {
                    trial,
                    left_stimulus: row.try_get("left_stimulus")?,
                    right_stimulus: row.try_get("right_stimulus")?,
                    shown: row.try_get::<Option<String>, _>("shown_at")?.is_some(),
                });
            }
        }
        Ok(Some((participant, trials)))
    }
}

/// A [`ParticipantRow`] from a row with the `participants` columns it reads.
fn participant_row(row: &sqlx::any::AnyRow) -> Result<ParticipantRow, sqlx::Error> {
    Ok(ParticipantRow {
        id: row.try_get("id")?,
        study: row.try_get("study")?,
        token_sha256: row.try_get("token_sha256")?,
        trials: row.try_get("trials")?,
        answered: row.try_get("answered")?,
        completion_code: row.try_get("completion_code")?,
        completed: row.try_get::<Option<String>, _>("completed_at")?.is_some(),
        url_params: row.try_get("url_params")?,
    })
}

/// What joining did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum JoinOutcome {
    /// A new participant with the given id.
    Created,
    /// The study keeps one run per external id, this one had joined before, and the join
    /// carried that run's token: the run (`id`) continues, with the same token.
    Resumed { id: String, trials: i64 },
    /// The study keeps one run per external id and this one had joined before, but the join
    /// did not carry that run's token: refused, nothing changed.
    Taken,
}

/// A visitor who does not meet the study's screen requirements.
#[derive(Debug, Clone)]
pub struct ScreenOut {
    /// Random id; an existing row with this id (the same visitor checking again) is updated.
    pub id: String,
    pub study: String,
    pub reason: String,
    pub client: String,
    pub url_params: String,
    pub pilot: bool,
}

impl WriteJob for NewResponse {
    type Outcome = Result<ResponseOutcome, ResponseRefused>;

    fn run(
        &self,
        connection: &mut Connection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send {
        store_response(connection, self)
    }
}

impl WriteJob for NewParticipant {
    type Outcome = JoinOutcome;

    fn run(
        &self,
        connection: &mut Connection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send {
        insert_participant(connection, self)
    }
}

/// Records (or updates) the screen-out `screen_out`, or with `None` withdraws the one with `id`.
pub struct ScreenOutWrite {
    pub id: String,
    pub screen_out: Option<ScreenOut>,
}

impl WriteJob for ScreenOutWrite {
    type Outcome = ();

    fn run(
        &self,
        connection: &mut Connection,
    ) -> impl std::future::Future<Output = Result<Self::Outcome, sqlx::Error>> + Send {
        write_screen_out(connection, &self.id, self.screen_out.as_ref())
    }
}

/// Records that a trial was served, if it had not been. It is awaited ([`Storage::write`])
/// before the trial is sent, so that a response to the trial finds it served even after the
/// server was killed or on another server of the database (a response to a trial never served
/// is refused).
pub struct Shown {
    pub participant: String,
    pub trial: i64,
}

impl WriteJob for Shown {
    type Outcome = ();

    async fn run(&self, connection: &mut Connection) -> Result<(), sqlx::Error> {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "UPDATE trials SET shown_at = {NOW} WHERE participant = $1 AND trial = $2 AND shown_at IS NULL"
        )))
        .bind(&self.participant)
        .bind(self.trial)
        .execute(&mut *connection)
        .await?;
        Ok(())
    }
}

/// A participant's answered and planned trials, if the participant exists.
async fn progress(connection: &mut Connection, participant: &str) -> Result<Option<(i64, i64)>, sqlx::Error> {
    let row = sqlx::query("SELECT answered, trials FROM participants WHERE id = $1")
        .bind(participant)
        .fetch_optional(&mut *connection)
        .await?;
    row.map(|row| Ok((row.try_get("answered")?, row.try_get("trials")?))).transpose()
}

async fn store_response(
    connection: &mut Connection,
    response: &NewResponse,
) -> Result<Result<ResponseOutcome, ResponseRefused>, sqlx::Error> {
    // Only a trial that was served can be answered; the server's own time since serving it
    // (first serving, so a reload never shortens it) is stored beside the client's.
    // The token is checked here, in the transaction that stores the response: the database is
    // the truth on which participants exist and which token each answers to (a server's cache
    // of credentials may be older than a deletion made by another server).
    let served = sqlx::query(
        "SELECT CASE WHEN trials.shown_at IS NULL THEN 0 ELSE 1 END AS served,
                (julianday('now') - julianday(trials.shown_at)) * 86400000.0 AS served_ms
         FROM trials JOIN participants ON participants.id = trials.participant
         WHERE trials.participant = $1 AND trials.trial = $2 AND participants.token_sha256 = $3",
    )
    .bind(&response.participant)
    .bind(response.trial)
    .bind(&response.token_sha256)
    .fetch_optional(&mut *connection)
    .await?;
    let Some(served) = &served else {
        // No such trial: out of range, or (active designs) not chosen yet, so never served; or
        // the participant does not answer to this token (any more).
        let owner: Option<Vec<u8>> = sqlx::query_scalar("SELECT token_sha256 FROM participants WHERE id = $1")
            .bind(&response.participant)
            .fetch_optional(&mut *connection)
            .await?;
        if !owner.is_some_and(|owner| crate::auth::constant_time_eq(&owner, &response.token_sha256)) {
            return Ok(Err(ResponseRefused::NotYours));
        }
        let Some((answered, trials)) = progress(connection, &response.participant).await? else {
            return Ok(Err(ResponseRefused::UnknownParticipant));
        };
        if response.trial < 1 || response.trial > trials {
            return Ok(Err(ResponseRefused::OutOfRange { trial: response.trial, trials }));
        }
        return Ok(Err(ResponseRefused::NeverServed { trial: response.trial, next: answered + 1 }));
    };
    if served.try_get::<i64, _>("served")? == 0 {
        let answered: i64 = sqlx::query_scalar("SELECT answered FROM participants WHERE id = $1")
            .bind(&response.participant)
            .fetch_one(&mut *connection)
            .await?;
        return Ok(Err(ResponseRefused::NeverServed { trial: response.trial, next: answered + 1 }));
    }
    let served_ms = served.try_get::<Option<f64>, _>("served_ms")?.map(|ms| ms.max(0.0));
    let floor = f64::from(response.min_response_ms);
    let too_fast = response.rt_ms < floor || served_ms.is_some_and(|ms| ms < floor);
    // The usual case in two statements: advance the participant's progress if this is the next
    // trial, then insert the response. Responses are answered in order, so `answered` is the
    // number of stored responses and trial `answered + 1` has none yet.
    let advanced = sqlx::query(sqlx::AssertSqlSafe(format!(
        "UPDATE participants SET answered = answered + 1,
             completed_at = CASE WHEN answered + 1 = trials THEN {NOW} ELSE completed_at END
         WHERE id = $1 AND answered = $2 AND $3 <= trials"
    )))
    .bind(&response.participant)
    .bind(response.trial - 1)
    .bind(response.trial)
    .execute(&mut *connection)
    .await?;
    let (chosen, rating) = response.answer.columns();
    if advanced.rows_affected() == 1 {
        sqlx::query(sqlx::AssertSqlSafe(format!(
            "INSERT INTO responses (participant, trial, chosen, rating, rt_ms, client, answered_at, too_fast, served_ms,
                 seq, display_css, display_device)
             VALUES ($1, $2, $3, $4, $5, $6, {NOW}, $7, $8, (SELECT COALESCE(MAX(seq), 0) + 1 FROM responses), $9, $10)"
        )))
        .bind(&response.participant)
        .bind(response.trial)
        .bind(chosen)
        .bind(rating)
        .bind(response.rt_ms)
        .bind(&response.client)
        .bind(too_fast as i64)
        .bind(OptionalF64(served_ms))
        .bind(&response.display_css)
        .bind(&response.display_device)
        .execute(&mut *connection)
        .await?;
        return Ok(Ok(ResponseOutcome::Created));
    }
    // Not the next trial: a repeat, a changed answer, or out of order.
    let existing = sqlx::query("SELECT chosen, rating FROM responses WHERE participant = $1 AND trial = $2")
        .bind(&response.participant)
        .bind(response.trial)
        .fetch_optional(&mut *connection)
        .await?;
    if let Some(existing) = existing {
        let stored: (Option<String>, Option<i64>) = (existing.try_get("chosen")?, existing.try_get("rating")?);
        return Ok(if stored.0.as_deref() == chosen && stored.1 == rating {
            Ok(ResponseOutcome::Repeated)
        } else {
            let chosen = stored.0.or(stored.1.map(|rating| rating.to_string())).unwrap_or_default();
            Err(ResponseRefused::AlreadyAnswered { trial: response.trial, chosen })
        });
    }
    let Some((answered, trials)) = progress(connection, &response.participant).await? else {
        return Ok(Err(ResponseRefused::UnknownParticipant));
    };
    if response.trial < 1 || response.trial > trials {
        return Ok(Err(ResponseRefused::OutOfRange { trial: response.trial, trials }));
    }
    Ok(Err(ResponseRefused::NotYet { trial: response.trial, next: answered + 1 }))
}

async fn write_screen_out(
    connection: &mut Connection,
    id: &str,
    screen_out: Option<&ScreenOut>,
) -> Result<(), sqlx::Error> {
    match screen_out {
        None => {
            sqlx::query("DELETE FROM screen_outs WHERE id = $1").bind(id).execute(&mut *connection).await?;
        }
        Some(screen_out) => {
            sqlx::query(sqlx::AssertSqlSafe(format!(
                "INSERT INTO screen_outs (id, study, reason, client, url_params, pilot, created_at)
                 VALUES ($1, $2, $3, $4, $5, $6, {NOW})
                 ON CONFLICT (id) DO UPDATE SET reason = excluded.reason, client = excluded.client"
            )))
            .bind(id)
            .bind(&screen_out.study)
            .bind(&screen_out.reason)
            .bind(&screen_out.client)
            .bind(&screen_out.url_params)
            .bind(screen_out.pilot as i64)
            .execute(&mut *connection)
            .await?;
        }
    }
    Ok(())
}

/// Stores trial number `number` of a participant's schedule; `chosen` is the posterior state and
/// batch number of an actively chosen trial (`None` for a trial planned at join).
pub(crate) async fn insert_trial(
    connection: &mut Connection,
    participant: &str,
    number: i64,
    trial: &ScheduledTrial,
    chosen: Option<(&str, i64)>,
) -> Result<(), sqlx::Error> {
    sqlx::query(
        "INSERT INTO trials (participant, trial, left_condition, right_condition, left_scene, right_scene,
             left_stimulus, right_stimulus, catch_expected, chosen_by, active_batch, catch_rating)
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12)",
    )
    .bind(participant)
    .bind(number)
    .bind(&trial.left_condition)
    .bind(&trial.right_condition)
    .bind(&trial.left_scene)
    .bind(&trial.right_scene)
    .bind(&trial.left_stimulus)
    .bind(&trial.right_stimulus)
    .bind(trial.catch_expected.map(Side::as_str))
    .bind(chosen.map(|(state, _)| state))
    .bind(chosen.map(|(_, batch)| batch))
    .bind(trial.catch_rating.map(i64::from))
    .execute(&mut *connection)
    .await?;
    Ok(())
}

/// Withdraws the screen-out the joining visitor had, if any.
async fn withdraw_screen_out(connection: &mut Connection, participant: &NewParticipant) -> Result<(), sqlx::Error> {
    if let Some(withdraw) = &participant.withdraw_screen_out {
        sqlx::query("DELETE FROM screen_outs WHERE id = $1 AND study = $2")
            .bind(withdraw)
            .bind(&participant.study.study.slug)
            .execute(&mut *connection)
            .await?;
    }
    Ok(())
}

async fn insert_participant(
    connection: &mut Connection,
    participant: &NewParticipant,
) -> Result<JoinOutcome, sqlx::Error> {
    let study = &participant.study.study;
    if let Some(external_key) = &participant.external_key {
        let existing =
            sqlx::query("SELECT id, trials, token_sha256 FROM participants WHERE study = $1 AND external_key = $2")
                .bind(&study.slug)
                .bind(external_key)
                .fetch_optional(&mut *connection)
                .await?;
        if let Some(existing) = existing {
            // only the run's own token resumes it, and nothing about the run changes
            let token_sha256: Vec<u8> = existing.try_get("token_sha256")?;
            let proven = participant
                .resume_token_sha256
                .as_deref()
                .is_some_and(|given| crate::auth::constant_time_eq(given, &token_sha256));
            if !proven {
                return Ok(JoinOutcome::Taken);
            }
            withdraw_screen_out(connection, participant).await?;
            return Ok(JoinOutcome::Resumed { id: existing.try_get("id")?, trials: existing.try_get("trials")? });
        }
    }
    withdraw_screen_out(connection, participant).await?;
    let ordinal: i64 = sqlx::query_scalar("SELECT COALESCE(MAX(ordinal) + 1, 0) FROM participants WHERE study = $1")
        .bind(&study.slug)
        .fetch_one(&mut *connection)
        .await?;
    let seed = match study.design.seed {
        Some(study_seed) => schedule::derived_seed(study_seed, ordinal as u64),
        None => participant.random_seed,
    };
    let trials = participant.study.schedule(seed);
    let completion_code = study.completion.code.clone().unwrap_or_else(|| participant.random_completion_code.clone());
    sqlx::query(sqlx::AssertSqlSafe(format!(
        "INSERT INTO participants (id, study, ordinal, token_sha256, seed, schedule_version, file_sha256,
             demographics, client, url_params, trials, completion_code, created_at, pilot, external_key)
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, {NOW}, $13, $14)"
    )))
    .bind(&participant.id)
    .bind(&study.slug)
    .bind(ordinal)
    .bind(&participant.token_sha256)
    .bind(seed as i64)
    .bind(schedule::SCHEDULE_VERSION)
    .bind(&study.file_sha256)
    .bind(&participant.demographics)
    .bind(&participant.client)
    .bind(&participant.url_params)
    .bind(study.trial_count() as i64)
    .bind(completion_code)
    .bind(participant.pilot as i64)
    .bind(&participant.external_key)
    .execute(&mut *connection)
    .await?;
    for (index, trial) in trials.iter().enumerate() {
        insert_trial(connection, &participant.id, index as i64 + 1, trial, None).await?;
    }
    Ok(JoinOutcome::Created)
}
