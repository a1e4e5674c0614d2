//! Reading the two inputs of a paired-comparison analysis from text: the trials CSV (one row
//! per judgment, DESIGN.md's long format) and the optional conditions CSV (factor levels per
//! condition). Every error names the source, the line and the column.
//!
//! Trials CSV: required columns `participant,left,right,chosen`; `chosen` equals `left` or
//! `right`. An optional column `count` (a positive integer) makes a row stand for that many
//! identical judgments, so aggregated tallies (up to 10⁹ and more per pair) can be analysed
//! without expanding them. Other columns are ignored, except the one named for grouping.
//!
//! Pilot and excluded participants: where the trials CSV has the columns `pilot` and
//! `excluded` (`true`/`false`, as `mrstudy export` writes them), every judgment of a
//! participant marked `true` in either is left out unless [`TrialsOptions`] asks to keep them,
//! and [`LeftOut`] says how many participants and judgments went and why. A file without these
//! columns is read as it is. Any other value in them is an error naming line and column.
//!
//! Conditions CSV: `condition,<factor>,<factor>,…`, one row per condition, numeric levels.

use std::collections::HashMap;

use crate::error::{AnalysisError, Result};

/// One row of the trials CSV after validation (conditions and participant as indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Judgment {
    pub participant: u32,
    pub left: u32,
    pub right: u32,
    /// True when the left condition was chosen.
    pub left_chosen: bool,
    /// How many identical judgments this row stands for (1 unless a `count` column is given).
    pub count: u64,
    /// Index into [`Judgments::groups`] when grouping was asked for.
    pub group: u32,
}

/// All judgments of a data set.
#[derive(Debug, Clone, Default)]
pub struct Judgments {
    /// Condition names; indices into this list are used everywhere else.
    pub conditions: Vec<String>,
    pub participants: Vec<String>,
    /// Distinct values of the grouping column in order of first appearance (empty if none).
    pub groups: Vec<String>,
    pub rows: Vec<Judgment>,
}

impl Judgments {
    /// Total number of judgments (rows weighted by `count`).
    pub fn n_judgments(&self) -> u64 {
        self.rows.iter().map(|row| row.count).sum()
    }
}

/// How to read a trials CSV. `Default` is the documented default: no grouping, pilot and
/// excluded participants left out.
#[derive(Debug, Clone, Default)]
pub struct TrialsOptions {
    /// Column to group by.
    pub group_by: Option<String>,
    /// Keep participants marked `pilot = true`.
    pub include_pilots: bool,
    /// Keep participants marked `excluded = true`.
    pub include_excluded: bool,
}

/// Participants left out of an analysis and why. Each participant is counted once: as a pilot
/// when left out as one, else as excluded.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct LeftOut {
    /// Participants left out because `pilot` is `true`.
    pub pilots: usize,
    /// Their judgments.
    pub pilot_judgments: u64,
    /// Participants left out because `excluded` is `true` (and not already as pilots).
    pub excluded: usize,
    pub excluded_judgments: u64,
}

impl LeftOut {
    pub fn participants(&self) -> usize {
        self.pilots + self.excluded
    }

    pub fn judgments(&self) -> u64 {
        self.pilot_judgments + self.excluded_judgments
    }

    pub fn is_empty(&self) -> bool {
        self.participants() == 0
    }

    /// One sentence for the warnings: how many went, and why.
    pub fn describe(&self) -> String {
        let plural =
            |n: usize, one: &str, many: &str| if n == 1 { format!("{n} {one}") } else { format!("{n} {many}") };
        let mut reasons = Vec::new();
        if self.pilots > 0 {
            reasons.push(format!(
                "{} with {} (pilot = true)",
                plural(self.pilots, "pilot participant", "pilot participants"),
                plural_u64(self.pilot_judgments)
            ));
        }
        if self.excluded > 0 {
            reasons.push(format!(
                "{} with {} (excluded = true)",
                plural(self.excluded, "excluded participant", "excluded participants"),
                plural_u64(self.excluded_judgments)
            ));
        }
        format!(
            "left out {} and {}: {}",
            plural(self.participants(), "participant", "participants"),
            plural_u64(self.judgments()),
            reasons.join("; ")
        )
    }
}

fn plural_u64(judgments: u64) -> String {
    if judgments == 1 { "1 judgment".to_string() } else { format!("{judgments} judgments") }
}

/// The judgments of a trials CSV, and the participants left out of them.
#[derive(Debug, Clone)]
pub struct ParsedTrials {
    pub judgments: Judgments,
    pub left_out: LeftOut,
}

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

