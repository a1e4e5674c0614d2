//! The psychometric fit of a threshold study: maximum likelihood with the threshold and the
//! slope free, the lapse rate free in [0, `lapse_max`] (0.1 by default) and the guess rate
//! fixed; 95 % intervals by parametric bootstrap; the deviance and a goodness-of-fit p by
//! bootstrap of the deviance (Wichmann & Hill 2001).
//!
//! **Model.** p(x) = γ + (1 − γ − δ)·F(u), the functions of [`PsychFunction::prob`] (questplus
//! 2023.1's parameterisations): u = β(x − t) for `weibull` log10 (F(u) = 1 − exp(−10^u)), u =
//! β(x − t)/20 for dB, u = β(ln x − ln t) for linear (F(u) = 1 − exp(−e^u)); u = β(x − t) for
//! `logistic` (F = 1/(1 + e^−u)); u = (x − t)/β for `normal` (F = Φ; β is the sd).
//!
//! **Maximum likelihood.** ℓ(t, β, δ) = Σ_levels k·ln p + (n − k)·ln(1 − p). Projected Fisher
//! scoring in (t, ln β, δ) (ln t for the linear Weibull) with δ in [0, lapse_max] (a coordinate
//! on its bound with the gradient pointing out is held), step halving so that ℓ never falls,
//! from the best point of a coarse grid (thresholds: the levels, their midpoints and 25 points
//! over the range; 15 slopes) at each of δ = 0, 0.3·lapse_max, lapse_max;
//! the best of the three runs. The threshold is kept within the levels' range widened by
//! twice its width on each side, the slope within u spanning 0.01…1000 units over the levels;
//! an estimate on such a bound is reported with a note (the data do not determine it).
//!
//! **Bootstrap.** B replicates k*ᵢ ~ Binomial(nᵢ, p̂(xᵢ)) at the observed levels, each refitted
//! from the grid starts and the original estimate (replicate r draws from ChaCha8 stream r of the seed, so the result does not depend on the
//! thread count); the 2.5 % and 97.5 % quantiles (R's type 7) of t* and β* are the intervals;
//! p_fit = (1 + #{D* ≥ D}) / (B + 1) with D the deviance against the saturated model.
//!
//! **Degenerate data** (no trials, all correct, all wrong, a single level) get no estimates but
//! a reason; they never fail the analysis.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use super::quest::{Params, PsychFunction, StimScale};
use crate::quantile::type7 as quantile_type7;

/// The psychometric model: shape, scale and the fixed guess rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Model {
    pub function: PsychFunction,
    pub scale: StimScale,
    pub guess: f64,
}

/// The trials at one stimulus value: `n` shown, `k` correct.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Point {
    pub x: f64,
    pub n: u32,
    pub k: u32,
}

/// Trials `(x, correct)` gathered per distinct x, sorted by x.
pub fn aggregate(trials: impl IntoIterator<Item = (f64, bool)>) -> Vec<Point> {
    let mut points: Vec<Point> = Vec::new();
    let mut all: Vec<(f64, bool)> = trials.into_iter().collect();
    all.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (x, correct) in all {
        match points.last_mut() {
            Some(p) if p.x == x => {
                p.n += 1;
                p.k += u32::from(correct);
            }
            _ => points.push(Point { x, n: 1, k: u32::from(correct) }),
        }
    }
    points
}

/// How to fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Bootstrap replicates (0: no intervals, no p_fit).
    pub bootstrap: usize,
    pub seed: u64,
    /// The upper bound of the lapse rate (0.1).
    pub lapse_max: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self { bootstrap: 1000, seed: 48, lapse_max: 0.1 }
    }
}

/// A maximum-likelihood point estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MlEstimate {
    pub threshold: f64,
    pub slope: f64,
    pub lapse: f64,
    pub log_likelihood: f64,
    /// 2·(ℓ_saturated − ℓ).
    pub deviance: f64,
    /// The threshold or slope sits on its search bound.
    pub at_bound: Option<&'static str>,
}

/// Why a fit was not made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Degenerate {
    NoTrials,
    AllCorrect,
    AllWrong,
    SingleLevel,
    NoConvergence,
}

