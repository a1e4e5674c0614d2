//! The analysis's benchmark, behind `mrstudy bench analysis`: the time of the whole
//! paired-comparison analysis against the number of judgments and of conditions, and time and
//! error of the log-worth against the convergence tolerance, on synthetic studies
//! ([`synthetic`]). Returns a typed [`Report`] (docs/design.md's bench JSON by [`Report::to_json`]);
//! table lines go to a callback as the rows are measured. The `end_to_end` row times what
//! `mrstudy analyze` does with a trials CSV of 10⁶ judgments ([`synthetic_csv`]: 8 conditions,
//! factors, two groups), parsing included. The targets are stated for one core:
//! the caller runs it on a one-thread rayon pool.

use std::fmt::Write as _;
use std::time::Instant;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::agreement::AgreementMethod;
use crate::analysis::{Options, Screening, analyze, analyze_judgments};
use crate::data::{ConditionTable, Judgment, Judgments};
use crate::error::Result;
use crate::plot::{LinePlot, LineSeries};

/// One row of the benchmark.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum AnalysisRow {
    Size(SizeRow),
    Tolerance(ToleranceRow),
    EndToEnd(EndToEndRow),
}

/// `mrstudy analyze` as the command runs it, from the CSV text to the analysis: parsing, item
/// and factor models, agreement, observer screening and the per-group analyses, with defaults.
#[derive(Clone, Debug, Serialize)]
pub struct EndToEndRow {
    /// Always `end_to_end`.
    pub bench: &'static str,
    pub conditions: usize,
    pub judgments: usize,
    /// Groups of `--group-by`.
    pub groups: usize,
    /// Fastest of five runs of the whole (wall time: on a shared machine the minimum is what
    /// other work inflates least; `examples/end_to_end.rs` also reports this thread's CPU time).
    pub ms: f64,
    /// Fastest of five runs of parsing the trials and conditions CSV alone.
    pub parse_ms: f64,
    pub participants: usize,
}

/// The whole analysis at the default tolerance (1e-10) on one study size.
#[derive(Clone, Debug, Serialize)]
pub struct SizeRow {
    /// `size` (judgments varied) or `conditions` (conditions varied).
    pub bench: &'static str,
    pub conditions: usize,
    pub judgments: usize,
    /// Median wall time.
    pub ms: f64,
    pub item_iterations: usize,
    pub agreement_method: AgreementMethod,
}

/// The analysis at one convergence tolerance, against a fit at 1e-14.
#[derive(Clone, Debug, Serialize)]
pub struct ToleranceRow {
    /// Always `tolerance`.
    pub bench: &'static str,
    pub conditions: usize,
    pub judgments: usize,
    pub tolerance: f64,
    pub ms: f64,
    /// Largest |Δλ| of a condition's log-worth against the reference fit.
    pub max_abs_error: f64,
    pub item_iterations: usize,
}

/// The benchmark's result: the adapter (none: `cpu`), the rows and the plots (file name, plot).
#[derive(Clone, Debug)]
pub struct Report {
    pub adapter: String,
    pub rows: Vec<AnalysisRow>,
    pub plots: Vec<(String, LinePlot)>,
}

impl Report {
    /// docs/design.md's bench JSON: `{"adapter": "...", "rows": [...]}`.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({ "adapter": self.adapter, "rows": self.rows })
    }
}

