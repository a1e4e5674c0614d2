//! Dot-and-interval ("forest") figures, the layout behind worth and effect plots: one row
//! per item (condition or factor) in the order given, the value axis horizontal, and per
//! series one point with its interval, dodged vertically within the row.
//!
//! Rows rather than columns because item names may be long and there may be fifty items:
//! labels then read horizontally and the figure grows downwards.

use std::fmt::Write as _;

use super::scale::{Axis, TickLabel};
use super::svg::{self, AXIS, GRID, LABEL_SIZE, LEGEND_LINE, MUTED, OUTER, Px, Svg, TICK_SIZE};

/// Width of the value axis, px.
const PLOT_WIDTH: f64 = 460.0;
/// Major ticks wanted on the value axis.
const TARGET_TICKS: usize = 6;
/// Vertical distance between dodged series in a row, px.
const DODGE: f64 = 9.0;
const MARKER_SIZE: f64 = 9.0;
/// Height of the caps at the ends of an interval, px.
const CAP: f64 = 7.0;
/// Above this many rows the tick labels are repeated at the top.
const TOP_TICKS_ABOVE_ROWS: usize = 12;
const BAND: &str = "#f2f3f5";

/// One point with its (possibly missing, possibly one-sided) interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Estimate {
    pub value: f64,
    pub low: Option<f64>,
    pub high: Option<f64>,
}

impl Estimate {
    /// `None` for a non-finite value; a non-finite bound counts as missing, and swapped
    /// bounds are put in order.
    pub fn new(value: f64, low: Option<f64>, high: Option<f64>) -> Option<Estimate> {
        if !value.is_finite() {
            return None;
        }
        let finite = |bound: Option<f64>| bound.filter(|v| v.is_finite());
        let (low, high) = match (finite(low), finite(high)) {
            (Some(low), Some(high)) if low > high => (Some(high), Some(low)),
            bounds => bounds,
        };
        Some(Estimate { value, low, high })
    }
}

/// One series: its name and an estimate (or none) per row.
pub(super) struct Series {
    pub name: String,
    pub estimates: Vec<Option<Estimate>>,
}

/// A table to the right of the plot: one column per series, one cell per row.
pub(super) struct Annotation {
    pub header: String,
    /// `cells[series_idx][row_idx]`; `None` is drawn as a dash.
    pub cells: Vec<Vec<Option<String>>>,
}

pub(super) struct Spec {
    pub title: String,
    pub rows: Vec<String>,
    pub series: Vec<Series>,
    pub value_label: String,
    /// The value's symbol in tooltips (`λ`, `β`).
    pub symbol: &'static str,
    pub annotation: Option<Annotation>,
}

/// A series as the caller gives it: (row label, estimate) pairs in any order.
pub(super) struct Labelled {
    pub name: String,
    pub points: Vec<(String, Option<Estimate>)>,
}

/// Rows and per-row estimates: the labels of `order` first (duplicates dropped), then
/// labels that only the series use, in order of first appearance. Within a series the
/// first estimate for a label wins.
pub(super) fn assemble(order: &[String], series: Vec<Labelled>) -> (Vec<String>, Vec<Series>) {
    let mut rows: Vec<String> = Vec::with_capacity(order.len());
    let row_of = |rows: &mut Vec<String>, label: &str| match rows.iter().position(|r| r == label) {
        Some(row_idx) => row_idx,
        None => {
            rows.push(label.to_owned());
            rows.len() - 1
        }
    };
    for label in order {
        row_of(&mut rows, label);
    }
    let row_indices: Vec<Vec<usize>> = series
        .iter()
        .map(|labelled| labelled.points.iter().map(|(label, _)| row_of(&mut rows, label)).collect())
        .collect();
    let series = series
        .into_iter()
        .zip(row_indices)
        .map(|(labelled, row_indices)| {
            let mut estimates = vec![None; rows.len()];
            let mut seen = vec![false; rows.len()];
            for (row_idx, (_, estimate)) in row_indices.into_iter().zip(labelled.points) {
                if !seen[row_idx] {
                    seen[row_idx] = true;
                    estimates[row_idx] = estimate;
                }
            }
            Series { name: labelled.name, estimates }
        })
        .collect();
    (rows, series)
}

/// `value` with two decimals and a proper minus sign, for tooltips.
pub(super) fn format_value(value: f64) -> String {
    let text = format!("{value:.2}");
    let text = if text == "-0.00" { "0.00".to_owned() } else { text };
    text.replace('-', "−")
}

