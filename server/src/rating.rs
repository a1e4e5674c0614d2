//! Rating studies' trials (`kind = "rating"`, ITU-T P.910's ACR, DCR and ACR-HR): which
//! stimulus each trial shows, planned at join from the participant's seed, and the rating
//! export's own cells.
//!
//! **The plan** ([`plan`]): every stimulus of the study — each scene configuration under each
//! condition, and in ACR-HR each scene configuration's ground truth (the hidden reference) —
//! `repetitions` times, and each catch trial its `repetitions` times, in a uniformly random
//! order drawn from the participant's seed (the schedules' ChaCha8 stream,
//! [`crate::schedule`]); where it can, no stimulus comes twice in a row (a later trial is
//! swapped in). The plan is a pure function of the study and the seed, so the stored seed
//! reproduces it; `crate::prepared` turns it into stored trials (the rated stimulus on the left,
//! DCR's reference on the right).

use crate::schedule::Stream;
use crate::study::Study;
use crate::study::rating::{Method, RatingDesign};

/// One planned rating trial, before stimuli are attached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RatedTrial {
    /// Scene configuration `scene` under condition `condition` (indices into the study's).
    Condition { scene: usize, condition: usize },
    /// ACR-HR: the ground truth of scene configuration `scene`, rated as one more stimulus.
    HiddenReference { scene: usize },
    /// Catch trial `index` of `[[rating.catch]]`.
    Catch { index: usize },
}

/// The trials of the participant with this seed (empty for a study that is not a rating study).
pub fn plan(study: &Study, seed: u64) -> Vec<RatedTrial> {
    let Some(design) = &study.rating else { return Vec::new() };
    let mut trials = Vec::with_capacity(study.trial_count());
    for _ in 0..design.repetitions {
        for scene in 0..study.scenes.len() {
            for condition in 0..study.conditions.len() {
                trials.push(RatedTrial::Condition { scene, condition });
            }
            if design.method == Method::AcrHr {
                trials.push(RatedTrial::HiddenReference { scene });
            }
        }
    }
    for (index, catch) in design.catch.iter().enumerate() {
        trials.extend(std::iter::repeat_n(RatedTrial::Catch { index }, catch.repetitions as usize));
    }
    let mut stream = Stream::seeded(seed);
    stream.shuffle(&mut trials);
    // no stimulus twice in a row: swap in the next different one (none when all are the same)
    for index in 1..trials.len() {
        if trials[index] == trials[index - 1]
            && let Some(other) = (index + 1..trials.len()).find(|&other| trials[other] != trials[index - 1])
        {
            trials.swap(index, other);
        }
    }
    trials
}

/// The rating export's own cells of one row (`scene,condition,rating,method,reference,scale,
/// catch,expected`, docs/design.md), from the stored trial (`left_*`: the stimulus rated,
/// `right_condition`: the reference shown, if any) and its rating.
pub fn csv_cells(
    design: &RatingDesign,
    scene: &str,
    condition: &str,
    rating: i64,
    catch_rating: Option<i64>,
) -> Vec<String> {
    // DCR's shown reference, ACR-HR's hidden one (its own rows have condition `ground-truth`)
    let reference = design.method.reference();
    vec![
        scene.to_string(),
        condition.to_string(),
        rating.to_string(),
        design.method.name().to_string(),
        reference.to_string(),
        design.method.scale().name().to_string(),
        catch_rating.is_some().to_string(),
        catch_rating.map(|expected| expected.to_string()).unwrap_or_default(),
    ]
}
