//! Tests of the Davidson tie model against a direct SciPy fit (`tests/reference/davidson.py`),
//! against the Bradley–Terry item fit without ties, and through `analyze` on a CSV with ties.

use super::*;
use crate::design::PairTally;
use crate::fit::{FitOptions, ModelMatrix};

/// SciPy 1.17.1 direct maximum likelihood (analysis/tests/reference/davidson.py).
const REFERENCE: &str = include_str!("../../../tests/reference/davidson.json");

fn numbers(value: &serde_json::Value) -> Vec<f64> {
    value.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

#[test]
fn equals_a_direct_scipy_fit() {
    let json: serde_json::Value = serde_json::from_str(REFERENCE).unwrap();
    for set in json["sets"].as_array().unwrap() {
        let pairs: Vec<TiePair> = set["pairs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                let p = numbers(p);
                TiePair { i: p[0] as usize, j: p[1] as usize, wins_i: p[2], wins_j: p[3], ties: p[4] }
            })
            .collect();
        let n = set["conditions"].as_u64().unwrap() as usize;
        let reference = set["reference"].as_u64().unwrap() as usize;
        let fitted = fit(n, &pairs, reference, 1e-12).unwrap();
        let name = set["name"].as_str().unwrap();
        for (what, ours, theirs) in
            [("log_worth", &fitted.log_worth, numbers(&set["log_worth"])), ("se", &fitted.se, numbers(&set["se"]))]
        {
            for (a, b) in ours.iter().zip(&theirs) {
                assert!((a - b).abs() < 1e-6, "{name} {what}: {a} against SciPy's {b}");
            }
        }
        assert!((fitted.nu - set["nu"].as_f64().unwrap()).abs() < 1e-6, "{name} nu {}", fitted.nu);
        assert!((fitted.nu_se.unwrap() - set["nu_se"].as_f64().unwrap()).abs() < 1e-6, "{name} nu_se");
        let kernel = set["log_likelihood_kernel"].as_f64().unwrap();
        assert!((fitted.log_likelihood - kernel).abs() < 1e-6, "{name}: {} against {kernel}", fitted.log_likelihood);
    }
}

#[test]
fn without_ties_it_is_bradley_terry() {
    let counts = [(0, 1, 12, 8), (0, 2, 5, 15), (1, 2, 9, 11), (1, 3, 14, 6), (2, 3, 17, 3), (0, 3, 10, 10)];
    let pairs: Vec<TiePair> =
        counts.iter().map(|&(i, j, a, b)| TiePair { i, j, wins_i: a as f64, wins_j: b as f64, ties: 0.0 }).collect();
    let davidson = fit(4, &pairs, 0, 1e-12).unwrap();
    assert_eq!((davidson.nu, davidson.nu_se), (0.0, None));
    let tallies: Vec<PairTally> = counts.iter().map(|&(i, j, a, b)| PairTally { i, j, wins_i: a, wins_j: b }).collect();
    let x = ModelMatrix::items(4, &[0, 1, 2, 3], 0);
    let bt = crate::fit::fit_ml(&tallies, &x, None, FitOptions { tolerance: 1e-12, ..FitOptions::default() }).unwrap();
    for c in 0..4 {
        let lambda = x.predict(c, &bt.beta);
        let se = bt.variance_of(&x.rows[c]).sqrt();
        assert!((davidson.log_worth[c] - lambda).abs() < 1e-9, "{c}: {} against {lambda}", davidson.log_worth[c]);
        assert!((davidson.se[c] - se).abs() < 1e-9, "{c}: se {} against {se}", davidson.se[c]);
    }
}

#[test]
fn never_winning_nor_tying_is_separation_and_gaps_are_refused() {
    let pairs = [
        TiePair { i: 0, j: 1, wins_i: 5.0, wins_j: 0.0, ties: 0.0 },
        TiePair { i: 1, j: 2, wins_i: 3.0, wins_j: 2.0, ties: 1.0 },
    ];
    assert_eq!(fit(3, &pairs, 0, 1e-10), Err(DavidsonFailure::Separation));
    assert_eq!(fit(4, &pairs, 0, 1e-10), Err(DavidsonFailure::Disconnected { condition: 3 }));
}