pub(super) fn render(spec: &Spec) -> String {
    let mut values = vec![0.0];
    for estimate in spec.series.iter().flat_map(|s| s.estimates.iter().flatten()) {
        values.push(estimate.value);
        values.extend(estimate.low);
        values.extend(estimate.high);
    }
    if spec.rows.is_empty() || values.len() == 1 {
        return svg::no_data(&spec.title);
    }
    let axis = Axis::linear(&values, TARGET_TICKS);
    let n_rows = spec.rows.len();
    let n_series = spec.series.len();
    let row_height = (DODGE * n_series as f64 + 14.0).max(24.0);

    // Horizontal layout: row labels | plot | annotation columns.
    let label_width = spec.rows.iter().map(|row| svg::text_width(&svg::shorten(row), LABEL_SIZE)).fold(0.0, f64::max);
    let plot_left = OUTER + label_width + 14.0;
    let plot_right = plot_left + PLOT_WIDTH;
    let annotation_columns: Vec<f64> = match &spec.annotation {
        None => Vec::new(),
        Some(annotation) => annotation
            .cells
            .iter()
            .zip(&spec.series)
            .map(|(cells, series)| {
                let widest_cell =
                    cells.iter().flatten().map(|cell| svg::text_width(cell, TICK_SIZE)).fold(0.0, f64::max);
                let name_width =
                    if n_series > 1 { svg::text_width(&svg::shorten(&series.name), TICK_SIZE) } else { 0.0 };
                widest_cell.max(name_width).max(svg::text_width(&annotation.header, TICK_SIZE) / n_series as f64) + 14.0
            })
            .collect(),
    };
    let annotation_left = plot_right + 22.0;
    let content_right = if annotation_columns.is_empty() {
        plot_right
    } else {
        annotation_left + annotation_columns.iter().sum::<f64>()
    };
    let title = svg::Title::layout(&spec.title, content_right + OUTER + 8.0);
    let width = title.width;

    // Vertical layout: title, legend, header band (annotation headers, top ticks), rows, axis.
    let mut y = OUTER + title.height();
    // A legend of nameless series would be swatches without words: leave it out.
    let names: Vec<&str> = if spec.series.iter().all(|s| s.name.is_empty()) {
        Vec::new()
    } else {
        spec.series.iter().map(|s| s.name.as_str()).collect()
    };
    let legend = svg::legend_layout(&names, width - 2.0 * OUTER);
    let legend_top = y + LEGEND_LINE / 2.0;
    y += legend.n_lines as f64 * LEGEND_LINE + 6.0;
    let top_ticks = n_rows > TOP_TICKS_ABOVE_ROWS;
    let header_lines = match &spec.annotation {
        Some(_) if n_series > 1 => 2,
        Some(_) => 1,
        None => usize::from(top_ticks),
    };
    let header_line = 17.0;
    y += header_lines as f64 * header_line + 4.0;
    let plot_top = y;
    let plot_bottom = plot_top + n_rows as f64 * row_height;
    let height = plot_bottom + 5.0 + TICK_SIZE + 8.0 + LABEL_SIZE + 10.0 + OUTER;

    let x_of = |value: f64| plot_left + axis.fraction(value) * PLOT_WIDTH;
    let row_centre = |row_idx: usize| plot_top + (row_idx as f64 + 0.5) * row_height;
    let dodge = |series_idx: usize| (series_idx as f64 - (n_series as f64 - 1.0) / 2.0) * DODGE;

    let mut svg = Svg::new(width, height, &spec.title);
    title.draw(&mut svg, width / 2.0, OUTER);
    let legend_width = legend
        .places
        .iter()
        .zip(&names)
        .map(|(&(dx, _), name)| dx + 30.0 + svg::text_width(&svg::shorten(name), LABEL_SIZE))
        .fold(0.0, f64::max);
    let legend_left = if legend.n_lines == 1 { (width - legend_width) / 2.0 } else { OUTER };
    svg::draw_legend(&mut svg, &names, &legend, (legend_left, legend_top));

    // Alternate row bands, across labels, plot and annotation.
    for row_idx in (1..n_rows).step_by(2) {
        svg.rect(
            OUTER - 4.0,
            row_centre(row_idx) - row_height / 2.0,
            content_right - OUTER + 8.0,
            row_height,
            &format!(r#"fill="{BAND}""#),
        );
    }

    // Grid, zero line, axis.
    let tick_label = |svg: &mut Svg, x: f64, y: f64, label: &TickLabel| {
        draw_tick_label(svg, (x, y), label, r#"text-anchor="middle""#);
    };
    for tick in &axis.major {
        let x = x_of(tick.value);
        if tick.value != 0.0 {
            svg.line((x, plot_top), (x, plot_bottom), GRID, 1.0);
        }
        svg.line((x, plot_bottom), (x, plot_bottom + 5.0), AXIS, 1.0);
        tick_label(&mut svg, x, plot_bottom + 5.0 + TICK_SIZE + 2.0, &tick.label);
        if top_ticks {
            tick_label(&mut svg, x, plot_top - 6.0, &tick.label);
        }
    }
    let zero = x_of(0.0);
    svg.line_with(
        (zero, plot_top),
        (zero, plot_bottom),
        &format!(r#"stroke="{MUTED}" stroke-width="1.2" stroke-dasharray="5 3""#),
    );
    svg.line((plot_left, plot_bottom), (plot_right, plot_bottom), AXIS, 1.0);
    svg.text(((plot_left + plot_right) / 2.0, height - OUTER - 2.0), &spec.value_label, r#"text-anchor="middle""#);

    // Row labels.
    for (row_idx, row) in spec.rows.iter().enumerate() {
        svg.label((plot_left - 10.0, row_centre(row_idx) + 0.35 * LABEL_SIZE), row, r#"text-anchor="end""#);
    }

    // Intervals first, then all markers over them.
    for (series_idx, series) in spec.series.iter().enumerate() {
        let style = svg::style(series_idx);
        for (row_idx, estimate) in series.estimates.iter().enumerate() {
            let Some(estimate) = estimate else { continue };
            if estimate.low.is_none() && estimate.high.is_none() {
                continue;
            }
            let y = row_centre(row_idx) + dodge(series_idx);
            let (left, right) = (estimate.low.unwrap_or(estimate.value), estimate.high.unwrap_or(estimate.value));
            let stroke = format!(r#"stroke="{}" stroke-width="1.6""#, style.colour);
            svg.line_with((x_of(left), y), (x_of(right), y), &stroke);
            for bound in [estimate.low, estimate.high].into_iter().flatten() {
                svg.line_with((x_of(bound), y - CAP / 2.0), (x_of(bound), y + CAP / 2.0), &stroke);
            }
        }
    }
    for (series_idx, series) in spec.series.iter().enumerate() {
        let style = svg::style(series_idx);
        for (row_idx, estimate) in series.estimates.iter().enumerate() {
            let Some(estimate) = estimate else { continue };
            let y = row_centre(row_idx) + dodge(series_idx);
            let tooltip = tooltip(&spec.rows[row_idx], &series.name, spec.symbol, estimate);
            svg.marker((x_of(estimate.value), y), style, MARKER_SIZE, Some(&tooltip));
        }
    }

    // Annotation table.
    if let Some(annotation) = &spec.annotation {
        let attributes = format!(r#"text-anchor="middle" font-size="{}""#, Px(TICK_SIZE));
        let table_centre = (annotation_left + content_right) / 2.0;
        let header_baseline = plot_top - 8.0 - if n_series > 1 { header_line } else { 0.0 };
        svg.text((table_centre, header_baseline), &annotation.header, &format!(r#"{attributes} font-weight="bold""#));
        let mut column_left = annotation_left;
        for (series_idx, (cells, column_width)) in annotation.cells.iter().zip(&annotation_columns).enumerate() {
            let centre = column_left + column_width / 2.0;
            if n_series > 1 {
                let colour = svg::style(series_idx).colour;
                let name = spec.series.get(series_idx).map_or("", |s| s.name.as_str());
                svg.label((centre, plot_top - 8.0), name, &format!(r#"{attributes} fill="{colour}""#));
            }
            for (row_idx, cell) in cells.iter().enumerate().take(n_rows) {
                let y = row_centre(row_idx) + 0.35 * TICK_SIZE;
                match cell {
                    Some(cell) => {
                        svg.text((centre, y), cell, &format!(r#"{attributes} font-variant-numeric="tabular-nums""#))
                    }
                    None => svg.text((centre, y), "–", &format!(r#"{attributes} fill="{MUTED}""#)),
                }
            }
            column_left += column_width;
        }
    }
    svg.finish()
}

fn tooltip(row: &str, series: &str, symbol: &str, estimate: &Estimate) -> String {
    let mut tooltip = format!("{row} ({series}): {symbol} = {}", format_value(estimate.value));
    match (estimate.low, estimate.high) {
        (Some(low), Some(high)) => {
            let _ = write!(tooltip, ", 95 % CI [{}, {}]", format_value(low), format_value(high));
        }
        (Some(low), None) => {
            let _ = write!(tooltip, ", 95 % CI from {}", format_value(low));
        }
        (None, Some(high)) => {
            let _ = write!(tooltip, ", 95 % CI up to {}", format_value(high));
        }
        (None, None) => {}
    }
    tooltip
}

/// Draws a tick label at baseline `(x, y)`; a power of ten gets a raised, smaller exponent.
pub(super) fn draw_tick_label(svg: &mut Svg, (x, y): (f64, f64), label: &TickLabel, attributes: &str) {
    match label {
        TickLabel::Plain(text) => {
            svg.text((x, y), text, &format!(r#"{attributes} font-size="{}" fill="{MUTED}""#, Px(TICK_SIZE)));
        }
        TickLabel::Power { mantissa, exponent } => {
            let mantissa = mantissa.as_ref().map(|m| format!("{}×", svg::escape(m))).unwrap_or_default();
            let exponent = exponent.to_string().replace('-', "−");
            svg.raw(&format!(
                r#"<text x="{}" y="{}" {attributes} font-size="{}" fill="{MUTED}">{mantissa}10<tspan dy="{}" font-size="{}">{exponent}</tspan></text>
"#,
                Px(x),
                Px(y),
                Px(TICK_SIZE),
                Px(-0.45 * TICK_SIZE),
                Px(0.75 * TICK_SIZE),
            ));
        }
    }
}

/// Estimated width of a drawn tick label.
pub(super) fn tick_label_width(label: &TickLabel) -> f64 {
    match label {
        TickLabel::Plain(text) => svg::text_width(text, TICK_SIZE),
        TickLabel::Power { mantissa, exponent } => {
            let mantissa = mantissa.as_ref().map(|m| format!("{m}×")).unwrap_or_default();
            svg::text_width(&format!("{mantissa}10"), TICK_SIZE)
                + svg::text_width(&exponent.to_string(), 0.75 * TICK_SIZE)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(label: &str, value: f64) -> (String, Option<Estimate>) {
        (label.to_owned(), Estimate::new(value, None, None))
    }

    #[test]
    fn estimates_drop_non_finite_values_and_order_bounds() {
        assert_eq!(Estimate::new(f64::NAN, Some(0.0), Some(1.0)), None);
        let estimate = Estimate::new(0.5, Some(1.0), Some(0.0)).unwrap();
        assert_eq!((estimate.low, estimate.high), (Some(0.0), Some(1.0)));
        let estimate = Estimate::new(0.5, Some(f64::NEG_INFINITY), Some(0.9)).unwrap();
        assert_eq!((estimate.low, estimate.high), (None, Some(0.9)));
    }

    #[test]
    fn assemble_keeps_the_given_order_and_appends_unknown_rows() {
        let order = vec!["LQ".to_owned(), "GI".to_owned(), "LQ".to_owned()];
        let series = vec![
            Labelled { name: "all".to_owned(), points: vec![point("GI", 1.0), point("XX", 2.0), point("GI", 9.0)] },
            Labelled { name: "male".to_owned(), points: vec![point("LQ", 0.0)] },
        ];
        let (rows, series) = assemble(&order, series);
        assert_eq!(rows, ["LQ", "GI", "XX"]);
        assert_eq!(
            series[0].estimates.iter().map(|e| e.map(|e| e.value)).collect::<Vec<_>>(),
            [None, Some(1.0), Some(2.0)]
        );
        assert_eq!(series[1].estimates.iter().map(|e| e.map(|e| e.value)).collect::<Vec<_>>(), [Some(0.0), None, None]);
    }

    #[test]
    fn values_are_formatted_with_a_minus_sign() {
        assert_eq!(format_value(-0.541), "−0.54");
        assert_eq!(format_value(-0.001), "0.00");
        assert_eq!(format_value(1.2), "1.20");
    }
}
