//! The bridge to `mrstudy-analysis`: runs the analysis on a study's trials CSV with the study's
//! conditions (as the analysis's condition table, not CSV text parsed again), for the admin API
//! and page, with the same options as `mrstudy analyze`'s defaults and the study's `prior_sd`, so
//! the live analysis equals `mrstudy export` fed to `mrstudy analyze --conditions --prior-sd`.

use mrstudy_analysis::AnalysisError;
use mrstudy_analysis::analysis::{Options, Scale};
use mrstudy_analysis::data::ConditionTable;
use mrstudy_analysis::report::{Report, analyze_with_table};
use mrstudy_analysis::stimulus_metrics::{StimulusMetrics, StimulusOptions, analyze_stimuli};

use crate::error::AppError;
use crate::export::Include;
use crate::study::Study;

/// The study's conditions as the analysis reads them (the conditions CSV of docs/design.md).
pub fn condition_table(study: &Study) -> ConditionTable {
    ConditionTable {
        conditions: study.conditions.iter().map(|condition| condition.name.clone()).collect(),
        factors: study.design_columns(),
        levels: study.conditions.iter().map(|condition| condition.levels.clone()).collect(),
    }
}

/// The analysis crate leaves pilot and excluded rows out by itself unless told to keep them;
/// the export already left out what `include` does not keep, so the two agree. Detection trials
/// (one side the ground truth) are analysed apart; with the study's stimulus metrics CSV the
/// preference is set beside the stimuli's errors against the ground truth. A rating study's
/// export gets the rating analysis (`ratings`).
fn report(
    trials_csv: &str,
    study: &Study,
    include: Include,
    stimuli: Option<&StimulusMetrics>,
    scale: Scale,
) -> Result<Report, AppError> {
    // a rating study's export is analysed as ratings (MOS, P.910 screening, SUREAL's MLE_CO:
    // the `ratings` section), as `mrstudy analyze` does; the condition table is not used there
    analyze_with_table(
        trials_csv,
        "trials CSV",
        Some(&condition_table(study)),
        stimuli,
        &options(Some(study), include, scale),
    )
    .map_err(cannot_run)
}

/// `log_worth_map` with the active design's `prior_sd` (what `prior = "spread"` scores under),
/// as `mrstudy simulate` scores it; 1 without an active design.
fn options(study: Option<&Study>, include: Include, scale: Scale) -> Options {
    let prior_sd = study
        .and_then(|study| study.design.active.as_ref())
        .map_or(Options::default().prior_sd, |active| active.prior_sd);
    Options {
        include_pilots: include.pilots,
        include_excluded: include.excluded,
        scale,
        prior_sd,
        ..Options::default()
    }
}

/// No judgments yet, or a design the models cannot fit: the researcher sees why.
fn cannot_run(error: AnalysisError) -> AppError {
    AppError::Unprocessable(format!("The analysis cannot be run on the data so far: {error}."))
}

/// The Analysis JSON of docs/design.md, with its `detection` and `metrics` sections where they
/// apply; with [`Scale::Jod`] also pwcmp's JOD (`mrstudy analyze --scale jod`, no bootstrap:
/// no `jod_ci`), as the admin page shows it.
pub fn run(
    trials_csv: &str,
    study: &Study,
    include: Include,
    stimuli: Option<&StimulusMetrics>,
    scale: Scale,
) -> Result<serde_json::Value, AppError> {
    let report = report(trials_csv, study, include, stimuli, scale)?;
    serde_json::to_value(&report).map_err(|error| AppError::Internal(format!("analysis JSON: {error}")))
}

/// The worth plot as SVG, drawn as `mrstudy analyze --plot` draws it.
pub fn worth_svg(trials_csv: &str, study: &Study, include: Include) -> Result<String, AppError> {
    match report(trials_csv, study, include, None, Scale::Bt)?.preference {
        Some(analysis) => Ok(analysis.worth_plot()),
        None if study.rating.is_some() => Err(AppError::Unprocessable(
            "A rating study has no worth plot: its mean opinion scores are in the analysis' `ratings` section (`mrstudy analyze --plot-dir` draws them)."
                .into(),
        )),
        None => Err(AppError::Unprocessable(
            "The study has only detection trials (each condition beside the ground truth): there is no worth plot."
                .into(),
        )),
    }
}

/// The scatter plot of the metric that predicts preference best (worth against error), drawn
/// as `mrstudy analyze --stimuli … --plot-dir` draws it: the stimulus-metrics analysis alone,
/// not the whole report.
pub fn best_metric_svg(trials_csv: &str, include: Include, stimuli: &StimulusMetrics) -> Result<String, AppError> {
    let metrics = analyze_stimuli(
        trials_csv,
        "trials CSV",
        stimuli,
        &StimulusOptions::from_analysis(&options(None, include, Scale::Bt)),
    )
    .map_err(cannot_run)?;
    metrics.scatter_plots().into_iter().next().map(|(_, svg)| svg).ok_or_else(|| {
        AppError::Unprocessable("No image metric could be set beside the preference on the data so far.".into())
    })
}
