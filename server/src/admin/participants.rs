//! The participants of a study (issue 12): their list with status and flags, exclude/include
//! (kept, with the reason), deletion of every datum of one participant, and preview links.

use super::stats::{Metrics, analysis_json};
use super::store;
use crate::AppState;
use crate::auth::{Admin, AdminChange};
use crate::error::{AppError, AppResult, Json};
use crate::export::{self, Include};
use axum::extract::{Path, State};
use axum::http::StatusCode;
use serde::{Deserialize, Serialize};

/// A participant's progress: answered trials of their schedule.
#[derive(Debug, Clone, Serialize)]
pub struct Progress {
    pub answered: i64,
    pub trials: i64,
}

/// What the researcher should look at before trusting a participant's judgments.
#[derive(Debug, Clone, Serialize)]
pub struct Flags {
    /// Responses faster than the study's `min_response_ms`.
    pub too_fast: i64,
    pub catch_answered: i64,
    pub catch_failed: i64,
    /// Flagged by the analysis's leave-one-out observer screening (choices unlikely under the
    /// consensus of the others); absent when the participant was not screened (left out of the
    /// analysis, no judgments, or screening not possible on the data so far).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub observer_flagged: Option<bool>,
}

/// One row of `GET /api/admin/studies/{slug}/participants`: a participant, or a visitor who was
/// screened out (whose `participant` is the screen-out's id, deletable the same way).
#[derive(Debug, Clone, Serialize)]
pub struct ParticipantEntry {
    pub participant: String,
    /// `completed`, `started`, `abandoned` or `screened-out`.
    pub status: &'static str,
    pub progress: Progress,
    pub external_ids: serde_json::Map<String, serde_json::Value>,
    pub completion_code: Option<String>,
    pub pilot: bool,
    pub excluded: bool,
    pub flags: Flags,
    /// 0, 1, 2, … in joining order (absent for a screen-out).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ordinal: Option<i64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exclusion_reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub excluded_at: Option<String>,
    /// The sentence a screened-out visitor was shown.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub screen_out_reason: Option<String>,
    pub joined_at: String,
    pub last_activity_at: String,
}

/// The participants of a study and then its screened-out visitors. `analysis` (the default
/// analysis JSON, if it could be run) gives the observer-screening flags.
pub async fn participants(
    state: &AppState,
    slug: &str,
    analysis: Option<&serde_json::Value>,
) -> AppResult<Vec<ParticipantEntry>> {
    let pool = &state.storage().admin;
    let definition = export::definition(pool, slug).await?;
    let mut screened = std::collections::HashMap::new();
    if let Some(observers) = analysis.and_then(|analysis| analysis["observers"]["participants"].as_array()) {
        for observer in observers {
            if let (Some(name), Some(flagged)) = (observer["participant"].as_str(), observer["flagged"].as_bool()) {
                screened.insert(name.to_string(), flagged);
            }
        }
    }
    let mut entries: Vec<ParticipantEntry> = export::participant_records(pool, slug, &definition)
        .await?
        .into_iter()
        .map(|record| ParticipantEntry {
            status: record.status,
            progress: Progress { answered: record.answered, trials: record.trials },
            external_ids: record.external_ids,
            completion_code: Some(record.completion_code),
            pilot: record.pilot,
            excluded: record.excluded,
            flags: Flags {
                too_fast: record.too_fast,
                catch_answered: record.catch_answered,
                catch_failed: record.catch_failed,
                observer_flagged: screened.get(&record.participant).copied(),
            },
            ordinal: Some(record.ordinal),
            exclusion_reason: record.exclusion_reason,
            excluded_at: record.excluded_at,
            screen_out_reason: None,
            joined_at: record.joined_at,
            last_activity_at: record.last_activity_at,
            participant: record.participant,
        })
        .collect();
    for row in store::screen_outs(pool, slug).await? {
        entries.push(ParticipantEntry {
            participant: row.id,
            status: "screened-out",
            progress: Progress { answered: 0, trials: 0 },
            external_ids: export::external_ids(&definition, &row.url_params),
            completion_code: None,
            pilot: row.pilot,
            excluded: false,
            flags: Flags { too_fast: 0, catch_answered: 0, catch_failed: 0, observer_flagged: None },
            ordinal: None,
            exclusion_reason: None,
            excluded_at: None,
            screen_out_reason: Some(row.reason),
            joined_at: row.created_at.clone(),
            last_activity_at: row.created_at,
        });
    }
    Ok(entries)
}

