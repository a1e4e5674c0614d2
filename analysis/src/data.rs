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

/// Where the columns the analysis reads are in the trials CSV.
#[derive(Clone, Copy)]
struct Columns<'a> {
    participant: usize,
    left: usize,
    right: usize,
    chosen: usize,
    count: Option<usize>,
    group: Option<usize>,
    group_name: &'a str,
    pilot: Option<usize>,
    excluded: Option<usize>,
}

/// FNV-1a: the names hashed here are short and come from the analyst's own file.
#[derive(Default)]
struct Fnv(u64);

impl std::hash::Hasher for Fnv {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        let mut hash = if self.0 == 0 { 0xcbf2_9ce4_8422_2325 } else { self.0 };
        for &byte in bytes {
            hash = (hash ^ u64::from(byte)).wrapping_mul(0x100_0000_01b3);
        }
        self.0 = hash;
    }
}

type FnvMap<V> = HashMap<String, V, std::hash::BuildHasherDefault<Fnv>>;

/// The trials CSV's rows turned into judgments: condition, participant and group names interned
/// (the last participant and group remembered, as a file lists a participant's rows together).
struct RowReader<'a> {
    source_name: &'a str,
    conditions: Option<&'a ConditionTable>,
    columns: Columns<'a>,
    condition_index: FnvMap<u32>,
    condition_names: Vec<String>,
    /// [`short_key`] of each condition name, in index order.
    short_keys: Vec<(u64, usize)>,
    participant_index: FnvMap<u32>,
    group_index: FnvMap<u32>,
    last_participant: Option<(String, u32)>,
    last_group: Option<(String, u32)>,
    /// Per participant (by index): marked pilot, marked excluded, in any of their rows.
    marks: Vec<(bool, bool)>,
    judgments: Judgments,
}