fn csv_error(source_name: &str, error: csv::Error) -> AnalysisError {
    let line = error.position().map(|p| p.line()).unwrap_or(0);
    let message = match error.kind() {
        csv::ErrorKind::UnequalLengths { expected_len, len, .. } => {
            format!("the row has {len} fields but the header has {expected_len}")
        }
        csv::ErrorKind::Utf8 { .. } => "the text is not valid UTF-8".to_string(),
        _ => error.to_string(),
    };
    AnalysisError::MalformedCsv { source_name: source_name.to_string(), line, message }
}

fn header_index(source_name: &str, headers: &csv::StringRecord, column: &str) -> Result<usize> {
    headers.iter().position(|h| h.trim() == column).ok_or_else(|| AnalysisError::MissingColumn {
        source_name: source_name.to_string(),
        column: column.to_string(),
        found: headers.iter().map(|h| h.trim()).collect::<Vec<_>>().join(", "),
    })
}

fn reader(text: &str) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new().has_headers(true).flexible(false).from_reader(text.as_bytes())
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

/// Parses a trials CSV. Conditions are indexed in the order of `conditions` when it is given
/// (and every condition of the trials must be in it); otherwise sorted by name. Pilot and
/// excluded participants are left out (see [`parse_trials_with`] to keep them or to learn how
/// many went).
pub fn parse_trials(
    text: &str,
    source_name: &str,
    conditions: Option<&ConditionTable>,
    group_by: Option<&str>,
) -> Result<Judgments> {
    let options = TrialsOptions { group_by: group_by.map(str::to_string), ..TrialsOptions::default() };
    Ok(parse_trials_with(text, source_name, conditions, &options)?.judgments)
}

/// A `true`/`false` cell (ASCII case ignored, as spreadsheets write `TRUE`).
fn parse_flag(cell: &str) -> Option<bool> {
    if cell.eq_ignore_ascii_case("true") {
        Some(true)
    } else if cell.eq_ignore_ascii_case("false") {
        Some(false)
    } else {
        None
    }
}

