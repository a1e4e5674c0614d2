//! The analysis crate's error types — `AnalysisError`, and `ActiveError` of active pair
//! selection (here so that `active` depends on `error`, not the other way round): one variant
//! per way the input can be wrong, each carrying the offending file, line, column or value so
//! the message is one clear sentence.

use thiserror::Error;

/// Everything that can go wrong in an analysis. Bad input never panics; it becomes one of these.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum AnalysisError {
    /// A CSV file could not be parsed as CSV.
    #[error("{source_name}: line {line}: {message}")]
    MalformedCsv { source_name: String, line: u64, message: String },
    /// A required column is missing from a CSV header.
    #[error("{source_name}: the header has no column `{column}` (it has: {found})")]
    MissingColumn { source_name: String, column: String, found: String },
    /// A cell holds a value that is not allowed there.
    #[error("{source_name}: line {line}, column `{column}`: {message}")]
    BadValue { source_name: String, line: u64, column: String, message: String },
    /// A condition appears twice in a conditions file.
    #[error("{source_name}: line {line}: condition `{condition}` is listed twice (first on line {first_line})")]
    DuplicateCondition { source_name: String, line: u64, condition: String, first_line: u64 },
    /// A row repeats what an earlier row of the same file gave (e.g. a metric of a stimulus).
    #[error("{source_name}: line {line}: {what} is listed twice (first on line {first_line})")]
    DuplicateRow { source_name: String, line: u64, what: String, first_line: u64 },
    /// A condition of the trials is not in the conditions file.
    #[error("{source_name}: line {line}: condition `{condition}` is not in the conditions file")]
    UnknownCondition { source_name: String, line: u64, condition: String },
    /// The input holds no usable data.
    #[error("{0}")]
    Empty(String),
    /// A model formula names something that does not exist or is malformed.
    #[error("model `{formula}`: {message}")]
    BadModel { formula: String, message: String },
    /// An option value is out of range.
    #[error("{option}: {message}")]
    BadOption { option: String, message: String },
    /// Active pair selection refused its input or lost its posterior.
    #[error(transparent)]
    Active(#[from] ActiveError),
}

pub type Result<T, E = AnalysisError> = std::result::Result<T, E>;

/// Why active selection could not answer. Bad input names the value; `Degenerate` is the
/// signal to fall back to a fixed design.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ActiveError {
    /// Fewer than three conditions: there is at most one pair, nothing to choose.
    #[error("active pair selection needs at least 3 conditions, got {conditions}")]
    TooFewConditions { conditions: usize },
    /// A batch of zero trials was asked for.
    #[error("a batch of 0 trials was asked for; ask for at least one trial")]
    NoTrials,
    /// A judgment or pair names a condition index out of range.
    #[error("condition {condition} does not exist (the study has conditions 0 to {})", .conditions - 1)]
    UnknownCondition { condition: usize, conditions: usize },
    /// A judgment compares a condition with itself.
    #[error("a judgment compares condition {condition} with itself")]
    SameCondition { condition: usize },
    /// A factor named for the factor target is not a column of the conditions table.
    #[error("`{factor}` is not a factor of the conditions (factors: {factors})")]
    UnknownFactor { factor: String, factors: String },
    /// The condition × factor design matrix cannot be used.
    #[error("the factor design cannot be used: {message}")]
    BadDesign { message: String },
    /// An option is out of range.
    #[error("{option}: {message}")]
    BadOption { option: &'static str, message: String },
    /// The posterior is no longer usable (non-finite, or a variance not positive): fall back
    /// to the fixed design and warn.
    #[error("the active-selection posterior after {judgments} judgments is unusable ({message}); use the fixed design")]
    Degenerate { judgments: u64, message: String },
}
