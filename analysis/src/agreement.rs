//! How far judges agree with one another, and how consistent each judge is with themselves, in
//! a paired-comparison study: Kendall & Babington Smith's (1940) coefficient of agreement `u`
//! with its test, its generalisation to unbalanced designs, and the coefficient of
//! consistence ζ.
//!
//! # Coefficient of agreement
//!
//! Let `a_ij` be the number of judgments in which condition `i` was chosen over `j`, and
//! `n_ij = a_ij + a_ji` the number of judgments of the pair. For a complete design in which each
//! of `m` judges judged every pair of `t` conditions once (Kendall & Babington Smith 1940),
//! with `Σ = Σ_{i≠j} C(a_ij, 2)` the number of agreeing pairs of judges:
//!
//! ```text
//! u    = 2·Σ / (C(m,2)·C(t,2)) − 1
//! χ²   = 4/(m−2) · (Σ − c − ½·C(t,2)·C(m,2)·(m−3)/(m−2))
//! df   = C(t,2) · m(m−1) / (m−2)²
//! ```
//!
//! `u = 1` when all judges agree; its minimum is `−1/(m−1)` for even `m` and `−1/m` for odd
//! `m`. `c = 1` is the continuity correction (Kendall, *Rank Correlation Methods*; on by default
//! here and in R's eba since 2018, [`AgreementOptions::continuity_correction`]); `c = 0` gives
//! the uncorrected statistic. These are the formulas of R's eba `kendall.u` (Wickelmaier); the
//! tests reproduce `kendall.u`'s published output for the school-subjects data of the 1940 paper
//! (from matrices with the same Σ, the only statistic u depends on; see
//! `tests/reference/agreement.R`). In simulations of the null for m = 3–21 and t = 4–13 the
//! corrected χ² p-value was the closer to the exact one at p ≈ 0.1 and 0.01 and conservative
//! below, whereas the uncorrected one was too small.
//!
//! **Generalisation.** When pairs are judged different numbers of times (an anchored design, in
//! which only some pairs are compared, or unequal repetitions), the same idea — the proportion
//! of pairs of judgments of the same pair of conditions that agree — gives
//!
//! ```text
//! u = 2 · Σ_pairs [C(a_ij,2) + C(a_ji,2)] / Σ_pairs C(n_ij,2) − 1,
//! ```
//!
//! which is Kendall's `u` when every `n_ij = m`. Its minimum is reached when every pair splits
//! as evenly as it can. Pairs judged fewer than twice contribute nothing; where no pair was
//! judged twice, `u` is not defined and [`Agreement::u`] is `None`. Under the null hypothesis
//! every judgment is a fair coin, `a_ij ~ Binomial(n_ij, ½)` independently, and the p-value of
//! the observed numerator `S` is estimated from `B` seeded simulations as
//! `p = (1 + #{S_sim ≥ S}) / (1 + B)` (comparing the exact integer numerators, so ties count).
//! Replicate `b` draws from its own ChaCha8 stream (`stream = b` of the seeded key), so the
//! p-value depends only on the seed and `B`, never on the number of rayon threads. Binomial
//! variates come from inversion of the exact CDF tabulated over n/2 ± 10σ for
//! 200 ≤ n_ij ≤ 10⁷ (three times faster), else from statrs' exact BINV/BTPE sampler
//! (Kachitvichyanukul & Schmeiser 1988), which takes constant expected time however large
//! `n_ij` is.
//!
//! **Which test.** The closed-form χ² is used when the design is complete and balanced: every
//! pair of the compared conditions (those in at least one judged pair) was judged the same
//! number of times `m ≥ 3`. Otherwise the simulation is used, unless it would take more than
//! [`SIMULATION_BUDGET`] binomial draws (more than 200 pairs judged twice at 10 000 simulations): then Kendall's χ² generalised
//! by matching three cumulants (see `generalised_chi2`; it reduces to Kendall's uncorrected χ²
//! on a balanced design). [`Agreement::method`] says which.
//! (The χ² assumes each judge judged each pair once; from tallies alone this cannot be checked,
//! but its null hypothesis, independent fair coins, is the same either way.)
//!
//! Counts are carried as `u128`, so `C(n, 2)` of counts of 10⁹ and more per pair, and their
//! sums, are exact; the χ² numerator is formed in exact integer arithmetic before the one
//! division.
//!
//! # Coefficient of consistence
//!
//! For one judge who compared every pair of the `t` conditions, with `s_i` the number of
//! conditions that `i` was preferred to, the number of circular triads (`i > j > k > i`) is
//! `d = C(t,3) − Σ_i C(s_i, 2)`, at most `(t³ − t)/24` for odd `t` and `(t³ − 4t)/24` for even
//! `t`, and `ζ = 1 − d / d_max` (= 1 − 24d/(t³ − t) or 1 − 24d/(t³ − 4t)): 1 for a transitive
//! judge, 0 for the most circular one. (eba's `circular` computes the same `d` as
//! `t(t−1)(2t−1)/12 − ½·Σ s_i²`; the tests check against that form.) A pair
//! judged several times counts by its majority; a tie leaves that judge without ζ.
//!
//! Reference: Kendall, M. G. & Babington Smith, B. (1940). On the method of paired
//! comparisons. *Biometrika* 31, 324–345. doi:10.1093/biomet/31.3-4.324.

use rand::SeedableRng;
use rand::distr::Distribution;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use statrs::distribution::{Binomial, BinomialAlgorithm, BinomialSampler};

use crate::design::PairTally;
use crate::error::{AnalysisError, Result};
use crate::pvalue::PValue;

/// The most binomial draws (simulations × pairs judged at least twice) the Monte-Carlo test may
/// take; larger unbalanced designs use the generalised χ² instead.
pub const SIMULATION_BUDGET: usize = 2_000_000;

/// The smallest number of judgments per pair for which the χ² approximation is used.
pub const CHI2_MIN_JUDGMENTS_PER_PAIR: u64 = 3;

/// How to test the coefficient of agreement.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AgreementOptions {
    /// Number of simulated data sets `B` for the Monte-Carlo test of unbalanced designs (at
    /// least 1; the smallest reportable p is `1/(B+1)`).
    pub simulations: usize,
    /// Seed of the simulation; the same seed and `simulations` give the same p-value.
    pub seed: u64,
    /// Subtract 1 from Σ in the χ² statistic of balanced designs (Kendall's continuity
    /// correction, as R's eba does by default).
    pub continuity_correction: bool,
}

impl Default for AgreementOptions {
    fn default() -> Self {
        AgreementOptions { simulations: 10_000, seed: 1940, continuity_correction: true }
    }
}

/// How the p-value of an [`Agreement`] was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AgreementMethod {
    /// Kendall & Babington Smith's χ² approximation (complete, balanced design).
    Chi2,
    /// Monte-Carlo simulation under the null hypothesis of fair-coin judgments.
    Simulation,
    /// Kendall's χ² generalised to unbalanced designs by matching the first three cumulants
    /// (used where the simulation would exceed [`SIMULATION_BUDGET`]).
    Chi2Generalised,
    /// No pair was judged twice: `u` is not defined and nothing was tested.
    Undefined,
}

impl AgreementMethod {
    /// The name used in JSON and tables: `chi2`, `simulation` or `undefined`.
    pub fn as_str(self) -> &'static str {
        match self {
            AgreementMethod::Chi2 => "chi2",
            AgreementMethod::Simulation => "simulation",
            AgreementMethod::Chi2Generalised => "chi2-generalised",
            AgreementMethod::Undefined => "undefined",
        }
    }
}

