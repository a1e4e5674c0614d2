//! Trial concepts shared by the schedule, storage and the participant API: the two sides of a
//! paired-comparison trial, and what answering a trial did or why it was refused.

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
