//! The QUEST+ part of a threshold study's trials: the study's stimulus domain and QUEST+
//! configuration (`mrstudy_analysis::threshold::quest`), the level after a participant's answers
//! (replayed through a fresh posterior), and the participant's next trial with that level.

use mrstudy_analysis::threshold::quest::{PsychFunction, QuestPlus, QuestPlusConfig, StimScale, StimulusDomain};

use super::{Answer, skeleton};
use crate::schedule::{PlannedKind, PlannedTrial};
use crate::study::Study;
use crate::study::threshold::{Function, Scale, ThresholdDesign};

/// QUEST+'s stimulus domain of the study: its levels with their `intensities`, sorted by
/// intensity, lowest first (so QUEST+'s ties go to the lowest intensity).
pub fn domain(design: &ThresholdDesign, intensities: &[f64]) -> Result<StimulusDomain, NextError> {
    let levels: Vec<f64> = design.levels.iter().map(|&value| f64::from(value)).collect();
    Ok(StimulusDomain::from_intensities(&levels, intensities, stim_scale(design.scale))?)
}

/// Why a threshold participant's next level or trial cannot be chosen.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NextError {
    #[error("not a threshold study")]
    NotThreshold,
    /// The skeleton has no trial `trial` (1-based).
    #[error("the participant has no trial {trial}")]
    NoTrial { trial: usize },
    /// An answer names level index `level`, which the study does not have.
    #[error("no level {level}")]
    NoLevel { level: usize },
    #[error("level {value} is not in the domain")]
    NotInDomain { value: u32 },
    #[error("QUEST+ chose {chosen}, which is not a level")]
    NotALevel { chosen: f64 },
    /// QUEST+ refused the domain or the replay.
    #[error(transparent)]
    Quest(#[from] mrstudy_analysis::threshold::ThresholdError),
}

fn stim_scale(scale: Scale) -> StimScale {
    match scale {
        Scale::Log10 => StimScale::Log10,
        Scale::Decibel => StimScale::Db,
        Scale::Linear => StimScale::Linear,
    }
}

/// The QUEST+ configuration of the study over `domain`: its grids, guess rate and model.
pub fn quest_config(design: &ThresholdDesign, domain: &StimulusDomain) -> QuestPlusConfig {
    QuestPlusConfig {
        x: domain.x.clone(),
        thresholds: design.threshold.clone(),
        slopes: design.slope.clone(),
        lapses: design.lapse.clone(),
        guess: design.guess,
        function: match design.function {
            Function::Weibull => PsychFunction::Weibull,
            Function::Logistic => PsychFunction::Logistic,
            Function::Normal => PsychFunction::Normal,
        },
        scale: stim_scale(design.scale),
    }
}

/// The level (index into the study's levels) QUEST+ shows after `answers`, replayed in order
/// through a fresh posterior; the levels' intensities are `intensities`.
pub fn next_level(design: &ThresholdDesign, intensities: &[f64], answers: &[Answer]) -> Result<usize, NextError> {
    let domain = domain(design, intensities)?;
    let config = quest_config(design, &domain);
    let mut replayed = Vec::with_capacity(answers.len());
    for answer in answers {
        let value = design.levels.get(answer.level).ok_or(NextError::NoLevel { level: answer.level })?;
        let index = domain.index_of_level(f64::from(*value)).ok_or(NextError::NotInDomain { value: *value })?;
        replayed.push((index, answer.correct));
    }
    let quest = QuestPlus::replay(&config, &replayed)?;
    let chosen = domain.levels[quest.next_index()];
    design.levels.iter().position(|&value| f64::from(value) == chosen).ok_or(NextError::NotALevel { chosen })
}

/// Trial `position` (0-based) of the participant with `seed`, whose answered threshold trials so
/// far are `answers`: the skeleton's trial, its level QUEST+'s next one.
pub fn next_trial(
    study: &Study,
    seed: u64,
    position: usize,
    intensities: &[f64],
    answers: &[Answer],
) -> Result<PlannedTrial, NextError> {
    let design = study.threshold.as_ref().ok_or(NextError::NotThreshold)?;
    let mut trial =
        skeleton(study, seed).into_iter().nth(position).ok_or(NextError::NoTrial { trial: position + 1 })?;
    if let PlannedKind::Pair { left, right } = &mut trial.kind {
        let level = next_level(design, intensities, answers)?;
        let truth = study.conditions.len();
        if *left == truth {
            *right = level;
        } else {
            *left = level;
        }
    }
    Ok(trial)
}