/// A synthetic paired-comparison study: `n_conditions` conditions with true log-worth from
/// three binary factors plus noise, `n_judgments` judgments on random pairs (a full design when
/// the conditions are few), 65 judgments per participant.
pub fn synthetic(n_conditions: usize, n_judgments: usize, seed: u64) -> (Judgments, ConditionTable) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let factors = ["gi", "cm", "ca"];
    let levels: Vec<Vec<f64>> = (0..n_conditions).map(|c| (0..3).map(|k| ((c >> k) & 1) as f64).collect()).collect();
    let lambda: Vec<f64> =
        levels.iter().map(|x| 0.54 * x[0] - 0.44 * x[1] + 0.86 * x[2] + 0.3 * (rng.random::<f64>() - 0.5)).collect();
    let conditions: Vec<String> = (0..n_conditions).map(|c| format!("C{c:04}")).collect();
    let n_participants = n_judgments.div_ceil(65);
    let rows = (0..n_judgments)
        .map(|k| {
            let left = rng.random_range(0..n_conditions);
            let mut right = rng.random_range(0..n_conditions - 1);
            if right >= left {
                right += 1;
            }
            let p_left = 1.0 / (1.0 + (lambda[right] - lambda[left]).exp());
            Judgment {
                participant: (k / 65) as u32,
                left: left as u32,
                right: right as u32,
                left_chosen: rng.random::<f64>() < p_left,
                count: 1,
                group: 0,
            }
        })
        .collect();
    let judgments = Judgments {
        conditions: conditions.clone(),
        participants: (0..n_participants).map(|p| format!("p{p}")).collect(),
        groups: Vec::new(),
        rows,
    };
    let table = ConditionTable { conditions, factors: factors.iter().map(|f| f.to_string()).collect(), levels };
    (judgments, table)
}

/// Condition names of the 2×2×2 factorial, indexed by the bits (gi, cm, ca) of the index.
const FACTORIAL_NAMES: [&str; 8] = ["LQ", "GI", "CM", "GI+CM", "CA", "GI+CA", "CM+CA", "HQ"];

/// A synthetic study of [`synthetic`] with 8 conditions as the text `mrstudy analyze` reads: an
/// export-like trials CSV (`participant,trial,left,right,chosen,rt_ms,pilot,excluded,gender`,
/// two groups) and its conditions CSV (`condition,gi,cm,ca`).
pub fn synthetic_csv(n_judgments: usize, seed: u64) -> (String, String) {
    let (judgments, table) = synthetic(8, n_judgments, seed);
    let mut trials = String::with_capacity(n_judgments * 48);
    trials.push_str("participant,trial,left,right,chosen,rt_ms,pilot,excluded,gender\n");
    for (k, row) in judgments.rows.iter().enumerate() {
        let (left, right) = (FACTORIAL_NAMES[row.left as usize], FACTORIAL_NAMES[row.right as usize]);
        let chosen = if row.left_chosen { left } else { right };
        let gender = if row.participant % 3 == 0 { "female" } else { "male" };
        let _ = writeln!(
            trials,
            "{},{},{left},{right},{chosen},{},false,false,{gender}",
            judgments.participants[row.participant as usize],
            k % 65 + 1,
            700 + (k * 7919) % 1500
        );
    }
    let mut conditions = String::from("condition,gi,cm,ca\n");
    for (name, levels) in FACTORIAL_NAMES.iter().zip(&table.levels) {
        let _ = writeln!(conditions, "{name},{},{},{}", levels[0], levels[1], levels[2]);
    }
    (trials, conditions)
}

fn options(tolerance: f64) -> Options {
    Options { tolerance, screening: Screening::Off, bootstrap: 0, ..Options::default() }
}

/// Wall times in ms of `repeats` runs of `f`, sorted, and the last run's result.
fn times_ms<T>(repeats: usize, mut f: impl FnMut() -> T) -> (Vec<f64>, T) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeats {
        let start = Instant::now();
        let out = f();
        times.push(start.elapsed().as_secs_f64() * 1e3);
        last = Some(out);
    }
    times.sort_by(f64::total_cmp);
    (times, last.expect("repeats > 0"))
}

/// Median wall time in ms of `repeats` runs of `f`, and the last run's result.
fn time_ms<T>(repeats: usize, f: impl FnMut() -> T) -> (f64, T) {
    let (times, last) = times_ms(repeats, f);
    (times[times.len() / 2], last)
}

/// Fastest wall time in ms of `repeats` runs of `f`, and the last run's result.
fn fastest_ms<T>(repeats: usize, f: impl FnMut() -> T) -> (f64, T) {
    let (times, last) = times_ms(repeats, f);
    (times[0], last)
}

fn size_line(row: &SizeRow) -> String {
    format!(
        "{:<12} {:>10} {:>12} {:>10} {:>12.2} {:>14}",
        row.bench, row.conditions, row.judgments, "1e-10", row.ms, ""
    )
}

