//! Issue 14's early gap to ASAP, measured: `cargo run --release -p mrstudy-analysis --example
//! early_gap -- [RUNS] [20|8] [NAME,NAME…] [FLAG,FLAG…]` (NAME: only the schedulers whose
//! names contain one of these; FLAG: `long`, `reference`, `mle`, `precise` — 5 decimals).
//! Schedulers against the same simulated Thurstone observers (no taste noise, a new participant
//! every 20 trials, requests of 5 pairs): random pairs; the active design as the server runs it (ADF, ρ ramped to ½ over 20 judgments per condition);
//! the same posterior re-anchored on a Laplace refit of every judgment before each request
//! ([`Posterior::reanchor`]) with the plain EIG (ρ = 1 from the start) or with the server's
//! ramp; the ADF posterior scoring by variance alone (ρ = 0); and four rules tried on top of the refit with the plain EIG: ASAP's batches (the
//! spanning tree of largest total EIG, N − 1 pairs, served in order across requests and
//! recomputed when used up), balanced candidates (only pairs with a least-judged condition),
//! pairs drawn with probability ∝ (EIG / largest EIG)⁴ instead of the greedy best, and ρ from
//! the James–Stein factor of the posterior means, squared; and the EIG with ASAP's diagonal
//! variance, batched by spanning trees or by greedy matchings; and switches from the server's
//! ramp to the plain EIG once the worths' sd — by a moment estimate, or the prior sd of largest
//! Laplace evidence — reaches a threshold; and a hierarchical prior on the worths' spread (the
//! prior sd of largest Laplace evidence before each request, the posterior re-anchored on the
//! refit with it); and the hybrid served as `prior = "spread"` (the τ-mixture for the first 15
//! judgments per condition, then the ADF design with its ramp; also switched at 20 and 30).
//! Each run's judgments are scored by
//! one estimator, the centred MAP of the Thurstone model with prior N(0, 1) per condition
//! ([`laplace::centred_map_log_worths`], `mrstudy analyze`'s `log_worth_map` on the probit scale), as docs/simulate/README.md's side-by-side with ASAP scores them; the centred RMSE ±
//! its Monte-Carlo standard error at each checkpoint. `20`: the 20 log-worths of
//! `studies/examples/twenty-conditions-worths.csv`; `8`: the thesis's factor effects (gi 0.27,
//! cm −0.22, ca 0.43) as 8 conditions' log-worths.

use std::collections::VecDeque;

use mrstudy_analysis::active::laplace::{self, refit};
use mrstudy_analysis::active::simulate::{centred_rmse, factorial, mean_and_standard_error};
use mrstudy_analysis::active::spread;
use mrstudy_analysis::active::{
    DEFAULT_MEAN_WEIGHT, DEFAULT_PRIOR_SD, Link, Posterior, SPREAD_SWITCH, Target, tie_stream,
};
use mrstudy_analysis::design::{find, union};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

/// How a scheduler picks a request's pairs.
#[derive(Clone, Copy)]
enum Rule {
    Random,
    /// The posterior's greedy batch with a largest ρ and a ramp (judgments per condition, 0:
    /// none), re-anchored on a refit before each request or not.
    Greedy {
        rho: f64,
        ramp: f64,
        reanchor: bool,
    },
    /// Refit; the largest-EIG spanning tree, served in order.
    Tree,
    /// Refit; plain EIG among pairs with a least-judged condition.
    Balanced,
    /// Refit; pairs drawn ∝ (EIG / largest)^γ, without replacement.
    Draw(f64),
    /// Refit; ρ = (James–Stein factor of the means)^power, no ramp.
    Stein(f64),
    /// Refit; the EIG with the diagonal variance Σᵢᵢ + Σⱼⱼ (as ASAP's factorised posterior has
    /// it), batched by spanning trees (true) or by greedy matchings (false).
    Diagonal(bool),
    /// Refit; the plain EIG (ρ = 1) once the moment estimate of the worths' sd,
    /// √(Σ(mᵢ − m̄)²/(n − 1) − v̄), reaches the threshold, the server's ρ ramp to ½ before.
    Spread(f64),
    /// Refit; the plain EIG once the prior sd of largest Laplace evidence (over
    /// [`EVIDENCE_SDS`]) reaches the threshold, the server's ρ ramp to ½ before.
    Evidence(f64),
    /// A hierarchical prior on the worths' spread (issue 48): before each request the prior sd
    /// τ of largest Laplace evidence (empirical Bayes, golden-section search on ln τ within
    /// [0.05, 3]), the posterior re-anchored on the refit with that τ, and the EIG with the
    /// mean weight ρ (no ramp).
    Hierarchical(f64),
    /// Full Bayes over the spread τ (issue 48): the posterior over τ on
    /// [`spread::SPREAD_GRID`] (Laplace evidence × the zero-avoiding hyperprior Gamma(2, rate 2)
    /// on τ, Chung et al. 2013), one refit per τ ([`spread::spread_posterior`]), and the pair
    /// score the weighted sum of the per-τ EIGs (`Summed`) or the plain EIG of the mixture's
    /// moment-matched Gaussian (`Moment`: [`Posterior::with_spread_prior`]).
    Mixture(MixtureScore),
    /// The τ-mixture with the moment EIG (ρ = 1) for the first `switch` judgments per
    /// condition, then the served ADF design with its ρ ramp to ½ on the ADF posterior that
    /// absorbed every judgment ([`Posterior::with_spread_switch`]; issue 48: the mixture is
    /// inside the oracle bound early, the ramp late). At 15 it is the served `prior = "spread"`.
    Hybrid(f64),
}