pub(super) async fn list_participants(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: Admin,
) -> AppResult<Json<Vec<ParticipantEntry>>> {
    // The observer flags come from the default analysis; a study whose data cannot be analysed
    // yet still lists its participants, without those flags.
    let analysis =
        match analysis_json(&state, &slug, Include::default(), Metrics::Skip, mrstudy_analysis::analysis::Scale::Bt)
            .await
        {
            Ok(analysis) => Some(analysis),
            Err(AppError::Unprocessable(_)) => None,
            Err(error) => return Err(error),
        };
    Ok(Json(participants(&state, &slug, analysis.as_ref()).await?))
}

#[derive(Deserialize)]
pub(super) struct ReasonBody {
    reason: Option<String>,
}

/// Longest exclusion reason kept, in characters.
pub const MAX_REASON_CHARS: usize = 500;

/// A refused admin write, as the researcher reads it.
impl From<store::AdminRefused> for AppError {
    fn from(refused: store::AdminRefused) -> Self {
        match refused {
            store::AdminRefused::UnknownParticipant { id } => {
                AppError::NotFound(format!("There is no participant \"{}\".", id.chars().take(64).collect::<String>()))
            }
            store::AdminRefused::UnknownStudy { slug } => AppError::NotFound(format!("There is no study \"{slug}\".")),
        }
    }
}

/// The participant after an exclude or include.
#[derive(Serialize)]
pub(super) struct ExclusionState {
    participant: String,
    excluded: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    exclusion_reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    excluded_at: Option<String>,
}

pub(super) async fn set_excluded(
    state: &AppState,
    id: String,
    reason: Option<String>,
) -> AppResult<Json<ExclusionState>> {
    let written =
        state.storage().admin_write(store::AdminWrite::SetExcluded { participant: id.clone(), reason }).await??;
    match written {
        store::AdminWritten::Excluded { excluded, reason, excluded_at, .. } => {
            Ok(Json(ExclusionState { participant: id, excluded, exclusion_reason: reason, excluded_at }))
        }
        _ => Err(AppError::Internal("an exclusion had no exclusion outcome".into())),
    }
}

pub(super) async fn exclude_participant(
    State(state): State<AppState>,
    Path(id): Path<String>,
    _: AdminChange,
    Json(body): Json<ReasonBody>,
) -> AppResult<Json<ExclusionState>> {
    let reason = body.reason.map(|reason| reason.trim().to_string()).unwrap_or_default();
    if reason.is_empty() {
        return Err(AppError::Unprocessable(
            "Excluding a participant needs a reason: send {\"reason\": \"…\"}.".into(),
        ));
    }
    if reason.chars().count() > MAX_REASON_CHARS {
        return Err(AppError::Unprocessable(format!(
            "The reason must be at most {MAX_REASON_CHARS} characters, found {}.",
            reason.chars().count()
        )));
    }
    set_excluded(&state, id, Some(reason)).await
}

/// Includes an excluded participant again; a body, if any, is not read.
pub(super) async fn include_participant(
    State(state): State<AppState>,
    Path(id): Path<String>,
    _: AdminChange,
) -> AppResult<Json<ExclusionState>> {
    set_excluded(&state, id, None).await
}

pub(super) async fn delete_participant(
    State(state): State<AppState>,
    Path(id): Path<String>,
    _: AdminChange,
) -> AppResult<Json<store::Deletion>> {
    let deletion = state.storage().delete(&id).await??;
    state.forget_credentials(&id);
    Ok(Json(deletion))
}

#[derive(Serialize)]
pub(super) struct PreviewLink {
    url: String,
    /// When the link stops letting pilots join ([`crate::storage::PREVIEW_LINK_DAYS`] from now).
    expires_at: String,
}

