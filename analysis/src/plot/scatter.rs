//! Scatter plots: labelled (x, y) points on linear axes, optionally coloured by group with a
//! legend, and a note under the plot. Each label is put beside its point where it overlaps
//! the fewest other labels and markers (greedy, in order of the points), and every point keeps
//! its label and coordinates as a tooltip.

use super::ScatterPlot;
use super::frame::{self, Area};
use super::scale::{Axis, compact};
use super::svg::{self, MUTED, NOTE_SIZE, OUTER, Px, Svg};

const PLOT_WIDTH: f64 = 600.0;
const PLOT_HEIGHT: f64 = 420.0;
const TARGET_X_TICKS: usize = 7;
const TARGET_Y_TICKS: usize = 6;
const MARKER_SIZE: f64 = 8.0;
/// Font size of the point labels.
const POINT_LABEL_SIZE: f64 = 10.0;
/// Share of the plot's width a note line is wrapped to (room for wider fallback fonts).
const NOTE_WIDTH_SHARE: f64 = 0.85;
/// Gap between a marker and its label.
const LABEL_GAP: f64 = 5.0;

/// An axis-aligned box: left, top, right, bottom.
#[derive(Debug, Clone, Copy)]
struct Box2 {
    left: f64,
    top: f64,
    right: f64,
    bottom: f64,
}

impl Box2 {
    fn overlap(&self, other: &Box2) -> f64 {
        let width = (self.right.min(other.right) - self.left.max(other.left)).max(0.0);
        let height = (self.bottom.min(other.bottom) - self.top.max(other.top)).max(0.0);
        width * height
    }

    /// The area of the box outside `bounds`.
    fn outside(&self, bounds: &Box2) -> f64 {
        let area = (self.right - self.left) * (self.bottom - self.top);
        area - self.overlap(bounds)
    }
}

/// Where a label goes relative to its point: offset of the anchor and the text anchor.
#[derive(Debug, Clone, Copy)]
enum Place {
    Right,
    Left,
    Above,
    Below,
    AboveRight,
    BelowRight,
    AboveLeft,
    BelowLeft,
}

const PLACES: [Place; 8] = [
    Place::Right,
    Place::Left,
    Place::Above,
    Place::Below,
    Place::AboveRight,
    Place::BelowRight,
    Place::AboveLeft,
    Place::BelowLeft,
];

