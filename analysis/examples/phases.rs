//! Times the phases of an analysis on synthetic data: `cargo run --release -p mrstudy-analysis
//! --example phases -- CONDITIONS JUDGMENTS` (one thread, as analysis/bench/README.md's targets).
use std::time::Instant;

use mrstudy_analysis::analysis::{Options, Screening, analyze_judgments};
use mrstudy_analysis::data::{ConditionTable, Judgment, Judgments};
use mrstudy_analysis::design;

fn main() {
    let mut args = std::env::args().skip(1).map(|s| s.parse::<usize>().expect("a number"));
    let t = args.next().unwrap_or(8);
    let n = args.next().unwrap_or(1_000_000);
    let mut state = 1u64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let levels: Vec<Vec<f64>> = (0..t).map(|c| (0..3).map(|k| ((c >> k) & 1) as f64).collect()).collect();
    let lambda: Vec<f64> = levels.iter().map(|x| 0.5 * x[0] - 0.4 * x[1] + 0.8 * x[2]).collect();
    let rows: Vec<Judgment> = (0..n)
        .map(|k| {
            let a = (next() * t as f64) as usize;
            let mut b = (next() * (t - 1) as f64) as usize;
            if b >= a {
                b += 1;
            }
            let p = 1.0 / (1.0 + (lambda[b] - lambda[a]).exp());
            Judgment {
                participant: (k / 65) as u32,
                left: a as u32,
                right: b as u32,
                left_chosen: next() < p,
                count: 1,
                group: 0,
            }
        })
        .collect();
    let names: Vec<String> = (0..t).map(|c| format!("C{c}")).collect();
    let judgments = Judgments {
        conditions: names.clone(),
        participants: (0..n.div_ceil(65)).map(|p| format!("p{p}")).collect(),
        groups: vec![],
        rows,
    };
    let table = ConditionTable { conditions: names, factors: vec!["gi".into(), "cm".into(), "ca".into()], levels };
    rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| {
        let start = Instant::now();
        let pairs = design::tally_dense(t, judgments.rows.iter().map(|r| (r.left, r.right, r.left_chosen, r.count)));
        println!("tally: {:?}", start.elapsed());
        let start = Instant::now();
        let agreement = mrstudy_analysis::agreement::coefficient_of_agreement(&pairs, t, &Default::default()).unwrap();
        println!("agreement ({}): {:?}", agreement.method, start.elapsed());
        for _ in 0..3 {
            let start = Instant::now();
            let options = Options { screening: Screening::Off, ..Options::default() };
            analyze_judgments(&judgments, Some(&table), &options).unwrap();
            println!("full analysis: {:?}", start.elapsed());
        }
    });
}
