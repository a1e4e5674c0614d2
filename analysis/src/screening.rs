//! The null distribution of one participant's log-likelihood under the consensus, for observer
//! screening: how likely a participant's choices are if they judged as everybody else does.
//!
//! A participant judged pair `k` (conditions `i`, `j`) `nₖ` times and chose `i` `yₖ` times; the
//! consensus (the item model fitted without them) gives `πₖ = σ(ηₖ)`, `ηₖ = λᵢ − λⱼ`. Their
//! log-likelihood `T = Σ yₖ·ln πₖ + (nₖ − yₖ)·ln(1 − πₖ) = Σ nₖ·ln(1 − πₖ) + S`, `S = Σ yₖ·ηₖ`,
//! and under the null `yₖ ~ Binomial(nₖ, πₖ)` independently. The p-value is the lower tail
//! `P(S ≤ s_obs)`:
//! - exactly, by enumerating every outcome, where there are at most [`EXACT_OUTCOMES`];
//! - otherwise by the saddlepoint approximation of Barndorff-Nielsen's `r*` (Lugannani–Rice to
//!   the same order) on the cumulant generating function
//!   `K(θ) = Σ nₖ·[softplus((1+θ)ηₖ) − softplus(ηₖ)]`, whose relative error stays small far
//!   into the tail, where the normal approximation of `S` (which this replaces) was too
//!   liberal: a log-likelihood has a long lower tail, and the normal tail flagged 1.6× α of
//!   participants simulated from the consensus itself.
//!
//! Where the observed value is the least likely outcome (every choice against the consensus),
//! the p-value is that outcome's probability.

use crate::fit::softplus;
use crate::pvalue::{PValue, ln_normal_upper};

/// Up to this many outcomes (`Π (nₖ + 1)`) the null distribution is enumerated exactly.
pub const EXACT_OUTCOMES: usize = 4096;

/// One pair a participant judged: consensus logit `eta` of the first condition over the second,
/// `n` judgments, `wins` of the first condition.
#[derive(Debug, Clone, Copy)]
pub struct PairTerm {
    pub eta: f64,
    pub n: u64,
    pub wins: u64,
}

/// A participant's log-likelihood under the consensus and its null distribution.
#[derive(Debug, Clone, Copy)]
pub struct LogLikelihoodTest {
    pub observed: f64,
    pub mean: f64,
    pub variance: f64,
    /// `P(T ≤ observed)` under the consensus.
    pub p: PValue,
}

/// `1 / (1 + exp(−x))` as `1 / (1 + e)` for `x ≥ 0` and `e / (1 + e)` below, `e = exp(−|x|)`:
/// the two branches' arithmetic, chosen by a select rather than a jump (the sign of `x` is
/// data, and a mispredicted branch costs more than the division).
#[inline]
fn sigmoid(x: f64) -> f64 {
    let e = (-x.abs()).exp();
    let numerator = if x >= 0.0 { 1.0 } else { e };
    numerator / (1.0 + e)
}

/// `Σ nₖ·ln(1 + tₖ)` for `tₖ ∈ [0, 1]`, as the logarithm of the product of the `(1 + tₖ)^nₖ`
/// (one logarithm for a participant's pairs instead of one per pair: the product is folded
/// into the sum before it could overflow, and a pair judged more than 64 times adds its own
/// term). Each factor lies in `[1, 2]`, so the product rounds no worse than the sum would.
#[derive(Clone, Copy)]
struct LnProduct {
    sum: f64,
    product: f64,
}

impl LnProduct {
    const EMPTY: LnProduct = LnProduct { sum: 0.0, product: 1.0 };

    #[inline]
    fn add(&mut self, n: u64, t: f64) {
        if n > 64 {
            self.sum += n as f64 * t.ln_1p();
            return;
        }
        let factor = 1.0 + t;
        // Most pairs are judged once or twice: those without a call.
        self.product *= match n {
            0 => 1.0,
            1 => factor,
            2 => factor * factor,
            _ => factor.powi(n as i32),
        };
        if self.product > 1e280 {
            self.sum += self.product.ln();
            self.product = 1.0;
        }
    }

