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
pub fn domain(design: &ThresholdDesign, intensities: &[f64]) -> Result<StimulusDomain, String> {
    let levels: Vec<f64> = design.levels.iter().map(|&value| f64::from(value)).collect();
    StimulusDomain::from_intensities(&levels, intensities, stim_scale(design.scale)).map_err(|error| error.to_string())
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
pub fn next_level(design: &ThresholdDesign, intensities: &[f64], answers: &[Answer]) -> Result<usize, String> {
    let domain = domain(design, intensities)?;
    let config = quest_config(design, &domain);
    let mut replayed = Vec::with_capacity(answers.len());
    for answer in answers {
        let value = design.levels.get(answer.level).ok_or_else(|| format!("no level {}", answer.level))?;
        let index =
            domain.index_of_level(f64::from(*value)).ok_or_else(|| format!("level {value} is not in the domain"))?;
        replayed.push((index, answer.correct));
    }
    let quest = QuestPlus::replay(&config, &replayed).map_err(|error| error.to_string())?;
    let chosen = domain.levels[quest.next_index()];
    design
        .levels
        .iter()
        .position(|&value| f64::from(value) == chosen)
        .ok_or_else(|| format!("QUEST+ chose {chosen}, which is not a level"))
}

/// Trial `position` (0-based) of the participant with `seed`, whose answered threshold trials so
/// far are `answers`: the skeleton's trial, its level QUEST+'s next one.
pub fn next_trial(
    study: &Study,
    seed: u64,
    position: usize,
    intensities: &[f64],
    answers: &[Answer],
) -> Result<PlannedTrial, String> {
    let design = study.threshold.as_ref().ok_or("not a threshold study")?;
    let mut trial = skeleton(study, seed)
        .into_iter()
        .nth(position)
        .ok_or_else(|| format!("the participant has no trial {}", position + 1))?;
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
