//! The SVG writer shared by the plots: XML escaping, compact coordinates, text-width
//! estimates, the series palette and marker shapes, the legend and the "no data" figure.
//!
//! Everything written goes through [`Px`] (numbers) or [`escape`] (text), so no plot can
//! emit `NaN`, `inf` or unescaped markup.

use std::fmt::{self, Write as _};

/// Outer margin of every figure, in px.
pub(super) const OUTER: f64 = 16.0;
pub(super) const TITLE_SIZE: f64 = 16.0;
pub(super) const LABEL_SIZE: f64 = 13.0;
pub(super) const TICK_SIZE: f64 = 12.0;
pub(super) const NOTE_SIZE: f64 = 11.0;
/// Distance between the baselines of a wrapped title's lines, in px.
pub(super) const TITLE_LINE: f64 = 1.25 * TITLE_SIZE;
/// Bold text runs wider than [`text_width`]'s regular estimate: DejaVu Sans Bold, the widest
/// of the fonts in [`FONT_FAMILY`], by about 13 % (measured in Chromium on the worth plot's
/// title: 585 px bold against 518 px regular at 16 px).
pub(super) const BOLD_WIDTH: f64 = 1.15;
/// A title is wrapped at the content's width, but never narrower than this, in px.
pub(super) const MIN_TITLE_WRAP: f64 = 420.0;
/// Height of one legend line, in px.
pub(super) const LEGEND_LINE: f64 = 20.0;
/// Labels longer than this many characters are shortened with an ellipsis (the full text
/// stays in a tooltip).
pub(super) const MAX_LABEL_CHARS: usize = 40;

const FONT_FAMILY: &str = "'Helvetica Neue', Helvetica, Arial, 'DejaVu Sans', 'Liberation Sans', sans-serif";
pub(super) const TEXT: &str = "#222222";
pub(super) const MUTED: &str = "#555555";
pub(super) const GRID: &str = "#dddddd";
pub(super) const AXIS: &str = "#333333";

/// Okabe & Ito's colour-blind-safe palette (yellow left out: too faint on white).
const COLOURS: [&str; 7] = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000"];

/// Marker shapes, cycled independently of the colours so that series stay distinct in
/// greyscale print.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Shape {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
    Cross,
}

const SHAPES: [Shape; 6] =
    [Shape::Circle, Shape::Square, Shape::TriangleUp, Shape::Diamond, Shape::TriangleDown, Shape::Cross];

/// Colour and marker of the series at `series_idx`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Style {
    pub colour: &'static str,
    pub shape: Shape,
}

pub(super) fn style(series_idx: usize) -> Style {
    Style { colour: COLOURS[series_idx % COLOURS.len()], shape: SHAPES[series_idx % SHAPES.len()] }
}

/// A coordinate or length, written with at most two decimals and no trailing zeros; a
/// non-finite value (which the plots never produce) is written as 0 rather than `NaN`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Px(pub f64);

impl fmt::Display for Px {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let value = if self.0.is_finite() { (self.0 * 100.0).round() / 100.0 } else { 0.0 };
        if value == 0.0 {
            return f.write_str("0");
        }
        let text = format!("{value:.2}");
        f.write_str(text.trim_end_matches('0').trim_end_matches('.'))
    }
}

/// Escapes text for XML character data and attribute values. Characters that XML 1.0 does
/// not allow become U+FFFD; tabs and line breaks become spaces (labels are one line).
pub(super) fn escape(text: &str) -> String {
    let mut escaped = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => escaped.push_str("&amp;"),
            '<' => escaped.push_str("&lt;"),
            '>' => escaped.push_str("&gt;"),
            '"' => escaped.push_str("&quot;"),
            '\'' => escaped.push_str("&apos;"),
            '\t' | '\n' | '\r' => escaped.push(' '),
            '\u{20}'..='\u{D7FF}' | '\u{E000}'..='\u{FFFD}' | '\u{10000}'..='\u{10FFFF}' => escaped.push(c),
            _ => escaped.push('\u{FFFD}'),
        }
    }
    escaped
}

/// `label`, shortened to [`MAX_LABEL_CHARS`] characters with an ellipsis.
pub(super) fn shorten(label: &str) -> String {
    if label.chars().count() <= MAX_LABEL_CHARS {
        label.to_owned()
    } else {
        let mut short: String = label.chars().take(MAX_LABEL_CHARS - 1).collect();
        short.push('…');
        short
    }
}

