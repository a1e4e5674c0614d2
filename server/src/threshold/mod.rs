//! Threshold studies' trials (`kind = "threshold"`): which level each trial shows, chosen by the
//! participant's own QUEST+ posterior (`mrstudy_analysis::threshold::quest`), and the rest of
//! the trial (scene configuration, side of the ground truth, catch trials) from their seed.
//!
//! **One posterior per participant**, over all their scene configurations: the threshold is a
//! property of the observer and the knob that the study asks about, and 40 trials split over
//! three scene configurations would leave each posterior with about 13 answers, too few for
//! QUEST+ to settle (its threshold and slope grids need tens of answers). Differences between
//! scene configurations are the analysis's to find (a fit per scene configuration).
//!
//! **The skeleton** of a participant's trials is fixed by their seed alone ([`skeleton`]): it is
//! the detection design's schedule ([`schedule::plan_detection`]) of `trials` trials against the
//! ground truth — sides balanced over the participant's trials, scene configurations balanced
//! and never twice in a row (as in "real or rendered?"), each scene configuration's sensor-noise
//! realisations in turn — with the catch trials at random places. Only the level of each
//! threshold trial is left open: when the participant reaches the trial, [`next_trial`] replays
//! their answers so far through a fresh QUEST+ (answers are stored durably, one committed row
//! each, before their 201) and takes its next level. Replay is deterministic, so the level a
//! reload, another server or a restart computes is the level stored; the trial is stored when
//! first chosen and never chosen again.

use mrstudy_analysis::stimulus_metrics::{Metric, Region, StimulusMetrics};

mod next;
pub use next::{NextError, domain, next_level, next_trial, quest_config};

use crate::schedule::{self, PlannedTrial};
use crate::study::threshold::{Intensity, ThresholdDesign};
use crate::study::{GROUND_TRUTH, Study};

/// One answered threshold trial: the level shown and whether the ground truth was picked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Answer {
    pub level: usize,
    pub correct: bool,
}

/// The participant's trials with every threshold trial at level 0 (its level is chosen when the
/// trial is reached, [`next_trial`]); catch trials as planned.
pub fn skeleton(study: &Study, seed: u64) -> Vec<PlannedTrial> {
    let Some(design) = &study.threshold else { return schedule::plan(study, seed) };
    let truth = study.conditions.len();
    let mut shape = study.clone();
    shape.design.pairs = vec![(0, truth); design.trials as usize];
    shape.design.repetitions = 1;
    shape.threshold = None;
    schedule::plan_detection(&shape, seed)
}

/// Each level's intensity: from the knob value (`knob`, `inverse-knob`), or the mean over the
/// study's scene configurations of the metric of the level's stimuli (`metric:<m>:<region>`,
/// realisation 0's records). An error names what is missing.
pub fn intensities(study: &Study, metrics: Option<&StimulusMetrics>) -> Result<Vec<f64>, ThresholdStudyError> {
    let design = study.threshold.as_ref().ok_or(ThresholdStudyError::NotThreshold)?;
    if let Some(intensities) = design.intensities.clone().or_else(|| design.knob_intensities()) {
        return Ok(intensities);
    }
    let Intensity::Metric { metric, region } = &design.intensity else { unreachable!("knob intensities above") };
    let (Some(metric_kind), Some(region_kind)) = (Metric::parse(metric), Region::parse(region)) else {
        return Err(ThresholdStudyError::UnknownMetric { metric: metric.clone(), region: region.clone() });
    };
    let metrics = metrics.ok_or(ThresholdStudyError::NoRecords)?;
    let mut intensities = Vec::with_capacity(design.levels.len());
    for condition in &study.conditions {
        let values: Vec<f64> =
            metrics.of_condition(&condition.name).filter_map(|record| record.value(metric_kind, region_kind)).collect();
        if values.is_empty() {
            return Err(ThresholdStudyError::NoStimulus {
                level: condition.name.clone(),
                metric: metric.clone(),
                region: region.clone(),
            });
        }
        intensities.push(values.iter().sum::<f64>() / values.len() as f64);
    }
    Ok(intensities)
}

