//! Which error people see: image metrics of each stimulus against its ground truth (the stimulus
//! metrics CSV of `mrstudy stimuli --metrics`) set beside the preference the participants
//! showed for it.
//!
//! 1. [`parse_stimulus_metrics`] reads the CSV (`stimulus,scene,condition,metric,region,value`),
//!    strictly: unknown metric or region names, non-finite values and a (scene, condition,
//!    metric, region) given twice are errors naming the line and column.
//! 2. [`analyze_stimuli`] fits the perceived log-worth of each **stimulus** (scene × condition)
//!    with the crate's Bradley–Terry item model (Firth's estimate under separation) where every
//!    trial names its scenes, every stimulus has metrics and the comparisons connect all
//!    stimuli; otherwise of each **condition**, with every metric averaged over the condition's
//!    stimuli. [`StimulusAnalysis::level_reason`] says which and why.
//! 3. For every metric × region with at least three items and variance in both variables:
//!    Spearman's ρ and Kendall's τ-b between the metric and the log-worth, each with a
//!    bootstrap interval over participants (resampled with replacement, the model refitted,
//!    the correlation recomputed): the *basic* interval, which corrects for the attenuation of
//!    a correlation by the noise of the estimated log-worths (see `basic_interval` for why not
//!    the percentile interval). Pairs that cannot be computed are listed with the reason.
//! 4. A ranking by *agreement*, the correlation signed so that higher means "predicts preference
//!    better": −ρ for the errors (higher error, less preferred), +ρ for `ssim` (a similarity).
//!    Only image metrics are ranked ([`MetricKind::ImageError`]): a timing such as `render_ms`
//!    is a cost of making the image, not an error of it, so its correlation is listed apart
//!    (`timings`), unranked, and is never the best predictor.
//!
//! Pure: text and typed values in, a serialisable [`StimulusAnalysis`] out (the `metrics`
//! section of the Analysis JSON), and scatter plots as SVG text ([`StimulusAnalysis::scatter_plots`]).

use std::collections::BTreeMap;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use crate::analysis::{NotEstimablePart, Options, Part, failure_message, fit_items, not_estimable_part};
use crate::data::{Judgments, TrialScenes, TrialsOptions};
use crate::design::{self, ParticipantTallies};
use crate::error::{AnalysisError, Result};
use crate::fit::{Method, ModelMatrix};
use crate::plot::{ScatterPlot, ScatterPoint};

mod correlation;
mod items;
mod parse;

use correlation::{all_equal, basic_interval};
pub use correlation::{kendall_tau_b, spearman_rho};
use items::{Items, condition_items, stimulus_items};
pub use parse::{
    Direction, Metric, MetricKind, MetricValues, Region, StimulusMetrics, StimulusRecord, parse_stimulus_metrics,
};

/// Bootstrap replicates over participants for the correlations' intervals unless asked otherwise.
pub const DEFAULT_REPLICATES: usize = 1000;

/// Options of the stimulus-metrics analysis. `Default`: the analysis defaults (pilots and
/// excluded participants left out), [`DEFAULT_REPLICATES`] replicates, seed 1, 95 % intervals.
#[derive(Debug, Clone)]
pub struct StimulusOptions {
    pub include_pilots: bool,
    pub include_excluded: bool,
    /// Convergence tolerance of the fits.
    pub tolerance: f64,
    /// Firth's bias reduction for every fit, not only under separation.
    pub always_firth: bool,
    /// Bootstrap replicates over participants (0: no intervals).
    pub replicates: usize,
    pub seed: u64,
    /// Level of the percentile intervals.
    pub level: f64,
}

impl Default for StimulusOptions {
    fn default() -> Self {
        StimulusOptions {
            include_pilots: false,
            include_excluded: false,
            tolerance: 1e-10,
            always_firth: false,
            replicates: DEFAULT_REPLICATES,
            seed: 1,
            level: 0.95,
        }
    }
}