impl Degenerate {
    /// One sentence for the report.
    pub fn reason(self) -> &'static str {
        match self {
            Self::NoTrials => "no trials",
            Self::AllCorrect => "every answer correct: the threshold lies below the levels shown",
            Self::AllWrong => "every answer wrong: below chance at every level, no threshold to fit",
            Self::SingleLevel => "a single level shown: a threshold and a slope need at least two",
            Self::NoConvergence => "the likelihood could not be maximised",
        }
    }
}

/// A fit with its bootstrap.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PsychometricFit {
    pub threshold: f64,
    pub slope: f64,
    pub lapse: f64,
    /// 95 % percentile interval, parametric bootstrap (absent without bootstrap).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold_ci: Option<[f64; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slope_ci: Option<[f64; 2]>,
    pub log_likelihood: f64,
    pub deviance: f64,
    /// Goodness of fit: the share of bootstrap deviances at least as large, (1 + #)/(B + 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p_fit: Option<f64>,
    pub bootstrap: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<&'static str>,
}

/// The parts of u = f(x; a, s) the fit needs: u, ∂u/∂a, ∂u/∂s.
#[derive(Clone, Copy)]
struct Shape {
    model: Model,
}

impl Shape {
    /// Whether the threshold is searched on a log axis (the linear-scale Weibull).
    fn log_threshold(self) -> bool {
        self.model.function == PsychFunction::Weibull && self.model.scale == StimScale::Linear
    }

    fn params(self, a: f64, s: f64, lapse: f64) -> Params {
        let threshold = if self.log_threshold() { a.exp() } else { a };
        Params { threshold, slope: s.exp(), lapse }
    }

    /// The span of u per unit of slope over the levels (to scale the slope search).
    fn u_span(self, lo: f64, hi: f64) -> f64 {
        match (self.model.function, self.model.scale) {
            (PsychFunction::Weibull, StimScale::Linear) => (hi / lo).ln(),
            (PsychFunction::Weibull, StimScale::Db) => (hi - lo) / 20.0,
            (PsychFunction::Normal, _) => 1.0 / (hi - lo),
            _ => hi - lo,
        }
    }

    /// p and ∂p/∂a, ∂p/∂s at x.
    fn eval(self, x: f64, a: f64, s: f64, lapse: f64) -> (f64, f64, f64) {
        let m = self.model;
        let b = s.exp();
        let amp = 1.0 - m.guess - lapse;
        let p = m.function.prob(m.scale, x, self.params(a, s, lapse), m.guess);
        let (u, du_da, du_ds) = match (m.function, m.scale) {
            (PsychFunction::Weibull, StimScale::Linear) => {
                let u = b * (x.ln() - a);
                (u, -b, u)
            }
            (PsychFunction::Weibull, StimScale::Db) => {
                let u = b * (x - a) / 20.0;
                (u, -b / 20.0, u)
            }
            (PsychFunction::Normal, _) => {
                let u = (x - a) / b;
                (u, -1.0 / b, -u)
            }
            _ => {
                let u = b * (x - a);
                (u, -b, u)
            }
        };
        let dfdu = match m.function {
            PsychFunction::Weibull if m.scale == StimScale::Linear => {
                let e = u.exp();
                e * (-e).exp()
            }
            PsychFunction::Weibull => {
                let e = 10f64.powf(u);
                std::f64::consts::LN_10 * e * (-e).exp()
            }
            PsychFunction::Logistic => {
                let q = 1.0 / (1.0 + (-u).exp());
                q * (1.0 - q)
            }
            PsychFunction::Normal => (-0.5 * u * u).exp() / (2.0 * std::f64::consts::PI).sqrt(),
        };
        (p, amp * dfdu * du_da, amp * dfdu * du_ds)
    }
}

fn log_lik(shape: Shape, points: &[Point], a: f64, s: f64, lapse: f64) -> f64 {
    let mut l = 0.0;
    for pt in points {
        let p = shape.eval(pt.x, a, s, lapse).0;
        if pt.k > 0 {
            l += f64::from(pt.k) * p.ln();
        }
        if pt.n > pt.k {
            l += f64::from(pt.n - pt.k) * (1.0 - p).ln();
        }
    }
    if l.is_nan() { f64::NEG_INFINITY } else { l }
}

