//! The post hoc tests: the paired Wilcoxon signed-rank test (as R's `wilcox.test(x, y, paired =
//! TRUE)`, exact or normal approximation) and Holm's step-down adjustment (as R's `p.adjust`).

use super::descriptives::compare;
use super::friedman::average_ranks;
use super::{WILCOXON_EXACT_BELOW, WilcoxonMethod, WilcoxonTest};
use crate::pvalue::PValue;

/// The paired Wilcoxon signed-rank test of x against y, as R's `wilcox.test(x, y, paired =
/// TRUE)` with its defaults (two-sided, `exact = NULL`, `correct = TRUE`): zero differences are
/// dropped; with fewer than [`WILCOXON_EXACT_BELOW`] non-zero differences, no ties among their
/// magnitudes and no zeros, p comes from the exact distribution of V; otherwise from the normal
/// approximation with tie-corrected variance and continuity correction. `None` when x and y are
/// empty or differ in length. When every difference is zero, V = 0 and there is no p.
///
/// `min_p` is the smallest two-sided p that any signs of these n non-zero differences could give
/// under the exact (sign-flip) null distribution: all of one sign, probability 2⁻ⁿ, so 2/2ⁿ
/// whatever the ties. R's normal approximation can go below it with ties (five equal differences
/// give p = 0.037 against 2/2⁵ = 0.0625), an artefact of the approximation at tiny n. The post
/// hoc table reports a test whose `min_p` exceeds α as not estimable.
pub fn wilcoxon_signed_rank_paired(x: &[f64], y: &[f64]) -> Option<WilcoxonTest> {
    if x.is_empty() || x.len() != y.len() {
        return None;
    }
    let all_differences: Vec<f64> = x.iter().zip(y).map(|(a, b)| a - b).collect();
    let differences: Vec<f64> = all_differences.iter().copied().filter(|&d| d != 0.0).collect();
    let zeros = differences.len() < all_differences.len();
    let n = differences.len();
    if n == 0 {
        return Some(WilcoxonTest { n_nonzero: 0, v: 0.0, method: None, z: None, p: None, min_p: None });
    }
    let magnitudes: Vec<f64> = differences.iter().map(|d| d.abs()).collect();
    let (ranks, tie_sizes) = average_ranks(&magnitudes);
    let v: f64 = ranks.iter().zip(&differences).filter(|(_, d)| **d > 0.0).map(|(rank, _)| rank).sum();
    let ties = tie_sizes.len() < n;
    let nf = n as f64;
    let min_p = PValue::from_ln(((1.0 - nf) * std::f64::consts::LN_2).min(0.0));

    if n < WILCOXON_EXACT_BELOW && !ties && !zeros {
        let p = signed_rank_two_sided_exact(v.round() as usize, n);
        return Some(WilcoxonTest {
            n_nonzero: n,
            v,
            method: Some(WilcoxonMethod::Exact),
            z: None,
            p: Some(p),
            min_p: Some(min_p),
        });
    }
    let tie_term: f64 = tie_sizes.iter().map(|&t| (t as f64).powi(3) - t as f64).sum();
    let sigma = (nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - tie_term / 48.0).sqrt();
    let centred = v - nf * (nf + 1.0) / 4.0;
    let correction = if centred > 0.0 {
        0.5
    } else if centred < 0.0 {
        -0.5
    } else {
        0.0
    };
    let z = (centred - correction) / sigma;
    Some(WilcoxonTest {
        n_nonzero: n,
        v,
        method: Some(WilcoxonMethod::Normal),
        z: Some(z),
        p: Some(PValue::normal_two_sided(z)),
        min_p: Some(min_p),
    })
}

/// Two-sided exact p of the signed-rank statistic V with n untied, non-zero differences, as R:
/// 2·P(S ≥ V) when V > n(n+1)/4, else 2·P(S ≤ V), at most 1. The null distribution is counted
/// exactly (subsets of {1..n} by rank sum; n < 64 keeps every count in a u64).
fn signed_rank_two_sided_exact(v: usize, n: usize) -> PValue {
    let max_sum = n * (n + 1) / 2;
    let mut counts = vec![0_u64; max_sum + 1];
    counts[0] = 1;
    for rank in 1..=n {
        for sum in (rank..=rank * (rank + 1) / 2).rev() {
            counts[sum] += counts[sum - rank];
        }
    }
    let v = v.min(max_sum);
    let tail: u64 = if 4 * v > n * (n + 1) { counts[v..].iter().sum() } else { counts[..=v].iter().sum() };
    // Exact in binary: the count is below 2⁶³ and the division is by a power of two. The smallest
    // possible p, 2/2⁴⁹, is far above `P_FLOOR`, so the value is stored as is.
    let p = (2.0 * tail as f64 / 2.0_f64.powi(n as i32)).min(1.0);
    PValue::new(p)
}

/// Holm's step-down adjustment, as R's `p.adjust(p, method = "holm")`: with the m p-values in
/// ascending order, p̃₍ᵢ₎ = min(1, maxⱼ≤ᵢ (m − j + 1)·p₍ⱼ₎), returned in input order. The products
/// are formed as R forms them; p below `P_FLOOR` are scaled through their logarithms so that they
/// stay exact.
pub fn holm_adjust(p_values: &[PValue]) -> Vec<PValue> {
    let m = p_values.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| compare(&p_values[i].log10_p, &p_values[j].log10_p));
    let mut adjusted = vec![PValue::new(1.0); m];
    // The running maximum of (m − j + 1)·p₍ⱼ₎, compared in log space: (ln of it, p₍ⱼ₎, factor).
    let mut running_max: Option<(f64, PValue, f64)> = None;
    for (position, &idx) in order.iter().enumerate() {
        let factor = (m - position) as f64;
        let ln_product = p_values[idx].log10_p * std::f64::consts::LN_10 + factor.ln();
        if running_max.is_none_or(|(ln_max, _, _)| ln_product > ln_max) {
            running_max = Some((ln_product, p_values[idx], factor));
        }
        if let Some((_, p, factor)) = running_max {
            adjusted[idx] = scale_p(p, factor);
        }
    }
    adjusted
}

/// min(1, factor·p), exact where p is a plain number and through logarithms where it is a bound.
fn scale_p(p: PValue, factor: f64) -> PValue {
    if p.is_bound() {
        PValue::from_ln(p.log10_p * std::f64::consts::LN_10 + factor.ln())
    } else {
        let scaled = (factor * p.p).min(1.0);
        PValue::new(scaled)
    }
}
