//! `mrstudy simulate` and `mrstudy power`: read the study and the truth, call
//! `mrstudy_server::simulate` with a progress bar, print the table or JSON, draw the plots.

use std::path::PathBuf;

use anyhow::Result;
use mrstudy_analysis::plot::line_plot;
use mrstudy_server::simulate::{self, Config, DesignChoice, Options, Report};

use crate::Format;
use crate::progress::progress_bar;

mod threshold;

flags! {
    /// What `simulate` and `power` share: the study, the truth, the observers, the runs.
    StudyArgs {
        /// The study file (`studies/*.toml`); its scheduler and conditions are simulated.
        #[arg(long)] study: PathBuf,
        /// True factor effects on the logit scale, e.g. `gi=0.3,cm=-0.2,ca=0.4` (a factor not named: 0). Default: the thesis's gi 0.27, cm −0.22, ca 0.43 for a study with factors gi, cm, ca. A threshold study: `threshold=T,slope=B` (x units) of the simulated observers' psychometric function.
        #[arg(long, conflicts_with = "truth_worth", allow_hyphen_values = true)] truth: Option<String>,
        /// True log-worths: a CSV `condition,log_worth` with every condition of the study.
        #[arg(long)] truth_worth: Option<PathBuf>,
        #[command(flatten)] options: OptionsFlags,
        /// Threshold studies: trials per participant to simulate (QUEST+ and constant stimuli at each).
        #[arg(long, value_delimiter = ',', default_value = "10,20,40,80,160", value_parser = clap::value_parser!(u32).range(1..))] trials_per_participant: Vec<u32>,
    }
}

flags! {
    /// [`simulate::Options`]' flags and their defaults.
    OptionsFlags => Options {} {
        /// Designs side by side: `study` (the file's), `all`, `anchored`, `active` (at equal trials; target factors where a factor varies), `active-worths` (target worths), `active-both` (target both).
        #[arg(long, value_delimiter = ',', default_value = "study", value_parser = crate::choice(DesignChoice::parse, "study, all, anchored, active, active-worths, active-both"))] designs: Vec<DesignChoice>,
        /// Per-participant taste noise: sd of each condition's log-worth (a threshold study: sd of a participant's threshold, x units).
        #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)] observer_sd: f64,
        /// Probability that an answer is a coin flip.
        #[arg(long, default_value_t = 0.02, allow_negative_numbers = true)] lapse: f64,
        /// Probability that a participant stops after each trial.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)] dropout: f64,
        /// Studies with `allow_tie = true`: Davidson's ν of the simulated observers ("not sure" is ν/(2 + ν) of the answers between equal conditions).
        #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)] tie_nu: f64,
        /// Simulated studies per design and participant count.
        #[arg(long, default_value_t = 200)] runs: usize,
        #[arg(long, default_value_t = 1)] seed: u64,
        /// Bootstrap replicates per analysis for the intervals (0: Wald intervals).
        #[arg(long, default_value_t = 0)] bootstrap: usize,
    }
}

flags! {
    SimulateArgs {
        #[command(flatten)] study: StudyArgs,
        /// Participant counts to simulate.
        #[arg(long, value_delimiter = ',', default_value = "10,20,40,80", value_parser = clap::value_parser!(u32).range(1..))] participants: Vec<u32>,
        #[arg(long, value_enum, default_value = "table")] format: Format,
        /// Write the plots (simulate-rmse.svg, simulate-power.svg) into this directory.
        #[arg(long)] plot_dir: Option<PathBuf>,
    }
}

flags! {
    PowerArgs {
        #[command(flatten)] study: StudyArgs,
        /// Participant counts to simulate.
        #[arg(long, value_delimiter = ',', default_value = "10,20,40,80,160", value_parser = clap::value_parser!(u32).range(1..))] participants: Vec<u32>,
        /// The power to reach (docs/design.md's `--target`; `--target-power` is the same).
        #[arg(long = "target", visible_alias = "target-power", default_value = "0.8", value_parser = simulate::parse_target)] target_power: f64,
    }
}

fn run_simulation(args: StudyArgs, participants: &[u32]) -> Result<Report> {
    let study = mrstudy_server::study::load_study(&args.study)?;
    let worths = args.truth_worth.as_deref().map(crate::read_text).transpose()?;
    let truth =
        simulate::choose_truth(&study, args.truth.as_deref(), worths.as_ref().map(|(t, n)| (t.as_str(), n.as_str())))?;
    let participants = participants.iter().map(|&count| count as usize).collect();
    let config = Config { truth, participants, options: args.options.into() };
    let bar = progress_bar(0, "simulating", "runs");
    let report = simulate::simulate(&study, &config, &|done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    Ok(report?)
}

pub fn run_simulate(args: SimulateArgs) -> Result<()> {
    if let Some(study) = threshold::threshold_study(&args.study)? {
        return threshold::run_simulate(&args, &study);
    }
    let report = run_simulation(args.study, &args.participants)?;
    match args.format {
        Format::Table => print!("{}", report.table()),
        Format::Json => println!("{}", serde_json::to_string_pretty(&report)?),
    }
    if let Some(dir) = &args.plot_dir {
        crate::write_into(dir, report.plots().into_iter().map(|(name, plot)| (name, line_plot(&plot))))?;
    }
    Ok(())
}

pub fn run_power(args: PowerArgs) -> Result<()> {
    if let Some(study) = threshold::threshold_study(&args.study)? {
        return threshold::run_power(&args, &study);
    }
    let report = run_simulation(args.study, &args.participants)?;
    simulate::power_report(&report, args.target_power)?.iter().for_each(|line| println!("{line}"));
    Ok(())
}
