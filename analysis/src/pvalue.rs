//! p-values that never underflow to 0: every p is carried with its base-10 logarithm, computed
//! in log space in the far tails, so that a p below 1e-300 is still reported as a bound with its
//! true order of magnitude.
//!
//! A p-value known only to lie below some number is a *bound*, printed `p < 1e-300` and
//! serialised with that number as `p_bound`: a closed-form p below [`P_FLOOR`]
//! ([`PValue::from_ln`]), and a Monte-Carlo p-value where no simulated statistic reached the
//! observed one ([`PValue::monte_carlo`]: `p < 1/B` after `B` simulations).

use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};
use statrs::function::gamma::ln_gamma;

/// The smallest p printed as a number; anything below is printed as a bound `< 1e-300`.
pub const P_FLOOR: f64 = 1e-300;

/// A p-value with its base-10 logarithm. `p` is clamped to [`P_FLOOR`, 1]; `log10_p` is exact
/// (to the precision of the tail expansion) even where `p` itself would underflow.
/// Serialised as `{"p": …, "log10_p": …}`, with `"p_bound": …` added where the p-value is a bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PValue {
    pub p: f64,
    pub log10_p: f64,
    /// Where the p-value is known only to lie below a number, that number: [`P_FLOOR`] for a
    /// closed-form p below it (`p` is then the floor and `log10_p` the true order of
    /// magnitude), `1/B` for a Monte-Carlo p-value after `B` simulations of which none reached
    /// the observed statistic (`p`, `log10_p` are then the usual `1/(B+1)`).
    #[serde(rename = "p_bound", skip_serializing_if = "Option::is_none")]
    pub bound: Option<f64>,
}

impl PValue {
    /// A p-value in [0, 1] that is a plain number (a bound only below [`P_FLOOR`]).
    pub fn new(p: f64) -> PValue {
        if p >= P_FLOOR {
            PValue { p: p.min(1.0), log10_p: p.min(1.0).log10(), bound: None }
        } else {
            PValue::from_ln(p.ln())
        }
    }

    /// From the natural logarithm of a p-value.
    pub fn from_ln(ln_p: f64) -> PValue {
        let ln_p = ln_p.min(0.0);
        let p = ln_p.exp().max(P_FLOOR);
        let log10_p = ln_p / std::f64::consts::LN_10;
        PValue { p, log10_p, bound: (log10_p < P_FLOOR.log10()).then_some(P_FLOOR) }
    }

    /// The Monte-Carlo p-value `(1 + at_least) / (1 + simulations)` of a statistic that
    /// `at_least` of `simulations` simulated statistics reached; where none did, a bound
    /// `p < 1/simulations` (the simulation cannot tell smaller p-values apart).
    pub fn monte_carlo(at_least: usize, simulations: usize) -> PValue {
        let p = (1.0 + at_least as f64) / (1.0 + simulations as f64);
        let bound = (at_least == 0 && simulations > 0).then(|| 1.0 / simulations as f64);
        PValue { p, log10_p: p.log10(), bound }
    }

    /// Whether the p-value is printed as a bound (`< 1e-300`, `< 1e-4`).
    pub fn is_bound(&self) -> bool {
        self.bound.is_some()
    }

    /// Two-sided p-value of a standard-normal statistic: P(|Z| ≥ |z|).
    pub fn normal_two_sided(z: f64) -> PValue {
        PValue::from_ln(std::f64::consts::LN_2 + ln_normal_upper(z.abs()))
    }

    /// Upper-tail p-value of a χ² statistic with `df` degrees of freedom: P(X ≥ x).
    pub fn chi2_upper(x: f64, df: f64) -> PValue {
        PValue::from_ln(ln_chi2_upper(x, df))
    }

    /// Text for tables: the value with four significant digits, or a bound, `< 1e-300`, `< 1e-4`.
    pub fn display(&self) -> String {
        if let Some(bound) = self.bound {
            format!("< {}", format_bound(bound))
        } else if self.p >= 1e-4 {
            format!("{:.4}", self.p)
        } else {
            format!("{:.3e}", self.p)
        }
    }
}

impl PValue {
    /// `p = 0.0123`, or `p < 1e-4` for a bound.
    pub fn equation(&self) -> String {
        if self.is_bound() { format!("p {}", self.display()) } else { format!("p = {}", self.display()) }
    }
}

