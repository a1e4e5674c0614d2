//! `mrstudy simulate` and `mrstudy power` on a threshold study (`kind = "threshold"`): the
//! flags into `mrstudy_server::simulate::threshold::ThresholdConfig`, the table or JSON, the
//! plots, `power`'s sentences.

use anyhow::{Result, bail};
use mrstudy_analysis::plot::line_plot;
use mrstudy_server::simulate::DesignChoice;
use mrstudy_server::simulate::threshold::{ThresholdConfig, ThresholdReport, simulate_threshold};
use mrstudy_server::study::Study;

use super::{PowerArgs, SimulateArgs, StudyArgs};
use crate::Format;
use crate::progress::progress_bar;

/// The study of `args` when it is a threshold study.
pub(super) fn threshold_study(args: &StudyArgs) -> Result<Option<Study>> {
    let study = mrstudy_server::study::load_study(&args.study)?;
    Ok(study.threshold.is_some().then_some(study))
}

fn run(args: &StudyArgs, study: &Study) -> Result<ThresholdReport> {
    if args.truth_worth.is_some() {
        bail!("--truth-worth gives log-worths of conditions; a threshold study takes --truth threshold=T,slope=B");
    }
    if args.options.dropout != 0.0 {
        bail!("--dropout does not apply to a threshold study (every simulated participant answers all trials)");
    }
    if args.options.designs != [DesignChoice::Study] {
        bail!("--designs does not apply to a threshold study: QUEST+ and constant stimuli are always compared");
    }
    let config = ThresholdConfig {
        trials: args.trials_per_participant.iter().map(|&n| n as usize).collect(),
        truth: args.truth.clone(),
        threshold_sd: args.options.observer_sd,
        lapse: args.options.lapse,
        runs: args.options.runs,
        seed: args.options.seed,
        bootstrap: args.options.bootstrap,
    };
    let bar = progress_bar(0, "simulating", "participants");
    let report = simulate_threshold(study, &config, &|done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    Ok(report?)
}

pub(super) fn run_simulate(args: &SimulateArgs, study: &Study) -> Result<()> {
    let report = run(&args.study, study)?;
    match args.format {
        Format::Table => print!("{}", report.table()),
        Format::Json => println!("{}", serde_json::to_string_pretty(&report)?),
    }
    if let Some(dir) = &args.plot_dir {
        crate::write_into(dir, report.plots().into_iter().map(|(name, plot)| (name, line_plot(&plot))))?;
    }
    Ok(())
}

pub(super) fn run_power(args: &PowerArgs, study: &Study) -> Result<()> {
    let report = run(&args.study, study)?;
    report.power_lines(args.target_power).iter().for_each(|line| println!("{line}"));
    Ok(())
}
