//! `mrstudy stimuli` and the start-up rendering of `mrstudy serve`: progress bars around
//! `mrstudy_server::stimuli`, which renders a study's missing stimuli into the stimulus store.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result};
use clap::Args;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use mrstudy_server::stimuli::{self, Progress};

#[derive(Args)]
pub struct StimuliArgs {
    /// The study file (TOML) whose stimuli to render.
    #[arg(long)]
    study: PathBuf,
    /// Data directory whose stimulus store receives them (the one `mrstudy serve` uses).
    #[arg(long, default_value = "./mrstudy-data")]
    data_dir: PathBuf,
    /// Also write every stimulus of the study here as `<scene>__<condition>.png` (rendered now,
    /// rendered before, or an image file of the study).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write each stimulus's errors against its ground truth here (DESIGN.md's stimulus metrics
    /// CSV: `stimulus,scene,condition,metric,region,value`).
    #[arg(long)]
    metrics: Option<PathBuf>,
    /// Render only share K of N (e.g. 3/8) of the study's scene configurations, for a cluster's
    /// job array; merge the shards' stores by copying (docs/cluster.md).
    #[arg(long, value_parser = stimuli::Shard::parse)]
    shard: Option<stimuli::Shard>,
}

/// Progress bars for rendering: one for the photograph being path-traced, one for the stimuli.
pub fn progress_bars() -> Arc<dyn Fn(&str, &Progress) + Send + Sync> {
    let bars = MultiProgress::new();
    let state: Mutex<Option<(ProgressBar, ProgressBar)>> = Mutex::new(None);
    Arc::new(move |slug: &str, step: &Progress| {
        let mut state = state.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        match step {
            Progress::Start { photos, stimuli } => {
                let style =
                    ProgressStyle::with_template("{msg:40} [{bar:30}] {pos}/{len} {elapsed_precise} (eta {eta})")
                        .unwrap_or_else(|_| ProgressStyle::default_bar())
                        .progress_chars("=> ");
                let photo = bars.add(ProgressBar::new(1).with_style(style.clone()));
                let frames = bars.add(ProgressBar::new(*stimuli as u64).with_style(style));
                frames.set_message(format!("{slug}: {stimuli} stimuli ({photos} photographs first)"));
                *state = Some((photo, frames));
            }
            Progress::Photo { scene, done, total } => {
                if let Some((photo, _)) = state.as_ref() {
                    photo.set_length(*total as u64);
                    photo.set_position(*done as u64);
                    photo.set_message(format!("photograph {scene} (spp)"));
                }
            }
            Progress::Stimulus { scene, condition, .. } => {
                if let Some((photo, frames)) = state.as_ref() {
                    frames.inc(1);
                    frames.set_message(format!("{slug}: {scene} {condition}"));
                    if frames.position() == frames.length().unwrap_or(0) {
                        photo.finish_and_clear();
                        frames.finish_and_clear();
                    }
                }
            }
        }
    })
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
    let progress = progress_bars();
    let slug = study.slug.clone();
    let plan = stimuli::StimulusPlan::of(&study)?;
    if let Some(shard) = args.shard {
        let owned = plan.shard_scenes(shard);
        let names: Vec<&str> = owned.iter().map(|&index| study.scenes[index].name.as_str()).collect();
        eprintln!(
            "shard {shard}: {} of the study's {} rendered scene configurations{}",
            owned.len(),
            plan.scenes.iter().flatten().count(),
            if names.is_empty() {
                " (nothing to do: more shards than scene configurations)".to_string()
            } else {
                format!(": {}", names.join(", "))
            }
        );
    }
    let rendered = stimuli::render_missing_shard(&study, &plan, &store, args.shard, &|step| progress(&slug, &step))
        .with_context(|| format!("cannot render the stimuli of {}", args.study.display()))?;
    if let Some(path) = &args.metrics {
        let (csv, notes) = stimuli::metrics_csv(&study, &plan, &store)?;
        std::fs::write(path, csv).with_context(|| format!("cannot write {}", path.display()))?;
        for note in notes {
            eprintln!("note: {note}");
        }
        eprintln!("wrote the stimulus metrics to {}", path.display());
    }
    if let Some(out) = &args.out {
        let written = stimuli::write_copies(&study, &plan, &store, out)
            .with_context(|| format!("cannot write the stimuli of {} into {}", args.study.display(), out.display()))?;
        eprintln!("wrote {written} stimuli into {}", out.display());
    }
    let total = match args.shard {
        Some(shard) => plan.stimuli_in(&plan.shard_scenes(shard)),
        None => plan.stimuli().count(),
    };
    eprintln!(
        "study \"{}\": rendered {} stimuli, {} were already in {} ({total} rendered stimuli in all); {} ground truths and {} stimulus records made",
        study.slug,
        rendered.stimuli,
        total - rendered.stimuli,
        store.display(),
        rendered.ground_truths,
        rendered.records
    );
    Ok(())
}