    fn ln(self) -> f64 {
        self.sum + self.product.ln()
    }
}

/// The participant's log-likelihood, its null mean and variance, and the lower-tail p-value.
///
/// With `e = exp(−|η|)`, `ln(1 − π) = −softplus(η) = −max(η, 0) − ln(1 + e)` and
/// `ln π = ln(1 − π) + η`, so the log-likelihood is `S − Σ nₖ·softplus(ηₖ)`, its mean
/// `E[S] − Σ nₖ·softplus(ηₖ)`, and the least likely outcome's `−Σ nₖ·softplus(|ηₖ|)`: one
/// exponential per pair and one logarithm in all (a product of the `(1 + eₖ)^nₖ`).
pub fn log_likelihood_test(terms: &[PairTerm]) -> LogLikelihoodTest {
    let (mut variance, mut third) = (0.0, 0.0);
    let (mut s_observed, mut s_mean, mut s_min) = (0.0, 0.0, 0.0);
    // Σ nₖ·max(ηₖ, 0), Σ nₖ·|ηₖ|, Σ nₖ·ln(1 + eₖ), and the judgments of pairs with η = 0.
    let (mut positive_part, mut absolute) = (0.0, 0.0);
    let mut ln_1_plus_e = LnProduct::EMPTY;
    let mut n_uninformative = 0.0;
    let mut outcomes: usize = 1;
    for term in terms {
        let (n, y) = (term.n as f64, term.wins as f64);
        let e = (-term.eta.abs()).exp();
        ln_1_plus_e.add(term.n, e);
        // Selects, not branches (see `sigmoid`).
        let pi = if term.eta >= 0.0 { 1.0 } else { e } / (1.0 + e);
        positive_part += n * term.eta.max(0.0);
        absolute += n * term.eta.abs();
        if term.eta == 0.0 {
            n_uninformative += n;
        }
        variance += n * pi * (1.0 - pi) * term.eta * term.eta;
        third += n * pi * (1.0 - pi) * (1.0 - 2.0 * pi) * term.eta * term.eta * term.eta;
        s_observed += y * term.eta;
        s_mean += n * pi * term.eta;
        s_min += n * term.eta.min(0.0);
        outcomes = outcomes.saturating_mul(term.n as usize + 1);
    }
    let ln_1_plus_e = ln_1_plus_e.ln();
    // Σ nₖ·softplus(ηₖ), the constant of K(θ).
    let k_offset = positive_part + ln_1_plus_e;
    let observed = s_observed - k_offset;
    let mean = s_mean - k_offset;
    // Pairs with η = 0 have one outcome probability (½ each way) and are left out.
    let ln_min_atom = -(absolute + ln_1_plus_e - n_uninformative * std::f64::consts::LN_2);
    let tie = 1e-9 * (1.0 + absolute);
    let p = if variance <= 0.0 {
        PValue::new(1.0)
    } else if s_observed <= s_min + tie {
        PValue::from_ln(ln_min_atom)
    } else if outcomes <= EXACT_OUTCOMES {
        PValue::new(exact_lower_tail(terms, s_observed + tie))
    } else {
        saddlepoint_lower_tail(terms, s_observed, s_mean, variance, third, k_offset)
    };
    LogLikelihoodTest { observed, mean, variance, p }
}

