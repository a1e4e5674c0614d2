//! An analysis that never goes blank: every prefix (1, 2, …, 200 judgments) of a simulated
//! export of the default web survey (`studies/web-survey.toml`: 8 conditions of the 2³ design,
//! the anchored pairs, 5 repetitions, 6 scene configurations drawn two different ones per
//! trial) is analysed with its conditions and its stimulus metrics without an error, and no
//! number printed (table or JSON) is NaN or infinite. Early in data collection most of the 48
//! stimuli have no judgment, one or only wins or only losses, which is exactly when a
//! researcher checks a pilot.
//!
//! Also the regression case of issue 44: a stimulus model with one-sided and unjudged stimuli
//! on which the old `fit_firth` (a step taken when the line search gave up, convergence judged
//! on a shrunken step) stopped with "did not converge in 200 iterations".

use mrstudy_analysis::analysis::Options;
use mrstudy_analysis::fit::Method;
use mrstudy_analysis::report::{Report, analyze_named};
use mrstudy_analysis::stimulus_metrics::{Level, Metric, Region};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;

/// The web survey's conditions with their factor levels (gi, cm, ca).
const CONDITIONS: [(&str, [u8; 3]); 8] = [
    ("LQ", [0, 0, 0]),
    ("GI", [1, 0, 0]),
    ("CM", [0, 1, 0]),
    ("CA", [0, 0, 1]),
    ("GI+CM", [1, 1, 0]),
    ("GI+CA", [1, 0, 1]),
    ("CM+CA", [0, 1, 1]),
    ("HQ", [1, 1, 1]),
];
const SCENES: usize = 6;
const REPETITIONS: usize = 5;
/// Judgments in the longest prefix.
const PREFIXES: usize = 200;

