//! Times `mrstudy analyze` of a synthetic trials CSV end to end and by phase, on one thread:
//! `cargo run --release -p mrstudy-analysis --example end_to_end -- JUDGMENTS`. Each line is
//! the fastest of five runs (or `REPEATS`), by this thread's CPU time (the machine may be shared) and wall time.
use std::time::Instant;

use mrstudy_analysis::analysis::{Options, Screening, analyze_judgments, analyze_named};
use mrstudy_analysis::bench::synthetic_csv;
use mrstudy_analysis::data::{TrialsOptions, parse_conditions, parse_trials_with};

/// This thread's CPU time in ms (Linux; 0 elsewhere).
fn cpu_ms() -> f64 {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap_or_default();
    text.split_whitespace().next().and_then(|t| t.parse::<f64>().ok()).unwrap_or(0.0) / 1e6
}

fn time(what: &str, mut f: impl FnMut()) {
    let (mut wall, mut cpu) = (f64::INFINITY, f64::INFINITY);
    let repeats = std::env::var("REPEATS").ok().and_then(|r| r.parse().ok()).unwrap_or(5);
    for _ in 0..repeats {
        let (start, start_cpu) = (Instant::now(), cpu_ms());
        f();
        wall = wall.min(start.elapsed().as_secs_f64() * 1e3);
        cpu = cpu.min(cpu_ms() - start_cpu);
    }
    println!("{what:<40} cpu {cpu:7.1} ms   wall {wall:7.1} ms");
}

fn main() {
    let n = std::env::args().nth(1).map(|s| s.parse::<usize>().expect("a number")).unwrap_or(1_000_000);
    let (trials, conditions) = synthetic_csv(n, 1);
    println!("trials CSV: {n} judgments, {} MB", trials.len() / 1_000_000);
    let options = Options { group_by: Some("gender".into()), ..Options::default() };
    rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| {
        time("end to end, groups", || {
            analyze_named(&trials, "t", Some((&conditions, "c")), &options).unwrap();
        });
        let plain = Options { group_by: None, ..Options::default() };
        time("end to end, no groups", || {
            analyze_named(&trials, "t", Some((&conditions, "c")), &plain).unwrap();
        });
        let table = parse_conditions(&conditions, "c").unwrap();
        let trials_options = TrialsOptions { group_by: Some("gender".into()), ..TrialsOptions::default() };
        time("parse", || {
            parse_trials_with(&trials, "t", Some(&table), &trials_options).unwrap();
        });
        let judgments = parse_trials_with(&trials, "t", Some(&table), &trials_options).unwrap().judgments;
        let mut ungrouped = judgments.clone();
        ungrouped.groups.clear();
        let bare = Options { screening: Screening::Off, agreement_simulations: 1, ..plain.clone() };
        for (name, options, data) in [
            ("analysis: fits, tallies, consistence", bare.clone(), &ungrouped),
            ("  + agreement simulation", Options { agreement_simulations: 10_000, ..bare.clone() }, &ungrouped),
            ("  + screening (= no groups)", plain.clone(), &ungrouped),
            ("  + groups", options.clone(), &judgments),
        ] {
            time(name, || {
                analyze_judgments(data, Some(&table), &options).unwrap();
            });
        }
    });
}