/// `P(S ≤ s)` by enumerating every outcome.
fn exact_lower_tail(terms: &[PairTerm], s: f64) -> f64 {
    let mut atoms: Vec<(f64, f64)> = vec![(0.0, 1.0)];
    let mut next = Vec::new();
    for term in terms {
        let pi = sigmoid(term.eta);
        let n = term.n;
        // Binomial(n, π) probabilities by the recurrence from P(0) = (1 − π)ⁿ.
        let mut pmf = Vec::with_capacity(n as usize + 1);
        let mut probability = (1.0 - pi).powi(n as i32);
        if probability == 0.0 || pi == 0.0 {
            // |η| is huge: compute each term directly.
            for y in 0..=n {
                let ln = ln_choose(n, y) - y as f64 * softplus(-term.eta) - (n - y) as f64 * softplus(term.eta);
                pmf.push(ln.exp());
            }
        } else {
            for y in 0..=n {
                pmf.push(probability);
                probability *= (n - y) as f64 / (y + 1) as f64 * pi / (1.0 - pi);
            }
        }
        next.clear();
        for &(value, probability) in &atoms {
            for (y, &q) in pmf.iter().enumerate() {
                next.push((value + y as f64 * term.eta, probability * q));
            }
        }
        std::mem::swap(&mut atoms, &mut next);
    }
    atoms.iter().filter(|&&(value, _)| value <= s).map(|&(_, probability)| probability).sum::<f64>().min(1.0)
}

fn ln_choose(n: u64, k: u64) -> f64 {
    use statrs::function::gamma::ln_gamma;
    ln_gamma(n as f64 + 1.0) - ln_gamma(k as f64 + 1.0) - ln_gamma((n - k) as f64 + 1.0)
}

/// `K'(θ)`, `K''(θ)` and `K'''(θ)` of `S` (one exponential per pair), keeping each pair's
/// `exp(−|(1+θ)ηₖ|)` in `tails` for [`cumulant_at`].
fn cumulant_derivatives(terms: &[PairTerm], theta: f64, tails: &mut Vec<f64>) -> [f64; 3] {
    let (mut first, mut second, mut third) = (0.0, 0.0, 0.0);
    tails.clear();
    for term in terms {
        let x = (1.0 + theta) * term.eta;
        let e = (-x.abs()).exp();
        tails.push(e);
        let sigma = if x >= 0.0 { 1.0 } else { e } / (1.0 + e);
        let n_eta = term.n as f64 * term.eta;
        let spread = n_eta * term.eta * sigma * (1.0 - sigma);
        first += n_eta * sigma;
        second += spread;
        third += spread * term.eta * (1.0 - 2.0 * sigma);
    }
    [first, second, third]
}

/// `K(θ)` of `S`, given `k_offset = Σ nₖ·softplus(ηₖ)` and the `tails` that
/// [`cumulant_derivatives`] left at the same `θ`: `softplus(x) = max(x, 0) + ln(1 + e^(−|x|))`,
/// one logarithm in all ([`LnProduct`]).
fn cumulant_at(terms: &[PairTerm], theta: f64, tails: &[f64], k_offset: f64) -> f64 {
    let mut ln_1_plus_e = LnProduct::EMPTY;
    let mut positive_part = 0.0;
    for (t, &e) in terms.iter().zip(tails) {
        ln_1_plus_e.add(t.n, e);
        positive_part += t.n as f64 * ((1.0 + theta) * t.eta).max(0.0);
    }
    positive_part + ln_1_plus_e.ln() - k_offset
}

/// `P(S ≤ s)` by the saddlepoint approximation `Φ(r*)`, `r* = w + ln(u/w)/w`, with
/// `w = sign(θ̂)·√(2(θ̂s − K(θ̂)))`, `u = θ̂·√K''(θ̂)` and `K'(θ̂) = s`. Near the mean, where `r*`
/// is 0/0, the normal approximation with the same mean and variance.
///
/// `θ̂` is found by Halley's method from the root of `K'`'s expansion to second order (`third`
/// is `K'''(0)`), close enough that one step usually finishes. It stops at the first `θ` whose
/// residual `r = K'(θ) − s` puts it within `δ ≈ r/K''` = [`THETA_TOLERANCE`]`·|θ|` of `θ̂`: `u`
/// is then within that relative error and `w²` within `K''·δ²` (its derivative in `θ` is zero
/// at `θ̂`), far below what the p-value shows. `K` is evaluated at that `θ`, with the
/// exponentials of the pass that tested it.
/// The relative error in `θ̂` at which [`saddlepoint_lower_tail`]'s iteration stops.
const THETA_TOLERANCE: f64 = 1e-9;

