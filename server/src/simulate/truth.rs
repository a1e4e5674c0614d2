//! The true worths of a simulation: factor effects or log-worths per condition, the thesis's
//! effects by default, and their projection on the factors.

use crate::study::Study;
use serde::Serialize;

use super::SimulateError;

/// The thesis's factor effects (Knecht 2013, Table 6.1, logit scale), the default truth of a
/// study whose factors are exactly `gi`, `cm`, `ca`.
pub const THESIS_EFFECTS: [(&str, f64); 3] = [("gi", 0.27), ("cm", -0.22), ("ca", 0.43)];

/// The true log-worth of every condition (study order) and the true factor effects.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Truth {
    pub log_worths: Vec<ConditionWorth>,
    pub effects: Vec<FactorEffect>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConditionWorth {
    pub condition: String,
    pub log_worth: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FactorEffect {
    pub factor: String,
    pub effect: f64,
}

/// The truth of `mrstudy simulate` and `power`: factor effects (`--truth gi=0.3,…`), true
/// log-worths from a CSV (`--truth-worth`: its text and name), or else the thesis's default.
pub fn choose_truth(
    study: &Study,
    effects: Option<&str>,
    worths: Option<(&str, &str)>,
) -> Result<Truth, SimulateError> {
    match (effects, worths) {
        (Some(text), _) => truth_from_effects(study, &parse_effects(text)?),
        (None, Some((text, name))) => truth_from_worths_csv(study, text, name),
        (None, None) => default_truth(study),
    }
}

/// Parses `gi=0.3,cm=-0.2` into (factor, effect) pairs.
pub fn parse_effects(text: &str) -> Result<Vec<(String, f64)>, SimulateError> {
    let bad = |message: String| SimulateError::BadTruth { source_name: "--truth".into(), message };
    text.split(',')
        .filter(|part| !part.trim().is_empty())
        .map(|part| {
            let (name, value) =
                part.split_once('=').ok_or_else(|| bad(format!("expected FACTOR=EFFECT, found `{}`", part.trim())))?;
            let effect: f64 = value.trim().parse().map_err(|_| bad(format!("`{}` is not a number", value.trim())))?;
            if !effect.is_finite() {
                return Err(bad(format!("`{}` is not a finite number", value.trim())));
            }
            Ok((name.trim().to_string(), effect))
        })
        .collect()
}

/// The truth from factor effects; a factor the study lacks is refused, one not given is 0.
pub fn truth_from_effects(study: &Study, effects: &[(String, f64)]) -> Result<Truth, SimulateError> {
    let names = study.design_columns();
    let mut values = vec![0.0; names.len()];
    for (name, effect) in effects {
        let index = names.iter().position(|n| n == name).ok_or_else(|| SimulateError::UnknownFactor {
            factor: name.clone(),
            factors: if names.is_empty() { "none".into() } else { names.join(", ") },
        })?;
        values[index] = *effect;
    }
    let log_worths = study
        .conditions
        .iter()
        .map(|condition| ConditionWorth {
            condition: condition.name.clone(),
            log_worth: condition.levels.iter().zip(&values).map(|(level, effect)| level * effect).sum(),
        })
        .collect();
    let effects =
        names.iter().zip(values).map(|(name, effect)| FactorEffect { factor: name.to_string(), effect }).collect();
    Ok(Truth { log_worths, effects })
}

/// The thesis's effects when the study's factors are gi, cm, ca; else a refusal asking for a truth.
pub fn default_truth(study: &Study) -> Result<Truth, SimulateError> {
    let mut names = study.design_columns();
    names.sort_unstable();
    if names != ["ca", "cm", "gi"] {
        let factors = study.design_columns().join(", ");
        return Err(SimulateError::NoDefaultTruth {
            factors: if factors.is_empty() { "none".into() } else { factors },
        });
    }
    let effects: Vec<(String, f64)> = THESIS_EFFECTS.iter().map(|&(name, effect)| (name.to_string(), effect)).collect();
    truth_from_effects(study, &effects)
}

/// The truth from a CSV `condition,log_worth` (one row per condition of the study).
pub fn truth_from_worths_csv(study: &Study, text: &str, source_name: &str) -> Result<Truth, SimulateError> {
    let bad = |message: String| SimulateError::BadTruth { source_name: source_name.to_string(), message };
    let mut reader = csv::ReaderBuilder::new().has_headers(true).from_reader(text.as_bytes());
    let headers = reader.headers().map_err(|error| bad(error.to_string()))?.clone();
    let column = |name: &str| {
        headers.iter().position(|h| h.trim() == name).ok_or_else(|| {
            bad(format!(
                "expected a header `condition,log_worth`, found `{}`",
                headers.iter().collect::<Vec<_>>().join(",")
            ))
        })
    };
    let (condition_column, worth_column) = (column("condition")?, column("log_worth")?);
    let names: Vec<&str> = study.conditions.iter().map(|condition| condition.name.as_str()).collect();
    let mut values: Vec<Option<f64>> = vec![None; names.len()];
    for (row, record) in reader.records().enumerate() {
        let record = record.map_err(|error| bad(error.to_string()))?;
        let name = record.get(condition_column).unwrap_or("").trim();
        let text = record.get(worth_column).unwrap_or("").trim();
        let index = names.iter().position(|n| *n == name).ok_or_else(|| SimulateError::UnknownCondition {
            condition: name.to_string(),
            conditions: names.join(", "),
        })?;
        let value: f64 = text.parse().map_err(|_| bad(format!("line {}: `{text}` is not a number", row + 2)))?;
        if !value.is_finite() {
            return Err(bad(format!("line {}: `{text}` is not a finite number", row + 2)));
        }
        values[index] = Some(value);
    }
    let mut log_worths = Vec::with_capacity(names.len());
    for (name, value) in names.iter().zip(values) {
        let log_worth = value.ok_or_else(|| SimulateError::MissingCondition { condition: name.to_string() })?;
        log_worths.push(ConditionWorth { condition: name.to_string(), log_worth });
    }
    let worths: Vec<f64> = log_worths.iter().map(|w| w.log_worth).collect();
    let effects = projected_effects(study, &worths)
        .map(|values| {
            study
                .design_columns()
                .into_iter()
                .zip(values)
                .map(|(factor, effect)| FactorEffect { factor, effect })
                .collect()
        })
        .unwrap_or_default();
    Ok(Truth { log_worths, effects })
}

/// Least squares of the log-worths on [1, levels]: the factor effects (none when the factors
/// are collinear or absent).
pub(super) fn projected_effects(study: &Study, worths: &[f64]) -> Option<Vec<f64>> {
    let p = study.design_columns().len() + 1;
    if p == 1 {
        return None;
    }
    let row = |c: usize| std::iter::once(1.0).chain(study.conditions[c].levels.iter().copied()).collect::<Vec<f64>>();
    let mut normal = vec![vec![0.0; p + 1]; p];
    for (c, &worth) in worths.iter().enumerate() {
        let x = row(c);
        for i in 0..p {
            for j in 0..p {
                normal[i][j] += x[i] * x[j];
            }
            normal[i][p] += x[i] * worth;
        }
    }
    // Gauss–Jordan with partial pivoting on the augmented normal equations.
    for col in 0..p {
        let pivot = (col..p).max_by(|&a, &b| normal[a][col].abs().total_cmp(&normal[b][col].abs()))?;
        if normal[pivot][col].abs() < 1e-9 {
            return None;
        }
        normal.swap(col, pivot);
        for r in 0..p {
            if r != col {
                let factor = normal[r][col] / normal[col][col];
                for k in col..=p {
                    normal[r][k] -= factor * normal[col][k];
                }
            }
        }
    }
    Some((1..p).map(|i| normal[i][p] / normal[i][i]).collect())
}
