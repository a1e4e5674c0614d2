//! JOD (just-objectionable differences) as pwcmp computes them (Mantiuk's
//! github.com/mantiuk/pwcmp, `pw_scale` with its defaults, commit 07876b2): a Thurstone Case V
//! scale on which P(i chosen over j) = Φ((qᵢ − qⱼ)/σ) with σ = 1.4826, so that 1 JOD is 75 %
//! preference; the maximum of the likelihood times pwcmp's "gaussian" distance prior, with its
//! mean-0 regularisation. [`bootstrap`] is `pw_scale_bootstrp` (observers resampled, percentile
//! interval and covariance of the replicates) and [`outliers`] `pw_outlier_analysis`.
//!
//! pw_scale minimises, over the ordered pairs a = (i, j) with nᵢⱼ = Dᵢⱼ + Dⱼᵢ > 0
//! (each unordered pair counted twice, as pwcmp does),
//!
//! `−Σₐ [Dᵢⱼ ln pₐ + Dⱼᵢ ln(1 − pₐ)] − Σₐ ln(priorₐ + 0.1) + 0.01·mean(q)²`, pₐ = Φ((qᵢ − qⱼ)/σ),
//!
//! `priorₐ = Σ_b pₐ^{k_b} (1 − pₐ)^{n_b − k_b} / Σ_c p_c^{k_b} (1 − p_c)^{n_b − k_b}`, where k_b is
//! D of pair b with unanimous pairs moved one vote towards the other side (0 becomes 1, and the
//! other side loses one). Disconnected components of the comparison graph are linked as pwcmp
//! links them: one vote each way between each component's best condition by ISO 20462's
//! first estimate. Differences from the MATLAB code, none of which changes the minimum: the
//! prior is summed in logarithms (pwcmp's products underflow to 0/0 beyond some hundreds of
//! judgments per pair), observations with the same (k, n) are summed once, and the minimum
//! is found by BFGS with a line search and Newton steps instead of `fminunc`.
//!
//! Ties count as half a vote each way (pwcmp's `pw_scale_bootstrp` assigns 0.5 to both
//! conditions for an answer without preference); pwcmp then rounds the fractional counts at
//! random to integers, which this module does not: the likelihood takes the half votes as they
//! are (equal to pwcmp wherever the ties of a pair are even in number).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use statrs::function::erf::erfc;
use statrs::function::gamma::ln_gamma;

use crate::data::Judgment;
use crate::design::ParticipantTallies;

/// σ of pwcmp's cumulative normal: Φ(1/σ) = 0.75.
pub const SIGMA: f64 = 1.4826;

/// A comparison matrix: `wins[i * n + j]` is how often condition i was chosen over j (half a
/// vote each way per tie).
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    pub n: usize,
    pub wins: Vec<f64>,
}

impl Matrix {
    pub fn zeros(n: usize) -> Matrix {
        Matrix { n, wins: vec![0.0; n * n] }
    }

    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.wins[i * self.n + j]
    }

    pub fn add(&mut self, other: &Matrix) {
        for (a, b) in self.wins.iter_mut().zip(&other.wins) {
            *a += b;
        }
    }
}

/// Why a JOD scale could not be computed, with the values that show it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum JodFailure {
    /// The count of condition `i` chosen over `j` is negative or not finite.
    #[error("a comparison count is negative or not finite")]
    BadCount { i: usize, j: usize, count: f64 },
    /// Nothing was compared among the `conditions`.
    #[error("no pair of conditions was compared")]
    NoComparisons { conditions: usize },
    /// The minimisation did not converge; its gradient's largest component was `gradient`.
    #[error("the JOD scaling did not converge")]
    NotConverged { gradient: f64 },
}

