//! Issue 14's early gap to ASAP, measured: `cargo run --release -p mrstudy-analysis --example
//! early_gap -- [RUNS] [20|8]`. Four schedulers against the same simulated Thurstone observers
//! (no taste noise, a new participant every 20 trials, batches of 5 pairs per request): random
//! pairs; the active design as the server runs it (ADF, ρ ramped to ½ over 20 judgments per
//! condition); the same posterior re-anchored on a Laplace refit of every judgment before each
//! batch ([`Posterior::reanchor`]) with the plain EIG (ρ = 1 from the start); and the refit with
//! the server's ramp. Each run's judgments are scored by one estimator, the MAP of the Thurstone
//! model with prior N(0, 1) per condition ([`laplace::refit`]), as the README's side-by-side with
//! ASAP scores them; the centred RMSE ± its Monte-Carlo standard error at each checkpoint. `20`:
//! the 20 log-worths of `studies/examples/twenty-conditions-worths.csv`; `8`: the thesis's
//! factor effects (gi 0.27, cm −0.22, ca 0.43) as 8 conditions' log-worths.

use mrstudy_analysis::active::laplace::{self, refit};
use mrstudy_analysis::active::simulate::{centred_rmse, factorial, mean_and_standard_error};
use mrstudy_analysis::active::{DEFAULT_MEAN_WEIGHT, DEFAULT_PRIOR_SD, Link, Posterior, Target, tie_stream};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

/// A scheduler: random pairs, or the active posterior with a largest ρ, a ramp (judgments per
/// condition, 0: none) and whether it is re-anchored on a refit before each batch.
struct Scheduler {
    name: &'static str,
    active: Option<(f64, f64, bool)>,
}

const SCHEDULERS: [Scheduler; 4] = [
    Scheduler { name: "random pairs", active: None },
    Scheduler { name: "active (ADF, ρ ramp to ½)", active: Some((DEFAULT_MEAN_WEIGHT, 20.0, false)) },
    Scheduler { name: "refit + plain EIG (ρ = 1)", active: Some((1.0, 0.0, true)) },
    Scheduler { name: "refit + ρ ramp to ½", active: Some((DEFAULT_MEAN_WEIGHT, 20.0, true)) },
];

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let runs: u64 = args.next().map_or(40, |a| a.parse().expect("RUNS"));
    let study = args.next().unwrap_or_else(|| "20".into());
    let worths: Vec<f64> = match study.as_str() {
        "20" => std::fs::read_to_string("studies/examples/twenty-conditions-worths.csv")
            .expect("run from the repository's root")
            .lines()
            .skip(1)
            .map(|line| line.split(',').nth(1).expect("a log_worth").parse().expect("a number"))
            .collect(),
        "8" => factorial(&[0.27, -0.22, 0.43]).1,
        other => panic!("the study is 20 or 8, not {other}"),
    };
    let n = worths.len();
    let checkpoints: Vec<usize> = if n == 20 { vec![100, 200, 400, 800] } else { vec![40, 80, 160, 320] };
    let total = *checkpoints.last().expect("a checkpoint");
    let target = Target::Worths { conditions: n };
    let map = |judgments: &[(usize, usize)]| -> laplace::LaplaceFit {
        refit(&target, Link::Probit, DEFAULT_PRIOR_SD, judgments).expect("a refit")
    };
    println!("{n} conditions, {runs} runs; centred RMSE of the MAP (prior sd 1) ± its standard error");
    for scheduler in &SCHEDULERS {
        let mut at: Vec<Vec<f64>> = vec![Vec::new(); checkpoints.len()];
        for run in 0..runs {
            let mut posterior = scheduler.active.map(|(rho, ramp, _)| {
                Posterior::new(&target, Link::Probit, DEFAULT_PRIOR_SD)
                    .and_then(|p| p.with_mean_weight(rho))
                    .and_then(|p| p.with_mean_ramp(ramp))
                    .expect("a posterior")
            });
            let mut outcomes = ChaCha8Rng::seed_from_u64(1000 + run);
            let mut random = ChaCha8Rng::seed_from_u64(5000 + run);
            let mut judgments: Vec<(usize, usize)> = Vec::new();
            let (mut participant, mut previous) = (0u64, None);
            while judgments.len() < total {
                if judgments.len().is_multiple_of(20) {
                    participant += 1;
                    previous = None;
                }
                let k = 5.min(total - judgments.len());
                let pairs = match (&mut posterior, scheduler.active) {
                    (Some(posterior), Some((_, _, reanchor))) => {
                        if reanchor && !judgments.is_empty() {
                            posterior.reanchor(&map(&judgments)).expect("a usable refit");
                        }
                        let mut ties = tie_stream(run, posterior.state_id(), participant);
                        posterior.best_pairs(k, previous, &mut ties).expect("a batch")
                    }
                    _ => (0..k)
                        .map(|_| {
                            loop {
                                let (i, j) =
                                    ((random.next_u64() % n as u64) as usize, (random.next_u64() % n as u64) as usize);
                                if i != j {
                                    break (i.min(j), i.max(j));
                                }
                            }
                        })
                        .collect(),
                };
                for (i, j) in pairs {
                    let i_won = uniform(&mut outcomes) < Link::Probit.probability(worths[i] - worths[j]);
                    let (winner, loser) = if i_won { (i, j) } else { (j, i) };
                    if let Some(posterior) = &mut posterior {
                        posterior.update(winner, loser).expect("an update");
                    }
                    judgments.push((winner, loser));
                    previous = Some((i, j));
                    if let Some(c) = checkpoints.iter().position(|&c| c == judgments.len()) {
                        at[c].push(centred_rmse(&map(&judgments).mean, &worths));
                    }
                }
            }
        }
        let cells: Vec<String> = at
            .iter()
            .zip(&checkpoints)
            .map(|(values, trials)| {
                let (mean, se) = mean_and_standard_error(values);
                format!("{trials}: {mean:.3} ± {se:.3}")
            })
            .collect();
        println!("{:<28} {}", scheduler.name, cells.join("   "));
    }
}
