//! The bridge to `mrstudy-analysis`: runs the analysis on a study's trials CSV and conditions
//! CSV, for the admin API and page, with the same options as `mrstudy analyze`'s defaults, so
//! the live analysis equals `mrstudy export` fed to `mrstudy analyze --conditions`.

use mrstudy_analysis::analysis::{Analysis, Options, analyze};

use crate::error::AppError;

fn analysis(trials_csv: &str, conditions_csv: &str) -> Result<Analysis, AppError> {
    analyze(trials_csv, Some(conditions_csv), &Options::default()).map_err(|error| {
        // No judgments yet, or a design the models cannot fit: the researcher sees why.
        AppError::Unprocessable(format!("The analysis cannot be run on the data so far: {error}."))
    })
}

/// The Analysis JSON of DESIGN.md.
pub fn run(trials_csv: &str, conditions_csv: &str) -> Result<serde_json::Value, AppError> {
    let analysis = analysis(trials_csv, conditions_csv)?;
    serde_json::to_value(&analysis).map_err(|error| AppError::Internal(format!("analysis JSON: {error}")))
}

/// The worth plot as SVG, drawn as `mrstudy analyze --plot` draws it.
pub fn worth_svg(trials_csv: &str, conditions_csv: &str) -> Result<String, AppError> {
    Ok(analysis(trials_csv, conditions_csv)?.worth_plot())
}