/// How [`Rule::Mixture`] scores a pair.
#[derive(Clone, Copy)]
enum MixtureScore {
    Summed,
    Moment,
    /// The moment-matched Gaussian scored by EIG(ρ·m, v) with ρ = ½ (no ramp).
    MomentHalf,
}

/// The prior sds whose Laplace evidence [`Rule::Evidence`] compares.
const EVIDENCE_SDS: [f64; 7] = [0.15, 0.25, 0.35, 0.5, 0.7, 1.0, 1.4];

const SCHEDULERS: [(&str, Rule); 24] = [
    ("random pairs", Rule::Random),
    ("active (ADF, ρ ramp to ½)", Rule::Greedy { rho: DEFAULT_MEAN_WEIGHT, ramp: 20.0, reanchor: false }),
    ("refit + plain EIG (ρ = 1)", Rule::Greedy { rho: 1.0, ramp: 0.0, reanchor: true }),
    ("refit + ρ ramp to ½", Rule::Greedy { rho: DEFAULT_MEAN_WEIGHT, ramp: 20.0, reanchor: true }),
    ("ADF + variance only (ρ = 0)", Rule::Greedy { rho: 0.0, ramp: 0.0, reanchor: false }),
    ("refit + spanning trees", Rule::Tree),
    ("refit + balanced", Rule::Balanced),
    ("refit + draw ∝ EIG⁴", Rule::Draw(4.0)),
    ("refit + ρ Stein²", Rule::Stein(2.0)),
    ("refit + diagonal EIG + trees", Rule::Diagonal(true)),
    ("refit + diagonal + matchings", Rule::Diagonal(false)),
    ("refit + switch at sd 0.5", Rule::Spread(0.5)),
    ("refit + switch at sd 0.7", Rule::Spread(0.7)),
    ("refit + switch at sd 0.9", Rule::Spread(0.9)),
    ("refit + evidence switch 0.5", Rule::Evidence(0.5)),
    ("refit + evidence switch 0.7", Rule::Evidence(0.7)),
    ("hierarchical τ + plain EIG", Rule::Hierarchical(1.0)),
    ("hierarchical τ + ρ ½", Rule::Hierarchical(DEFAULT_MEAN_WEIGHT)),
    ("τ-mixture + summed EIG", Rule::Mixture(MixtureScore::Summed)),
    ("τ-mixture + moment EIG", Rule::Mixture(MixtureScore::Moment)),
    ("τ-mixture + moment, ρ ½", Rule::Mixture(MixtureScore::MomentHalf)),
    ("hybrid 15/cond → ADF", Rule::Hybrid(SPREAD_SWITCH)),
    ("hybrid 20/cond → ADF", Rule::Hybrid(20.0)),
    ("hybrid 30/cond → ADF", Rule::Hybrid(30.0)),
];

