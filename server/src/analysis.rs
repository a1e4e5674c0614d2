//! The bridge to `mrstudy-analysis`: runs the analysis on an exported trials CSV and the
//! study's conditions CSV, for the admin API and page.

use crate::error::AppError;

/// The Analysis JSON of DESIGN.md.
pub fn run(trials_csv: &str, conditions_csv: &str) -> Result<serde_json::Value, AppError> {
    let _ = (trials_csv, conditions_csv);
    Err(AppError::Unavailable("analysis not available".into()))
}

/// The worth plot as SVG.
pub fn worth_svg(trials_csv: &str, conditions_csv: &str) -> Result<String, AppError> {
    let _ = (trials_csv, conditions_csv);
    Err(AppError::Unavailable("analysis not available".into()))
}
