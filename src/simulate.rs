//! `mrstudy simulate` and `mrstudy power`: their flags, run by `mrstudy_server::simulate::command`
//! (the table or JSON, the plots, `power`'s sentences) on the console.

use std::path::PathBuf;

use crate::Say;
use anyhow::Result;
use mrstudy_analysis::command::Format;
use mrstudy_server::simulate::command::{StudyRequest, power_command, simulate_command};
use mrstudy_server::simulate::{self, DesignChoice, Options};

flags! {
    /// What `simulate` and `power` share: the study, the truth, the observers, the runs.
    StudyArgs => StudyRequest {} {
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
        /// Designs side by side: `study` (the file's), `all`, `anchored`, `active` (at equal trials; target factors where a factor varies), `active-worths` (target worths), `active-both` (target both), `active-spread` (target worths, prior spread: optimises the centred MAP log-worths).
        #[arg(long, value_delimiter = ',', default_value = "study", value_parser = crate::choice(DesignChoice::parse, "study, all, anchored, active, active-worths, active-both, active-spread"))] designs: Vec<DesignChoice>,
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
        #[arg(long, default_value = "table", value_parser = crate::values(Format::NAMES))] format: Format,
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

pub fn run_simulate(args: SimulateArgs, say: Say) -> Result<()> {
    let json = args.format == Format::Json;
    let study = args.study.into();
    Ok(simulate_command(&study, &args.participants, json, args.plot_dir.as_deref(), say)?)
}

pub fn run_power(args: PowerArgs, say: Say) -> Result<()> {
    Ok(power_command(&args.study.into(), &args.participants, args.target_power, say)?)
}