/// As [`parse_trials`], with options, returning also who was left out.
pub fn parse_trials_with(
    text: &str,
    source_name: &str,
    conditions: Option<&ConditionTable>,
    options: &TrialsOptions,
) -> Result<ParsedTrials> {
    let group_by = options.group_by.as_deref();
    let mut reader = reader(text);
    let headers = reader.headers().map_err(|e| csv_error(source_name, e))?.clone();
    let participant_column = header_index(source_name, &headers, "participant")?;
    let left_column = header_index(source_name, &headers, "left")?;
    let right_column = header_index(source_name, &headers, "right")?;
    let chosen_column = header_index(source_name, &headers, "chosen")?;
    let count_column = headers.iter().position(|h| h.trim() == "count");
    let group_column = group_by.map(|column| header_index(source_name, &headers, column)).transpose()?;
    let pilot_column = headers.iter().position(|h| h.trim() == "pilot");
    let excluded_column = headers.iter().position(|h| h.trim() == "excluded");
    // Per participant (by index): marked pilot, marked excluded, in any of their rows.
    let mut marks: Vec<(bool, bool)> = Vec::new();

    let mut condition_index: HashMap<String, u32> = HashMap::new();
    let mut condition_names: Vec<String> = Vec::new();
    if let Some(table) = conditions {
        for (k, name) in table.conditions.iter().enumerate() {
            condition_index.insert(name.clone(), k as u32);
        }
        condition_names = table.conditions.clone();
    }
    let mut participant_index: HashMap<String, u32> = HashMap::new();
    let mut group_index: HashMap<String, u32> = HashMap::new();
    let mut judgments = Judgments::default();
    let bad = |line: u64, column: &str, message: String| AnalysisError::BadValue {
        source_name: source_name.to_string(),
        line,
        column: column.to_string(),
        message,
    };

    let mut record = csv::StringRecord::new();
    loop {
        match reader.read_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_error(source_name, e)),
        }
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        let field = |k: usize| record.get(k).unwrap_or("").trim();
        let mut condition = |column: &str, name: &str| -> Result<u32> {
            if name.is_empty() {
                return Err(bad(line, column, "the condition name is empty".to_string()));
            }
            if let Some(&k) = condition_index.get(name) {
                return Ok(k);
            }
            if conditions.is_some() {
                return Err(AnalysisError::UnknownCondition {
                    source_name: source_name.to_string(),
                    line,
                    condition: name.to_string(),
                });
            }
            let k = condition_names.len() as u32;
            condition_index.insert(name.to_string(), k);
            condition_names.push(name.to_string());
            Ok(k)
        };
        let left_name = field(left_column);
        let right_name = field(right_column);
        let left = condition("left", left_name)?;
        let right = condition("right", right_name)?;
        if left == right {
            return Err(bad(line, "right", format!("the trial compares condition `{left_name}` with itself")));
        }
        let chosen = field(chosen_column);
        let left_chosen = if chosen == left_name {
            true
        } else if chosen == right_name {
            false
        } else {
            return Err(bad(
                line,
                "chosen",
                format!("`{chosen}` is neither the left (`{left_name}`) nor the right (`{right_name}`) condition"),
            ));
        };
        let participant_name = field(participant_column);
        if participant_name.is_empty() {
            return Err(bad(line, "participant", "the participant is empty".to_string()));
        }
        let next = participant_index.len() as u32;
        let participant = *participant_index.entry(participant_name.to_string()).or_insert_with(|| {
            judgments.participants.push(participant_name.to_string());
            next
        });
        if marks.len() <= participant as usize {
            marks.push((false, false));
        }
        for (column, name, is_pilot) in [(pilot_column, "pilot", true), (excluded_column, "excluded", false)] {
            let Some(k) = column else { continue };
            let cell = field(k);
            let flag =
                parse_flag(cell).ok_or_else(|| bad(line, name, format!("`{cell}` is neither `true` nor `false`")))?;
            let mark = &mut marks[participant as usize];
            if is_pilot { mark.0 |= flag } else { mark.1 |= flag }
        }
        let count = match count_column {
            None => 1,
            Some(k) => {
                let cell = field(k);
                cell.parse::<u64>()
                    .ok()
                    .filter(|&c| c > 0)
                    .ok_or_else(|| bad(line, "count", format!("`{cell}` is not a positive whole number")))?
            }
        };
        let group = match group_column {
            None => 0,
            Some(k) => {
                let value = field(k);
                if value.is_empty() {
                    return Err(bad(line, group_by.unwrap_or_default(), "the group value is empty".to_string()));
                }
                let next = group_index.len() as u32;
                *group_index.entry(value.to_string()).or_insert_with(|| {
                    judgments.groups.push(value.to_string());
                    next
                })
            }
        };
        judgments.rows.push(Judgment { participant, left, right, left_chosen, count, group });
    }
    if judgments.rows.is_empty() {
        return Err(AnalysisError::Empty(format!("{source_name}: there are no trials in the file")));
    }

    // Leave out pilot and excluded participants, then renumber participants and groups (and,
    // below, conditions) so that only what is analysed remains.
    #[derive(Clone, Copy)]
    enum Reason {
        Pilot,
        Excluded,
    }
    let mut left_out = LeftOut::default();
    let reason: Vec<Option<Reason>> = marks
        .iter()
        .map(|&(pilot, excluded)| {
            if pilot && !options.include_pilots {
                Some(Reason::Pilot)
            } else if excluded && !options.include_excluded {
                Some(Reason::Excluded)
            } else {
                None
            }
        })
        .collect();
    for why in &reason {
        match why {
            Some(Reason::Pilot) => left_out.pilots += 1,
            Some(Reason::Excluded) => left_out.excluded += 1,
            None => {}
        }
    }
    if !left_out.is_empty() {
        let all_rows = std::mem::take(&mut judgments.rows);
        for row in all_rows {
            match reason[row.participant as usize] {
                Some(Reason::Pilot) => left_out.pilot_judgments += row.count,
                Some(Reason::Excluded) => left_out.excluded_judgments += row.count,
                None => judgments.rows.push(row),
            }
        }
        if judgments.rows.is_empty() {
            return Err(AnalysisError::Empty(format!(
                "{source_name}: every participant is a pilot or excluded, so no trials are left to analyse ({})",
                left_out.describe()
            )));
        }
        let mut participant_map = vec![u32::MAX; judgments.participants.len()];
        let mut group_map = vec![u32::MAX; judgments.groups.len()];
        let (mut participants, mut groups) = (Vec::new(), Vec::new());
        for row in &mut judgments.rows {
            let p = row.participant as usize;
            if participant_map[p] == u32::MAX {
                participant_map[p] = participants.len() as u32;
                participants.push(std::mem::take(&mut judgments.participants[p]));
            }
            row.participant = participant_map[p];
            if group_column.is_some() {
                let g = row.group as usize;
                if group_map[g] == u32::MAX {
                    group_map[g] = groups.len() as u32;
                    groups.push(std::mem::take(&mut judgments.groups[g]));
                }
                row.group = group_map[g];
            }
        }
        judgments.participants = participants;
        judgments.groups = groups;
    }

    if conditions.is_none() {
        // Conditions only left-out participants compared are dropped.
        let mut used = vec![left_out.is_empty(); condition_names.len()];
        for row in &judgments.rows {
            used[row.left as usize] = true;
            used[row.right as usize] = true;
        }
        // Sorted by name, so results do not depend on row order.
        let mut order: Vec<usize> = (0..condition_names.len()).filter(|&c| used[c]).collect();
        order.sort_by(|&a, &b| condition_names[a].cmp(&condition_names[b]));
        let mut new_index = vec![0u32; condition_names.len()];
        for (new, &old) in order.iter().enumerate() {
            new_index[old] = new as u32;
        }
        for row in &mut judgments.rows {
            row.left = new_index[row.left as usize];
            row.right = new_index[row.right as usize];
        }
        condition_names = order.iter().map(|&old| condition_names[old].clone()).collect();
    }
    judgments.conditions = condition_names;
    Ok(ParsedTrials { judgments, left_out })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_trials_and_sorts_conditions_by_name() {
        let text = "participant,left,right,chosen,rt_ms\np1,LQ,HQ,HQ,800\np1,GI,LQ,GI,700\n";
        let judgments = parse_trials(text, "t.csv", None, None).unwrap();
        assert_eq!(judgments.conditions, vec!["GI", "HQ", "LQ"]);
        assert_eq!(
            judgments.rows[0],
            Judgment { participant: 0, left: 2, right: 1, left_chosen: false, count: 1, group: 0 }
        );
        assert_eq!(judgments.n_judgments(), 2);
    }

    #[test]
    fn chosen_must_be_left_or_right() {
        let text = "participant,left,right,chosen\np1,LQ,HQ,GI\n";
        let message = parse_trials(text, "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(
            message,
            "t.csv: line 2, column `chosen`: `GI` is neither the left (`LQ`) nor the right (`HQ`) condition"
        );
    }

    #[test]
    fn malformed_row_names_the_line() {
        let text = "participant,left,right,chosen\np1,LQ,HQ,HQ\np2,LQ,HQ\n";
        let message = parse_trials(text, "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(message, "t.csv: line 3: the row has 3 fields but the header has 4");
    }

    #[test]
    fn missing_column_is_named() {
        let message = parse_trials("participant,left,chosen\n", "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(message, "t.csv: the header has no column `right` (it has: participant, left, chosen)");
    }

    #[test]
    fn condition_missing_from_conditions_file() {
        let conditions = parse_conditions("condition,gi\nLQ,0\nGI,1\n", "c.csv").unwrap();
        let message = parse_trials("participant,left,right,chosen\np,LQ,HQ,HQ\n", "t.csv", Some(&conditions), None)
            .unwrap_err()
            .to_string();
        assert_eq!(message, "t.csv: line 2: condition `HQ` is not in the conditions file");
    }

    #[test]
    fn duplicate_and_non_numeric_conditions() {
        let message = parse_conditions("condition,gi\nLQ,0\nGI,1\nLQ,1\n", "c.csv").unwrap_err().to_string();
        assert_eq!(message, "c.csv: line 4: condition `LQ` is listed twice (first on line 2)");
        let message = parse_conditions("condition,gi\nLQ,off\n", "c.csv").unwrap_err().to_string();
        assert_eq!(message, "c.csv: line 2, column `gi`: the factor level `off` is not a finite number");
        let message = parse_conditions("condition,gi\nLQ,NaN\n", "c.csv").unwrap_err().to_string();
        assert!(message.contains("not a finite number"));
    }

    #[test]
    fn counts_and_groups() {
        let text = "participant,left,right,chosen,count,gender\np1,A,B,A,1000000000,f\np2,A,B,B,3,m\n";
        let judgments = parse_trials(text, "t.csv", None, Some("gender")).unwrap();
        assert_eq!(judgments.n_judgments(), 1_000_000_003);
        assert_eq!(judgments.groups, vec!["f", "m"]);
        let message = parse_trials("participant,left,right,chosen,count\np,A,B,A,0\n", "t.csv", None, None)
            .unwrap_err()
            .to_string();
        assert_eq!(message, "t.csv: line 2, column `count`: `0` is not a positive whole number");
    }

    #[test]
    fn self_comparison_and_empty_file() {
        let message =
            parse_trials("participant,left,right,chosen\np,A,A,A\n", "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(message, "t.csv: line 2, column `right`: the trial compares condition `A` with itself");
        let message = parse_trials("participant,left,right,chosen\n", "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(message, "t.csv: there are no trials in the file");
    }
}
