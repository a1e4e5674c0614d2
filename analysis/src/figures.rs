//! The figures of an analysis: the worth plot (log-worth per condition with 95 % intervals, one
//! series per group), the factor-effect plot and the JOD ranking (`--scale jod`). Intervals are the bootstrap percentile
//! intervals where a bootstrap was run, else Wald intervals (estimate ± 1.96·se).

use crate::analysis::Analysis;
use crate::plot::{
    EffectPoint, EffectSeries, RankingPoint, WorthPoint, WorthSeries, effect_plot, ranking_plot, worth_plot,
};

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

    /// The JOD ranking as SVG (`--scale jod`): the compared conditions by JOD, highest first,
    /// with their intervals (`jod_ci`, with `--bootstrap`) and, beside each, its difference from
    /// the next lower condition with pwcmp's p and whether it is significant at 0.05
    /// (`jod_scale.ranking`). `None` without a JOD scale.
    pub fn jod_ranking_plot(&self) -> Option<String> {
        let section = self.jod_scale.as_ref()?;
        let mut points: Vec<RankingPoint> = self
            .items
            .iter()
            .filter_map(|item| {
                let value = item.jod?;
                let (low, high) = item.jod_ci.map_or((None, None), |[low, high]| (Some(low), Some(high)));
                let step = section.ranking.iter().find(|n| n.upper == item.condition).map(|n| {
                    let difference = format!("+{:.2}", n.difference).replace("+-", "−");
                    match (n.p, n.significant) {
                        (Some(p), Some(true)) => format!("{difference}  p\u{a0}{}  significant", p_text(p)),
                        (Some(p), _) => format!("{difference}  p\u{a0}{}  n.s.", p_text(p)),
                        _ => difference,
                    }
                });
                Some(RankingPoint { condition: item.condition.clone(), value, low, high, step })
            })
            .collect();
        points.sort_by(|a, b| b.value.total_cmp(&a.value));
        let tested = section.ranking.iter().any(|n| n.p.is_some());
        let title = if tested {
            "JOD of each condition (1 JOD = 75\u{a0}% preference), 95\u{a0}% bootstrap intervals; neighbours tested at 0.05"
        } else {
            "JOD of each condition (1 JOD = 75\u{a0}% preference); no intervals or tests without --bootstrap"
        };
        Some(ranking_plot(title, "JOD (mean 0)", "difference from the next lower", &points))
    }
}

/// A p-value's relation for a figure: `= 0.378`, small ones `< 0.001`.
fn p_text(p: f64) -> String {
    if p < 0.001 { "<\u{a0}0.001".to_owned() } else { format!("=\u{a0}{p:.3}") }
}