impl StimulusOptions {
    /// The options of a whole analysis carried over: who is left out, tolerance, Firth, seed,
    /// and its bootstrap replicates where it asks for any (else [`DEFAULT_REPLICATES`]).
    pub fn from_analysis(options: &Options) -> StimulusOptions {
        StimulusOptions {
            include_pilots: options.include_pilots,
            include_excluded: options.include_excluded,
            tolerance: options.tolerance,
            always_firth: options.always_firth,
            replicates: if options.bootstrap > 0 { options.bootstrap } else { DEFAULT_REPLICATES },
            seed: options.seed,
            level: 0.95,
        }
    }
}

/// What the perceived worth was fitted for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Level {
    /// One log-worth per stimulus (scene × condition).
    Stimulus,
    /// One log-worth per condition; each metric averaged over the condition's stimuli.
    Condition,
}

/// One item of the fit (a stimulus or a condition) with its metrics.
#[derive(Debug, Clone, Serialize)]
pub struct MetricItem {
    /// The scene configuration (stimulus level only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
    pub condition: String,
    /// `scene/condition`, or the condition.
    pub label: String,
    /// Perceived log-worth relative to `reference`; absent for an item outside the fitted
    /// comparisons (a condition in another unconnected group).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub log_worth: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub se: Option<f64>,
    pub wins: u64,
    pub comparisons: u64,
    /// metric → region → value (at the condition level the mean over its stimuli).
    pub metrics: BTreeMap<&'static str, BTreeMap<&'static str, f64>>,
    /// The item's values by index (for plots and correlations).
    #[serde(skip)]
    pub values: MetricValues,
}

/// The correlation of one metric × region with the perceived log-worth.
#[derive(Debug, Clone, Serialize)]
pub struct MetricCorrelation {
    pub metric: Metric,
    pub region: Region,
    /// `image_error` (ranked, in `correlations`) or `timing` (in `timings`, unranked).
    pub kind: MetricKind,
    pub direction: Direction,
    /// Items with both a value and a log-worth.
    pub items: usize,
    pub spearman_rho: f64,
    /// Basic bootstrap interval over participants (of the correlation with the worths
    /// themselves; it may lie beyond `spearman_rho`, which noise attenuates).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spearman_ci: Option<[f64; 2]>,
    pub kendall_tau_b: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kendall_ci: Option<[f64; 2]>,
    /// ρ signed to "predicts preference": −ρ for errors, +ρ for `ssim`, |ρ| for `render_ms`.
    pub agreement: f64,
    /// 1 for the best predictor; omitted for a timing, which is not ranked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rank: Option<usize>,
}

/// A metric × region without correlation, and why.
#[derive(Debug, Clone, Serialize)]
pub struct NotComputed {
    pub metric: Metric,
    pub region: Region,
    pub reason: String,
}

/// The best predictor of preference.
#[derive(Debug, Clone, Serialize)]
pub struct BestMetric {
    pub metric: Metric,
    pub region: Region,
    pub agreement: f64,
}

/// The bootstrap behind the correlations' intervals.
#[derive(Debug, Clone, Serialize)]
pub struct MetricBootstrap {
    /// `basic`: the reverse-percentile interval, which corrects the attenuation of a
    /// correlation by the noise of the estimated log-worths (see `docs/analysis.md`).
    pub method: &'static str,
    pub replicates: usize,
    pub seed: u64,
    pub level: f64,
    /// Replicates whose resample could not be fitted (comparisons no longer connected); left out.
    pub failed: usize,
}

/// How ranks are made, as said in the JSON.
pub const RANKED_BY: &str = "agreement: −ρ for image errors (higher error, less preferred), +ρ for ssim (a similarity); timings (render_ms) are costs, not image errors: listed apart in `timings`, not ranked";

