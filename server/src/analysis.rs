//! The bridge to `mrstudy-analysis`: runs the analysis on a study's trials CSV and conditions
//! CSV, for the admin API and page, with the same options as `mrstudy analyze`'s defaults, so
//! the live analysis equals `mrstudy export` fed to `mrstudy analyze --conditions`.

use mrstudy_analysis::analysis::{Analysis, Options, analyze};
use mrstudy_analysis::plot::{WorthPoint, WorthSeries};

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

/// The worth plot as SVG: the log-worth of each condition with 95 % Wald intervals, drawn as
/// `mrstudy analyze --plot` draws it.
pub fn worth_svg(trials_csv: &str, conditions_csv: &str) -> Result<String, AppError> {
    let analysis = analysis(trials_csv, conditions_csv)?;
    let conditions: Vec<String> = analysis.items.iter().map(|item| item.condition.clone()).collect();
    let series_of = |name: &str, analysis: &Analysis| WorthSeries {
        name: name.to_string(),
        points: analysis
            .items
            .iter()
            .filter_map(|item| {
                let log_worth = item.log_worth?;
                let (low, high) = match (item.ci, item.se) {
                    (Some([low, high]), _) => (Some(low), Some(high)),
                    (None, Some(se)) if se > 0.0 => (Some(log_worth - 1.96 * se), Some(log_worth + 1.96 * se)),
                    _ => (None, None),
                };
                Some(WorthPoint { condition: item.condition.clone(), log_worth, low, high })
            })
            .collect(),
    };
    let series = vec![series_of("all", &analysis)];
    let title = format!("Worth of each condition (log scale, reference {}), 95 % intervals", analysis.reference);
    Ok(mrstudy_analysis::plot::worth_plot(&title, &conditions, &series))
}
