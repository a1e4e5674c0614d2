//! Tests of the JOD scale against pwcmp 07876b2 run by GNU Octave 7.3.0
//! (`tests/reference/pwcmp_jod.m`): scaling, bootstrap on the same resamples, outlier analysis,
//! and `analyze --scale jod` on pwcmp's ex3 data; the gradient against finite differences.

use super::*;

/// pwcmp 07876b2 under GNU Octave 7.3.0 (analysis/tests/reference/pwcmp_jod.m).
const REFERENCE: &str = include_str!("../../../tests/reference/jod_pwcmp.json");

struct Set {
    name: String,
    observers: Vec<Matrix>,
    jod: Vec<f64>,
    resamples: Vec<Vec<usize>>,
    low: Vec<f64>,
    high: Vec<f64>,
    covariance: Vec<f64>,
    l: Vec<f64>,
    dist_l: Vec<f64>,
}

fn numbers(value: &serde_json::Value) -> Vec<f64> {
    match value {
        serde_json::Value::Array(items) => items.iter().flat_map(numbers).collect(),
        serde_json::Value::Number(x) => vec![x.as_f64().unwrap()],
        other => panic!("not a number: {other}"),
    }
}

fn sets() -> Vec<Set> {
    let json: serde_json::Value = serde_json::from_str(REFERENCE).unwrap();
    json["sets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|set| {
            let n = set["conditions"].as_array().unwrap().len();
            let observers =
                set["matrices"].as_array().unwrap().iter().map(|m| Matrix { n, wins: numbers(m) }).collect();
            Set {
                name: set["name"].as_str().unwrap().to_string(),
                observers,
                jod: numbers(&set["jod"]),
                resamples: set["resamples"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|r| numbers(r).into_iter().map(|x| x as usize).collect())
                    .collect(),
                low: numbers(&set["jod_low"]),
                high: numbers(&set["jod_high"]),
                covariance: numbers(&set["jod_cov"]),
                l: numbers(&set["L"]),
                dist_l: numbers(&set["dist_L"]),
            }
        })
        .collect()
}

fn pooled(observers: &[Matrix]) -> Matrix {
    let mut sum = Matrix::zeros(observers[0].n);
    for o in observers {
        sum.add(o);
    }
    sum
}

fn assert_close(name: &str, what: &str, ours: &[f64], theirs: &[f64], tolerance: f64) {
    assert_eq!(ours.len(), theirs.len(), "{name} {what}");
    for (k, (a, b)) in ours.iter().zip(theirs).enumerate() {
        assert!((a - b).abs() < tolerance, "{name} {what}[{k}]: {a} against pwcmp's {b}");
    }
}

#[test]
fn scale_equals_pwcmp() {
    for set in sets() {
        let jod = scale(&pooled(&set.observers)).unwrap_or_else(|e| panic!("{}: {e}", set.name));
        assert_close(&set.name, "jod", &jod, &set.jod, 1e-3);
    }
}

#[test]
fn bootstrap_on_the_same_resamples_equals_pwcmp() {
    for set in sets() {
        let found = bootstrap(&set.observers, &set.resamples, 0.05).unwrap();
        assert_eq!(found.failed, 0);
        assert_close(&set.name, "jod_low", &found.low, &set.low, 1e-3);
        assert_close(&set.name, "jod_high", &found.high, &set.high, 1e-3);
        assert_close(&set.name, "jod_cov", &found.covariance, &set.covariance, 1e-4);
    }
}

#[test]
fn outlier_analysis_equals_pwcmp() {
    for set in sets() {
        let groups = vec![set.observers.iter().cloned().map(Some).collect()];
        let (l, dist) = outliers(&groups).unwrap();
        assert_close(&set.name, "L", &l, &set.l, 1e-4);
        assert_close(&set.name, "dist_L", &dist, &set.dist_l, 1e-3);
    }
}