impl<'a> RowReader<'a> {
    fn new(source_name: &'a str, conditions: Option<&'a ConditionTable>, columns: Columns<'a>) -> RowReader<'a> {
        let mut condition_index = FnvMap::default();
        let mut condition_names = Vec::new();
        if let Some(table) = conditions {
            for (k, name) in table.conditions.iter().enumerate() {
                condition_index.insert(name.clone(), k as u32);
            }
            condition_names = table.conditions.clone();
        }
        RowReader {
            source_name,
            conditions,
            columns,
            condition_index,
            short_keys: condition_names.iter().map(|name| short_key(name)).collect(),
            condition_names,
            participant_index: FnvMap::default(),
            group_index: FnvMap::default(),
            last_participant: None,
            last_group: None,
            marks: Vec::new(),
            judgments: Judgments::default(),
        }
    }

    fn bad(&self, line: u64, column: &str, message: String) -> AnalysisError {
        AnalysisError::BadValue { source_name: self.source_name.to_string(), line, column: column.to_string(), message }
    }

    /// The index of a known condition. A study has a handful of conditions with short names:
    /// comparing a name's first eight bytes and length, as one integer, with each beats hashing.
    fn find_condition(&self, name: &str) -> Option<u32> {
        if self.condition_names.len() <= 16 && name.len() <= 8 {
            let key = short_key(name);
            return self.short_keys.iter().position(|&k| k == key).map(|k| k as u32);
        }
        self.condition_index.get(name).copied()
    }

    fn condition(&mut self, line: u64, column: &str, name: &str) -> Result<u32> {
        if name.is_empty() {
            return Err(self.bad(line, column, "the condition name is empty".to_string()));
        }
        if let Some(k) = self.find_condition(name) {
            return Ok(k);
        }
        if self.conditions.is_some() {
            return Err(AnalysisError::UnknownCondition {
                source_name: self.source_name.to_string(),
                line,
                condition: name.to_string(),
            });
        }
        let k = self.condition_names.len() as u32;
        self.condition_index.insert(name.to_string(), k);
        self.condition_names.push(name.to_string());
        self.short_keys.push(short_key(name));
        Ok(k)
    }

    /// One record; `field(k)` is its k-th field, trimmed.
    fn row<'f>(&mut self, line: u64, field: impl Fn(usize) -> &'f str) -> Result<()> {
        let columns = self.columns;
        let left_name = field(columns.left);
        let right_name = field(columns.right);
        let left = self.condition(line, "left", left_name)?;
        let right = self.condition(line, "right", right_name)?;
        if left == right {
            return Err(self.bad(line, "right", format!("the trial compares condition `{left_name}` with itself")));
        }
        let chosen = field(columns.chosen);
        let chosen_index = self.find_condition(chosen);
        let left_chosen = if chosen_index == Some(left) {
            true
        } else if chosen_index == Some(right) {
            false
        } else {
            return Err(self.bad(
                line,
                "chosen",
                format!("`{chosen}` is neither the left (`{left_name}`) nor the right (`{right_name}`) condition"),
            ));
        };
        let participant_name = field(columns.participant);
        if participant_name.is_empty() {
            return Err(self.bad(line, "participant", "the participant is empty".to_string()));
        }
        let participant = match &self.last_participant {
            Some((name, index)) if name == participant_name => *index,
            _ => {
                let next = self.participant_index.len() as u32;
                let participants = &mut self.judgments.participants;
                let index = *self.participant_index.entry(participant_name.to_string()).or_insert_with(|| {
                    participants.push(participant_name.to_string());
                    next
                });
                self.last_participant = Some((participant_name.to_string(), index));
                index
            }
        };
        if self.marks.len() <= participant as usize {
            self.marks.push((false, false));
        }
        for (column, name, is_pilot) in [(columns.pilot, "pilot", true), (columns.excluded, "excluded", false)] {
            let Some(k) = column else { continue };
            let cell = field(k);
            let flag = parse_flag(cell)
                .ok_or_else(|| self.bad(line, name, format!("`{cell}` is neither `true` nor `false`")))?;
            let mark = &mut self.marks[participant as usize];
            if is_pilot { mark.0 |= flag } else { mark.1 |= flag }
        }
        let count = match columns.count {
            None => 1,
            Some(k) => {
                let cell = field(k);
                cell.parse::<u64>()
                    .ok()
                    .filter(|&c| c > 0)
                    .ok_or_else(|| self.bad(line, "count", format!("`{cell}` is not a positive whole number")))?
            }
        };
        let group = match columns.group {
            None => 0,
            Some(k) => {
                let value = field(k);
                if value.is_empty() {
                    return Err(self.bad(line, columns.group_name, "the group value is empty".to_string()));
                }
                match &self.last_group {
                    Some((name, index)) if name == value => *index,
                    _ => {
                        let next = self.group_index.len() as u32;
                        let groups = &mut self.judgments.groups;
                        let index = *self.group_index.entry(value.to_string()).or_insert_with(|| {
                            groups.push(value.to_string());
                            next
                        });
                        self.last_group = Some((value.to_string(), index));
                        index
                    }
                }
            }
        };
        self.judgments.rows.push(Judgment { participant, left, right, left_chosen, count, group });
        Ok(())
    }
}

/// Reads the records of `data` (the text after the header, whose first line is `first_line`)
/// by splitting at `\n` and `,` (found by `memchr`'s vectorised search): the whole reading
/// where the file has no quote and no `\r` but before a `\n`. Returns `Ok(false)` where it
/// meets a quote or another `\r` (the caller then reads the file with the csv crate instead).
/// Empty lines are skipped (and not counted in line numbers) and rows of the wrong length
/// refused, all as the csv crate does.
fn read_unquoted(data: &str, first_line: u64, n_columns: usize, rows: &mut RowReader) -> Result<bool> {
    let bytes = data.as_bytes();
    if bytes.contains(&b'"') {
        return Ok(false);
    }
    // Room for every row, from the length of the first.
    let first_length = data.find('\n').unwrap_or(data.len()) + 1;
    rows.judgments.rows.reserve(data.len() / first_length.max(8) + 1);
    let mut fields: Vec<&str> = Vec::with_capacity(n_columns);
    let mut line_number = first_line;
    let (mut line_start, mut field_start) = (0, 0);
    for at in memchr::memchr3_iter(b',', b'\n', b'\r', bytes) {
        match bytes[at] {
            b',' => {
                fields.push(&data[field_start..at]);
                field_start = at + 1;
            }
            b'\r' => {
                if bytes.get(at + 1) != Some(&b'\n') {
                    return Ok(false);
                }
            }
            _ => {
                let end = if at > field_start && bytes[at - 1] == b'\r' { at - 1 } else { at };
                // Empty lines are skipped and, as the csv crate counts, not counted.
                if end > line_start {
                    fields.push(&data[field_start..end]);
                    record(rows, &fields, line_number, n_columns)?;
                    line_number += 1;
                }
                fields.clear();
                line_start = at + 1;
                field_start = at + 1;
            }
        }
    }
    if line_start < bytes.len() {
        fields.push(&data[field_start..]);
        record(rows, &fields, line_number, n_columns)?;
    }
    Ok(true)
}