/// Estimated advance width of `text` in a Helvetica-like sans-serif at `size` px. SVG has
/// no text metrics; the estimate errs on the wide side so margins do not clip labels.
pub(super) fn text_width(text: &str, size: f64) -> f64 {
    let em: f64 = text
        .chars()
        .map(|c| match c {
            'i' | 'l' | 'j' | '!' | '|' | '.' | ',' | ':' | ';' | '\'' | 'I' | ' ' => 0.3,
            'f' | 't' | 'r' | '(' | ')' | '[' | ']' | '-' | '/' => 0.36,
            'm' | 'w' | 'M' | 'W' | '%' | '@' => 0.86,
            'A'..='Z' => 0.69,
            '0'..='9' => 0.57,
            'a'..='z' => 0.56,
            '+' | '=' | '<' | '>' | '−' | '×' | '±' => 0.6,
            c if u32::from(c) >= 0x2E80 => 1.0,
            _ => 0.62,
        })
        .sum();
    em * size
}

/// Estimated width of `text` as a title (bold, [`TITLE_SIZE`]).
pub(super) fn title_width(text: &str) -> f64 {
    text_width(text, TITLE_SIZE) * BOLD_WIDTH
}

/// A title broken at spaces into lines whose estimated width is at most `max_width` (a single
/// word wider than that gets a line of its own). No-break spaces (`95\u{a0}%`) hold. No
/// lines for an empty title.
pub(super) fn wrap_title(title: &str, max_width: f64) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in title.split([' ', '\t', '\n', '\r']).filter(|word| !word.is_empty()) {
        match lines.last_mut() {
            Some(line) if title_width(&format!("{line} {word}")) <= max_width => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_owned()),
        }
    }
    lines
}

/// A figure's title, wrapped to fit: its lines and the figure width that holds both them and
/// content `content_width` px wide (margins included).
pub(super) struct Title {
    pub lines: Vec<String>,
    pub width: f64,
}

impl Title {
    pub fn layout(title: &str, content_width: f64) -> Title {
        let lines = wrap_title(title, (content_width - 2.0 * OUTER).max(MIN_TITLE_WRAP));
        let widest = lines.iter().map(|line| title_width(line)).fold(0.0, f64::max);
        Title { lines, width: content_width.max(widest + 2.0 * OUTER) }
    }

    /// Vertical space the title takes above the next element, px (0 without a title).
    pub fn height(&self) -> f64 {
        match self.lines.len() {
            0 => 0.0,
            n => TITLE_SIZE + (n - 1) as f64 * TITLE_LINE + 14.0,
        }
    }

    /// Draws the lines centred on `centre_x`, the first baseline at `top + TITLE_SIZE`.
    pub fn draw(&self, svg: &mut Svg, centre_x: f64, top: f64) {
        for (line_idx, line) in self.lines.iter().enumerate() {
            svg.text((centre_x, top + TITLE_SIZE + line_idx as f64 * TITLE_LINE), line, &title_attributes());
        }
    }
}

/// An SVG document being written.
pub(super) struct Svg {
    out: String,
}