/// ℓ of the saturated model (each level its own proportion).
fn saturated(points: &[Point]) -> f64 {
    points
        .iter()
        .map(|p| {
            let (n, k) = (f64::from(p.n), f64::from(p.k));
            let mut l = 0.0;
            if p.k > 0 {
                l += k * (k / n).ln();
            }
            if p.n > p.k {
                l += (n - k) * ((n - k) / n).ln();
            }
            l
        })
        .sum()
}

#[derive(Clone, Copy)]
struct Bounds {
    a: (f64, f64),
    s: (f64, f64),
    lapse_max: f64,
}

fn bounds(shape: Shape, points: &[Point], lapse_max: f64) -> Bounds {
    let (lo, hi) = (points[0].x, points[points.len() - 1].x);
    let (alo, ahi) = if shape.log_threshold() { (lo.ln(), hi.ln()) } else { (lo, hi) };
    let w = ahi - alo;
    let span = shape.u_span(lo, hi);
    let s = if shape.model.function == PsychFunction::Normal {
        // β is an sd: u spans (hi − lo)/β.
        ((1.0 / (1000.0 * span)).ln(), (1.0 / (0.01 * span)).ln())
    } else {
        ((0.01 / span).ln(), (1000.0 / span).ln())
    };
    Bounds { a: (alo - 2.0 * w, ahi + 2.0 * w), s, lapse_max }
}

/// Projected Fisher scoring in (a, s, δ) from `start` within the box; returns (a, s, δ, ℓ).
fn scoring(shape: Shape, points: &[Point], b: &Bounds, start: [f64; 3]) -> ([f64; 3], f64) {
    let lo = [b.a.0, b.s.0, 0.0];
    let hi = [b.a.1, b.s.1, b.lapse_max];
    let cap = [0.5 * (b.a.1 - b.a.0) / 5.0, 1.0, 0.5 * b.lapse_max];
    let guess = shape.model.guess;
    let mut th = start;
    let mut l = log_lik(shape, points, th[0], th[1], th[2]);
    for _ in 0..500 {
        let mut g = [0.0; 3];
        let mut info = [[0.0; 3]; 3];
        for pt in points {
            let (p, da, ds) = shape.eval(pt.x, th[0], th[1], th[2]);
            let amp = 1.0 - guess - th[2];
            let dd = -(p - guess) / amp;
            let grad = [da, ds, dd];
            // Floored: where p is within 1e-12 of 0 or 1 the level's information (∂p)²/(p(1 − p))
            // vanishes anyway, and an unfloored 1/(p(1 − p)) would swamp the others.
            let v = (p * (1.0 - p)).max(1e-12);
            let r = (f64::from(pt.k) - f64::from(pt.n) * p) / v;
            let w = f64::from(pt.n) / v;
            for i in 0..3 {
                g[i] += r * grad[i];
                for j in 0..3 {
                    info[i][j] += w * grad[i] * grad[j];
                }
            }
        }
        // Coordinates on a bound with the gradient pointing out stay fixed.
        let free: Vec<usize> =
            (0..3).filter(|&i| !((th[i] <= lo[i] && g[i] <= 0.0) || (th[i] >= hi[i] && g[i] >= 0.0))).collect();
        if free.is_empty() {
            break;
        }
        let mut dir = [0.0; 3];
        let sol = solve(
            &free.iter().map(|&i| free.iter().map(|&j| info[i][j]).collect()).collect::<Vec<Vec<f64>>>(),
            &free.iter().map(|&i| g[i]).collect::<Vec<f64>>(),
        );
        for (m, &i) in free.iter().enumerate() {
            dir[i] = sol.as_ref().map_or(g[i], |s| s[m]);
        }
        if dir.iter().any(|d| !d.is_finite()) {
            break;
        }
        let shrink = (0..3).map(|i| dir[i].abs() / cap[i]).fold(1.0, f64::max);
        for d in &mut dir {
            *d /= shrink;
        }
        let mut step = 1.0;
        let mut moved = false;
        for _ in 0..60 {
            let cand: [f64; 3] = std::array::from_fn(|i| (th[i] + step * dir[i]).clamp(lo[i], hi[i]));
            let nl = log_lik(shape, points, cand[0], cand[1], cand[2]);
            if nl >= l {
                let change = (0..3).map(|i| (cand[i] - th[i]).abs()).fold(0.0, f64::max);
                let gain = nl - l;
                th = cand;
                l = nl;
                moved = change > 1e-13 && gain > 1e-14 * (1.0 + l.abs());
                break;
            }
            step *= 0.5;
        }
        if !moved {
            break;
        }
    }
    (th, l)
}

