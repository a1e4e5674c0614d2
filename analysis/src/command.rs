//! `mrstudy analyze` on the texts of its files: a task CSV gets the lab-task analysis
//! ([`crate::task`]), a trials CSV the [`Report`](crate::report::Report); printed as a table ([`crate::table`]) or
//! JSON, with the plots asked for made before anything is written.

use crate::analysis::Options;
use crate::error::{AnalysisError, Result};
use crate::report::analyze_named;

/// The plots `mrstudy analyze` draws besides its text.
#[derive(Debug, Clone, Copy, Default)]
pub struct Drawings {
    /// The worth plot (`--plot`).
    pub worth: bool,
    /// The factor-effect plot (`--effect-plot`).
    pub effects: bool,
    /// One scatter plot per metric × region (`--plot-dir`).
    pub scatter: bool,
}

/// What `mrstudy analyze` prints and draws: every SVG is made before anything is written.
#[derive(Debug, Clone, Default)]
pub struct Printed {
    pub text: String,
    pub worth_plot: Option<String>,
    pub effect_plot: Option<String>,
    /// (file name, SVG) of each metric scatter plot.
    pub scatter_plots: Vec<(String, String)>,
}

/// A task CSV (lab tasks) has a `value` and a `condition` column and no `left`.
pub fn is_task_csv(text: &str) -> bool {
    let columns = crate::data::header_columns(text);
    columns.contains(&"value") && columns.contains(&"condition") && !columns.contains(&"left")
}

/// `mrstudy analyze` on the texts of its files, each with its name for messages: a task CSV
/// gets the lab-task analysis (Friedman tests), a trials CSV the [`Report`](crate::report::Report); `json` picks the
/// JSON over the table. A plot that cannot be drawn (no factor model, only detection trials)
/// is refused with a sentence.
pub fn analyze_files(
    trials: (&str, &str),
    conditions: Option<(&str, &str)>,
    stimuli: Option<(&str, &str)>,
    options: &Options,
    json: bool,
    drawings: Drawings,
) -> Result<Printed> {
    let (trials_csv, trials_name) = trials;
    let refuse = |option: &str, message: String| AnalysisError::BadOption { option: option.to_string(), message };
    if is_task_csv(trials_csv) {
        if conditions.is_some()
            || options.model.is_some()
            || stimuli.is_some()
            || drawings.worth
            || drawings.effects
            || drawings.scatter
        {
            return Err(refuse(
                "--trials",
                format!(
                    "{trials_name} is a task CSV (participant,condition,value): --conditions, --model, --stimuli and the plots apply to paired comparisons only"
                ),
            ));
        }
        let analysis = crate::task::analyze_task_csv(trials_csv, trials_name)?;
        let text = if json {
            serde_json::to_string_pretty(&analysis).expect("a task analysis serialises") + "\n"
        } else {
            crate::task::render_table(&analysis)
        };
        return Ok(Printed { text, ..Printed::default() });
    }
    let threshold_export = crate::threshold::report::is_threshold_csv(trials_csv);
    let rating_export = crate::ratings::is_rating_csv(trials_csv);
    if drawings.scatter && stimuli.is_none() && !threshold_export && !rating_export {
        return Err(refuse(
            "--plot-dir",
            "it holds the metric scatter plots (or a threshold export's fits, a rating export's MOS plot): give --stimuli with a stimulus metrics CSV"
                .to_string(),
        ));
    }
    if rating_export && (drawings.worth || drawings.effects || stimuli.is_some() || conditions.is_some()) {
        return Err(refuse(
            "--trials",
            format!(
                "{trials_name} is a rating export (participant,scene,condition,rating,method): --conditions, --stimuli, --plot and --effect-plot apply to paired comparisons; --plot-dir draws its MOS plot"
            ),
        ));
    }
    let report = analyze_named(trials_csv, trials_name, conditions, stimuli, options)?;
    let text = if json {
        serde_json::to_string_pretty(&report).expect("a report serialises") + "\n"
    } else {
        crate::table::render_report(&report)
    };
    let preference = |option: &str| {
        report.preference.as_ref().ok_or_else(|| {
            refuse(
                option,
                format!(
                    "{trials_name} has only detection trials (one side `ground-truth`): there is no worth or effect to plot"
                ),
            )
        })
    };
    let mut printed = Printed { text, ..Printed::default() };
    if drawings.worth {
        printed.worth_plot = Some(preference("--plot")?.worth_plot());
    }
    if drawings.effects {
        printed.effect_plot = Some(preference("--effect-plot")?.effect_plot().ok_or_else(|| {
            refuse("--effect-plot", "it needs a factor model: give --conditions with factor columns".to_string())
        })?);
    }
    if drawings.scatter
        && let Some(threshold) = &report.threshold
    {
        printed.scatter_plots.extend(threshold.plots());
    }
    if drawings.scatter
        && let Some(ratings) = &report.ratings
    {
        printed.scatter_plots.extend(ratings.plots());
    }
    if drawings.scatter && stimuli.is_some() && !threshold_export {
        let metrics = report.metrics.as_ref().ok_or_else(|| {
            refuse(
                "--plot-dir",
                format!("{trials_name} has no preference trials to set the stimulus metrics beside: no scatter plots"),
            )
        })?;
        printed.scatter_plots.extend(metrics.scatter_plots());
    }
    Ok(printed)
}
