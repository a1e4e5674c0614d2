//! Issue 14, "calibrate what the analysis reports": on data simulated from a known
//! Bradley–Terry model, observer screening flags about α of the participants, and 95 % Wald and
//! bootstrap intervals cover the true log-worths and factor effects about 95 % of the time.
//!
//! The studies are the thesis design: eight conditions, the 2×2×2 factorial of `gi`, `cm`,
//! `ca`, 65 trials per participant, either the default study's anchored design (every condition
//! against LQ and HQ, and LQ–HQ: 13 pairs × 5) or every one of the 28 pairs once plus 37
//! repeats. The fast tests here use enough participant-tests and intervals that a real
//! miscalibration fails them (the normal approximation that screening used flagged 1.2–1.5× α
//! at α = 0.01, and 1.5× in the fast test's complete design; uncorrected percentile bootstrap
//! intervals covered 91–93 %); the `#[ignore]`d
//! ones are the larger runs whose numbers the issue reports (`cargo test --release -p
//! mrstudy-analysis --test calibration -- --ignored --nocapture`).

use mrstudy_analysis::analysis::{Analysis, Options, Screening, analyze_judgments};
use mrstudy_analysis::data::{ConditionTable, Judgment, Judgments};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// True factor effects (logit scale) of `gi`, `cm`, `ca`.
const EFFECTS: [f64; 3] = [0.54, -0.44, 0.86];
const TRIALS_PER_PARTICIPANT: usize = 65;
/// The normal quantile of a two-sided 95 % interval.
const Z_975: f64 = 1.959963984540054;

#[derive(Clone, Copy, Debug)]
enum Design {
    /// The default study's: every condition against LQ (0) and HQ (7), and LQ–HQ, 5 times each.
    Anchored,
    /// All 28 pairs once, plus 37 repeats of pairs drawn at random.
    Complete,
}

fn levels(condition: usize) -> [f64; 3] {
    [(condition & 1) as f64, ((condition >> 1) & 1) as f64, ((condition >> 2) & 1) as f64]
}

fn true_log_worth(condition: usize) -> f64 {
    levels(condition).iter().zip(EFFECTS).map(|(x, beta)| x * beta).sum()
}

fn pairs_of(design: Design, rng: &mut ChaCha8Rng) -> Vec<(usize, usize)> {
    match design {
        Design::Anchored => {
            let mut pairs: Vec<(usize, usize)> = (1..8).map(|c| (0, c)).chain((1..7).map(|c| (c, 7))).collect();
            let base = pairs.clone();
            for _ in 1..5 {
                pairs.extend_from_slice(&base);
            }
            pairs
        }
        Design::Complete => {
            let all: Vec<(usize, usize)> = (0..8).flat_map(|i| (i + 1..8).map(move |j| (i, j))).collect();
            let mut pairs = all.clone();
            while pairs.len() < TRIALS_PER_PARTICIPANT {
                pairs.push(all[rng.random_range(0..all.len())]);
            }
            pairs
        }
    }
}

/// A study of `n_participants` who all follow the true model, 65 trials each, sides at random.
fn study(design: Design, n_participants: usize, seed: u64) -> (Judgments, ConditionTable) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut rows = Vec::with_capacity(n_participants * TRIALS_PER_PARTICIPANT);
    for participant in 0..n_participants {
        for (a, b) in pairs_of(design, &mut rng) {
            let (left, right) = if rng.random::<bool>() { (a, b) } else { (b, a) };
            let p_left = 1.0 / (1.0 + (true_log_worth(right) - true_log_worth(left)).exp());
            rows.push(Judgment {
                participant: participant as u32,
                left: left as u32,
                right: right as u32,
                left_chosen: rng.random::<f64>() < p_left,
                count: 1,
                group: 0,
            });
        }
    }
    let conditions: Vec<String> = (0..8).map(|c| format!("C{c}")).collect();
    let judgments = Judgments {
        conditions: conditions.clone(),
        participants: (0..n_participants).map(|p| format!("p{p}")).collect(),
        groups: Vec::new(),
        rows,
    };
    let table = ConditionTable {
        conditions,
        factors: vec!["gi".into(), "cm".into(), "ca".into()],
        levels: (0..8).map(|c| levels(c).to_vec()).collect(),
    };
    (judgments, table)
}

/// Participant-tests and how many had p below 0.01 and below 0.05.
#[derive(Debug, Default)]
struct FalsePositives {
    tests: usize,
    below_01: usize,
    below_05: usize,
}

fn screening_false_positives(design: Design, data_sets: usize, participants: usize, seed: u64) -> FalsePositives {
    let mut counts = FalsePositives::default();
    for k in 0..data_sets {
        let (judgments, table) = study(design, participants, seed + k as u64);
        let options =
            Options { screening: Screening::On, agreement_simulations: 100, seed: k as u64, ..Options::default() };
        let analysis = analyze_judgments(&judgments, Some(&table), &options).unwrap();
        for observer in &analysis.observers.unwrap().participants {
            counts.tests += 1;
            counts.below_01 += usize::from(observer.p.p < 0.01);
            counts.below_05 += usize::from(observer.p.p < 0.05);
        }
    }
    counts
}

