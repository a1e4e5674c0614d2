//! Active designs in the web survey (`pairs = "active"`): each study's shared posterior and the
//! batches it chooses for a participant when their planned trials run out.
//!
//! The posterior of a study absorbs the committed judgments of its non-pilot participants in
//! the order they were committed (`responses.seq`, numbered by the writer), catch trials left
//! out, so "the state after N judgments" is a fact of the database and a batch's `chosen_by`
//! (`N-<fingerprint>`) names it. A batch is chosen under the study's lock, from every judgment
//! committed before it, by [`schedule::active_batch`] with the participant's own history (their
//! previous pair, their left/right counts, their batch number) — the same function
//! `mrstudy simulate` runs — and is stored by one write job that adds nothing if another
//! request of the same participant stored it first. Replaying a trial's batch from the database
//! (absorb the first N judgments, rebuild the participant's history, call `active_batch`) gives
//! the same trials; `server/tests/active.rs` checks it.
//!
//! When the posterior cannot be computed ([`mrstudy_analysis::active::ActiveError`]) the study
//! falls back to its fixed design ([`schedule::fallback_batch`]) from then on, `chosen_by`
//! says why, and the admin page shows the warning.

use sqlx::Row;

use crate::storage::Connection;
use tokio::sync::Mutex;

use super::store::{Position, insert_trial};
use crate::AppState;
use crate::error::{AppError, AppResult};
use crate::prepared::PreparedStudy;
use crate::schedule::{self, ActiveHistory, Posterior};
use crate::storage::WriteJob;
use crate::trial::ScheduledTrial;

/// One active study's shared state.
#[derive(Debug)]
pub struct ActiveState {
    /// `None` once the posterior failed (the study then uses its fixed design).
    posterior: Option<Posterior>,
    /// The last `responses.seq` absorbed.
    absorbed_seq: i64,
    /// Why the fixed design is used instead, for the admin page.
    pub failure: Option<String>,
}

impl ActiveState {
    /// Judgments absorbed so far.
    pub fn judgments(&self) -> u64 {
        self.posterior.as_ref().map_or(0, Posterior::judgments)
    }
}

/// A fresh state for a study with an active design (a posterior the study file's checks already
/// accepted); `None` for a fixed design.
pub fn active_state(prepared: &PreparedStudy) -> Option<Mutex<ActiveState>> {
    let posterior = schedule::active_posterior(&prepared.study)?;
    let (posterior, failure) = match posterior {
        Ok(posterior) => (Some(posterior), None),
        Err(error) => (None, Some(format!("the posterior could not be set up: {error}"))),
    };
    Some(Mutex::new(ActiveState { posterior, absorbed_seq: 0, failure }))
}

/// Absorbs the judgments committed since the last call, in commit order.
async fn absorb(state: &AppState, prepared: &PreparedStudy, active: &mut ActiveState) -> AppResult<()> {
    let rows = sqlx::query(
        "SELECT r.seq, t.left_condition, t.right_condition, r.chosen
         FROM responses r
         JOIN trials t ON t.participant = r.participant AND t.trial = r.trial
         JOIN participants p ON p.id = r.participant
         WHERE r.seq > $1 AND p.study = $2 AND p.pilot = 0 AND t.catch_expected IS NULL
         ORDER BY r.seq",
    )
    .bind(active.absorbed_seq)
    .bind(&prepared.study.slug)
    .fetch_all(&state.storage().read)
    .await
    .map_err(|error| AppError::Internal(format!("cannot read the judgments: {error}")))?;
    let index = |name: &str| prepared.study.condition_index(name);
    for row in rows {
        let seq: i64 = row.try_get("seq").map_err(internal)?;
        active.absorbed_seq = seq;
        let (left, right, chosen): (String, String, String) = (
            row.try_get("left_condition").map_err(internal)?,
            row.try_get("right_condition").map_err(internal)?,
            row.try_get("chosen").map_err(internal)?,
        );
        let (Some(left), Some(right)) = (index(&left), index(&right)) else { continue };
        // a "not sure" (allow_tie) informs no Bradley–Terry direction: the posterior skips it
        let (winner, loser) = match chosen.as_str() {
            "left" => (left, right),
            "right" => (right, left),
            _ => continue,
        };
        if let Some(posterior) = &mut active.posterior
            && let Err(error) = posterior.update(winner, loser)
        {
            active.failure = Some(format!(
                "the posterior failed after {} judgments ({error}); the study's fixed design chooses the trials from now on",
                posterior.judgments()
            ));
            active.posterior = None;
        }
    }
    Ok(())
}

