//! The Bradley–Terry model as a binomial GLM with logit link, fitted on pair tallies.
//!
//! Every condition i has a model row xᵢ (sparse); its log-worth is λᵢ = xᵢ·β. One unordered pair
//! (i, j) with nᵢⱼ judgments is one binomial observation: yᵢⱼ = wins of i,
//! P(i chosen over j) = σ(λᵢ − λⱼ) = 1 / (1 + exp(−(xᵢ − xⱼ)·β)). This is exactly the model of
//! R's `BradleyTerry2::BTm` with data in `countsToBinomial` form, so log-likelihood, deviance
//! and AIC are comparable with R (the log-likelihood includes the binomial coefficients, as
//! R's `logLik.glm` does).
//!
//! Two estimators:
//! - **maximum likelihood** by Newton–Raphson (= Fisher scoring for the canonical link) with
//!   step halving;
//! - **Firth's bias reduction** (penalised likelihood l(β) + ½·log|I(β)|, as BradleyTerry2's
//!   `br = TRUE` through brglm), by the modified-score iteration
//!   U*(β) = Σ dᵢⱼ·(yᵢⱼ − nᵢⱼπᵢⱼ + hᵢⱼ(½ − πᵢⱼ)), hᵢⱼ the leverages. It exists where the MLE does
//!   not (separation), and is the one estimate reported then.
//!
//! Standard errors come from the inverse Fisher information at the estimate.
//!
//! Cost per iteration: O(Σ nnz(dᵢⱼ)²) to assemble the information matrix plus one dense
//! Cholesky factorisation of the p×p information (faer); Firth additionally needs the inverse.

use faer::linalg::solvers::DenseSolveCore;
use faer::prelude::*;
use faer::{Mat, Side};
use statrs::function::gamma::ln_gamma;

use crate::design::PairTally;

/// A model row per condition, sparse: `(column, value)` with distinct columns.
#[derive(Debug, Clone)]
pub struct ModelMatrix {
    pub n_params: usize,
    pub rows: Vec<Vec<(usize, f64)>>,
}

impl ModelMatrix {
    /// The item model: one indicator column per condition except the reference.
    /// `members` are the conditions of one comparison component (global indices), `reference`
    /// one of them. Conditions outside `members` get an empty row.
    pub fn items(n_conditions: usize, members: &[usize], reference: usize) -> ModelMatrix {
        let mut rows = vec![Vec::new(); n_conditions];
        let mut column = 0;
        for &member in members {
            if member != reference {
                rows[member] = vec![(column, 1.0)];
                column += 1;
            }
        }
        ModelMatrix { n_params: column, rows }
    }

    /// A dense covariate matrix (rows = conditions) restricted to the kept columns.
    pub fn covariates(values: &[Vec<f64>], kept: &[usize]) -> ModelMatrix {
        let rows = values
            .iter()
            .map(|row| {
                kept.iter()
                    .enumerate()
                    .filter(|(_, source)| row[**source] != 0.0)
                    .map(|(column, &source)| (column, row[source]))
                    .collect()
            })
            .collect();
        ModelMatrix { n_params: kept.len(), rows }
    }

    /// Linear predictor λᵢ = xᵢ·β of one condition.
    pub fn predict(&self, condition: usize, beta: &[f64]) -> f64 {
        self.rows[condition].iter().map(|&(column, value)| value * beta[column]).sum()
    }
}

/// Which estimator produced a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Maximum likelihood.
    Ml,
    /// Firth's bias-reduced (penalised) likelihood.
    Firth,
}

impl Method {
    pub fn describe(self) -> &'static str {
        match self {
            Method::Ml => "maximum likelihood",
            Method::Firth => "Firth bias-reduced (penalised) likelihood",
        }
    }
}

/// Convergence settings.
#[derive(Debug, Clone, Copy)]
pub struct FitOptions {
    /// Converged when the largest parameter change of an iteration is below this (for Firth's
    /// fit: of the full scoring step I⁻¹·U*, the gradient, however far the line search shrank
    /// the step taken).
    pub tolerance: f64,
    pub max_iterations: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { tolerance: 1e-10, max_iterations: 200 }
    }
}