fn saddlepoint_lower_tail(terms: &[PairTerm], s: f64, mean: f64, variance: f64, third: f64, k_offset: f64) -> PValue {
    let z = (s - mean) / variance.sqrt();
    if z.abs() < 1e-3 {
        return PValue::from_ln(ln_normal_upper(-z));
    }
    // K'(θ) ≈ mean + variance·θ + third·θ²/2 = s, by the root nearer 0 (written without
    // cancellation); the linear root where the quadratic has none.
    let d = s - mean;
    let discriminant = variance * variance + 2.0 * third * d;
    let mut theta = if discriminant > 0.0 { 2.0 * d / (variance + discriminant.sqrt()) } else { d / variance };
    // Steps kept inside the bracket that the values of K' seen so far give (it increases;
    // K'(0) is the mean).
    let (mut low, mut high) = if s < mean { (f64::NEG_INFINITY, 0.0) } else { (0.0, f64::INFINITY) };
    let mut second = variance;
    let mut tails = Vec::with_capacity(terms.len());
    for _ in 0..200 {
        let [first, curvature, skew] = cumulant_derivatives(terms, theta, &mut tails);
        second = curvature;
        let residual = first - s;
        if residual.abs() <= THETA_TOLERANCE * theta.abs() * curvature {
            break;
        }
        if residual > 0.0 {
            high = theta;
        } else {
            low = theta;
        }
        // Halley's step (Newton's where its denominator is not safely positive).
        let halley = 2.0 * curvature * curvature - residual * skew;
        let mut next = if halley > curvature * curvature {
            theta - 2.0 * residual * curvature / halley
        } else {
            theta - residual / curvature.max(1e-300)
        };
        if !(next > low && next < high) {
            next = match (low.is_finite(), high.is_finite()) {
                (true, true) => 0.5 * (low + high),
                (false, _) => 2.0 * high.min(-1.0),
                (_, false) => 2.0 * low.max(1.0),
            };
        }
        if next == theta {
            break;
        }
        theta = next;
    }
    let w2 = 2.0 * (theta * s - cumulant_at(terms, theta, &tails, k_offset));
    let w = theta.signum() * w2.max(0.0).sqrt();
    let u = theta * second.sqrt();
    if w.abs() < 1e-6 || u / w <= 0.0 {
        return PValue::from_ln(ln_normal_upper(-z));
    }
    let r_star = w + (u / w).ln() / w;
    PValue::from_ln(ln_normal_upper(-r_star))
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    /// The saddlepoint tail against the exact one on designs small enough to enumerate (and
    /// large enough that the saddlepoint is what they would get with a few more pairs).
    #[test]
    fn saddlepoint_tail_is_close_to_the_exact_tail() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..40 {
            let terms: Vec<PairTerm> = (0..11)
                .map(|_| {
                    let eta = 2.0 * rng.random::<f64>() - 1.0;
                    PairTerm { eta, n: 1 + rng.random_range(0..2u64), wins: 0 }
                })
                .collect();
            let mean: f64 = terms.iter().map(|t| t.n as f64 * t.eta * sigmoid(t.eta)).sum();
            let variance: f64 =
                terms.iter().map(|t| t.n as f64 * t.eta * t.eta * sigmoid(t.eta) * (1.0 - sigmoid(t.eta))).sum();
            for z in [-3.0, -2.5, -2.0] {
                let s = mean + z * variance.sqrt();
                let exact = exact_lower_tail(&terms, s);
                let k_offset: f64 = terms.iter().map(|t| t.n as f64 * softplus(t.eta)).sum();
                let third: f64 = terms
                    .iter()
                    .map(|t| {
                        let pi = sigmoid(t.eta);
                        t.n as f64 * t.eta.powi(3) * pi * (1.0 - pi) * (1.0 - 2.0 * pi)
                    })
                    .sum();
                let saddle = saddlepoint_lower_tail(&terms, s, mean, variance, third, k_offset).p;
                // The exact distribution is a step function; the saddlepoint lies within its
                // steps, so compare with the mid-point of the step at s.
                let below = exact_lower_tail(&terms, s - 1e-9);
                assert!(saddle < 2.0 * exact + 1e-4 && saddle > 0.4 * below - 1e-4, "{saddle} vs [{below}, {exact}]");
            }
        }
    }

    #[test]
    fn the_least_likely_outcome_has_its_own_probability() {
        let terms = [PairTerm { eta: 1.0, n: 3, wins: 0 }, PairTerm { eta: -2.0, n: 2, wins: 2 }];
        let test = log_likelihood_test(&terms);
        let expected = 3.0 * (1.0 - sigmoid(1.0)).ln() + 2.0 * sigmoid(-2.0).ln();
        assert!((test.p.p.ln() - expected).abs() < 1e-12 && (test.observed - expected).abs() < 1e-12);
    }

    /// The log-likelihood, its mean and the least likely outcome from one logarithm in all,
    /// against the sum of each pair's logarithms; with pairs judged once and 200 times, logits
    /// up to ±40 and zero, and enough judgments that the product is folded many times.
    #[test]
    fn the_one_logarithm_sums_equal_the_sums_over_pairs() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for case in 0..50 {
            let size = if case < 40 { 1 + case } else { 3000 };
            let terms: Vec<PairTerm> = (0..size)
                .map(|k| {
                    let eta = if k % 7 == 3 { 0.0 } else { 80.0 * rng.random::<f64>() - 40.0 };
                    let n = if k % 5 == 0 { 200 } else { 1 + rng.random_range(0..4u64) };
                    PairTerm { eta, n, wins: rng.random_range(0..=n) }
                })
                .collect();
            let test = log_likelihood_test(&terms);
            let (mut observed, mut mean, mut least) = (0.0, 0.0, 0.0);
            for t in &terms {
                let (n, y) = (t.n as f64, t.wins as f64);
                let (ln_pi, ln_1_pi) = (-softplus(-t.eta), -softplus(t.eta));
                observed += y * ln_pi + (n - y) * ln_1_pi;
                mean += n * (sigmoid(t.eta) * ln_pi + (1.0 - sigmoid(t.eta)) * ln_1_pi);
                if t.eta != 0.0 {
                    least += n * ln_pi.min(ln_1_pi);
                }
            }
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-11 * (1.0 + b.abs());
            assert!(close(test.observed, observed), "case {case}: {} vs {observed}", test.observed);
            assert!(close(test.mean, mean), "case {case}: {} vs {mean}", test.mean);
            let mut product = LnProduct::EMPTY;
            let mut direct = 0.0;
            for t in &terms {
                let e = (-t.eta.abs()).exp();
                product.add(t.n, e);
                direct += t.n as f64 * e.ln_1p();
            }
            assert!(close(product.ln(), direct), "case {case}: {} vs {direct}", product.ln());
            let absolute: f64 = terms.iter().map(|t| t.n as f64 * t.eta.abs()).sum();
            let n_zero: f64 = terms.iter().filter(|t| t.eta == 0.0).map(|t| t.n as f64).sum();
            let ln_min_atom = -(absolute + direct - n_zero * std::f64::consts::LN_2);
            assert!(close(ln_min_atom, least), "case {case}: {ln_min_atom} vs {least}");
        }
    }

    #[test]
    fn no_information_gives_p_one() {
        let test = log_likelihood_test(&[PairTerm { eta: 0.0, n: 5, wins: 2 }]);
        assert_eq!(test.p.p, 1.0);
    }
}
