//! Active pair selection, measured: `cargo run --release -p mrstudy-analysis --example active
//! -- [bench|bench-quick|simulate] [RUNS]`. `bench` runs `active::bench::run` (one thread) and
//! prints its table; `simulate` prints the RMSE of active against random pairs for the two
//! studies of issue 14 (8 conditions from the factor effects gi 0.27, cm −0.22, ca 0.43 with
//! 0/1 levels; 20 conditions with log-worths N(0, 1)), Thurstone observers, RUNS runs each.
//! `log RUNS WORTHS TASTE_SD TRIALS DIR` writes the judgment logs (`run,trial,i,j,i_won`) of
//! active and random pairs on Thurstone observers with the log-worths of the CSV `WORTHS`
//! (column `log_worth`) to `DIR/active.csv` and `DIR/random.csv`, for
//! `analysis/reference/score_design_logs.py` to score beside another scheduler's log;
//! `score WORTHS CHECKPOINTS LOG` scores such a log (any scheduler's) with this crate's own
//! estimator instead: each run's judgments through a fresh Thurstone posterior (prior sd 1), the
//! centred RMSE of its mean at each of the comma-separated trial counts.
use std::fmt::Write as _;

use mrstudy_analysis::active::simulate::{
    Design, SimulationConfig, centred_rmse, factorial, judgment_log, mean_and_standard_error, simulate,
};
use mrstudy_analysis::active::{DEFAULT_MEAN_WEIGHT, DEFAULT_PRIOR_SD, Link, Posterior, Target, bench};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

fn main() {
    let mut args = std::env::args().skip(1);
    let what = args.next().unwrap_or_else(|| "simulate".into());
    match what.as_str() {
        "bench" | "bench-quick" => {
            let report = bench::run(what == "bench-quick", &|line| println!("{line}")).expect("bench");
            println!("{}", serde_json::to_string(&report.to_json()).expect("json"));
        }
        "score" => {
            let mut arg = |what: &str| args.next().unwrap_or_else(|| panic!("give {what}"));
            let (worths_csv, checkpoints, log) = (arg("WORTHS"), arg("CHECKPOINTS"), arg("LOG"));
            let worths = read_worths(&worths_csv);
            let checkpoints: Vec<usize> = checkpoints.split(',').map(|c| c.parse().expect("a trial count")).collect();
            let text = std::fs::read_to_string(&log).expect("the log");
            let mut runs: Vec<Vec<(usize, usize)>> = Vec::new();
            for line in text.lines().skip(1) {
                let cells: Vec<usize> = line.split(',').map(|c| c.parse().expect("a number")).collect();
                let (run, i, j, i_won) = (cells[0], cells[2], cells[3], cells[4] == 1);
                if runs.len() <= run {
                    runs.resize(run + 1, Vec::new());
                }
                runs[run].push(if i_won { (i, j) } else { (j, i) });
            }
            let target = Target::Worths { conditions: worths.len() };
            for &c in &checkpoints {
                let values: Vec<f64> = runs
                    .iter()
                    .map(|judgments| {
                        let mut posterior = Posterior::new(&target, Link::Probit, DEFAULT_PRIOR_SD).unwrap();
                        for &(winner, loser) in &judgments[..c] {
                            posterior.update(winner, loser).expect("update");
                        }
                        centred_rmse(&posterior.log_worths(), &worths)
                    })
                    .collect();
                let (mean, se) = mean_and_standard_error(&values);
                println!("{log}: {c} trials, {} runs, RMSE (posterior mean) {mean:.3} ± {se:.3}", values.len());
            }
        }
        "log" => {
            let runs = runs_arg(&mut args);
            let mut arg = |what: &str| args.next().unwrap_or_else(|| panic!("give {what}"));
            let (worths_csv, taste_sd, trials, dir) = (arg("WORTHS"), arg("TASTE_SD"), arg("TRIALS"), arg("DIR"));
            let worths = read_worths(&worths_csv);
            let config = SimulationConfig {
                target: Target::Worths { conditions: worths.len() },
                true_log_worths: worths,
                link: Link::Probit,
                prior_sd: DEFAULT_PRIOR_SD,
                mean_weight: DEFAULT_MEAN_WEIGHT,
                taste_sd: taste_sd.parse().expect("a taste sd"),
                trials_per_participant: 20,
                batch: 5,
                checkpoints: vec![trials.parse().expect("a number of trials")],
                runs,
                seed: 2024,
            };
            std::fs::create_dir_all(&dir).expect("the output directory");
            for (design, name) in [(Design::Active, "active"), (Design::Random, "random")] {
                let mut csv = String::from("run,trial,i,j,i_won\n");
                for run in 0..runs as u64 {
                    for (t, judgment) in judgment_log(&config, design, run).expect("simulation").iter().enumerate() {
                        let won = judgment.first_won as u8;
                        let _ = writeln!(csv, "{run},{},{},{},{won}", t + 1, judgment.first, judgment.second);
                    }
                }
                std::fs::write(format!("{dir}/{name}.csv"), csv).expect("write the log");
            }
        }
        _ => {
            let runs = runs_arg(&mut args);
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

/// RUNS, the argument after `log` and `simulate` (40 when absent).
fn runs_arg(args: &mut impl Iterator<Item = String>) -> usize {
    args.next().map_or(40, |s| s.parse().expect("a number of runs"))
}

/// The `log_worth` column (the last) of a worths CSV, in row order.
fn read_worths(path: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).expect("the worths CSV");
    text.lines().skip(1).map(|line| line.rsplit(',').next().unwrap().parse().expect("a log-worth")).collect()
}
