//! The report of a simulation: rows of means with their Monte-Carlo errors, as JSON, a text
//! table and a plot.

use crate::study::{ActivePrior, PairsRule, Study};
use mrstudy_analysis::plot::{LinePlot, LineSeries};
use mrstudy_analysis::table::fixed;
use serde::Serialize;

use super::compare::{Comparison, versus};
use super::design::DesignChoice;
use super::marginal::MarginalTruth;
use super::truth::Truth;
use super::{ALPHA, Config};

/// A mean over runs and its Monte-Carlo standard error (absent with fewer than two runs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    pub mean: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mcse: Option<f64>,
}

impl Estimate {
    pub(super) fn of(values: &[f64]) -> Option<Estimate> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let mcse = (n > 1)
            .then(|| (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64 / n as f64).sqrt());
        Some(Estimate { mean, mcse })
    }
}

/// Power of one factor: the fraction of runs with p < [`ALPHA`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FactorPower {
    pub factor: String,
    /// The true effect.
    pub effect: f64,
    pub power: f64,
    /// √(power (1 − power) / runs).
    pub mcse: f64,
}

/// One design × participant count.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    pub design: DesignChoice,
    pub pairs: PairsRule,
    /// What an active design optimises: `worths`, `effects` or `both` (absent for a fixed design).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<&'static str>,
    /// An active design's prior, `fixed` or `spread` (absent for a fixed design).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior: Option<ActivePrior>,
    /// An active design's choice in words: its warm-up and criterion (absent for a fixed design).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optimises: Option<String>,
    pub participants: usize,
    pub runs: usize,
    pub failed: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    pub judgments_per_participant: Estimate,
    /// participants × mean judgments per participant.
    pub trials: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_log_worth: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_effects: Option<Estimate>,
    /// The RMSE of the centred MAP log-worths (`log_worth_map`, with the active design's
    /// `prior_sd`, else 1) against the centred truth: what `prior = "spread"` optimises.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_log_worth_map: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage_log_worth: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage_effects: Option<Estimate>,
    /// The coverage of the marginal truth (`marginal_truth`): what the pooled analysis estimates.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage_log_worth_marginal: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage_effects_marginal: Option<Estimate>,
    pub power: Vec<FactorPower>,
    /// Per factor: the signed bias of its estimate (issue 48).
    pub bias_effects: Vec<Bias>,
    /// Per condition after the reference: the signed bias of its log-worth (a difference to
    /// the reference).
    pub bias_log_worth: Vec<Bias>,
}

/// The signed error of one reported quantity over the runs that estimated it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bias {
    /// The factor or the condition.
    pub name: String,
    /// The true value (for a log-worth: its difference to the reference).
    pub truth: f64,
    /// Mean of estimate − truth, with its Monte-Carlo standard error.
    pub bias: Estimate,
    /// The estimates' standard deviation over the runs (absent with fewer than two).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sd: Option<f64>,
    /// The mean of the reported standard errors.
    pub mean_se: f64,
}

impl Bias {
    fn of(
        name: &str,
        truth: f64,
        runs: &[RunOutcome],
        pick: impl Fn(&RunOutcome) -> Option<(f64, f64)>,
    ) -> Option<Bias> {
        let pairs: Vec<(f64, f64)> = runs.iter().filter_map(pick).collect();
        let errors: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        let bias = Estimate::of(&errors)?;
        let sd = bias.mcse.map(|mcse| mcse * (errors.len() as f64).sqrt());
        let mean_se = pairs.iter().map(|p| p.1).sum::<f64>() / pairs.len() as f64;
        Some(Bias { name: name.to_string(), truth, bias, sd, mean_se })
    }
}

/// The simulation's settings as reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Settings {
    pub observer_sd: f64,
    pub lapse: f64,
    pub dropout: f64,
    pub runs: usize,
    pub seed: u64,
    pub bootstrap: usize,
    pub alpha: f64,
}

/// Everything `mrstudy simulate` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    pub study: String,
    pub reference: String,
    pub truth: Truth,
    /// What the pooled analysis estimates under the observers' taste and lapses
    /// (`simulate::marginal`); absent with "not sure" answers or collinear factors.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub marginal_truth: Option<MarginalTruth>,
    pub settings: Settings,
    pub rows: Vec<Row>,
    /// Each active design against the study's fixed design (see [`Comparison`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub comparisons: Vec<Comparison>,
}

