//! Scatter plots: labelled (x, y) points on linear axes, optionally coloured by group with a
//! legend, and a note under the plot. Labels never overlap one another or a marker where the
//! plot has room: greedy, in order of the points, each label takes the first of eight places
//! around its point that lies inside the plot and clear of every label placed so far and every
//! marker ([`place_labels`]); where none is clear it moves outwards on rings of growing radius
//! and is joined to its point by a leader line. Every point keeps its label and coordinates as
//! a tooltip.

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
/// Clear space kept around a placed label (so that neighbours do not touch).
const LABEL_PADDING: f64 = 1.0;
/// Step between the rings searched for a label that has no clear place beside its point.
const RING_STEP: f64 = 6.0;
/// Directions tried on each ring.
const RING_DIRECTIONS: usize = 24;

/// An axis-aligned box: left, top, right, bottom.
#[derive(Debug, Clone, Copy)]
struct Box2 {
    left: f64,
    top: f64,
    right: f64,
    bottom: f64,
}

impl Box2 {
    /// Whether the two boxes share an area (touching edges do not count).
    fn intersects(&self, other: &Box2) -> bool {
        self.left < other.right && other.left < self.right && self.top < other.bottom && other.top < self.bottom
    }

    fn inside(&self, bounds: &Box2) -> bool {
        self.left >= bounds.left && self.right <= bounds.right && self.top >= bounds.top && self.bottom <= bounds.bottom
    }

    fn padded(&self, padding: f64) -> Box2 {
        Box2 {
            left: self.left - padding,
            top: self.top - padding,
            right: self.right + padding,
            bottom: self.bottom + padding,
        }
    }