#[test]
fn gradient_is_the_objectives() {
    let set = &sets()[6];
    let problem = Problem::new(&pooled(&set.observers));
    let q: Vec<f64> = (0..problem.n).map(|k| 0.3 * k as f64 - 0.5).collect();
    let mut gradient = vec![0.0; problem.n];
    problem.evaluate(&q, &mut gradient);
    let mut scratch = vec![0.0; problem.n];
    for k in 0..problem.n {
        let h = 1e-6;
        let (mut up, mut down) = (q.clone(), q.clone());
        up[k] += h;
        down[k] -= h;
        let numeric = (problem.evaluate(&up, &mut scratch) - problem.evaluate(&down, &mut scratch)) / (2.0 * h);
        assert!((numeric - gradient[k]).abs() < 1e-5 * (1.0 + numeric.abs()), "{k}: {numeric} against {}", gradient[k]);
    }
}

#[test]
fn one_jod_is_75_percent() {
    let z: f64 = 1.0 / SIGMA;
    let cdf = 0.5 * erfc(-z / std::f64::consts::SQRT_2);
    assert!((cdf - 0.75).abs() < 1e-4, "{cdf}");
}

#[test]
fn even_ties_as_half_votes_equal_their_integer_matrix() {
    // two ties in a pair are one vote each way: the same matrix as pwcmp scales
    let mut halves = Matrix::zeros(3);
    let mut whole = Matrix::zeros(3);
    for (i, j, w) in [(0, 1, 3.0), (1, 0, 1.0), (1, 2, 2.0), (2, 1, 2.0), (0, 2, 4.0), (2, 0, 1.0)] {
        whole.wins[i * 3 + j] = w;
        halves.wins[i * 3 + j] = w;
    }
    // two ties between 0 and 1: half a vote each way twice
    halves.wins[1] -= 1.0;
    halves.wins[3] -= 1.0;
    halves.wins[1] += 0.5 + 0.5;
    halves.wins[3] += 0.5 + 0.5;
    assert_eq!(scale(&halves).unwrap(), scale(&whole).unwrap());
}

#[test]
fn quantile_is_matlabs() {
    let x = [1.0, 2.0, 3.0, 4.0, 10.0];
    // Octave 7.3.0: quantile(x, 0.25) = 1.75, prctile(x, 2.5) = 1, quantile(x, 0.75) = 5.5
    assert_eq!(quantile_method5(&x, 0.25), 1.75);
    assert_eq!(quantile_method5(&x, 0.025), 1.0);
    assert_eq!(quantile_method5(&x, 0.75), 5.5);
}

/// `mrstudy analyze --scale jod` on pwcmp's ex3 data (all scenes) written as a trials CSV: the
/// items' `jod` and the participants' dist_L are pwcmp's.
#[test]
fn analyze_scale_jod_reports_pwcmps_values() {
    let set = sets().into_iter().find(|s| s.name == "ex3/all").unwrap();
    let json: serde_json::Value = serde_json::from_str(REFERENCE).unwrap();
    let names: Vec<String> =
        json["sets"][0]["conditions"].as_array().unwrap().iter().map(|c| c.as_str().unwrap().to_string()).collect();
    let participants: Vec<String> =
        json["sets"][0]["observers"].as_array().unwrap().iter().map(|c| c.as_str().unwrap().to_string()).collect();
    let mut csv = String::from("participant,left,right,chosen,count\n");
    for (o, m) in set.observers.iter().enumerate() {
        for i in 0..m.n {
            for j in 0..m.n {
                if m.get(i, j) > 0.0 {
                    csv += &format!("{},{},{},{},{}\n", participants[o], names[i], names[j], names[i], m.get(i, j));
                }
            }
        }
    }
    let options = crate::analysis::Options {
        scale: crate::analysis::Scale::Jod,
        screening: crate::analysis::Screening::Off,
        bootstrap: 20,
        ..crate::analysis::Options::default()
    };
    let analysis = crate::analysis::analyze(&csv, None, &options).unwrap();
    assert_eq!(analysis.items.iter().map(|i| i.condition.clone()).collect::<Vec<_>>(), names);
    let jod: Vec<f64> = analysis.items.iter().map(|i| i.jod.unwrap()).collect();
    assert_close("analyze ex3/all", "jod", &jod, &set.jod, 1e-3);
    let section = analysis.jod_scale.as_ref().unwrap();
    let dist: Vec<f64> =
        participants.iter().map(|p| section.observers.iter().find(|o| &o.participant == p).unwrap().dist_l).collect();
    assert_close("analyze ex3/all", "dist_L", &dist, &set.dist_l, 1e-3);
    assert_eq!(section.outliers.len(), set.dist_l.iter().filter(|&&d| d > 1.5).count());
    assert_eq!(section.ranking.len(), names.len() - 1);
    assert!(section.ranking.iter().all(|n| n.difference >= 0.0 && n.p.is_some()));
    for item in &analysis.items {
        let [low, high] = item.jod_ci.unwrap();
        assert!(low <= item.jod.unwrap() + 1e-9 && item.jod.unwrap() <= high + 1e-9, "{item:?}");
    }
    let text = serde_json::to_string(&analysis).unwrap();
    assert!(text.contains("\"jod\":") && text.contains("\"jod_ci\":") && text.contains("\"jod_scale\":"));
}

