//! `mrstudy bench`: measures speed, and error against a reference where a quality knob exists.
//! Prints a table; `--json FILE` writes `{"adapter": ..., "rows": [...]}` (DESIGN.md);
//! `--plot-dir DIR` draws the speed/error curves as SVG.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use mrstudy_analysis::analysis::{Options, Screening, analyze_judgments};
use mrstudy_analysis::data::{ConditionTable, Judgment, Judgments};
use mrstudy_analysis::plot::{LinePlot, LineSeries, line_plot};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};

#[derive(Clone, Copy, ValueEnum)]
pub enum Target {
    /// Bradley–Terry analysis: time against data size and against convergence tolerance.
    Analysis,
    /// Rendering: the GPU renderer's frame time and error against the path-traced ground truth over VPL counts; with `--reference`, the CPU reference path tracer's samples/s and error against a high-spp render; with `--ca`, noise and blur on the virtual objects against the camera's, ca off/on.
    Render,
    /// Web survey server: responses/s and latency percentiles with durable writes, concurrent simulated participants over loopback.
    Server,
}

#[derive(Args)]
pub struct BenchArgs {
    target: Target,
    /// Write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write SVG plots of the curves into this directory.
    #[arg(long)]
    plot_dir: Option<PathBuf>,
    /// Smaller sizes only (for a quick check).
    #[arg(long)]
    quick: bool,
    /// bench render: measure the CPU reference path tracer.
    #[arg(long)]
    reference: bool,
    /// bench render: the ca factor's accuracy — noise and blur on the virtual objects against
    /// the camera's (ground truth), ca off / scene / estimated parameters, per scene and preset.
    #[arg(long, conflicts_with_all = ["reference", "cm"])]
    ca: bool,
    /// bench render: each colour-mapping (cm) method's CIEDE2000 on the virtual objects against the ground truth through the known camera, over camera presets and settings.
    #[arg(long, conflicts_with = "reference")]
    cm: bool,
    /// bench render: the scene (default: DIR scenes on the GPU, survey-1 with --reference, every built-in scene with --cm).
    #[arg(long)]
    scene: Option<String>,
}

pub fn run(args: BenchArgs) -> Result<()> {
    let (adapter, rows, plots) = match args.target {
        Target::Analysis => bench_analysis(args.quick)?,
        Target::Render if args.reference => crate::render::bench_reference(args.scene.as_deref(), args.quick)?,
        Target::Render if args.ca => crate::render::bench_ca(args.scene.as_deref(), args.quick)?,
        Target::Render if args.cm => crate::render::bench_cm(args.scene.as_deref(), args.quick)?,
        Target::Server => crate::serve::bench_server(args.quick)?,
        Target::Render => crate::render::bench_gpu(args.scene.as_deref(), args.quick)?,
    };
    if let Some(path) = &args.json {
        let document = json!({ "adapter": adapter, "rows": rows });
        std::fs::write(path, serde_json::to_string_pretty(&document)? + "\n").with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(dir) = &args.plot_dir {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for (name, svg) in plots {
            let path = dir.join(name);
            std::fs::write(&path, svg).with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    Ok(())
}

/// A synthetic paired-comparison study: `n_conditions` conditions with true log-worth from
/// three binary factors plus noise, `n_judgments` judgments on random pairs (a full design when
/// the conditions are few), 65 judgments per participant.
fn synthetic(n_conditions: usize, n_judgments: usize, seed: u64) -> (Judgments, ConditionTable) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let factors = ["gi", "cm", "ca"];
    let levels: Vec<Vec<f64>> = (0..n_conditions).map(|c| (0..3).map(|k| ((c >> k) & 1) as f64).collect()).collect();
    let lambda: Vec<f64> = levels.iter().map(|x| 0.54 * x[0] - 0.44 * x[1] + 0.86 * x[2] + 0.3 * (rng.random::<f64>() - 0.5)).collect();
    let conditions: Vec<String> = (0..n_conditions).map(|c| format!("C{c:04}")).collect();
    let n_participants = n_judgments.div_ceil(65);
    let rows = (0..n_judgments)
        .map(|k| {
            let left = rng.random_range(0..n_conditions);
            let mut right = rng.random_range(0..n_conditions - 1);
            if right >= left {
                right += 1;
            }
            let p_left = 1.0 / (1.0 + (lambda[right] - lambda[left]).exp());
            Judgment { participant: (k / 65) as u32, left: left as u32, right: right as u32, left_chosen: rng.random::<f64>() < p_left, count: 1, group: 0 }
        })
        .collect();
    let judgments = Judgments { conditions: conditions.clone(), participants: (0..n_participants).map(|p| format!("p{p}")).collect(), groups: Vec::new(), rows };
    let table = ConditionTable { conditions, factors: factors.iter().map(|f| f.to_string()).collect(), levels };
    (judgments, table)
}

fn options(tolerance: f64) -> Options {
    Options { tolerance, screening: Screening::Off, bootstrap: 0, ..Options::default() }
}

/// Median wall time in ms of `repeats` runs of `f`.
fn time_ms<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeats {
        let start = Instant::now();
        let out = f();
        times.push(start.elapsed().as_secs_f64() * 1e3);
        last = Some(out);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], last.expect("repeats > 0"))
}

