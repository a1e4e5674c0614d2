//! Tests of active pair selection: quadrature and EIG against brute force, the ADF update against
//! the exact posterior mean by grid integration, replay, the batch rules (no back-to-back
//! repeat, connectivity), side balance, bad input, the factor target, the `both` target's
//! criterion (by hand), and active against random pairs in simulation.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;

use super::both::{Criterion, effect_projection};
use super::laplace::refit;
use super::quadrature::{EIG_NODES, Rule, UPDATE_NODES, binary_entropy, normal_pdf};
use super::simulate::{Design, SimulationConfig, centred_rmse, factorial, judgment_log, normal, simulate, uniform};
use super::*;
use crate::newton::cholesky;

/// EIG by the 20-point rule against the dense trapezoid rule, for v ≤ 2 (a pair at the default
/// prior) and for 2 < v ≤ 4.5 (a pair at prior sd 1.5).
const EIG_TOLERANCE: f64 = 1e-4;
const EIG_TOLERANCE_WIDE: f64 = 5e-4;
/// Tilted moments by the 48-point rule (logit) or closed form (probit) against the trapezoid.
const MOMENT_TOLERANCE: f64 = 1e-5;
/// ADF posterior mean against the exact posterior mean on the tiny designs below (ADF is one
/// pass of EP; its error with ~10 judgments is a few hundredths, shrinking with data).
const ADF_MEAN_TOLERANCE: f64 = 0.05;

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// E f(d), d ~ N(m, v), by the trapezoid rule on m ± 12 sd with 4001 points.
fn dense(m: f64, v: f64, f: impl Fn(f64) -> f64) -> f64 {
    let sd = v.sqrt();
    let points = 4001;
    let h = 24.0 / (points - 1) as f64;
    (0..points)
        .map(|k| {
            let z = -12.0 + k as f64 * h;
            let weight = if k == 0 || k == points - 1 { 0.5 } else { 1.0 };
            weight * h * normal_pdf(z) * f(m + sd * z)
        })
        .sum()
}

#[test]
fn gauss_hermite_rules_integrate_normal_moments() {
    for n in [EIG_NODES, UPDATE_NODES] {
        let rule = Rule::gauss_hermite(n);
        let moment = |k: i32| rule.nodes.iter().zip(&rule.weights).map(|(z, w)| w * z.powi(k)).sum::<f64>();
        assert!((moment(0) - 1.0).abs() < 1e-13, "{n}: {}", moment(0));
        assert!(moment(1).abs() < 1e-13);
        assert!((moment(2) - 1.0).abs() < 1e-12);
        assert!((moment(4) - 3.0).abs() < 1e-11);
        assert!((moment(8) - 105.0).abs() < 1e-8);
    }
}

#[test]
fn eig_matches_dense_quadrature() {
    let rule = Rule::gauss_hermite(EIG_NODES);
    for link in [Link::Logit, Link::Probit] {
        for m in [-4.0, -1.5, 0.0, 0.7, 3.0] {
            for v in [1e-4, 0.1, 1.0, 2.0, 4.5] {
                let mean_p = dense(m, v, |d| link.probability(d));
                let expected = binary_entropy(mean_p) - dense(m, v, |d| link.entropy(d));
                let eig = link.eig(m, v, &rule);
                let tolerance = if v > 2.0 { EIG_TOLERANCE_WIDE } else { EIG_TOLERANCE };
                assert!((eig - expected).abs() < tolerance, "{link:?} m {m} v {v}: {eig} vs {expected}");
            }
        }
    }
}

#[test]
fn tilted_moments_match_dense_quadrature() {
    let rule = Rule::gauss_hermite(UPDATE_NODES);
    for link in [Link::Logit, Link::Probit] {
        // m = −5, v = 4 is a surprise: the winner was 2.5 sd behind.
        for (m, v) in [(0.0, 4.5), (1.2, 0.3), (-5.0, 4.0), (3.0, 2.0), (-0.4, 1e-3)] {
            let z = dense(m, v, |d| link.probability(d));
            let mean = dense(m, v, |d| d * link.probability(d)) / z;
            let variance = dense(m, v, |d| (d - mean).powi(2) * link.probability(d)) / z;
            let (z_q, mean_q, variance_q) = link.tilted(m, v, &rule);
            assert!((z_q - z).abs() < MOMENT_TOLERANCE, "{link:?} ({m}, {v}) Z {z_q} vs {z}");
            assert!((mean_q - mean).abs() < MOMENT_TOLERANCE, "{link:?} ({m}, {v}) mean {mean_q} vs {mean}");
            assert!(
                (variance_q - variance).abs() < MOMENT_TOLERANCE,
                "{link:?} ({m}, {v}) var {variance_q} vs {variance}"
            );
        }
    }
}