impl std::fmt::Display for AgreementMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The coefficient of agreement of a set of pair tallies and its test. Serialised as
/// `{"u": …, "min_u": …, "chi2": …, "df": …, "p": …, "log10_p": …, "method": "chi2", …}`;
/// fields that do not apply are left out, and no field is ever NaN or infinite.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Agreement {
    /// The coefficient of agreement; `None` when no pair was judged at least twice.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub u: Option<f64>,
    /// The smallest `u` this design allows (every pair split as evenly as it can be).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_u: Option<f64>,
    /// χ² statistic (method `chi2` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chi2: Option<f64>,
    /// Degrees of freedom of the χ² statistic (method `chi2` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub df: Option<f64>,
    /// p-value of the null hypothesis that judges agree no more than chance; serialised as the
    /// two numbers `p` and `log10_p`.
    #[serde(flatten)]
    pub p: Option<PValue>,
    /// Which test gave `p`.
    pub method: AgreementMethod,
    /// Number of simulated data sets (method `simulation` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub simulations: Option<usize>,
    /// Whether the χ² statistic was continuity-corrected (method `chi2` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub continuity_correction: Option<bool>,
    /// Number of conditions in at least one judged pair.
    pub conditions: usize,
    /// Number of distinct pairs of conditions judged at least once.
    pub pairs: usize,
    /// Why the simulation was used, or why `u` is not defined.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// One unordered pair after merging its tallies: `n` judgments, `a` won by the lower index.
#[derive(Debug, Clone, Copy)]
struct MergedPair {
    n: u64,
    a: u64,
}

/// `C(x, 2)` without overflow for any `u64`.
fn choose2(x: u64) -> u128 {
    let x = u128::from(x);
    if x < 2 { 0 } else { x * (x - 1) / 2 }
}

/// `C(a,2) + C(n−a,2)`: the number of agreeing pairs of judgments of one pair of conditions.
fn agreeing(n: u64, a: u64) -> u128 {
    choose2(a) + choose2(n - a)
}

/// `2·num/den − 1` with the difference formed exactly where it fits.
fn twice_ratio_minus_one(num: u128, den: u128) -> f64 {
    match num.checked_mul(2) {
        Some(twice) if twice >= den => (twice - den) as f64 / den as f64,
        Some(twice) => -((den - twice) as f64 / den as f64),
        None => 2.0 * (num as f64 / den as f64) - 1.0,
    }
}

fn too_large(what: &str) -> AnalysisError {
    AnalysisError::BadOption {
        option: "pairs".to_string(),
        message: format!("the counts are too large: {what} does not fit in 128 bits"),
    }
}

/// Validates the tallies and merges them by unordered pair (ignoring pairs never judged).
fn merge_pairs(pairs: &[PairTally], n_conditions: usize) -> Result<Vec<((usize, usize), MergedPair)>> {
    // Validate and orient, then sort and add up tallies of the same pair (sorting is several
    // times faster than a tree map at a million pairs).
    let mut oriented: Vec<((usize, usize), u64, u64)> = Vec::with_capacity(pairs.len());
    for (index, tally) in pairs.iter().enumerate() {
        for (name, condition) in [("i", tally.i), ("j", tally.j)] {
            if condition >= n_conditions {
                return Err(AnalysisError::BadOption {
                    option: format!("pairs[{index}].{name}"),
                    message: format!("condition index {condition} is out of range for {n_conditions} conditions"),
                });
            }
        }
        if tally.i == tally.j {
            return Err(AnalysisError::BadOption {
                option: format!("pairs[{index}]"),
                message: format!("pairs a condition with itself (index {})", tally.i),
            });
        }
        let (key, wins_low) =
            if tally.i < tally.j { ((tally.i, tally.j), tally.wins_i) } else { ((tally.j, tally.i), tally.wins_j) };
        let n = tally.wins_i.checked_add(tally.wins_j).ok_or_else(|| too_large("a pair's judgments"))?;
        if n == 0 {
            continue;
        }
        oriented.push((key, n, wins_low));
    }
    if !oriented.is_sorted_by_key(|&(key, _, _)| key) {
        oriented.sort_unstable_by_key(|&(key, _, _)| key);
    }
    let mut merged: Vec<((usize, usize), MergedPair)> = Vec::with_capacity(oriented.len());
    for (key, n, wins_low) in oriented {
        match merged.last_mut() {
            Some((last, entry)) if *last == key => {
                entry.n = entry.n.checked_add(n).ok_or_else(|| too_large("a pair's judgments"))?;
                entry.a += wins_low; // a ≤ n, so this cannot overflow when n did not
            }
            _ => merged.push((key, MergedPair { n, a: wins_low })),
        }
    }
    Ok(merged)
}

/// Kendall & Babington Smith's coefficient of agreement `u` of the judgments tallied in
/// `pairs` (conditions indexed `0..n_conditions`; several tallies of one pair are added), tested
/// by χ² for a complete balanced design and by seeded simulation otherwise (see the module
/// documentation). Errors only on malformed input: an index out of range, a condition paired
/// with itself, `options.simulations == 0`, or counts too large to add.
pub fn coefficient_of_agreement(
    pairs: &[PairTally],
    n_conditions: usize,
    options: &AgreementOptions,
) -> Result<Agreement> {
    if options.simulations == 0 {
        return Err(AnalysisError::BadOption {
            option: "simulations".to_string(),
            message: "must be at least 1".to_string(),
        });
    }
    let merged = merge_pairs(pairs, n_conditions)?;
    let mut compared = vec![false; n_conditions];
    for &((i, j), _) in &merged {
        compared[i] = true;
        compared[j] = true;
    }
    let n_compared = compared.iter().filter(|&&c| c).count();
    let n_pairs = merged.len();

    let mut numerator: u128 = 0;
    let mut denominator: u128 = 0;
    let mut min_numerator: u128 = 0;
    for pair in merged.iter().map(|(_, pair)| pair) {
        numerator = numerator.checked_add(agreeing(pair.n, pair.a)).ok_or_else(|| too_large("Σ C(a_ij, 2)"))?;
        denominator = denominator.checked_add(choose2(pair.n)).ok_or_else(|| too_large("Σ C(n_ij, 2)"))?;
        // cannot overflow: each term is at most C(n, 2), and their sum (the denominator) fit
        min_numerator += agreeing(pair.n, pair.n / 2);
    }

    let mut agreement = Agreement {
        u: None,
        min_u: None,
        chi2: None,
        df: None,
        p: None,
        method: AgreementMethod::Undefined,
        simulations: None,
        continuity_correction: None,
        conditions: n_compared,
        pairs: n_pairs,
        note: None,
    };
    if denominator == 0 {
        agreement.note = Some(if n_pairs == 0 {
            "no pair of conditions was judged, so the coefficient of agreement is not defined".to_string()
        } else {
            "no pair of conditions was judged at least twice, so the coefficient of agreement is not defined"
                .to_string()
        });
        return Ok(agreement);
    }
    agreement.u = Some(twice_ratio_minus_one(numerator, denominator));
    agreement.min_u = Some(twice_ratio_minus_one(min_numerator, denominator));

    let all_pairs = n_compared * (n_compared - 1) / 2;
    let n_min = merged.iter().map(|(_, pair)| pair).map(|p| p.n).min().unwrap_or(0);
    let n_max = merged.iter().map(|(_, pair)| pair).map(|p| p.n).max().unwrap_or(0);
    let balanced = n_pairs == all_pairs && n_min == n_max && n_min >= CHI2_MIN_JUDGMENTS_PER_PAIR;
    if balanced {
        let (chi2, df) = kendall_chi2(numerator, n_min, n_compared as u64, options.continuity_correction);
        agreement.chi2 = Some(chi2);
        agreement.df = Some(df);
        agreement.p = Some(PValue::chi2_upper(chi2, df));
        agreement.method = AgreementMethod::Chi2;
        agreement.continuity_correction = Some(options.continuity_correction);
        return Ok(agreement);
    }

    agreement.note = Some(if n_pairs < all_pairs {
        format!(
            "simulated p-value: {n_pairs} of the {all_pairs} pairs of the {n_compared} compared conditions were judged"
        )
    } else if n_min != n_max {
        format!("simulated p-value: pairs were judged between {n_min} and {n_max} times")
    } else {
        format!(
            "simulated p-value: every pair was judged {n_min} times, fewer than the {CHI2_MIN_JUDGMENTS_PER_PAIR} the χ² approximation needs"
        )
    });
    let counts: Vec<u64> = merged.iter().map(|(_, pair)| pair).map(|p| p.n).filter(|&n| n >= 2).collect();
    if counts.len().saturating_mul(options.simulations) > SIMULATION_BUDGET {
        let (statistic, df, p) = generalised_chi2(merged.iter().map(|(_, pair)| pair));
        agreement.note = Some(format!(
            "generalised χ² (three matched cumulants): simulating {} pairs {} times would exceed the budget of {SIMULATION_BUDGET} draws",
            counts.len(),
            options.simulations
        ));
        agreement.chi2 = statistic;
        agreement.df = df;
        agreement.p = Some(p);
        agreement.method = AgreementMethod::Chi2Generalised;
        return Ok(agreement);
    }
    agreement.p = Some(simulated_p(&counts, numerator, options.simulations, options.seed));
    agreement.method = AgreementMethod::Simulation;
    agreement.simulations = Some(options.simulations);
    Ok(agreement)
}