impl Svg {
    /// Starts a `width` × `height` px figure on a white background; `title` becomes the
    /// document's accessible name.
    pub fn new(width: f64, height: f64, title: &str) -> Svg {
        let mut out = String::with_capacity(16 * 1024);
        let (width, height) = (Px(width.ceil()), Px(height.ceil()));
        let _ = writeln!(
            out,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" font-family="{FONT_FAMILY}" font-size="{size}" fill="{TEXT}" role="img">"#,
            size = Px(LABEL_SIZE),
        );
        let _ = writeln!(out, "<title>{}</title>", escape(title));
        let _ = writeln!(out, r##"<rect width="{width}" height="{height}" fill="#ffffff"/>"##);
        Svg { out }
    }

    /// Appends markup as it is; the caller escapes any text in it.
    pub fn raw(&mut self, markup: &str) {
        self.out.push_str(markup);
    }

    pub fn line(&mut self, (x1, y1): (f64, f64), (x2, y2): (f64, f64), stroke: &str, width: f64) {
        self.line_with((x1, y1), (x2, y2), &format!(r#"stroke="{stroke}" stroke-width="{}""#, Px(width)));
    }

    /// A line with arbitrary (already escaped) presentation attributes.
    pub fn line_with(&mut self, (x1, y1): (f64, f64), (x2, y2): (f64, f64), attributes: &str) {
        let _ = writeln!(
            self.out,
            r#"<line x1="{}" y1="{}" x2="{}" y2="{}" {attributes}/>"#,
            Px(x1),
            Px(y1),
            Px(x2),
            Px(y2)
        );
    }

    pub fn rect(&mut self, x: f64, y: f64, width: f64, height: f64, attributes: &str) {
        let _ = writeln!(
            self.out,
            r#"<rect x="{}" y="{}" width="{}" height="{}" {attributes}/>"#,
            Px(x),
            Px(y),
            Px(width.max(0.0)),
            Px(height.max(0.0))
        );
    }

    /// Text at baseline `(x, y)`; `content` is escaped here. `attributes` (already escaped)
    /// set anchor, size, colour and the like.
    pub fn text(&mut self, (x, y): (f64, f64), content: &str, attributes: &str) {
        let _ = writeln!(self.out, r#"<text x="{}" y="{}" {attributes}>{}</text>"#, Px(x), Px(y), escape(content));
    }

    /// A label shortened to [`MAX_LABEL_CHARS`]; when shortened, the full text is kept as a
    /// tooltip.
    pub fn label(&mut self, (x, y): (f64, f64), label: &str, attributes: &str) {
        let short = shorten(label);
        if short == label {
            self.text((x, y), label, attributes);
        } else {
            let _ = writeln!(
                self.out,
                r#"<text x="{}" y="{}" {attributes}><title>{}</title>{}</text>"#,
                Px(x),
                Px(y),
                escape(label),
                escape(&short)
            );
        }
    }

    /// A marker of `style` centred on `(x, y)`, `size` px across, with an optional tooltip.
    pub fn marker(&mut self, (x, y): (f64, f64), style: Style, size: f64, tooltip: Option<&str>) {
        let r = size / 2.0;
        let colour = style.colour;
        let filled = format!(r##"fill="{colour}" stroke="#ffffff" stroke-width="0.8""##);
        let shape = match style.shape {
            Shape::Circle => {
                format!(r#"<circle cx="{}" cy="{}" r="{}" {filled}"#, Px(x), Px(y), Px(r))
            }
            Shape::Square => {
                let side = size * 0.88;
                format!(
                    r#"<rect x="{}" y="{}" width="{}" height="{}" {filled}"#,
                    Px(x - side / 2.0),
                    Px(y - side / 2.0),
                    Px(side),
                    Px(side)
                )
            }
            Shape::TriangleUp | Shape::TriangleDown => {
                let r = r * 1.2;
                let sign = if style.shape == Shape::TriangleUp { 1.0 } else { -1.0 };
                let (top, bottom) = (y - sign * r, y + sign * r * 0.6);
                let half = r * 0.95;
                format!(
                    r#"<path d="M{} {}L{} {}L{} {}Z" {filled}"#,
                    Px(x),
                    Px(top),
                    Px(x + half),
                    Px(bottom),
                    Px(x - half),
                    Px(bottom)
                )
            }
            Shape::Diamond => {
                let r = r * 1.2;
                format!(
                    r#"<path d="M{} {}L{} {}L{} {}L{} {}Z" {filled}"#,
                    Px(x),
                    Px(y - r),
                    Px(x + r),
                    Px(y),
                    Px(x),
                    Px(y + r),
                    Px(x - r),
                    Px(y)
                )
            }
            Shape::Cross => {
                let r = r * 0.9;
                format!(
                    r#"<path d="M{} {}L{} {}M{} {}L{} {}" fill="none" stroke="{colour}" stroke-width="2.2" stroke-linecap="round""#,
                    Px(x - r),
                    Px(y - r),
                    Px(x + r),
                    Px(y + r),
                    Px(x - r),
                    Px(y + r),
                    Px(x + r),
                    Px(y - r)
                )
            }
        };
        match tooltip {
            Some(tooltip) => {
                let _ = writeln!(self.out, "{shape}><title>{}</title></{}>", escape(tooltip), tag(&shape));
            }
            None => {
                let _ = writeln!(self.out, "{shape}/>");
            }
        }
    }

    pub fn finish(mut self) -> String {
        self.out.push_str("</svg>\n");
        self.out
    }
}

/// The element name at the start of `markup` (`<circle …` → `circle`).
fn tag(markup: &str) -> &str {
    markup.trim_start_matches('<').split(' ').next().unwrap_or("g")
}

/// Where each legend entry goes: its x offset from the legend's left edge and its line.
pub(super) struct LegendLayout {
    pub places: Vec<(f64, usize)>,
    pub n_lines: usize,
}

/// Width of the swatch (a short line with the marker on it) before each legend name.
const SWATCH: f64 = 24.0;

/// Lays out legend entries left to right, wrapping at `max_width`.
pub(super) fn legend_layout(names: &[&str], max_width: f64) -> LegendLayout {
    let mut places = Vec::with_capacity(names.len());
    let (mut x, mut line) = (0.0, 0);
    for name in names {
        let width = SWATCH + 6.0 + text_width(&shorten(name), LABEL_SIZE);
        if x > 0.0 && x + width > max_width {
            x = 0.0;
            line += 1;
        }
        places.push((x, line));
        x += width + 20.0;
    }
    LegendLayout { places, n_lines: if names.is_empty() { 0 } else { line + 1 } }
}

/// Draws the legend laid out by [`legend_layout`] with its first line centred on `y`.
pub(super) fn draw_legend(svg: &mut Svg, names: &[&str], layout: &LegendLayout, (x0, y): (f64, f64)) {
    for (series_idx, (name, &(dx, line))) in names.iter().zip(&layout.places).enumerate() {
        let style = style(series_idx);
        let (x, y) = (x0 + dx, y + line as f64 * LEGEND_LINE);
        svg.line((x, y), (x + SWATCH, y), style.colour, 1.8);
        svg.marker((x + SWATCH / 2.0, y), style, 9.0, None);
        svg.label((x + SWATCH + 6.0, y + 0.35 * LABEL_SIZE), name, "");
    }
}

/// The figure for a plot without data: its title and the words "no data".
pub(super) fn no_data(title_text: &str) -> String {
    let title = Title::layout(title_text, 480.0);
    let width = title.width;
    let height = 160.0 + title.height();
    let mut svg = Svg::new(width, height, title_text);
    title.draw(&mut svg, width / 2.0, OUTER);
    svg.text(
        (width / 2.0, (height + OUTER + title.height()) / 2.0 + 8.0),
        "no data",
        &format!(r#"text-anchor="middle" font-size="{}" fill="{MUTED}""#, Px(LABEL_SIZE + 2.0)),
    );
    svg.finish()
}

pub(super) fn title_attributes() -> String {
    format!(r#"text-anchor="middle" font-size="{}" font-weight="bold""#, Px(TITLE_SIZE))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn px_is_compact_and_never_non_finite() {
        assert_eq!(Px(12.0).to_string(), "12");
        assert_eq!(Px(12.5).to_string(), "12.5");
        assert_eq!(Px(12.345).to_string(), "12.35");
        assert_eq!(Px(-0.001).to_string(), "0");
        assert_eq!(Px(-3.10).to_string(), "-3.1");
        assert_eq!(Px(f64::NAN).to_string(), "0");
        assert_eq!(Px(f64::INFINITY).to_string(), "0");
    }

    #[test]
    fn escape_handles_markup_quotes_and_control_characters() {
        assert_eq!(escape(r#"a<b>&"c"'"#), "a&lt;b&gt;&amp;&quot;c&quot;&apos;");
        assert_eq!(escape("x\u{0}y\nz"), "x\u{FFFD}y z");
        assert_eq!(escape("λ π …"), "λ π …");
    }

    #[test]
    fn shorten_keeps_short_labels_and_cuts_long_ones() {
        assert_eq!(shorten("GI+CA"), "GI+CA");
        let long = "x".repeat(MAX_LABEL_CHARS + 5);
        let short = shorten(&long);
        assert_eq!(short.chars().count(), MAX_LABEL_CHARS);
        assert!(short.ends_with('…'));
    }

    #[test]
    fn legend_wraps_when_too_wide() {
        let names = ["all", "female", "male"];
        assert_eq!(legend_layout(&names, 1000.0).n_lines, 1);
        assert_eq!(legend_layout(&names, 80.0).n_lines, 3);
        assert_eq!(legend_layout(&[], 80.0).n_lines, 0);
    }
}