/// The `metrics` section of the Analysis JSON.
#[derive(Debug, Clone, Serialize)]
pub struct StimulusAnalysis {
    pub level: Level,
    /// Why this level: `per stimulus: …` or `per condition: …`.
    pub level_reason: String,
    /// At the condition level, how the metrics were averaged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub averaging: Option<String>,
    pub judgments: u64,
    pub participants: usize,
    pub method: Method,
    /// The item with log-worth 0.
    pub reference: String,
    pub items: Vec<MetricItem>,
    /// The image metrics (errors and `ssim`), best predictor first.
    pub correlations: Vec<MetricCorrelation>,
    /// The timings (`render_ms`): correlated the same way, but costs rather than image errors,
    /// so listed apart and never ranked.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub timings: Vec<MetricCorrelation>,
    pub ranked_by: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub best: Option<BestMetric>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_computed: Vec<NotComputed>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bootstrap: Option<MetricBootstrap>,
    /// Parts that could not be estimated on these data (the stimulus model, the correlations,
    /// the bootstrap), each with its reason; each is also said in `warnings`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_estimable: Vec<NotEstimablePart>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// The whole stimulus-metrics analysis from the trials CSV text: pilots and excluded
/// participants left out as in the main analysis, detection trials (one side
/// [`crate::data::GROUND_TRUTH`]) set aside.
pub fn analyze_stimuli(
    trials_csv: &str,
    trials_name: &str,
    metrics: &StimulusMetrics,
    options: &StimulusOptions,
) -> Result<StimulusAnalysis> {
    let trials_options = TrialsOptions {
        include_pilots: options.include_pilots,
        include_excluded: options.include_excluded,
        scenes: true,
        allow_ground_truth: true,
        ..TrialsOptions::default()
    };
    let parsed = crate::data::parse_trials_with(trials_csv, trials_name, None, &trials_options)?;
    let Some((judgments, scenes)) = crate::detection::split(parsed, None).preference else {
        return Err(AnalysisError::Empty(format!(
            "{trials_name}: every trial is a detection trial (one side `{}`), so there is no preference to set the metrics beside",
            crate::data::GROUND_TRUTH
        )));
    };
    analyze_judgments(&judgments, scenes.as_ref(), metrics, options)
}

/// The stimulus-metrics analysis of parsed preference judgments (no side the ground truth) and,
/// where read, their scenes.
pub fn analyze_judgments(
    judgments: &Judgments,
    scenes: Option<&TrialScenes>,
    metrics: &StimulusMetrics,
    options: &StimulusOptions,
) -> Result<StimulusAnalysis> {
    if !(options.level > 0.0 && options.level < 1.0) {
        return Err(AnalysisError::BadOption {
            option: "level".into(),
            message: format!("{} is not between 0 and 1", options.level),
        });
    }
    let mut warnings = Vec::new();
    let mut not_estimable = Vec::new();
    let fit_options =
        Options { tolerance: options.tolerance, always_firth: options.always_firth, ..Options::default() };
    let fit_of = |items: &Items| {
        let n_items = items.condition.len();
        let tallies = ParticipantTallies::new(judgments.participants.len(), n_items, items.rows.iter());
        let active = tallies.present();
        let pairs = tallies.pooled(n_items, &active);
        let fit = fit_items(n_items, &pairs, 0, &fit_options);
        (tallies, active, pairs, fit)
    };
    let scenes_named = scenes.is_some_and(|s| !s.rows.iter().any(|pair| pair.contains(&TrialScenes::EMPTY)));
    let stimulus_level = match stimulus_items(judgments, scenes, metrics) {
        Ok(items) => {
            let (tallies, active, pairs, fit) = fit_of(&items);
            match fit {
                Ok(item_fit) => Ok((items, tallies, active, pairs, item_fit)),
                Err(failure) => Err(failure_message("stimulus model", failure).to_string()),
            }
        }
        Err(why) => Err(why),
    };
    let (items, level_reason, averaging, tallies, active, pairs, item_fit) = match stimulus_level {
        Ok((items, tallies, active, pairs, item_fit)) => {
            let reason = format!(
                "per stimulus: every trial names its scenes, every stimulus has metrics and the comparisons connect all {} stimuli",
                items.condition.len()
            );
            let shown: std::collections::HashSet<(&str, &str)> = (0..items.condition.len())
                .map(|k| (items.scene[k].as_deref().unwrap_or_default(), items.condition[k].as_str()))
                .collect();
            let unjudged: Vec<String> = metrics
                .stimuli
                .iter()
                .filter(|record| judgments.conditions.contains(&record.condition))
                .filter(|record| !shown.contains(&(record.scene.as_str(), record.condition.as_str())))
                .map(|record| format!("`{}/{}`", record.scene, record.condition))
                .collect();
            if !unjudged.is_empty() {
                warnings.push(format!(
                    "{} of the metrics CSV's stimuli of these conditions {} no judgment yet and {} left out of the stimulus model: {}",
                    unjudged.len(),
                    if unjudged.len() == 1 { "has" } else { "have" },
                    if unjudged.len() == 1 { "is" } else { "are" },
                    listed(&unjudged)
                ));
            }
            (items, reason, None, tallies, active, pairs, item_fit)
        }
        Err(why) => {
            if scenes_named {
                // The trials name the stimuli shown, so a model per stimulus was meant.
                not_estimable_part(&mut warnings, &mut not_estimable, Part::StimulusModel, why.clone());
            }
            let (items, averaging) = condition_items(judgments, scenes, metrics);
            let (tallies, active, pairs, fit) = fit_of(&items);
            let item_fit =
                fit.map_err(|failure| failure_message("condition model of the metrics analysis", failure))?;
            (items, format!("per condition: {why}"), Some(averaging), tallies, active, pairs, item_fit)
        }
    };
    let n_items = items.condition.len();
    let without: Vec<String> = (0..n_items)
        .filter(|&k| items.values[k].iter().flatten().all(Option::is_none))
        .map(|k| format!("`{}`", items.label(k)))
        .collect();
    if !without.is_empty() {
        warnings.push(format!("no metrics for {}, left out of the correlations", without.join(", ")));
    }
    // The largest group of connected items (all of them, except at the condition level of a
    // disconnected design).
    let largest = (0..item_fit.components.len())
        .max_by_key(|&k| (item_fit.components[k].0.len(), std::cmp::Reverse(k)))
        .ok_or_else(|| AnalysisError::Empty("there are no preference trials to fit".into()))?;
    if item_fit.components.len() > 1 {
        let members = &item_fit.components[largest].0;
        warnings.push(format!(
            "the conditions form {} unconnected groups; the correlations use the largest ({})",
            item_fit.components.len(),
            members.iter().map(|&m| items.label(m)).collect::<Vec<_>>().join(", ")
        ));
    }
    let (members, reference, fit, separated) = &item_fit.components[largest];
    let (mut wins, mut comparisons) = (vec![0u64; n_items], vec![0u64; n_items]);
    for pair in &pairs {
        wins[pair.i] += pair.wins_i;
        wins[pair.j] += pair.wins_j;
        comparisons[pair.i] += pair.n();
        comparisons[pair.j] += pair.n();
    }
    if separated.is_some() {
        let what = if items.level == Level::Stimulus { "stimuli" } else { "conditions" };
        let one_sided = |won: bool| -> Vec<String> {
            members
                .iter()
                .filter(|&&m| comparisons[m] > 0 && (wins[m] == comparisons[m]) == won && (wins[m] == 0) != won)
                .map(|&m| format!("`{}`", items.label(m)))
                .collect()
        };
        let (only_won, only_lost) = (one_sided(true), one_sided(false));
        let mut sides = Vec::new();
        if !only_won.is_empty() {
            sides.push(format!("{} only won ({})", only_won.len(), listed(&only_won)));
        }
        if !only_lost.is_empty() {
            sides.push(format!("{} only lost ({})", only_lost.len(), listed(&only_lost)));
        }
        let sides = if sides.is_empty() {
            String::new()
        } else {
            format!(" ({} of the {} {})", sides.join(", "), members.len(), what)
        };
        warnings.push(format!(
            "separation among the {what}{sides}: the maximum-likelihood estimate does not exist; the log-worths are Firth's bias-reduced estimate"
        ));
    }
    let x = ModelMatrix::items(n_items, members, *reference);
    let mut log_worth = vec![None; n_items];
    let mut se = vec![None; n_items];
    for &m in members {
        log_worth[m] = Some(x.predict(m, &fit.beta) + 0.0);
        se[m] = Some(fit.variance_of(&x.rows[m]).sqrt());
    }

    // Correlations over the fitted items.
    let mut correlations = Vec::new();
    let mut not_computed = Vec::new();
    let mut computed: Vec<(Metric, Region, Vec<usize>)> = Vec::new();
    for (metric, region) in pairs_of_metric_and_region() {
        let with_value: Vec<usize> = (0..n_items)
            .filter(|&k| log_worth[k].is_some() && items.values[k][metric.index()][region.index()].is_some())
            .collect();
        let reason = if with_value.is_empty() {
            if items.values.iter().all(|v| v[metric.index()][region.index()].is_none()) {
                Some("no stimulus of the trials has it in the metrics CSV".to_string())
            } else {
                Some("no fitted item has it".to_string())
            }
        } else if with_value.len() < 3 {
            Some(format!(
                "only {} {} {} it (a correlation needs at least 3)",
                with_value.len(),
                if with_value.len() == 1 { "item" } else { "items" },
                if with_value.len() == 1 { "has" } else { "have" }
            ))
        } else {
            let xs: Vec<f64> = with_value.iter().map(|&k| value(&items, k, metric, region)).collect();
            let ys: Vec<f64> = with_value.iter().map(|&k| log_worth[k].unwrap_or(0.0)).collect();
            match (spearman_rho(&xs, &ys), kendall_tau_b(&xs, &ys)) {
                (Some(rho), Some(tau)) => {
                    correlations.push(MetricCorrelation {
                        metric,
                        region,
                        kind: metric.kind(),
                        direction: metric.direction(),
                        items: with_value.len(),
                        spearman_rho: rho,
                        spearman_ci: None,
                        kendall_tau_b: tau,
                        kendall_ci: None,
                        agreement: metric.agreement(rho),
                        rank: None,
                    });
                    computed.push((metric, region, with_value));
                    None
                }
                _ if all_equal(&xs) => Some(format!("it is the same for all {} items (no variance)", with_value.len())),
                _ => Some(format!("the perceived log-worth is the same for all {} items", with_value.len())),
            }
        };
        if let Some(reason) = reason {
            not_computed.push(NotComputed { metric, region, reason });
        }
    }

    // Bootstrap over participants: resample, refit, recompute.
    let mut bootstrap = None;
    if options.replicates > 0 && !correlations.is_empty() {
        if active.len() < 2 {
            not_estimable_part(
                &mut warnings,
                &mut not_estimable,
                Part::Bootstrap,
                "it needs at least two participants".into(),
            );
        } else {
            let replicate_options = Options { tolerance: options.tolerance.max(1e-8), ..fit_options.clone() };
            let replicates: Vec<Option<Vec<(Option<f64>, Option<f64>)>>> = (0..options.replicates)
                .into_par_iter()
                .map(|b| {
                    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
                    rng.set_stream(b as u64 + 1);
                    let rows: Vec<_> = (0..active.len())
                        .flat_map(|_| tallies.rows_of(active[rng.random_range(0..active.len())]))
                        .collect();
                    let pairs = if n_items <= 512 { design::tally_dense(n_items, rows) } else { design::tally(rows) };
                    let refit = fit_items(n_items, &pairs, *reference, &replicate_options).ok()?;
                    // The resample must still connect every item the correlations use.
                    let component = refit.components.iter().find(|c| c.0.contains(reference))?;
                    if members.iter().any(|m| component.0.binary_search(m).is_err()) {
                        return None;
                    }
                    let x = ModelMatrix::items(n_items, &component.0, component.1);
                    let lambda: Vec<f64> = (0..n_items).map(|k| x.predict(k, &component.2.beta)).collect();
                    Some(
                        computed
                            .iter()
                            .map(|(metric, region, with_value)| {
                                let xs: Vec<f64> =
                                    with_value.iter().map(|&k| value(&items, k, *metric, *region)).collect();
                                let ys: Vec<f64> = with_value.iter().map(|&k| lambda[k]).collect();
                                (spearman_rho(&xs, &ys), kendall_tau_b(&xs, &ys))
                            })
                            .collect(),
                    )
                })
                .collect();
            let successful: Vec<&Vec<(Option<f64>, Option<f64>)>> = replicates.iter().flatten().collect();
            let failed = replicates.len() - successful.len();
            if failed == replicates.len() {
                not_estimable_part(
                    &mut warnings,
                    &mut not_estimable,
                    Part::Bootstrap,
                    format!(
                        "none of its {failed} resamples still connected the items, so the correlations have no intervals"
                    ),
                );
            } else if failed > 0 {
                warnings.push(format!(
                    "bootstrap: {failed} of {} resamples no longer connected the items and are left out of the intervals",
                    replicates.len()
                ));
            }
            for (k, correlation) in correlations.iter_mut().enumerate() {
                let rhos = successful.iter().filter_map(|r| r[k].0).collect();
                let taus = successful.iter().filter_map(|r| r[k].1).collect();
                correlation.spearman_ci = basic_interval(rhos, options.level, correlation.spearman_rho);
                correlation.kendall_ci = basic_interval(taus, options.level, correlation.kendall_tau_b);
            }
            bootstrap = Some(MetricBootstrap {
                method: "basic",
                replicates: options.replicates,
                seed: options.seed,
                level: options.level,
                failed,
            });
        }
    }

    // Timings apart; ranking of the image metrics: best agreement first; ties keep
    // docs/design.md's order.
    let (mut correlations, timings): (Vec<MetricCorrelation>, Vec<MetricCorrelation>) =
        correlations.into_iter().partition(|c| c.kind == MetricKind::ImageError);
    correlations.sort_by(|a, b| b.agreement.total_cmp(&a.agreement));
    for (k, correlation) in correlations.iter_mut().enumerate() {
        correlation.rank = Some(k + 1);
    }
    let best = correlations.first().map(|c| BestMetric { metric: c.metric, region: c.region, agreement: c.agreement });
    if correlations.is_empty() {
        not_estimable_part(
            &mut warnings,
            &mut not_estimable,
            Part::MetricCorrelations,
            "no image metric × region has values, variance and at least 3 fitted items (each is in `not_computed` with its reason)"
                .into(),
        );
    }

    let metric_items = (0..n_items)
        .map(|k| {
            let mut by_metric: BTreeMap<&'static str, BTreeMap<&'static str, f64>> = BTreeMap::new();
            for metric in Metric::ALL {
                for region in Region::ALL {
                    if let Some(v) = items.values[k][metric.index()][region.index()] {
                        by_metric.entry(metric.name()).or_default().insert(region.name(), v);
                    }
                }
            }
            MetricItem {
                scene: items.scene[k].clone(),
                condition: items.condition[k].clone(),
                label: items.label(k),
                log_worth: log_worth[k],
                se: se[k],
                wins: wins[k],
                comparisons: comparisons[k],
                metrics: by_metric,
                values: items.values[k],
            }
        })
        .collect();
    Ok(StimulusAnalysis {
        level: items.level,
        level_reason,
        averaging,
        judgments: pairs.iter().map(|p| p.n()).sum(),
        participants: active.len(),
        method: fit.method,
        reference: items.label(*reference),
        items: metric_items,
        correlations,
        timings,
        ranked_by: RANKED_BY,
        best,
        not_computed,
        bootstrap,
        not_estimable,
        warnings,
    })
}

/// A list of names for a sentence: the first three, then how many more.
fn listed(names: &[String]) -> String {
    let more = if names.len() > 3 { format!(" and {} more", names.len() - 3) } else { String::new() };
    format!("{}{more}", names[..names.len().min(3)].join(", "))
}

/// Every metric × region there can be: `render_ms` only for the whole image.
fn pairs_of_metric_and_region() -> impl Iterator<Item = (Metric, Region)> {
    Metric::ALL
        .into_iter()
        .flat_map(|metric| Region::ALL.into_iter().map(move |region| (metric, region)))
        .filter(|&(metric, region)| metric != Metric::RenderMs || region == Region::Image)
}

fn value(items: &Items, k: usize, metric: Metric, region: Region) -> f64 {
    items.values[k][metric.index()][region.index()].unwrap_or(0.0)
}

impl StimulusAnalysis {
    /// One scatter plot per correlation (metric × region): the metric against the perceived
    /// log-worth, each point labelled, with ρ and τ in the title. File names
    /// `metric-<metric>-<region>.svg` with their SVG text, in ranking order, the timings last.
    pub fn scatter_plots(&self) -> Vec<(String, String)> {
        self.correlations
            .iter()
            .chain(&self.timings)
            .map(|correlation| {
                let (metric, region) = (correlation.metric, correlation.region);
                let points = self
                    .items
                    .iter()
                    .filter_map(|item| {
                        Some(ScatterPoint {
                            x: item.values[metric.index()][region.index()]?,
                            y: item.log_worth?,
                            label: item.label.clone(),
                            group: (self.level == Level::Stimulus).then(|| item.condition.clone()),
                        })
                    })
                    .collect();
                let interval = |ci: Option<[f64; 2]>| match ci {
                    Some([low, high]) => format!(" [{},\u{a0}{}]", signed(low), signed(high)),
                    None => String::new(),
                };
                let title = format!(
                    "{} ({} region) against preference: Spearman ρ\u{a0}=\u{a0}{}{}, Kendall τb\u{a0}=\u{a0}{}{}, n\u{a0}=\u{a0}{} {}",
                    metric.name(),
                    region.name(),
                    signed(correlation.spearman_rho),
                    interval(correlation.spearman_ci),
                    signed(correlation.kendall_tau_b),
                    interval(correlation.kendall_ci),
                    correlation.items,
                    if self.level == Level::Stimulus { "stimuli" } else { "conditions" },
                );
                let x_label = match self.level {
                    Level::Stimulus => format!("{} ({} region)", metric.name(), region.name()),
                    Level::Condition => format!("{} ({} region), mean over the condition's stimuli", metric.name(), region.name()),
                };
                let spec = ScatterPlot {
                    title,
                    x_label,
                    y_label: format!("perceived log-worth λ ({} = 0)", self.reference),
                    points,
                    note: Some(format!(
                        "{}{}; level: {}",
                        match correlation.rank {
                            Some(rank) => format!(
                                "rank {rank} of {} image metrics by {}",
                                self.correlations.len(),
                                match metric.direction() {
                                    Direction::Error => "−ρ (an error)",
                                    Direction::Similarity => "+ρ (a similarity)",
                                    Direction::None => "|ρ| (no direction)",
                                }
                            ),
                            None => "a timing (a cost of the image, not an error of it): not ranked".to_string(),
                        },
                        match &self.bootstrap {
                            Some(b) => format!(
                                "; intervals: {:.0}\u{a0}% basic bootstrap over participants ({} replicates), of the correlation with the worths themselves (noise in the estimated worths pulls ρ and τb towards 0)",
                                100.0 * b.level,
                                b.replicates
                            ),
                            None => String::new(),
                        },
                        self.level_reason
                    )),
                };
                (format!("metric-{}-{}.svg", metric.name(), region.name()), crate::plot::scatter(&spec))
            })
            .collect()
    }
}

/// A correlation for a title: two decimals, a true minus sign, never `-0.00`.
fn signed(value: f64) -> String {
    let text = format!("{value:.2}");
    let text = if text.trim_start_matches('-').bytes().all(|b| b == b'0' || b == b'.') {
        text.trim_start_matches('-').to_string()
    } else {
        text
    };
    text.replace('-', "−")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Kendall's τ-b by its definition over all pairs.
    fn kendall_by_pairs(x: &[f64], y: &[f64]) -> f64 {
        let (mut s, mut n1, mut n2, mut n0) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..x.len() {
            for j in i + 1..x.len() {
                let (dx, dy) = ((x[i] - x[j]).signum(), (y[i] - y[j]).signum());
                let (dx, dy) = (if x[i] == x[j] { 0.0 } else { dx }, if y[i] == y[j] { 0.0 } else { dy });
                s += dx * dy;
                n0 += 1.0;
                n1 += f64::from(dx == 0.0);
                n2 += f64::from(dy == 0.0);
            }
        }
        s / ((n0 - n1) * (n0 - n2)).sqrt()
    }

    #[test]
    fn knight_equals_the_definition_with_ties() {
        let mut state = 7u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 33) % 5) as f64
        };
        for n in [2usize, 3, 5, 8, 13, 40, 101] {
            let x: Vec<f64> = (0..n).map(|_| next()).collect();
            let y: Vec<f64> = (0..n).map(|_| next()).collect();
            if all_equal(&x) || all_equal(&y) {
                continue;
            }
            let fast = kendall_tau_b(&x, &y).unwrap();
            let slow = kendall_by_pairs(&x, &y);
            assert!((fast - slow).abs() < 1e-12, "n = {n}: {fast} vs {slow}");
        }
    }

    #[test]
    fn no_variance_gives_no_correlation() {
        assert_eq!(spearman_rho(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]), None);
        assert_eq!(kendall_tau_b(&[1.0, 2.0, 3.0], &[4.0, 4.0, 4.0]), None);
        assert!((spearman_rho(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]).unwrap() + 1.0).abs() < 1e-15);
    }

    #[test]
    fn signed_never_writes_minus_zero() {
        assert_eq!(signed(-0.001), "0.00");
        assert_eq!(signed(-0.5), "−0.50");
        assert_eq!(signed(0.956), "0.96");
    }

    #[test]
    fn metrics_parse_and_refuse_with_line_and_column() {
        let header = "stimulus,scene,condition,metric,region,value\n";
        let ok = format!("{header}h1,s1,GI,flip_mean,affected,0.25\nh1,s1,GI,ssim,image,0.9\n");
        let metrics = parse_stimulus_metrics(&ok, "m.csv").unwrap();
        assert_eq!(metrics.get("s1", "GI").unwrap().value(Metric::Ssim, Region::Image), Some(0.9));
        let cases = [
            (
                "h1,s1,GI,psnr,image,1\n",
                "m.csv: line 2, column `metric`: `psnr` is not a metric (metrics: flip_mean, flip_p95, rmse_linear, rmse_display, ssim, ciede2000_mean, ciede2000_p95, render_ms)",
            ),
            (
                "h1,s1,GI,ssim,sky,1\n",
                "m.csv: line 2, column `region`: `sky` is not a region (regions: image, affected, virtual)",
            ),
            ("h1,s1,GI,ssim,image,NaN\n", "m.csv: line 2, column `value`: `NaN` is not a finite number"),
            ("h1,s1,GI,ssim,image,inf\n", "m.csv: line 2, column `value`: `inf` is not a finite number"),
            (
                "h1,s1,GI,ssim,image,1\nh1,s1,GI,ssim,image,2\n",
                "m.csv: line 3: `ssim` in region `image` of scene `s1` under condition `GI` is listed twice (first on line 2)",
            ),
            (
                "h1,s1,GI,ssim,image,1\nh2,s1,GI,flip_mean,image,2\n",
                "m.csv: line 3, column `stimulus`: scene `s1` under condition `GI` is stimulus `h1` on line 2, not `h2`",
            ),
            (
                "h1,s1,GI,render_ms,virtual,2\n",
                "m.csv: line 2, column `region`: `render_ms` is the time of the whole image: its region is `image`, not `virtual`",
            ),
            ("h1,,GI,ssim,image,1\n", "m.csv: line 2, column `scene`: the scene is empty"),
            ("h1,s1,GI,ssim,image\n", "m.csv: line 2: the row has 5 fields but the header has 6"),
        ];
        for (rows, expected) in cases {
            let error = parse_stimulus_metrics(&format!("{header}{rows}"), "m.csv").unwrap_err().to_string();
            assert_eq!(error, expected);
        }
        let error = parse_stimulus_metrics("stimulus,scene,condition,metric,value\n", "m.csv").unwrap_err().to_string();
        assert_eq!(
            error,
            "m.csv: the header has no column `region` (it has: stimulus, scene, condition, metric, value)"
        );
        let error = parse_stimulus_metrics(header, "m.csv").unwrap_err().to_string();
        assert_eq!(error, "m.csv: there are no metrics in the file");
    }
}
