//! Line plots: series of (x, y) points drawn as markers joined by lines, on linear or log10
//! axes, for benchmarks (time against error and the like).

use super::LinePlot;
use super::frame::{self, Area, TICK_LENGTH};
use super::scale::{Axis, compact};
use super::svg::{self, AXIS, MUTED, NOTE_SIZE, OUTER, Px, Svg};

const PLOT_WIDTH: f64 = 520.0;
const PLOT_HEIGHT: f64 = 340.0;
const TARGET_X_TICKS: usize = 7;
const TARGET_Y_TICKS: usize = 6;
const MARKER_SIZE: f64 = 8.0;
const MINOR_GRID: &str = "#f1f1f1";

pub(super) fn render(spec: &LinePlot) -> String {
    let usable =
        |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && (!spec.x_log || x > 0.0) && (!spec.y_log || y > 0.0);
    let series: Vec<(&str, Vec<(f64, f64)>)> = spec
        .series
        .iter()
        .map(|series| (series.name.as_str(), series.points.iter().copied().filter(usable).collect()))
        .collect();
    let n_points: usize = spec.series.iter().map(|s| s.points.len()).sum();
    let n_shown: usize = series.iter().map(|(_, points)| points.len()).sum();
    if n_shown == 0 {
        return svg::no_data(&spec.title);
    }
    let xs: Vec<f64> = series.iter().flat_map(|(_, points)| points.iter().map(|p| p.0)).collect();
    let ys: Vec<f64> = series.iter().flat_map(|(_, points)| points.iter().map(|p| p.1)).collect();
    let axis = |values: &[f64], log: bool, target: usize| {
        if log { Axis::log(values, target) } else { Axis::linear(values, target) }
    };
    let x_axis = axis(&xs, spec.x_log, TARGET_X_TICKS);
    let y_axis = axis(&ys, spec.y_log, TARGET_Y_TICKS);

    // Horizontal layout: y label | y tick labels | plot.
    let frame::Columns { left: plot_left, right: plot_right, title } =
        frame::columns(&spec.title, &spec.y_label, &x_axis, &y_axis, PLOT_WIDTH);
    let width = title.width;

    // Vertical layout: title, legend, plot, x tick labels, x label, note.
    // A legend of nameless series would be swatches without words: leave it out.
    let names: Vec<&str> = if series.iter().all(|(name, _)| name.is_empty()) {
        Vec::new()
    } else {
        series.iter().map(|(name, _)| *name).collect()
    };
    let legend = svg::legend_layout(&names, width - 2.0 * OUTER);
    let frame::Rows { legend_top, plot_top, plot_bottom, x_tick_baseline, x_label_baseline, bottom } =
        frame::rows(&title, &legend, 10.0, PLOT_HEIGHT, &spec.x_label);
    let mut y = bottom;
    let n_skipped = n_points - n_shown;
    let note_baseline = y + NOTE_SIZE + 10.0;
    if n_skipped > 0 {
        y = note_baseline;
    }
    let height = y + OUTER;

    let x_of = |value: f64| plot_left + x_axis.fraction(value) * PLOT_WIDTH;
    let y_of = |value: f64| plot_bottom - y_axis.fraction(value) * PLOT_HEIGHT;

    let mut svg = Svg::new(width, height, &spec.title);
    title.draw(&mut svg, width / 2.0, OUTER);
    frame::draw_legend(&mut svg, &names, &legend, (plot_left, plot_right), legend_top);
    let area = Area { left: plot_left, top: plot_top, right: plot_right, bottom: plot_bottom };

    // Grid: minor lines faint, major lines light; then the frame and ticks.
    for &value in &x_axis.minor {
        let x = x_of(value);
        svg.line((x, plot_top), (x, plot_bottom), MINOR_GRID, 1.0);
    }
    for &value in &y_axis.minor {
        let y = y_of(value);
        svg.line((plot_left, y), (plot_right, y), MINOR_GRID, 1.0);
    }
    frame::draw_major_ticks(&mut svg, (&x_axis, &y_axis), area, (&x_of, &y_of), x_tick_baseline);
    for &value in &x_axis.minor {
        let x = x_of(value);
        svg.line((x, plot_bottom), (x, plot_bottom + TICK_LENGTH * 0.6), AXIS, 0.8);
    }
    for &value in &y_axis.minor {
        let y = y_of(value);
        svg.line((plot_left - TICK_LENGTH * 0.6, y), (plot_left, y), AXIS, 0.8);
    }
    frame::draw_frame_and_labels(&mut svg, area, (&spec.x_label, &spec.y_label), x_label_baseline);

    // Series: lines, then markers with tooltips.
    for (series_idx, (_, points)) in series.iter().enumerate() {
        if points.len() < 2 {
            continue;
        }
        let style = svg::style(series_idx);
        let path: Vec<String> = points.iter().map(|&(x, y)| format!("{},{}", Px(x_of(x)), Px(y_of(y)))).collect();
        svg.raw(&format!(
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.8\" stroke-linejoin=\"round\"/>\n",
            path.join(" "),
            style.colour
        ));
    }
    for (series_idx, (name, points)) in series.iter().enumerate() {
        let style = svg::style(series_idx);
        for &(x, y) in points {
            let tooltip = format!(
                "{name}: {} = {}, {} = {}",
                axis_name(&spec.x_label, "x"),
                compact(x),
                axis_name(&spec.y_label, "y"),
                compact(y)
            );
            svg.marker((x_of(x), y_of(y)), style, MARKER_SIZE, Some(&tooltip));
        }
    }

    if n_skipped > 0 {
        let reason = if spec.x_log || spec.y_log { "not finite, or not positive on a log axis" } else { "not finite" };
        let points = if n_skipped == 1 { "point" } else { "points" };
        svg.text(
            (plot_left, note_baseline),
            &format!("{n_skipped} {points} not shown ({reason})."),
            &format!(r#"font-size="{}" fill="{MUTED}" font-style="italic""#, Px(NOTE_SIZE)),
        );
    }
    svg.finish()
}

fn axis_name<'a>(label: &'a str, fallback: &'a str) -> &'a str {
    if label.is_empty() { fallback } else { label }
}