/// The label's box and its baseline anchor `(x, y, text-anchor)` for a point at `(x, y)`.
fn place(place: Place, (x, y): (f64, f64), width: f64) -> (Box2, (f64, f64, &'static str)) {
    let height = POINT_LABEL_SIZE;
    let half = MARKER_SIZE / 2.0;
    let (left, top) = match place {
        Place::Right => (x + half + LABEL_GAP, y - height / 2.0),
        Place::Left => (x - half - LABEL_GAP - width, y - height / 2.0),
        Place::Above => (x - width / 2.0, y - half - LABEL_GAP / 2.0 - height),
        Place::Below => (x - width / 2.0, y + half + LABEL_GAP / 2.0),
        Place::AboveRight => (x + half, y - half - height),
        Place::BelowRight => (x + half, y + half),
        Place::AboveLeft => (x - half - width, y - half - height),
        Place::BelowLeft => (x - half - width, y + half),
    };
    let bounds = Box2 { left, top, right: left + width, bottom: top + height };
    // The baseline sits about a fifth of the size above the box's bottom.
    (bounds, (left, top + 0.82 * height, "start"))
}

pub(super) fn render(spec: &ScatterPlot) -> String {
    let points: Vec<_> = spec.points.iter().filter(|p| p.x.is_finite() && p.y.is_finite()).collect();
    let n_skipped = spec.points.len() - points.len();
    if points.is_empty() {
        return svg::no_data(&spec.title);
    }
    // Groups in order of first appearance.
    let mut groups: Vec<&str> = Vec::new();
    for point in &points {
        if let Some(group) = point.group.as_deref()
            && !groups.contains(&group)
        {
            groups.push(group);
        }
    }
    let style_of =
        |group: Option<&str>| svg::style(group.and_then(|g| groups.iter().position(|&x| x == g)).unwrap_or(0));

    let xs: Vec<f64> = points.iter().map(|p| p.x).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.y).collect();
    let x_axis = Axis::linear(&xs, TARGET_X_TICKS);
    let y_axis = Axis::linear(&ys, TARGET_Y_TICKS);

    // Horizontal layout: y label | y tick labels | plot.
    let frame::Columns { left: plot_left, right: plot_right, title } =
        frame::columns(&spec.title, &spec.y_label, &x_axis, &y_axis, PLOT_WIDTH);
    let width = title.width;

    // Vertical layout: title, legend, plot, x tick labels, x label, note lines.
    let legend = svg::legend_layout(&groups, width - 2.0 * OUTER);
    let gap = if groups.is_empty() { 0.0 } else { 10.0 };
    let frame::Rows { legend_top, plot_top, plot_bottom, x_tick_baseline, x_label_baseline, bottom } =
        frame::rows(&title, &legend, gap, PLOT_HEIGHT, &spec.x_label);
    let mut y = bottom;
    let mut notes: Vec<String> = Vec::new();
    if n_skipped > 0 {
        notes.push(format!("{n_skipped} {} not shown (not finite).", if n_skipped == 1 { "point" } else { "points" }));
    }
    if let Some(note) = &spec.note {
        // Widths are estimated for Helvetica/Arial; where the viewer falls back to DejaVu Sans
        // (about an eighth wider) a line wrapped to the full width runs off the edge.
        notes.extend(wrap(note, (width - 2.0 * OUTER) * NOTE_WIDTH_SHARE, NOTE_SIZE));
    }
    let note_first_baseline = y + NOTE_SIZE + 10.0;
    if !notes.is_empty() {
        y = note_first_baseline + (notes.len() - 1) as f64 * (NOTE_SIZE + 4.0);
    }
    let height = y + OUTER;

    let x_of = |value: f64| plot_left + x_axis.fraction(value) * PLOT_WIDTH;
    let y_of = |value: f64| plot_bottom - y_axis.fraction(value) * PLOT_HEIGHT;

    let mut svg = Svg::new(width, height, &spec.title);
    title.draw(&mut svg, width / 2.0, OUTER);
    if !groups.is_empty() {
        frame::draw_legend(&mut svg, &groups, &legend, (plot_left, plot_right), legend_top);
    }
    let area = Area { left: plot_left, top: plot_top, right: plot_right, bottom: plot_bottom };
    frame::draw_major_ticks(&mut svg, (&x_axis, &y_axis), area, (&x_of, &y_of), x_tick_baseline);
    frame::draw_frame_and_labels(&mut svg, area, (&spec.x_label, &spec.y_label), x_label_baseline);

    // Labels first placed, then drawn under the markers.
    let positions: Vec<(f64, f64)> = points.iter().map(|p| (x_of(p.x), y_of(p.y))).collect();
    let half = MARKER_SIZE / 2.0;
    let markers: Vec<Box2> = positions
        .iter()
        .map(|&(x, y)| Box2 { left: x - half, top: y - half, right: x + half, bottom: y + half })
        .collect();
    let figure = Box2 { left: plot_left, top: plot_top, right: plot_right, bottom: plot_bottom };
    let mut placed: Vec<Box2> = Vec::with_capacity(points.len());
    for (point, &position) in points.iter().zip(&positions) {
        let label = svg::shorten(&point.label);
        let label_width = svg::text_width(&label, POINT_LABEL_SIZE);
        let cost = |bounds: &Box2| {
            let labels: f64 = placed.iter().map(|other| bounds.overlap(other)).sum();
            let marks: f64 = markers.iter().map(|other| bounds.overlap(other)).sum();
            4.0 * bounds.outside(&figure) + labels + 2.0 * marks
        };
        let (bounds, (x, y, anchor)) = PLACES
            .iter()
            .map(|&p| place(p, position, label_width))
            .min_by(|a, b| cost(&a.0).total_cmp(&cost(&b.0)))
            .expect("eight places");
        placed.push(bounds);
        svg.text(
            (x, y),
            &label,
            &format!(r#"text-anchor="{anchor}" font-size="{}" fill="{MUTED}""#, Px(POINT_LABEL_SIZE)),
        );
    }
    for (point, &position) in points.iter().zip(&positions) {
        let tooltip = format!("{}: {}, {}", point.label, compact(point.x), compact(point.y));
        svg.marker(position, style_of(point.group.as_deref()), MARKER_SIZE, Some(&tooltip));
    }

    for (k, line) in notes.iter().enumerate() {
        svg.text(
            (OUTER, note_first_baseline + k as f64 * (NOTE_SIZE + 4.0)),
            line,
            &format!(r#"font-size="{}" fill="{MUTED}" font-style="italic""#, Px(NOTE_SIZE)),
        );
    }
    svg.finish()
}

/// Text broken at spaces into lines of at most `max_width` px at `size`.
fn wrap(text: &str, max_width: f64, size: f64) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split(' ').filter(|w| !w.is_empty()) {
        match lines.last_mut() {
            Some(line) if svg::text_width(&format!("{line} {word}"), size) <= max_width => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_owned()),
        }
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::ScatterPoint;

    #[test]
    fn labels_avoid_each_other_where_there_is_room() {
        let points: Vec<ScatterPoint> = (0..6)
            .map(|k| ScatterPoint { x: k as f64, y: (k % 2) as f64, label: format!("point {k}"), group: None })
            .collect();
        let svg = render(&ScatterPlot { title: "t".into(), points, ..ScatterPlot::default() });
        assert_eq!(svg.matches("<circle").count(), 6);
        for k in 0..6 {
            assert!(svg.contains(&format!(">point {k}</text>")), "{svg}");
        }
        assert!(!svg.contains("NaN"));
    }

    #[test]
    fn non_finite_points_are_counted_not_drawn() {
        let points = vec![
            ScatterPoint { x: 1.0, y: 2.0, label: "a".into(), group: Some("G".into()) },
            ScatterPoint { x: f64::NAN, y: 2.0, label: "b".into(), group: Some("G".into()) },
        ];
        let svg = render(&ScatterPlot { title: "t".into(), points, ..ScatterPlot::default() });
        assert!(svg.contains("1 point not shown (not finite)."));
        assert!(!svg.contains("NaN"));
        let empty = render(&ScatterPlot { title: "t".into(), ..ScatterPlot::default() });
        assert!(empty.contains("no data"));
    }
}