/// Runs the benchmark (`quick`: smaller sizes only); `line` receives the table's lines.
pub fn run(quick: bool, line: &dyn Fn(&str)) -> Result<Report> {
    let mut rows = Vec::new();
    line(&format!(
        "{:<12} {:>10} {:>12} {:>10} {:>12} {:>14}",
        "bench", "conditions", "judgments", "tolerance", "ms", "max |Δλ|"
    ));

    // Size: 1e3 … 1e7 judgments on 8 conditions.
    let sizes: &[usize] =
        if quick { &[1_000, 10_000, 100_000] } else { &[1_000, 10_000, 100_000, 1_000_000, 10_000_000] };
    let mut size_points = Vec::new();
    for &n in sizes {
        let (judgments, table) = synthetic(8, n, 1);
        let repeats = if n >= 1_000_000 { 3 } else { 7 };
        let (ms, analysis) = time_ms(repeats, || analyze_judgments(&judgments, Some(&table), &options(1e-10)));
        let analysis = analysis?;
        let row = SizeRow {
            bench: "size",
            conditions: 8,
            judgments: n,
            ms,
            item_iterations: analysis.item_model.iterations,
            agreement_method: analysis.agreement.method,
        };
        line(&size_line(&row));
        size_points.push((n as f64, ms));
        rows.push(AnalysisRow::Size(row));
    }

    // End to end: the trials CSV text of 1e6 judgments (8 conditions, factors, two groups).
    let n = if quick { 100_000 } else { 1_000_000 };
    let (trials, conditions) = synthetic_csv(n, 4);
    let end_to_end_options = Options { group_by: Some("gender".into()), ..Options::default() };
    let (parse_ms, _) = fastest_ms(5, || {
        let table = crate::data::parse_conditions(&conditions, "conditions CSV")?;
        let options = crate::data::TrialsOptions { group_by: Some("gender".into()), ..Default::default() };
        crate::data::parse_trials_with(&trials, "trials CSV", Some(&table), &options)
    });
    let (ms, analysis) = fastest_ms(5, || analyze(&trials, Some(&conditions), &end_to_end_options));
    let analysis = analysis?;
    let row = EndToEndRow {
        bench: "end_to_end",
        conditions: 8,
        judgments: n,
        groups: analysis.groups.as_ref().map_or(0, |g| g.len()),
        ms,
        parse_ms,
        participants: analysis.participants,
    };
    line(&format!(
        "{:<12} {:>10} {:>12} {:>10} {:>12.2} {:>14}",
        row.bench,
        row.conditions,
        row.judgments,
        "1e-10",
        row.ms,
        format!("parse {parse_ms:.1}")
    ));
    rows.push(AnalysisRow::EndToEnd(row));

    // Conditions: 10 … 2000 with 1e6 judgments.
    let counts: &[usize] = if quick { &[10, 100, 500] } else { &[10, 50, 100, 500, 1000, 2000] };
    let n = if quick { 100_000 } else { 1_000_000 };
    let mut condition_points = Vec::new();
    for &t in counts {
        let (judgments, table) = synthetic(t, n, 2);
        let (ms, analysis) =
            time_ms(if t >= 1000 { 1 } else { 3 }, || analyze_judgments(&judgments, Some(&table), &options(1e-10)));
        let analysis = analysis?;
        let row = SizeRow {
            bench: "conditions",
            conditions: t,
            judgments: n,
            ms,
            item_iterations: analysis.item_model.iterations,
            agreement_method: analysis.agreement.method,
        };
        line(&size_line(&row));
        condition_points.push((t as f64, ms));
        rows.push(AnalysisRow::Size(row));
    }

    // Tolerance: time and error against a fit at 1e-14.
    let mut tolerance_series = Vec::new();
    for &(t, n) in if quick { &[(8usize, 100_000usize)][..] } else { &[(8, 1_000_000), (500, 1_000_000)][..] } {
        let (judgments, table) = synthetic(t, n, 3);
        let reference = analyze_judgments(&judgments, Some(&table), &options(1e-14))?;
        let mut time_points = Vec::new();
        let mut error_points = Vec::new();
        for tolerance in [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12] {
            let (ms, analysis) = time_ms(3, || analyze_judgments(&judgments, Some(&table), &options(tolerance)));
            let analysis = analysis?;
            let error = analysis
                .items
                .iter()
                .zip(&reference.items)
                .filter_map(|(a, b)| Some((a.log_worth? - b.log_worth?).abs()))
                .fold(0.0, f64::max);
            line(&format!(
                "{:<12} {:>10} {:>12} {:>10} {:>12.2} {:>14}",
                "tolerance",
                t,
                n,
                format!("{tolerance:.0e}"),
                ms,
                format!("{error:.2e}")
            ));
            time_points.push((tolerance, ms));
            error_points.push((tolerance, error.max(1e-17)));
            rows.push(AnalysisRow::Tolerance(ToleranceRow {
                bench: "tolerance",
                conditions: t,
                judgments: n,
                tolerance,
                ms,
                max_abs_error: error,
                item_iterations: analysis.item_model.iterations,
            }));
        }
        tolerance_series.push((format!("{t} conditions"), time_points, error_points));
    }

    let log_log = |title: String, x_label: &str, y_label: &str, series: Vec<LineSeries>| LinePlot {
        title,
        x_label: x_label.into(),
        y_label: y_label.into(),
        x_log: true,
        y_log: true,
        series,
    };
    let whole = |points| vec![LineSeries { name: "item + factor fit, SEs, agreement".into(), points }];
    let plots = vec![
        (
            "analysis-size.svg".to_string(),
            log_log(
                "Full analysis time against judgments (8 conditions, one core)".into(),
                "judgments",
                "time (ms)",
                whole(size_points),
            ),
        ),
        (
            "analysis-conditions.svg".to_string(),
            log_log(
                format!("Full analysis time against conditions ({n} judgments, one core)"),
                "conditions",
                "time (ms)",
                whole(condition_points),
            ),
        ),
        (
            "analysis-tolerance.svg".to_string(),
            log_log(
                "Error of log-worth against convergence tolerance (reference: tolerance 1e-14)".into(),
                "tolerance",
                "max |Δλ|",
                tolerance_series
                    .iter()
                    .map(|(name, _, error)| LineSeries { name: name.clone(), points: error.clone() })
                    .collect(),
            ),
        ),
        (
            "analysis-tolerance-time.svg".to_string(),
            log_log(
                "Analysis time against convergence tolerance (1e6 judgments, one core)".into(),
                "tolerance",
                "time (ms)",
                tolerance_series
                    .iter()
                    .map(|(name, time, _)| LineSeries { name: name.clone(), points: time.clone() })
                    .collect(),
            ),
        ),
    ];
    Ok(Report { adapter: "cpu (analysis needs no GPU)".to_string(), rows, plots })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_studies_have_the_asked_size_and_factor_levels() {
        let (judgments, table) = synthetic(8, 1000, 1);
        assert_eq!(judgments.rows.len(), 1000);
        assert_eq!(judgments.participants.len(), 16);
        assert_eq!(table.levels[5], [1.0, 0.0, 1.0]);
        assert!(judgments.rows.iter().all(|j| j.left != j.right && j.left < 8 && j.right < 8));
    }

    #[test]
    fn synthetic_csv_is_read_back_as_the_synthetic_study() {
        let (judgments, _) = synthetic(8, 650, 9);
        let (trials, conditions) = synthetic_csv(650, 9);
        let table = crate::data::parse_conditions(&conditions, "c").unwrap();
        let options = crate::data::TrialsOptions { group_by: Some("gender".into()), ..Default::default() };
        let parsed = crate::data::parse_trials_with(&trials, "t", Some(&table), &options).unwrap().judgments;
        assert_eq!(parsed.groups, ["female", "male"]);
        for (read, made) in parsed.rows.iter().zip(&judgments.rows) {
            assert_eq!((read.left, read.right, read.left_chosen), (made.left, made.right, made.left_chosen));
        }
        assert_eq!(table.levels, synthetic(8, 1, 9).1.levels);
    }
}
