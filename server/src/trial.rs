//! The trial, one screen shown to a participant, in each of its stages — the vocabulary the
//! schedule, the participant API (paired comparisons, active and threshold designs), storage and
//! the lab build on:
//!
//! - planned: [`PlannedTrial`] (a paired-comparison schedule, by indices) and
//!   [`PlannedTaskTrial`] (a lab task schedule);
//! - served: [`ScheduledTrial`] (with its stimuli, as written to `trials`) and [`TrialRow`]
//!   (read back from `trials` to serve again); the two sides are [`Side`]s;
//! - answered: a [`Choice`], what storing it did ([`ResponseOutcome`]) or why it was refused
//!   ([`ResponseRefused`]); in the lab a [`TrialResult`].
//!
//! A catch trial as the study file defines it (images, repetitions) is part of the study:
//! `crate::study::CatchTrial`.

use serde::Serialize;

use crate::study::task::{Condition, TaskKind};

/// A side of a paired-comparison trial: where a stimulus is shown (an answer is a [`Choice`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Left,
    Right,
}

impl Side {
    pub fn as_str(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }
}

/// A participant's answer to a paired comparison: one side, or "not sure" where the study
/// allows it (`allow_tie = true`; stored and exported as `tie`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Choice {
    Left,
    Right,
    Tie,
}

impl Choice {
    pub fn as_str(self) -> &'static str {
        match self {
            Choice::Left => "left",
            Choice::Right => "right",
            Choice::Tie => "tie",
        }
    }
}

/// What a response answers: a paired comparison's [`Choice`], or a rating study's rating (1 to 5,
/// 5 the best; `crate::rating`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    Choice(Choice),
    Rating(u8),
}

impl Answer {
    /// `responses.chosen` and `responses.rating`: exactly one is set.
    pub fn columns(self) -> (Option<&'static str>, Option<i64>) {
        match self {
            Answer::Choice(choice) => (Some(choice.as_str()), None),
            Answer::Rating(rating) => (None, Some(i64::from(rating))),
        }
    }
}

/// What storing a response did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResponseOutcome {
    /// Stored now (`201`).
    Created,
    /// The same answer was already stored (`200`).
    Repeated,
}

/// Why a response was refused; nothing was stored.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum ResponseRefused {
    /// The trial was never served to the participant; `next` is their next trial.
    NeverServed {
        trial: i64,
        next: i64,
    },
    /// The trial was already answered with another choice.
    AlreadyAnswered {
        trial: i64,
        chosen: String,
    },
    UnknownParticipant,
    /// The participant no longer answers to this token (deleted, or the token is not theirs): the
    /// database's word, whatever a server's memory says.
    NotYours,
    /// The trial is not in the participant's schedule of `trials` trials.
    OutOfRange {
        trial: i64,
        trials: i64,
    },
    /// The trial is later than the participant's next trial, `next`.
    NotYet {
        trial: i64,
        next: i64,
    },
}

/// Planned: one trial of a paired-comparison schedule (`schedule::plan`), by indices
/// into the study's conditions and scene configurations, before stimuli are attached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlannedTrial {
    pub kind: PlannedKind,
    pub left_scene: usize,
    pub right_scene: usize,
    /// The sensor-noise realisation of the scene configuration shown (both sides): 0 except in
    /// a detection design with `realisations` > 1.
    pub realisation: usize,
}

/// What a [`PlannedTrial`] shows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PlannedKind {
    /// Condition indices shown left and right.
    Pair { left: usize, right: usize },
    /// Catch trial `index`; `better_left` says on which side the better image is.
    Catch { index: usize, better_left: bool },
}

/// Served: one trial of a participant's schedule with its stimuli, as written to the `trials`
/// table at join (or when an active or threshold design chooses it) and served from there: the
/// conditions and scene configurations by name, the stimulus files by content hash.
#[derive(Debug, Clone)]
pub struct ScheduledTrial {
    pub left_condition: String,
    pub right_condition: String,
    pub left_scene: String,
    pub right_scene: String,
    pub left_stimulus: String,
    pub right_stimulus: String,
    pub catch_expected: Option<Side>,
    /// A rating study's catch trial: its expected rating (`crate::rating`; a rating trial keeps
    /// the rated stimulus on the left, DCR's reference on the right, empty without one).
    pub catch_rating: Option<u8>,
}

/// Stored, read back: a trial of the `trials` table as the participant API serves it again
/// (its number, its two stimulus files, whether it was served already).
#[derive(Debug, Clone)]
pub struct TrialRow {
    pub trial: i64,
    pub left_stimulus: String,
    pub right_stimulus: String,
    /// Whether the trial has been served (its `shown_at` is set).
    pub shown: bool,
}

/// Planned, lab: one trial of a participant's task schedule (`lab::plan::plan`), as
/// stored in `task_trials` at join and served by the lab session.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedTaskTrial {
    /// 1-based position in the schedule.
    pub trial: u32,
    pub task: String,
    pub kind: TaskKind,
    pub condition: Condition,
    pub practice: bool,
    /// The virtual cube's centre when the trial starts (metres).
    pub start: [f64; 3],
    /// Where the virtual cube's centre should end (`placement`, `contact`); for `distance` the
    /// cube does not move and this is its position.
    pub target: [f64; 3],
}

/// Answered, lab: the result of one task trial as the lab session measured it, stored in
/// `task_trials` (the judgment of a paired comparison is a [`Choice`] instead).
#[derive(Debug, Clone)]
pub struct TrialResult {
    pub participant: String,
    pub trial: u32,
    pub answer_cm: Option<f64>,
    pub final_position: Option<[f64; 3]>,
    pub error_cm: f64,
    pub signed_error_cm: Option<f64>,
    /// Signed per-axis error (x, y, z) in cm.
    pub error_axes_cm: [f64; 3],
    pub completion_ms: f64,
    /// JSON array.
    pub key_log: String,
    pub frames: u32,
    pub frame_ms_mean: Option<f64>,
    pub frame_ms_max: Option<f64>,
    /// Frames the page reported shown.
    pub frames_shown: u32,
    /// Per frame, request → sent (rendering, queueing, pacing), mean over the trial, ms.
    pub shown_frame_ms_mean: Option<f64>,
    /// The frame time frames were paced to (`pace = "equal"`), ms.
    pub paced_ms: Option<f64>,
    /// Frames that reached the participant more than the lab session's `LATE_TOLERANCE` later
    /// than the pace (0 when not paced).
    pub frames_late: u32,
    /// When the page reported the trial's first frame shown (UTC, ISO 8601 with ms).
    pub shown_at: String,
    pub latency_ms_mean: Option<f64>,
    pub latency_ms_p95: Option<f64>,
    pub smoothing: bool,
    pub adapter: String,
    /// When the trial's first frame was sent (UTC, ISO 8601 with ms).
    pub started_at: String,
}
