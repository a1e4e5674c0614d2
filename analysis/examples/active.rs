//! Active pair selection, measured: `cargo run --release -p mrstudy-analysis --example active
//! -- [bench|bench-quick|simulate] [RUNS]`. `bench` runs `active::bench::run` (one thread) and
//! prints its table; `simulate` prints the RMSE of active against random pairs for the two
//! studies of issue 14 (8 conditions from the factor effects gi 0.27, cm −0.22, ca 0.43 with
//! 0/1 levels; 20 conditions with log-worths N(0, 1)), Thurstone observers, RUNS runs each.
use mrstudy_analysis::active::simulate::{Design, SimulationConfig, factorial, simulate};
use mrstudy_analysis::active::{DEFAULT_MEAN_WEIGHT, DEFAULT_PRIOR_SD, Link, Target, bench};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

fn main() {
    let mut args = std::env::args().skip(1);
    let what = args.next().unwrap_or_else(|| "simulate".into());
    let runs: usize = args.next().map_or(40, |s| s.parse().expect("a number of runs"));
    match what.as_str() {
        "bench" | "bench-quick" => {
            let report = bench::run(what == "bench-quick", &|line| println!("{line}")).expect("bench");
            println!("{}", serde_json::to_string(&report.to_json()).expect("json"));
        }
        _ => {
            let (_, eight) = factorial(&[0.27, -0.22, 0.43]);
            // Log-worths N(0, 1) by Box–Muller on a seeded ChaCha8 stream.
            let mut rng = ChaCha8Rng::from_seed([7; 32]);
            let mut uniform = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
            let twenty: Vec<f64> = (0..20)
                .map(|_| (-2.0 * (1.0 - uniform()).ln()).sqrt() * (2.0 * std::f64::consts::PI * uniform()).cos())
                .collect();
            for (worths, checkpoints) in [(eight, vec![40, 80, 160, 320]), (twenty, vec![100, 200, 400, 800])] {
                for (taste_sd, mean_weight) in
                    [(0.0, DEFAULT_MEAN_WEIGHT), (0.3, DEFAULT_MEAN_WEIGHT), (0.0, 1.0), (0.0, 0.0)]
                {
                    let config = SimulationConfig {
                        target: Target::Worths { conditions: worths.len() },
                        true_log_worths: worths.clone(),
                        link: Link::Probit,
                        prior_sd: DEFAULT_PRIOR_SD,
                        mean_weight,
                        taste_sd,
                        trials_per_participant: 20,
                        batch: 5,
                        checkpoints: checkpoints.clone(),
                        runs,
                        seed: 2024,
                    };
                    let mut rows = simulate(&config, Design::Active).expect("simulation");
                    if mean_weight == DEFAULT_MEAN_WEIGHT {
                        rows.extend(simulate(&config, Design::Random).expect("simulation"));
                    }
                    for row in rows {
                        println!(
                            "{:>3} conditions  taste {:.1}  ρmax {:.1}  {:<7} {:>5} trials  RMSE {:.3} ± {:.3}",
                            row.conditions,
                            taste_sd,
                            mean_weight,
                            format!("{:?}", row.design).to_lowercase(),
                            row.trials,
                            row.rmse,
                            row.rmse_se
                        );
                    }
                }
            }
        }
    }
}
