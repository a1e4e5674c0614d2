//! A simulated observer that learns repeated pictures, run through a detection design ("real or
//! rendered?") to measure whether remembering pictures tells the answer.
//!
//! **Observer.** It has no sense of realism at all — it stands for a rendering equal to the
//! ground truth, where the detection rate of an honest design is 0.5 — but a perfect picture
//! memory: it counts every picture it has been shown (both sides of every earlier trial) and in
//! each trial picks the picture it has seen more often, a coin flip on a tie. This is the
//! familiarity heuristic in its strongest form (picture memory after one exposure: Standing
//! 1973, Brady et al. 2008; repetition taken for truth, for statements: Hasher, Goldstein &
//! Toppino 1977; `docs/studies.md`). Two memories:
//!
//! - [`Memory::Exact`]: a picture is a file — scene configuration, sensor-noise realisation and
//!   condition (or the ground truth); two realisations of one scene configuration are two
//!   pictures;
//! - [`Memory::Gist`]: a picture is what a person remembers of it — scene configuration and
//!   condition; the noise realisation is not remembered, so realisations of one picture are the
//!   same picture.
//!
//! **Scores.** Over `participants` simulated participants with schedule seeds
//! `derived_seed(seed, k)`: the detection rate (ground truth chosen / detection trials) with
//! its binomial standard error, and the share of trials in which familiarity was informative
//! (the two pictures' counts differed). A design keeps familiarity from telling the answer for
//! a memory when no trial is informative to it: then its rate is exactly a coin's.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use serde::Serialize;

use crate::schedule::{PlannedKind, PlannedTrial, derived_seed};
use crate::study::Study;

/// What the observer takes to be the same picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Memory {
    /// The same file: scene configuration, realisation and condition.
    Exact,
    /// The same scene configuration and condition, whatever the noise realisation.
    Gist,
}

/// The learning observer's results on one design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FamiliarityScore {
    pub memory: Memory,
    pub participants: usize,
    /// Detection trials simulated.
    pub trials: u64,
    /// Trials in which the ground truth was chosen.
    pub correct: u64,
    /// `correct / trials`: 0.5 where familiarity tells nothing.
    pub rate: f64,
    /// Binomial standard error of `rate`.
    pub se: f64,
    /// Trials in which one picture had been seen more often than the other.
    pub informative: u64,
    /// Of those, the ones in which the ground truth was the more familiar picture.
    pub informative_toward_truth: u64,
}

/// Runs `participants` learning observers with `memory` through the schedules `schedule` makes
/// of `study` (a detection design), participant k's seed `derived_seed(seed, k)`.
pub fn learning_observer(
    study: &Study,
    schedule: &dyn Fn(&Study, u64) -> Vec<PlannedTrial>,
    memory: Memory,
    participants: usize,
    seed: u64,
) -> FamiliarityScore {
    let truth = study.conditions.len();
    let (mut trials, mut correct, mut informative, mut toward_truth) = (0u64, 0u64, 0u64, 0u64);
    for participant in 0..participants {
        let participant_seed = derived_seed(seed, participant as u64);
        let mut coin = ChaCha8Rng::seed_from_u64(derived_seed(participant_seed, 1));
        // pictures seen and how often: (scene, realisation or 0 for gist, condition index)
        let mut seen: std::collections::HashMap<(usize, usize, usize), u32> = std::collections::HashMap::new();
        for trial in schedule(study, participant_seed) {
            let PlannedKind::Pair { left, right } = trial.kind else { continue };
            if left != truth && right != truth {
                continue;
            }
            let realisation = match memory {
                Memory::Exact => trial.realisation,
                Memory::Gist => 0,
            };
            let picture = |condition: usize, scene: usize| (scene, realisation, condition);
            let (left_picture, right_picture) = (picture(left, trial.left_scene), picture(right, trial.right_scene));
            let left_count = seen.get(&left_picture).copied().unwrap_or(0);
            let right_count = seen.get(&right_picture).copied().unwrap_or(0);
            let picks_left = match left_count.cmp(&right_count) {
                std::cmp::Ordering::Greater => true,
                std::cmp::Ordering::Less => false,
                std::cmp::Ordering::Equal => coin.next_u64() >> 63 == 1,
            };
            if left_count != right_count {
                informative += 1;
                let truth_count = if left == truth { left_count } else { right_count };
                if truth_count == left_count.max(right_count) {
                    toward_truth += 1;
                }
            }
            trials += 1;
            if picks_left == (left == truth) {
                correct += 1;
            }
            *seen.entry(left_picture).or_default() += 1;
            *seen.entry(right_picture).or_default() += 1;
        }
    }
    let rate = if trials == 0 { 0.5 } else { correct as f64 / trials as f64 };
    let se = if trials == 0 { 0.0 } else { (rate * (1.0 - rate) / trials as f64).sqrt() };
    FamiliarityScore {
        memory,
        participants,
        trials,
        correct,
        rate,
        se,
        informative,
        informative_toward_truth: toward_truth,
    }
}

