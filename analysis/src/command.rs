//! `mrstudy analyze` on the texts of its files: a task CSV gets the lab-task analysis
//! ([`crate::task`]), a trials CSV the [`Report`](crate::report::Report); printed as a table ([`crate::table`]) or
//! JSON, with the plots asked for made before anything is written. [`analyze_request`] is the
//! whole command over its files, read and written by the caller's functions (no IO here).

use std::path::{Path, PathBuf};

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
    /// One scatter plot per metric × region, a threshold export's fits, the JOD ranking
    /// (`--plot-dir`).
    pub scatter: bool,
}

/// What `mrstudy analyze` prints and draws: every SVG is made before anything is written.
#[derive(Debug, Clone, Default)]
pub struct Printed {
    pub text: String,
    pub worth_plot: Option<String>,
    pub effect_plot: Option<String>,
    /// (file name, SVG) of each plot of `--plot-dir`.
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
    let jod = options.scale == crate::analysis::Scale::Jod;
    if drawings.scatter && stimuli.is_none() && !threshold_export && !rating_export && !jod {
        return Err(refuse(
            "--plot-dir",
            "it holds the metric scatter plots (or a threshold export's fits, a rating export's MOS plot, or the JOD ranking): give --stimuli with a stimulus metrics CSV, or --scale jod"
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
    if drawings.scatter
        && jod
        && let Some(ranking) = report.preference.as_ref().and_then(|analysis| analysis.jod_ranking_plot())
    {
        printed.scatter_plots.push(("jod-ranking.svg".to_owned(), ranking));
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

/// How `analyze` and `simulate` print their result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Table,
    Json,
}

impl Format {
    /// `--format`'s values: (name, help, value).
    pub const NAMES: &[(&str, &str, Format)] = &[("table", "", Format::Table), ("json", "", Format::Json)];
}

/// `mrstudy analyze`'s request: the files to read, how to print, where the plots go.
#[derive(Debug, Clone)]
pub struct AnalyzeRequest {
    pub trials: PathBuf,
    pub conditions: Option<PathBuf>,
    pub stimuli: Option<PathBuf>,
    pub format: Format,
    pub plot: Option<PathBuf>,
    pub effect_plot: Option<PathBuf>,
    pub plot_dir: Option<PathBuf>,
    pub options: Options,
}

/// How [`analyze_request`] reaches the files: the caller's read, write and create-folder.
#[derive(Clone, Copy)]
pub struct FileAccess<'a, E> {
    pub read: &'a dyn Fn(&Path) -> std::result::Result<String, E>,
    pub write: &'a dyn Fn(&Path, &str) -> std::result::Result<(), E>,
    pub create_dir: &'a dyn Fn(&Path) -> std::result::Result<(), E>,
}

/// `mrstudy analyze`: reads the request's files through `files`, analyses them
/// ([`analyze_files`]), writes the plots (all drawn before any is written: no partial output on
/// error) and returns the text to print.
pub fn analyze_request<E: From<AnalysisError>>(
    request: &AnalyzeRequest,
    files: FileAccess<'_, E>,
) -> std::result::Result<String, E> {
    let read = |path: &PathBuf| (files.read)(path).map(|text| (text, path.display().to_string()));
    let (trials, conditions, stimuli) = (
        read(&request.trials)?,
        request.conditions.as_ref().map(read).transpose()?,
        request.stimuli.as_ref().map(read).transpose()?,
    );
    let drawings = Drawings {
        worth: request.plot.is_some(),
        effects: request.effect_plot.is_some(),
        scatter: request.plot_dir.is_some(),
    };
    let trials = (trials.0.as_str(), trials.1.as_str());
    let printed = analyze_files(
        trials,
        named(&conditions),
        named(&stimuli),
        &request.options,
        request.format == Format::Json,
        drawings,
    )?;
    let plots = request.plot.iter().zip(&printed.worth_plot);
    for (path, svg) in plots.chain(request.effect_plot.iter().zip(&printed.effect_plot)) {
        (files.write)(path, svg)?;
    }
    if let Some(folder) = &request.plot_dir {
        (files.create_dir)(folder)?;
        printed.scatter_plots.iter().try_for_each(|(name, svg)| (files.write)(&folder.join(name), svg))?;
    }
    Ok(printed.text)
}

/// A file read as (text, name) borrowed as `analyze_files` takes it.
fn named(file: &Option<(String, String)>) -> Option<(&str, &str)> {
    file.as_ref().map(|(text, name)| (text.as_str(), name.as_str()))
}