/// |η| beyond which a fitted probability is treated as 0 or 1: the MLE is running off to
/// infinity (separation). σ(35) = 1 − 6e-16.
const SEPARATION_ETA: f64 = 35.0;

/// Why a fit could not be made.
#[derive(Debug, Clone, PartialEq)]
pub enum FitFailure {
    /// The information matrix is singular: the parameters are not identifiable.
    Singular,
    /// The maximum-likelihood estimate does not exist (the linear predictor diverges).
    Separation,
    /// No convergence within the iteration limit.
    NotConverged { iterations: usize, last_change: f64 },
}

/// A fitted model.
#[derive(Debug, Clone)]
pub struct Fit {
    pub method: Method,
    pub beta: Vec<f64>,
    /// Inverse Fisher information at `beta` (p×p).
    pub covariance: Mat<f64>,
    /// Log-likelihood including binomial coefficients (as R's `logLik`).
    pub log_likelihood: f64,
    /// Log-likelihood without the binomial coefficients, Σ y·ln π + (n−y)·ln(1−π): additive
    /// over any split of the data, so likelihood-ratio tests across groups use it.
    pub kernel_log_likelihood: f64,
    /// Residual deviance against the saturated model of one binomial per unordered pair.
    pub deviance: f64,
    /// Number of binomial observations (pairs with at least one judgment).
    pub n_observations: usize,
    pub iterations: usize,
}

impl Fit {
    pub fn se(&self, column: usize) -> f64 {
        self.covariance[(column, column)].max(0.0).sqrt()
    }

    /// Variance of the difference of two linear combinations given as sparse rows.
    pub fn variance_of(&self, row: &[(usize, f64)]) -> f64 {
        let mut variance = 0.0;
        for &(a, va) in row {
            for &(b, vb) in row {
                variance += va * vb * self.covariance[(a, b)];
            }
        }
        variance.max(0.0)
    }

    pub fn aic(&self) -> f64 {
        -2.0 * self.log_likelihood + 2.0 * self.beta.len() as f64
    }

    pub fn df_residual(&self) -> i64 {
        self.n_observations as i64 - self.beta.len() as i64
    }
}

/// One binomial observation with its sparse design row dᵢⱼ = xᵢ − xⱼ.
struct Observation {
    design: Vec<(usize, f64)>,
    wins: f64,
    n: f64,
}

fn observations(pairs: &[PairTally], x: &ModelMatrix) -> Vec<Observation> {
    pairs
        .iter()
        .filter(|pair| pair.n() > 0)
        .map(|pair| {
            let mut design: Vec<(usize, f64)> = x.rows[pair.i].clone();
            for &(column, value) in &x.rows[pair.j] {
                match design.iter_mut().find(|(c, _)| *c == column) {
                    Some(entry) => entry.1 -= value,
                    None => design.push((column, -value)),
                }
            }
            design.retain(|&(_, value)| value != 0.0);
            Observation { design, wins: pair.wins_i as f64, n: pair.n() as f64 }
        })
        .collect()
}

/// ln(1 + eˣ) without overflow.
pub(crate) fn softplus(x: f64) -> f64 {
    // ln(1 + e^x) = max(x, 0) + ln(1 + e^(−|x|)); both sides' arithmetic, joined by a select.
    let tail = (-x.abs()).exp().ln_1p();
    if x > 0.0 { x + tail } else { tail }
}

fn sigmoid(x: f64) -> f64 {
    if x >= 0.0 {
        1.0 / (1.0 + (-x).exp())
    } else {
        let e = x.exp();
        e / (1.0 + e)
    }
}

fn eta(observation: &Observation, beta: &[f64]) -> f64 {
    observation.design.iter().map(|&(column, value)| value * beta[column]).sum()
}

/// Kernel log-likelihood Σ y·ln π + (n−y)·ln(1−π) (no binomial coefficients).
fn kernel_log_likelihood(observations: &[Observation], beta: &[f64]) -> f64 {
    observations
        .iter()
        .map(|o| {
            let eta = eta(o, beta);
            -o.wins * softplus(-eta) - (o.n - o.wins) * softplus(eta)
        })
        .sum()
}

fn ln_choose(n: f64, k: f64) -> f64 {
    if k == 0.0 || k == n { 0.0 } else { ln_gamma(n + 1.0) - ln_gamma(k + 1.0) - ln_gamma(n - k + 1.0) }
}

