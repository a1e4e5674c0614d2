//! Parsing of the long task CSV into groups of measurements, keyed by participant and condition;
//! every error names the source, line and column.

use std::collections::HashMap;

use super::{AUTO_GROUP_COLUMNS, CONDITION_COLUMN, GroupKey, PARTICIPANT_COLUMN, VALUE_COLUMN};
use crate::error::{AnalysisError, Result};

/// The measurements of one group, keyed by participant and condition indices.
#[derive(Debug, Default)]
pub(super) struct MeasureData {
    pub(super) group: GroupKey,
    pub(super) participants: Vec<String>,
    pub(super) participant_index: HashMap<String, usize>,
    pub(super) conditions: Vec<String>,
    pub(super) condition_index: HashMap<String, usize>,
    /// (participant, condition) → every value given, in file order.
    pub(super) cells: HashMap<(usize, usize), Vec<f64>>,
}

impl MeasureData {
    fn add(&mut self, participant: &str, condition: &str, value: f64) {
        let participant_idx = intern(&mut self.participants, &mut self.participant_index, participant);
        let condition_idx = intern(&mut self.conditions, &mut self.condition_index, condition);
        self.cells.entry((participant_idx, condition_idx)).or_default().push(value);
    }
}

fn intern(names: &mut Vec<String>, index: &mut HashMap<String, usize>, name: &str) -> usize {
    if let Some(&idx) = index.get(name) {
        return idx;
    }
    names.push(name.to_string());
    index.insert(name.to_string(), names.len() - 1);
    names.len() - 1
}

#[derive(Debug)]
pub(super) struct ParsedCsv {
    pub(super) rows: usize,
    pub(super) grouped_by: Vec<String>,
    pub(super) measures: Vec<MeasureData>,
}

pub(super) fn parse_task_csv(text: &str, source_name: &str, measure_column: Option<&str>) -> Result<ParsedCsv> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut reader = csv::ReaderBuilder::new().has_headers(true).trim(csv::Trim::All).from_reader(text.as_bytes());
    let header = reader.headers().map_err(|error| csv_error(source_name, &error))?.clone();
    if header.iter().all(str::is_empty) {
        return Err(AnalysisError::Empty(format!(
            "{source_name}: no header row; expected columns \
            {PARTICIPANT_COLUMN},{CONDITION_COLUMN},{VALUE_COLUMN}"
        )));
    }
    let find = |name: &str| header.iter().position(|column| column.eq_ignore_ascii_case(name));
    let found = header.iter().collect::<Vec<_>>().join(", ");
    let require = |name: &str| {
        find(name).ok_or_else(|| AnalysisError::MissingColumn {
            source_name: source_name.to_string(),
            column: name.to_string(),
            found: found.clone(),
        })
    };
    let participant_col = require(PARTICIPANT_COLUMN)?;
    let condition_col = require(CONDITION_COLUMN)?;
    let value_col = require(VALUE_COLUMN)?;

    let grouped_by: Vec<String> = match measure_column {
        Some(column) => {
            let column = column.trim();
            if column.is_empty()
                || [PARTICIPANT_COLUMN, CONDITION_COLUMN, VALUE_COLUMN].iter().any(|c| column.eq_ignore_ascii_case(c))
            {
                return Err(AnalysisError::BadOption {
                    option: "group-by".to_string(),
                    message: format!(
                        "`{column}` cannot group task measurements; name a column such as `task` or `measure`"
                    ),
                });
            }
            vec![header[require(column)?].to_string()]
        }
        None => AUTO_GROUP_COLUMNS.iter().filter_map(|name| find(name).map(|idx| header[idx].to_string())).collect(),
    };
    let group_cols: Vec<usize> = grouped_by.iter().filter_map(|name| find(name)).collect();

    let mut measures: Vec<MeasureData> = Vec::new();
    let mut measure_index: HashMap<Vec<String>, usize> = HashMap::new();
    let mut rows = 0;
    for record in reader.records() {
        let record = record.map_err(|error| csv_error(source_name, &error))?;
        let line = record.position().map_or(0, |position| position.line());
        let bad_value = |col: usize, message: String| AnalysisError::BadValue {
            source_name: source_name.to_string(),
            line,
            column: header[col].to_string(),
            message,
        };
        let text_cell = |col: usize| -> Result<&str> {
            let cell = record.get(col).unwrap_or("");
            if cell.is_empty() { Err(bad_value(col, "is empty".to_string())) } else { Ok(cell) }
        };
        let participant = text_cell(participant_col)?;
        let condition = text_cell(condition_col)?;
        let value =
            parse_value(record.get(value_col).unwrap_or("")).map_err(|message| bad_value(value_col, message))?;
        let group_values =
            group_cols.iter().map(|&col| text_cell(col).map(str::to_string)).collect::<Result<Vec<_>>>()?;

        let measure_idx = match measure_index.get(&group_values) {
            Some(&idx) => idx,
            None => {
                let group = GroupKey(grouped_by.iter().cloned().zip(group_values.iter().cloned()).collect());
                measures.push(MeasureData { group, ..MeasureData::default() });
                measure_index.insert(group_values, measures.len() - 1);
                measures.len() - 1
            }
        };
        measures[measure_idx].add(participant, condition, value);
        rows += 1;
    }
    if rows == 0 {
        return Err(AnalysisError::Empty(format!("{source_name}: the CSV has a header but no data rows")));
    }
    Ok(ParsedCsv { rows, grouped_by, measures })
}

/// A measured value: a finite number, or a sentence saying why the cell is not one.
fn parse_value(cell: &str) -> std::result::Result<f64, String> {
    if cell.is_empty() {
        return Err("is empty; every row needs a finite number (leave out rows without a measurement)".to_string());
    }
    match cell.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(format!("`{cell}` is not a finite number")),
        Err(_) => Err(format!("`{cell}` is not a number")),
    }
}

fn csv_error(source_name: &str, error: &csv::Error) -> AnalysisError {
    let line = error.position().map_or(0, |position| position.line());
    let message = match error.kind() {
        csv::ErrorKind::UnequalLengths { expected_len, len, .. } => {
            format!("the row has {len} fields but the header has {expected_len}")
        }
        _ => error.to_string(),
    };
    AnalysisError::MalformedCsv { source_name: source_name.to_string(), line, message }
}
