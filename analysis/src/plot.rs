//! SVG figures of analysis results, written by hand as strings (this crate does no IO).
//!
//! - [`worth_plot`] / [`worth_plot_with`]: log-worth per condition with 95 % intervals,
//!   one series per group (e.g. all, female, male), optionally with each condition's worth
//!   π beside it (the thesis' Figures 6.14(a) and 6.16(a));
//! - [`effect_plot`]: factor estimates (`gi`, `cm`, `ca`, interactions) with 95 % intervals
//!   per group (Figure 6.14(b));
//! - [`ranking_plot`]: values ranked best first with 95 % intervals and, beside each row, how
//!   it differs from the row below (the JOD ranking of `--scale jod`);
//! - [`line_plot`]: benchmark series of (x, y) points on linear or log10 axes;
//! - [`scatter`]: labelled (x, y) points, optionally coloured by group (an image metric of
//!   each stimulus or condition against its perceived log-worth).
//!
//! Worth and effect plots put one row per condition or factor, in the order given, and the
//! logit scale horizontally with a dashed zero line; the groups' points are dodged within a
//! row and told apart by colour (Okabe & Ito's colour-blind-safe palette) and marker shape
//! (so they survive greyscale print). Rows rather than columns, because names may be long
//! and there may be fifty conditions: labels stay horizontal and the figure grows down.
//!
//! Missing data is left out, never invented: a point without an interval has no bar, an
//! interval with one bound is drawn one-sided, a condition a group could not estimate has
//! no point in that group's series (its row stays), and a line-plot point that is not finite
//! or not positive on a log axis is skipped and counted in a note under the plot. Every
//! number goes through one formatter, so `NaN` and `inf` never reach the SVG; all text is
//! XML-escaped. A figure without data is a valid SVG with its title and "no data".
//!
//! SVG has no text metrics, so margins come from an estimate of label widths in a
//! Helvetica-like font (`svg::text_width`); labels over 40 characters are shortened with an
//! ellipsis and keep their full text as a tooltip, as does every point.

mod forest;
mod frame;
mod line;
mod scale;
mod scatter;
mod svg;

use forest::{Annotation, Estimate, Labelled};

/// One condition's log-worth λ (logit scale) with its 95 % interval, either bound of which
/// may be missing.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WorthPoint {
    pub condition: String,
    pub log_worth: f64,
    pub low: Option<f64>,
    pub high: Option<f64>,
}

/// The log-worths of one group (e.g. "all", "female", "male"). Conditions the group could
/// not estimate are simply absent.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WorthSeries {
    pub name: String,
    pub points: Vec<WorthPoint>,
}

/// Options of [`worth_plot_with`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WorthPlotOptions {
    /// Print each condition's worth π = exp(λᵢ) / Σⱼ exp(λⱼ) beside the plot, one column per
    /// series; the sum runs over the conditions present in that series.
    pub show_worth: bool,
    /// The reference condition (log-worth 0), named in the axis label.
    pub reference: Option<String>,
}

/// One factor's (or interaction's) estimate on the logit scale with its 95 % interval.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EffectPoint {
    pub factor: String,
    pub estimate: f64,
    pub low: Option<f64>,
    pub high: Option<f64>,
}

/// The factor estimates of one group.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EffectSeries {
    pub name: String,
    pub points: Vec<EffectPoint>,
}

/// A line plot: markers joined by lines, in the order of each series' points.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinePlot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Log10 x axis; points with x ≤ 0 are skipped.
    pub x_log: bool,
    /// Log10 y axis; points with y ≤ 0 are skipped.
    pub y_log: bool,
    pub series: Vec<LineSeries>,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct LineSeries {
    pub name: String,
    /// (x, y) pairs; non-finite ones are skipped.
    pub points: Vec<(f64, f64)>,
}

/// A scatter plot: labelled points on linear axes, with an optional note under the plot.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScatterPlot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Points that are not finite are skipped and counted in a note.
    pub points: Vec<ScatterPoint>,
    /// A line of text (wrapped) under the plot.
    pub note: Option<String>,
}

/// One point of a [`ScatterPlot`]: its label is drawn beside it; points of the same `group`
/// share a colour and marker, named in a legend.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScatterPoint {
    pub x: f64,
    pub y: f64,
    pub label: String,
    pub group: Option<String>,
}

/// Log-worth per condition with 95 % intervals, one series per group, conditions in the
/// order of `conditions` (conditions only the series name follow, in order of appearance).
#[must_use]
pub fn worth_plot(title: &str, conditions: &[String], series: &[WorthSeries]) -> String {
    worth_plot_with(title, conditions, series, &WorthPlotOptions::default())
}