fn internal(error: sqlx::Error) -> AppError {
    AppError::Internal(format!("cannot read the judgments: {error}"))
}

/// Chooses and stores the participant's next batch if their next trial (`answered + 1`) has not
/// been chosen yet and they have trials left.
pub(crate) async fn extend(state: &AppState, prepared: &PreparedStudy, participant: &str) -> AppResult<()> {
    let Some(lock) = state.active(&prepared.study.slug) else { return Ok(()) };
    let mut active = lock.lock().await;
    let study = &prepared.study;
    let read = &state.storage().read;
    let Position { seed, trials: total, answered } = Position::read(read, participant, internal).await?;
    let rows = sqlx::query(
        "SELECT left_condition, right_condition, catch_expected, active_batch FROM trials
         WHERE participant = $1 ORDER BY trial",
    )
    .bind(participant)
    .fetch_all(read)
    .await
    .map_err(internal)?;
    let existing = rows.len() as i64;
    if existing > answered || existing >= total {
        return Ok(()); // chosen already (another request), or nothing left to choose
    }
    let index = |name: &str| study.condition_index(name);
    let mut pairs = Vec::new();
    let mut batches = 0u64;
    for row in &rows {
        if let Some(batch) = row.try_get::<Option<i64>, _>("active_batch").map_err(internal)? {
            batches = batches.max(batch as u64 + 1);
        }
        if row.try_get::<Option<String>, _>("catch_expected").map_err(internal)?.is_some() {
            continue;
        }
        let left: String = row.try_get("left_condition").map_err(internal)?;
        let right: String = row.try_get("right_condition").map_err(internal)?;
        if let (Some(left), Some(right)) = (index(&left), index(&right)) {
            pairs.push((left, right));
        }
    }
    let mut history = ActiveHistory::of(study.conditions.len(), &pairs, batches);
    absorb(state, prepared, &mut active).await?;
    let batch = study.design.active.as_ref().map_or(1, |design| design.batch as i64);
    let count = batch.min(total - existing) as usize;
    let chosen = match &active.posterior {
        Some(posterior) => schedule::active_batch(study, posterior, seed, &mut history, count)
            .map(|planned| (planned, posterior.state_id().to_string()))
            .map_err(|error| error.to_string()),
        None => Err(active.failure.clone().unwrap_or_else(|| "no posterior".into())),
    };
    let (planned, chosen_by) = match chosen {
        Ok(chosen) => chosen,
        Err(reason) => {
            if active.posterior.is_some() {
                active.failure = Some(format!(
                    "the posterior could not choose a batch ({reason}); the study's fixed design chooses the trials from now on"
                ));
                active.posterior = None;
            }
            let planned = schedule::fallback_batch(study, seed, &mut history, count);
            (planned, format!("fixed design: {reason}"))
        }
    };
    let trials: Vec<ScheduledTrial> = planned.iter().map(|planned| prepared.scheduled(planned)).collect();
    state
        .storage()
        .write(ActiveBatch {
            participant: participant.to_string(),
            first: existing + 1,
            trials,
            chosen_by,
            batch: history.batches as i64 - 1,
        })
        .await?;
    Ok(())
}

/// Stores a chosen batch as the participant's trials `first`, `first + 1`, …, unless trial
/// `first` exists already.
pub struct ActiveBatch {
    pub participant: String,
    pub first: i64,
    pub trials: Vec<ScheduledTrial>,
    pub chosen_by: String,
    pub batch: i64,
}

impl WriteJob for ActiveBatch {
    type Outcome = ();

    async fn run(&self, connection: &mut Connection) -> Result<(), sqlx::Error> {
        let taken: Option<i64> = sqlx::query_scalar("SELECT trial FROM trials WHERE participant = $1 AND trial = $2")
            .bind(&self.participant)
            .bind(self.first)
            .fetch_optional(&mut *connection)
            .await?;
        if taken.is_some() {
            return Ok(());
        }
        for (offset, trial) in self.trials.iter().enumerate() {
            let number = self.first + offset as i64;
            insert_trial(connection, &self.participant, number, trial, Some((&self.chosen_by, self.batch))).await?;
        }
        Ok(())
    }
}