fn bench_analysis(quick: bool) -> Result<(String, Vec<Value>, Vec<(String, String)>)> {
    // One core, as the targets are stated for one core of the 2-core machine.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    pool.install(|| -> Result<_> {
        let mut rows = Vec::new();
        println!("{:<12} {:>10} {:>12} {:>10} {:>12} {:>14}", "bench", "conditions", "judgments", "tolerance", "ms", "max |Δλ|");
        let print = |row: &Value| {
            println!(
                "{:<12} {:>10} {:>12} {:>10} {:>12.2} {:>14}",
                row["bench"].as_str().unwrap_or(""),
                row["conditions"].to_string(),
                row["judgments"].to_string(),
                row.get("tolerance").map(|t| format!("{:.0e}", t.as_f64().unwrap_or(0.0))).unwrap_or_else(|| "1e-10".into()),
                row["ms"].as_f64().unwrap_or(0.0),
                row.get("max_abs_error").map(|e| format!("{:.2e}", e.as_f64().unwrap_or(0.0))).unwrap_or_default()
            )
        };

        // Size: 1e3 … 1e7 judgments on 8 conditions.
        let sizes: &[usize] = if quick { &[1_000, 10_000, 100_000] } else { &[1_000, 10_000, 100_000, 1_000_000, 10_000_000] };
        let mut size_points = Vec::new();
        for &n in sizes {
            let (judgments, table) = synthetic(8, n, 1);
            let repeats = if n >= 1_000_000 { 3 } else { 7 };
            let (ms, analysis) = time_ms(repeats, || analyze_judgments(&judgments, Some(&table), &options(1e-10)));
            let analysis = analysis?;
            let row = json!({"bench": "size", "conditions": 8, "judgments": n, "ms": ms, "item_iterations": analysis.item_model.iterations, "agreement_method": analysis.agreement.method});
            print(&row);
            size_points.push((n as f64, ms));
            rows.push(row);
        }

        // Conditions: 10 … 2000 with 1e6 judgments.
        let counts: &[usize] = if quick { &[10, 100, 500] } else { &[10, 50, 100, 500, 1000, 2000] };
        let n = if quick { 100_000 } else { 1_000_000 };
        let mut condition_points = Vec::new();
        for &t in counts {
            let (judgments, table) = synthetic(t, n, 2);
            let (ms, analysis) = time_ms(if t >= 1000 { 1 } else { 3 }, || analyze_judgments(&judgments, Some(&table), &options(1e-10)));
            let analysis = analysis?;
            let row = json!({"bench": "conditions", "conditions": t, "judgments": n, "ms": ms, "item_iterations": analysis.item_model.iterations, "agreement_method": analysis.agreement.method});
            print(&row);
            condition_points.push((t as f64, ms));
            rows.push(row);
        }

        // Tolerance: time and error against a fit at 1e-14.
        let mut tolerance_series = Vec::new();
        for &(t, n) in if quick { &[(8usize, 100_000usize)][..] } else { &[(8, 1_000_000), (500, 1_000_000)][..] } {
            let (judgments, table) = synthetic(t, n, 3);
            let reference = analyze_judgments(&judgments, Some(&table), &options(1e-14))?;
            let mut time_points = Vec::new();
            let mut error_points = Vec::new();
            for tolerance in [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12] {
                let (ms, analysis) = time_ms(3, || analyze_judgments(&judgments, Some(&table), &options(tolerance)));
                let analysis = analysis?;
                let error = analysis
                    .items
                    .iter()
                    .zip(&reference.items)
                    .filter_map(|(a, b)| Some((a.log_worth? - b.log_worth?).abs()))
                    .fold(0.0, f64::max);
                let row = json!({"bench": "tolerance", "conditions": t, "judgments": n, "tolerance": tolerance, "ms": ms, "max_abs_error": error, "item_iterations": analysis.item_model.iterations});
                print(&row);
                time_points.push((tolerance, ms));
                error_points.push((tolerance, error.max(1e-17)));
                rows.push(row);
            }
            tolerance_series.push((format!("{t} conditions"), time_points, error_points));
        }

        let mut plots = vec![
            (
                "analysis-size.svg".to_string(),
                line_plot(&LinePlot {
                    title: "Full analysis time against judgments (8 conditions, one core)".into(),
                    x_label: "judgments".into(),
                    y_label: "time (ms)".into(),
                    x_log: true,
                    y_log: true,
                    series: vec![LineSeries { name: "item + factor fit, SEs, agreement".into(), points: size_points }],
                }),
            ),
            (
                "analysis-conditions.svg".to_string(),
                line_plot(&LinePlot {
                    title: format!("Full analysis time against conditions ({n} judgments, one core)"),
                    x_label: "conditions".into(),
                    y_label: "time (ms)".into(),
                    x_log: true,
                    y_log: true,
                    series: vec![LineSeries { name: "item + factor fit, SEs, agreement".into(), points: condition_points }],
                }),
            ),
        ];
        plots.push((
            "analysis-tolerance.svg".to_string(),
            line_plot(&LinePlot {
                title: "Error of log-worth against convergence tolerance (reference: tolerance 1e-14)".into(),
                x_label: "tolerance".into(),
                y_label: "max |Δλ|".into(),
                x_log: true,
                y_log: true,
                series: tolerance_series.iter().map(|(name, _, error)| LineSeries { name: name.clone(), points: error.clone() }).collect(),
            }),
        ));
        plots.push((
            "analysis-tolerance-time.svg".to_string(),
            line_plot(&LinePlot {
                title: "Analysis time against convergence tolerance (1e6 judgments, one core)".into(),
                x_label: "tolerance".into(),
                y_label: "time (ms)".into(),
                x_log: true,
                y_log: true,
                series: tolerance_series.iter().map(|(name, time, _)| LineSeries { name: name.clone(), points: time.clone() }).collect(),
            }),
        ));
        Ok(("cpu (analysis needs no GPU)".to_string(), rows, plots))
    })
}
