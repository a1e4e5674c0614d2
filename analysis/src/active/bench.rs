//! The active-selection benchmark (to be wired as `mrstudy bench active`): the time to choose
//! the next pair against conditions and judgments absorbed so far (the state built by absorbing
//! that many simulated judgments on random pairs first; the absorb time per judgment is a
//! column), and the update methods compared — ADF, online Laplace, Laplace refit — in time per
//! judgment and error of the posterior mean and sd against the refitted Laplace posterior (the
//! exact MAP and inverse Hessian). Returns a typed [`Report`] like `analysis::bench`; lines go to
//! a callback as rows are measured. One thread: nothing here uses rayon.
//!
//! Measured (this crate at opt-level 3, one core of a shared 2-core machine; issue 14):
//! - choosing the next pair: 0.01 ms at 8 conditions, 0.1 ms at 20, 0.5–0.7 ms at 50,
//!   1.8–2.7 ms at 100, 8–16 ms at 200, the same from 10² to 10⁶ judgments absorbed (the
//!   state is O(p²) whatever the log); absorbing one judgment 0.7 µs (8) to 10–13 µs (200);
//! - ADF against the refitted Laplace posterior: max |Δμ| 0.003–0.14 posterior sd at 10⁴
//!   judgments on the logit scale (0.5 sd for the probit with log-worths N(0, 1), whose
//!   early judgments are absorbed under a wide posterior and never revisited); the online
//!   Laplace step is 2–5× cheaper but 2–4× further off in most rows (0.4–1.2 sd at 10³–10⁴
//!   judgments; it wins only on the 3-parameter factor target at few judgments); the refit
//!   costs 16 µs (8 conditions, 30 judgments) to 1.4 ms (50 conditions, 10⁴) per judgment if
//!   done on every judgment, and grows with p³ and the number of pairs. Hence ADF.

use std::time::Instant;

use serde::Serialize;

use super::laplace;
use super::posterior::Update;
use super::simulate::{normal, uniform};
use super::{Link, Posterior, Result, Target, tie_stream};
use crate::plot::{LinePlot, LineSeries};

/// One row of the benchmark.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum ActiveRow {
    Choose(ChooseRow),
    Update(UpdateRow),
}

/// Choosing the next pair at one state size.
#[derive(Clone, Debug, Serialize)]
pub struct ChooseRow {
    /// Always `choose`.
    pub bench: &'static str,
    pub conditions: usize,
    pub judgments: usize,
    /// Median wall time of `best_pairs` for one pair.
    pub ms: f64,
    /// Median wall time of a batch of 10 pairs, per pair.
    pub batch_ms_per_pair: f64,
    /// Mean time to absorb one judgment (ADF), over the judgments added since the last row.
    pub absorb_us: f64,
    /// Median wall time of a batch of 10 pairs under the hierarchical prior on the spread
    /// ([`Posterior::with_spread_prior`], served with a study's `prior = "spread"`) at a state whose mixture
    /// is not computed yet (ten Laplace refits), per pair.
    pub spread_ms_per_pair: f64,
}

/// One update method on one simulated log, against the Laplace refit.
#[derive(Clone, Debug, Serialize)]
pub struct UpdateRow {
    /// Always `update`.
    pub bench: &'static str,
    /// `adf`, `online-laplace` or `laplace-refit`.
    pub method: &'static str,
    /// `worths` or `factors`.
    pub target: &'static str,
    pub link: Link,
    pub conditions: usize,
    pub judgments: usize,
    /// Time per judgment: an incremental update, or one whole refit for `laplace-refit`.
    pub us_per_judgment: f64,
    /// Largest |mean − MAP| over the parameters.
    pub max_mean_error: f64,
    /// The same in units of the Laplace posterior sd.
    pub max_mean_error_sd: f64,
    /// Largest |sd / Laplace sd − 1| over the parameters.
    pub max_sd_error: f64,
}

/// The benchmark's result: the adapter (none: `cpu`), the rows and the plots (file name, plot).
#[derive(Clone, Debug)]
pub struct Report {
    pub adapter: String,
    pub rows: Vec<ActiveRow>,
    pub plots: Vec<(String, LinePlot)>,
}

impl Report {
    /// docs/design.md's bench JSON: `{"adapter": "...", "rows": [...]}`.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({ "adapter": self.adapter, "rows": self.rows })
    }
}

/// A simulated log of `count` judgments on uniform random pairs with true log-worths `truth`.
fn simulated_log(truth: &[f64], link: Link, count: usize, seed: u64) -> Vec<(usize, usize)> {
    let n = truth.len();
    let mut rng = tie_stream(seed, super::StateId { judgments: 0, fingerprint: 0 }, u64::MAX);
    (0..count)
        .map(|_| {
            let i = (rand_chacha::rand_core::Rng::next_u64(&mut rng) % n as u64) as usize;
            let mut j = (rand_chacha::rand_core::Rng::next_u64(&mut rng) % (n as u64 - 1)) as usize;
            if j >= i {
                j += 1;
            }
            if uniform(&mut rng) < link.probability(truth[i] - truth[j]) { (i, j) } else { (j, i) }
        })
        .collect()
}