impl Report {
    /// The report of `rows`, simulated on `study` under `config` (no comparisons yet).
    pub(super) fn new(study: &Study, config: &Config, rows: Vec<Row>) -> Report {
        let options = &config.options;
        Report {
            study: study.slug.clone(),
            reference: study.conditions[0].name.clone(),
            truth: config.truth.clone(),
            marginal_truth: None,
            settings: Settings {
                observer_sd: options.observer_sd,
                lapse: options.lapse,
                dropout: options.dropout,
                runs: options.runs,
                seed: options.seed,
                bootstrap: options.bootstrap,
                alpha: ALPHA,
            },
            rows,
            comparisons: Vec::new(),
        }
    }
}

pub(super) fn summarise(
    (choice, variant): &(DesignChoice, Study),
    participants: usize,
    runs: &[RunOutcome],
    config: &Config,
) -> Row {
    let values = |pick: fn(&RunOutcome) -> Option<f64>| Estimate::of(&runs.iter().filter_map(pick).collect::<Vec<_>>());
    let per_participant: Vec<f64> = runs.iter().map(|run| run.judgments as f64 / run.participants as f64).collect();
    let judgments_per_participant = Estimate::of(&per_participant).expect("at least one run");
    let n = runs.len() as f64;
    let power = config
        .truth
        .effects
        .iter()
        .enumerate()
        .map(|(k, effect)| {
            let power = runs.iter().filter(|run| run.significant[k]).count() as f64 / n;
            FactorPower {
                factor: effect.factor.clone(),
                effect: effect.effect,
                power,
                mcse: (power * (1.0 - power) / n).sqrt(),
            }
        })
        .collect();
    Row {
        design: *choice,
        pairs: variant.design.pairs_rule,
        target: variant.design.active.as_ref().map(|active| active.target.describe().0),
        prior: variant.design.active.as_ref().map(|active| active.prior),
        optimises: variant.design.active.as_ref().map(|active| {
            let warmup = variant.design.pairs.len() * variant.design.repetitions as usize;
            format!(
                "{} fixed warm-up pair trials, then {} chosen {} (optimises {})",
                warmup,
                active.trials,
                active.criterion(),
                active.optimises()
            )
        }),
        participants,
        runs: runs.len(),
        failed: runs.iter().filter(|run| run.failure.is_some()).count(),
        failure: runs.iter().find_map(|run| run.failure.clone()),
        trials: participants as f64 * judgments_per_participant.mean,
        judgments_per_participant,
        rmse_log_worth: values(|run| run.rmse_log_worth),
        rmse_effects: values(|run| run.rmse_effects),
        rmse_log_worth_map: values(|run| run.rmse_log_worth_map),
        coverage_log_worth: values(|run| run.coverage_log_worth),
        coverage_effects: values(|run| run.coverage_effects),
        coverage_log_worth_marginal: values(|run| run.coverage_log_worth_marginal),
        coverage_effects_marginal: values(|run| run.coverage_effects_marginal),
        power,
        bias_effects: config
            .truth
            .effects
            .iter()
            .enumerate()
            .filter_map(|(k, effect)| {
                Bias::of(&effect.factor, effect.effect, runs, |run| run.effect_errors.get(k).copied().flatten())
            })
            .collect(),
        bias_log_worth: {
            let reference = config.truth.log_worths[0].log_worth;
            config
                .truth
                .log_worths
                .iter()
                .enumerate()
                .skip(1)
                .filter_map(|(c, worth)| {
                    Bias::of(&worth.condition, worth.log_worth - reference, runs, |run| {
                        run.log_worth_errors.get(c - 1).copied().flatten()
                    })
                })
                .collect()
        },
    }
}

/// A mean ± its Monte-Carlo standard error, or `—` when no run gave it.
pub(super) fn cell(estimate: Option<Estimate>, digits: usize) -> String {
    match estimate {
        Some(Estimate { mean, mcse: Some(mcse) }) => format!("{} ± {}", fixed(mean, digits), fixed(mcse, digits)),
        Some(Estimate { mean, mcse: None }) => fixed(mean, digits),
        None => "—".into(),
    }
}

