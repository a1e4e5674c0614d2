//! `mrstudy stimuli`: progress bars around `mrstudy_server::stimuli`, which renders a study's
//! missing stimuli (or one shard's) into the stimulus store.

use std::path::PathBuf;

use anyhow::{Context, Result};
use mrstudy_server::stimuli;

flags! {
    StimuliArgs {
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

pub fn run(args: StimuliArgs) -> Result<()> {
    if let Some(shard) = args.shard
        && (args.out.is_some() || args.metrics.is_some())
    {
        anyhow::bail!(
            "--shard {shard} renders part of the study; --out and --metrics need all of it: merge the shards' stores first, then run mrstudy stimuli without --shard"
        );
    }
    let study = mrstudy_server::study::load_study(&args.study)?;
    let store = args.data_dir.join("stimuli");
    let progress = crate::progress::stimulus_bars();
    let slug = study.slug.clone();
    let plan = stimuli::StimulusPlan::of(&study)?;
    // what loading each scene found (a light inside an object, …), once per scene configuration
    for planned in plan.scenes.iter().flatten() {
        planned.scene.warnings.iter().for_each(|warning| eprintln!("warning: {}: {warning}", planned.scene.name));
    }
    if let Some(shard) = args.shard {
        eprintln!("{}", plan.shard_line(&study, shard));
    }
    let rendered = stimuli::render_missing_shard(&study, &plan, &store, args.shard, &|step| progress(&slug, &step))
        .with_context(|| format!("cannot render the stimuli of {}", args.study.display()))?;
    if let Some(path) = &args.metrics {
        let (csv, notes) = stimuli::metrics_csv(&study, &plan, &store)?;
        crate::write_file(path, &csv)?;
        notes.iter().for_each(|note| eprintln!("note: {note}"));
        eprintln!("wrote the stimulus metrics to {}", path.display());
    }
    if let Some(out) = &args.out {
        let written = stimuli::write_copies(&study, &plan, &store, out)
            .with_context(|| format!("cannot write the stimuli of {} into {}", args.study.display(), out.display()))?;
        eprintln!("wrote {written} stimuli into {}", out.display());
    }
    eprintln!("{}", plan.rendered_line(&study, &rendered, &store, args.shard));
    Ok(())
}
