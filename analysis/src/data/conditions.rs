//! The conditions CSV: `condition,<factor>,<factor>,…`, one row per condition, numeric levels.

use std::collections::HashMap;

use super::csv::{csv_error, reader};
use crate::error::{AnalysisError, Result};

/// Factor levels per condition, from a conditions CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct ConditionTable {
    pub conditions: Vec<String>,
    pub factors: Vec<String>,
    /// `levels[condition][factor]`.
    pub levels: Vec<Vec<f64>>,
}

impl ConditionTable {
    pub fn index_of(&self, condition: &str) -> Option<usize> {
        self.conditions.iter().position(|c| c == condition)
    }
}

/// Parses a conditions CSV. The first column is the condition name; every further column is a
/// factor with numeric levels.
pub fn parse_conditions(text: &str, source_name: &str) -> Result<ConditionTable> {
    let mut reader = reader(text);
    let headers = reader.headers().map_err(|e| csv_error(source_name, e))?.clone();
    let first = headers.get(0).map(str::trim).unwrap_or("");
    if first != "condition" {
        return Err(AnalysisError::MissingColumn {
            source_name: source_name.to_string(),
            column: "condition (as the first column)".to_string(),
            found: headers.iter().collect::<Vec<_>>().join(", "),
        });
    }
    let factors: Vec<String> = headers.iter().skip(1).map(|h| h.trim().to_string()).collect();
    for (k, factor) in factors.iter().enumerate() {
        if factor.is_empty() {
            return Err(AnalysisError::BadValue {
                source_name: source_name.to_string(),
                line: 1,
                column: format!("#{}", k + 2),
                message: "the factor column has no name".to_string(),
            });
        }
        if factors[..k].contains(factor) {
            return Err(AnalysisError::BadValue {
                source_name: source_name.to_string(),
                line: 1,
                column: factor.clone(),
                message: "the factor is named twice in the header".to_string(),
            });
        }
    }
    let mut table = ConditionTable { conditions: Vec::new(), factors, levels: Vec::new() };
    let mut first_lines: HashMap<String, u64> = HashMap::new();
    for record in reader.records() {
        let record = record.map_err(|e| csv_error(source_name, e))?;
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        let name = record.get(0).unwrap_or("").trim().to_string();
        if name.is_empty() {
            return Err(AnalysisError::BadValue {
                source_name: source_name.to_string(),
                line,
                column: "condition".to_string(),
                message: "the condition name is empty".to_string(),
            });
        }
        if let Some(&first_line) = first_lines.get(&name) {
            return Err(AnalysisError::DuplicateCondition {
                source_name: source_name.to_string(),
                line,
                condition: name,
                first_line,
            });
        }
        first_lines.insert(name.clone(), line);
        let mut levels = Vec::with_capacity(table.factors.len());
        for (k, factor) in table.factors.iter().enumerate() {
            let cell = record.get(k + 1).unwrap_or("").trim();
            let value: f64 =
                cell.parse().ok().filter(|v: &f64| v.is_finite()).ok_or_else(|| AnalysisError::BadValue {
                    source_name: source_name.to_string(),
                    line,
                    column: factor.clone(),
                    message: format!("the factor level `{cell}` is not a finite number"),
                })?;
            levels.push(value);
        }
        table.conditions.push(name);
        table.levels.push(levels);
    }
    if table.conditions.is_empty() {
        return Err(AnalysisError::Empty(format!("{source_name}: there are no conditions in the file")));
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duplicate_and_non_numeric_conditions() {
        let message = parse_conditions("condition,gi\nLQ,0\nGI,1\nLQ,1\n", "c.csv").unwrap_err().to_string();
        assert_eq!(message, "c.csv: line 4: condition `LQ` is listed twice (first on line 2)");
        let message = parse_conditions("condition,gi\nLQ,off\n", "c.csv").unwrap_err().to_string();
        assert_eq!(message, "c.csv: line 2, column `gi`: the factor level `off` is not a finite number");
        let message = parse_conditions("condition,gi\nLQ,NaN\n", "c.csv").unwrap_err().to_string();
        assert!(message.contains("not a finite number"));
    }
}