/// ln Φ(x) and Φ'(x)/Φ(x), accurate far into the lower tail.
fn log_cdf_and_ratio(x: f64) -> (f64, f64) {
    let cdf = 0.5 * erfc(-x / std::f64::consts::SQRT_2);
    let log_pdf = -0.5 * x * x - 0.5 * (2.0 * std::f64::consts::PI).ln();
    if cdf > 1e-300 {
        (cdf.ln(), (log_pdf - cdf.ln()).exp())
    } else {
        // Φ(x) ≈ φ(x)/|x| below the underflow
        let log_cdf = log_pdf - (-x).ln();
        (log_cdf, -x)
    }
}

/// The ordered pairs with comparisons and the prior's observations, fixed for one matrix.
struct Problem {
    n: usize,
    /// (i, j, Dᵢⱼ, Dⱼᵢ) per ordered pair with nᵢⱼ > 0.
    pairs: Vec<(usize, usize, f64, f64)>,
    /// Distinct (k, n) of the prior with their multiplicity.
    observations: Vec<(f64, f64, f64)>,
}

impl Problem {
    fn new(matrix: &Matrix) -> Problem {
        let n = matrix.n;
        let mut d = matrix.wins.clone();
        let compared = |d: &[f64], i: usize, j: usize| d[i * n + j] + d[j * n + i] > 0.0;
        // Components of the comparison graph; pwcmp links each one's best by ISO 20462's
        // first estimate (the first such condition) to the others' with a vote each way.
        let mut component = vec![usize::MAX; n];
        let mut count = 0;
        for start in 0..n {
            if component[start] != usize::MAX {
                continue;
            }
            let mut stack = vec![start];
            component[start] = count;
            while let Some(i) = stack.pop() {
                for j in 0..n {
                    if j != i && component[j] == usize::MAX && compared(&d, i, j) {
                        component[j] = count;
                        stack.push(j);
                    }
                }
            }
            count += 1;
        }
        if count > 1 {
            let iso: Vec<f64> = (0..n)
                .map(|j| {
                    (0..n)
                        .map(|i| {
                            let total = d[i * n + j] + d[j * n + i];
                            let m = if total > 0.0 { d[i * n + j] / total } else { 0.5 };
                            -(12.0 / std::f64::consts::PI * m.sqrt().asin() - 3.0) / 2.0
                        })
                        .sum()
                })
                .collect();
            let best: Vec<usize> = (0..count)
                .map(|k| {
                    let members = (0..n).filter(|&c| component[c] == k);
                    let top = members.clone().map(|c| iso[c]).fold(f64::NEG_INFINITY, f64::max);
                    members.into_iter().find(|&c| iso[c] == top).expect("a component has members")
                })
                .collect();
            for (a, &x) in best.iter().enumerate() {
                for &y in &best[a + 1..] {
                    d[x * n + y] = 1.0;
                    d[y * n + x] = 1.0;
                }
            }
        }
        let mut pairs = Vec::new();
        let mut observations: Vec<(f64, f64, f64)> = Vec::new();
        // pwcmp's order (column-major) does not matter to the sums.
        for i in 0..n {
            for j in 0..n {
                let (dij, dji) = (d[i * n + j], d[j * n + i]);
                if i == j || dij + dji <= 0.0 {
                    continue;
                }
                pairs.push((i, j, dij, dji));
                let unanimous = !(dij > 0.0 && dji > 0.0);
                let k = match (unanimous, dij == 0.0) {
                    (true, true) => 1.0,
                    (true, false) => dij - 1.0,
                    (false, _) => dij,
                };
                let total = dij + dji;
                match observations.iter_mut().find(|o| o.0 == k && o.1 == total) {
                    Some(o) => o.2 += 1.0,
                    None => observations.push((k, total, 1.0)),
                }
            }
        }
        Problem { n, pairs, observations }
    }