/// Kendall & Babington Smith's χ² statistic and degrees of freedom for `Σ = sigma`, `m` judges
/// (`m ≥ 3`) and `t` conditions; `χ² = 2·[2(m−2)(Σ−c) − C(t,2)·C(m,2)·(m−3)] / (m−2)²`, the
/// bracket formed exactly in `i128` where it fits. A continuity correction that would take the
/// statistic below 0 (possible only for tiny designs) is reported as 0.
fn kendall_chi2(sigma: u128, m: u64, t: u64, continuity_correction: bool) -> (f64, f64) {
    let correction: u128 = if continuity_correction { 1 } else { 0 };
    let pairs = choose2(t);
    let judge_pairs = choose2(m);
    let exact = || -> Option<i128> {
        let sigma_c = i128::try_from(sigma).ok()? - correction as i128;
        let first = 2i128.checked_mul(i128::from(m - 2))?.checked_mul(sigma_c)?;
        let second = i128::try_from(pairs.checked_mul(judge_pairs)?.checked_mul(u128::from(m - 3))?).ok()?;
        first.checked_sub(second)
    };
    let mf = m as f64;
    let scale = (mf - 2.0) * (mf - 2.0);
    let chi2 = match exact() {
        Some(bracket) => 2.0 * bracket as f64 / scale,
        None => {
            let sigma_c = sigma as f64 - correction as f64;
            4.0 / (mf - 2.0) * (sigma_c - 0.5 * pairs as f64 * judge_pairs as f64 * (mf - 3.0) / (mf - 2.0))
        }
    };
    let df = pairs as f64 * mf * (mf - 1.0) / scale;
    (chi2.max(0.0), df)
}

/// Monte-Carlo p-value `(1 + #{S_sim ≥ observed}) / (1 + B)` of the agreement numerator
/// `S = Σ_pairs [C(a,2) + C(n−a,2)]`, `a ~ Binomial(n, ½)` for each of `counts`.
fn simulated_p(counts: &[u64], observed: u128, simulations: usize, seed: u64) -> PValue {
    let samplers: Vec<(u64, PairSampler)> = counts.iter().map(|&n| (n, PairSampler::new(n))).collect();
    let key = ChaCha8Rng::seed_from_u64(seed);
    let at_least: usize = (0..simulations)
        .into_par_iter()
        .map(|replicate| {
            let mut rng = key.clone();
            rng.set_stream(replicate as u64);
            let mut sum: u128 = 0;
            for (n, sampler) in &samplers {
                sum += agreeing(*n, sampler.sample(&mut rng).min(*n));
            }
            usize::from(sum >= observed)
        })
        .sum();
    let p = (1.0 + at_least as f64) / (1.0 + simulations as f64);
    PValue::from_ln(p.ln())
}

/// Draws `a ~ Binomial(n, ½)`. For `TABLE_MIN_N ≤ n ≤ TABLE_MAX_N` by inversion of the exact
/// CDF tabulated over `n/2 ± 10σ` (the mass outside is below 1e-22, far under the 2⁻⁵³
/// resolution of the uniform variate), about three times faster than BTPE with one uniform per
/// draw; otherwise statrs' exact BINV/BTPE sampler.
enum PairSampler {
    Exact(BinomialSampler),
    Table { low: u64, cdf: Vec<f64> },
}

const TABLE_MIN_N: u64 = 200;
const TABLE_MAX_N: u64 = 10_000_000;

impl PairSampler {
    fn new(n: u64) -> PairSampler {
        if (TABLE_MIN_N..=TABLE_MAX_N).contains(&n) {
            let half = n as f64 / 2.0;
            let width = (10.0 * (n as f64).sqrt() / 2.0).ceil();
            let low = (half - width).floor().max(0.0) as u64;
            let high = ((half + width).ceil() as u64).min(n);
            let ln_norm = statrs::function::gamma::ln_gamma(n as f64 + 1.0) - n as f64 * std::f64::consts::LN_2;
            let mut cdf = Vec::with_capacity((high - low + 1) as usize);
            let mut total = 0.0;
            for a in low..=high {
                let ln_pmf = ln_norm
                    - statrs::function::gamma::ln_gamma(a as f64 + 1.0)
                    - statrs::function::gamma::ln_gamma((n - a) as f64 + 1.0);
                total += ln_pmf.exp();
                cdf.push(total);
            }
            for value in &mut cdf {
                *value /= total;
            }
            PairSampler::Table { low, cdf }
        } else {
            let binomial = Binomial::new(0.5, n).expect("p = 1/2 is a valid probability");
            PairSampler::Exact(binomial.sampler(BinomialAlgorithm::Automatic).expect("automatic never fails"))
        }
    }

    fn sample(&self, rng: &mut ChaCha8Rng) -> u64 {
        match self {
            PairSampler::Exact(sampler) => sampler.sample(rng),
            PairSampler::Table { low, cdf } => {
                let uniform: f64 = rand::RngExt::random(rng);
                low + cdf.partition_point(|&c| c < uniform).min(cdf.len() - 1) as u64
            }
        }
    }
}