/// A bound with one significant digit, rounded up (`1e-4`, `5e-3`, `1e-300`).
fn format_bound(bound: f64) -> String {
    let exponent = bound.log10().floor();
    let mantissa = (bound / 10f64.powf(exponent) - 1e-9).ceil();
    if mantissa >= 10.0 { format!("1e{}", exponent + 1.0) } else { format!("{mantissa}e{exponent}") }
}

/// ln P(Z ≥ z) for a standard normal Z, accurate far into the upper tail.
pub fn ln_normal_upper(z: f64) -> f64 {
    if z < 30.0 {
        let normal = Normal::standard();
        let upper = if z > 0.0 { normal.sf(z) } else { 1.0 - normal.cdf(z) };
        return upper.ln();
    }
    // Mills-ratio asymptotic series: Q(z) = φ(z)/z · (1 − 1/z² + 3/z⁴ − 15/z⁶ + …).
    let z2 = z * z;
    let series = 1.0 - 1.0 / z2 + 3.0 / (z2 * z2) - 15.0 / (z2 * z2 * z2) + 105.0 / (z2 * z2 * z2 * z2);
    -0.5 * z2 - z.ln() - 0.5 * (2.0 * std::f64::consts::PI).ln() + series.ln()
}

/// ln P(X ≥ x) for X ~ χ²(df), accurate far into the upper tail.
pub fn ln_chi2_upper(x: f64, df: f64) -> f64 {
    if !(x > 0.0) {
        return 0.0;
    }
    let a = 0.5 * df;
    let t = 0.5 * x;
    if t < a + 1.0 || t < 200.0 {
        let dist = ChiSquared::new(df).expect("df > 0");
        let upper = dist.sf(x);
        if upper > 1e-280 {
            return upper.ln();
        }
    }
    // Regularised upper incomplete gamma Q(a, t) by Lentz's continued fraction, in log space:
    // ln Q = −t + a·ln t − ln Γ(a) + ln CF.
    let tiny = 1e-300;
    let mut b = t + 1.0 - a;
    let mut c = 1.0 / tiny;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..10_000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < tiny {
            d = tiny;
        }
        c = b + an / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-15 {
            break;
        }
    }
    -t + a * t.ln() - ln_gamma(a) + h.ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    // Reference values from mpmath 1.3 at 50 digits: analysis/tests/reference/pvalue_tails.py.
    const TAIL_TOLERANCE: f64 = 1e-9;

    #[test]
    fn normal_tail_matches_mpmath() {
        assert!((ln_normal_upper(40.0) - -804.60844201375379).abs() < TAIL_TOLERANCE);
        assert!((ln_normal_upper(3.0) - -6.6077262215103495).abs() < TAIL_TOLERANCE);
    }

    #[test]
    fn chi2_tail_matches_mpmath() {
        assert!((ln_chi2_upper(10.0, 4.0) - -3.208240530771945).abs() < TAIL_TOLERANCE);
        assert!((ln_chi2_upper(2000.0, 3.0) - -996.42484049733325).abs() < TAIL_TOLERANCE * 1000.0);
        assert!((ln_chi2_upper(900.0, 13.0) - -422.04943053731495).abs() < TAIL_TOLERANCE * 1000.0);
    }

    #[test]
    fn tiny_p_is_a_bound_not_zero() {
        let p = PValue::normal_two_sided(40.0);
        assert_eq!(p.p, P_FLOOR);
        assert!(p.is_bound());
        assert_eq!(p.display(), "< 1e-300");
        assert!(p.log10_p < -349.0);
        let json = serde_json::to_value(p).unwrap();
        assert_eq!(json["p_bound"], 1e-300);
        assert!(serde_json::to_value(PValue::normal_two_sided(1.0)).unwrap().get("p_bound").is_none());
    }

    #[test]
    fn monte_carlo_p_without_an_exceedance_is_a_bound() {
        let p = PValue::monte_carlo(0, 10_000);
        assert_eq!(p.display(), "< 1e-4");
        assert_eq!(p.p, 1.0 / 10_001.0);
        let json = serde_json::to_value(p).unwrap();
        assert_eq!(json["p_bound"], 1e-4);
        assert_eq!(PValue::monte_carlo(0, 200).display(), "< 5e-3");
        assert_eq!(p.equation(), "p < 1e-4");
        assert_eq!(PValue::new(0.25).equation(), "p = 0.2500");
        assert_eq!(PValue::monte_carlo(0, 300).display(), "< 4e-3");
        let plain = PValue::monte_carlo(3, 999);
        assert_eq!((plain.p, plain.bound, plain.display()), (0.004, None, "0.0040".to_string()));
    }
}
