//! Line plots: series of (x, y) points drawn as markers joined by lines, on linear or log10
//! axes, for benchmarks (time against error and the like).

use super::LinePlot;
use super::forest::{draw_tick_label, tick_label_width};
use super::scale::Axis;
use super::svg::{self, AXIS, GRID, LABEL_SIZE, LEGEND_LINE, MUTED, NOTE_SIZE, OUTER, Px, Svg, TICK_SIZE};

const PLOT_WIDTH: f64 = 520.0;
const PLOT_HEIGHT: f64 = 340.0;
const TARGET_X_TICKS: usize = 7;
const TARGET_Y_TICKS: usize = 6;
const MARKER_SIZE: f64 = 8.0;
const TICK_LENGTH: f64 = 5.0;
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
    let y_tick_width = y_axis.major.iter().map(|tick| tick_label_width(&tick.label)).fold(0.0, f64::max);
    let y_label_band = if spec.y_label.is_empty() { 0.0 } else { LABEL_SIZE + 10.0 };
    let plot_left = OUTER + y_label_band + y_tick_width + TICK_LENGTH + 6.0;
    let plot_right = plot_left + PLOT_WIDTH;
    let last_x_tick_overhang = x_axis.major.last().map_or(0.0, |tick| tick_label_width(&tick.label) / 2.0);
    let title = svg::Title::layout(&spec.title, plot_right + last_x_tick_overhang.max(8.0) + OUTER);
    let width = title.width;

    // Vertical layout: title, legend, plot, x tick labels, x label, note.
    let mut y = OUTER + title.height();
    // A legend of nameless series would be swatches without words: leave it out.
    let names: Vec<&str> = if series.iter().all(|(name, _)| name.is_empty()) {
        Vec::new()
    } else {
        series.iter().map(|(name, _)| *name).collect()
    };
    let legend = svg::legend_layout(&names, width - 2.0 * OUTER);
    let legend_top = y + LEGEND_LINE / 2.0;
    y += legend.n_lines as f64 * LEGEND_LINE + 10.0;
    let plot_top = y.max(OUTER + TICK_SIZE / 2.0);
    let plot_bottom = plot_top + PLOT_HEIGHT;
    let x_tick_baseline = plot_bottom + TICK_LENGTH + TICK_SIZE + 3.0;
    let mut y = x_tick_baseline;
    let x_label_baseline = y + LABEL_SIZE + 10.0;
    if !spec.x_label.is_empty() {
        y = x_label_baseline;
    }
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
    let legend_width = legend
        .places
        .iter()
        .zip(&names)
        .map(|(&(dx, _), name)| dx + 30.0 + svg::text_width(&svg::shorten(name), LABEL_SIZE))
        .fold(0.0, f64::max);
    let legend_left = if legend.n_lines == 1 { (plot_left + plot_right - legend_width) / 2.0 } else { OUTER };
    svg::draw_legend(&mut svg, &names, &legend, (legend_left.max(OUTER), legend_top));

    // Grid: minor lines faint, major lines light; then the frame and ticks.
    for &value in &x_axis.minor {
        let x = x_of(value);
        svg.line((x, plot_top), (x, plot_bottom), MINOR_GRID, 1.0);
    }
    for &value in &y_axis.minor {
        let y = y_of(value);
        svg.line((plot_left, y), (plot_right, y), MINOR_GRID, 1.0);
    }
    for tick in &x_axis.major {
        let x = x_of(tick.value);
        svg.line((x, plot_top), (x, plot_bottom), GRID, 1.0);
        svg.line((x, plot_bottom), (x, plot_bottom + TICK_LENGTH), AXIS, 1.0);
        draw_tick_label(&mut svg, (x, x_tick_baseline), &tick.label, r#"text-anchor="middle""#);
    }
    for tick in &y_axis.major {
        let y = y_of(tick.value);
        svg.line((plot_left, y), (plot_right, y), GRID, 1.0);
        svg.line((plot_left - TICK_LENGTH, y), (plot_left, y), AXIS, 1.0);
        draw_tick_label(
            &mut svg,
            (plot_left - TICK_LENGTH - 4.0, y + 0.35 * TICK_SIZE),
            &tick.label,
            r#"text-anchor="end""#,
        );
    }
    for &value in &x_axis.minor {
        let x = x_of(value);
        svg.line((x, plot_bottom), (x, plot_bottom + TICK_LENGTH * 0.6), AXIS, 0.8);
    }
    for &value in &y_axis.minor {
        let y = y_of(value);
        svg.line((plot_left - TICK_LENGTH * 0.6, y), (plot_left, y), AXIS, 0.8);
    }
    svg.rect(plot_left, plot_top, PLOT_WIDTH, PLOT_HEIGHT, &format!(r#"fill="none" stroke="{AXIS}" stroke-width="1""#));

    if !spec.x_label.is_empty() {
        svg.text(((plot_left + plot_right) / 2.0, x_label_baseline), &spec.x_label, r#"text-anchor="middle""#);
    }
    if !spec.y_label.is_empty() {
        let (x, y) = (OUTER + LABEL_SIZE, (plot_top + plot_bottom) / 2.0);
        svg.text(
            (x, y),
            &spec.y_label,
            &format!(r#"text-anchor="middle" transform="rotate(-90 {} {})""#, Px(x), Px(y)),
        );
    }

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

/// A data value in a tooltip: four significant digits, no trailing zeros.
fn compact(value: f64) -> String {
    if value == 0.0 || !value.is_finite() {
        return "0".to_owned();
    }
    let magnitude = value.abs().log10().floor();
    let text = if !(-4.0..6.0).contains(&magnitude) {
        format!("{value:.3e}")
    } else {
        let decimals = (3.0 - magnitude).max(0.0) as usize;
        let text = format!("{value:.decimals$}");
        if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.').to_owned() } else { text }
    };
    text.replace('-', "−")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tooltip_numbers_are_compact() {
        assert_eq!(compact(12.5), "12.5");
        assert_eq!(compact(0.0012341), "0.001234");
        assert_eq!(compact(-3.0), "−3");
        assert_eq!(compact(1.5e9), "1.500e9");
        assert_eq!(compact(f64::NAN), "0");
    }
}