/// Fills in a threshold study's intensities (a metric intensity's from the stimulus records)
/// and checks that every level has an x and the threshold grid reaches into their range: the
/// check a metric intensity could not have when the file was loaded. One sentence on failure.
pub fn prepare(study: &mut Study, metrics: Option<&StimulusMetrics>) -> Result<(), ThresholdStudyError> {
    if study.threshold.is_none() {
        return Ok(());
    }
    let intensities =
        intensities(study, metrics).map_err(|reason| ThresholdStudyError::Intensities(Box::new(reason)))?;
    let fail = crate::study::checks::Fail(&study.file);
    let design = study.threshold.as_mut().expect("a threshold study");
    crate::study::threshold::check_grid_covers(fail, design, &intensities)
        .map_err(|error| ThresholdStudyError::Grid(Box::new(error)))?;
    design.intensities = Some(intensities);
    Ok(())
}

/// Why a threshold study's intensities cannot be found, or its grid does not fit them.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ThresholdStudyError {
    #[error("not a threshold study")]
    NotThreshold,
    #[error("the metric \"{metric}\" in region \"{region}\" is not one the stimulus records keep")]
    UnknownMetric { metric: String, region: String },
    #[error("the stimuli have no records of their errors against the ground truth")]
    NoRecords,
    /// No stimulus of level (condition) `level` has the metric.
    #[error("no stimulus of level \"{level}\" has a {metric} in region {region}")]
    NoStimulus { level: String, metric: String, region: String },
    /// [`prepare`]: the intensities are missing for this reason.
    #[error("the intensities of its levels cannot be found: {0}")]
    Intensities(Box<ThresholdStudyError>),
    /// [`prepare`]: the threshold grid does not reach into the levels' x range.
    #[error("{0}")]
    Grid(Box<crate::study::StudyError>),
}

/// The threshold export's cells ([`crate::study::threshold::CSV_COLUMNS`]) of one answered
/// trial between `left` and `right` (condition names, one of them the ground truth), `chosen`
/// the name picked, shown in scene configuration `scene`. Empty cells where the trial is not a
/// level against the ground truth.
pub fn csv_cells(design: &ThresholdDesign, left: &str, right: &str, chosen: &str, scene: &str) -> Vec<String> {
    let shown = if left == GROUND_TRUTH { right } else { left };
    let level = design.level_of(shown);
    let intensity = level.and_then(|level| design.intensities.as_ref().and_then(|all| all.get(level).copied()));
    let x = intensity.and_then(|intensity| design.scale.x(intensity));
    let number = |value: Option<f64>| value.map(crate::study::format_number).unwrap_or_default();
    vec![
        // a scene configuration's name never starts like a spreadsheet formula (`is_condition_name`)
        scene.to_string(),
        design.knob.name().to_string(),
        level.map(|level| design.levels[level].to_string()).unwrap_or_default(),
        number(intensity),
        number(x),
        if level.is_some() { (chosen == GROUND_TRUTH).to_string() } else { String::new() },
        design.function.name().to_string(),
        design.scale.name().to_string(),
        crate::study::format_number(design.guess),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::schedule::PlannedKind;

    fn study() -> Study {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("t.toml");
        let text = crate::study::threshold_tests::THRESHOLD.replace("trials = 40", "trials = 12");
        std::fs::write(
            &file,
            format!("{text}\n[[catch]]\nname = \"c\"\nbetter = \"b.png\"\nworse = \"w.png\"\nrepetitions = 2\n"),
        )
        .unwrap();
        for name in ["b.png", "w.png"] {
            mrstudy_renderer::Image::new(2, 2).save_png(&dir.path().join(name)).unwrap();
        }
        crate::study::load_study(&file).unwrap()
    }

    #[test]
    fn the_skeleton_balances_sides_and_scenes_and_places_the_catch_trials() {
        let study = study();
        let truth = study.conditions.len();
        let trials = skeleton(&study, 7);
        assert_eq!(trials.len(), 14);
        let pairs: Vec<&PlannedTrial> = trials.iter().filter(|t| matches!(t.kind, PlannedKind::Pair { .. })).collect();
        assert_eq!(pairs.len(), 12);
        let truth_left =
            pairs.iter().filter(|t| matches!(t.kind, PlannedKind::Pair { left, .. } if left == truth)).count();
        assert_eq!(truth_left, 6);
        let first_scene = pairs.iter().filter(|t| t.left_scene == 0).count();
        assert_eq!(first_scene, 6);
        assert_eq!(skeleton(&study, 7), trials, "the seed alone fixes the skeleton");
    }
}
