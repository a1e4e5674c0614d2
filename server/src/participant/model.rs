//! The participant, one person taking part in a study, in each of its stages — joining, stored,
//! listed and exported — for paired-comparison studies (the web survey) and lab task studies.
//! The SQL that writes and reads them stays with its module: [`super::store`] (paired
//! comparisons), `crate::lab::store` and `crate::lab::results` (lab), `crate::export`. The
//! admin's participant list rows (`ParticipantEntry`, `ParticipantLine`) are the admin page's:
//! they add the analysis's observer flags and the page's wording to a [`ParticipantRecord`].

use std::sync::Arc;

use serde_json::{Map, Value};

use crate::prepared::PreparedStudy;
use crate::study::task::TaskStudy;

/// Joining, paired comparisons: a participant to create (the `participants` row and the
/// schedule), with the parts that do not depend on the seed.
#[derive(Debug)]
pub struct NewParticipant {
    pub study: Arc<PreparedStudy>,
    pub id: String,
    pub token_sha256: Vec<u8>,
    /// A random seed, used when the study has no study seed.
    pub random_seed: u64,
    pub demographics: String,
    pub client: String,
    pub url_params: String,
    /// Used when the study has no fixed completion code.
    pub random_completion_code: String,
    /// Joined through an admin preview link.
    pub pilot: bool,
    /// The external id when the study keeps one run per external id: a participant already
    /// stored with it is resumed instead of created, if the join proves it is that run.
    pub external_key: Option<String>,
    /// SHA-256 of the token the page kept from its earlier join, if any: the proof that resumes
    /// the run of `external_key` (which keeps its token; nobody else's join changes it).
    pub resume_token_sha256: Option<Vec<u8>>,
    /// A screen-out of this visitor to withdraw (they now meet the requirements and joined).
    pub withdraw_screen_out: Option<String>,
}

/// Stored, paired comparisons: a participant as the participant API reads them back from
/// `participants` (`Storage::participant`, `Storage::participant_with_next`).
#[derive(Debug, Clone)]
pub struct ParticipantRow {
    pub id: String,
    pub study: String,
    pub token_sha256: Vec<u8>,
    pub trials: i64,
    pub answered: i64,
    pub completion_code: String,
    pub completed: bool,
    pub url_params: String,
}

/// Exported: a participant as the admin list and the exports see them (paired comparisons;
/// `crate::export::participant_records` reads them).
#[derive(Debug, Clone, serde::Serialize)]
pub struct ParticipantRecord {
    pub participant: String,
    pub ordinal: i64,
    /// `completed`, `started` or `abandoned`.
    pub status: &'static str,
    pub trials: i64,
    pub answered: i64,
    pub completion_code: String,
    pub pilot: bool,
    pub excluded: bool,
    pub exclusion_reason: Option<String>,
    pub excluded_at: Option<String>,
    /// The study's `url_params` the participant arrived with, in the study's order.
    pub external_ids: Map<String, Value>,
    pub joined_at: String,
    pub completed_at: Option<String>,
    /// The last join, trial served or response.
    pub last_activity_at: String,
    /// Responses flagged `too_fast`.
    pub too_fast: i64,
    pub catch_answered: i64,
    pub catch_failed: i64,
}

/// Joining, lab: a task participant to create (the `task_participants` row and the task
/// schedule, planned in the scene layout the write carries).
#[derive(Debug)]
pub struct NewTaskParticipant {
    pub study: Arc<TaskStudy>,
    pub id: String,
    pub label: String,
    pub token_sha256: Vec<u8>,
    /// Used when the study has no seed.
    pub random_seed: u64,
    /// Joined through an admin preview link.
    pub pilot: bool,
    /// The frame time every frame of this participant is held to (`pace = "equal"`), fixed now
    /// for all its sessions; None when not paced.
    pub pace_ms: Option<f64>,
}

/// Stored, lab: a task participant as read back from `task_participants`.
#[derive(Debug, Clone)]
pub struct TaskParticipantRow {
    pub id: String,
    pub study: String,
    pub ordinal: i64,
    pub slot: i64,
    pub label: String,
    pub token_sha256: Vec<u8>,
    pub trials: i64,
    pub answered: i64,
    pub completed: bool,
    pub abandoned: bool,
    pub pilot: bool,
    /// The participant's fixed pace (see [`NewTaskParticipant::pace_ms`]).
    pub pace_ms: Option<f64>,
}

/// Listed, lab: a task participant's progress as the lab results list it (admin lab page and
/// its JSON).
#[derive(serde::Serialize)]
pub struct ParticipantProgress {
    pub participant: String,
    pub label: String,
    pub ordinal: i64,
    /// Counterbalancing slot (the row of the design the condition order comes from).
    pub slot: i64,
    pub condition_order: String,
    pub answered: i64,
    pub trials: i64,
    pub completed: bool,
    /// The slot was given to another participant after `abandon_after_minutes` without activity.
    pub abandoned: bool,
    /// Joined through a preview link.
    pub pilot: bool,
    pub excluded: bool,
    pub exclusion_reason: Option<String>,
    /// The frame time this participant's frames are held to (`pace = "equal"`), ms.
    pub pace_ms: Option<f64>,
    /// Frames of answered trials, and those that reached the participant late (more than
    /// `session::LATE_TOLERANCE` after the pace).
    pub frames: i64,
    pub frames_late: i64,
    /// Whether at most `session::LATE_SHARE` of the frames were late; None when not paced or
    /// no frame yet.
    pub pace_kept: Option<bool>,
}