/// The solution of a small symmetric positive-definite system (Gaussian elimination with a
/// ridge), or None when it is singular.
fn solve(a: &[Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    let n = b.len();
    let scale = (0..n).map(|i| a[i][i].abs()).fold(0.0, f64::max).max(1e-300);
    let mut m: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            let mut row = a[i].clone();
            row[i] += 1e-12 * scale;
            row.push(b[i]);
            row
        })
        .collect();
    for c in 0..n {
        let piv = (c..n).max_by(|&x, &y| m[x][c].abs().total_cmp(&m[y][c].abs()))?;
        m.swap(c, piv);
        if !(m[c][c].abs() > 1e-300) {
            return None;
        }
        for r in c + 1..n {
            let f = m[r][c] / m[c][c];
            for k in c..=n {
                m[r][k] -= f * m[c][k];
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| m[r][k] * x[k]).sum();
        x[r] = (m[r][n] - s) / m[r][r];
    }
    Some(x)
}

/// Starting points: the best point of a coarse grid at each of three lapse rates. Thresholds:
/// the levels, the midpoints between neighbours and 25 points over the search range; slopes:
/// 15 log-spaced over theirs.
fn grid_starts(shape: Shape, points: &[Point], b: &Bounds) -> Vec<[f64; 3]> {
    let (alo, ahi) = (b.a.0 + 1.5 * (b.a.1 - b.a.0) / 5.0, b.a.1 - 1.5 * (b.a.1 - b.a.0) / 5.0);
    let to_a = |x: f64| if shape.log_threshold() { x.ln() } else { x };
    let mut thresholds: Vec<f64> = (0..=24).map(|i| alo + (ahi - alo) * f64::from(i) / 24.0).collect();
    for (i, p) in points.iter().enumerate() {
        thresholds.push(to_a(p.x));
        if let Some(q) = points.get(i + 1) {
            thresholds.push(0.5 * (to_a(p.x) + to_a(q.x)));
        }
    }
    [0.0, 0.3 * b.lapse_max, b.lapse_max]
        .iter()
        .map(|&d| {
            let mut best = (f64::NEG_INFINITY, [alo, b.s.0, d]);
            for &a in &thresholds {
                for j in 0..=14 {
                    let s = b.s.0 + (b.s.1 - b.s.0) * f64::from(j) / 14.0;
                    let l = log_lik(shape, points, a, s, d);
                    if l > best.0 {
                        best = (l, [a, s, d]);
                    }
                }
            }
            best.1
        })
        .collect()
}

/// The maximum-likelihood fit (no degeneracy checks: the bootstrap refits any replicate).
pub fn ml_fit(model: Model, points: &[Point], lapse_max: f64) -> Option<MlEstimate> {
    ml_search(model, points, lapse_max, None)
}