/// y·ln(y/μ) with 0·ln 0 = 0, where ln μ is given.
fn y_ln_y_over_mu(y: f64, ln_mu: f64) -> f64 {
    if y == 0.0 { 0.0 } else { y * (y.ln() - ln_mu) }
}

fn deviance(observations: &[Observation], beta: &[f64]) -> f64 {
    observations
        .iter()
        .map(|o| {
            let eta = eta(o, beta);
            let ln_n = o.n.ln();
            let ln_mu_win = ln_n - softplus(-eta);
            let ln_mu_loss = ln_n - softplus(eta);
            2.0 * (y_ln_y_over_mu(o.wins, ln_mu_win) + y_ln_y_over_mu(o.n - o.wins, ln_mu_loss))
        })
        .sum::<f64>()
        .max(0.0)
}

/// Score vector and Fisher information at β (lower triangle only).
fn score_and_information(observations: &[Observation], beta: &[f64], p: usize) -> (Vec<f64>, Mat<f64>, f64) {
    let mut score = vec![0.0; p];
    let mut information = Mat::<f64>::zeros(p, p);
    let mut max_eta: f64 = 0.0;
    for o in observations {
        let eta = eta(o, beta);
        max_eta = max_eta.max(eta.abs());
        let pi = sigmoid(eta);
        let residual = o.wins - o.n * pi;
        let weight = o.n * pi * (1.0 - pi);
        for &(a, va) in &o.design {
            score[a] += va * residual;
            for &(b, vb) in &o.design {
                if b <= a {
                    information[(a, b)] += weight * va * vb;
                }
            }
        }
    }
    // Only the lower triangle is filled: every consumer (Cholesky with `Side::Lower`) reads
    // only that, and mirroring a large matrix costs more than the assembly itself.
    (score, information, max_eta)
}

fn solve(information: &Mat<f64>, rhs: &[f64]) -> Option<Vec<f64>> {
    let llt = information.llt(Side::Lower).ok()?;
    let b = Mat::from_fn(rhs.len(), 1, |i, _| rhs[i]);
    let x = llt.solve(&b);
    let out: Vec<f64> = (0..rhs.len()).map(|i| x[(i, 0)]).collect();
    out.iter().all(|v| v.is_finite()).then_some(out)
}

fn inverse(information: &Mat<f64>) -> Option<Mat<f64>> {
    let llt = information.llt(Side::Lower).ok()?;
    Some(llt.inverse())
}

fn log_det(information: &Mat<f64>) -> Option<f64> {
    let llt = information.llt(Side::Lower).ok()?;
    let l = llt.L();
    Some((0..information.nrows()).map(|i| 2.0 * l[(i, i)].ln()).sum())
}

fn finish(method: Method, observations: &[Observation], beta: Vec<f64>, iterations: usize) -> Result<Fit, FitFailure> {
    let p = beta.len();
    let (_, information, _) = score_and_information(observations, &beta, p);
    let covariance = if p == 0 { Mat::zeros(0, 0) } else { inverse(&information).ok_or(FitFailure::Singular)? };
    let constants: f64 = observations.iter().map(|o| ln_choose(o.n, o.wins)).sum();
    let kernel = kernel_log_likelihood(observations, &beta);
    Ok(Fit {
        method,
        log_likelihood: kernel + constants,
        kernel_log_likelihood: kernel,
        deviance: deviance(observations, &beta),
        n_observations: observations.len(),
        beta,
        covariance,
        iterations,
    })
}

/// The kernel log-likelihood of the observations as [`crate::newton`]'s objective.
struct Likelihood<'a> {
    observations: &'a [Observation],
    p: usize,
}

impl crate::newton::Concave for Likelihood<'_> {
    type Failure = FitFailure;

    fn value(&self, beta: &[f64]) -> f64 {
        kernel_log_likelihood(self.observations, beta)
    }

    fn step(&self, beta: &[f64]) -> Result<Vec<f64>, FitFailure> {
        let (score, information, max_eta) = score_and_information(self.observations, beta, self.p);
        if max_eta > SEPARATION_ETA {
            return Err(FitFailure::Separation);
        }
        solve(&information, &score).ok_or(FitFailure::Singular)
    }
}

