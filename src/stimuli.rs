//! `mrstudy stimuli`: its flags, run by `mrstudy_server::stimuli::command` (a study's missing
//! stimuli, or one shard's, rendered into the stimulus store) with the stimulus bars.

use std::path::PathBuf;

use crate::Say;
use anyhow::Result;
use mrstudy_server::console::stimulus_bars;
use mrstudy_server::stimuli::{self, command::StimuliRequest};

flags! {
    StimuliArgs => StimuliRequest {} {
        /// The study file (TOML) whose stimuli to render.
        #[arg(long)] study: PathBuf,
        /// Data directory whose stimulus store receives them (the one `mrstudy serve` uses).
        #[arg(long, default_value = "./mrstudy-data")] data_dir: PathBuf,
        /// Also write every stimulus of the study here as `<scene>__<condition>.png` (rendered now, rendered before, or an image file of the study).
        #[arg(long)] out: Option<PathBuf>,
        /// Write each stimulus's errors against its ground truth here (docs/design.md's stimulus metrics CSV: `stimulus,scene,condition,metric,region,value`).
        #[arg(long)] metrics: Option<PathBuf>,
        /// Render only share K of N (e.g. 3/8) of the study's scene configurations, for a cluster's job array; merge the shards' stores by copying (docs/cluster.md).
        #[arg(long, value_parser = stimuli::Shard::parse)] shard: Option<stimuli::Shard>,
    }
}

pub fn run(args: StimuliArgs, say: Say) -> Result<()> {
    Ok(stimuli::command::stimuli_command(&args.into(), &stimulus_bars(), say)?)
}
