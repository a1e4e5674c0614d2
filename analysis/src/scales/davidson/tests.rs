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
    assert_eq!(fit(4, &pairs, 0, 1e-10), Err(DavidsonFailure::Disconnected));
}