/// Asserts both rates lie in [0.5α, 1.5α].
fn assert_calibrated(design: Design, counts: &FalsePositives) {
    for (alpha, flagged) in [(0.01, counts.below_01), (0.05, counts.below_05)] {
        let rate = flagged as f64 / counts.tests as f64;
        println!("{design:?}: {flagged} of {} participant-tests below α = {alpha}: rate {rate:.4}", counts.tests);
        assert!(
            (0.5 * alpha..=1.5 * alpha).contains(&rate),
            "{design:?}: false-positive rate {rate:.4} at α = {alpha} ({flagged} of {})",
            counts.tests
        );
    }
}

/// 12 data sets × 250 participants = 3000 participant-tests per design: 30 expected at α = 0.01
/// (Poisson sd 5.5, so [15, 45] is ±2.7 sd) and 150 at α = 0.05 (sd 12, [75, 225] is ±6 sd).
/// The normal approximation this replaces flagged 46 (1.5 × α) in the complete design.
#[test]
fn observer_screening_flags_alpha_of_null_participants() {
    for design in [Design::Anchored, Design::Complete] {
        let counts = screening_false_positives(design, 12, 250, 1400);
        assert_calibrated(design, &counts);
    }
}

/// The size and more: 60 data sets × 200 participants (12 000 tests) per design.
#[test]
#[ignore]
fn observer_screening_false_positive_rate_large() {
    for design in [Design::Anchored, Design::Complete] {
        let counts = screening_false_positives(design, 60, 200, 90_000);
        assert_calibrated(design, &counts);
    }
}

/// Intervals that covered their truth, and how many there were, per kind.
#[derive(Debug, Default)]
struct Coverage {
    items: (usize, usize),
    factors: (usize, usize),
}

impl Coverage {
    fn add(slot: &mut (usize, usize), interval: [f64; 2], truth: f64) {
        slot.1 += 1;
        slot.0 += usize::from(interval[0] <= truth && truth <= interval[1]);
    }

    fn rate(slot: (usize, usize)) -> f64 {
        slot.0 as f64 / slot.1 as f64
    }
}

/// Wald (`estimate ± 1.96 se`) and, with `bootstrap > 0`, bootstrap coverage over `studies`
/// simulated studies. The reference is condition 0 (LQ, true log-worth 0).
fn coverage(design: Design, studies: usize, participants: usize, bootstrap: usize, seed: u64) -> (Coverage, Coverage) {
    let (mut wald, mut boot) = (Coverage::default(), Coverage::default());
    for k in 0..studies {
        let (judgments, table) = study(design, participants, seed + k as u64);
        let options = Options {
            screening: Screening::Off,
            agreement_simulations: 100,
            bootstrap,
            seed: seed + k as u64,
            ..Options::default()
        };
        let analysis: Analysis = analyze_judgments(&judgments, Some(&table), &options).unwrap();
        for (c, item) in analysis.items.iter().enumerate().skip(1) {
            let (estimate, se) = (item.log_worth.unwrap(), item.se.unwrap());
            Coverage::add(&mut wald.items, [estimate - Z_975 * se, estimate + Z_975 * se], true_log_worth(c));
            if let Some(ci) = item.ci {
                Coverage::add(&mut boot.items, ci, true_log_worth(c));
            }
        }
        for (f, covariate) in analysis.covariates.unwrap().iter().enumerate() {
            let (estimate, se) = (covariate.estimate, covariate.se);
            Coverage::add(&mut wald.factors, [estimate - Z_975 * se, estimate + Z_975 * se], EFFECTS[f]);
            if let Some(ci) = covariate.ci {
                Coverage::add(&mut boot.factors, ci, EFFECTS[f]);
            }
        }
    }
    (wald, boot)
}

fn assert_coverage(what: &str, coverage: &Coverage, low: f64, high: f64) {
    for (kind, slot) in [("log-worth", coverage.items), ("factor effect", coverage.factors)] {
        let rate = Coverage::rate(slot);
        println!("{what} {kind}: {} of {} intervals cover the truth: {rate:.4}", slot.0, slot.1);
        assert!((low..=high).contains(&rate), "{what} {kind} coverage {rate:.4} ({} of {})", slot.0, slot.1);
    }
}

/// Wald intervals: 400 studies × (7 log-worths, 3 effects). Binomial sd of a rate near 0.95 over
/// 2800 intervals is 0.004 (more with the correlation within a study), so [0.93, 0.97] is
/// about ±4 sd for the log-worths.
#[test]
fn wald_intervals_cover_the_truth() {
    let (wald, _) = coverage(Design::Anchored, 400, 30, 0, 7000);
    assert_coverage("Wald", &wald, 0.93, 0.97);
}

/// Bootstrap percentile intervals over participants, small enough for a debug build: 60
/// studies × 200 resamples. The band is wider than the 93–97 % because 420 correlated
/// intervals cannot tell 95 % from 93 % (sd ≈ 0.011); the `#[ignore]`d test below can. The
/// uncorrected percentile intervals covered 90.7 % here and fail it.
#[test]
fn bootstrap_intervals_cover_the_truth() {
    let (_, boot) = coverage(Design::Complete, 60, 30, 200, 8000);
    assert_coverage("bootstrap", &boot, 0.91, 0.985);
}

/// The bands over more studies: 400 studies × 500 resamples, both designs.
#[test]
#[ignore]
fn interval_coverage_large() {
    for (design, seed) in [(Design::Anchored, 20_000), (Design::Complete, 30_000)] {
        let (wald, boot) = coverage(design, 400, 30, 500, seed);
        assert_coverage(&format!("{design:?} Wald"), &wald, 0.93, 0.97);
        assert_coverage(&format!("{design:?} bootstrap"), &boot, 0.93, 0.97);
    }
}