/// `analyze --scale jod --bootstrap N --plot-dir DIR` draws `jod-ranking.svg`: the conditions by
/// JOD, highest first, each with its difference from the next lower one marked significant or
/// not as `jod_scale.ranking` says.
#[test]
fn the_ranking_plot_orders_by_jod_and_marks_each_neighbouring_difference() {
    let truth = [("A", 0.0), ("B", 0.0), ("C", 1.5), ("D", 3.0)];
    let mut csv = String::from("participant,left,right,chosen,count\n");
    for p in 0..10 {
        for (i, &(a, qa)) in truth.iter().enumerate() {
            for (j, &(b, qb)) in truth.iter().enumerate().skip(i + 1) {
                let share = 0.5 * statrs::function::erf::erfc(-(qa - qb) / SIGMA / std::f64::consts::SQRT_2);
                let jitter = ((p * 7 + i * 3 + j) % 5) as f64 / 5.0;
                let wins = ((6.0 * share + 2.0 * jitter - 0.5).floor().max(0.0) as u32).min(6);
                csv += &format!("p{p},{a},{b},{a},{wins}\np{p},{a},{b},{b},{}\n", 6 - wins);
            }
        }
    }
    let csv = csv.lines().filter(|line| !line.ends_with(",0")).collect::<Vec<_>>().join("\n") + "\n";
    let options = crate::analysis::Options {
        scale: crate::analysis::Scale::Jod,
        screening: crate::analysis::Screening::Off,
        bootstrap: 100,
        ..crate::analysis::Options::default()
    };
    let drawings = crate::command::Drawings { scatter: true, ..crate::command::Drawings::default() };
    let printed = crate::command::analyze_files((&csv, "t.csv"), None, None, &options, true, drawings).unwrap();
    let [(name, svg)] = &printed.scatter_plots[..] else { panic!("{:?}", printed.scatter_plots) };
    assert_eq!(name, "jod-ranking.svg");
    let analysis = crate::analysis::analyze(&csv, None, &options).unwrap();
    let section = analysis.jod_scale.as_ref().unwrap();
    // rows top to bottom: highest JOD first
    let mut by_jod: Vec<(&str, f64)> = analysis.items.iter().map(|i| (i.condition.as_str(), i.jod.unwrap())).collect();
    by_jod.sort_by(|a, b| b.1.total_cmp(&a.1));
    let at =
        |condition: &str| svg.find(&format!(">{condition}</text>")).unwrap_or_else(|| panic!("no row {condition}"));
    for pair in by_jod.windows(2) {
        assert!(at(pair[0].0) < at(pair[1].0), "{} is drawn below {}", pair[0].0, pair[1].0);
    }
    let significant = section.ranking.iter().filter(|n| n.significant == Some(true)).count();
    let not_significant = section.ranking.iter().filter(|n| n.significant == Some(false)).count();
    assert!(significant >= 2 && not_significant >= 1, "{:?}", section.ranking);
    assert_eq!(svg.matches("  significant").count(), significant, "{svg}");
    assert_eq!(svg.matches("  n.s.").count(), not_significant);
    assert!(!svg.contains("NaN") && !svg.contains("inf"));
    // without --scale jod (and without --stimuli) the folder has nothing to hold
    let bt = crate::analysis::Options { scale: crate::analysis::Scale::Bt, ..options };
    let refused = crate::command::analyze_files((&csv, "t.csv"), None, None, &bt, true, drawings).unwrap_err();
    assert!(refused.to_string().contains("--scale jod"), "{refused}");
}
