//! The bridge to `mrstudy-analysis`: runs the analysis on a study's trials CSV with the study's
//! conditions (as the analysis's condition table, not CSV text parsed again), for the admin API
//! and page, with the same options as `mrstudy analyze`'s defaults, so the live analysis equals
//! `mrstudy export` fed to `mrstudy analyze --conditions`.

use mrstudy_analysis::analysis::{Analysis, Options, analyze_with_table};
use mrstudy_analysis::data::ConditionTable;

use crate::error::AppError;
use crate::export::Include;
use crate::study::Study;

/// The study's conditions as the analysis reads them (the conditions CSV of DESIGN.md).
pub fn condition_table(study: &Study) -> ConditionTable {
    ConditionTable {
        conditions: study.conditions.iter().map(|condition| condition.name.clone()).collect(),
        factors: study.factors.iter().map(|factor| factor.name.clone()).collect(),
        levels: study.conditions.iter().map(|condition| condition.levels.clone()).collect(),
    }
}

/// The analysis crate leaves pilot and excluded rows out by itself unless told to keep them;
/// the export already left out what `include` does not keep, so the two agree.
fn analysis(trials_csv: &str, study: &Study, include: Include) -> Result<Analysis, AppError> {
    let options = Options { include_pilots: include.pilots, include_excluded: include.excluded, ..Options::default() };
    analyze_with_table(trials_csv, "trials CSV", Some(&condition_table(study)), &options).map_err(|error| {
        // No judgments yet, or a design the models cannot fit: the researcher sees why.
        AppError::Unprocessable(format!("The analysis cannot be run on the data so far: {error}."))
    })
}

/// The Analysis JSON of DESIGN.md.
pub fn run(trials_csv: &str, study: &Study, include: Include) -> Result<serde_json::Value, AppError> {
    let analysis = analysis(trials_csv, study, include)?;
    serde_json::to_value(&analysis).map_err(|error| AppError::Internal(format!("analysis JSON: {error}")))
}

/// The worth plot as SVG, drawn as `mrstudy analyze --plot` draws it.
pub fn worth_svg(trials_csv: &str, study: &Study, include: Include) -> Result<String, AppError> {
    Ok(analysis(trials_csv, study, include)?.worth_plot())
}