fn truth(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = tie_stream(seed, super::StateId { judgments: 0, fingerprint: 1 }, u64::MAX);
    (0..n).map(|_| normal(&mut rng)).collect()
}

/// Median wall time in ms of `repeats` runs of `f`.
fn median_ms<T>(repeats: usize, mut f: impl FnMut() -> T) -> f64 {
    let mut times: Vec<f64> = (0..repeats)
        .map(|_| {
            let start = Instant::now();
            std::hint::black_box(f());
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// Errors of (mean, covariance) against the Laplace fit.
fn errors(mean: &[f64], covariance: &[f64], reference: &laplace::LaplaceFit) -> (f64, f64, f64) {
    let p = mean.len();
    let (mut abs, mut in_sd, mut sd) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..p {
        let reference_sd = reference.covariance[k * p + k].sqrt();
        let error = (mean[k] - reference.mean[k]).abs();
        abs = abs.max(error);
        in_sd = in_sd.max(error / reference_sd);
        sd = sd.max((covariance[k * p + k].sqrt() / reference_sd - 1.0).abs());
    }
    (abs, in_sd, sd)
}

/// Runs the benchmark (`quick`: fewer sizes); `line` receives the table's lines.
pub fn run(quick: bool, line: &dyn Fn(&str)) -> crate::Result<Report> {
    Ok(run_active(quick, line)?)
}

fn run_active(quick: bool, line: &dyn Fn(&str)) -> Result<Report> {
    let mut rows = Vec::new();
    let mut plots = Vec::new();

    // Choose: time of the next pair against conditions × judgments so far.
    line(&format!(
        "{:<8} {:>10} {:>10} {:>12} {:>16} {:>12} {:>18}",
        "bench", "conditions", "judgments", "choose ms", "batch ms / pair", "absorb µs", "spread ms / pair"
    ));
    let conditions: &[usize] = if quick { &[8, 20, 200] } else { &[8, 20, 50, 100, 200] };
    let judgment_counts: &[usize] =
        if quick { &[100, 1_000, 10_000] } else { &[100, 1_000, 10_000, 100_000, 1_000_000] };
    let mut choose_series = Vec::new();
    let mut absorb_points = Vec::new();
    for &n in conditions {
        let truth = truth(n, 1);
        let log = simulated_log(&truth, Link::Logit, *judgment_counts.last().expect("sizes"), 2);
        let mut posterior = Posterior::new(&Target::Worths { conditions: n }, Link::Logit, super::DEFAULT_PRIOR_SD)?;
        // the same judgments under the spread prior (absorbed outside the timed loop)
        let mut spread = posterior.clone().with_spread_prior()?;
        let mut absorbed = 0;
        let mut points = Vec::new();
        for &count in judgment_counts {
            let start = Instant::now();
            for &(winner, loser) in &log[absorbed..count] {
                posterior.update(winner, loser)?;
            }
            let absorb_us = start.elapsed().as_secs_f64() * 1e6 / (count - absorbed) as f64;
            for &(winner, loser) in &log[absorbed..count] {
                spread.update(winner, loser)?;
            }
            absorbed = count;
            let repeats = if n >= 100 { 7 } else { 21 };
            let state = posterior.state_id();
            let ms = median_ms(repeats, || posterior.best_pairs(1, Some((0, 1)), &mut tie_stream(3, state, 0)));
            let batch_ms_per_pair =
                median_ms(repeats.div_ceil(3), || posterior.best_pairs(10, Some((0, 1)), &mut tie_stream(3, state, 0)))
                    / 10.0;
            // a clone has no mixture yet: every call computes it (the clone copies the log too)
            let spread_ms_per_pair = median_ms(repeats.div_ceil(3), || {
                spread.clone().best_pairs(10, Some((0, 1)), &mut tie_stream(3, state, 0))
            }) / 10.0;
            let row = ChooseRow {
                bench: "choose",
                conditions: n,
                judgments: count,
                ms,
                batch_ms_per_pair,
                absorb_us,
                spread_ms_per_pair,
            };
            line(&format!(
                "{:<8} {:>10} {:>10} {:>12.3} {:>16.3} {:>12.2} {:>18.3}",
                row.bench, n, count, ms, batch_ms_per_pair, absorb_us, spread_ms_per_pair
            ));
            points.push((count as f64, ms));
            if count == *judgment_counts.last().expect("sizes") {
                absorb_points.push((n as f64, absorb_us));
            }
            rows.push(ActiveRow::Choose(row));
        }
        choose_series.push(LineSeries { name: format!("{n} conditions"), points });
    }
    plots.push((
        "active-choose.svg".to_string(),
        LinePlot {
            title: "Time to choose the next pair against judgments absorbed (one core)".into(),
            x_label: "judgments absorbed".into(),
            y_label: "time (ms)".into(),
            x_log: true,
            y_log: true,
            series: choose_series,
        },
    ));
    plots.push((
        "active-absorb.svg".to_string(),
        LinePlot {
            title: "ADF time to absorb one judgment against conditions (one core)".into(),
            x_label: "conditions".into(),
            y_label: "time per judgment (µs)".into(),
            x_log: true,
            y_log: true,
            series: vec![LineSeries { name: "ADF rank-one update".into(), points: absorb_points }],
        },
    ));

    // Update methods: time and error against the Laplace refit.
    line(&format!(
        "{:<8} {:<15} {:<8} {:<7} {:>10} {:>10} {:>14} {:>12} {:>14} {:>10}",
        "bench",
        "method",
        "target",
        "link",
        "conditions",
        "judgments",
        "µs / judgment",
        "max |Δμ|",
        "max |Δμ| / sd",
        "max sd err"
    ));
    let cases: Vec<(&'static str, Link, usize)> = if quick {
        vec![("worths", Link::Logit, 8), ("worths", Link::Logit, 20), ("factors", Link::Logit, 8)]
    } else {
        vec![
            ("worths", Link::Logit, 8),
            ("worths", Link::Logit, 20),
            ("worths", Link::Logit, 50),
            ("worths", Link::Probit, 20),
            ("factors", Link::Logit, 8),
        ]
    };
    let method_counts: &[usize] = if quick { &[100, 1_000] } else { &[30, 100, 1_000, 10_000] };
    let mut error_series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for &(target_name, link, n) in &cases {
        let (target, truth) = if target_name == "factors" {
            let (design, worths) = super::simulate::factorial(&[0.27, -0.22, 0.43]);
            (Target::Factors { design }, worths)
        } else {
            (Target::Worths { conditions: n }, truth(n, 4))
        };
        let log = simulated_log(&truth, link, *method_counts.last().expect("sizes"), 5);
        for &count in method_counts {
            let judgments = &log[..count];
            let refit_ms = median_ms(3, || laplace::refit(&target, link, super::DEFAULT_PRIOR_SD, judgments));
            let reference = laplace::refit(&target, link, super::DEFAULT_PRIOR_SD, judgments)?;
            let mut measured = Vec::new();
            for (name, method) in
                [("adf", Some(Update::Adf)), ("online-laplace", Some(Update::OnlineLaplace)), ("laplace-refit", None)]
            {
                let (us, mean, covariance) = match method {
                    Some(method) => {
                        let mut posterior = Posterior::new(&target, link, super::DEFAULT_PRIOR_SD)?;
                        let start = Instant::now();
                        for &(winner, loser) in judgments {
                            posterior.update_by(method, winner, loser)?;
                        }
                        let us = start.elapsed().as_secs_f64() * 1e6 / count as f64;
                        (us, posterior.mean().to_vec(), posterior.covariance().to_vec())
                    }
                    None => (refit_ms * 1e3, reference.mean.clone(), reference.covariance.clone()),
                };
                let (max_mean_error, max_mean_error_sd, max_sd_error) = errors(&mean, &covariance, &reference);
                let row = UpdateRow {
                    bench: "update",
                    method: name,
                    target: target_name,
                    link,
                    conditions: n,
                    judgments: count,
                    us_per_judgment: us,
                    max_mean_error,
                    max_mean_error_sd,
                    max_sd_error,
                };
                line(&format!(
                    "{:<8} {:<15} {:<8} {:<7} {:>10} {:>10} {:>14.2} {:>12.2e} {:>14.2e} {:>10.2e}",
                    row.bench,
                    name,
                    target_name,
                    format!("{link:?}").to_lowercase(),
                    n,
                    count,
                    us,
                    max_mean_error,
                    max_mean_error_sd,
                    max_sd_error
                ));
                measured.push((name, count, max_mean_error_sd));
                rows.push(ActiveRow::Update(row));
            }
            if target_name == "worths" && link == Link::Logit && n == 20 {
                for (name, count, error) in measured.into_iter().filter(|m| m.0 != "laplace-refit") {
                    match error_series.iter_mut().find(|s| s.0 == name) {
                        Some(series) => series.1.push((count as f64, error.max(1e-12))),
                        None => error_series.push((name.to_string(), vec![(count as f64, error.max(1e-12))])),
                    }
                }
            }
        }
    }
    plots.push((
        "active-update-error.svg".to_string(),
        LinePlot {
            title: "Incremental updates against the Laplace refit (20 conditions, logit): max |Δμ| in posterior sd"
                .into(),
            x_label: "judgments".into(),
            y_label: "max |μ − MAP| / sd".into(),
            x_log: true,
            y_log: true,
            series: error_series.into_iter().map(|(name, points)| LineSeries { name, points }).collect(),
        },
    ));
    Ok(Report { adapter: "cpu (active selection needs no GPU)".to_string(), rows, plots })
}