impl Report {
    /// Each active row against the study's fixed design at the same participant count (none
    /// unless the study's own design is fixed and both were simulated).
    pub(super) fn compare_with_study(&self) -> Vec<Comparison> {
        let study_rows: Vec<&Row> = self.rows.iter().filter(|row| row.design == DesignChoice::Study).collect();
        if study_rows.is_empty() || study_rows[0].pairs == PairsRule::Active {
            return Vec::new();
        }
        let curve = |pick: fn(&Row) -> Option<f64>| -> Vec<(f64, f64)> {
            let mut points: Vec<(f64, f64)> =
                study_rows.iter().filter_map(|row| Some((row.trials, pick(row)?))).filter(|p| p.1 > 0.0).collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            points
        };
        let worth: fn(&Row) -> Option<f64> = |row| row.rmse_log_worth.map(|e| e.mean);
        let effects: fn(&Row) -> Option<f64> = |row| row.rmse_effects.map(|e| e.mean);
        let (worth_curve, effects_curve) = (curve(worth), curve(effects));
        let mut out = Vec::new();
        for row in self.rows.iter().filter(|row| row.pairs == PairsRule::Active && row.design != DesignChoice::Study) {
            let Some(study) = study_rows.iter().find(|study| study.participants == row.participants) else { continue };
            let compare = |pick: fn(&Row) -> Option<f64>, curve: &[(f64, f64)]| {
                versus(pick(study)?, pick(row)?, row.trials, curve)
            };
            out.push(Comparison {
                design: row.design,
                target: row.target.unwrap_or("worths"),
                participants: row.participants,
                trials: row.trials,
                study_trials: study.trials,
                rmse_log_worth: compare(worth, &worth_curve),
                rmse_effects: compare(effects, &effects_curve),
            });
        }
        out
    }

    /// The plain-text table: one line per design × participant count, then notes on failures.
    pub fn table(&self) -> String {
        let mut header = vec![
            "design".to_string(),
            "participants".into(),
            "trials/participant".into(),
            "trials".into(),
            "RMSE log-worth".into(),
            "RMSE effects".into(),
            "RMSE MAP log-worth".into(),
            "coverage log-worth".into(),
            "coverage effects".into(),
        ];
        if self.marginal_truth.is_some() {
            header.push("coverage log-worth (marginal)".into());
            header.push("coverage effects (marginal)".into());
        }
        header.extend(self.truth.effects.iter().map(|effect| format!("power {}", effect.factor)));
        let mut lines = vec![header];
        for row in &self.rows {
            let mut line = vec![
                match (row.target, row.prior) {
                    (Some(target), Some(ActivePrior::Spread)) => {
                        format!("{} (target {target}, prior spread)", row.design.name())
                    }
                    (Some(target), _) => format!("{} (target {target})", row.design.name()),
                    (None, _) => row.design.name().to_string(),
                },
                row.participants.to_string(),
                fixed(row.judgments_per_participant.mean, 1),
                fixed(row.trials, 0),
                cell(row.rmse_log_worth, 3),
                cell(row.rmse_effects, 3),
                cell(row.rmse_log_worth_map, 3),
                cell(row.coverage_log_worth, 3),
                cell(row.coverage_effects, 3),
            ];
            if self.marginal_truth.is_some() {
                line.push(cell(row.coverage_log_worth_marginal, 3));
                line.push(cell(row.coverage_effects_marginal, 3));
            }
            line.extend(row.power.iter().map(|power| format!("{} ± {}", fixed(power.power, 2), fixed(power.mcse, 2))));
            lines.push(line);
        }
        let widths: Vec<usize> =
            (0..lines[0].len()).map(|c| lines.iter().map(|line| line[c].chars().count()).max().unwrap_or(0)).collect();
        let mut text = String::new();
        for line in &lines {
            let cells: Vec<String> = line.iter().zip(&widths).map(|(cell, &width)| format!("{cell:>width$}")).collect();
            text += cells.join("  ").trim_end();
            text.push('\n');
        }
        text += &format!(
            "log-worths as differences to {} (the analysis's reference); ± is the Monte-Carlo standard error over {} runs; power: p < {ALPHA}\n",
            self.reference, self.settings.runs
        );
        if let Some(marginal) = &self.marginal_truth {
            text += &marginal.line(&self.truth, self.settings.observer_sd, self.settings.lapse);
        }
        let mut described: Vec<DesignChoice> = Vec::new();
        for row in &self.rows {
            if let Some(optimises) = &row.optimises
                && !described.contains(&row.design)
            {
                described.push(row.design);
                text += &format!("{} per participant: {optimises}\n", row.design.name());
            }
        }
        text += &super::compare::comparison_lines(&self.comparisons);
        for row in &self.rows {
            if row.failed == row.runs {
                text += &format!(
                    "{} with {} participants: every run failed, so there is no RMSE, coverage or power ({})\n",
                    row.design.name(),
                    row.participants,
                    row.failure.as_deref().unwrap_or("no reason given")
                );
            } else if row.failed > 0 {
                text += &format!(
                    "{} with {} participants: {} of {} runs failed and have no scores, e.g. {}\n",
                    row.design.name(),
                    row.participants,
                    row.failed,
                    row.runs,
                    row.failure.as_deref().unwrap_or("no reason given")
                );
            }
        }
        text
    }