/// A greedy batch scored by Σₖ wₖ·EIGₖ: each τ's mean and covariance, a fantasy update of every
/// τ's covariance (outcome-averaged, as [`Posterior::best_pairs`]) after each pick; no pair
/// follows itself or `previous`; while the judged pairs and the batch leave components, only
/// pairs joining two are candidates. Ties by the stream's keys.
fn summed_batch(
    mixture: &spread::SpreadPosterior,
    judgments: &[(usize, usize)],
    trials: usize,
    previous: Option<(usize, usize)>,
    ties: &mut ChaCha8Rng,
) -> Vec<(usize, usize)> {
    let n = mixture.fits[0].mean.len();
    let gauss =
        mrstudy_analysis::active::quadrature::Rule::gauss_hermite(mrstudy_analysis::active::quadrature::EIG_NODES);
    let update =
        mrstudy_analysis::active::quadrature::Rule::gauss_hermite(mrstudy_analysis::active::quadrature::UPDATE_NODES);
    let kept: Vec<usize> = (0..mixture.weights.len()).filter(|&k| mixture.weights[k] > 1e-6).collect();
    let mut covariances: Vec<Vec<f64>> = kept.iter().map(|&k| mixture.fits[k].covariance.clone()).collect();
    let mut parent: Vec<usize> = (0..n).collect();
    let mut components = n;
    for &(w, l) in judgments {
        if union(&mut parent, w, l) {
            components -= 1;
        }
    }
    let mut last = previous;
    let mut batch = Vec::new();
    while batch.len() < trials {
        let mut best: Option<(f64, u64, usize, usize)> = None;
        for i in 0..n {
            for j in i + 1..n {
                if last == Some((i, j)) || (components > 1 && find(&mut parent, i) == find(&mut parent, j)) {
                    continue;
                }
                let score: f64 = kept
                    .iter()
                    .zip(&covariances)
                    .map(|(&k, c)| {
                        let m = &mixture.fits[k].mean;
                        let v = c[i * n + i] + c[j * n + j] - 2.0 * c[i * n + j];
                        mixture.weights[k] * Link::Probit.eig(m[i] - m[j], v.max(f64::MIN_POSITIVE), &gauss)
                    })
                    .sum();
                let key = ties.next_u64();
                if best.is_none_or(|(s, t, _, _)| score > s * (1.0 + 1e-12) || (score >= s * (1.0 - 1e-12) && key > t))
                {
                    best = Some((score, key, i, j));
                }
            }
        }
        let (_, _, i, j) = best.expect("a candidate");
        batch.push((i, j));
        last = Some((i, j));
        if union(&mut parent, i, j) {
            components -= 1;
        }
        for (&k, c) in kept.iter().zip(covariances.iter_mut()) {
            let u: Vec<f64> = (0..n).map(|r| c[r * n + i] - c[r * n + j]).collect();
            let v = u[i] - u[j];
            let m = mixture.fits[k].mean[i] - mixture.fits[k].mean[j];
            let (z, _, v_won) = Link::Probit.tilted(m, v, &update);
            let (_, _, v_lost) = Link::Probit.tilted(-m, v, &update);
            let shrink = (v - (z * v_won + (1.0 - z) * v_lost)) / (v * v);
            for r in 0..n {
                for s in 0..n {
                    c[r * n + s] -= shrink * u[r] * u[s];
                }
            }
        }
    }
    batch
}

/// ln p(judgments | prior sd) by Laplace ([`spread::log_evidence`]).
fn log_evidence(n: usize, sd: f64, judgments: &[(usize, usize)]) -> f64 {
    let fit = refit(&Target::Worths { conditions: n }, Link::Probit, sd, judgments).expect("a refit");
    spread::log_evidence(n, Link::Probit, &fit, sd, judgments).expect("an evidence")
}