    /// Whether the segment from `a` to `b` passes through the box (Liang–Barsky clipping).
    fn crossed_by(&self, a: (f64, f64), b: (f64, f64)) -> bool {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (mut enter, mut leave) = (0.0_f64, 1.0_f64);
        for (p, q) in [(-dx, a.0 - self.left), (dx, self.right - a.0), (-dy, a.1 - self.top), (dy, self.bottom - a.1)] {
            if p == 0.0 {
                if q <= 0.0 {
                    return false;
                }
            } else {
                let t = q / p;
                if p < 0.0 {
                    enter = enter.max(t);
                } else {
                    leave = leave.min(t);
                }
            }
        }
        enter < leave
    }

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

/// Where a point's label went: its box, the baseline anchor of its text and, when it is away
/// from its point, the leader line from the marker's edge to the box.
#[derive(Debug, Clone, Copy)]
struct LabelPlacement {
    bounds: Box2,
    anchor: (f64, f64),
    leader: Option<((f64, f64), (f64, f64))>,
}

/// Greedy label placement, in order of the points (`positions`, with their labels' `widths`):
/// the first of [`PLACES`] beside the point that lies inside `figure` and intersects no label
/// placed so far (padded by [`LABEL_PADDING`]) and no marker; else the first box, on rings
/// [`RING_STEP`] apart around the point, that does, with a leader line; else (no clear place
/// anywhere in the plot) the place beside the point that overlaps least.
fn place_labels(positions: &[(f64, f64)], widths: &[f64], figure: Box2) -> Vec<LabelPlacement> {
    let half = MARKER_SIZE / 2.0;
    let markers: Vec<Box2> = positions
        .iter()
        .map(|&(x, y)| Box2 { left: x - half, top: y - half, right: x + half, bottom: y + half })
        .collect();
    let diagonal = ((figure.right - figure.left).powi(2) + (figure.bottom - figure.top).powi(2)).sqrt();
    let mut placed: Vec<LabelPlacement> = Vec::with_capacity(positions.len());
    for (&position, &width) in positions.iter().zip(widths) {
        // Clear: inside the plot, off every placed label, marker and leader line.
        let clear = |bounds: &Box2, placed: &[LabelPlacement]| {
            bounds.inside(&figure)
                && placed.iter().all(|other| {
                    !bounds.intersects(&other.bounds.padded(LABEL_PADDING))
                        && other.leader.is_none_or(|(from, to)| !bounds.crossed_by(from, to))
                })
                && markers.iter().all(|marker| !bounds.intersects(marker))
        };
        // A leader line from the point to `bounds` that crosses no placed label.
        let leader_clear = |bounds: &Box2, placed: &[LabelPlacement]| {
            let target = (position.0.clamp(bounds.left, bounds.right), position.1.clamp(bounds.top, bounds.bottom));
            placed.iter().all(|other| !other.bounds.crossed_by(position, target))
        };
        let beside = PLACES.iter().map(|&p| place(p, position, width)).find(|(bounds, _)| clear(bounds, &placed));
        if let Some((bounds, (x, y, _))) = beside {
            placed.push(LabelPlacement { bounds, anchor: (x, y), leader: None });
            continue;
        }
        let height = POINT_LABEL_SIZE;
        let mut away = None;
        let mut crossing = None;
        let mut radius = half + LABEL_GAP + RING_STEP;
        'rings: while radius < diagonal {
            for direction in 0..RING_DIRECTIONS {
                let angle = std::f64::consts::TAU * direction as f64 / RING_DIRECTIONS as f64;
                let (centre_x, centre_y) = (position.0 + radius * angle.cos(), position.1 + radius * angle.sin());
                let bounds = Box2 {
                    left: centre_x - width / 2.0,
                    top: centre_y - height / 2.0,
                    right: centre_x + width / 2.0,
                    bottom: centre_y + height / 2.0,
                };
                if clear(&bounds, &placed) {
                    if leader_clear(&bounds, &placed) {
                        away = Some(bounds);
                        break 'rings;
                    }
                    // Clear, but its leader would cross a label: only if nothing better.
                    crossing = crossing.or(Some(bounds));
                }
            }
            radius += RING_STEP;
        }
        let placement = match away.or(crossing) {
            Some(bounds) => {
                // From the marker's edge towards the nearest point of the box.
                let target = (position.0.clamp(bounds.left, bounds.right), position.1.clamp(bounds.top, bounds.bottom));
                let (dx, dy) = (target.0 - position.0, target.1 - position.1);
                let length = (dx * dx + dy * dy).sqrt().max(f64::MIN_POSITIVE);
                let start = (position.0 + dx / length * half, position.1 + dy / length * half);
                LabelPlacement {
                    bounds,
                    anchor: (bounds.left, bounds.top + 0.82 * height),
                    leader: Some((start, target)),
                }
            }
            None => {
                let cost = |bounds: &Box2| {
                    let labels: f64 = placed.iter().map(|other| bounds.overlap(&other.bounds)).sum();
                    let marks: f64 = markers.iter().map(|other| bounds.overlap(other)).sum();
                    4.0 * bounds.outside(&figure) + labels + 2.0 * marks
                };
                let (bounds, (x, y, _)) = PLACES
                    .iter()
                    .map(|&p| place(p, position, width))
                    .min_by(|a, b| cost(&a.0).total_cmp(&cost(&b.0)))
                    .expect("eight places");
                LabelPlacement { bounds, anchor: (x, y), leader: None }
            }
        };
        placed.push(placement);
    }
    placed
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