/// [`worth_plot`] with options: the worth π column and the reference condition.
#[must_use]
pub fn worth_plot_with(
    title: &str,
    conditions: &[String],
    series: &[WorthSeries],
    options: &WorthPlotOptions,
) -> String {
    let labelled = series
        .iter()
        .map(|series| {
            let points = series
                .points
                .iter()
                .map(|p| (p.condition.clone(), Estimate::new(p.log_worth, p.low, p.high)))
                .collect();
            Labelled { name: series.name.clone(), points }
        })
        .collect();
    let (rows, series) = forest::assemble(conditions, labelled);
    let annotation = options.show_worth.then(|| Annotation {
        header: "worth π".to_owned(),
        cells: series.iter().map(|s| worth_column(&s.estimates)).collect(),
    });
    let value_label = match &options.reference {
        Some(reference) => format!("log-worth λ (logit scale, {reference} = 0)"),
        None => "log-worth λ (logit scale)".to_owned(),
    };
    forest::render(&forest::Spec { title: title.to_owned(), rows, series, value_label, symbol: "λ", annotation })
}

/// Factor estimates with 95 % intervals, one series per group, factors in the order of
/// `factors` (factors only the series name follow, in order of appearance).
#[must_use]
pub fn effect_plot(title: &str, factors: &[String], series: &[EffectSeries]) -> String {
    estimate_plot(title, factors, series, "effect on log-worth (logit scale)", "β")
}

/// Mean opinion scores with 95 % intervals (rating studies, [`crate::ratings`]): one row per
/// label in the order of `rows`, one series per [`EffectSeries`] (its `factor` the row label,
/// `estimate` the MOS); `value_label` names the scale.
#[must_use]
pub fn mos_plot(title: &str, value_label: &str, rows: &[String], series: &[EffectSeries]) -> String {
    estimate_plot(title, rows, series, value_label, "MOS")
}

/// Estimates with 95 % intervals, one row per label of `rows` (labels only a series names
/// follow), one series per [`EffectSeries`]: the factor-effect and the MOS plots.
fn estimate_plot(
    title: &str,
    rows: &[String],
    series: &[EffectSeries],
    value_label: &str,
    symbol: &'static str,
) -> String {
    let labelled = series
        .iter()
        .map(|series| {
            let points =
                series.points.iter().map(|p| (p.factor.clone(), Estimate::new(p.estimate, p.low, p.high))).collect();
            Labelled { name: series.name.clone(), points }
        })
        .collect();
    let (rows, series) = forest::assemble(rows, labelled);
    forest::render(&forest::Spec {
        title: title.to_owned(),
        rows,
        series,
        value_label: value_label.to_owned(),
        symbol,
        annotation: None,
    })
}

/// One row of a [`ranking_plot`]: a condition's value with its 95 % interval, and a note on its
/// difference from the next row down (none on the last row).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RankingPoint {
    pub condition: String,
    pub value: f64,
    pub low: Option<f64>,
    pub high: Option<f64>,
    pub step: Option<String>,
}

/// A ranking: one row per point in the order given (best first), the value with its interval
/// on the horizontal axis, and the notes on neighbouring differences in a column headed
/// `step_header` beside the plot.
#[must_use]
pub fn ranking_plot(title: &str, value_label: &str, step_header: &str, points: &[RankingPoint]) -> String {
    let rows: Vec<String> = points.iter().map(|p| p.condition.clone()).collect();
    let estimates = points.iter().map(|p| (p.condition.clone(), Estimate::new(p.value, p.low, p.high))).collect();
    let (rows, series) = forest::assemble(&rows, vec![Labelled { name: "all".to_owned(), points: estimates }]);
    let annotation =
        Annotation { header: step_header.to_owned(), cells: vec![points.iter().map(|p| p.step.clone()).collect()] };
    forest::render(&forest::Spec {
        title: title.to_owned(),
        rows,
        series,
        value_label: value_label.to_owned(),
        symbol: "JOD",
        annotation: Some(annotation),
    })
}

/// Series of (x, y) points as markers joined by lines, on linear or log10 axes.
#[must_use]
pub fn line_plot(spec: &LinePlot) -> String {
    line::render(spec)
}

/// Labelled points on linear axes (see [`ScatterPlot`]).
#[must_use]
pub fn scatter(spec: &ScatterPlot) -> String {
    scatter::render(spec)
}

/// Worth π of each present estimate, normalised over the present ones, as table cells.
fn worth_column(estimates: &[Option<Estimate>]) -> Vec<Option<String>> {
    let max = estimates.iter().flatten().map(|e| e.value).fold(f64::NEG_INFINITY, f64::max);
    let total: f64 = estimates.iter().flatten().map(|e| (e.value - max).exp()).sum();
    estimates
        .iter()
        .map(|estimate| {
            let worth = (estimate.as_ref()?.value - max).exp() / total;
            Some(if worth >= 0.0005 { format!("{worth:.3}") } else { "<0.001".to_owned() })
        })
        .collect()
}

#[cfg(test)]
mod tests;
