//! The report of a threshold simulation: one row per method × trials per participant, as JSON,
//! a text table, plots, and the trials needed for the tolerance (`mrstudy power`).

use mrstudy_analysis::plot::{LinePlot, LineSeries};
use mrstudy_analysis::table::fixed;
use mrstudy_analysis::threshold::quest::{PsychFunction, StimScale};
use serde::Serialize;

use super::super::report::{Estimate, cell};
use super::{Outcome, TOLERANCE_LOG10};

/// How a simulated participant's levels are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Method {
    /// The study's QUEST+ selection (minimum expected entropy), as the server runs it.
    #[serde(rename = "quest+")]
    QuestPlus,
    /// The trials spread evenly over the study's levels.
    #[serde(rename = "constant-stimuli")]
    ConstantStimuli,
}

impl Method {
    pub const ALL: [Method; 2] = [Method::QuestPlus, Method::ConstantStimuli];

    pub fn name(self) -> &'static str {
        match self {
            Method::QuestPlus => "quest+",
            Method::ConstantStimuli => "constant-stimuli",
        }
    }

    pub(super) fn code(self) -> u64 {
        self as u64
    }
}

/// The simulated observers' psychometric function.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThresholdTruth {
    pub function: PsychFunction,
    pub scale: StimScale,
    pub guess: f64,
    /// The population's threshold and the slope (x units).
    pub threshold: f64,
    pub slope: f64,
    pub lapse: f64,
    /// sd of a participant's threshold around `threshold` (x units; relative on the linear Weibull).
    pub threshold_sd: f64,
    /// The levels' x range, lowest and highest.
    pub levels_x: [f64; 2],
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThresholdSettings {
    /// Simulated participants per row.
    pub runs: usize,
    pub seed: u64,
    /// Bootstrap replicates per fit.
    pub bootstrap: usize,
    /// ±tolerance in x units ([`TOLERANCE_LOG10`] log10 units).
    pub tolerance: f64,
}

/// One method × trials per participant.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThresholdRow {
    pub method: Method,
    pub trials_per_participant: usize,
    /// Simulated participants.
    pub participants: usize,
    /// Participants whose trials could not be simulated (never with a lapse grid that has a
    /// positive value), with the first one's sentence.
    pub failed: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// Share of participants whose fit is degenerate (all correct, all wrong: no estimate).
    pub degenerate: Estimate,
    /// Estimate − true threshold over the participants with an estimate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse: Option<Estimate>,
    /// Share of 95 % intervals holding the participant's threshold.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ci_width: Option<Estimate>,
    /// Share of all participants (a degenerate fit counts as outside) whose estimate is within
    /// ±tolerance of their threshold.
    pub within_tolerance: Estimate,
}

/// Everything `mrstudy simulate` reports for a threshold study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThresholdReport {
    pub study: String,
    /// `"threshold"`, telling this report from a paired comparison's.
    pub kind: &'static str,
    pub truth: ThresholdTruth,
    pub settings: ThresholdSettings,
    pub rows: Vec<ThresholdRow>,
}

/// The tolerance in x units: 0.1 log10 units, 2 dB, or 0.1 on a linear scale.
pub(super) fn tolerance(scale: StimScale) -> f64 {
    match scale {
        StimScale::Db => 20.0 * TOLERANCE_LOG10,
        StimScale::Log10 | StimScale::Linear => TOLERANCE_LOG10,
    }
}

/// A share with its binomial Monte-Carlo error.
fn share(hits: usize, n: usize) -> Estimate {
    let p = hits as f64 / n.max(1) as f64;
    Estimate { mean: p, mcse: (n > 1).then(|| (p * (1.0 - p) / n as f64).sqrt()) }
}

