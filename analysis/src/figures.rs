//! The figures of an analysis: the worth plot (log-worth per condition with 95 % intervals, one
//! series per group) and the factor-effect plot. Intervals are the bootstrap percentile
//! intervals where a bootstrap was run, else Wald intervals (estimate ± 1.96·se).

use crate::analysis::Analysis;
use crate::plot::{EffectPoint, EffectSeries, WorthPoint, WorthSeries, effect_plot, worth_plot};

/// Two-sided 95 % normal quantile.
const Z_95: f64 = 1.959_963_984_540_054;

fn worth_series(name: &str, analysis: &Analysis) -> WorthSeries {
    WorthSeries {
        name: name.to_string(),
        points: analysis
            .items
            .iter()
            .filter_map(|item| {
                let log_worth = item.log_worth?;
                let (low, high) = match (item.ci, item.se) {
                    (Some([low, high]), _) => (Some(low), Some(high)),
                    (None, Some(se)) if se > 0.0 => (Some(log_worth - Z_95 * se), Some(log_worth + Z_95 * se)),
                    _ => (None, None),
                };
                Some(WorthPoint { condition: item.condition.clone(), log_worth, low, high })
            })
            .collect(),
    }
}

fn effect_series(name: &str, analysis: &Analysis) -> EffectSeries {
    EffectSeries {
        name: name.to_string(),
        points: analysis
            .covariates
            .iter()
            .flatten()
            .map(|c| {
                let (low, high) = match c.ci {
                    Some([low, high]) => (low, high),
                    None => (c.estimate - Z_95 * c.se, c.estimate + Z_95 * c.se),
                };
                EffectPoint { factor: c.name.clone(), estimate: c.estimate, low: Some(low), high: Some(high) }
            })
            .collect(),
    }
}

impl Analysis {
    /// The worth plot as SVG: the whole data set, then each group.
    pub fn worth_plot(&self) -> String {
        let conditions: Vec<String> = self.items.iter().map(|i| i.condition.clone()).collect();
        let mut series = vec![worth_series("all", self)];
        for (name, group) in self.groups.iter().flatten() {
            // A group that could not be estimated has no series (it is named in the warnings).
            if let Some(group) = group.analysis() {
                series.push(worth_series(name, group));
            }
        }
        let title = format!("Worth of each condition (log scale, reference {}), 95\u{a0}% intervals", self.reference);
        worth_plot(&title, &conditions, &series)
    }

    /// The factor-effect plot as SVG, where a factor model was fitted.
    pub fn effect_plot(&self) -> Option<String> {
        let covariates = self.covariates.as_ref()?;
        let factors: Vec<String> = covariates.iter().map(|c| c.name.clone()).collect();
        let mut series = vec![effect_series("all", self)];
        for (name, group) in self.groups.iter().flatten() {
            if let Some(group) = group.analysis() {
                series.push(effect_series(name, group));
            }
        }
        Some(effect_plot("Factor effects (logit scale), 95\u{a0}% intervals", &factors, &series))
    }
}