/// Kendall's χ² generalised to any design. Under the null, `a ~ Binomial(n, ½)` per pair, and
/// with `d = a − n/2`, `C(a,2) + C(n−a,2) = n(n−2)/4 + d²`: the statistic is `D = Σ d²`, whose
/// cumulants add over pairs, `κ₁ = Σ n/4`, `κ₂ = Σ n(n−1)/8`, `κ₃ = Σ n(n−1)(n−2)/8` (from the
/// moments of a sum of Rademacher variables). Matching a shifted, scaled χ² (Pearson type III)
/// to these three cumulants gives `χ² = (D − κ₁)/c + ν` with `c = κ₃/(4κ₂)`, `ν = 8κ₂³/κ₃²`. For a
/// balanced design (`n = m` everywhere) this is exactly Kendall's uncorrected χ² and df. Where
/// `κ₃ = 0` (no pair judged three times) the normal approximation `z = (D − κ₁)/√κ₂` is used and
/// no χ² is reported.
fn generalised_chi2<'a>(pairs: impl Iterator<Item = &'a MergedPair>) -> (Option<f64>, Option<f64>, PValue) {
    let (mut d, mut k1, mut k2, mut k3) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for pair in pairs {
        let n = pair.n as f64;
        let deviation = pair.a as f64 - n / 2.0;
        d += deviation * deviation;
        k1 += n / 4.0;
        k2 += n * (n - 1.0) / 8.0;
        k3 += n * (n - 1.0) * (n - 2.0) / 8.0;
    }
    if k3 <= 0.0 {
        let z = if k2 > 0.0 { (d - k1) / k2.sqrt() } else { 0.0 };
        return (None, None, PValue::from_ln(crate::pvalue::ln_normal_upper(z)));
    }
    let scale = k3 / (4.0 * k2);
    let df = 8.0 * k2 * k2 * k2 / (k3 * k3);
    let statistic = ((d - k1) / scale + df).max(0.0);
    (Some(statistic), Some(df), PValue::chi2_upper(statistic, df))
}

/// Kendall & Babington Smith's coefficient of consistence of one judge.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Consistence {
    /// ζ = 1 − d/d_max; `None` when the judge did not give a majority on every pair, or when
    /// there are fewer than three conditions.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub zeta: Option<f64>,
    /// Number of circular triads `d` in the judge's tournament (with `zeta`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub circular_triads: Option<u64>,
    /// The most circular triads possible with these conditions.
    pub max_circular_triads: u64,
    /// Why `zeta` is missing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// The coefficient of consistence ζ of one judge from their judgments `(i, j, i_won)` among