pub(super) fn summarise(method: Method, trials: usize, runs: &[Outcome], tolerance: f64) -> ThresholdRow {
    let n = runs.len();
    let errors: Vec<f64> = runs.iter().filter_map(|run| run.error).collect();
    let squares: Vec<f64> = errors.iter().map(|e| e * e).collect();
    let rmse = Estimate::of(&squares).map(|mse| {
        let rmse = mse.mean.sqrt();
        Estimate { mean: rmse, mcse: mse.mcse.map(|se| if rmse > 0.0 { se / (2.0 * rmse) } else { 0.0 }) }
    });
    let covered: Vec<f64> = runs.iter().filter_map(|run| run.covered.map(f64::from)).collect();
    let widths: Vec<f64> = runs.iter().filter_map(|run| run.width).collect();
    let failed = runs.iter().filter(|run| run.failure.is_some()).count();
    ThresholdRow {
        method,
        trials_per_participant: trials,
        participants: n,
        failed,
        failure: runs.iter().find_map(|run| run.failure.clone()),
        degenerate: share(runs.iter().filter(|run| run.error.is_none() && run.failure.is_none()).count(), n),
        bias: Estimate::of(&errors),
        rmse,
        coverage: Estimate::of(&covered),
        ci_width: Estimate::of(&widths),
        within_tolerance: share(errors.iter().filter(|e| e.abs() <= tolerance).count(), n),
    }
}

/// The trials per participant a method needs for the tolerance.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThresholdNeed {
    pub method: Method,
    /// The smallest simulated count whose share within ±tolerance reaches the target.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub within_target: Option<usize>,
    /// Trials at which the RMSE falls to the tolerance, interpolated linearly in log trials and
    /// log RMSE between the two simulated counts around it (absent outside them).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_at_tolerance: Option<f64>,
    /// The best share seen, at its count.
    pub best_within: f64,
    pub best_at: usize,
}

impl ThresholdReport {
    fn rows_of(&self, method: Method) -> Vec<&ThresholdRow> {
        self.rows.iter().filter(|row| row.method == method).collect()
    }

    /// Per method, the trials per participant the tolerance needs (`target`: the share of
    /// participants within it).
    pub fn needs(&self, target: f64) -> Vec<ThresholdNeed> {
        let tolerance = self.settings.tolerance;
        Method::ALL
            .iter()
            .filter_map(|&method| {
                let rows = self.rows_of(method);
                let best = rows.iter().max_by(|a, b| a.within_tolerance.mean.total_cmp(&b.within_tolerance.mean))?;
                let curve: Vec<(f64, f64)> = rows
                    .iter()
                    .filter_map(|row| Some((row.trials_per_participant as f64, row.rmse?.mean)))
                    .filter(|&(_, rmse)| rmse > 0.0)
                    .collect();
                let rmse_at_tolerance = curve.windows(2).find_map(|pair| {
                    let [(n0, r0), (n1, r1)] = [pair[0], pair[1]];
                    (r0 > tolerance && r1 <= tolerance).then(|| {
                        let f = (tolerance.ln() - r0.ln()) / (r1.ln() - r0.ln());
                        (n0.ln() + f * (n1.ln() - n0.ln())).exp()
                    })
                });
                Some(ThresholdNeed {
                    method,
                    within_target: rows
                        .iter()
                        .find(|row| row.within_tolerance.mean >= target)
                        .map(|row| row.trials_per_participant),
                    rmse_at_tolerance: rmse_at_tolerance
                        .or_else(|| curve.first().filter(|&&(_, rmse)| rmse <= tolerance).map(|&(n, _)| n)),
                    best_within: best.within_tolerance.mean,
                    best_at: best.trials_per_participant,
                })
            })
            .collect()
    }

    /// `mrstudy power`'s sentences for a threshold study.
    pub fn power_lines(&self, target: f64) -> Vec<String> {
        let tolerance = fixed(self.settings.tolerance, 2);
        self.needs(target)
            .iter()
            .map(|need| {
                let share = match need.within_target {
                    Some(n) => format!(
                        "{n} trials per participant put {} % of thresholds within ±{tolerance} of the truth",
                        fixed(100.0 * target, 0)
                    ),
                    None => format!(
                        "no simulated trial count put {} % of thresholds within ±{tolerance} (best {} % at {} trials)",
                        fixed(100.0 * target, 0),
                        fixed(100.0 * need.best_within, 0),
                        need.best_at
                    ),
                };
                let rmse = match need.rmse_at_tolerance {
                    Some(n) => format!("the RMSE reaches {tolerance} at about {} trials", fixed(n, 0)),
                    None => format!("the RMSE does not reach {tolerance} within the simulated trial counts"),
                };
                format!("{}: {share}; {rmse}", need.method.name())
            })
            .collect()
    }

