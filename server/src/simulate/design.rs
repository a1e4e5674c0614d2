//! The design variants a simulation compares (`--designs`): the study's own, all pairs,
//! anchored, active; each the study with its design replaced, built by the study's own pair rules.

use crate::study::{ActiveDesign, ActivePrior, ActiveTarget, PairsRule, Study, active_target};
use mrstudy_analysis::active::DEFAULT_PRIOR_SD;
use serde::Serialize;

use super::SimulateError;

/// Active batches of the `active` design variant.
pub const ACTIVE_BATCH: u32 = 5;

/// A design to simulate, each built from the study by changing only its `design`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DesignChoice {
    /// The study file's own design.
    Study,
    /// Every pair of conditions, the study's repetitions.
    All,
    /// The study's anchors if it has them, else the first and last condition; the study's repetitions.
    Anchored,
    /// `pairs = "active"` at the study's fixed design's pair trials per participant, batch 5,
    /// target factors when the study has a factor that varies, else worths. (On a 2³ factorial
    /// the factor target picks almost only complementary pairs, LQ–HQ, GI–CM+CA, …, whose
    /// item model the analysis then cannot fit: see `active-worths`.)
    Active,
    /// As `active`, with target worths whatever the factors (`active-worths`).
    ActiveWorths,
    /// The default active design (`active-both`): target both (worths where no factor varies)
    /// after the default warm-up — the anchored pairs (the study's, else the first and last
    /// condition as anchors) for about 60 % of the same pair trials, as a study file with
    /// `pairs = "active"` and neither `target` nor `warmup` gets.
    ActiveBoth,
    /// As `active-worths` with `prior = "spread"` (`active-spread`): the hierarchical prior on the
    /// log-worths' spread, which optimises the centred MAP log-worths, not the analysis's
    /// maximum-likelihood ones that `simulate` scores.
    ActiveSpread,
}

impl DesignChoice {
    pub fn parse(text: &str) -> Option<DesignChoice> {
        Some(match text {
            "study" => DesignChoice::Study,
            "all" => DesignChoice::All,
            "anchored" => DesignChoice::Anchored,
            "active" => DesignChoice::Active,
            "active-worths" => DesignChoice::ActiveWorths,
            "active-both" => DesignChoice::ActiveBoth,
            "active-spread" => DesignChoice::ActiveSpread,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            DesignChoice::Study => "study",
            DesignChoice::All => "all",
            DesignChoice::Anchored => "anchored",
            DesignChoice::Active => "active",
            DesignChoice::ActiveWorths => "active-worths",
            DesignChoice::ActiveBoth => "active-both",
            DesignChoice::ActiveSpread => "active-spread",
        }
    }

    pub(super) fn code(self) -> u64 {
        self as u64
    }
}

/// Pair trials per participant of a study's design (warm-up and active trials, no catch trials).
pub(super) fn pair_trials(study: &Study) -> usize {
    study.design.pairs.len() * study.design.repetitions as usize
        + study.design.active.as_ref().map_or(0, |active| active.trials as usize)
}

/// The study with its design replaced by `choice` (the same scheduler runs every variant).
pub fn design_variant(study: &Study, choice: DesignChoice) -> Result<Study, SimulateError> {
    let mut variant = study.clone();
    let n = study.conditions.len();
    let repetitions = if study.design.active.is_some() { 1 } else { study.design.repetitions };
    match choice {
        DesignChoice::Study => {}
        DesignChoice::All => {
            variant.design.pairs = crate::study::survey::all_pairs(n);
            variant.design.pairs_rule = PairsRule::All;
            variant.design.repetitions = repetitions;
            variant.design.active = None;
        }
        DesignChoice::Anchored => {
            if study.design.pairs_rule != PairsRule::Anchored {
                variant.design.pairs = anchored_pairs(study);
                variant.design.repetitions = repetitions;
            }
            variant.design.pairs_rule = PairsRule::Anchored;
            variant.design.active = None;
        }
        DesignChoice::Active | DesignChoice::ActiveWorths | DesignChoice::ActiveBoth | DesignChoice::ActiveSpread => {
            if study.design.active.is_none() || choice != DesignChoice::Active {
                if n < 3 {
                    return Err(SimulateError::TooFewConditions { conditions: n });
                }
                let varying = (0..study.design_columns().len()).any(|k| {
                    study.conditions.iter().any(|condition| condition.levels[k] != study.conditions[0].levels[k])
                });
                let mut active = ActiveDesign {
                    trials: pair_trials(study) as u32,
                    batch: ACTIVE_BATCH,
                    target: match choice {
                        DesignChoice::Active if varying => ActiveTarget::Factors,
                        DesignChoice::ActiveBoth if varying => ActiveTarget::Both,
                        _ => ActiveTarget::Worths,
                    },
                    prior_sd: DEFAULT_PRIOR_SD,
                    prior: ActivePrior::Fixed,
                };
                if active_target(&active, &study.conditions).check().is_err() {
                    active.target = ActiveTarget::Worths;
                }
                active_target(&active, &study.conditions).check().map_err(SimulateError::Active)?;
                // The factor target needs a warm-up that connects the conditions (a study file
                // without one is refused): the anchored pairs once, within the same trials.
                variant.design.pairs = Vec::new();
                variant.design.repetitions = 1;
                if active.target == ActiveTarget::Factors {
                    variant.design.pairs = anchored_pairs(study);
                    active.trials = (active.trials as usize).saturating_sub(variant.design.pairs.len()).max(1) as u32;
                }
                // The default design's warm-up, within the same trials: chosen trials 40 % of
                // them, the warm-up's repetitions by the study files' own default rule.
                if choice == DesignChoice::ActiveBoth {
                    let total = active.trials;
                    variant.design.pairs = anchored_pairs(study);
                    active.trials = ((0.4 * total as f64).round() as u32).max(1);
                    let repetitions =
                        crate::study::survey::default_repetitions(Some(active.trials), variant.design.pairs.len());
                    variant.design.repetitions = repetitions;
                    let warmup = repetitions as usize * variant.design.pairs.len();
                    active.trials = (total as usize).saturating_sub(warmup).max(1) as u32;
                }
                if choice == DesignChoice::ActiveSpread {
                    active.prior = ActivePrior::Spread;
                }
                variant.design.pairs_rule = PairsRule::Active;
                variant.design.active = Some(active);
            }
        }
    }
    Ok(variant)
}

/// The study's anchored pairs, or with another design the study's anchored rule with the first
/// and last condition as anchors.
pub(super) fn anchored_pairs(study: &Study) -> Vec<(usize, usize)> {
    if study.design.pairs_rule == PairsRule::Anchored {
        return study.design.pairs.clone();
    }
    let count = study.conditions.len();
    crate::study::survey::anchored_pair_indices(&[0, count - 1], count)
}