/// conditions `0..n_conditions`. Every pair must have been judged; a pair judged several times
/// counts by its majority. Errors only on an index out of range or a condition paired with
/// itself.
pub fn coefficient_of_consistence(judgments: &[(usize, usize, bool)], n_conditions: usize) -> Result<Consistence> {
    let t = n_conditions;
    // wins[lower * t + higher] = (wins of the lower index, wins of the higher index)
    let mut wins = vec![(0u64, 0u64); t * t];
    for (index, &(i, j, i_won)) in judgments.iter().enumerate() {
        for (name, condition) in [("i", i), ("j", j)] {
            if condition >= t {
                return Err(AnalysisError::BadOption {
                    option: format!("judgments[{index}].{name}"),
                    message: format!("condition index {condition} is out of range for {t} conditions"),
                });
            }
        }
        if i == j {
            return Err(AnalysisError::BadOption {
                option: format!("judgments[{index}]"),
                message: format!("pairs a condition with itself (index {i})"),
            });
        }
        let low_won = (i < j) == i_won;
        let cell = &mut wins[i.min(j) * t + i.max(j)];
        if low_won {
            cell.0 += 1;
        } else {
            cell.1 += 1;
        }
    }

    let t128 = t as u128;
    let max_triads = if t < 3 {
        0
    } else if t % 2 == 1 {
        (t128.pow(3) - t128) / 24
    } else {
        (t128.pow(3) - 4 * t128) / 24
    };
    let max_circular_triads = u64::try_from(max_triads).unwrap_or(u64::MAX);
    let missing_reason =
        |reason: String| Consistence { zeta: None, circular_triads: None, max_circular_triads, reason: Some(reason) };
    if t < 3 {
        return Ok(missing_reason(format!("{t} conditions form no triads")));
    }

    let all_pairs = t * (t - 1) / 2;
    let mut judged = 0usize;
    let mut ties: Vec<(usize, usize, u64)> = Vec::new();
    let mut score = vec![0u64; t];
    for low in 0..t {
        for high in low + 1..t {
            let (w_low, w_high) = wins[low * t + high];
            if w_low + w_high == 0 {
                continue;
            }
            judged += 1;
            match w_low.cmp(&w_high) {
                std::cmp::Ordering::Greater => score[low] += 1,
                std::cmp::Ordering::Less => score[high] += 1,
                std::cmp::Ordering::Equal => ties.push((low, high, w_low)),
            }
        }
    }
    if judged < all_pairs {
        return Ok(missing_reason(format!(
            "judged {judged} of the {all_pairs} pairs of the {t} conditions; ζ needs every pair"
        )));
    }
    if let Some(&(low, high, each)) = ties.first() {
        let more = if ties.len() > 1 { format!(" (and {} more pairs)", ties.len() - 1) } else { String::new() };
        return Ok(missing_reason(format!(
            "chose each of conditions {low} and {high} {each} times, so the pair has no majority{more}"
        )));
    }

    let triads = t128 * (t128 - 1) * (t128 - 2) / 6;
    let transitive: u128 = score.iter().map(|&s| choose2(s)).sum();
    let circular = triads - transitive;
    Ok(Consistence {
        zeta: Some(1.0 - circular as f64 / max_triads as f64),
        circular_triads: Some(u64::try_from(circular).unwrap_or(u64::MAX)),
        max_circular_triads,
        reason: None,
    })
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // index loops over square matrices read most plainly
mod tests {
    use super::*;
    use rand::Rng;
    use serde_json::Value;
    use statrs::distribution::{ContinuousCDF, DiscreteCDF, Normal};

    /// Reference values written by `tests/reference/agreement.R` (R 4.2.2, base R).
    const REFERENCE: &str = include_str!("../tests/reference/agreement.json");

    /// u, χ² and df against R: both compute the same closed forms in doubles.
    const TOL_R_STATISTIC: f64 = 1e-12;
    /// log10 p against R's `pchisq(log.p = TRUE)`: both are continued fractions / series of the
    /// incomplete gamma function, agreeing to ~1e-13 relative.
    const TOL_R_LOG10_P: f64 = 1e-9;
    /// Monte-Carlo p against an exact p: allowed error in standard errors sqrt(p(1−p)/B).
    const MC_STANDARD_ERRORS: f64 = 4.5;

    fn reference() -> Value {
        serde_json::from_str(REFERENCE).expect("agreement.json parses")
    }

    fn f(value: &Value) -> f64 {
        value.as_f64().expect("a number")
    }

    fn tallies_from_matrix(matrix: &Value) -> (Vec<PairTally>, usize) {
        let rows: Vec<Vec<u64>> = matrix
            .as_array()
            .unwrap()
            .iter()
            .map(|row| row.as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect())
            .collect();
        let t = rows.len();
        let mut tallies = Vec::new();
        for i in 0..t {
            for j in i + 1..t {
                tallies.push(PairTally { i, j, wins_i: rows[i][j], wins_j: rows[j][i] });
            }
        }
        (tallies, t)
    }

    fn tallies_from_pairs(pairs: &Value) -> Vec<PairTally> {
        pairs
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                let p: Vec<u64> = p.as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect();
                PairTally { i: p[0] as usize, j: p[1] as usize, wins_i: p[2], wins_j: p[3] }
            })
            .collect()
    }

    fn options(correct: bool) -> AgreementOptions {
        AgreementOptions { continuity_correction: correct, ..AgreementOptions::default() }
    }

    fn assert_close(actual: f64, expected: f64, tolerance: f64, what: &str) {
        assert!(
            (actual - expected).abs() <= tolerance * expected.abs().max(1.0),
            "{what}: {actual} vs {expected} (tolerance {tolerance})"
        );
    }

    fn check_balanced_against_r(case: &Value, corrected: bool) {
        let (tallies, t) = tallies_from_matrix(&case["matrix"]);
        let r = &case[if corrected { "corrected" } else { "uncorrected" }];
        let agreement = coefficient_of_agreement(&tallies, t, &options(corrected)).unwrap();
        assert_eq!(agreement.method, AgreementMethod::Chi2);
        assert_close(agreement.u.unwrap(), f(&r["u"]), TOL_R_STATISTIC, "u");
        assert_close(agreement.min_u.unwrap(), f(&r["min_u"]), TOL_R_STATISTIC, "min_u");
        assert_close(agreement.chi2.unwrap(), f(&r["chi2"]), TOL_R_STATISTIC, "chi2");
        assert_close(agreement.df.unwrap(), f(&r["df"]), TOL_R_STATISTIC, "df");
        let p = agreement.p.unwrap();
        assert_close(p.log10_p, f(&r["log10_p"]), TOL_R_LOG10_P, "log10 p");
        assert_eq!(agreement.continuity_correction, Some(corrected));
    }

    #[test]
    fn celebrities_matches_r_kendall_u_formulas() {
        let reference = reference();
        check_balanced_against_r(&reference["celebrities"], true);
        check_balanced_against_r(&reference["celebrities"], false);
    }

    /// eba's manual prints, for Kendall & Babington Smith's school-subjects data, boys:
    /// u = 0.1866, min u = −0.04762, χ² = 412.22, df = 90.75, p = 1.721e−42; girls: u = 0.08218,
    /// min u = −0.04, χ² = 180.12, df = 62.38, p = 2.307e−13 (continuity-corrected). The
    /// matrices are synthetic with the same Σ (see agreement.R); the check is to the digits
    /// printed.
    #[test]
    fn school_subjects_reproduce_eba_published_output() {
        let reference = reference();
        for case in ["school_subjects_boys", "school_subjects_girls"] {
            let case = &reference[case];
            check_balanced_against_r(case, true);
            check_balanced_against_r(case, false);
            let (tallies, t) = tallies_from_matrix(&case["matrix"]);
            let agreement = coefficient_of_agreement(&tallies, t, &options(true)).unwrap();
            let published = &case["published"];
            let four_digits =
                |x: f64, printed: f64| (x - printed).abs() <= 0.5 * 10f64.powf(printed.abs().log10().floor() - 3.0);
            let two_decimals = |x: f64, printed: f64| (x - printed).abs() <= 0.005;
            assert!(four_digits(agreement.u.unwrap(), f(&published["u"])));
            assert!(four_digits(agreement.min_u.unwrap(), f(&published["min_u"])));
            assert!(two_decimals(agreement.chi2.unwrap(), f(&published["chi2"])));
            assert!(two_decimals(agreement.df.unwrap(), f(&published["df"])));
            assert!(four_digits(agreement.p.unwrap().p, f(&published["p"])));
        }
    }

    #[test]
    fn generalised_u_equals_kendall_u_on_a_balanced_design() {
        let reference = reference();
        let case = &reference["balanced_exact"];
        let tallies = tallies_from_pairs(&case["pairs"]);
        let agreement = coefficient_of_agreement(&tallies, 5, &options(true)).unwrap();
        // R's generalised numerator/denominator and its kendall_u on the same design agree.
        assert_close(f(&case["u"]), f(&case["corrected"]["u"]), 1e-15, "R generalised vs Kendall");
        assert_close(agreement.u.unwrap(), f(&case["corrected"]["u"]), TOL_R_STATISTIC, "u");
        // Kendall's formula written out for this design: m = 10, t = 5.
        let sigma: u128 = tallies.iter().map(|p| choose2(p.wins_i) + choose2(p.wins_j)).sum();
        let kendall = 2.0 * sigma as f64 / (45.0 * 10.0) - 1.0;
        assert_close(agreement.u.unwrap(), kendall, 1e-15, "u vs Kendall's formula");
        assert_close(agreement.min_u.unwrap(), -1.0 / 9.0, 1e-15, "min u");
    }

    #[test]
    fn generalised_u_of_an_anchored_design_matches_r() {
        let reference = reference();
        let case = &reference["anchored_exact"];
        let tallies = tallies_from_pairs(&case["pairs"]);
        let agreement = coefficient_of_agreement(&tallies, 5, &AgreementOptions::default()).unwrap();
        assert_eq!(agreement.method, AgreementMethod::Simulation);
        assert_close(agreement.u.unwrap(), f(&case["u"]), TOL_R_STATISTIC, "u");
        assert_close(agreement.min_u.unwrap(), f(&case["min_u"]), TOL_R_STATISTIC, "min u");
        assert_eq!(agreement.pairs, 6);
        assert_eq!(agreement.conditions, 5);
        assert!(agreement.chi2.is_none() && agreement.df.is_none());
    }

    #[test]
    fn tallies_of_one_pair_in_either_order_are_added() {
        let split = [
            PairTally { i: 0, j: 1, wins_i: 3, wins_j: 1 },
            PairTally { i: 1, j: 0, wins_i: 2, wins_j: 4 },
            PairTally { i: 0, j: 2, wins_i: 5, wins_j: 0 },
        ];
        let whole = [PairTally { i: 0, j: 1, wins_i: 7, wins_j: 3 }, PairTally { i: 0, j: 2, wins_i: 5, wins_j: 0 }];
        let a = coefficient_of_agreement(&split, 3, &AgreementOptions::default()).unwrap();
        let b = coefficient_of_agreement(&whole, 3, &AgreementOptions::default()).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.pairs, 2);
    }

    /// The exact p of the anchored design (R, by convolution over pairs) against the simulated
    /// one. With B = 20000 and p ≈ 0.018 the standard error is 0.00094.
    #[test]
    fn simulated_p_matches_exact_p_of_an_anchored_design() {
        let reference = reference();
        let case = &reference["anchored_exact"];
        let tallies = tallies_from_pairs(&case["pairs"]);
        let simulations = 20_000;
        let options = AgreementOptions { simulations, seed: 7, continuity_correction: true };
        let agreement = coefficient_of_agreement(&tallies, 5, &options).unwrap();
        let exact = f(&case["p_exact"]);
        let standard_error = (exact * (1.0 - exact) / simulations as f64).sqrt();
        let p = agreement.p.unwrap().p;
        assert!((p - exact).abs() <= MC_STANDARD_ERRORS * standard_error, "simulated {p} vs exact {exact}");
        assert_eq!(agreement.simulations, Some(simulations));
    }

    #[test]
    fn simulated_p_is_reproducible_for_a_seed_whatever_the_thread_count() {
        let reference = reference();
        let tallies = tallies_from_pairs(&reference["anchored_exact"]["pairs"]);
        let options = AgreementOptions { simulations: 3000, seed: 42, continuity_correction: true };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| coefficient_of_agreement(&tallies, 5, &options).unwrap())
        };
        let one = run(1);
        assert_eq!(one, run(1));
        assert_eq!(one, run(4));
        assert_eq!(one, run(7));
    }

    /// On the balanced design (t = 5, m = 10, R's exact p = 0.0284), the simulation agrees with
    /// the exact p within its standard error, and the corrected χ² p (0.0301) is within 10 % of
    /// the exact p, so the simulation and the χ² agree within 4.5 standard errors plus that.
    #[test]
    fn simulated_p_is_close_to_chi2_p_on_a_balanced_design() {
        let reference = reference();
        let case = &reference["balanced_exact"];
        let tallies = tallies_from_pairs(&case["pairs"]);
        let chi2 = coefficient_of_agreement(&tallies, 5, &options(true)).unwrap();
        assert_eq!(chi2.method, AgreementMethod::Chi2);
        let chi2_p = chi2.p.unwrap().p;
        assert_close(chi2_p, f(&case["corrected"]["p"]), 1e-10, "χ² p vs R");
        let exact = f(&case["p_exact"]);
        assert!((chi2_p - exact).abs() <= 0.1 * exact, "χ² {chi2_p} vs exact {exact}");

        let simulations = 20_000;
        let counts: Vec<u64> = tallies.iter().map(PairTally::n).collect();
        let numerator: u128 = tallies.iter().map(|p| agreeing(p.n(), p.wins_i)).sum();
        let simulated = simulated_p(&counts, numerator, simulations, 11).p;
        let standard_error = (exact * (1.0 - exact) / simulations as f64).sqrt();
        assert!(
            (simulated - exact).abs() <= MC_STANDARD_ERRORS * standard_error,
            "simulated {simulated} vs exact {exact}"
        );
        assert!((simulated - chi2_p).abs() <= MC_STANDARD_ERRORS * standard_error + 0.1 * exact);
    }

    fn complete_design(t: usize, wins: impl Fn(usize, usize) -> (u64, u64)) -> Vec<PairTally> {
        let mut tallies = Vec::new();
        for i in 0..t {
            for j in i + 1..t {
                let (wins_i, wins_j) = wins(i, j);
                tallies.push(PairTally { i, j, wins_i, wins_j });
            }
        }
        tallies
    }

    #[test]
    fn u_is_one_when_all_judges_agree() {
        let tallies = complete_design(6, |_, _| (9, 0));
        let agreement = coefficient_of_agreement(&tallies, 6, &AgreementOptions::default()).unwrap();
        assert_eq!(agreement.u, Some(1.0));
        assert_eq!(agreement.method, AgreementMethod::Chi2);
        assert!(agreement.p.unwrap().p < 1e-20);
        // Unbalanced, all agreeing: still exactly 1.
        let anchored = [PairTally { i: 0, j: 1, wins_i: 5, wins_j: 0 }, PairTally { i: 2, j: 0, wins_i: 0, wins_j: 9 }];
        let agreement = coefficient_of_agreement(&anchored, 3, &AgreementOptions::default()).unwrap();
        assert_eq!(agreement.u, Some(1.0));
        assert_eq!(agreement.method, AgreementMethod::Simulation);
    }

    #[test]
    fn u_reaches_its_minimum_when_judges_split_evenly() {
        // Even m: −1/(m − 1).
        let tallies = complete_design(5, |_, _| (5, 5));
        let agreement = coefficient_of_agreement(&tallies, 5, &AgreementOptions::default()).unwrap();
        assert_close(agreement.u.unwrap(), -1.0 / 9.0, 1e-15, "even m");
        assert_eq!(agreement.u, agreement.min_u);
        assert!(agreement.p.unwrap().p > 0.99);
        // Odd m: −1/m.
        let tallies = complete_design(4, |_, _| (4, 5));
        let agreement = coefficient_of_agreement(&tallies, 4, &AgreementOptions::default()).unwrap();
        assert_close(agreement.u.unwrap(), -1.0 / 9.0, 1e-15, "odd m");
        assert_eq!(agreement.u, agreement.min_u);
        // Corrected χ² of a tiny design cannot go below 0.
        let tallies = complete_design(2, |_, _| (2, 2));
        let agreement = coefficient_of_agreement(&tallies, 2, &AgreementOptions::default()).unwrap();
        assert_eq!(agreement.chi2, Some(0.0));
        assert_eq!(agreement.p.unwrap().p, 1.0);
    }

    #[test]
    fn counts_of_a_billion_per_pair_are_exact() {
        let m: u64 = 1_000_000_000;
        let tallies = complete_design(3, |_, _| (m, 0));
        let agreement = coefficient_of_agreement(&tallies, 3, &options(true)).unwrap();
        assert_eq!(agreement.u, Some(1.0));
        // Perfect agreement: χ² = 2·C(t,2)·C(m,2)·(m−1)/(m−2)² − 4c/(m−2).
        let mf = m as f64;
        let expected = 2.0 * 3.0 * (mf * (mf - 1.0) / 2.0) * (mf - 1.0) / ((mf - 2.0) * (mf - 2.0)) - 4.0 / (mf - 2.0);
        assert_close(agreement.chi2.unwrap(), expected, 1e-12, "χ²");
        assert!(agreement.p.unwrap().p > 0.0 && agreement.p.unwrap().log10_p.is_finite());

        let tallies = complete_design(4, |_, _| (m / 2, m / 2));
        let agreement = coefficient_of_agreement(&tallies, 4, &options(false)).unwrap();
        assert_close(agreement.u.unwrap(), -1.0 / (mf - 1.0), 1e-15, "even split");
        // The uncorrected χ² at the minimum is C(t,2)·m/(m−2)², computed exactly.
        assert_close(agreement.chi2.unwrap(), 6.0 * mf / ((mf - 2.0) * (mf - 2.0)), 1e-12, "χ² at the minimum");
        let json = serde_json::to_string(&agreement).unwrap();
        assert!(!json.contains("NaN") && !json.contains("inf"));

        // Counts far above 1e9 still add up exactly.
        let big = [PairTally { i: 0, j: 1, wins_i: u64::MAX / 2, wins_j: u64::MAX / 2 }];
        let agreement = coefficient_of_agreement(&big, 2, &AgreementOptions::default()).unwrap();
        assert!(agreement.u.unwrap().abs() < 1e-15);
        let overflow = [PairTally { i: 0, j: 1, wins_i: u64::MAX, wins_j: 1 }];
        assert!(coefficient_of_agreement(&overflow, 2, &AgreementOptions::default()).is_err());
    }

    /// Three anchor pairs judged 10⁹ and 7·10⁸ times, `a = n/2 + z·√n/2`: R's p from the
    /// large-n limit of the null (a weighted sum of χ²(1)) is 0.0534; with B = 4000 the standard
    /// error is 0.0036.
    #[test]
    fn simulation_with_a_billion_judgments_per_pair_matches_the_large_n_limit() {
        let reference = reference();
        let case = &reference["huge_anchored"];
        let tallies = tallies_from_pairs(&case["pairs"]);
        let simulations = 4000;
        let options = AgreementOptions { simulations, seed: 5, continuity_correction: true };
        let agreement = coefficient_of_agreement(&tallies, 4, &options).unwrap();
        assert_eq!(agreement.method, AgreementMethod::Simulation);
        let limit = f(&case["p_limit"]);
        let standard_error = (limit * (1.0 - limit) / simulations as f64).sqrt();
        let p = agreement.p.unwrap().p;
        assert!((p - limit).abs() <= MC_STANDARD_ERRORS * standard_error, "simulated {p} vs limit {limit}");
    }

    #[test]
    fn no_pair_judged_twice_leaves_u_undefined() {
        let tallies = [
            PairTally { i: 0, j: 1, wins_i: 1, wins_j: 0 },
            PairTally { i: 1, j: 2, wins_i: 0, wins_j: 1 },
            PairTally { i: 0, j: 2, wins_i: 0, wins_j: 0 },
        ];
        for pairs in [&tallies[..], &[]] {
            let agreement = coefficient_of_agreement(pairs, 3, &AgreementOptions::default()).unwrap();
            assert_eq!(agreement.method, AgreementMethod::Undefined);
            assert!(agreement.u.is_none() && agreement.p.is_none() && agreement.chi2.is_none());
            assert!(agreement.note.as_deref().unwrap().contains("not defined"));
            let json = serde_json::to_value(&agreement).unwrap();
            assert_eq!(json["method"], "undefined");
            assert!(json.get("u").is_none() && json.get("p").is_none());
            assert!(!json.to_string().contains("NaN"));
        }
    }

    #[test]
    fn json_has_the_keys_of_the_analysis_json() {
        let tallies = complete_design(4, |i, j| (6 + (i + j) as u64 % 3, 2 - (i + j) as u64 % 3));
        let agreement = coefficient_of_agreement(&tallies, 4, &AgreementOptions::default()).unwrap();
        let json = serde_json::to_value(&agreement).unwrap();
        for key in ["u", "chi2", "df", "p", "log10_p", "min_u"] {
            assert!(json[key].is_number(), "{key} in {json}");
        }
        assert_eq!(json["method"], "chi2");
        assert_eq!(json["method"], agreement.method.to_string());
        assert_eq!(json["continuity_correction"], true);
        assert!(json.get("simulations").is_none() && json.get("note").is_none());
    }

    #[test]
    fn malformed_tallies_are_errors() {
        let out_of_range = [PairTally { i: 0, j: 3, wins_i: 1, wins_j: 1 }];
        let error = coefficient_of_agreement(&out_of_range, 3, &AgreementOptions::default()).unwrap_err();
        assert!(error.to_string().contains("pairs[0].j"), "{error}");
        let itself = [PairTally { i: 1, j: 1, wins_i: 1, wins_j: 1 }];
        assert!(coefficient_of_agreement(&itself, 3, &AgreementOptions::default()).is_err());
        let no_simulations = AgreementOptions { simulations: 0, ..AgreementOptions::default() };
        assert!(coefficient_of_agreement(&[], 3, &no_simulations).is_err());
    }

    /// statrs' BINV/BTPE sampler at p = ½, against the binomial CDF: the largest difference of
    /// empirical and reference CDF stays below the Kolmogorov–Smirnov critical value 1.95/√N
    /// (α = 0.001; conservative for a discrete distribution). The reference is statrs' exact
    /// CDF up to n = 5000; at n = 10⁹ it is the normal CDF with continuity correction, whose
    /// error for p = ½ is O(1/n) (statrs 0.19.1's `Binomial::cdf` returns −3.71 at k = n/2 for
    /// n = 10⁹, so it cannot serve there).
    #[test]
    fn binomial_sampler_follows_the_binomial_distribution() {
        let draws = 50_000;
        for (n, seed) in [(7u64, 1u64), (60, 2), (5000, 3), (1_000_000_000, 4)] {
            let sampler = Binomial::new(0.5, n).unwrap().sampler(BinomialAlgorithm::Automatic).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut sample: Vec<u64> = (0..draws).map(|_| sampler.sample(&mut rng)).collect();
            sample.sort_unstable();
            let exact = Binomial::new(0.5, n).unwrap();
            let normal = Normal::new(n as f64 / 2.0, (n as f64 / 4.0).sqrt()).unwrap();
            let cdf = |k: u64| {
                if n <= 5000 { exact.cdf(k) } else { normal.cdf(k as f64 + 0.5) }
            };
            let mut largest: f64 = 0.0;
            let mut index = 0;
            while index < sample.len() {
                let k = sample[index];
                let below = index as f64 / draws as f64;
                while index < sample.len() && sample[index] == k {
                    index += 1;
                }
                let at = index as f64 / draws as f64;
                let cdf_below = if k == 0 { 0.0 } else { cdf(k - 1) };
                largest = largest.max((at - cdf(k)).abs()).max((below - cdf_below).abs());
            }
            assert!(largest < 1.95 / (draws as f64).sqrt(), "n = {n}: KS distance {largest}");
        }
    }

    /// `d` by enumerating every triple, for comparison with the score formula.
    fn circular_triads_by_enumeration(beats: &[Vec<bool>]) -> u64 {
        let t = beats.len();
        let mut count = 0;
        for i in 0..t {
            for j in i + 1..t {
                for k in j + 1..t {
                    let cycle =
                        (beats[i][j] && beats[j][k] && beats[k][i]) || (beats[j][i] && beats[k][j] && beats[i][k]);
                    count += u64::from(cycle);
                }
            }
        }
        count
    }

    fn judgments_of(beats: &[Vec<bool>]) -> Vec<(usize, usize, bool)> {
        let t = beats.len();
        let mut judgments = Vec::new();
        for i in 0..t {
            for j in i + 1..t {
                judgments.push((i, j, beats[i][j]));
            }
        }
        judgments
    }

    #[test]
    fn consistence_matches_r_circular_triads() {
        let reference = reference();
        for case in reference["consistence"].as_array().unwrap() {
            let t = case["t"].as_u64().unwrap() as usize;
            let judgments: Vec<(usize, usize, bool)> = case["judgments"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| (j[0].as_u64().unwrap() as usize, j[1].as_u64().unwrap() as usize, j[2].as_bool().unwrap()))
                .collect();
            let consistence = coefficient_of_consistence(&judgments, t).unwrap();
            let name = case["name"].as_str().unwrap();
            assert_eq!(consistence.circular_triads, Some(case["circular_triads"].as_u64().unwrap()), "{name}");
            assert_eq!(consistence.max_circular_triads, case["max_circular_triads"].as_u64().unwrap(), "{name}");
            assert_close(consistence.zeta.unwrap(), f(&case["zeta"]), 1e-15, name);
        }
    }

    #[test]
    fn transitive_judge_has_zeta_one_and_regular_tournament_the_most_triads() {
        let transitive: Vec<(usize, usize, bool)> =
            (0..6).flat_map(|i| (i + 1..6).map(move |j| (j, i, false))).collect();
        let consistence = coefficient_of_consistence(&transitive, 6).unwrap();
        assert_eq!(consistence.zeta, Some(1.0));
        assert_eq!(consistence.circular_triads, Some(0));
        assert_eq!(consistence.max_circular_triads, 8);

        // t = 5, each condition beats the next two: every condition has 2 wins, d = 5 = max.
        let regular: Vec<(usize, usize, bool)> =
            (0..5).flat_map(|i| [(i, (i + 1) % 5, true), (i, (i + 2) % 5, true)]).collect();
        let consistence = coefficient_of_consistence(&regular, 5).unwrap();
        assert_eq!(consistence.circular_triads, Some(5));
        assert_eq!(consistence.max_circular_triads, 5);
        assert_eq!(consistence.zeta, Some(0.0));
    }

    #[test]
    fn circular_triads_agree_with_enumeration_on_random_tournaments() {
        let mut rng = ChaCha8Rng::seed_from_u64(1940);
        for t in 3..=9 {
            for _ in 0..20 {
                let mut beats = vec![vec![false; t]; t];
                for i in 0..t {
                    for j in i + 1..t {
                        let i_won = rng.next_u32() % 2 == 0;
                        beats[i][j] = i_won;
                        beats[j][i] = !i_won;
                    }
                }
                let consistence = coefficient_of_consistence(&judgments_of(&beats), t).unwrap();
                assert_eq!(consistence.circular_triads, Some(circular_triads_by_enumeration(&beats)));
                let zeta = consistence.zeta.unwrap();
                assert!((0.0..=1.0).contains(&zeta));
            }
        }
    }

    #[test]
    fn repeated_judgments_count_by_majority_and_ties_give_no_zeta() {
        // 0 > 1 twice of three, 1 > 2, 0 > 2: transitive by majority.
        let judgments = [(0, 1, true), (1, 0, true), (0, 1, true), (1, 2, true), (2, 0, false)];
        let consistence = coefficient_of_consistence(&judgments, 3).unwrap();
        assert_eq!(consistence.zeta, Some(1.0));
        // 1 > 0 by majority (2 of 3), 0 > 2 and 2 > 1: one circular triad.
        let judgments = [(0, 1, false), (1, 0, true), (0, 1, true), (2, 1, true), (0, 2, true)];
        let consistence = coefficient_of_consistence(&judgments, 3).unwrap();
        assert_eq!(consistence.circular_triads, Some(1));
        assert_eq!(consistence.zeta, Some(0.0));

        let tie = [(0, 1, true), (0, 1, false), (1, 2, true), (0, 2, true)];
        let consistence = coefficient_of_consistence(&tie, 3).unwrap();
        assert!(consistence.zeta.is_none() && consistence.circular_triads.is_none());
        assert!(consistence.reason.as_deref().unwrap().contains("no majority"));
        assert_eq!(consistence.max_circular_triads, 1);
        let json = serde_json::to_value(&consistence).unwrap();
        assert!(json.get("zeta").is_none() && json["reason"].is_string());
    }

    #[test]
    fn judge_who_missed_a_pair_or_too_few_conditions_gets_no_zeta() {
        let consistence = coefficient_of_consistence(&[(0, 1, true), (1, 2, true)], 3).unwrap();
        assert!(consistence.zeta.is_none());
        assert!(consistence.reason.as_deref().unwrap().contains("2 of the 3 pairs"));
        let consistence = coefficient_of_consistence(&[(0, 1, true)], 2).unwrap();
        assert!(consistence.zeta.is_none() && consistence.reason.is_some());
        assert_eq!(consistence.max_circular_triads, 0);
        assert!(coefficient_of_consistence(&[(0, 3, true)], 3).is_err());
        assert!(coefficient_of_consistence(&[(2, 2, true)], 3).is_err());
    }
}