    /// The plots: RMSE of the log-worths against trials per study, one series per design; and,
    /// where the study has factors, power per factor against participants.
    pub fn plots(&self) -> Vec<(String, LinePlot)> {
        let mut designs: Vec<DesignChoice> = Vec::new();
        for row in &self.rows {
            if !designs.contains(&row.design) {
                designs.push(row.design);
            }
        }
        let series =
            |pick: &dyn Fn(&Row) -> Option<(f64, f64)>, name: &dyn Fn(DesignChoice) -> String| -> Vec<LineSeries> {
                designs
                    .iter()
                    .map(|&design| LineSeries {
                        name: name(design),
                        points: self.rows.iter().filter(|row| row.design == design).filter_map(pick).collect(),
                    })
                    .collect()
            };
        let mut plots = vec![(
            "simulate-rmse.svg".to_string(),
            LinePlot {
                title: format!("{}: RMSE of the log-worths against trials per study", self.study),
                x_label: "trials per study (participants × judgments per participant)".into(),
                y_label: format!("RMSE of log-worths (differences to {})", self.reference),
                x_log: true,
                y_log: true,
                series: series(&|row| Some((row.trials, row.rmse_log_worth?.mean)), &|design| design.name().into()),
            },
        )];
        if !self.truth.effects.is_empty() {
            let mut power_series = Vec::new();
            for (k, effect) in self.truth.effects.iter().enumerate() {
                power_series.extend(series(&|row| Some((row.participants as f64, row.power[k].power)), &|design| {
                    format!("{} {}", design.name(), effect.factor)
                }));
            }
            plots.push((
                "simulate-power.svg".to_string(),
                LinePlot {
                    title: format!("{}: power per factor (p < {ALPHA}) against participants", self.study),
                    x_label: "participants".into(),
                    y_label: "power".into(),
                    x_log: true,
                    y_log: false,
                    series: power_series,
                },
            ));
        }
        plots
    }
}

/// One run's scores (absent where the analysis gave none).
#[derive(Debug, Clone, Default)]
pub(super) struct RunOutcome {
    pub(super) judgments: usize,
    pub(super) participants: usize,
    pub(super) failure: Option<String>,
    pub(super) rmse_log_worth: Option<f64>,
    pub(super) coverage_log_worth: Option<f64>,
    pub(super) rmse_effects: Option<f64>,
    /// The centred MAP log-worths' RMSE against the centred truth.
    pub(super) rmse_log_worth_map: Option<f64>,
    pub(super) coverage_effects: Option<f64>,
    /// The coverage of the marginal truth (`simulate::marginal`).
    pub(super) coverage_log_worth_marginal: Option<f64>,
    pub(super) coverage_effects_marginal: Option<f64>,
    /// Per truth factor: p < α.
    pub(super) significant: Vec<bool>,
    /// Per truth factor: (estimate − truth, reported se), absent where the analysis gave none.
    pub(super) effect_errors: Vec<Option<(f64, f64)>>,
    /// Per condition after the reference: (λ̂ − (λ − λ_ref), reported se), absent where the
    /// analysis gave none.
    pub(super) log_worth_errors: Vec<Option<(f64, f64)>>,
}