/// Maximum-likelihood fit by Newton–Raphson with step halving ([`crate::newton::maximise`]),
/// from `start` (or zeros). Fails with [`FitFailure::Separation`] when the estimate runs off to
/// infinity.
pub fn fit_ml(
    pairs: &[PairTally],
    x: &ModelMatrix,
    start: Option<&[f64]>,
    options: FitOptions,
) -> Result<Fit, FitFailure> {
    use crate::newton::{Settings, Stop, maximise};
    let observations = observations(pairs, x);
    let p = x.n_params;
    let beta = start.map(<[f64]>::to_vec).unwrap_or_else(|| vec![0.0; p]);
    if p == 0 {
        return finish(Method::Ml, &observations, beta, 0);
    }
    let settings = Settings { tolerance: options.tolerance, max_iterations: options.max_iterations, min_scale: 1e-6 };
    match maximise(&Likelihood { observations: &observations, p }, beta, settings) {
        Ok(maximum) => finish(Method::Ml, &observations, maximum.beta, maximum.iterations),
        Err(Stop::Failed(failure)) => Err(failure),
        // A step is finite where the information could be solved.
        Err(Stop::NotFinite) => Err(FitFailure::Singular),
        Err(Stop::NotConverged { beta, iterations, last_change }) => {
            // A fit whose predictor keeps growing without converging is separated.
            let max_eta = observations.iter().map(|o| eta(o, &beta).abs()).fold(0.0, f64::max);
            if max_eta > SEPARATION_ETA / 2.0 {
                return Err(FitFailure::Separation);
            }
            Err(FitFailure::NotConverged { iterations, last_change })
        }
    }
}

/// Firth's scoring direction at β: the modified score U*(β) (the gradient of the penalised
/// log-likelihood l(β) + ½·log|I(β)| for the logit link) and the scoring step I(β)⁻¹·U*(β).
/// `None` where the information is singular.
fn firth_direction(observations: &[Observation], beta: &[f64], p: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let (_, information, _) = score_and_information(observations, beta, p);
    let covariance = inverse(&information)?;
    let mut modified_score = vec![0.0; p];
    for o in observations {
        let eta = eta(o, beta);
        let pi = sigmoid(eta);
        let weight = o.n * pi * (1.0 - pi);
        let mut quadratic = 0.0;
        for &(a, va) in &o.design {
            for &(b, vb) in &o.design {
                quadratic += va * vb * covariance[(a, b)];
            }
        }
        let leverage = weight * quadratic;
        let residual = o.wins - o.n * pi + leverage * (0.5 - pi);
        for &(a, va) in &o.design {
            modified_score[a] += va * residual;
        }
    }
    let step: Vec<f64> = (0..p).map(|a| (0..p).map(|b| covariance[(a, b)] * modified_score[b]).sum()).collect();
    step.iter().all(|s| s.is_finite()).then_some((modified_score, step))
}

/// Sufficient increase of a step (Armijo): the penalised log-likelihood must rise by at least
/// this fraction of what its slope at β promises, so a step across the maximum to a point no
/// higher (the scoring iteration's 2-cycle) is refused.
const FIRTH_SUFFICIENT_INCREASE: f64 = 1e-4;

/// Below this relative change of the penalised log-likelihood, the change is measured by the
/// trapezoid rule on its directional derivatives rather than as a difference of two values:
/// those are exact to about 1e-15 relative, so a smaller difference is mostly rounding.
const FIRTH_DIRECT_CHANGE: f64 = 1e-9;

/// The line search halves the step at most this often (a scale of 2⁻⁴⁰ ≈ 1e-12).
const FIRTH_HALVINGS: usize = 40;

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn largest_magnitude(values: &[f64]) -> f64 {
    values.iter().fold(0.0, |m, v| m.max(v.abs()))
}