#[cfg(test)]
mod generalised_tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// On a balanced design the generalised χ² is Kendall's uncorrected χ² and df, exactly.
    #[test]
    fn generalised_chi2_reduces_to_kendalls_on_a_balanced_design() {
        let (t, m) = (6u64, 9u64);
        let mut merged = Vec::new();
        let mut sigma: u128 = 0;
        for k in 0..t * (t - 1) / 2 {
            let a = (k * 7 + 3) % (m + 1);
            merged.push(MergedPair { n: m, a });
            sigma += agreeing(m, a);
        }
        let (statistic, df, _) = generalised_chi2(merged.iter());
        let (kendall, kendall_df) = kendall_chi2(sigma, m, t, false);
        assert!((statistic.unwrap() - kendall).abs() < 1e-9 * kendall.abs().max(1.0), "{statistic:?} vs {kendall}");
        assert!((df.unwrap() - kendall_df).abs() < 1e-9 * kendall_df);
    }

    /// On a moderate unbalanced design the three-cumulant χ² p-value agrees with the simulated
    /// one (B = 40 000) to within 15 % of its value.
    #[test]
    fn generalised_chi2_agrees_with_simulation_on_an_unbalanced_design() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let merged: Vec<MergedPair> = (0..60)
            .map(|_| {
                let n = rng.random_range(3..30u64);
                // Slight agreement: each judgment favours the first condition with probability 0.56.
                let a = (0..n).filter(|_| rng.random::<f64>() < 0.56).count() as u64;
                MergedPair { n, a }
            })
            .collect();
        let observed: u128 = merged.iter().map(|p| agreeing(p.n, p.a)).sum();
        let counts: Vec<u64> = merged.iter().map(|p| p.n).collect();
        let simulated = simulated_p(&counts, observed, 40_000, 5).p;
        let (_, _, generalised) = generalised_chi2(merged.iter());
        assert!(simulated > 1e-3 && simulated < 0.5, "pick a design with a moderate p, got {simulated}");
        assert!(
            (generalised.p - simulated).abs() < 0.15 * simulated,
            "generalised {} vs simulated {simulated}",
            generalised.p
        );
    }

    /// The tabulated sampler follows Binomial(n, ½): its empirical CDF stays within the
    /// Kolmogorov–Smirnov bound at α = 0.001 of the exact CDF, and d² has the exact mean n/4.
    #[test]
    fn table_sampler_follows_the_binomial_distribution() {
        for n in [TABLE_MIN_N, 5_000, 1_000_003] {
            let sampler = PairSampler::new(n);
            assert!(matches!(sampler, PairSampler::Table { .. }));
            let mut rng = ChaCha8Rng::seed_from_u64(n);
            let draws = 100_000;
            let mut sample: Vec<u64> = (0..draws).map(|_| sampler.sample(&mut rng)).collect();
            sample.sort_unstable();
            let exact = |a: u64| -> f64 {
                // Exact CDF from the normal approximation is not good enough at small n: sum the pmf.
                let ln_norm = statrs::function::gamma::ln_gamma(n as f64 + 1.0) - n as f64 * std::f64::consts::LN_2;
                let sd = (n as f64).sqrt() / 2.0;
                let start = ((n as f64 / 2.0 - 12.0 * sd).floor().max(0.0)) as u64;
                (start..=a)
                    .map(|k| {
                        (ln_norm
                            - statrs::function::gamma::ln_gamma(k as f64 + 1.0)
                            - statrs::function::gamma::ln_gamma((n - k) as f64 + 1.0))
                        .exp()
                    })
                    .sum()
            };
            let bound = 1.95 / (draws as f64).sqrt(); // KS critical value at α = 0.001
            for q in [0.05, 0.25, 0.5, 0.75, 0.95] {
                let a = sample[(q * draws as f64) as usize];
                let empirical = sample.partition_point(|&x| x <= a) as f64 / draws as f64;
                assert!((empirical - exact(a)).abs() < bound, "n = {n}, a = {a}: {empirical} vs {}", exact(a));
            }
            let mean_d2: f64 = sample.iter().map(|&a| (a as f64 - n as f64 / 2.0).powi(2)).sum::<f64>() / draws as f64;
            let sd_of_mean = ((n * (n - 1)) as f64 / 8.0 / draws as f64).sqrt();
            assert!((mean_d2 - n as f64 / 4.0).abs() < 4.5 * sd_of_mean, "n = {n}: mean d² {mean_d2}");
        }
    }

    /// Thousands of conditions: the simulation would exceed its budget, the generalised χ²
    /// answers instead, and under the null its p-value is not extreme.
    #[test]
    fn large_unbalanced_designs_use_the_generalised_chi2() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let tallies: Vec<PairTally> = (0..5000)
            .map(|k| {
                let n = rng.random_range(2..40u64);
                let wins_i = (0..n).filter(|_| rng.random::<bool>()).count() as u64;
                PairTally { i: k, j: k + 1, wins_i, wins_j: n - wins_i }
            })
            .collect();
        let agreement = coefficient_of_agreement(&tallies, 5001, &AgreementOptions::default()).unwrap();
        assert_eq!(agreement.method, AgreementMethod::Chi2Generalised);
        let p = agreement.p.unwrap().p;
        assert!(p > 0.001 && p < 0.999, "null data gave p = {p}");
        assert!(agreement.chi2.is_some() && agreement.df.is_some());
    }
}
