//! `mrstudy stimuli` as a function over a plain [`StimuliRequest`]: load the study, render what
//! its stimulus store lacks (or one shard's share) with its progress, then the metrics CSV and
//! the copies it asks for, saying what was done.

use std::path::PathBuf;
use std::sync::Arc;

use mrstudy_renderer::command::Said;
use thiserror::Error;

use super::{Progress, Shard, StimuliError, StimulusPlan, metrics_csv, render_missing_shard, write_copies};
use crate::study::{StudyError, load_study};

/// `mrstudy stimuli`'s request.
#[derive(Debug, Clone)]
pub struct StimuliRequest {
    /// The study file whose stimuli to render.
    pub study: PathBuf,
    /// The data directory whose `stimuli/` store receives them.
    pub data_dir: PathBuf,
    /// Also write every stimulus of the study here.
    pub out: Option<PathBuf>,
    /// Write the stimulus metrics CSV here.
    pub metrics: Option<PathBuf>,
    /// Render only this share of the scene configurations.
    pub shard: Option<Shard>,
}

/// Why `mrstudy stimuli` stopped.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum StimuliCommandError {
    #[error(
        "--shard {0} renders part of the study; --out and --metrics need all of it: merge the shards' stores first, then run mrstudy stimuli without --shard"
    )]
    ShardWithCopies(Shard),
    #[error(transparent)]
    Study(#[from] StudyError),
    #[error(transparent)]
    Stimuli(#[from] StimuliError),
    #[error("cannot render the stimuli of {}", study.display())]
    Render { study: PathBuf, source: StimuliError },
    #[error("cannot write {}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
    #[error("cannot write the stimuli of {} into {}", study.display(), out.display())]
    Copies { study: PathBuf, out: PathBuf, source: StimuliError },
}

/// Runs `request` as `mrstudy stimuli` does: `progress(slug, step)` follows the rendering (the
/// CLI's bars), `say` gets the notes.
pub fn stimuli_command(
    request: &StimuliRequest,
    progress: &Arc<dyn Fn(&str, &Progress) + Send + Sync>,
    say: &(dyn Fn(Said) + Sync),
) -> Result<(), StimuliCommandError> {
    if let Some(shard) = request.shard
        && (request.out.is_some() || request.metrics.is_some())
    {
        return Err(StimuliCommandError::ShardWithCopies(shard));
    }
    let note = |text: String| say(Said::Note(&text));
    let study = load_study(&request.study)?;
    let store = request.data_dir.join("stimuli");
    let plan = StimulusPlan::of(&study)?;
    // what loading each scene found (a light inside an object, …), once per scene configuration
    for planned in plan.scenes.iter().flatten() {
        planned.scene.warnings.iter().for_each(|warning| note(format!("warning: {}: {warning}", planned.scene.name)));
    }
    if let Some(shard) = request.shard {
        note(plan.shard_line(&study, shard));
    }
    let rendered = render_missing_shard(&study, &plan, &store, request.shard, &|step| progress(&study.slug, &step))
        .map_err(|source| StimuliCommandError::Render { study: request.study.clone(), source })?;
    if let Some(path) = &request.metrics {
        let (csv, notes) = metrics_csv(&study, &plan, &store)?;
        std::fs::write(path, csv).map_err(|source| StimuliCommandError::Write { path: path.clone(), source })?;
        notes.iter().for_each(|text| note(format!("note: {text}")));
        note(format!("wrote the stimulus metrics to {}", path.display()));
    }
    if let Some(out) = &request.out {
        let copies = |source| StimuliCommandError::Copies { study: request.study.clone(), out: out.clone(), source };
        let written = write_copies(&study, &plan, &store, out).map_err(copies)?;
        note(format!("wrote {written} stimuli into {}", out.display()));
    }
    // what the stored records warn of (the statistics colour mapping's ratios), once per scene
    // configuration, also when nothing was rendered this time
    let warnings = super::warnings::stored_warnings(&study, &plan, &store);
    warnings.iter().for_each(|line| note(format!("warning: {line}")));
    note(plan.rendered_line(&study, &rendered, &store, request.shard));
    Ok(())
}
