//! Tests of the agreement statistics: u, χ² and the coefficient of consistence against R
//! (`tests/reference/agreement.R`), the generalised u and χ² against exact enumeration and
//! simulation.

use super::*;
use rand::Rng;
use serde_json::Value;
use statrs::distribution::{ContinuousCDF, DiscreteCDF, Normal};

/// Reference values written by `tests/reference/agreement.R` (R 4.2.2, base R).
const REFERENCE: &str = include_str!("../../tests/reference/agreement.json");

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
    assert!((simulated - exact).abs() <= MC_STANDARD_ERRORS * standard_error, "simulated {simulated} vs exact {exact}");
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
                let cycle = (beats[i][j] && beats[j][k] && beats[k][i]) || (beats[j][i] && beats[k][j] && beats[i][k]);
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
    let transitive: Vec<(usize, usize, bool)> = (0..6).flat_map(|i| (i + 1..6).map(move |j| (j, i, false))).collect();
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

/// Where no simulated numerator reaches the observed one, the Monte-Carlo p-value is reported as
/// the bound `p < 1/B` (`p_bound` in JSON), not as the number 1/(B+1).
#[test]
fn simulated_p_beyond_every_simulation_is_a_bound() {
    let pairs = [
        PairTally { i: 0, j: 1, wins_i: 10, wins_j: 0 },
        PairTally { i: 0, j: 2, wins_i: 12, wins_j: 0 },
        PairTally { i: 1, j: 2, wins_i: 8, wins_j: 0 },
    ];
    let options = AgreementOptions { simulations: 1000, seed: 3, continuity_correction: true };
    let agreement = coefficient_of_agreement(&pairs, 3, &options).unwrap();
    assert_eq!(agreement.method, AgreementMethod::Simulation);
    let p = agreement.p.unwrap();
    assert_eq!((p.bound, p.display()), (Some(1e-3), "< 1e-3".to_string()));
    let json = serde_json::to_value(&agreement).unwrap();
    assert_eq!(json["p_bound"], 1e-3);
}

/// The generalised u and χ² of unbalanced designs.
mod generalised {
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
