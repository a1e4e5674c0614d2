//! The plain-text report of a task analysis for the terminal: per measure, the descriptives, the
//! Friedman test with Kendall's W, the post hoc tests and the warnings.

use std::fmt::Write as _;

use super::measure::plural;
use super::{TaskAnalysis, WilcoxonMethod};

/// A readable plain-text report for the terminal: per measure, the descriptives, the Friedman
/// test with Kendall's W, the post hoc tests and the warnings.
pub fn render_table(analysis: &TaskAnalysis) -> String {
    let mut out = String::new();
    for (measure_idx, measure) in analysis.measures.iter().enumerate() {
        if measure_idx > 0 {
            out.push('\n');
        }
        let title = if measure.group.is_empty() { analysis.source.clone() } else { measure.group.label() };
        let _ = writeln!(
            out,
            "{title}: {} participant{}, {} condition{}",
            measure.participants,
            plural(measure.participants),
            measure.conditions.len(),
            plural(measure.conditions.len())
        );

        let mut header = vec!["condition", "n", "mean", "sd", "median", "q1", "q3", "min", "max"];
        let with_ranks = measure.conditions.iter().any(|condition| condition.mean_rank.is_some());
        if with_ranks {
            header.push("mean rank");
        }
        let rows: Vec<Vec<String>> = measure
            .conditions
            .iter()
            .map(|condition| {
                let mut row = vec![
                    condition.condition.clone(),
                    condition.n.to_string(),
                    format_number(condition.mean),
                    condition.sd.map_or_else(|| "–".to_string(), format_number),
                    format_number(condition.median),
                    format_number(condition.q1),
                    format_number(condition.q3),
                    format_number(condition.min),
                    format_number(condition.max),
                ];
                if with_ranks {
                    row.push(condition.mean_rank.map_or_else(|| "–".to_string(), |rank| format!("{rank:.2}")));
                }
                row
            })
            .collect();
        write_columns(&mut out, &header, &rows);

        if let Some(friedman) = &measure.friedman {
            let _ = writeln!(
                out,
                "Friedman χ²({}) = {}, {}, n = {}, Kendall's W = {:.3}",
                friedman.df,
                format_number(friedman.statistic),
                friedman.p.equation(),
                friedman.participants,
                friedman.kendall_w
            );
        }
        if !measure.post_hoc.is_empty() {
            out.push_str("Post hoc: Wilcoxon signed-rank, paired, two-sided; p Holm-adjusted\n");
            let header = ["pair", "n", "V", "method", "p", "p (Holm)"];
            let rows: Vec<Vec<String>> = measure
                .post_hoc
                .iter()
                .map(|pair| {
                    let test = pair.test.as_ref();
                    vec![
                        format!("{} – {}", pair.condition_a, pair.condition_b),
                        pair.n.to_string(),
                        test.map_or_else(|| "–".to_string(), |test| format_rank_sum(test.v)),
                        match test.and_then(|test| test.method) {
                            Some(WilcoxonMethod::Exact) => "exact".to_string(),
                            Some(WilcoxonMethod::Normal) => "normal".to_string(),
                            None => "–".to_string(),
                        },
                        match (test.and_then(|test| test.p), &pair.not_estimable) {
                            (Some(p), _) => p.display(),
                            (None, Some(_)) => "not estimable".to_string(),
                            (None, None) => "–".to_string(),
                        },
                        pair.p_holm.map_or_else(|| "–".to_string(), |p| p.display()),
                    ]
                })
                .collect();
            write_columns(&mut out, &header, &rows);
        }
        for warning in &measure.warnings {
            let _ = writeln!(out, "warning: {warning}");
        }
    }
    out
}

/// Writes rows under a header, the first column left-aligned and the others right-aligned.
fn write_columns(out: &mut String, header: &[&str], rows: &[Vec<String>]) {
    let mut widths: Vec<usize> = header.iter().map(|cell| cell.chars().count()).collect();
    for row in rows {
        for (width, cell) in widths.iter_mut().zip(row) {
            *width = (*width).max(cell.chars().count());
        }
    }
    let mut write_row = |cells: Vec<&str>| {
        let mut line = String::new();
        for (column_idx, (cell, width)) in cells.iter().zip(&widths).enumerate() {
            let padding = " ".repeat(width - cell.chars().count());
            if column_idx == 0 {
                line.push_str(cell);
                line.push_str(&padding);
            } else {
                line.push_str("  ");
                line.push_str(&padding);
                line.push_str(cell);
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
    };
    write_row(header.to_vec());
    for row in rows {
        write_row(row.iter().map(String::as_str).collect());
    }
}

/// A sum of (mid)ranks: a multiple of 0.5, shown without trailing zeros.
fn format_rank_sum(value: f64) -> String {
    if value.fract() == 0.0 { format!("{value:.0}") } else { format!("{value:.1}") }
}

/// Four significant digits in fixed notation for ordinary magnitudes, scientific otherwise.
fn format_number(value: f64) -> String {
    let magnitude = value.abs();
    if magnitude == 0.0 {
        "0".to_string()
    } else if !(1e-3..1e6).contains(&magnitude) {
        format!("{value:.3e}")
    } else {
        let decimals = (3 - magnitude.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{value:.decimals$}")
    }
}
