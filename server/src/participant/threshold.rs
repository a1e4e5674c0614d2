//! Threshold studies in the web survey (`kind = "threshold"`): a participant's next trial is
//! chosen when they reach it, by [`crate::threshold::next_trial`] from their seed and their own
//! answers so far, replayed from the database through a fresh QUEST+ — so the posterior is as
//! durable as the answers (each committed before its 201), and a reload, a second server or a
//! restart computes the same level. The chosen trial is stored by the active designs' write job
//! ([`super::active::ActiveBatch`]: nothing is added if another request stored it first), with
//! `chosen_by` = `quest+ <answers replayed>` and the trial's position as its batch.

use sqlx::Row;

use super::active::ActiveBatch;
use super::store::Position;
use crate::AppState;
use crate::error::{AppError, AppResult};
use crate::prepared::PreparedStudy;
use crate::render_queue::Unready;
use crate::study::GROUND_TRUTH;
use crate::threshold::Answer;
use crate::trial::{PlannedKind, PlannedTrial};

/// A level that is not there: 503 with `Retry-After` while it renders or the queue is full (the
/// page asks again), a logged internal error when its render failed.
fn unready(unready: Unready) -> AppError {
    match unready.retry_after_seconds() {
        Some(retry_after_seconds) => AppError::Rendering { retry_after_seconds },
        None => AppError::Internal(unready.to_string()),
    }
}

fn internal(error: sqlx::Error) -> AppError {
    AppError::Internal(format!("cannot read the participant's answers: {error}"))
}

/// The participant's answered threshold trials, in trial order (catch trials left out).
pub async fn answers(state: &AppState, prepared: &PreparedStudy, participant: &str) -> AppResult<Vec<Answer>> {
    let design = prepared.study.threshold.as_ref().ok_or_else(|| AppError::Internal("not a threshold study".into()))?;
    let rows = sqlx::query(
        "SELECT t.left_condition, t.right_condition, r.chosen FROM trials t
         JOIN responses r ON r.participant = t.participant AND r.trial = t.trial
         WHERE t.participant = $1 AND t.catch_expected IS NULL ORDER BY t.trial",
    )
    .bind(participant)
    .fetch_all(&state.storage().read)
    .await
    .map_err(internal)?;
    let mut answers = Vec::with_capacity(rows.len());
    for row in rows {
        let left: String = row.try_get("left_condition").map_err(internal)?;
        let right: String = row.try_get("right_condition").map_err(internal)?;
        let chosen: String = row.try_get("chosen").map_err(internal)?;
        let (shown, truth_side) = if left == GROUND_TRUTH { (right, "left") } else { (left, "right") };
        let Some(level) = design.level_of(&shown) else { continue };
        answers.push(Answer { level, correct: chosen == truth_side });
    }
    Ok(answers)
}

/// Chooses and stores the participant's next trial if it (`answered + 1`) has not been chosen
/// yet and they have trials left.
pub(crate) async fn extend(state: &AppState, prepared: &PreparedStudy, participant: &str) -> AppResult<()> {
    let study = &prepared.study;
    let read = &state.storage().read;
    let Position { seed, trials: total, answered } = Position::read(read, participant, internal).await?;
    let existing: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM trials WHERE participant = $1")
        .bind(participant)
        .fetch_one(read)
        .await
        .map_err(internal)?;
    if existing > answered || existing >= total {
        return Ok(()); // chosen already (another request), or nothing left to choose
    }
    let answers = answers(state, prepared, participant).await?;
    let chosen = crate::threshold::intensities(study, prepared.stimulus_metrics.as_ref())
        .map_err(|error| error.to_string())
        .and_then(|intensities| {
            crate::threshold::next_trial(study, seed, existing as usize, &intensities, &answers)
                .map_err(|error| error.to_string())
        })
        .map_err(|reason| AppError::Internal(format!("the next level cannot be chosen: {reason}")))?;
    let mut scheduled = prepared.scheduled(&chosen);
    if let PlannedKind::Pair { left, right } = chosen.kind
        && (scheduled.left_stimulus.is_empty() || scheduled.right_stimulus.is_empty())
    {
        // an on-demand level not rendered yet: the trial is stored only once its stimulus is
        // there, so the level shown is QUEST+'s (a reload asks again and gets the same level)
        let truth = study.conditions.len();
        let (level, scene, on_left) =
            if left == truth { (right, chosen.right_scene, false) } else { (left, chosen.left_scene, true) };
        let name = state
            .render_queue()
            .stimulus(&study.slug, scene, chosen.realisation, level, crate::render_queue::WAIT)
            .await
            .map_err(unready)?;
        if on_left {
            scheduled.left_stimulus = name;
        } else {
            scheduled.right_stimulus = name;
        }
    }
    state
        .storage()
        .write(ActiveBatch {
            participant: participant.to_string(),
            first: existing + 1,
            trials: vec![scheduled],
            chosen_by: format!("quest+ {}", answers.len()),
            batch: existing,
        })
        .await?;
    if crate::render_queue::on_demand(study) && (existing as usize) + 1 < total as usize {
        prefetch(state, prepared, seed, existing as usize + 1, &chosen, answers);
    }
    Ok(())
}

/// Queues, ahead of need, the levels trial `position` can show after the answer to `shown`
/// (two: one per answer; one after a catch trial, which QUEST+ does not see), so an on-demand
/// level is usually rendered before the participant asks for it. Off the request's path.
fn prefetch(
    state: &AppState,
    prepared: &PreparedStudy,
    seed: u64,
    position: usize,
    shown: &PlannedTrial,
    answers: Vec<Answer>,
) {
    let study = prepared.study.clone();
    let intensities = crate::threshold::intensities(&study, prepared.stimulus_metrics.as_ref());
    let truth = study.conditions.len();
    let shown_level = match shown.kind {
        PlannedKind::Pair { left, right } => Some(if left == truth { right } else { left }),
        PlannedKind::Catch { .. } => None,
    };
    let queue = state.render_queue().clone();
    tokio::task::spawn_blocking(move || {
        let Ok(intensities) = intensities else { return };
        let outcomes: Vec<Vec<Answer>> = match shown_level {
            Some(level) => {
                [true, false].map(|correct| answers.iter().copied().chain([Answer { level, correct }]).collect()).into()
            }
            None => vec![answers],
        };
        for answers in outcomes {
            let Ok(next) = crate::threshold::next_trial(&study, seed, position, &intensities, &answers) else {
                continue;
            };
            if let PlannedKind::Pair { left, right } = next.kind {
                let (level, scene) = if left == truth { (right, next.right_scene) } else { (left, next.left_scene) };
                queue.prefetch(&study.slug, scene, next.realisation, level);
            }
        }
    });
}