/// `mrstudy analyze` on a trials CSV with `chosen = tie` rows: the item model is the BT fit of
/// the rows without ties, and the `davidson` section is the Davidson fit of all of them.
#[test]
fn analyze_reports_davidson_beside_bradley_terry_without_ties() {
    let mut with_ties = String::from("participant,left,right,chosen\n");
    let mut without = with_ties.clone();
    let counts = [("A", "B", 12, 8, 5), ("A", "C", 5, 15, 3), ("B", "C", 9, 11, 6)];
    for (k, &(l, r, a, b, t)) in counts.iter().enumerate() {
        for (chosen, times) in [(l, a), (r, b), ("tie", t)] {
            for n in 0..times {
                let row = format!("p{},{l},{r},{chosen}\n", (k + n) % 4);
                with_ties += &row;
                if chosen != "tie" {
                    without += &row;
                }
            }
        }
    }
    let options = crate::analysis::Options {
        screening: crate::analysis::Screening::Off,
        scale: crate::analysis::Scale::Jod,
        ..crate::analysis::Options::default()
    };
    let tied = crate::analysis::analyze(&with_ties, None, &options).unwrap();
    let plain = crate::analysis::analyze(&without, None, &options).unwrap();
    for (a, b) in tied.items.iter().zip(&plain.items) {
        assert_eq!(a.log_worth, b.log_worth, "BT on the judgments without ties");
    }
    assert!(plain.davidson.is_none());
    let section = tied.davidson.as_ref().unwrap();
    assert_eq!(section.ties, 14);
    let pairs: Vec<TiePair> = [(0, 1, 12.0, 8.0, 5.0), (0, 2, 5.0, 15.0, 3.0), (1, 2, 9.0, 11.0, 6.0)]
        .iter()
        .map(|&(i, j, wins_i, wins_j, ties)| TiePair { i, j, wins_i, wins_j, ties })
        .collect();
    let direct = fit(3, &pairs, 0, 1e-10).unwrap();
    for (item, lambda) in section.items.iter().zip(&direct.log_worth) {
        assert!((item.log_worth.unwrap() - lambda).abs() < 1e-9);
    }
    assert!((section.nu - direct.nu).abs() < 1e-9 && section.nu > 0.0);
    // JOD: ties are half a vote each way, so the JOD differ from those without ties
    assert_ne!(tied.items[1].jod, plain.items[1].jod);
    assert_eq!(tied.jod_scale.as_ref().unwrap().ties, 14);
    let json = serde_json::to_string(&tied).unwrap();
    assert!(json.contains("\"davidson\":{\"items\":[{\"condition\":\"A\",\"log_worth\":0.0,\"se\":0.0}"), "{json}");
}

/// `--group-by`: each group's analysis has its own `davidson` section, the Davidson fit of that
/// group's judgments and ties alone; a group without ties has none.
#[test]
fn each_group_has_the_davidson_fit_of_its_own_judgments() {
    let groups = [
        ("f", [("A", "B", 12, 8, 5), ("A", "C", 5, 15, 3), ("B", "C", 9, 11, 6)]),
        ("m", [("A", "B", 4, 14, 2), ("A", "C", 10, 6, 7), ("B", "C", 13, 5, 1)]),
        ("x", [("A", "B", 6, 5, 0), ("A", "C", 4, 7, 0), ("B", "C", 5, 6, 0)]),
    ];
    let mut csv = String::from("participant,left,right,chosen,gender\n");
    for (g, (gender, counts)) in groups.iter().enumerate() {
        for (k, &(l, r, a, b, t)) in counts.iter().enumerate() {
            for (chosen, times) in [(l, a), (r, b), ("tie", t)] {
                for n in 0..times {
                    csv += &format!("{gender}{},{l},{r},{chosen},{gender}\n", (k + n + g) % 3);
                }
            }
        }
    }
    let options = crate::analysis::Options {
        screening: crate::analysis::Screening::Off,
        group_by: Some("gender".into()),
        ..crate::analysis::Options::default()
    };
    let analysis = crate::analysis::analyze(&csv, None, &options).unwrap();
    let groups_found = analysis.groups.as_ref().unwrap();
    for (gender, counts) in &groups[..2] {
        let pairs: Vec<TiePair> = [(0, 1), (0, 2), (1, 2)]
            .iter()
            .zip(counts)
            .map(|(&(i, j), &(_, _, a, b, t))| TiePair { i, j, wins_i: a as f64, wins_j: b as f64, ties: t as f64 })
            .collect();
        let direct = fit(3, &pairs, 0, 1e-10).unwrap();
        let section = groups_found[*gender].analysis().unwrap().davidson.as_ref().expect("a davidson section");
        assert_eq!(section.ties, counts.iter().map(|c| c.4 as u64).sum::<u64>());
        for (item, lambda) in section.items.iter().zip(&direct.log_worth) {
            assert!((item.log_worth.unwrap() - lambda).abs() < 1e-9, "{gender}: {item:?} against {lambda}");
        }
        assert!((section.nu - direct.nu).abs() < 1e-9, "{gender}: ν {} against {}", section.nu, direct.nu);
    }
    assert!(groups_found["x"].analysis().unwrap().davidson.is_none(), "group x has no ties");
    // the whole data's section pools the groups
    assert_eq!(analysis.davidson.as_ref().unwrap().ties, 24);
    let json = serde_json::to_string(&analysis).unwrap();
    assert!(json.contains("\"groups\":{\"f\":{"), "{json}");
}