    /// The objective and its gradient at `q`.
    fn evaluate(&self, q: &[f64], gradient: &mut [f64]) -> f64 {
        let n = self.n;
        gradient.fill(0.0);
        let p = self.pairs.len();
        // per pair: ln p, ln(1 − p), dp/dη
        let mut log_p = vec![0.0; p];
        let mut log_q = vec![0.0; p];
        let mut dprob = vec![0.0; p];
        let mut objective = 0.0;
        let mut d_eta = vec![0.0; p];
        for (a, &(i, j, dij, dji)) in self.pairs.iter().enumerate() {
            let x = (q[i] - q[j]) / SIGMA;
            let (lp, rp) = log_cdf_and_ratio(x);
            let (lq, rq) = log_cdf_and_ratio(-x);
            log_p[a] = lp;
            log_q[a] = lq;
            let pdf = (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt() / SIGMA;
            dprob[a] = pdf;
            objective -= dij * lp + dji * lq;
            // d/dη of −[Dᵢⱼ ln Φ + Dⱼᵢ ln(1 − Φ)]
            d_eta[a] -= (dij * rp - dji * rq) / SIGMA;
        }
        // The prior, in logarithms.
        let u_count = self.observations.len();
        let mut log_s = vec![0.0; u_count];
        let mut log_aux = vec![0.0; u_count * p];
        for (u, &(k, total, _)) in self.observations.iter().enumerate() {
            let mut max = f64::NEG_INFINITY;
            for a in 0..p {
                let value = k * log_p[a] + (total - k) * log_q[a];
                log_aux[u * p + a] = value;
                max = max.max(value);
            }
            let sum: f64 = (0..p).map(|a| (log_aux[u * p + a] - max).exp()).sum();
            log_s[u] = max + sum.ln();
        }
        // π(a, u) = aux(a, u)/S_u; prior_a = Σ_u m_u π(a, u)
        let mut prior = vec![0.0; p];
        for (u, &(_, _, m)) in self.observations.iter().enumerate() {
            for a in 0..p {
                prior[a] += m * (log_aux[u * p + a] - log_s[u]).exp();
            }
        }
        for &value in &prior {
            objective -= (value + 0.1).ln();
        }
        // T_u = Σ_a m_u π(a, u)/(prior_a + 0.1)
        for (u, &(k, total, m)) in self.observations.iter().enumerate() {
            let t_u: f64 = (0..p).map(|a| m * (log_aux[u * p + a] - log_s[u]).exp() / (prior[a] + 0.1)).sum();
            for a in 0..p {
                // π(a, u)·∂ln aux(a, u)/∂p = π·k/p − π·(n − k)/(1 − p), each in logarithms
                let log_pi = log_aux[u * p + a] - log_s[u];
                let mut r_pi = 0.0;
                if k > 0.0 {
                    r_pi += k * (log_pi - log_p[a]).exp();
                }
                if total - k > 0.0 {
                    r_pi -= (total - k) * (log_pi - log_q[a]).exp();
                }
                d_eta[a] -= dprob[a] * r_pi * (m / (prior[a] + 0.1) - t_u);
            }
        }
        for (a, &(i, j, ..)) in self.pairs.iter().enumerate() {
            gradient[i] += d_eta[a];
            gradient[j] -= d_eta[a];
        }
        let mean = q.iter().sum::<f64>() / n as f64;
        objective += 0.01 * mean * mean;
        for g in gradient.iter_mut() {
            *g += 0.01 * 2.0 * mean / n as f64;
        }
        objective
    }
}

/// pwcmp's `pw_scale(D)` with its defaults (`prior` "gaussian", `regularization` "mean0"):
/// the JOD of each condition, mean about 0.
pub fn scale(matrix: &Matrix) -> Result<Vec<f64>, JodFailure> {
    if let Some(at) = matrix.wins.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(JodFailure::BadCount { i: at / matrix.n, j: at % matrix.n, count: matrix.wins[at] });
    }
    let problem = Problem::new(matrix);
    if problem.pairs.is_empty() {
        return Err(JodFailure::NoComparisons { conditions: matrix.n });
    }
    minimise(&problem)
}

/// The longest step of [`minimise`], in JOD.
const MAX_STEP: f64 = 0.5;