/// The ML search: from the grid starts (and, for a bootstrap replicate, the original estimate
/// `from` too, without the check for a flat ridge).
fn ml_search(model: Model, points: &[Point], lapse_max: f64, from: Option<[f64; 3]>) -> Option<MlEstimate> {
    let check_steep = from.is_none();
    if points.is_empty() {
        return None;
    }
    let shape = Shape { model };
    let b = bounds(shape, points, lapse_max);
    let mut best: Option<([f64; 3], f64)> = None;
    // From the original estimate alone, replicates stuck near it (coverage fell to 76 % in the
    // test below): the grid starts stay.
    let mut starts = grid_starts(shape, points, &b);
    starts.extend(from);
    for start in starts {
        let (th, l) = scoring(shape, points, &b, start);
        if best.is_none_or(|(_, bl)| l > bl) {
            best = Some((th, l));
        }
    }
    let ([mut a, mut s, mut lapse], mut l) = best?;
    if !l.is_finite() {
        return None;
    }
    let eps = 1e-6;
    // The slope is undetermined when pushing it to its upper bound costs no likelihood (a
    // flat ridge towards a step function); then the estimate is the one on the bound.
    let mut steep = false;
    if check_steep {
        let (th, ls) = scoring(shape, points, &Bounds { s: (b.s.1, b.s.1), ..b }, [a, b.s.1, lapse]);
        steep = ls >= l - 1e-6;
        if steep && ls > l {
            [a, s, lapse] = th;
            l = ls;
        }
    }
    let params = shape.params(a, s, lapse);
    let at_bound = if (a - b.a.0).abs() < eps || (a - b.a.1).abs() < eps {
        Some("the threshold is at the edge of its search range (levels ± twice their span): the data do not locate it")
    } else if (s - b.s.0).abs() < eps || (s - b.s.1).abs() < eps || steep {
        Some(
            "the slope is not determined (e.g. a jump from chance to all correct between two levels): its estimate and interval reach the edge of the search range",
        )
    } else {
        None
    };
    Some(MlEstimate {
        threshold: params.threshold,
        slope: params.slope,
        lapse,
        log_likelihood: l,
        deviance: (2.0 * (saturated(points) - l)).max(0.0),
        at_bound,
    })
}

/// Why these data get no fit, if they do not.
pub fn degeneracy(points: &[Point]) -> Option<Degenerate> {
    let n: u32 = points.iter().map(|p| p.n).sum();
    let k: u32 = points.iter().map(|p| p.k).sum();
    if n == 0 {
        Some(Degenerate::NoTrials)
    } else if k == n {
        Some(Degenerate::AllCorrect)
    } else if k == 0 {
        Some(Degenerate::AllWrong)
    } else if points.len() < 2 {
        Some(Degenerate::SingleLevel)
    } else {
        None
    }
}

/// The full fit: ML, bootstrap intervals and p_fit; or why not.
pub fn fit(model: Model, points: &[Point], options: &FitOptions) -> Result<PsychometricFit, Degenerate> {
    if let Some(d) = degeneracy(points) {
        return Err(d);
    }
    let ml = ml_fit(model, points, options.lapse_max).ok_or(Degenerate::NoConvergence)?;
    let mut out = PsychometricFit {
        threshold: ml.threshold,
        slope: ml.slope,
        lapse: ml.lapse,
        threshold_ci: None,
        slope_ci: None,
        log_likelihood: ml.log_likelihood,
        deviance: ml.deviance,
        p_fit: None,
        bootstrap: 0,
        note: ml.at_bound,
    };
    if options.bootstrap == 0 {
        return Ok(out);
    }
    let truth = Params { threshold: ml.threshold, slope: ml.slope, lapse: ml.lapse };
    let log_threshold = (Shape { model }).log_threshold();
    let start = [if log_threshold { ml.threshold.ln() } else { ml.threshold }, ml.slope.ln(), ml.lapse];
    let probs: Vec<f64> = points.iter().map(|p| model.function.prob(model.scale, p.x, truth, model.guess)).collect();
    let reps: Vec<MlEstimate> = (0..options.bootstrap)
        .into_par_iter()
        .filter_map(|r| {
            let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
            rng.set_stream(r as u64);
            let sim: Vec<Point> = points
                .iter()
                .zip(&probs)
                .map(|(pt, &p)| Point {
                    x: pt.x,
                    n: pt.n,
                    k: (0..pt.n).filter(|_| rng.random::<f64>() < p).count() as u32,
                })
                .collect();
            ml_search(model, &sim, options.lapse_max, Some(start))
        })
        .collect();
    if reps.len() < 2 {
        return Ok(out);
    }
    let ci = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        [quantile_type7(&v, 0.025), quantile_type7(&v, 0.975)]
    };
    out.threshold_ci = Some(ci(reps.iter().map(|r| r.threshold).collect()));
    out.slope_ci = Some(ci(reps.iter().map(|r| r.slope).collect()));
    let larger = reps.iter().filter(|r| r.deviance >= ml.deviance).count();
    out.p_fit = Some((1 + larger) as f64 / (reps.len() + 1) as f64);
    out.bootstrap = reps.len();
    Ok(out)
}