/// One row of [`compare_designs`]: a design's name and its scores for both memories.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignFamiliarity {
    pub design: String,
    pub exact: FamiliarityScore,
    pub gist: FamiliarityScore,
}

/// The learning observer on three designs of `study` (a detection design): version 1 of the
/// schedule with one realisation (the design before), version 2 with one realisation (balance
/// and no repeats in a row only), and version 2 with the study's realisations.
pub fn compare_designs(study: &Study, participants: usize, seed: u64) -> Vec<DesignFamiliarity> {
    let mut single = study.clone();
    single.design.realisations = 1;
    let v1: &dyn Fn(&Study, u64) -> Vec<PlannedTrial> = &crate::schedule::plan_detection_v1;
    let v2: &dyn Fn(&Study, u64) -> Vec<PlannedTrial> = &crate::schedule::plan_detection;
    let row = |design: String, study: &Study, schedule: &dyn Fn(&Study, u64) -> Vec<PlannedTrial>| DesignFamiliarity {
        design,
        exact: learning_observer(study, schedule, Memory::Exact, participants, seed),
        gist: learning_observer(study, schedule, Memory::Gist, participants, seed),
    };
    vec![
        row("v1: scene configurations drawn per trial, 1 realisation".into(), &single, v1),
        row("v2: balanced, no scene configuration twice in a row, 1 realisation".into(), &single, v2),
        row(format!("v2 with {} realisations", study.design.realisations), study, v2),
    ]
}

/// [`compare_designs`] as a plain-text table.
pub fn table(rows: &[DesignFamiliarity]) -> String {
    let mut out = String::from(
        "design | exact memory: rate ± se (informative trials) | gist memory: rate ± se (informative trials)\n",
    );
    for row in rows {
        let cell = |score: &FamiliarityScore| {
            format!(
                "{:.3} ± {:.3} ({:.1} %)",
                score.rate,
                score.se,
                100.0 * score.informative as f64 / score.trials.max(1) as f64
            )
        };
        out.push_str(&format!("{} | {} | {}\n", row.design, cell(&row.exact), cell(&row.gist)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::load_study;

    fn real_or_rendered() -> Study {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../studies/real-or-rendered.toml");
        load_study(&file).unwrap()
    }

    /// Participants per simulated design: enough for a standard error of about 0.002.
    const PARTICIPANTS: usize = 2000;

    #[test]
    fn the_shipped_design_leaves_a_picture_learner_nothing_to_learn() {
        let study = real_or_rendered();
        let score = learning_observer(&study, &crate::schedule::plan, Memory::Exact, PARTICIPANTS, 11);
        assert_eq!(score.trials, 24 * PARTICIPANTS as u64);
        // no ground-truth file (nor any stimulus file) is shown twice to anyone: no trial is
        // informative, so the rate is exactly a fair coin's
        assert_eq!(score.informative, 0, "{score:?}");
        assert!((score.rate - 0.5).abs() < 4.0 * score.se, "{score:?}");
    }

    #[test]
    fn the_design_before_let_a_picture_learner_score_above_chance() {
        let study = real_or_rendered();
        let mut single = study.clone();
        single.design.realisations = 1;
        let score = learning_observer(&single, &crate::schedule::plan_detection_v1, Memory::Exact, PARTICIPANTS, 11);
        assert!(score.rate > 0.75, "{score:?}");
        // every informative trial favoured the ground truth: it is the picture that repeats
        assert!(score.informative_toward_truth * 10 >= score.informative * 9, "{score:?}");
    }

    #[test]
    fn realisations_only_help_against_a_memory_that_keeps_the_noise() {
        // an honest limit, measured: a person's memory of a picture does not keep its sensor
        // noise, so to the gist memory the realisations are one picture and the ground truth of
        // a scene configuration repeats as often as the configuration is shown
        let rows = compare_designs(&real_or_rendered(), PARTICIPANTS, 11);
        println!("{}", table(&rows));
        assert!(rows[2].exact.informative == 0 && rows[0].exact.rate > 0.75);
        assert!(rows[2].gist.rate > 0.75, "{:?}", rows[2].gist);
    }
}
