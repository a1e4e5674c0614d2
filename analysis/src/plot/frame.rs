//! The frame the line and scatter plots share: the horizontal layout (y label, y tick labels,
//! plot, title width), the vertical layout (title, legend, plot, x tick labels, x label), the legend centred over the plot, the major ticks with their grid lines
//! and labels, the frame and the axis titles.

use super::forest::{draw_tick_label, tick_label_width};
use super::scale::Axis;
use super::svg::{self, AXIS, GRID, LABEL_SIZE, LEGEND_LINE, LegendLayout, OUTER, Px, Svg, TICK_SIZE};

/// Length of a major tick mark.
pub(super) const TICK_LENGTH: f64 = 5.0;

/// Where the plot area sits horizontally, and the title laid out over the whole width.
pub(super) struct Columns {
    pub left: f64,
    pub right: f64,
    pub title: svg::Title,
}

/// The horizontal layout: y label | y tick labels | plot of `plot_width`, the title as wide as
/// the plot and the last x tick label's overhang.
pub(super) fn columns(title: &str, y_label: &str, x_axis: &Axis, y_axis: &Axis, plot_width: f64) -> Columns {
    let y_tick_width = y_axis.major.iter().map(|tick| tick_label_width(&tick.label)).fold(0.0, f64::max);
    let y_label_band = if y_label.is_empty() { 0.0 } else { LABEL_SIZE + 10.0 };
    let left = OUTER + y_label_band + y_tick_width + TICK_LENGTH + 6.0;
    let right = left + plot_width;
    let last_x_tick_overhang = x_axis.major.last().map_or(0.0, |tick| tick_label_width(&tick.label) / 2.0);
    let title = svg::Title::layout(title, right + last_x_tick_overhang.max(8.0) + OUTER);
    Columns { left, right, title }
}

/// Where things sit vertically, from the top: the title, the legend, the plot area, the x tick
/// labels and the x label.
pub(super) struct Rows {
    pub legend_top: f64,
    pub plot_top: f64,
    pub plot_bottom: f64,
    pub x_tick_baseline: f64,
    pub x_label_baseline: f64,
    /// The bottom of the last row (the x label's baseline, or the x tick labels' without one).
    pub bottom: f64,
}

/// The vertical layout below `title`: the legend's lines and `legend_gap` under them, a plot of
/// `plot_height`, the x tick labels and, unless `x_label` is empty, the x label.
pub(super) fn rows(
    title: &svg::Title,
    legend: &LegendLayout,
    legend_gap: f64,
    plot_height: f64,
    x_label: &str,
) -> Rows {
    let top = OUTER + title.height();
    let legend_top = top + LEGEND_LINE / 2.0;
    let plot_top = (top + legend.n_lines as f64 * LEGEND_LINE + legend_gap).max(OUTER + TICK_SIZE / 2.0);
    let plot_bottom = plot_top + plot_height;
    let x_tick_baseline = plot_bottom + TICK_LENGTH + TICK_SIZE + 3.0;
    let x_label_baseline = x_tick_baseline + LABEL_SIZE + 10.0;
    let bottom = if x_label.is_empty() { x_tick_baseline } else { x_label_baseline };
    Rows { legend_top, plot_top, plot_bottom, x_tick_baseline, x_label_baseline, bottom }
}

/// The legend of `names`: centred over the plot when it fits on one line, else from the left.
pub(super) fn draw_legend(svg: &mut Svg, names: &[&str], legend: &LegendLayout, (left, right): (f64, f64), top: f64) {
    let legend_width = legend
        .places
        .iter()
        .zip(names)
        .map(|(&(dx, _), name)| dx + 30.0 + svg::text_width(&svg::shorten(name), LABEL_SIZE))
        .fold(0.0, f64::max);
    let legend_left = if legend.n_lines == 1 { (left + right - legend_width) / 2.0 } else { OUTER };
    svg::draw_legend(svg, names, legend, (legend_left.max(OUTER), top));
}

/// The plot area: left, top, right, bottom.
#[derive(Clone, Copy)]
pub(super) struct Area {
    pub left: f64,
    pub top: f64,
    pub right: f64,
    pub bottom: f64,
}

/// Major ticks of both axes: grid line, tick mark and label (`x_of`, `y_of` map values to
/// pixels; x labels on `x_tick_baseline`).
pub(super) fn draw_major_ticks(
    svg: &mut Svg,
    (x_axis, y_axis): (&Axis, &Axis),
    area: Area,
    (x_of, y_of): (&dyn Fn(f64) -> f64, &dyn Fn(f64) -> f64),
    x_tick_baseline: f64,
) {
    for tick in &x_axis.major {
        let x = x_of(tick.value);
        svg.line((x, area.top), (x, area.bottom), GRID, 1.0);
        svg.line((x, area.bottom), (x, area.bottom + TICK_LENGTH), AXIS, 1.0);
        draw_tick_label(svg, (x, x_tick_baseline), &tick.label, r#"text-anchor="middle""#);
    }
    for tick in &y_axis.major {
        let y = y_of(tick.value);
        svg.line((area.left, y), (area.right, y), GRID, 1.0);
        svg.line((area.left - TICK_LENGTH, y), (area.left, y), AXIS, 1.0);
        draw_tick_label(
            svg,
            (area.left - TICK_LENGTH - 4.0, y + 0.35 * TICK_SIZE),
            &tick.label,
            r#"text-anchor="end""#,
        );
    }
}

/// The frame around the plot area and the axis titles (x on `x_label_baseline`, y rotated
/// along the left edge); an empty title is left out.
pub(super) fn draw_frame_and_labels(
    svg: &mut Svg,
    area: Area,
    (x_label, y_label): (&str, &str),
    x_label_baseline: f64,
) {
    svg.rect(
        area.left,
        area.top,
        area.right - area.left,
        area.bottom - area.top,
        &format!(r#"fill="none" stroke="{AXIS}" stroke-width="1""#),
    );
    if !x_label.is_empty() {
        svg.text(((area.left + area.right) / 2.0, x_label_baseline), x_label, r#"text-anchor="middle""#);
    }
    if !y_label.is_empty() {
        let (x, y) = (OUTER + LABEL_SIZE, (area.top + area.bottom) / 2.0);
        svg.text((x, y), y_label, &format!(r#"text-anchor="middle" transform="rotate(-90 {} {})""#, Px(x), Px(y)));
    }
}
