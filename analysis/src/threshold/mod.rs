//! Threshold studies (issue 48): at what setting of a rendering knob does the difference from
//! the reference stop being visible.
//!
//! - [`quest`]: QUEST+ (Watson 2017) as the `questplus` package 2023.1 runs it — the level of
//!   each trial by minimum expected entropy over a grid posterior; the server keeps one per
//!   participant and rebuilds it from the stored answers.
//!
//! The crate's rule holds: no IO; bad input is a [`ThresholdError`] naming the offending value.

pub mod at_threshold;
pub mod fit;
pub mod quest;
pub mod report;

pub use quest::{IntensityRule, Params, PsychFunction, QuestPlus, QuestPlusConfig, StimScale, StimulusDomain};

use thiserror::Error;

/// Why a threshold model or run cannot be set up or continued; each variant names the value.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ThresholdError {
    /// A name (function, scale, intensity rule) is not one of the known ones.
    #[error("{what} `{value}` is not known (expected one of: {expected})")]
    UnknownName { what: &'static str, value: String, expected: String },
    /// A grid or list is empty.
    #[error("the {grid} grid is empty; give at least one value")]
    EmptyGrid { grid: &'static str },
    /// A value is NaN or infinite.
    #[error("{grid} value {index} is not a finite number ({value})")]
    NonFinite { grid: &'static str, index: usize, value: f64 },
    /// A list that must be strictly increasing is not.
    #[error(
        "{grid} must be strictly increasing, but value {index} ({value}) does not exceed the one before it ({previous})"
    )]
    NotIncreasing { grid: &'static str, index: usize, value: f64, previous: f64 },
    /// A value that must be positive is not.
    #[error("{what} {value} must be positive: {why}")]
    NotPositive { what: &'static str, value: f64, why: &'static str },
    /// A value lies outside its allowed range.
    #[error("{what} {value} is out of range: it must be {expected}")]
    OutOfRange { what: &'static str, value: f64, expected: &'static str },
    /// Two lists that go together differ in length.
    #[error("{what} has {got} values but there are {expected} levels")]
    LengthMismatch { what: &'static str, got: usize, expected: usize },
    /// The threshold grid lies entirely outside the stimuli's x range.
    #[error(
        "the threshold grid [{low}, {high}] does not meet the stimuli's range [{x_low}, {x_high}] (x units); no level could find such a threshold"
    )]
    GridOutsideStimuli { low: f64, high: f64, x_low: f64, x_high: f64 },
    /// An answer names a stimulus index outside the domain.
    #[error("stimulus {index} does not exist (the domain has {stimuli} stimuli)")]
    UnknownStimulus { index: usize, stimuli: usize },
    /// An answer has probability zero under every grid point left (e.g. incorrect where every
    /// remaining model says correct with certainty).
    #[error("answer {answers} ({outcome} at stimulus {index}) is impossible under every remaining grid point; widen the lapse grid", outcome = if *correct { "correct" } else { "incorrect" })]
    ImpossibleAnswer { index: usize, correct: bool, answers: usize },
    /// A stored posterior is not what replaying its answers gives.
    #[error("the stored posterior differs from the replay of its {answers} answers")]
    PosteriorMismatch { answers: usize },
}

#[cfg(test)]
mod fit_tests;
#[cfg(test)]
mod tests;
