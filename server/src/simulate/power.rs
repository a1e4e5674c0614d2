//! `mrstudy power`: participants needed per factor for a target power.

use mrstudy_analysis::table::fixed;
use serde::Serialize;

use super::SimulateError;
use super::design::DesignChoice;
use super::report::{Report, Row};

/// The smallest simulated participant count at which a factor's power reaches the target, for
/// one design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PowerNeed {
    pub design: DesignChoice,
    pub factor: String,
    pub effect: f64,
    /// The smallest count that reached the target, with its power and Monte-Carlo error.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reached: Option<PowerAt>,
    /// The highest power seen over the counts.
    pub best: PowerAt,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PowerAt {
    pub participants: usize,
    pub power: f64,
    pub mcse: f64,
}

/// A target power, strictly between 0 and 1 (`mrstudy power --target`).
pub fn parse_target(text: &str) -> Result<f64, TargetError> {
    match text.trim().parse::<f64>() {
        Ok(target) if target > 0.0 && target < 1.0 => Ok(target),
        _ => Err(TargetError::NotAPower { text: text.to_string() }),
    }
}

/// Why a target power was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TargetError {
    /// Not a number strictly between 0 and 1.
    #[error("`{text}` is not a power between 0 and 1 (e.g. 0.8)")]
    NotAPower { text: String },
}

/// `mrstudy power`'s answer: one sentence per design and factor ([`power_needs`],
/// [`power_lines`]); refused when the study varies no factor.
pub fn power_report(report: &Report, target: f64) -> Result<Vec<String>, SimulateError> {
    if report.truth.effects.is_empty() {
        return Err(SimulateError::NoFactors);
    }
    Ok(power_lines(&power_needs(report, target), target))
}

/// Per design and factor, the smallest participant count whose power reaches `target`.
pub fn power_needs(report: &Report, target: f64) -> Vec<PowerNeed> {
    let mut needs = Vec::new();
    let mut designs: Vec<DesignChoice> = Vec::new();
    for row in &report.rows {
        if !designs.contains(&row.design) {
            designs.push(row.design);
        }
    }
    for design in designs {
        let mut rows: Vec<&Row> = report.rows.iter().filter(|row| row.design == design).collect();
        rows.sort_by_key(|row| row.participants);
        for (k, effect) in report.truth.effects.iter().enumerate() {
            let at = |row: &Row| PowerAt {
                participants: row.participants,
                power: row.power[k].power,
                mcse: row.power[k].mcse,
            };
            let reached = rows.iter().find(|row| row.power[k].power >= target).map(|row| at(row));
            let best =
                rows.iter().map(|row| at(row)).max_by(|a, b| a.power.total_cmp(&b.power)).expect("a row per design");
            needs.push(PowerNeed { design, factor: effect.factor.clone(), effect: effect.effect, reached, best });
        }
    }
    needs
}

/// One sentence per [`PowerNeed`].
pub fn power_lines(needs: &[PowerNeed], target: f64) -> Vec<String> {
    needs
        .iter()
        .map(|need| match need.reached {
            Some(at) => format!(
                "{} {} (effect {}): {} participants reach power {} ± {} (target {})",
                need.design.name(),
                need.factor,
                fixed(need.effect, 2),
                at.participants,
                fixed(at.power, 2),
                fixed(at.mcse, 2),
                fixed(target, 2)
            ),
            None => format!(
                "{} {} (effect {}): none of the participant counts reached power {}; the highest was {} ± {} at {} participants",
                need.design.name(),
                need.factor,
                fixed(need.effect, 2),
                fixed(target, 2),
                fixed(need.best.power, 2),
                fixed(need.best.mcse, 2),
                need.best.participants
            ),
        })
        .collect()
}
