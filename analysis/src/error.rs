//! The analysis crate's error type: one variant per way the input can be wrong, each carrying
//! the offending file, line, column or value so the message is one clear sentence.

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
    Active(#[from] crate::active::ActiveError),
}

pub type Result<T, E = AnalysisError> = std::result::Result<T, E>;
