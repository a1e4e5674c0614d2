//! A lab participant is created over HTTP before its WebSocket session starts
//! (`POST /api/lab/{slug}/participants`, body `{label, preview?}` → `201 {participant, token,
//! trials}`), under the survey's join rules: a closed study accepts no one but pilots (who come
//! with an admin preview link's token), and the joins of one client address are limited by the
//! same bucket as the survey's joins ([`crate::limits`], `serve --join-limit`). The session then
//! starts with `{"type": "start", "participant", "token"}`; a WebSocket alone can create no
//! participant and take no counterbalancing slot.
//!
//! The participant's schedule, counterbalancing slot and pace (the frame time every frame of
//! theirs is held to with `pace = "equal"`, fixed now for all their sessions) are stored in one
//! write ([`super::store`]).

use axum::extract::{Path, State};
use axum::http::StatusCode;
use serde::{Deserialize, Serialize};

use super::store::{TaskWrite, TaskWritten};
use crate::AppState;
use crate::error::{AppError, AppResult, Json};
use crate::participant::model::NewTaskParticipant;

/// Longest participant code, in characters.
pub const MAX_LABEL_CHARS: usize = 64;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct JoinBody {
    /// The participant code the experimenter gave.
    label: String,
    /// The token of an admin preview link: the participant is a pilot.
    #[serde(default)]
    preview: Option<String>,
}

#[derive(Serialize)]
pub(crate) struct Joined {
    participant: String,
    token: String,
    trials: usize,
    pilot: bool,
}

/// The participant code, trimmed, or why it is refused.
pub fn check_label(label: &str) -> Result<String, LabelError> {
    let label = label.trim();
    if label.is_empty() {
        return Err(LabelError::Empty);
    }
    if label.chars().count() > MAX_LABEL_CHARS || label.chars().any(char::is_control) {
        return Err(LabelError::Unusable { chars: label.chars().count() });
    }
    Ok(label.to_string())
}

/// Why a participant code was refused (the sentence the lab page shows).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LabelError {
    #[error("The participant code is empty; type the code the experimenter gave you, then start.")]
    Empty,
    /// Longer than [`MAX_LABEL_CHARS`] (`chars` long), or with control characters.
    #[error("The participant code must be at most {MAX_LABEL_CHARS} characters without control characters.")]
    Unusable { chars: usize },
}

pub(crate) async fn create_participant(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    Json(body): Json<JoinBody>,
) -> AppResult<(StatusCode, Json<Joined>)> {
    let lab = state
        .lab()
        .ok_or_else(|| AppError::NotFound(format!("There is no task study \"{slug}\" (no lab studies are served).")))?;
    let study = lab
        .studies
        .get(&slug)
        .cloned()
        .ok_or_else(|| AppError::NotFound(format!("There is no task study \"{slug}\".")))?;
    let pilot = match body.preview.as_deref().map(str::trim).filter(|token| !token.is_empty()) {
        None => false,
        Some(token) if state.storage().is_preview(&slug, &crate::auth::sha256(token.as_bytes())).await? => true,
        Some(_) => {
            return Err(AppError::Forbidden(format!(
                "This preview link is not valid for the study \"{slug}\"; ask the researcher for a new one."
            )));
        }
    };
    // a preview runs the study as a participant would, also before the study is opened
    if !pilot && !state.storage().is_open(&slug).await? {
        return Err(AppError::Forbidden(format!("The study \"{slug}\" is closed and accepts no new participants.")));
    }
    let label = check_label(&body.label).map_err(|error| AppError::Unprocessable(error.to_string()))?;
    let token = crate::random_hex(32);
    let id = crate::random_hex(16);
    let mut seed_bytes = [0u8; 8];
    getrandom::fill(&mut seed_bytes).map_err(|error| AppError::Internal(format!("no random seed: {error}")))?;
    let written = state
        .storage()
        .write(TaskWrite::Participant {
            participant: NewTaskParticipant {
                study: study.study.clone(),
                id: id.clone(),
                label,
                token_sha256: crate::auth::sha256(token.as_bytes()).to_vec(),
                random_seed: u64::from_le_bytes(seed_bytes),
                pilot,
                pace_ms: study.pace_ms(),
            },
            layout: study.layout,
        })
        .await??;
    let TaskWritten::Participant { trials, .. } = written else {
        return Err(AppError::Internal("creating a lab participant wrote something else".into()));
    };
    Ok((StatusCode::CREATED, Json(Joined { participant: id, token, trials: trials.len(), pilot })))
}