/// BFGS from q = 0 (pwcmp's start) with a backtracking line search, until the gradient is below
/// 1e-9 or a step moves no JOD by more than 1e-10.
fn minimise(problem: &Problem) -> Result<Vec<f64>, JodFailure> {
    let n = problem.n;
    let mut q = vec![0.0; n];
    let mut g = vec![0.0; n];
    let mut f = problem.evaluate(&q, &mut g);
    // inverse Hessian estimate
    let mut h = vec![0.0; n * n];
    for k in 0..n {
        h[k * n + k] = 1.0;
    }
    let (mut q_new, mut g_new) = (vec![0.0; n], vec![0.0; n]);
    for _ in 0..2000 {
        let largest = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if largest < 1e-9 {
            return Ok(q);
        }
        let mut direction: Vec<f64> = (0..n).map(|a| -(0..n).map(|b| h[a * n + b] * g[b]).sum::<f64>()).collect();
        let mut slope: f64 = direction.iter().zip(&g).map(|(d, g)| d * g).sum();
        if !(slope < 0.0) {
            // not a descent direction: restart from steepest descent
            h.fill(0.0);
            for k in 0..n {
                h[k * n + k] = 1.0;
            }
            direction = g.iter().map(|x| -x).collect();
            slope = -g.iter().map(|x| x * x).sum::<f64>();
        }
        // At most half a JOD per step, as a trust region: far apart, the objective is flat to
        // rounding (a unanimous pair's likelihood and prior stop changing), and a long first
        // step would stop there, beyond the minimum.
        let longest = direction.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let mut step = if longest > MAX_STEP { MAX_STEP / longest } else { 1.0 };
        let mut accepted = false;
        for _ in 0..60 {
            for k in 0..n {
                q_new[k] = q[k] + step * direction[k];
            }
            let f_new = problem.evaluate(&q_new, &mut g_new);
            if f_new.is_finite() && f_new <= f + 1e-4 * step * slope {
                f = f_new;
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if !accepted {
            // no decrease found at double precision (the objective sums hundreds of terms):
            // converged as far as it goes where the quasi-Newton step is already tiny
            let largest = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            return if largest < 1e-4 || longest < 1e-6 {
                Ok(q)
            } else {
                Err(JodFailure::NotConverged { gradient: largest })
            };
        }
        let s: Vec<f64> = (0..n).map(|k| q_new[k] - q[k]).collect();
        let y: Vec<f64> = (0..n).map(|k| g_new[k] - g[k]).collect();
        let sy: f64 = s.iter().zip(&y).map(|(a, b)| a * b).sum();
        if sy > 1e-300 {
            let hy: Vec<f64> = (0..n).map(|a| (0..n).map(|b| h[a * n + b] * y[b]).sum()).collect();
            let yhy: f64 = y.iter().zip(&hy).map(|(a, b)| a * b).sum();
            for a in 0..n {
                for b in 0..n {
                    h[a * n + b] += (sy + yhy) * s[a] * s[b] / (sy * sy) - (hy[a] * s[b] + s[a] * hy[b]) / sy;
                }
            }
        }
        std::mem::swap(&mut q, &mut q_new);
        std::mem::swap(&mut g, &mut g_new);
        if step * longest < 1e-10 {
            return Ok(q);
        }
    }
    Err(JodFailure::NotConverged { gradient: g.iter().fold(0.0f64, |m, x| m.max(x.abs())) })
}

/// The bootstrap of `pw_scale_bootstrp`: pw_scale of the summed matrices of each resample of
/// observers (`resamples[b]` lists observer indices), the 2.5 and 97.5 percentiles as MATLAB's
/// `prctile` takes them, and the replicates' covariance. Resamples that cannot be scaled are
/// left out (counted in `failed`).
pub fn bootstrap(observers: &[Matrix], resamples: &[Vec<usize>], alpha: f64) -> Option<Bootstrapped> {
    let n = observers.first()?.n;
    let replicates: Vec<Vec<f64>> = resamples
        .par_iter()
        .filter_map(|sample| {
            let mut sum = Matrix::zeros(n);
            for &o in sample {
                sum.add(&observers[o]);
            }
            scale(&sum).ok()
        })
        .collect();
    let failed = resamples.len() - replicates.len();
    if replicates.len() < 2 {
        return None;
    }
    let mut low = Vec::with_capacity(n);
    let mut high = Vec::with_capacity(n);
    for c in 0..n {
        let mut values: Vec<f64> = replicates.iter().map(|r| r[c]).collect();
        values.sort_by(f64::total_cmp);
        low.push(quantile_method5(&values, alpha / 2.0));
        high.push(quantile_method5(&values, 1.0 - alpha / 2.0));
    }
    let b = replicates.len() as f64;
    let means: Vec<f64> = (0..n).map(|c| replicates.iter().map(|r| r[c]).sum::<f64>() / b).collect();
    let mut covariance = vec![0.0; n * n];
    for r in &replicates {
        for x in 0..n {
            for y in 0..n {
                covariance[x * n + y] += (r[x] - means[x]) * (r[y] - means[y]) / (b - 1.0);
            }
        }
    }
    Some(Bootstrapped { low, high, covariance, failed })
}

/// What [`bootstrap`] returns.
#[derive(Debug, Clone)]
pub struct Bootstrapped {
    pub low: Vec<f64>,
    pub high: Vec<f64>,
    /// Row-major n×n covariance of the replicates.
    pub covariance: Vec<f64>,
    pub failed: usize,
}

/// MATLAB's `quantile`/`prctile` (and Octave's default, method 5): the sorted values at
/// probabilities (k − 0.5)/n, linear between, the ends beyond.
pub fn quantile_method5(sorted: &[f64], p: f64) -> f64 {
    let n = sorted.len();
    let position = p * n as f64 - 0.5;
    if position <= 0.0 {
        return sorted[0];
    }
    if position >= (n - 1) as f64 {
        return sorted[n - 1];
    }
    let low = position.floor() as usize;
    let fraction = position - low as f64;
    sorted[low] + fraction * (sorted[low + 1] - sorted[low])
}

/// `pw_outlier_analysis`: per observer, the log10 likelihood per compared pair of their own
/// matrix under the JOD of everybody else (binomial probabilities, each at least 1e-200),
/// summed over `groups` (e.g. scenes; an observer absent from a group adds nothing there),
/// and dist_L, the distance below the lower quartile in interquartile ranges (0 above it).
/// pwcmp's example removes observers with dist_L > 1.5.
pub fn outliers(groups: &[Vec<Option<Matrix>>]) -> Result<(Vec<f64>, Vec<f64>), JodFailure> {
    let n_observers = groups.first().map_or(0, |g| g.len());
    let mut log_likelihood = vec![0.0; n_observers];
    let mut trials = vec![0usize; n_observers];
    for group in groups {
        let Some(n) = group.iter().flatten().map(|m| m.n).next() else { continue };
        for (o, own) in group.iter().enumerate() {
            let Some(own) = own else { continue };
            let mut others = Matrix::zeros(n);
            for (k, matrix) in group.iter().enumerate() {
                if let (true, Some(matrix)) = (k != o, matrix) {
                    others.add(matrix);
                }
            }
            let jod = scale(&others)?;
            for i in 0..n {
                for j in i + 1..n {
                    let (x, y) = (own.get(i, j), own.get(j, i));
                    let total = x + y;
                    if total <= 0.0 {
                        continue;
                    }
                    let z = (jod[i] - jod[j]) / SIGMA;
                    let (log_p, _) = log_cdf_and_ratio(z);
                    let (log_q, _) = log_cdf_and_ratio(-z);
                    let ln = ln_gamma(total + 1.0) - ln_gamma(x + 1.0) - ln_gamma(y + 1.0)
                        + if x > 0.0 { x * log_p } else { 0.0 }
                        + if y > 0.0 { y * log_q } else { 0.0 };
                    log_likelihood[o] += (ln / std::f64::consts::LN_10).max(-200.0);
                    trials[o] += 1;
                }
            }
        }
    }
    let l: Vec<f64> = log_likelihood.iter().zip(&trials).map(|(s, &t)| s / t.max(1) as f64).collect();
    let mut sorted = l.clone();
    sorted.sort_by(f64::total_cmp);
    if sorted.is_empty() {
        return Ok((l, Vec::new()));
    }
    let first = quantile_method5(&sorted, 0.25);
    let range = quantile_method5(&sorted, 0.75) - first;
    let dist = l.iter().map(|&x| if x < first && range > 0.0 { (first - x) / range } else { 0.0 }).collect();
    Ok((l, dist))
}

/// pwcmp's significance of a difference (`pw_significance_matrix`): the two-sided p of
/// qᵢ − qⱼ under a normal with the bootstrap's variance of the difference.
pub fn difference_p(jod: &[f64], covariance: &[f64], i: usize, j: usize) -> f64 {
    let n = jod.len();
    let variance = covariance[i * n + i] + covariance[j * n + j] - 2.0 * covariance[i * n + j];
    if !(variance > 0.0) {
        return if jod[i] == jod[j] { 1.0 } else { 0.0 };
    }
    let z = (jod[i] - jod[j]).abs() / variance.sqrt();
    (erfc(z / std::f64::consts::SQRT_2)).min(1.0)
}

/// pwcmp's outlier analysis of one participant.
#[derive(Debug, Clone, Serialize)]
pub struct JodObserver {
    pub participant: String,
    /// `pw_outlier_analysis`'s L: log10 likelihood per compared pair under the others' JOD.
    pub log10_likelihood: f64,
    /// Distance below the lower quartile of L, in interquartile ranges (0 above it).
    pub dist_l: f64,
    /// dist_L > 1.5 (pwcmp's example's cut-off); nobody is dropped.
    pub outlier: bool,
}

/// Two conditions next to each other in the JOD ranking.
#[derive(Debug, Clone, Serialize)]
pub struct JodNeighbour {
    pub lower: String,
    pub upper: String,
    /// JOD of `upper` minus JOD of `lower`.
    pub difference: f64,
    /// Two-sided p of the difference under the bootstrap's covariance (`pw_significance_matrix`);
    /// absent without `--bootstrap`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub significant: Option<bool>,
}

/// The `jod_scale` section of the Analysis JSON.
#[derive(Debug, Clone, Serialize)]
pub struct JodSection {
    /// σ of the cumulative normal (1 JOD = 75 %).
    pub sigma: f64,
    /// Ties counted as half a vote each way.
    pub ties: u64,
    /// `pw_outlier_analysis` per participant (absent with fewer than three participants).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub observers: Vec<JodObserver>,
    /// Participants with dist_L > 1.5.
    pub outliers: Vec<String>,
    /// The compared conditions by JOD, lowest first, with each neighbour's difference.
    pub ranking: Vec<JodNeighbour>,
    /// Bootstrap resamples whose scaling failed (left out of the intervals).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bootstrap_failed: Option<usize>,
    #[serde(skip)]
    pub warnings: Vec<String>,
}

/// Per-condition JOD, their bootstrap intervals (`bootstrap_replicates` resamples of the
/// participants, seeded as the log-worth bootstrap, where more than 0) and the
/// `jod_scale` section, from the active participants' tallies and their ties (half a vote each
/// way), or why there is no JOD scale.
pub type JodAnalysis = (Vec<f64>, Option<Vec<[f64; 2]>>, JodSection);

pub fn analyze(
    tallies: &ParticipantTallies,
    ties: &[Judgment],
    active: &[usize],
    condition_names: &[String],
    participant_names: &[String],
    bootstrap_replicates: usize,
    seed: u64,
) -> Result<JodAnalysis, JodFailure> {
    let n_conditions = condition_names.len();
    let mut position = vec![usize::MAX; participant_names.len()];
    let mut observers: Vec<Matrix> = active
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            position[p] = k;
            let mut m = Matrix::zeros(n_conditions);
            for pair in tallies.of(p) {
                m.wins[pair.i * n_conditions + pair.j] += pair.wins_i as f64;
                m.wins[pair.j * n_conditions + pair.i] += pair.wins_j as f64;
            }
            m
        })
        .collect();
    let mut tie_count = 0;
    for tie in ties {
        let Some(&k) = position.get(tie.participant as usize).filter(|&&k| k != usize::MAX) else { continue };
        let (i, j, half) = (tie.left as usize, tie.right as usize, 0.5 * tie.count as f64);
        observers[k].wins[i * n_conditions + j] += half;
        observers[k].wins[j * n_conditions + i] += half;
        tie_count += tie.count;
    }
    let mut pooled = Matrix::zeros(n_conditions);
    for m in &observers {
        pooled.add(m);
    }
    let jod = scale(&pooled)?;
    let mut warnings = Vec::new();
    let compared: Vec<usize> =
        (0..n_conditions).filter(|&c| (0..n_conditions).any(|d| pooled.get(c, d) + pooled.get(d, c) > 0.0)).collect();
    let (mut records, mut outliers) = (Vec::new(), Vec::new());
    if observers.len() >= 3 {
        match self::outliers(&[observers.iter().cloned().map(Some).collect()]) {
            Ok((l, dist)) => {
                for (k, &p) in active.iter().enumerate() {
                    let outlier = dist[k] > 1.5;
                    if outlier {
                        outliers.push(participant_names[p].clone());
                    }
                    records.push(JodObserver {
                        participant: participant_names[p].clone(),
                        log10_likelihood: l[k],
                        dist_l: dist[k],
                        outlier,
                    });
                }
            }
            Err(e) => warnings.push(format!("JOD outlier analysis not estimable: {e} for some participant's others")),
        }
    }
    let mut intervals = None;
    let mut covariance = None;
    let mut bootstrap_failed = None;
    if bootstrap_replicates > 0 && observers.len() >= 2 {
        let resamples: Vec<Vec<usize>> = (0..bootstrap_replicates)
            .map(|b| {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(b as u64 + 1);
                (0..observers.len()).map(|_| rng.random_range(0..observers.len())).collect()
            })
            .collect();
        match bootstrap(&observers, &resamples, 0.05) {
            Some(found) => {
                if found.failed > 0 {
                    warnings.push(format!(
                        "JOD bootstrap: {} of {} resamples could not be scaled and are left out",
                        found.failed, bootstrap_replicates
                    ));
                }
                intervals = Some((0..n_conditions).map(|c| [found.low[c], found.high[c]]).collect());
                covariance = Some(found.covariance);
                bootstrap_failed = Some(found.failed);
            }
            None => warnings.push("JOD bootstrap: fewer than two resamples could be scaled; no intervals".into()),
        }
    }
    let mut order = compared.clone();
    order.sort_by(|&a, &b| jod[a].total_cmp(&jod[b]));
    let ranking = order
        .windows(2)
        .map(|w| {
            let p = covariance.as_ref().map(|c| difference_p(&jod, c, w[1], w[0]));
            JodNeighbour {
                lower: condition_names[w[0]].clone(),
                upper: condition_names[w[1]].clone(),
                difference: jod[w[1]] - jod[w[0]],
                p,
                significant: p.map(|p| p < 0.05),
            }
        })
        .collect();
    let section =
        JodSection { sigma: SIGMA, ties: tie_count, observers: records, outliers, ranking, bootstrap_failed, warnings };
    Ok((jod, intervals, section))
}

#[cfg(test)]
mod tests;
