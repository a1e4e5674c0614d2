//! `mrstudy simulate` and `mrstudy power`: read the study and the truth, call
//! `mrstudy_server::simulate` with a progress bar, print the table or JSON, draw the plots.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use mrstudy_analysis::plot::line_plot;
use mrstudy_server::simulate::{self, Config, DesignChoice, Report};

#[derive(Clone, Copy, ValueEnum)]
pub enum Format {
    Table,
    Json,
}

/// What `simulate` and `power` share: the study, the truth, the observers, the runs.
#[derive(Args)]
pub struct StudyArgs {
    /// The study file (`studies/*.toml`); its scheduler and conditions are simulated.
    #[arg(long)]
    study: PathBuf,
    /// True factor effects on the logit scale, e.g. `gi=0.3,cm=-0.2,ca=0.4` (a factor not named: 0). Default: the thesis's gi 0.27, cm −0.22, ca 0.43 for a study with factors gi, cm, ca.
    #[arg(long, conflicts_with = "truth_worth", allow_hyphen_values = true)]
    truth: Option<String>,
    /// True log-worths: a CSV `condition,log_worth` with every condition of the study.
    #[arg(long)]
    truth_worth: Option<PathBuf>,
    /// Per-participant taste noise: sd of each condition's log-worth.
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    observer_sd: f64,
    /// Probability that an answer is a coin flip.
    #[arg(long, default_value_t = 0.02, allow_negative_numbers = true)]
    lapse: f64,
    /// Probability that a participant stops after each trial.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    dropout: f64,
    /// Simulated studies per design and participant count.
    #[arg(long, default_value_t = 200)]
    runs: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Designs side by side: `study` (the file's), `all`, `anchored`, `active` (at equal trials; target factors where a factor varies), `active-worths` (target worths).
    #[arg(long, value_delimiter = ',', default_value = "study", value_parser = crate::choice(DesignChoice::parse, "study, all, anchored, active, active-worths"))]
    designs: Vec<DesignChoice>,
    /// Bootstrap replicates per analysis for the intervals (0: Wald intervals).
    #[arg(long, default_value_t = 0)]
    bootstrap: usize,
}

#[derive(Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    study: StudyArgs,
    /// Participant counts to simulate.
    #[arg(long, value_delimiter = ',', default_value = "10,20,40,80", value_parser = clap::value_parser!(u32).range(1..))]
    participants: Vec<u32>,
    #[arg(long, value_enum, default_value = "table")]
    format: Format,
    /// Write the plots (simulate-rmse.svg, simulate-power.svg) into this directory.
    #[arg(long)]
    plot_dir: Option<PathBuf>,
}

#[derive(Args)]
pub struct PowerArgs {
    #[command(flatten)]
    study: StudyArgs,
    /// Participant counts to simulate.
    #[arg(long, value_delimiter = ',', default_value = "10,20,40,80,160", value_parser = clap::value_parser!(u32).range(1..))]
    participants: Vec<u32>,
    /// The power to reach (DESIGN.md's `--target`; `--target-power` is the same).
    #[arg(long = "target", visible_alias = "target-power", default_value_t = 0.8)]
    target_power: f64,
}

fn run_simulation(args: &StudyArgs, participants: &[u32]) -> Result<Report> {
    let study = mrstudy_server::study::load_study(&args.study)?;
    let truth = match (&args.truth, &args.truth_worth) {
        (Some(text), _) => simulate::truth_from_effects(&study, &simulate::parse_effects(text)?)?,
        (None, Some(path)) => {
            let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
            simulate::truth_from_worths_csv(&study, &text, &path.display().to_string())?
        }
        (None, None) => simulate::default_truth(&study)?,
    };
    let config = Config {
        truth,
        designs: args.designs.clone(),
        participants: participants.iter().map(|&count| count as usize).collect(),
        observer_sd: args.observer_sd,
        lapse: args.lapse,
        dropout: args.dropout,
        runs: args.runs,
        seed: args.seed,
        bootstrap: args.bootstrap,
    };
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("simulating [{bar:30}] {pos}/{len} runs {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let report = simulate::simulate(&study, &config, &|done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    Ok(report?)
}

pub fn run_simulate(args: SimulateArgs) -> Result<()> {
    let report = run_simulation(&args.study, &args.participants)?;
    match args.format {
        Format::Table => print!("{}", report.table()),
        Format::Json => println!("{}", serde_json::to_string_pretty(&report)?),
    }
    if let Some(dir) = &args.plot_dir {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for (name, plot) in report.plots() {
            let path = dir.join(name);
            std::fs::write(&path, line_plot(&plot)).with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    Ok(())
}

pub fn run_power(args: PowerArgs) -> Result<()> {
    anyhow::ensure!(
        args.target_power > 0.0 && args.target_power < 1.0,
        "--target must be between 0 and 1, found {}",
        args.target_power
    );
    let report = run_simulation(&args.study, &args.participants)?;
    anyhow::ensure!(
        !report.truth.effects.is_empty(),
        "the study has no factors, so there is no power per factor to find"
    );
    for line in simulate::power_lines(&simulate::power_needs(&report, args.target_power), args.target_power) {
        println!("{line}");
    }
    Ok(())
}