/// The anchored pairs of the web survey: LQ–HQ, then each other condition against LQ and HQ
/// (13 pairs), as condition indices.
fn anchored_pairs() -> Vec<(usize, usize)> {
    let mut pairs = vec![(0, 7)];
    for c in 1..7 {
        pairs.push((0, c));
        pairs.push((c, 7));
    }
    pairs
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller; 1 − u keeps the logarithm finite.
    let (u, v): (f64, f64) = (rng.random(), rng.random());
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn conditions_csv() -> String {
    let mut text = String::from("condition,gi,cm,ca\n");
    for (name, [gi, cm, ca]) in CONDITIONS {
        text += &format!("{name},{gi},{cm},{ca}\n");
    }
    text
}

/// The study's true log-worth of each stimulus (scene × condition): the thesis's factor effects
/// (gi 0.54, cm −0.44, ca 0.86) plus a deviation per stimulus; and its metrics CSV, the errors
/// falling with the log-worth, with noise.
fn stimuli(rng: &mut ChaCha8Rng) -> (Vec<[f64; 8]>, String) {
    let mut truth = vec![[0.0; 8]; SCENES];
    let mut csv = String::from("stimulus,scene,condition,metric,region,value\n");
    for (scene, row) in truth.iter_mut().enumerate() {
        for (c, (name, [gi, cm, ca])) in CONDITIONS.iter().enumerate() {
            let lambda = 0.54 * f64::from(*gi) - 0.44 * f64::from(*cm) + 0.86 * f64::from(*ca) + 0.3 * normal(rng);
            row[c] = lambda;
            for metric in Metric::ALL {
                for region in Region::ALL {
                    if metric == Metric::RenderMs && region != Region::Image {
                        continue;
                    }
                    let error = (0.4 - 0.1 * lambda + 0.05 * normal(rng)).clamp(0.01, 0.99);
                    let value = match metric {
                        Metric::Ssim => 1.0 - error,
                        Metric::RenderMs => 4.0 + 9.0 * f64::from(*gi) + rng.random::<f64>(),
                        Metric::Ciede2000Mean | Metric::Ciede2000P95 => 20.0 * error,
                        _ => error,
                    };
                    csv += &format!(
                        "h{scene}{c},survey-{},{name},{},{},{value}\n",
                        scene + 1,
                        metric.name(),
                        region.name()
                    );
                }
            }
        }
    }
    (truth, csv)
}

/// One judgment of the export: participant, left and right (condition, scene) and whether the
/// left was chosen.
#[derive(Clone, Copy)]
struct Row {
    participant: usize,
    trial: usize,
    left: (usize, usize),
    right: (usize, usize),
    left_chosen: bool,
}

/// One participant's 65 trials as the server schedules them (each pair 5 times, sides
/// balanced, two different scene configurations drawn per trial, random order), answered by a
/// Bradley–Terry observer with a taste of their own (sd 0.5 per condition) and 5 % lapses.
fn participant(p: usize, truth: &[[f64; 8]], rng: &mut ChaCha8Rng) -> Vec<Row> {
    let taste: Vec<f64> = (0..CONDITIONS.len()).map(|_| 0.5 * normal(rng)).collect();
    let mut planned = Vec::new();
    for (first, second) in anchored_pairs() {
        let first_left_count = REPETITIONS / 2 + usize::from(rng.random::<bool>());
        for rep in 0..REPETITIONS {
            let (left, right) = if rep < first_left_count { (first, second) } else { (second, first) };
            let left_scene = rng.random_range(0..SCENES);
            let right_scene = (left_scene + 1 + rng.random_range(0..SCENES - 1)) % SCENES;
            planned.push(((left, left_scene), (right, right_scene)));
        }
    }
    for k in (1..planned.len()).rev() {
        let other = rng.random_range(0..=k);
        planned.swap(k, other);
    }
    planned
        .into_iter()
        .enumerate()
        .map(|(trial, (left, right))| {
            let worth = |(c, s): (usize, usize)| truth[s][c] + taste[c];
            let p_left = 1.0 / (1.0 + (worth(right) - worth(left)).exp());
            let left_chosen =
                if rng.random::<f64>() < 0.05 { rng.random::<bool>() } else { rng.random::<f64>() < p_left };
            Row { participant: p, trial, left, right, left_chosen }
        })
        .collect()
}

/// The trials CSV as `mrstudy export` writes it (the columns the analysis reads, in its
/// order: participants in the order they joined, trials in schedule order).
fn export(rows: &[Row]) -> String {
    let mut sorted = rows.to_vec();
    sorted.sort_by_key(|row| (row.participant, row.trial));
    let mut text = String::from(
        "study,participant,trial,left,right,chosen,scene_left,scene_right,completed,status,pilot,excluded,too_fast\n",
    );
    for row in &sorted {
        let (left, right) = (CONDITIONS[row.left.0].0, CONDITIONS[row.right.0].0);
        let chosen = if row.left_chosen { left } else { right };
        text += &format!(
            "web-survey,p{},{},{left},{right},{chosen},survey-{},survey-{},0,started,false,false,false\n",
            row.participant + 1,
            row.trial + 1,
            row.left.1 + 1,
            row.right.1 + 1
        );
    }
    text
}

/// Every JSON value is a finite number, a string, a boolean, an array or an object: serde_json
/// writes a NaN or an infinity as `null`, and the Analysis JSON has no `null` otherwise
/// (absent sections are omitted).
fn assert_no_null(value: &Value, path: &str, context: &str) {
    match value {
        Value::Null => panic!("{context}: `{path}` is null (a NaN or infinity)"),
        Value::Number(number) => assert!(number.as_f64().is_some_and(f64::is_finite), "{context}: `{path}`"),
        Value::Array(values) => {
            for (k, v) in values.iter().enumerate() {
                assert_no_null(v, &format!("{path}[{k}]"), context);
            }
        }
        Value::Object(map) => {
            for (k, v) in map {
                assert_no_null(v, &format!("{path}.{k}"), context);
            }
        }
        Value::String(_) | Value::Bool(_) => {}
    }
}

/// No word of the table is a non-finite number as Rust or C writes it.
fn assert_table_finite(table: &str, context: &str) {
    for word in table.split(|c: char| c.is_whitespace() || ",;:()[]=".contains(c)) {
        let word = word.trim_start_matches(['-', '+', '−']).to_ascii_lowercase();
        assert!(!matches!(word.as_str(), "nan" | "inf" | "infinity"), "{context}: `{word}` in\n{table}");
    }
}

fn analyse(trials: &str, metrics: &str, options: &Options, context: &str) -> Report {
    let conditions = conditions_csv();
    let report = analyze_named(
        trials,
        "trials.csv",
        Some((&conditions, "conditions.csv")),
        Some((metrics, "stimuli.csv")),
        options,
    )
    .unwrap_or_else(|error| panic!("{context}: {error}"));
    let json = serde_json::to_value(&report).unwrap();
    assert_no_null(&json, "", context);
    assert_table_finite(&mrstudy_analysis::table::render_report(&report), context);
    report
}

/// The options of `mrstudy analyze` and the live analysis (screening on, agreement simulated),
/// with the shortest bootstrap that still runs both bootstraps (log-worths and correlations)
/// on every prefix: a replicate of the stimulus model is a Firth fit of up to 47 parameters,
/// about 0.2 s in a debug build.
fn options() -> Options {
    Options { bootstrap: 2, agreement_simulations: 200, ..Options::default() }
}

/// The simulated study: its metrics CSV, and the judgments of four participants one after
/// another and of eight at once (a browser walkthrough, a class), in the order they were
/// answered.
fn simulated_exports() -> (String, Vec<Row>, Vec<Row>) {
    let mut rng = ChaCha8Rng::seed_from_u64(44);
    let (truth, metrics) = stimuli(&mut rng);
    let sequential: Vec<Row> = (0..4).flat_map(|p| participant(p, &truth, &mut rng)).collect();
    let concurrent: Vec<Vec<Row>> = (0..8).map(|p| participant(p, &truth, &mut rng)).collect();
    let interleaved: Vec<Row> = (0..65).flat_map(|t| concurrent.iter().map(move |rows| rows[t])).collect();
    (metrics, sequential, interleaved)
}

#[test]
fn every_prefix_of_a_default_survey_export_is_analysed_with_its_stimulus_metrics() {
    let (metrics, sequential, interleaved) = simulated_exports();
    let options = options();
    let mut stimulus_level = 0;
    for (name, rows) in [("one participant after another", &sequential), ("eight at once", &interleaved)] {
        for n in 1..=PREFIXES {
            let report = analyse(&export(&rows[..n]), &metrics, &options, &format!("{name}, first {n} judgments"));
            let section = report.metrics.as_ref().expect("a metrics section on every prefix");
            if section.level == Level::Stimulus {
                stimulus_level += 1;
                // The stimuli not shown yet are named as left out.
                let unjudged = 48 - section.items.len();
                let have = if unjudged == 1 { "has" } else { "have" };
                let note =
                    format!("{unjudged} of the metrics CSV's stimuli of these conditions {have} no judgment yet");
                assert!(
                    unjudged == 0 || section.warnings.iter().any(|w| w.starts_with(&note)),
                    "{name}, {n}: {:?}",
                    section.warnings
                );
            }
        }
    }
    // The stimulus model itself is exercised, not only the fallback to conditions.
    assert!(stimulus_level > 20, "{stimulus_level} prefixes were analysed per stimulus");
}

/// Issue 44: 186 judgments of eight participants at once connect all 48 stimuli, many judged
/// once or twice and only winning or only losing. The old `fit_firth` circled the maximum of
/// the penalised likelihood and the whole analysis failed with "the stimulus model of the
/// metrics analysis did not converge in 200 iterations (last change 3.568e-4)"; now the
/// stimulus model is Firth's estimate, said in `warnings` with the one-sided stimuli.
#[test]
fn a_stimulus_model_with_one_sided_stimuli_converges() {
    let (metrics, _, interleaved) = simulated_exports();
    let report = analyse(&export(&interleaved[..186]), &metrics, &options(), "186 judgments");
    let section = report.metrics.as_ref().unwrap();
    assert_eq!(section.level, Level::Stimulus, "{}", section.level_reason);
    assert_eq!(section.method, Method::Firth);
    assert!(section.items.iter().all(|item| item.log_worth.is_some_and(|l| l.abs() < 10.0)));
    let separation = section.warnings.iter().find(|w| w.starts_with("separation among the stimuli (")).unwrap();
    assert!(separation.contains(" only won (`survey-") && separation.contains(" only lost (`survey-"), "{separation}");
    assert!(report.preference.as_ref().unwrap().not_estimable.is_empty());
}

/// The regression of issue 44 on a stimulus model small enough to be exact: seven stimuli,
/// most judged once or twice and only winning or only losing, and an eighth in the metrics
/// CSV that nobody judged yet. The old `fit_firth` took every step that did not lower the
/// penalised likelihood by more than 1e-12 relative and circled its maximum: "the stimulus
/// model of the metrics analysis did not converge in 200 iterations".
#[test]
fn a_stimulus_model_with_one_sided_and_unjudged_stimuli_is_fitted() {
    let mut trials = String::from("participant,left,right,chosen,scene_left,scene_right\n");
    // Stimulus k is scene `s{k}` (so the model's order is k) under a condition that differs
    // between the two sides of each trial; (k, l, wins of k, wins of l) as in
    // `fit::tests::firth_converges_with_one_sided_stimuli_of_one_judgment`.
    let condition = ["A", "B", "B", "A", "A", "C", "B"];
    let tallies = [(0, 1, 6, 4), (0, 2, 1, 0), (1, 3, 0, 1), (2, 4, 1, 0), (3, 5, 0, 2), (1, 5, 1, 0), (0, 6, 0, 1)];
    for (n, &(k, l, wins_k, wins_l)) in tallies.iter().enumerate() {
        for judgment in 0..wins_k + wins_l {
            let chosen = if judgment < wins_k { condition[k] } else { condition[l] };
            let participant = (n + judgment) % 3;
            trials += &format!("p{participant},{},{},{chosen},s{k},s{l}\n", condition[k], condition[l]);
        }
    }
    let mut metrics = String::from("stimulus,scene,condition,metric,region,value\n");
    for (k, condition) in condition.iter().chain(["A"].iter()).enumerate() {
        metrics += &format!("h{k},s{k},{condition},flip_mean,image,{}\n", 0.1 + 0.07 * k as f64);
    }
    let report = analyze_named(&trials, "t.csv", None, Some((&metrics, "m.csv")), &options())
        .unwrap_or_else(|error| panic!("{error}"));
    let section = report.metrics.as_ref().unwrap();
    assert_eq!(section.level, Level::Stimulus, "{}", section.level_reason);
    assert_eq!((section.method, section.items.len()), (Method::Firth, 7));
    assert!(section.items.iter().all(|item| item.log_worth.is_some_and(|l| l.abs() < 10.0)));
    assert!(
        section.warnings.iter().any(|w| w.starts_with(
            "1 of the metrics CSV's stimuli of these conditions has no judgment yet and is left out of the stimulus model: `s7/A`"
        )),
        "{:?}",
        section.warnings
    );
    assert!(section.warnings.iter().any(|w| w.starts_with("separation among the stimuli (")), "{:?}", section.warnings);
    assert_eq!(section.correlations.len(), 1);
}