/// A new preview link: a random 256-bit token, stored as its SHA-256 in `previews`; a participant
/// who joins with it (`preview` in the join body) is a pilot, for
/// [`crate::storage::PREVIEW_LINK_DAYS`] days or until the study's links are revoked.
pub(super) async fn create_preview(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: AdminChange,
) -> AppResult<(StatusCode, Json<PreviewLink>)> {
    let kind = store::study_kind(&state.storage().admin, &slug).await?;
    // a lab task study's preview opens its lab page; its participants are pilots too
    let page = match kind.as_deref() {
        None => return Err(AppError::NotFound(format!("There is no study \"{slug}\"."))),
        Some("task") => "lab",
        Some(_) => "studies",
    };
    let token = crate::random_hex(32);
    state
        .storage()
        .admin_write(store::AdminWrite::Preview {
            study: slug.clone(),
            token_sha256: crate::auth::sha256(token.as_bytes()).to_vec(),
        })
        .await??;
    let valid = std::time::Duration::from_secs(crate::storage::PREVIEW_LINK_DAYS * 86_400);
    let expires_at = crate::storage::iso(std::time::SystemTime::now() + valid);
    Ok((StatusCode::CREATED, Json(PreviewLink { url: format!("/{page}/{slug}?preview={token}"), expires_at })))
}

#[derive(Serialize)]
pub(super) struct Revoked {
    revoked: u64,
}

/// Revokes every preview link of the study: joining with one is refused from now on (pilots who
/// joined keep their run).
pub(super) async fn revoke_previews(
    State(state): State<AppState>,
    Path(slug): Path<String>,
    _: AdminChange,
) -> AppResult<Json<Revoked>> {
    if store::study_kind(&state.storage().admin, &slug).await?.is_none() {
        return Err(AppError::NotFound(format!("There is no study \"{slug}\".")));
    }
    match state.storage().admin_write(store::AdminWrite::RevokePreviews { study: slug }).await?? {
        store::AdminWritten::PreviewsRevoked(revoked) => Ok(Json(Revoked { revoked })),
        _ => Err(AppError::Internal("a revocation had no revocation outcome".into())),
    }
}

/// One row of the page's participants table, as text.
pub struct ParticipantLine {
    pub id: String,
    pub label: String,
    pub status: &'static str,
    pub progress: String,
    pub external_ids: String,
    pub completion_code: String,
    pub flags: Vec<String>,
    pub pilot: bool,
    pub excluded: bool,
    pub exclusion_reason: String,
    pub screened_out: bool,
}

impl From<&ParticipantEntry> for ParticipantLine {
    fn from(entry: &ParticipantEntry) -> Self {
        let mut flags = Vec::new();
        if entry.flags.too_fast > 0 {
            flags.push(format!("{} too fast", entry.flags.too_fast));
        }
        if entry.flags.catch_failed > 0 {
            flags.push(format!("catch failed {} of {}", entry.flags.catch_failed, entry.flags.catch_answered));
        }
        if entry.flags.observer_flagged == Some(true) {
            flags.push("unlike the others (observer screening)".into());
        }
        if let Some(reason) = &entry.screen_out_reason {
            flags.push(reason.clone());
        }
        ParticipantLine {
            id: entry.participant.clone(),
            label: match entry.ordinal {
                Some(ordinal) => format!("#{ordinal}"),
                None => "visitor".into(),
            },
            status: entry.status,
            progress: if entry.screen_out_reason.is_some() {
                "–".into()
            } else {
                format!("{}/{}", entry.progress.answered, entry.progress.trials)
            },
            external_ids: entry
                .external_ids
                .iter()
                .map(|(name, value)| {
                    format!("{name}={}", value.as_str().map(str::to_string).unwrap_or_else(|| value.to_string()))
                })
                .collect::<Vec<_>>()
                .join(", "),
            completion_code: entry.completion_code.clone().unwrap_or_default(),
            flags,
            pilot: entry.pilot,
            excluded: entry.excluded,
            exclusion_reason: entry.exclusion_reason.clone().unwrap_or_default(),
            screened_out: entry.screen_out_reason.is_some(),
        }
    }
}