/// Draws θ ~ N(mean, covariance).
fn draw(mean: &[f64], l: &[f64], rng: &mut ChaCha8Rng) -> Vec<f64> {
    let p = mean.len();
    let z: Vec<f64> = (0..p).map(|_| normal(rng)).collect();
    (0..p).map(|r| mean[r] + (0..=r).map(|c| l[r * p + c] * z[c]).sum::<f64>()).collect()
}

/// The EIG of a pair from its definition, I(y; θ) = H[E p(θ)] − E H[p(θ)], by Monte Carlo over
/// the whole posterior (not its projection), on a 3-condition and a 2×2×2 factor posterior.
#[test]
fn eig_matches_monte_carlo_over_the_whole_posterior() {
    let (design, _) = factorial(&[0.27, -0.22, 0.43]);
    for target in [Target::Worths { conditions: 3 }, Target::Factors { design }] {
        let mut posterior = Posterior::new(&target, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
        for (w, l) in [(0, 1), (2, 1), (0, 2), (1, 0)] {
            posterior.update(w, l).unwrap();
        }
        let p = posterior.parameters();
        let l = cholesky(posterior.covariance(), p).unwrap();
        let mut rng = rng(7);
        let samples = 40_000;
        let (i, j) = (0, 2);
        let (mut sum_p, mut sum_h) = (0.0, 0.0);
        for _ in 0..samples {
            let theta = draw(posterior.mean(), &l, &mut rng);
            let lambda = match &target {
                Target::Worths { .. } | Target::Both { .. } => theta,
                Target::Factors { design } => design.iter().map(|row| posterior::dot(row, &theta)).collect(),
            };
            let d = lambda[i] - lambda[j];
            sum_p += Link::Logit.probability(d);
            sum_h += Link::Logit.entropy(d);
        }
        let brute = binary_entropy(sum_p / samples as f64) - sum_h / samples as f64;
        let eig = posterior.eig(i, j);
        // Monte Carlo error of the difference of two means of bounded terms: ~1e-3 here.
        assert!((eig - brute).abs() < 3e-3, "{target:?}: {eig} vs Monte Carlo {brute}");
        assert!(eig > 0.01);
    }
}

/// The exact posterior mean of the log-worths of 3 conditions by grid integration (3-D, prior
/// N(0, 1.5²) each), against the ADF mean.
#[test]
fn adf_mean_matches_the_exact_posterior_mean_by_grid() {
    let log = [(0, 1), (0, 1), (1, 0), (0, 2), (2, 1), (0, 2), (1, 2), (2, 0), (0, 1)];
    for link in [Link::Logit, Link::Probit] {
        let mut posterior = Posterior::new(&Target::Worths { conditions: 3 }, link, DEFAULT_PRIOR_SD).unwrap();
        for &(w, l) in &log {
            posterior.update(w, l).unwrap();
        }
        let points = 61;
        let h = 12.0 / (points - 1) as f64;
        let grid: Vec<f64> = (0..points).map(|k| -6.0 + k as f64 * h).collect();
        let (mut z, mut first) = (0.0, [0.0; 3]);
        for &a in &grid {
            for &b in &grid {
                for &c in &grid {
                    let theta = [a, b, c];
                    let log_density = -(a * a + b * b + c * c) / (2.0 * DEFAULT_PRIOR_SD * DEFAULT_PRIOR_SD)
                        + log.iter().map(|&(w, l)| link.probability(theta[w] - theta[l]).ln()).sum::<f64>();
                    let density = log_density.exp();
                    z += density;
                    for k in 0..3 {
                        first[k] += density * theta[k];
                    }
                }
            }
        }
        let exact: Vec<f64> = first.iter().map(|f| f / z).collect();
        let error = posterior.mean().iter().zip(&exact).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(error < ADF_MEAN_TOLERANCE, "{link:?}: ADF {:?} vs exact {exact:?}", posterior.mean());
    }
}

/// Factor target with 2 factors on 4 conditions: the exact posterior mean of β by a 2-D grid.
#[test]
fn adf_factor_mean_matches_the_exact_posterior_mean_by_grid() {
    let (design, _) = factorial(&[0.5, -0.3]);
    let log = [(1, 0), (3, 2), (1, 2), (0, 2), (3, 0), (2, 1), (1, 3), (3, 0), (1, 0), (0, 3)];
    let target = Target::Factors { design: design.clone() };
    let mut posterior = Posterior::new(&target, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    for &(w, l) in &log {
        posterior.update(w, l).unwrap();
    }
    let points = 401;
    let h = 12.0 / (points - 1) as f64;
    let (mut z, mut first) = (0.0, [0.0; 2]);
    for a in 0..points {
        for b in 0..points {
            let beta = [-6.0 + a as f64 * h, -6.0 + b as f64 * h];
            let lambda: Vec<f64> = design.iter().map(|row| posterior::dot(row, &beta)).collect();
            let log_density = -(beta[0] * beta[0] + beta[1] * beta[1]) / (2.0 * DEFAULT_PRIOR_SD * DEFAULT_PRIOR_SD)
                + log.iter().map(|&(w, l)| Link::Logit.probability(lambda[w] - lambda[l]).ln()).sum::<f64>();
            let density = log_density.exp();
            z += density;
            first[0] += density * beta[0];
            first[1] += density * beta[1];
        }
    }
    let exact = [first[0] / z, first[1] / z];
    let error = posterior.mean().iter().zip(&exact).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(error < ADF_MEAN_TOLERANCE, "ADF {:?} vs exact {exact:?}", posterior.mean());
}

/// Many judgments: ADF and the Laplace refit (exact MAP) agree to a small part of a posterior sd.
#[test]
fn adf_agrees_with_the_laplace_refit_on_much_data() {
    let n = 6;
    let truth: Vec<f64> = (0..n).map(|k| 0.3 * k as f64 - 0.8).collect();
    let mut rng = rng(3);
    let mut log = Vec::new();
    for _ in 0..3000 {
        let i = (uniform(&mut rng) * n as f64) as usize;
        let j = (i + 1 + (uniform(&mut rng) * (n - 1) as f64) as usize) % n;
        log.push(if uniform(&mut rng) < Link::Logit.probability(truth[i] - truth[j]) { (i, j) } else { (j, i) });
    }
    let target = Target::Worths { conditions: n };
    let mut posterior = Posterior::new(&target, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    for &(w, l) in &log {
        posterior.update(w, l).unwrap();
    }
    let fit = refit(&target, Link::Logit, DEFAULT_PRIOR_SD, &log).unwrap();
    for k in 0..n {
        let sd = fit.covariance[k * n + k].sqrt();
        assert!((posterior.mean()[k] - fit.mean[k]).abs() < 0.05 * sd, "{k}: {:?} vs {:?}", posterior.mean(), fit.mean);
        let adf_sd = posterior.covariance()[k * n + k].sqrt();
        assert!((adf_sd / sd - 1.0).abs() < 0.02, "{k}: sd {adf_sd} vs {sd}");
    }
}

fn events() -> Vec<Event> {
    let mut events = vec![
        Event::Request { participant: 1, trials: 4, previous: None },
        Event::Request { participant: 2, trials: 4, previous: None },
    ];
    let mut rng = rng(11);
    for k in 0..40u64 {
        let i = (uniform(&mut rng) * 6.0) as usize;
        let j = (i + 1 + (uniform(&mut rng) * 5.0) as usize) % 6;
        events.push(Event::Judgment { winner: i, loser: j });
        if k % 7 == 0 {
            events.push(Event::Request { participant: k, trials: 3, previous: Some((i, j)) });
        }
    }
    events
}

#[test]
fn replaying_a_log_with_its_seed_gives_the_same_schedule() {
    let fresh = || Posterior::new(&Target::Worths { conditions: 6 }, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    let first = replay(fresh(), 42, &events()).unwrap();
    let second = replay(fresh(), 42, &events()).unwrap();
    assert_eq!(first, second);
    assert_eq!(first.len(), 8);
    // At the prior every pair ties: two participants at one state get different tie-breaks,
    // and the state ids say which state chose.
    assert_eq!(first[0].state, first[1].state);
    assert_ne!(first[0].pairs, first[1].pairs);
    assert_eq!(first[2].state.judgments, 1);
    let other_seed = replay(fresh(), 43, &events()).unwrap();
    assert_ne!(first[0].pairs, other_seed[0].pairs);
}

#[test]
fn state_ids_name_the_log_and_its_order() {
    let target = Target::Worths { conditions: 4 };
    let mut a = Posterior::new(&target, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    let mut b = a.clone();
    assert_eq!(a.state_id(), StateId { judgments: 0, fingerprint: 0 });
    a.update(0, 1).unwrap();
    a.update(2, 3).unwrap();
    b.update(2, 3).unwrap();
    b.update(0, 1).unwrap();
    assert_eq!(a.state_id().judgments, 2);
    assert_ne!(a.state_id(), b.state_id());
    assert!(a.state_id().to_string().starts_with("2-"));
}

#[test]
fn batches_never_repeat_a_pair_back_to_back() {
    let (design, _) = factorial(&[0.27, -0.22, 0.43]);
    for target in [Target::Worths { conditions: 3 }, Target::Worths { conditions: 5 }, Target::Factors { design }] {
        let n = target.conditions();
        let mut posterior = Posterior::new(&target, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
        let mut previous = None;
        let mut rng = rng(5);
        for round in 0..12 {
            let batch = posterior.best_pairs(8, previous, &mut rng).unwrap();
            assert_eq!(batch.len(), 8);
            let mut last = previous;
            for &(i, j) in &batch {
                assert!(i < j && j < n);
                assert_ne!(Some((i, j)), last, "{target:?} round {round}: {batch:?} after {previous:?}");
                last = Some((i, j));
            }
            // Judge the batch (the lower index wins), as a participant would.
            for &(i, j) in &batch {
                posterior.update(i, j).unwrap();
            }
            previous = batch.last().copied();
        }
    }
}

#[test]
fn the_comparison_graph_is_connected_after_n_minus_one_judgments() {
    for (n, batch) in [(20, 1), (20, 5), (8, 3)] {
        let mut posterior = Posterior::new(&Target::Worths { conditions: n }, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
        let mut rng = rng(9);
        let mut previous = None;
        let mut connected_at = None;
        while connected_at.is_none() {
            for (i, j) in posterior.best_pairs(batch, previous, &mut rng).unwrap() {
                posterior.update(j, i).unwrap();
                previous = Some((i, j));
                if posterior.connected() && connected_at.is_none() {
                    connected_at = Some(posterior.judgments());
                }
            }
        }
        assert_eq!(connected_at, Some(n as u64 - 1), "{n} conditions in batches of {batch}");
    }
    // Two participants served from one state at once: their batches may overlap, but the graph
    // is still connected soon after.
    let n = 12;
    let mut posterior = Posterior::new(&Target::Worths { conditions: n }, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    let state = posterior.state_id();
    let first = posterior.best_pairs(6, None, &mut tie_stream(1, state, 1)).unwrap();
    let second = posterior.best_pairs(6, None, &mut tie_stream(1, state, 2)).unwrap();
    for (i, j) in first.into_iter().chain(second) {
        posterior.update(i, j).unwrap();
    }
    let mut rng = rng(2);
    while !posterior.connected() {
        let (i, j) = posterior.best_pairs(1, None, &mut rng).unwrap()[0];
        posterior.update(i, j).unwrap();
    }
    assert!(posterior.judgments() <= n as u64 - 1 + 6, "{}", posterior.judgments());
}

#[test]
fn sides_stay_balanced_per_participant() {
    let mut rng = rng(13);
    let mut pairs_rng = self::rng(14);
    for n in [3, 8, 20] {
        let mut balance = SideBalance::new(n);
        for _ in 0..500 {
            let i = (uniform(&mut pairs_rng) * n as f64) as usize;
            let j = (i + 1 + (uniform(&mut pairs_rng) * (n - 1) as f64) as usize) % n;
            let (left, right) = balance.assign((i, j), &mut rng);
            assert!((left, right) == (i, j) || (left, right) == (j, i));
            let worst = balance.left_minus_right.iter().map(|b| b.abs()).max().unwrap();
            assert!(worst <= 3, "{n}: {:?}", balance.left_minus_right);
        }
    }
    // The rule itself: the lower count goes left; a tie is a coin of the stream.
    assert_eq!(assign_sides((0, 1), &[1, -1], &mut rng), (1, 0));
    assert_eq!(assign_sides((0, 1), &[-2, 0], &mut rng), (0, 1));
    let coins: Vec<(usize, usize)> = (0..16).map(|_| assign_sides((0, 1), &[0, 0], &mut rng)).collect();
    assert!(coins.contains(&(0, 1)) && coins.contains(&(1, 0)));
    let coins_from = |seed: u64| -> Vec<(usize, usize)> {
        let mut stream = self::rng(seed);
        (0..16).map(|_| assign_sides((0, 1), &[0, 0], &mut stream)).collect()
    };
    assert_eq!(coins_from(1), coins_from(1), "the coin is a pure function of the stream");
}

#[test]
fn bad_input_is_one_clear_sentence() {
    let error = Posterior::new(&Target::Worths { conditions: 1 }, Link::Logit, 1.5).unwrap_err();
    assert_eq!(error.to_string(), "active pair selection needs at least 3 conditions, got 1");
    let mut posterior = Posterior::new(&Target::Worths { conditions: 4 }, Link::Logit, 1.5).unwrap();
    assert_eq!(posterior.best_pairs(0, None, &mut rng(1)).unwrap_err(), ActiveError::NoTrials);
    assert_eq!(
        posterior.update(4, 1).unwrap_err().to_string(),
        "condition 4 does not exist (the study has conditions 0 to 3)"
    );
    assert_eq!(posterior.update(2, 2).unwrap_err(), ActiveError::SameCondition { condition: 2 });
    assert_eq!(posterior.judgments(), 0, "a refused judgment is not absorbed");
    assert!(Posterior::new(&Target::Worths { conditions: 4 }, Link::Logit, 0.0).is_err());
    let table = crate::data::ConditionTable {
        conditions: (0..4).map(|c| format!("C{c}")).collect(),
        factors: vec!["gi".into(), "ca".into()],
        levels: vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0], vec![1.0, 1.0]],
    };
    assert_eq!(
        Target::factors(&table, &["gi", "cm"]).unwrap_err().to_string(),
        "`cm` is not a factor of the conditions (factors: gi, ca)"
    );
    let constant = Target::Factors { design: vec![vec![1.0, 0.0], vec![1.0, 1.0], vec![1.0, 0.0]] };
    assert!(Posterior::new(&constant, Link::Logit, 1.5).unwrap_err().to_string().contains("factor 0 takes one value"));
    let ragged = Target::Factors { design: vec![vec![1.0, 0.0], vec![0.0], vec![1.0, 1.0]] };
    assert!(matches!(Posterior::new(&ragged, Link::Logit, 1.5), Err(ActiveError::BadDesign { .. })));
    let analysis_error: crate::AnalysisError = ActiveError::NoTrials.into();
    assert_eq!(analysis_error.to_string(), "a batch of 0 trials was asked for; ask for at least one trial");
}

#[test]
fn a_broken_posterior_is_the_fallback_signal() {
    let mut posterior = Posterior::new(&Target::Worths { conditions: 4 }, Link::Logit, 1.5).unwrap();
    posterior.update(0, 1).unwrap();
    posterior.covariance_for_tests()[2 * 4 + 2] = -10.0;
    let error = posterior.best_pairs(1, None, &mut rng(1)).unwrap_err();
    assert!(matches!(error, ActiveError::Degenerate { judgments: 1, .. }), "{error}");
    assert!(error.to_string().ends_with("use the fixed design"));
    posterior.covariance_for_tests()[0] = f64::NAN;
    assert!(matches!(posterior.update(0, 2), Err(ActiveError::Degenerate { .. })));
}

/// A 2×2×2 factorial with the factor target: the EIG is that of the projected difference, and
/// the posterior mean of β finds the true effects.
#[test]
fn factor_target_on_a_two_by_two_by_two_design() {
    let effects = [0.27, -0.22, 0.43];
    let (design, worths) = factorial(&effects);
    assert_eq!(design[5], [1.0, 0.0, 1.0]);
    let target = Target::Factors { design: design.clone() };
    let mut posterior = Posterior::new(&target, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    assert_eq!(posterior.parameters(), 3);
    // Pair (0, 7) differs in all three factors: v = 3σ², the largest at the prior.
    let rule = Rule::gauss_hermite(EIG_NODES);
    let sigma2 = DEFAULT_PRIOR_SD * DEFAULT_PRIOR_SD;
    assert!((posterior.eig(0, 7) - Link::Logit.eig(0.0, 3.0 * sigma2, &rule)).abs() < 1e-15);
    assert!((posterior.eig(0, 1) - Link::Logit.eig(0.0, sigma2, &rule)).abs() < 1e-15);
    // At the prior the best pairs differ in every factor: (0, 7), (1, 6), (2, 5), (3, 4).
    let first = posterior.best_pairs(1, None, &mut rng(1)).unwrap()[0];
    assert_eq!(first.0 + first.1, 7, "{first:?}");
    let mut rng = rng(17);
    let mut previous = None;
    for _ in 0..300 {
        for (i, j) in posterior.best_pairs(10, previous, &mut rng).unwrap() {
            let i_won = uniform(&mut rng) < Link::Logit.probability(worths[i] - worths[j]);
            let (winner, loser) = if i_won { (i, j) } else { (j, i) };
            posterior.update(winner, loser).unwrap();
            previous = Some((i, j));
        }
    }
    assert!(posterior.connected());
    for k in 0..3 {
        let sd = posterior.covariance()[k * 3 + k].sqrt();
        assert!((posterior.mean()[k] - effects[k]).abs() < 3.0 * sd, "{k}: {:?} ± {sd}", posterior.mean());
        assert!(sd < 0.06);
    }
}

fn study(worths: Vec<f64>, target: Target, checkpoints: Vec<usize>, runs: usize) -> SimulationConfig {
    SimulationConfig {
        true_log_worths: worths,
        target,
        link: Link::Probit,
        prior_sd: DEFAULT_PRIOR_SD,
        mean_weight: DEFAULT_MEAN_WEIGHT,
        taste_sd: 0.0,
        trials_per_participant: 20,
        batch: 5,
        checkpoints,
        runs,
        seed: 2024,
    }
}

/// Active pairs reach the RMSE of random pairs with fewer trials: at every checkpoint active
/// has the lower RMSE (seeded, so deterministic; few runs to stay fast — the report of issue 14
/// has 40 runs).
#[test]
fn active_beats_random_pairs_in_simulation() {
    let (_, worths) = factorial(&[0.27, -0.22, 0.43]);
    let eight = study(worths, Target::Worths { conditions: 8 }, vec![40, 80], 12);
    let mut rng = rng(21);
    let worths: Vec<f64> = (0..20).map(|_| normal(&mut rng)).collect();
    let twenty = study(worths, Target::Worths { conditions: 20 }, vec![100, 200], 4);
    for config in [eight, twenty] {
        let active = simulate(&config, Design::Active).unwrap();
        let random = simulate(&config, Design::Random).unwrap();
        for (a, r) in active.iter().zip(&random) {
            assert!(a.rmse < r.rmse, "active {a:?}, random {r:?}");
        }
    }
}

#[test]
fn simulation_refuses_a_mismatched_truth() {
    let config = study(vec![0.0; 4], Target::Worths { conditions: 5 }, vec![10], 1);
    assert_eq!(
        simulate(&config, Design::Random).unwrap_err().to_string(),
        "true_log_worths: 4 true log-worths for 5 conditions"
    );
}

/// The judgment log of a simulated run is the study `simulate` scored: replayed through a fresh
/// posterior it gives the same RMSE at the checkpoint, for both designs.
#[test]
fn a_judgment_log_replays_to_the_scored_study() {
    let (_, worths) = factorial(&[0.27, -0.22, 0.43]);
    let config = study(worths.clone(), Target::Worths { conditions: 8 }, vec![60], 1);
    for design in [Design::Active, Design::Random] {
        let log = judgment_log(&config, design, 0).unwrap();
        assert_eq!(log.len(), 60);
        let mut posterior = Posterior::new(&config.target, config.link, config.prior_sd).unwrap();
        for judgment in &log {
            let (winner, loser) =
                if judgment.first_won { (judgment.first, judgment.second) } else { (judgment.second, judgment.first) };
            posterior.update(winner, loser).unwrap();
        }
        let rmse = centred_rmse(&posterior.log_worths(), &worths);
        let scored = simulate(&config, design).unwrap()[0].rmse;
        assert!((rmse - scored).abs() < 1e-12, "{design:?}: replayed {rmse}, simulated {scored}");
    }
}

#[test]
fn a_posterior_reanchored_on_a_refit_has_the_fit_s_moments_and_keeps_its_state() {
    let target = Target::Worths { conditions: 5 };
    let mut posterior = Posterior::new(&target, Link::Probit, DEFAULT_PRIOR_SD).unwrap();
    let judgments = [(0, 1), (1, 2), (0, 2), (3, 4), (2, 3), (4, 0), (0, 3), (1, 4)];
    for &(w, l) in &judgments {
        posterior.update(w, l).unwrap();
    }
    let state = posterior.state_id();
    let fit = refit(&target, Link::Probit, DEFAULT_PRIOR_SD, &judgments).unwrap();
    // ADF is near the refit but not on it: re-anchoring moves the mean
    let moved = posterior.mean().iter().zip(&fit.mean).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(moved > 1e-6, "ADF's mean equals the refit's to {moved}");
    posterior.reanchor(&fit).unwrap();
    assert_eq!(posterior.mean(), &fit.mean[..]);
    let c = posterior.covariance();
    for a in 0..5 {
        for b in 0..5 {
            assert_eq!(c[a * 5 + b], c[b * 5 + a]);
            assert!((c[a * 5 + b] - fit.covariance[a * 5 + b]).abs() < 1e-12);
        }
    }
    assert_eq!(posterior.state_id(), state, "the state is the log's, refit or not");
    let pairs = posterior.best_pairs(3, None, &mut tie_stream(1, state, 0)).unwrap();
    assert_eq!(pairs.len(), 3);
    // a fit of another size, or with a NaN, is refused and changes nothing
    let small = refit(&Target::Worths { conditions: 4 }, Link::Probit, DEFAULT_PRIOR_SD, &[(0, 1)]).unwrap();
    assert!(matches!(posterior.reanchor(&small), Err(ActiveError::Degenerate { .. })));
    let mut broken = fit.clone();
    broken.covariance[3] = f64::NAN;
    assert!(matches!(posterior.reanchor(&broken), Err(ActiveError::Degenerate { .. })));
    assert_eq!(posterior.mean(), &fit.mean[..]);
}

#[test]
fn without_a_ramp_the_mean_weight_is_full_from_the_first_judgment() {
    let target = Target::Worths { conditions: 6 };
    let ramped = Posterior::new(&target, Link::Probit, DEFAULT_PRIOR_SD).unwrap().with_mean_weight(1.0).unwrap();
    assert_eq!(ramped.effective_mean_weight(), 0.0);
    let flat = ramped.clone().with_mean_ramp(0.0).unwrap();
    assert_eq!(flat.effective_mean_weight(), 1.0);
    let mut short = ramped.with_mean_ramp(1.0).unwrap();
    for k in 0..3 {
        short.update(k, k + 1).unwrap();
    }
    // 3 judgments of a 1-per-condition ramp over 6 conditions: half way
    assert!((short.effective_mean_weight() - 0.5).abs() < 1e-12);
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let refused = Posterior::new(&target, Link::Probit, DEFAULT_PRIOR_SD).unwrap().with_mean_ramp(bad);
        assert!(matches!(refused, Err(ActiveError::BadOption { option: "mean_ramp", .. })), "{bad}");
    }
}

// The `both` target (issue 48).

/// Three conditions, one factor on condition 2 alone: the effect is λ₂ − (λ₀ + λ₁)/2.
fn three() -> Vec<Vec<f64>> {
    vec![vec![0.0], vec![0.0], vec![1.0]]
}

#[test]
fn the_projection_is_the_least_squares_effect() {
    let projection = effect_projection(&three()).unwrap();
    for (got, want) in projection[0].iter().zip([-0.5, -0.5, 1.0]) {
        assert!((got - want).abs() < 1e-12, "{projection:?}");
    }
    // 2² factorial: each main effect is the mean of its level 1 minus the mean of level 0
    let design = vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0], vec![1.0, 1.0]];
    let projection = effect_projection(&design).unwrap();
    let want = [[-0.5, 0.5, -0.5, 0.5], [-0.5, -0.5, 0.5, 0.5]];
    for (row, want) in projection.iter().zip(want) {
        for (got, want) in row.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{projection:?}");
        }
    }
    // a factor that is another's complement has no estimate of its own
    let collinear = vec![vec![0.0, 1.0], vec![1.0, 0.0], vec![1.0, 0.0]];
    let error = effect_projection(&collinear).unwrap_err();
    assert!(error.to_string().contains("combination of the others"), "{error}");
    assert!(Target::Both { design: collinear }.check().is_err());
}

/// At the prior Σ = I (probit, mean 0) every pair's difference has v = 2 and the same
/// c = (2/π)/(1 + v) = 2/(3π). tr CΣC = 2 and tr PΣPᵀ = 1/4 + 1/4 + 1 = 3/2. (0, 1): ‖C·u‖²
/// = 2, P·u = 0, score 2/(3π)·1; (0, 2): ‖C·u‖² = 2, P·u = −3/2, score 2/(3π)·(1 + 9/4 / 3/2)
/// = 5/(3π). A worths-only criterion scores all three alike.
#[test]
fn the_criterion_prefers_the_pair_that_also_informs_the_effect_by_hand() {
    let projection = effect_projection(&three()).unwrap();
    let covariance = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let rule = Rule::gauss_hermite(48);
    let criterion = Criterion::new(Link::Probit, &rule, &projection, &covariance).unwrap();
    let pi = std::f64::consts::PI;
    for (pair, want) in [((0, 1), 2.0 / (3.0 * pi)), ((0, 2), 5.0 / (3.0 * pi)), ((1, 2), 5.0 / (3.0 * pi))] {
        let (score, v) = criterion.score(pair, 0.0).unwrap();
        assert!((v - 2.0).abs() < 1e-12);
        assert!((score - want).abs() < 1e-12, "{pair:?}: {score} against {want}");
    }
    // the posterior's batch takes a pair with condition 2 first, whatever the tie-break
    let posterior = Posterior::new(&Target::Both { design: three() }, Link::Probit, DEFAULT_PRIOR_SD).unwrap();
    for seed in 0..20 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let batch = posterior.best_pairs(1, None, &mut rng).unwrap();
        assert!(batch[0] == (0, 2) || batch[0] == (1, 2), "seed {seed}: {batch:?}");
    }
}

/// The posterior of the `both` target is the log-worths' one: the same log gives the same
/// mean and covariance as the `worths` target.
#[test]
fn both_updates_the_log_worths_posterior() {
    let design = vec![vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0], vec![1.0, 1.0]];
    let mut both = Posterior::new(&Target::Both { design }, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    let mut worths = Posterior::new(&Target::Worths { conditions: 4 }, Link::Logit, DEFAULT_PRIOR_SD).unwrap();
    for (w, l) in [(1, 0), (3, 2), (2, 0), (3, 1), (0, 3)] {
        both.update(w, l).unwrap();
        worths.update(w, l).unwrap();
    }
    assert_eq!((both.mean(), both.covariance()), (worths.mean(), worths.covariance()));
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let batch = both.best_pairs(5, Some((0, 3)), &mut rng).unwrap();
    assert_eq!(batch.len(), 5);
    assert_ne!(batch[0], (0, 3), "the previous pair follows itself");
    assert!(batch.windows(2).all(|pair| pair[0] != pair[1]), "{batch:?}");
}