    // Labels first placed, then drawn (with their leader lines) under the markers.
    let positions: Vec<(f64, f64)> = points.iter().map(|p| (x_of(p.x), y_of(p.y))).collect();
    let figure = Box2 { left: plot_left, top: plot_top, right: plot_right, bottom: plot_bottom };
    let labels: Vec<String> = points.iter().map(|point| svg::shorten(&point.label)).collect();
    let widths: Vec<f64> = labels.iter().map(|label| svg::text_width(label, POINT_LABEL_SIZE)).collect();
    for (label, placement) in labels.iter().zip(place_labels(&positions, &widths, figure)) {
        if let Some((from, to)) = placement.leader {
            svg.line(from, to, MUTED, 0.6);
        }
        svg.text(
            placement.anchor,
            label,
            &format!(r#"text-anchor="start" font-size="{}" fill="{MUTED}""#, Px(POINT_LABEL_SIZE)),
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

    /// The drawn point labels' boxes, from the SVG: `text-anchor="start"` at `x`, baseline `y`
    /// (0.82 of the size below the box's top), width as the layout estimates it.
    fn label_boxes(svg: &str) -> Vec<(String, Box2)> {
        let document = roxmltree::Document::parse(svg).expect("valid SVG");
        document
            .descendants()
            .filter(|node| node.has_tag_name("text") && node.attribute("font-size") == Some("10"))
            .map(|node| {
                let text = node.text().unwrap_or_default().to_string();
                let x: f64 = node.attribute("x").unwrap().parse().unwrap();
                let y: f64 = node.attribute("y").unwrap().parse().unwrap();
                let top = y - 0.82 * POINT_LABEL_SIZE;
                let width = svg::text_width(&text, POINT_LABEL_SIZE);
                (text, Box2 { left: x, top, right: x + width, bottom: top + POINT_LABEL_SIZE })
            })
            .collect()
    }

    /// The walkthrough's defect: a crowded metric scatter plot (40 stimuli, most in a small
    /// cluster, labels `scene/condition`) with labels drawn over each other. Every pair of
    /// drawn label boxes must be disjoint, and no label may cover a marker.
    #[test]
    fn labels_of_a_crowded_plot_never_overlap_each_other_or_markers() {
        let conditions = ["LQ", "GI", "CM", "CA", "GI+CM", "GI+CA", "CM+CA", "HQ"];
        let mut points = Vec::new();
        for scene in 0..5 {
            for (c, condition) in conditions.iter().enumerate() {
                // A tight cluster near (0.1, 0) and a few spread out, as the metrics come.
                let k = (scene * 8 + c) as f64;
                let (x, y) = if c < 6 {
                    (0.1 + 0.004 * ((k * 7.3).sin()), 0.05 * ((k * 3.1).cos()))
                } else {
                    (0.1 + 0.2 * (k / 40.0), -1.0 + 0.05 * k)
                };
                points.push(ScatterPoint {
                    x,
                    y,
                    label: format!("scene{scene}/{condition}"),
                    group: Some(condition.to_string()),
                });
            }
        }
        let spec = ScatterPlot {
            title: "flip_mean (affected region) against preference".into(),
            points,
            ..ScatterPlot::default()
        };
        let svg = render(&spec);
        if let Ok(path) = std::env::var("MRSTUDY_CROWDED_SVG") {
            std::fs::write(path, &svg).unwrap();
        }
        let boxes = label_boxes(&svg);
        assert_eq!(boxes.len(), 40, "{svg}");
        // Px writes two decimals: allow a hundredth of a pixel of rounding.
        let shrunk = |b: &Box2| b.padded(-0.02);
        for (i, (text_i, box_i)) in boxes.iter().enumerate() {
            for (text_j, box_j) in &boxes[i + 1..] {
                assert!(!shrunk(box_i).intersects(box_j), "`{text_i}` {box_i:?} overlaps `{text_j}` {box_j:?}");
            }
        }
        let document = roxmltree::Document::parse(&svg).unwrap();
        let half = MARKER_SIZE / 2.0;
        for node in
            document.descendants().filter(|n| n.has_tag_name("title") && n.text().is_some_and(|t| t.contains("scene")))
        {
            let marker = node.parent().unwrap();
            let (x, y) = match (marker.attribute("cx"), marker.attribute("x")) {
                (Some(cx), _) => (cx.parse::<f64>().unwrap(), marker.attribute("cy").unwrap().parse::<f64>().unwrap()),
                (None, Some(x)) => {
                    let side: f64 = marker.attribute("width").unwrap().parse().unwrap();
                    (
                        x.parse::<f64>().unwrap() + side / 2.0,
                        marker.attribute("y").unwrap().parse::<f64>().unwrap() + side / 2.0,
                    )
                }
                _ => continue,
            };
            let marker_box = Box2 { left: x - half, top: y - half, right: x + half, bottom: y + half };
            for (text, label_box) in &boxes {
                assert!(!shrunk(label_box).intersects(&marker_box), "`{text}` covers a marker at ({x}, {y})");
            }
        }
        // Some labels had to move away from their point: they are joined to it.
        assert!(svg.matches("<line").count() > 0);
    }

    #[test]
    fn a_label_with_room_stays_beside_its_point_without_a_leader() {
        let figure = Box2 { left: 0.0, top: 0.0, right: 600.0, bottom: 420.0 };
        let placements = place_labels(&[(100.0, 100.0), (400.0, 300.0)], &[40.0, 40.0], figure);
        assert!(placements.iter().all(|p| p.leader.is_none()));
        // The first place tried: to the right of the point.
        assert_eq!(placements[0].bounds.left, 100.0 + MARKER_SIZE / 2.0 + LABEL_GAP);
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
