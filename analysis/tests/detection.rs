//! Detection ("real or rendered?") compared with R 4.2.2's `binom.test` (p-values and
//! Clopper–Pearson intervals), the exact power of that test computed in R, 2AFC d′ against
//! R's `qnorm` and the published table of Hacker & Ratcliff (1979) (checked with scipy 1.17.1),
//! and simulated observers: a condition that equals the ground truth comes out at chance.
//! Scripts: `tests/reference/detection.R`, `tests/reference/d_prime.py`.

use mrstudy_analysis::analysis::{Options, Screening};
use mrstudy_analysis::detection::{
    ALPHA, ALTERNATIVE_RATE, DetectionOptions, Verdict, binomial_test, binomial_test_power, clopper_pearson,
    d_prime_2afc, detection_rate,
};
use mrstudy_analysis::report::analyze_named;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;

/// Agreement required with R and scipy (relative for p-values, absolute otherwise).
const TOLERANCE: f64 = 1e-10;

fn load(name: &str) -> Value {
    let path = format!("{}/tests/reference/{name}.json", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

fn close(what: &str, actual: f64, expected: f64, tolerance: f64) {
    assert!(
        (actual - expected).abs() <= tolerance,
        "{what}: mrstudy {actual} vs reference {expected} (|Δ| = {:.2e})",
        (actual - expected).abs()
    );
}

#[test]
fn binomial_test_and_clopper_pearson_equal_r_binom_test() {
    let reference = load("detection");
    for case in reference["binom_test"].as_array().unwrap() {
        let (x, n, p0) = (case["x"].as_u64().unwrap(), case["n"].as_u64().unwrap(), case["p0"].as_f64().unwrap());
        let what = format!("binom.test({x}, {n}, {p0})");
        let expected = case["p"].as_f64().unwrap();
        close(&format!("{what} p"), binomial_test(x, n, p0).p, expected, TOLERANCE * expected.max(1e-300));
        let [low, high] = clopper_pearson(x, n, 0.95);
        close(&format!("{what} lower"), low, case["ci"][0].as_f64().unwrap(), TOLERANCE);
        close(&format!("{what} upper"), high, case["ci"][1].as_f64().unwrap(), TOLERANCE);
    }
}

#[test]
fn power_equals_r_sum_over_the_rejection_region() {
    let reference = load("detection");
    assert_eq!(reference["alpha"].as_f64(), Some(ALPHA));
    assert_eq!(reference["alternative_rate"].as_f64(), Some(ALTERNATIVE_RATE));
    for case in reference["power"].as_array().unwrap() {
        let n = case["n"].as_u64().unwrap();
        let power = binomial_test_power(n, 0.5, ALPHA, ALTERNATIVE_RATE);
        close(&format!("power at n = {n}"), power, case["power"].as_f64().unwrap(), TOLERANCE);
    }
}

#[test]
fn d_prime_equals_r_and_the_published_2afc_table() {
    let reference = load("detection");
    for case in reference["d_prime"].as_array().unwrap() {
        let (correct, trials) = (case["correct"].as_u64().unwrap(), case["trials"].as_u64().unwrap());
        let d = d_prime_2afc(correct, trials);
        close(&format!("d′ of {correct}/{trials}"), d.d_prime, case["d_prime"].as_f64().unwrap(), TOLERANCE);
        close(&format!("se of {correct}/{trials}"), d.se, case["se"].as_f64().unwrap(), TOLERANCE);
    }
    let table = load("d_prime");
    for case in table["computed"].as_array().unwrap() {
        // pc = k/1000 exactly, so no correction applies.
        let pc = case["pc"].as_f64().unwrap();
        let d = d_prime_2afc((pc * 1000.0).round() as u64, 1000);
        close(&format!("d′ at pc = {pc} (scipy)"), d.d_prime, case["d_prime"].as_f64().unwrap(), TOLERANCE);
    }
    for case in table["published"].as_array().unwrap() {
        let pc = case["pc"].as_f64().unwrap();
        let d = d_prime_2afc((pc * 100.0).round() as u64, 100);
        close(&format!("d′ at pc = {pc} (published, 3 decimals)"), d.d_prime, case["d_prime"].as_f64().unwrap(), 5e-4);
    }
}

/// A detection study's trials CSV: per participant, `per_condition` trials of each condition
/// against the ground truth, the ground truth chosen with the condition's probability.
fn simulated_csv(rates: &[(&str, f64)], participants: usize, per_condition: usize, rng: &mut ChaCha8Rng) -> String {
    let mut text = String::from("participant,left,right,chosen,scene_left,scene_right\n");
    for p in 0..participants {
        for &(condition, rate) in rates {
            for t in 0..per_condition {
                let scene = format!("s{}", t % 6);
                let ground_truth_chosen = rng.random::<f64>() < rate;
                let chosen = if ground_truth_chosen { "ground-truth" } else { condition };
                if rng.random::<bool>() {
                    text += &format!("p{p},ground-truth,{condition},{chosen},{scene},{scene}\n");
                } else {
                    text += &format!("p{p},{condition},ground-truth,{chosen},{scene},{scene}\n");
                }
            }
        }
    }
    text
}

/// A condition whose stimuli equal the ground truth leaves the observer at 50/50: over many
/// simulated studies the exact test rejects at most α of the time (it is conservative), and
/// with enough trials the condition is reported indistinguishable whenever the test does not
/// reject. A condition people see through comes out distinguishable.
#[test]
fn a_condition_equal_to_the_ground_truth_comes_out_at_chance() {
    let options = Options { screening: Screening::Off, ..Options::default() };
    let mut rng = ChaCha8Rng::seed_from_u64(15);
    let studies = 1000;
    let (mut rejections, mut indistinguishable, mut seen_through) = (0, 0, 0);
    for _ in 0..studies {
        // 20 participants × 10 trials = 200 trials per condition: power ≈ 1 against 0.75.
        let text = simulated_csv(&[("exact", 0.5), ("LQ", 0.8)], 20, 10, &mut rng);
        let report = analyze_named(&text, "sim.csv", None, None, &options).unwrap();
        assert!(report.preference.is_none(), "only detection trials");
        let detection = report.detection.unwrap();
        let exact = detection.conditions.iter().find(|c| c.condition == "exact").unwrap();
        let lq = detection.conditions.iter().find(|c| c.condition == "LQ").unwrap();
        assert_eq!((exact.trials, lq.trials), (200, 200));
        assert!(exact.power > 0.999, "power {}", exact.power);
        match exact.verdict {
            Verdict::Distinguishable => rejections += 1,
            Verdict::Indistinguishable => indistinguishable += 1,
            Verdict::Inconclusive => panic!("power {} is enough", exact.power),
        }
        seen_through += usize::from(lq.verdict == Verdict::Distinguishable && lq.rate > 0.5);
    }
    let false_positive_rate = rejections as f64 / studies as f64;
    assert!(false_positive_rate <= ALPHA, "false-positive rate {false_positive_rate}");
    assert_eq!(indistinguishable + rejections, studies);
    assert!(seen_through >= studies * 99 / 100, "{seen_through} of {studies}");

    // Many more small studies through the per-condition computation: the test's size is at
    // most α at every n (n = 30: the exact size is 0.0428).
    let mut rejections = 0;
    let studies = 20_000;
    for _ in 0..studies {
        let correct = (0..30).filter(|_| rng.random::<bool>()).count() as u64;
        let rate = detection_rate("exact", correct, 30, &DetectionOptions::default());
        rejections += usize::from(rate.verdict == Verdict::Distinguishable);
    }
    let false_positive_rate = rejections as f64 / studies as f64;
    assert!(false_positive_rate <= ALPHA, "false-positive rate {false_positive_rate} at n = 30");
}

#[test]
fn all_correct_none_correct_and_a_single_trial_stay_finite_and_say_why() {
    let options = Options { screening: Screening::Off, ..Options::default() };
    let text = "participant,left,right,chosen\n\
                p1,ground-truth,LQ,ground-truth\np1,LQ,ground-truth,ground-truth\np2,ground-truth,LQ,ground-truth\n\
                p1,ground-truth,HQ,HQ\np2,HQ,ground-truth,HQ\np2,ground-truth,HQ,HQ\n\
                p3,ground-truth,GI,GI\n";
    let report = analyze_named(text, "t.csv", None, None, &options).unwrap();
    let json = serde_json::to_string(&report).unwrap();
    assert!(!json.contains("null") && !json.contains("NaN") && !json.contains("inf"), "{json}");
    let detection = report.detection.unwrap();
    let by_name = |name: &str| detection.conditions.iter().find(|c| c.condition == name).unwrap();
    let lq = by_name("LQ");
    assert_eq!((lq.correct, lq.trials, lq.rate), (3, 3, 1.0));
    assert!(lq.d_prime.is_finite() && lq.d_prime > 0.0 && lq.ci[1] == 1.0);
    assert!(lq.notes[0].contains("pc = 0.833333"), "{:?}", lq.notes);
    let hq = by_name("HQ");
    assert_eq!((hq.correct, hq.rate, hq.ci[0]), (0, 0.0, 0.0));
    assert!((hq.d_prime + lq.d_prime).abs() < 1e-12);
    // Three trials cannot reach p ≤ 0.05 (p = 0.25), and have no power.
    assert_eq!((lq.verdict, hq.verdict), (Verdict::Inconclusive, Verdict::Inconclusive));
    assert_eq!(lq.verdict.describe(lq.power), "inconclusive (power 0.00)");
    let gi = by_name("GI");
    assert_eq!((gi.trials, gi.correct, gi.p.p, gi.d_prime), (1, 0, 1.0, 0.0));
    assert_eq!(detection.participants, 3);
}

#[test]
fn detection_table_names_the_method() {
    let options = Options { screening: Screening::Off, ..Options::default() };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let text = simulated_csv(&[("exact", 0.5), ("LQ", 0.9)], 10, 4, &mut rng);
    let report = analyze_named(&text, "sim.csv", None, None, &options).unwrap();
    let table = mrstudy_analysis::table::render_report(&report);
    assert!(table.starts_with("detection (real or rendered?): 80 judgments by 10 participants"), "{table}");
    assert!(table.contains("Clopper–Pearson") && table.contains("binom.test"), "{table}");
}