/// One record of [`read_unquoted`].
fn record(rows: &mut RowReader, fields: &[&str], line: u64, n_columns: usize) -> Result<()> {
    if fields.len() != n_columns {
        return Err(AnalysisError::MalformedCsv {
            source_name: rows.source_name.to_string(),
            line,
            message: format!("the row has {} fields but the header has {n_columns}", fields.len()),
        });
    }
    rows.row(line, |k| trim(fields[k]))
}

/// A name's first eight bytes as an integer, with its length: equal for two names of up to eight
/// bytes exactly when the names are equal.
fn short_key(name: &str) -> (u64, usize) {
    let key = name.as_bytes().iter().take(8).enumerate().fold(0u64, |key, (k, &byte)| key | u64::from(byte) << (8 * k));
    (key, name.len())
}

/// `str::trim`, without decoding where the field starts and ends with a printable ASCII byte
/// (none of which is white space).
fn trim(field: &str) -> &str {
    match field.as_bytes() {
        [first, .., last] if (b'!'..=b'~').contains(first) && (b'!'..=b'~').contains(last) => field,
        [only] if (b'!'..=b'~').contains(only) => field,
        _ => field.trim(),
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
    let columns = Columns {
        participant: participant_column,
        left: left_column,
        right: right_column,
        chosen: chosen_column,
        count: count_column,
        group: group_column,
        group_name: group_by.unwrap_or_default(),
        pilot: pilot_column,
        excluded: excluded_column,
    };
    let n_columns = headers.len();
    let data_start = reader.position().clone();
    let mut rows = RowReader::new(source_name, conditions, columns);
    // The fast path reads the common file (no quotes, `\n` or `\r\n` line ends) by splitting
    // bytes; a file it cannot read that way is read again, from the start, by the csv crate.
    if !read_unquoted(&text[data_start.byte() as usize..], data_start.line(), n_columns, &mut rows)? {
        rows = RowReader::new(source_name, conditions, columns);
        let mut record = csv::StringRecord::new();
        loop {
            match reader.read_record(&mut record) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(csv_error(source_name, e)),
            }
            let line = record.position().map(|p| p.line()).unwrap_or(0);
            rows.row(line, |k| record.get(k).unwrap_or("").trim())?;
        }
    }
    let RowReader { mut judgments, marks, mut condition_names, .. } = rows;
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

    /// The byte-splitting fast path and the csv crate (which reads any file with a quote) agree
    /// on line ends, empty lines, white space, a missing last newline and the line of an error.
    #[test]
    fn fast_path_reads_as_the_csv_crate_does() {
        let quoted = |text: &str| text.replacen("p1,", "\"p1\",", 1);
        let texts = [
            "participant,left,right,chosen\r\np1,A,B,A\r\n\r\np2, B ,A,A\r\n",
            "participant,left,right,chosen,gender\n\np1,A,B,A,f\np1,Long name,B,B,f\n\np2,B,Long name,Long name,m",
            "participant,left,right,chosen\np1,A,B,A\n\n\np2,A,B\n",
            "participant,left,right,chosen\np1,A,B,A\np2,A,\u{a0}B,B\n",
            "participant,left,right,chosen\np1,A,B,A\rp2,A,B,B\n",
        ];
        for text in texts {
            let group = text.contains("gender").then_some("gender");
            let fast = parse_trials(text, "t.csv", None, group);
            let reference = parse_trials(&quoted(text), "t.csv", None, group);
            match (fast, reference) {
                (Ok(fast), Ok(reference)) => {
                    assert_eq!(fast.rows, reference.rows, "{text:?}");
                    assert_eq!((fast.conditions, fast.participants), (reference.conditions, reference.participants));
                    assert_eq!(fast.groups, reference.groups);
                }
                (Err(fast), Err(reference)) => assert_eq!(fast.to_string(), reference.to_string()),
                (fast, reference) => panic!("{text:?}: {fast:?} against {reference:?}"),
            }
        }
        let error = parse_trials(texts[2], "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(error, "t.csv: line 3: the row has 3 fields but the header has 4", "the csv crate's count");
    }
}
