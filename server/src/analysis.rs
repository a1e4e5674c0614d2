//! The bridge to `mrstudy-analysis`: runs the analysis on a study's trials CSV and conditions
//! CSV, for the admin API and page, with the same options as `mrstudy analyze`'s defaults, so
//! the live analysis equals `mrstudy export` fed to `mrstudy analyze --conditions`.

use mrstudy_analysis::analysis::{Analysis, Options, analyze};

use crate::error::AppError;
use crate::export::Include;

/// The analysis crate leaves pilot and excluded rows out by itself unless told to keep them;
/// the export already left out what `include` does not keep, so the two agree.
fn analysis(trials_csv: &str, conditions_csv: &str, include: Include) -> Result<Analysis, AppError> {
    let options = Options { include_pilots: include.pilots, include_excluded: include.excluded, ..Options::default() };
    analyze(trials_csv, Some(conditions_csv), &options).map_err(|error| {
        // No judgments yet, or a design the models cannot fit: the researcher sees why.
        AppError::Unprocessable(format!("The analysis cannot be run on the data so far: {error}."))
    })
}

/// The Analysis JSON of DESIGN.md.
pub fn run(trials_csv: &str, conditions_csv: &str, include: Include) -> Result<serde_json::Value, AppError> {
    let analysis = analysis(trials_csv, conditions_csv, include)?;
    serde_json::to_value(&analysis).map_err(|error| AppError::Internal(format!("analysis JSON: {error}")))
}

/// The worth plot as SVG, drawn as `mrstudy analyze --plot` draws it.
pub fn worth_svg(trials_csv: &str, conditions_csv: &str, include: Include) -> Result<String, AppError> {
    Ok(analysis(trials_csv, conditions_csv, include)?.worth_plot())
}
