//! The keys of `pairs = "active"` (trials, batch, target, prior_sd, prior) and the default active design
//! (issue 48): with `target` omitted the target is `both` where a factor varies (else
//! `worths`); with `target` omitted or `both` and `warmup` omitted the warm-up is the anchored
//! pairs (the `anchors` given, else the first and the last condition) repeated
//! [`default_repetitions`] times, so about 60 % of a participant's pair trials are the warm-up.
//! Measured in docs/simulate/active-target/README.md: the one setting of those simulated that
//! is no worse than the thesis survey's fixed anchored design on either reported quantity at
//! 5–80 participants.

use super::file::DesignFile;
use super::model::*;
use crate::study::StudyError;
use crate::study::checks::Fail;

/// Whether the file's active design takes the default warm-up: `warmup` omitted and `target`
/// omitted or `both`.
pub(super) fn default_warmup(design: &DesignFile) -> bool {
    design.warmup.is_none() && matches!(design.target.as_deref(), None | Some("both"))
}

/// The default warm-up's repetitions: 1.5 × the actively chosen `trials` over the warm-up's
/// pairs, rounded, at least 1 — warm-up : chosen ≈ 3 : 2, as measured (39 + 26 trials on the
/// thesis survey). Without `trials` (refused later) 1.
pub(crate) fn default_repetitions(trials: Option<u32>, pairs: usize) -> u32 {
    match trials {
        Some(trials) if pairs > 0 => ((1.5 * trials as f64 / pairs as f64).round() as u32).clamp(1, 100),
        _ => 1,
    }
}

/// The keys of `pairs = "active"`: trials, batch, target (checked against the conditions by
/// the posterior's own rules), prior_sd, prior (`"spread"` with target worths only).
pub(super) fn check_active(
    fail: Fail,
    design: &DesignFile,
    warmup: &[(usize, usize)],
    conditions: &[Condition],
) -> Result<ActiveDesign, StudyError> {
    let trials = design.trials.ok_or_else(|| {
        fail.at("design.trials", "expected the number of actively chosen trials per participant (1 to 1000)")
    })?;
    if !(1..=1000).contains(&trials) {
        return Err(fail.at("design.trials", format!("expected 1 to 1000, found {trials}")));
    }
    let batch = design.batch.unwrap_or(5);
    if !(1..=100).contains(&batch) {
        return Err(fail.at("design.batch", format!("expected 1 to 100, found {batch}")));
    }
    let target = match design.target.as_deref().unwrap_or(default_target(conditions)) {
        "worths" => ActiveTarget::Worths,
        // `effects` is the issue-48 name; `factors` the first spelling, still accepted
        "effects" | "factors" => ActiveTarget::Factors,
        "both" => ActiveTarget::Both,
        other => {
            return Err(fail.at(
                "design.target",
                format!("expected \"worths\", \"effects\" (also spelt \"factors\") or \"both\", found \"{other}\""),
            ));
        }
    };
    let prior_sd = design.prior_sd.unwrap_or(mrstudy_analysis::active::DEFAULT_PRIOR_SD);
    if !(prior_sd.is_finite() && (0.05..=10.0).contains(&prior_sd)) {
        return Err(fail.at("design.prior_sd", format!("expected a number from 0.05 to 10, found {prior_sd}")));
    }
    if target == ActiveTarget::Factors && !connects(warmup, conditions.len()) {
        return Err(fail.at(
            "design.warmup",
            "expected a warm-up that connects every condition (\"all\" or \"anchored\") with target = \"effects\" (or \"factors\"): \
             pairs chosen for the factor effects alone leave the per-condition model of the analysis without a fit \
             (every simulated study of the thesis design failed; `mrstudy simulate`)",
        ));
    }
    let prior = match design.prior.as_deref().unwrap_or("fixed") {
        "fixed" => ActivePrior::Fixed,
        "spread" if target == ActiveTarget::Worths => ActivePrior::Spread,
        "spread" => {
            return Err(fail.at(
                "design.prior",
                format!(
                    "expected \"fixed\" with target = \"{}\": the hierarchical prior on the spread (prior = \"spread\") \
                     applies to target = \"worths\" only",
                    target.describe().0
                ),
            ));
        }
        other => {
            return Err(fail.at("design.prior", format!("expected \"fixed\" or \"spread\", found \"{other}\"")));
        }
    };
    let active = ActiveDesign { trials, batch, target, prior_sd, prior };
    active_target(&active, conditions)
        .check()
        .map_err(|error| fail.at("design.target", format!("an active design this posterior can learn: {error}")))?;
    Ok(active)
}

/// Whether `pairs` connect all `count` conditions (union–find).
fn connects(pairs: &[(usize, usize)], count: usize) -> bool {
    let mut parent: Vec<usize> = (0..count).collect();
    fn root(parent: &mut [usize], mut node: usize) -> usize {
        while parent[node] != node {
            parent[node] = parent[parent[node]];
            node = parent[node];
        }
        node
    }
    let mut groups = count;
    for &(a, b) in pairs {
        let (a, b) = (root(&mut parent, a), root(&mut parent, b));
        if a != b {
            parent[a] = b;
            groups -= 1;
        }
    }
    groups <= 1
}

/// The target of a file that omits `target`: `both` where the posterior can learn it (a factor
/// varies over the conditions, no factor a combination of the others), else `worths`.
fn default_target(conditions: &[Condition]) -> &'static str {
    let both = ActiveDesign {
        trials: 1,
        batch: 1,
        target: ActiveTarget::Both,
        prior_sd: mrstudy_analysis::active::DEFAULT_PRIOR_SD,
        prior: ActivePrior::Fixed,
    };
    if active_target(&both, conditions).check().is_ok() { "both" } else { "worths" }
}
