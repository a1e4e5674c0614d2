//! The active design beside the study's fixed design (`simulate --designs study,active`): per
//! participant count, both designs' RMSEs of every quantity the analysis reports, what the
//! active design optimises, and the trials it saves — the trials the study's design would need
//! for the active design's RMSE (interpolated in log trials and log RMSE between the study
//! design's simulated counts), against the active design's own.

use mrstudy_analysis::table::fixed;
use serde::Serialize;

use super::design::DesignChoice;

/// One quantity of one comparison: both RMSEs and the trials saving.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Versus {
    /// RMSE under the study's design and under the active design.
    pub study: f64,
    pub active: f64,
    /// Trials per study the study's design needs for the active design's RMSE (absent outside
    /// the simulated counts).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub study_trials_needed: Option<f64>,
    /// 1 − active trials / `study_trials_needed`: the share of trials the active design saves
    /// (negative: it costs more).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saving: Option<f64>,
    /// Where the active RMSE lies beyond the study design's simulated counts: below its RMSE at
    /// the most trials (the saving is at least 1 − active trials / those trials), or above its
    /// RMSE at the fewest (the saving is at most 1 − active trials / those trials).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saving_at_least: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub saving_at_most: Option<f64>,
}

/// An active design against the study's design at one participant count.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    pub design: DesignChoice,
    /// What the active design optimises: `worths`, `effects` or `both`.
    pub target: &'static str,
    pub participants: usize,
    /// Trials per study of the active and the study design.
    pub trials: f64,
    pub study_trials: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_log_worth: Option<Versus>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rmse_effects: Option<Versus>,
}

/// Trials at which `curve` (trials, RMSE; increasing trials) reaches `rmse`.
fn trials_for(curve: &[(f64, f64)], rmse: f64) -> Option<f64> {
    curve.windows(2).find_map(|pair| {
        let [(n0, r0), (n1, r1)] = [pair[0], pair[1]];
        let (low, high) = (r0.min(r1), r0.max(r1));
        (low <= rmse && rmse <= high && r0 != r1).then(|| {
            let f = (rmse.ln() - r0.ln()) / (r1.ln() - r0.ln());
            (n0.ln() + f * (n1.ln() - n0.ln())).exp()
        })
    })
}

/// The study design's RMSE `study` and the active design's `active` at `active_trials` trials,
/// with the study design's curve (trials, RMSE; increasing trials).
pub(super) fn versus(study: f64, active: f64, active_trials: f64, curve: &[(f64, f64)]) -> Option<Versus> {
    let needed = trials_for(curve, active);
    let (first, last) = (curve.first()?, curve.last()?);
    let beyond = needed.is_none();
    Some(Versus {
        study,
        active,
        study_trials_needed: needed,
        saving: needed.map(|needed| 1.0 - active_trials / needed),
        saving_at_least: (beyond && active < last.1.min(first.1)).then(|| 1.0 - active_trials / last.0),
        saving_at_most: (beyond && active > first.1.max(last.1)).then(|| 1.0 - active_trials / first.0),
    })
}

/// The table's lines for the comparisons.
pub(super) fn comparison_lines(comparisons: &[Comparison]) -> String {
    let mut text = String::new();
    for c in comparisons {
        let part = |name: &str, versus: &Option<Versus>| match versus {
            None => String::new(),
            Some(v) => {
                let saving = match (v.saving, v.saving_at_least, v.saving_at_most) {
                    (Some(saving), _, _) if saving >= 0.0 => {
                        format!("saves {} % of the trials", fixed(100.0 * saving, 0))
                    }
                    (Some(saving), _, _) => format!("needs {} % more trials", fixed(-100.0 * saving, 0)),
                    (None, Some(bound), _) if bound >= 0.0 => format!(
                        "saves more than {} % of the trials (beyond the study design's counts)",
                        fixed(100.0 * bound, 0)
                    ),
                    (None, Some(_), _) => "better than the study's design at its most trials".to_string(),
                    (None, _, Some(bound)) if bound < 0.0 => format!(
                        "needs more than {} % more trials (worse than the study's design at its fewest)",
                        fixed(-100.0 * bound, 0)
                    ),
                    _ => "worse than the study's design at its fewest trials".to_string(),
                };
                format!("; {name} {} (study) vs {} (active): {saving}", fixed(v.study, 3), fixed(v.active, 3))
            }
        };
        text += &format!(
            "{} (optimises the {}) against the study's design at {} participants ({} vs {} trials){}{}\n",
            c.design.name(),
            match c.target {
                // prior = "spread": not the maximum-likelihood log-worths this RMSE scores
                _ if c.design == DesignChoice::ActiveSpread => {
                    "centred MAP log-worths with the prior, not the analysis's maximum-likelihood ones scored here"
                }
                "effects" => "factor effects",
                "both" => "log-worths and the factor effects together",
                _ => "log-worths",
            },
            c.participants,
            fixed(c.trials, 0),
            fixed(c.study_trials, 0),
            part("RMSE log-worth", &c.rmse_log_worth),
            part("RMSE effects", &c.rmse_effects),
        );
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trials_for_interpolates_in_log_log() {
        // RMSE ∝ 1/√trials: 0.2 at 100, 0.1 at 400; 0.1414… at 200
        let curve = [(100.0, 0.2), (400.0, 0.1)];
        assert!((trials_for(&curve, 0.2 / 2f64.sqrt()).unwrap() - 200.0).abs() < 1e-9);
        assert_eq!(trials_for(&curve, 0.05), None);
        assert_eq!(trials_for(&curve, 0.3), None);
    }

    #[test]
    fn the_lines_say_the_target_and_the_saving_or_the_cost() {
        let curve = [(100.0, 0.2), (400.0, 0.1)];
        // the active design at 400 trials reaches what the study's design reaches at 200: it
        // needs 100 % more trials; at 0.1 it saves nothing; below the curve, more than 0 %
        let worse = versus(0.1, 0.2 / 2f64.sqrt(), 400.0, &curve).unwrap();
        assert!((worse.saving.unwrap() + 1.0).abs() < 1e-9, "{worse:?}");
        let better = versus(0.1, 0.05, 400.0, &curve).unwrap();
        assert_eq!((better.saving, better.saving_at_least), (None, Some(0.0)));
        let comparison = Comparison {
            design: DesignChoice::Active,
            target: "effects",
            participants: 10,
            trials: 400.0,
            study_trials: 400.0,
            rmse_log_worth: Some(worse),
            rmse_effects: Some(better),
        };
        let line = comparison_lines(&[comparison]);
        assert!(line.starts_with("active (optimises the factor effects)"), "{line}");
        assert!(line.contains("needs 100 % more trials") && line.contains("saves more than 0 %"), "{line}");
    }
}