/// Firth's bias-reduced fit (Jeffreys-prior penalised likelihood), as BradleyTerry2's
/// `br = TRUE`. Exists under separation.
///
/// Step control: each iteration goes along the scoring step d = I⁻¹·U* (an ascent direction
/// of the penalised log-likelihood ℓ*, as I is positive definite), halved until ℓ* rises by at
/// least 1e-4 of what its slope promises. A step that does not improve ℓ*
/// is never taken: near the maximum, where ℓ* is flat to rounding, the rise is measured by
/// the trapezoid rule on the directional derivative U*ᵀd at both ends (exact for a quadratic,
/// which ℓ* is there). Convergence is judged on the gradient, not on a shrunken step: the fit
/// has converged when the full scoring step, the modified score in the metric of I⁻¹, is below
/// the tolerance in every parameter. When no halving improves ℓ*, β is kept and the fit has
/// converged if that step is below √tolerance (the maximum to the precision the arithmetic
/// allows), else it fails with that step's size.
pub fn fit_firth(pairs: &[PairTally], x: &ModelMatrix, options: FitOptions) -> Result<Fit, FitFailure> {
    let observations = observations(pairs, x);
    let p = x.n_params;
    let mut beta = vec![0.0; p];
    if p == 0 {
        return finish(Method::Firth, &observations, beta, 0);
    }
    let penalised = |beta: &[f64]| -> Option<f64> {
        let (_, information, _) = score_and_information(&observations, beta, p);
        let value = kernel_log_likelihood(&observations, beta) + 0.5 * log_det(&information)?;
        value.is_finite().then_some(value)
    };
    let mut objective = penalised(&beta).ok_or(FitFailure::Singular)?;
    let (mut modified_score, mut step) = firth_direction(&observations, &beta, p).ok_or(FitFailure::Singular)?;
    for iteration in 0..options.max_iterations {
        let size = largest_magnitude(&step);
        if size < options.tolerance {
            return finish(Method::Firth, &observations, beta, iteration);
        }
        // U*ᵀd = U*ᵀI⁻¹U* > 0: the slope of ℓ* along d at β.
        let slope = dot(&modified_score, &step);
        let mut scale = 1.0;
        let mut accepted = None;
        for _ in 0..=FIRTH_HALVINGS {
            let candidate: Vec<f64> = beta.iter().zip(&step).map(|(b, s)| b + scale * s).collect();
            if let Some(value) = penalised(&candidate) {
                let required = FIRTH_SUFFICIENT_INCREASE * scale * slope;
                let change = value - objective;
                if change.abs() > FIRTH_DIRECT_CHANGE * objective.abs().max(1.0) {
                    if change >= required {
                        accepted = Some((candidate, value, None));
                        break;
                    }
                } else if let Some((next_score, next_step)) = firth_direction(&observations, &candidate, p) {
                    let trapezoid = 0.5 * scale * (slope + dot(&next_score, &step));
                    if trapezoid >= required {
                        accepted = Some((candidate, value, Some((next_score, next_step))));
                        break;
                    }
                }
            }
            scale *= 0.5;
        }
        let Some((candidate, value, direction)) = accepted else {
            // No step improves ℓ*: β is its maximum as far as the arithmetic can tell, if the
            // gradient says so too.
            if size < options.tolerance.sqrt() {
                return finish(Method::Firth, &observations, beta, iteration);
            }
            return Err(FitFailure::NotConverged { iterations: iteration, last_change: size });
        };
        beta = candidate;
        objective = value;
        (modified_score, step) = match direction {
            Some(direction) => direction,
            None => firth_direction(&observations, &beta, p).ok_or(FitFailure::Singular)?,
        };
    }
    if largest_magnitude(&step) < options.tolerance {
        return finish(Method::Firth, &observations, beta, options.max_iterations);
    }
    Err(FitFailure::NotConverged { iterations: options.max_iterations, last_change: largest_magnitude(&step) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tally(i: usize, j: usize, wins_i: u64, wins_j: u64) -> PairTally {
        PairTally { i, j, wins_i, wins_j }
    }

    /// Two conditions: the MLE is the empirical logit, with the analytic binomial variance.
    #[test]
    fn two_conditions_give_the_empirical_logit_analytically() {
        let pairs = [tally(0, 1, 30, 70)];
        let x = ModelMatrix::items(2, &[0, 1], 0);
        let fit = fit_ml(&pairs, &x, None, FitOptions::default()).unwrap();
        let expected = (70.0f64 / 30.0).ln();
        assert!((fit.beta[0] - expected).abs() < 1e-12);
        let expected_se = (1.0 / 70.0 + 1.0 / 30.0f64).sqrt();
        assert!((fit.se(0) - expected_se).abs() < 1e-12);
        assert!(fit.deviance.abs() < 1e-9, "saturated: deviance {}", fit.deviance);
    }

    #[test]
    fn separation_is_detected_not_reported_as_huge_estimate() {
        let pairs = [tally(0, 1, 10, 0), tally(1, 2, 5, 5), tally(0, 2, 7, 0)];
        let x = ModelMatrix::items(3, &[0, 1, 2], 1);
        assert_eq!(fit_ml(&pairs, &x, None, FitOptions::default()).unwrap_err(), FitFailure::Separation);
        let firth = fit_firth(&pairs, &x, FitOptions::default()).unwrap();
        assert!(firth.beta.iter().all(|b| b.is_finite() && b.abs() < 10.0), "{:?}", firth.beta);
        assert!(firth.beta[0] > 2.0, "condition 0 never lost: {:?}", firth.beta);
    }

    /// Two conditions with 0 losses: Firth's estimate adds ½ to each cell (Haldane), an
    /// analytic result for the one-parameter logistic model.
    #[test]
    fn firth_on_two_conditions_is_the_haldane_logit() {
        let pairs = [tally(0, 1, 0, 12)];
        let x = ModelMatrix::items(2, &[0, 1], 0);
        let fit = fit_firth(&pairs, &x, FitOptions::default()).unwrap();
        assert!((fit.beta[0] - (12.5f64 / 0.5).ln()).abs() < 1e-9, "{}", fit.beta[0]);
    }

    /// One judgment, won: the penalised log-likelihood 1.5·ln π + 0.5·ln(1 − π) has its
    /// maximum at π = ¾ (Haldane: (1 + ½)/(0 + ½) = 3), where its curvature is twice the
    /// information, so the plain scoring step overshoots by exactly a factor 2 and the
    /// iteration circles the maximum. The old step control took every step that did not lower
    /// the objective by more than 1e-12 relative and stopped with "did not converge in 200
    /// iterations".
    #[test]
    fn firth_with_one_judgment_converges_to_the_haldane_logit() {
        let pairs = [tally(0, 1, 0, 1)];
        let x = ModelMatrix::items(2, &[0, 1], 0);
        let fit = fit_firth(&pairs, &x, FitOptions::default()).unwrap();
        assert!((fit.beta[0] - 3f64.ln()).abs() < 1e-9, "{}", fit.beta[0]);
    }

    /// Stimuli judged once or twice, each only winning or only losing against a well-judged
    /// pair (the early data of a stimulus model): every stimulus of one judgment is a direction
    /// in which the scoring step overshoots twofold. Converges, and to the maximum of the
    /// penalised log-likelihood: its modified score vanishes there.
    #[test]
    fn firth_converges_with_one_sided_stimuli_of_one_judgment() {
        let pairs = [
            tally(0, 1, 6, 4),
            tally(0, 2, 1, 0),
            tally(1, 3, 0, 1),
            tally(2, 4, 1, 0),
            tally(3, 5, 0, 2),
            tally(1, 5, 1, 0),
            tally(0, 6, 0, 1),
        ];
        let x = ModelMatrix::items(7, &[0, 1, 2, 3, 4, 5, 6], 0);
        let fit = fit_firth(&pairs, &x, FitOptions::default()).unwrap();
        let observations = observations(&pairs, &x);
        let (modified_score, _) = firth_direction(&observations, &fit.beta, x.n_params).unwrap();
        assert!(largest_magnitude(&modified_score) < 1e-9, "U* = {modified_score:?}");
        assert!(fit.iterations < 100, "{} iterations", fit.iterations);
    }

    #[test]
    fn huge_counts_keep_precision() {
        let pairs = [tally(0, 1, 1_000_000_000, 500_000_000)];
        let x = ModelMatrix::items(2, &[0, 1], 0);
        let fit = fit_ml(&pairs, &x, None, FitOptions::default()).unwrap();
        assert!((fit.beta[0] - 0.5f64.ln()).abs() < 1e-12);
        assert!(fit.log_likelihood.is_finite() && fit.deviance.is_finite());
    }
}