/// The prior sd of [`EVIDENCE_SDS`] with the largest Laplace evidence.
fn evidence_sd(n: usize, judgments: &[(usize, usize)]) -> f64 {
    EVIDENCE_SDS
        .iter()
        .map(|&sd| (sd, log_evidence(n, sd, judgments)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(1.0, |(sd, _)| sd)
}

/// The prior sd τ of largest Laplace evidence within [0.05, 3]: golden-section search on ln τ
/// (the evidence is unimodal in τ for these designs in practice; 24 steps: ln τ to 1e-4).
fn empirical_bayes_sd(n: usize, judgments: &[(usize, usize)]) -> f64 {
    let golden = (5f64.sqrt() - 1.0) / 2.0;
    let f = |log_sd: f64| log_evidence(n, log_sd.exp(), judgments);
    let (mut a, mut b) = (0.05f64.ln(), 3f64.ln());
    let (mut c, mut d) = (b - golden * (b - a), a + golden * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..24 {
        if fc > fd {
            b = d;
            (d, fd) = (c, fc);
            c = b - golden * (b - a);
            fc = f(c);
        } else {
            a = c;
            (c, fc) = (d, fd);
            d = a + golden * (b - a);
            fd = f(d);
        }
    }
    (0.5 * (a + b)).exp()
}

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Every pair (i < j) with its plain EIG.
fn scored_pairs(posterior: &Posterior) -> Vec<(usize, usize, f64)> {
    let n = posterior.conditions();
    (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).map(|(i, j)| (i, j, posterior.eig(i, j))).collect()
}

/// The spanning tree of largest total EIG (Kruskal; ties by `rng`), best pair first.
fn eig_tree(posterior: &Posterior, rng: &mut ChaCha8Rng) -> Vec<(usize, usize)> {
    let mut pairs: Vec<(f64, u64, usize, usize)> =
        scored_pairs(posterior).into_iter().map(|(i, j, eig)| (eig, rng.next_u64(), i, j)).collect();
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    spanning_tree(posterior.conditions(), pairs.into_iter().map(|(_, _, i, j)| (i, j)))
}

/// Kruskal's spanning tree over `pairs` sorted best first.
fn spanning_tree(n: usize, pairs: impl Iterator<Item = (usize, usize)>) -> Vec<(usize, usize)> {
    let mut parent: Vec<usize> = (0..n).collect();
    let mut tree = Vec::new();
    for (i, j) in pairs {
        if union(&mut parent, i, j) {
            tree.push((i, j));
        }
    }
    tree
}

/// ρ = (1 − (n − 3)·v̄ / Σ(mᵢ − m̄)²)₊^power, v̄ the mean variance of the centred log-worths.
fn stein_weight(posterior: &Posterior, power: f64) -> f64 {
    let (spread, centred_variance) = spread_and_centred_variance(posterior);
    let n = posterior.conditions() as f64;
    (1.0 - (n - 3.0) * centred_variance / spread.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0).powf(power)
}

/// Σ(mᵢ − m̄)² of the posterior means, and v̄, the mean variance of the centred log-worths.
fn spread_and_centred_variance(posterior: &Posterior) -> (f64, f64) {
    let n = posterior.conditions();
    let (m, c) = (posterior.mean(), posterior.covariance());
    let mean = m.iter().sum::<f64>() / n as f64;
    let spread: f64 = m.iter().map(|x| (x - mean).powi(2)).sum();
    let trace: f64 = (0..n).map(|i| c[i * n + i]).sum();
    (spread, (trace - c.iter().sum::<f64>() / n as f64) / n as f64)
}

/// The moment estimate of the sd of the log-worths: √(Σ(mᵢ − m̄)²/(n − 1) − v̄)₊, v̄ the mean
/// variance of the centred posterior log-worths.
fn spread_estimate(posterior: &Posterior) -> f64 {
    let (spread, centred_variance) = spread_and_centred_variance(posterior);
    (spread / (posterior.conditions() as f64 - 1.0) - centred_variance).max(0.0).sqrt()
}

fn main() {
    let mut args = std::env::args().skip(1);
    let runs: u64 = args.next().map_or(40, |a| a.parse().expect("RUNS"));
    let study = args.next().unwrap_or_else(|| "20".into());
    // optional: only the schedulers whose names contain one of these comma-separated parts
    let only: Option<Vec<String>> = args.next().map(|a| a.split(',').map(str::to_owned).collect());
    let worths: Vec<f64> = match study.as_str() {
        "20" => std::fs::read_to_string("studies/examples/twenty-conditions-worths.csv")
            .expect("run from the repository's root")
            .lines()
            .skip(1)
            .map(|line| line.split(',').nth(1).expect("a log_worth").parse().expect("a number"))
            .collect(),
        "8" => factorial(&[0.27, -0.22, 0.43]).1,
        path => std::fs::read_to_string(path)
            .unwrap_or_else(|_| panic!("the study is 20, 8 or a worths CSV, not {path}"))
            .lines()
            .skip(1)
            .map(|line| line.split(',').nth(1).expect("a log_worth").parse().expect("a number"))
            .collect(),
    };
    let n = worths.len();
    // optional: `long` adds a checkpoint at twice the last (random pairs' curve beyond it)
    // `reference`: score as the study's analysis does instead — the near-MLE (prior sd 10) and
    // the RMSE of the log-worths as differences to the first condition; `mle`: the near-MLE,
    // centred
    let flags: Vec<String> = args.next().map(|a| a.split(',').map(str::to_owned).collect()).unwrap_or_default();
    let long = flags.iter().any(|f| f == "long");
    let reference = flags.iter().any(|f| f == "reference");
    let mle = flags.iter().any(|f| f == "mle");
    // `precise`: the means and standard errors with 5 decimals instead of 3
    let decimals = if flags.iter().any(|f| f == "precise") { 5 } else { 3 };
    let mut checkpoints: Vec<usize> = if n >= 20 {
        vec![100, 200, 400, 800]
    } else if n > 8 {
        vec![60, 120, 240, 480]
    } else {
        vec![40, 80, 160, 320]
    };
    if long {
        checkpoints.push(2 * checkpoints[3]);
    }
    let total = *checkpoints.last().expect("a checkpoint");
    let target = Target::Worths { conditions: n };
    let gauss =
        mrstudy_analysis::active::quadrature::Rule::gauss_hermite(mrstudy_analysis::active::quadrature::EIG_NODES);
    let map = |judgments: &[(usize, usize)]| -> laplace::LaplaceFit {
        refit(&target, Link::Probit, DEFAULT_PRIOR_SD, judgments).expect("a refit")
    };
    if reference {
        println!("{n} conditions, {runs} runs; RMSE of the differences to the first condition, MAP with prior sd 10");
    } else if mle {
        println!("{n} conditions, {runs} runs; centred RMSE of the MAP with prior sd 10");
    } else {
        println!("{n} conditions, {runs} runs; centred RMSE of the MAP (prior sd 1) ± its standard error");
    }
    for (name, rule) in SCHEDULERS {
        if only.as_ref().is_some_and(|parts| !parts.iter().any(|p| name.contains(p.as_str()))) {
            continue;
        }
        let mut at: Vec<Vec<f64>> = vec![Vec::new(); checkpoints.len()];
        for run in 0..runs {
            let (rho, ramp) = match rule {
                Rule::Greedy { rho, ramp, .. } => (rho, ramp),
                _ => (1.0, 0.0),
            };
            let mut posterior = Posterior::new(&target, Link::Probit, DEFAULT_PRIOR_SD)
                .and_then(|p| p.with_mean_weight(rho))
                .and_then(|p| p.with_mean_ramp(ramp))
                .and_then(|p| match rule {
                    Rule::Mixture(MixtureScore::Moment) => p.with_spread_prior(),
                    Rule::Hybrid(switch) => p.with_spread_prior().and_then(|p| p.with_spread_switch(switch)),
                    _ => Ok(p),
                })
                .expect("a posterior");
            let mut outcomes = ChaCha8Rng::seed_from_u64(1000 + run);
            let mut random = ChaCha8Rng::seed_from_u64(5000 + run);
            let mut judgments: Vec<(usize, usize)> = Vec::new();
            let (mut participant, mut previous) = (0u64, None);
            let mut queue: VecDeque<(usize, usize)> = VecDeque::new();
            let mut counts = vec![0u64; n];
            while judgments.len() < total {
                if judgments.len().is_multiple_of(20) {
                    participant += 1;
                    previous = None;
                }
                let k = 5.min(total - judgments.len());
                let reanchor = !matches!(
                    rule,
                    Rule::Random
                        | Rule::Greedy { reanchor: false, .. }
                        | Rule::Tree
                        | Rule::Hierarchical(_)
                        | Rule::Mixture(_)
                        | Rule::Hybrid(_)
                );
                if reanchor && !judgments.is_empty() {
                    posterior.reanchor(&map(&judgments)).expect("a usable refit");
                }
                let mut ties = tie_stream(run, posterior.state_id(), participant);
                let pairs: Vec<(usize, usize)> = match rule {
                    Rule::Random => (0..k)
                        .map(|_| {
                            loop {
                                let (i, j) =
                                    ((random.next_u64() % n as u64) as usize, (random.next_u64() % n as u64) as usize);
                                if i != j {
                                    break (i.min(j), i.max(j));
                                }
                            }
                        })
                        .collect(),
                    Rule::Greedy { .. } => posterior.best_pairs(k, previous, &mut ties).expect("a batch"),
                    Rule::Hierarchical(rho) => {
                        if !judgments.is_empty() {
                            let sd = empirical_bayes_sd(n, &judgments);
                            let fit = refit(&target, Link::Probit, sd, &judgments).expect("a refit");
                            posterior.reanchor(&fit).expect("a usable refit");
                        }
                        posterior = posterior.clone().with_mean_weight(rho).expect("a weight");
                        posterior.best_pairs(k, previous, &mut ties).expect("a batch")
                    }
                    Rule::Mixture(MixtureScore::Summed) => {
                        let mixture =
                            spread::spread_posterior(n, Link::Probit, DEFAULT_PRIOR_SD, &judgments).expect("a mixture");
                        summed_batch(&mixture, &judgments, k, previous, &mut ties)
                    }
                    Rule::Mixture(MixtureScore::MomentHalf) => {
                        let mixture =
                            spread::spread_posterior(n, Link::Probit, DEFAULT_PRIOR_SD, &judgments).expect("a mixture");
                        posterior.reanchor(&mixture.moment_matched()).expect("a usable mixture");
                        posterior = posterior
                            .clone()
                            .with_mean_weight(DEFAULT_MEAN_WEIGHT)
                            .and_then(|p| p.with_mean_ramp(0.0))
                            .expect("a weight");
                        posterior.best_pairs(k, previous, &mut ties).expect("a batch")
                    }
                    Rule::Mixture(MixtureScore::Moment) | Rule::Hybrid(_) => {
                        posterior.best_pairs(k, previous, &mut ties).expect("a batch")
                    }
                    Rule::Spread(threshold) | Rule::Evidence(threshold) => {
                        // the worths' sd, by the moment estimate or the evidence
                        let sd = match rule {
                            Rule::Spread(_) => spread_estimate(&posterior),
                            _ if judgments.is_empty() => 0.0,
                            _ => evidence_sd(n, &judgments),
                        };
                        let (rho, ramp) = if sd >= threshold { (1.0, 0.0) } else { (DEFAULT_MEAN_WEIGHT, 20.0) };
                        posterior = posterior
                            .clone()
                            .with_mean_weight(rho)
                            .and_then(|p| p.with_mean_ramp(ramp))
                            .expect("a weight");
                        posterior.best_pairs(k, previous, &mut ties).expect("a batch")
                    }
                    Rule::Stein(power) => {
                        let weight = stein_weight(&posterior, power);
                        posterior = posterior.clone().with_mean_weight(weight).expect("a weight");
                        posterior.best_pairs(k, previous, &mut ties).expect("a batch")
                    }
                    Rule::Diagonal(trees) => {
                        let (m, c) = (posterior.mean(), posterior.covariance());
                        let mut scored: Vec<(f64, u64, usize, usize)> = (0..n)
                            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
                            .map(|(i, j)| {
                                let eig = Link::Probit.eig(m[i] - m[j], c[i * n + i] + c[j * n + j], &gauss);
                                (eig, ties.next_u64(), i, j)
                            })
                            .collect();
                        scored.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
                        let best_first = scored.iter().map(|&(_, _, i, j)| (i, j));
                        if trees {
                            (0..k)
                                .map(|_| {
                                    if queue.is_empty() {
                                        queue.extend(spanning_tree(n, best_first.clone()));
                                    }
                                    queue.pop_front().expect("a tree of n − 1 pairs")
                                })
                                .collect()
                        } else {
                            // each condition at most once per batch, then the best pairs left
                            let mut used = vec![false; n];
                            let mut batch: Vec<(usize, usize)> = Vec::new();
                            for (i, j) in best_first.clone() {
                                if batch.len() < k && !used[i] && !used[j] && previous != Some((i, j)) {
                                    used[i] = true;
                                    used[j] = true;
                                    batch.push((i, j));
                                }
                            }
                            for pair in best_first {
                                if batch.len() < k && !batch.contains(&pair) {
                                    batch.push(pair);
                                }
                            }
                            batch
                        }
                    }
                    Rule::Tree => (0..k)
                        .map(|_| {
                            if queue.is_empty() {
                                if !judgments.is_empty() {
                                    posterior.reanchor(&map(&judgments)).expect("a usable refit");
                                }
                                queue.extend(eig_tree(&posterior, &mut ties));
                            }
                            queue.pop_front().expect("a tree of n − 1 pairs")
                        })
                        .collect(),
                    Rule::Balanced => {
                        let scored = scored_pairs(&posterior);
                        let mut last = previous;
                        (0..k)
                            .map(|_| {
                                let least = *counts.iter().min().expect("conditions");
                                let (i, j, _, _) = scored
                                    .iter()
                                    .filter(|&&(i, j, _)| counts[i].min(counts[j]) == least && last != Some((i, j)))
                                    .map(|&(i, j, eig)| (i, j, eig, ties.next_u64()))
                                    .max_by(|a, b| a.2.total_cmp(&b.2).then(a.3.cmp(&b.3)))
                                    .expect("a candidate");
                                counts[i] += 1;
                                counts[j] += 1;
                                last = Some((i, j));
                                (i, j)
                            })
                            .collect()
                    }
                    Rule::Draw(gamma) => {
                        let mut scored = scored_pairs(&posterior);
                        let top = scored.iter().map(|c| c.2).fold(0.0, f64::max);
                        for c in &mut scored {
                            c.2 = (c.2 / top).powf(gamma);
                        }
                        let mut last = previous;
                        (0..k)
                            .map(|_| {
                                let total: f64 = scored.iter().filter(|c| Some((c.0, c.1)) != last).map(|c| c.2).sum();
                                let mut r = uniform(&mut ties) * total;
                                let mut pick = None;
                                for (index, c) in scored.iter().enumerate() {
                                    if Some((c.0, c.1)) != last {
                                        pick = Some(index);
                                        r -= c.2;
                                        if r < 0.0 {
                                            break;
                                        }
                                    }
                                }
                                let (i, j, _) = scored.remove(pick.expect("a pair"));
                                last = Some((i, j));
                                (i, j)
                            })
                            .collect()
                    }
                };
                for (i, j) in pairs {
                    let i_won = uniform(&mut outcomes) < Link::Probit.probability(worths[i] - worths[j]);
                    let (winner, loser) = if i_won { (i, j) } else { (j, i) };
                    if !matches!(rule, Rule::Random) {
                        posterior.update(winner, loser).expect("an update");
                    }
                    judgments.push((winner, loser));
                    previous = Some((i, j));
                    if let Some(c) = checkpoints.iter().position(|&c| c == judgments.len()) {
                        let rmse = if reference {
                            let fit = refit(&target, Link::Probit, 10.0, &judgments).expect("a refit");
                            let differences = |v: &[f64]| v.iter().map(|x| x - v[0]).collect::<Vec<f64>>();
                            let (estimate, truth) = (differences(&fit.mean), differences(&worths));
                            let squares: f64 = estimate.iter().zip(&truth).skip(1).map(|(e, t)| (e - t).powi(2)).sum();
                            (squares / (n - 1) as f64).sqrt()
                        } else if mle {
                            let fit = refit(&target, Link::Probit, 10.0, &judgments).expect("a refit");
                            centred_rmse(&fit.mean, &worths)
                        } else {
                            // the estimate `mrstudy analyze` reports as `log_worth_map` (there
                            // with the logistic link)
                            let judged = judgments.iter().map(|&(w, l)| (w, l, 1));
                            let estimate = laplace::centred_map_log_worths(n, Link::Probit, DEFAULT_PRIOR_SD, judged)
                                .expect("a refit");
                            centred_rmse(&estimate, &worths)
                        };
                        at[c].push(rmse);
                    }
                }
            }
        }
        let cells: Vec<String> = at
            .iter()
            .zip(&checkpoints)
            .map(|(values, trials)| {
                let (mean, se) = mean_and_standard_error(values);
                format!("{trials}: {mean:.decimals$} ± {se:.decimals$}")
            })
            .collect();
        println!("{name:<28} {}", cells.join("   "));
    }
}