    /// The plain-text table, then notes.
    pub fn table(&self) -> String {
        let header = [
            "method",
            "trials/participant",
            "participants",
            "degenerate",
            "bias",
            "RMSE",
            "coverage",
            "CI width",
            "within ±tol",
        ];
        let mut lines = vec![header.iter().map(|h| h.to_string()).collect::<Vec<_>>()];
        for row in &self.rows {
            lines.push(vec![
                row.method.name().to_string(),
                row.trials_per_participant.to_string(),
                row.participants.to_string(),
                cell(Some(row.degenerate), 2),
                cell(row.bias, 3),
                cell(row.rmse, 3),
                cell(row.coverage, 3),
                cell(row.ci_width, 2),
                cell(Some(row.within_tolerance), 2),
            ]);
        }
        let widths: Vec<usize> =
            (0..lines[0].len()).map(|c| lines.iter().map(|line| line[c].chars().count()).max().unwrap_or(0)).collect();
        let mut text = String::new();
        for line in &lines {
            let cells: Vec<String> = line.iter().zip(&widths).map(|(cell, &width)| format!("{cell:>width$}")).collect();
            text += cells.join("  ").trim_end();
            text.push('\n');
        }
        let truth = &self.truth;
        text += &format!(
            "threshold estimates (the psychometric fit per participant) against each participant's true threshold, x units ({} {}, guess {}); observers: threshold {} ± sd {}, slope {}, lapse {}; tol = ±{} x units; ± is the Monte-Carlo standard error over {} participants; intervals: parametric bootstrap, {} replicates\n",
            truth.function.name(),
            truth.scale.name(),
            fixed(truth.guess, 2),
            fixed(truth.threshold, 3),
            fixed(truth.threshold_sd, 3),
            fixed(truth.slope, 2),
            fixed(truth.lapse, 3),
            fixed(self.settings.tolerance, 2),
            self.settings.runs,
            self.settings.bootstrap
        );
        for row in self.rows.iter().filter(|row| row.failed > 0) {
            text += &format!(
                "{} with {} trials: {} of {} participants could not be simulated, e.g. {}\n",
                row.method.name(),
                row.trials_per_participant,
                row.failed,
                row.participants,
                row.failure.as_deref().unwrap_or("no reason given")
            );
        }
        text
    }

    /// `simulate-threshold.svg`: RMSE of the threshold against trials per participant, one
    /// series per method and the tolerance; `simulate-threshold-coverage.svg`: coverage and the
    /// share within the tolerance.
    pub fn plots(&self) -> Vec<(String, LinePlot)> {
        let series = |pick: &dyn Fn(&ThresholdRow) -> Option<f64>, suffix: &str| -> Vec<LineSeries> {
            Method::ALL
                .iter()
                .map(|&method| LineSeries {
                    name: format!("{}{suffix}", method.name()),
                    points: self
                        .rows_of(method)
                        .iter()
                        .filter_map(|row| Some((row.trials_per_participant as f64, pick(row)?)))
                        .collect(),
                })
                .filter(|series| !series.points.is_empty())
                .collect()
        };
        let counts: Vec<f64> = self.rows.iter().map(|row| row.trials_per_participant as f64).collect();
        let (first, last) = (
            counts.iter().copied().fold(f64::INFINITY, f64::min),
            counts.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        let mut rmse = series(&|row| row.rmse.map(|rmse| rmse.mean), "");
        let tolerance = self.settings.tolerance;
        rmse.push(LineSeries {
            name: format!("±{} (tolerance)", fixed(tolerance, 2)),
            points: vec![(first, tolerance), (last, tolerance)],
        });
        let mut shares = series(&|row| row.coverage.map(|coverage| coverage.mean), " coverage");
        shares.extend(series(&|row| Some(row.within_tolerance.mean), " within ±tol"));
        shares.push(LineSeries { name: "95 %".into(), points: vec![(first, 0.95), (last, 0.95)] });
        vec![
            (
                "simulate-threshold.svg".into(),
                LinePlot {
                    title: format!("{}: RMSE of a participant's threshold against trials", self.study),
                    x_label: "trials per participant".into(),
                    y_label: format!("RMSE of the threshold ({} units)", self.truth.scale.name()),
                    x_log: true,
                    y_log: true,
                    series: rmse,
                },
            ),
            (
                "simulate-threshold-coverage.svg".into(),
                LinePlot {
                    title: format!("{}: 95 % interval coverage and share within ±tolerance", self.study),
                    x_label: "trials per participant".into(),
                    y_label: "share of participants".into(),
                    x_log: true,
                    y_log: false,
                    series: shares,
                },
            ),
        ]
    }
}
