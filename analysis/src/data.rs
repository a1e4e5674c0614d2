//! Reading the two inputs of a paired-comparison analysis from text: the trials CSV (one row
//! per judgment, docs/design.md's long format) and the optional conditions CSV (factor levels per
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
//! Scenes: asked for by [`TrialsOptions::scenes`], the columns `scene_left` and `scene_right`
//! (the scene configuration of each side, as `mrstudy export` writes them) are read per row
//! into [`TrialScenes`], beside the judgments; a file without them is read as it is.
//!
//! The reserved condition [`GROUND_TRUTH`] (the path-traced composite a detection study
//! shows beside a rendered condition) is accepted where [`TrialsOptions::allow_ground_truth`]
//! says so even when a conditions file does not list it; it then comes after the file's
//! conditions.
//!
//! Conditions CSV: `condition,<factor>,<factor>,…`, one row per condition, numeric levels.

use std::collections::HashMap;

use crate::error::{AnalysisError, Result};

/// The reserved condition name of the ground truth: the path-traced composite of a scene
/// configuration, shown beside a rendered condition in a detection study ("which is real?").
pub const GROUND_TRUTH: &str = "ground-truth";

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

    /// Some of this data set's rows as a data set of their own: participants and groups without
    /// rows among them are left out and the rest renumbered in order of first appearance;
    /// conditions keep their order, except those `keep_condition` refuses (by index), which no
    /// row in `rows` may name.
    pub fn subset(
        &self,
        rows: impl IntoIterator<Item = Judgment>,
        keep_condition: impl Fn(usize) -> bool,
    ) -> Judgments {
        let mut condition_map = vec![u32::MAX; self.conditions.len()];
        let mut conditions = Vec::new();
        for (c, name) in self.conditions.iter().enumerate() {
            if keep_condition(c) {
                condition_map[c] = conditions.len() as u32;
                conditions.push(name.clone());
            }
        }
        let mut participant_map = vec![u32::MAX; self.participants.len()];
        let mut group_map = vec![u32::MAX; self.groups.len()];
        let mut subset = Judgments { conditions, ..Judgments::default() };
        for mut row in rows {
            let p = row.participant as usize;
            if participant_map[p] == u32::MAX {
                participant_map[p] = subset.participants.len() as u32;
                subset.participants.push(self.participants[p].clone());
            }
            row.participant = participant_map[p];
            if !self.groups.is_empty() {
                let g = row.group as usize;
                if group_map[g] == u32::MAX {
                    group_map[g] = subset.groups.len() as u32;
                    subset.groups.push(self.groups[g].clone());
                }
                row.group = group_map[g];
            }
            row.left = condition_map[row.left as usize];
            row.right = condition_map[row.right as usize];
            debug_assert!(row.left != u32::MAX && row.right != u32::MAX, "a row names a condition left out");
            subset.rows.push(row);
        }
        subset
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
    /// Read `scene_left` and `scene_right` per row into [`ParsedTrials::scenes`] (where the file
    /// has both columns).
    pub scenes: bool,
    /// Accept the reserved condition [`GROUND_TRUTH`] even where the conditions file does not
    /// list it (it is then indexed after the file's conditions).
    pub allow_ground_truth: bool,
}

/// The scene configuration of each side of each judgment, from the columns `scene_left` and
/// `scene_right`: `rows[k]` belongs to `Judgments::rows[k]`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TrialScenes {
    /// Scene names in order of first appearance; indices into this list are used in `rows`.
    pub names: Vec<String>,
    /// `[left, right]` scene of each judgment; [`TrialScenes::EMPTY`] where the cell is empty.
    pub rows: Vec<[u32; 2]>,
}

impl TrialScenes {
    /// The index that stands for an empty scene cell.
    pub const EMPTY: u32 = u32::MAX;
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
    /// Each judgment's scenes, where [`TrialsOptions::scenes`] asked for them and the file has
    /// the columns `scene_left` and `scene_right`.
    pub scenes: Option<TrialScenes>,
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

pub(crate) fn csv_error(source_name: &str, error: csv::Error) -> AnalysisError {
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

pub(crate) fn header_index(source_name: &str, headers: &csv::StringRecord, column: &str) -> Result<usize> {
    headers.iter().position(|h| h.trim() == column).ok_or_else(|| AnalysisError::MissingColumn {
        source_name: source_name.to_string(),
        column: column.to_string(),
        found: headers.iter().map(|h| h.trim()).collect::<Vec<_>>().join(", "),
    })
}

pub(crate) fn reader(text: &str) -> csv::Reader<&[u8]> {
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
#[inline]
fn parse_flag(cell: Field) -> Option<bool> {
    const FALSE: u64 = u64::from_le_bytes(*b"false\0\0\0");
    const TRUE: u64 = u64::from_le_bytes(*b"true\0\0\0\0");
    match (cell.text.len(), cell.word) {
        (5, FALSE) => Some(false),
        (4, TRUE) => Some(true),
        _ if cell.text.eq_ignore_ascii_case("true") => Some(true),
        _ if cell.text.eq_ignore_ascii_case("false") => Some(false),
        _ => None,
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
    /// `scene_left`, `scene_right`, where asked for and present.
    scenes: Option<(usize, usize)>,
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
    /// The condition names of up to eight bytes, for [`RowReader::find_condition`].
    short_names: ShortNames,
    participant_index: FnvMap<u32>,
    group_index: FnvMap<u32>,
    /// The last participant and group seen: name, [`short_word`] (where short), index.
    last_participant: Option<(String, u64, u32)>,
    last_group: Option<(String, u64, u32)>,
    /// Per participant (by index): marked pilot, marked excluded, in any of their rows.
    marks: Vec<(bool, bool)>,
    judgments: Judgments,
    /// Whether [`GROUND_TRUTH`] is accepted when the conditions file lacks it.
    allow_ground_truth: bool,
    scene_index: FnvMap<u32>,
    scenes: TrialScenes,
}

impl<'a> RowReader<'a> {
    fn new(
        source_name: &'a str,
        conditions: Option<&'a ConditionTable>,
        columns: Columns<'a>,
        allow_ground_truth: bool,
    ) -> RowReader<'a> {
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
            short_names: ShortNames::new(&condition_names),
            condition_names,
            participant_index: FnvMap::default(),
            group_index: FnvMap::default(),
            last_participant: None,
            last_group: None,
            marks: Vec::new(),
            judgments: Judgments::default(),
            allow_ground_truth,
            scene_index: FnvMap::default(),
            scenes: TrialScenes::default(),
        }
    }

    fn bad(&self, line: u64, column: &str, message: String) -> AnalysisError {
        AnalysisError::BadValue { source_name: self.source_name.to_string(), line, column: column.to_string(), message }
    }

    /// The index of a known condition: a name of up to eight bytes by [`ShortNames`] (one
    /// multiplication and one comparison, where a table could be built), any other by hashing.
    #[inline(always)]
    fn find_condition(&self, name: Field) -> Option<u32> {
        if name.is_short() && self.short_names.complete {
            return self.short_names.find(name);
        }
        self.condition_index.get(name.text).copied()
    }

    #[inline(always)]
    fn condition(&mut self, line: u64, column: &str, name: Field) -> Result<u32> {
        match self.find_condition(name) {
            Some(k) => Ok(k),
            None => self.new_condition(line, column, name),
        }
    }

    /// A condition not seen before: an error where the conditions file lists them all.
    #[cold]
    #[inline(never)]
    fn new_condition(&mut self, line: u64, column: &str, name: Field) -> Result<u32> {
        if name.text.is_empty() {
            return Err(self.bad(line, column, "the condition name is empty".to_string()));
        }
        if self.conditions.is_some() && !(self.allow_ground_truth && name.text == GROUND_TRUTH) {
            return Err(AnalysisError::UnknownCondition {
                source_name: self.source_name.to_string(),
                line,
                condition: name.text.to_string(),
            });
        }
        let k = self.condition_names.len() as u32;
        self.condition_index.insert(name.text.to_string(), k);
        self.condition_names.push(name.text.to_string());
        self.short_names = ShortNames::new(&self.condition_names);
        Ok(k)
    }

    /// The index of a participant or group `name`: `last` where it is the last one seen (rows
    /// are grouped by participant in exports), else interned by hashing in `index` and `names`
    /// and remembered as the last one.
    #[inline(always)]
    fn intern(
        name: Field,
        last: &mut Option<(String, u64, u32)>,
        index: &mut FnvMap<u32>,
        names: &mut Vec<String>,
    ) -> u32 {
        if let Some((last_name, last_word, last_index)) = last
            && name.same(Field { text: last_name, word: *last_word })
        {
            return *last_index;
        }
        Self::intern_new(name, last, index, names)
    }

    /// [`RowReader::intern`] where `name` is not the last one seen.
    #[inline(never)]
    fn intern_new(
        name: Field,
        last: &mut Option<(String, u64, u32)>,
        index: &mut FnvMap<u32>,
        names: &mut Vec<String>,
    ) -> u32 {
        let k = match index.get(name.text) {
            Some(&k) => k,
            None => {
                let k = names.len() as u32;
                index.insert(name.text.to_string(), k);
                names.push(name.text.to_string());
                k
            }
        };
        match last {
            Some((last_name, last_word, last_index)) => {
                last_name.clear();
                last_name.push_str(name.text);
                (*last_word, *last_index) = (name.word, k);
            }
            None => *last = Some((name.text.to_string(), name.word, k)),
        }
        k
    }

    /// One record; `field(k)` is its k-th field, trimmed.
    #[inline]
    fn row<'f>(&mut self, line: u64, field: impl Fn(usize) -> Field<'f>) -> Result<()> {
        let columns = self.columns;
        let left_name = field(columns.left);
        let right_name = field(columns.right);
        let left = self.condition(line, "left", left_name)?;
        let right = self.condition(line, "right", right_name)?;
        if left == right {
            return Err(self.bad(
                line,
                "right",
                format!("the trial compares condition `{}` with itself", left_name.text),
            ));
        }
        // Condition names are distinct, so `chosen` is the left condition exactly when it has its
        // name: compared directly, without a lookup.
        let chosen = field(columns.chosen);
        let left_chosen = if chosen.same(left_name) {
            true
        } else if chosen.same(right_name) {
            false
        } else {
            return Err(self.bad(
                line,
                "chosen",
                format!(
                    "`{}` is neither the left (`{}`) nor the right (`{}`) condition",
                    chosen.text, left_name.text, right_name.text
                ),
            ));
        };
        let participant_name = field(columns.participant);
        if participant_name.text.is_empty() {
            return Err(self.bad(line, "participant", "the participant is empty".to_string()));
        }
        let participant = Self::intern(
            participant_name,
            &mut self.last_participant,
            &mut self.participant_index,
            &mut self.judgments.participants,
        );
        if self.marks.len() <= participant as usize {
            self.marks.push((false, false));
        }
        for (column, name, is_pilot) in [(columns.pilot, "pilot", true), (columns.excluded, "excluded", false)] {
            let Some(k) = column else { continue };
            let cell = field(k);
            let flag = parse_flag(cell)
                .ok_or_else(|| self.bad(line, name, format!("`{}` is neither `true` nor `false`", cell.text)))?;
            let mark = &mut self.marks[participant as usize];
            if is_pilot { mark.0 |= flag } else { mark.1 |= flag }
        }
        let count = match columns.count {
            None => 1,
            Some(k) => {
                let cell = field(k).text;
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
                if value.text.is_empty() {
                    return Err(self.bad(line, columns.group_name, "the group value is empty".to_string()));
                }
                Self::intern(value, &mut self.last_group, &mut self.group_index, &mut self.judgments.groups)
            }
        };
        if let Some((left_column, right_column)) = columns.scenes {
            let mut scene = |k: usize| {
                let name = field(k).text;
                if name.is_empty() {
                    return TrialScenes::EMPTY;
                }
                if let Some(&index) = self.scene_index.get(name) {
                    return index;
                }
                let index = self.scenes.names.len() as u32;
                self.scene_index.insert(name.to_string(), index);
                self.scenes.names.push(name.to_string());
                index
            };
            let pair = [scene(left_column), scene(right_column)];
            self.scenes.rows.push(pair);
        }
        self.judgments.rows.push(Judgment { participant, left, right, left_chosen, count, group });
        Ok(())
    }
}

/// A field of a record, trimmed, with its bytes as one integer where it has at most eight
/// (for comparisons without a loop or a call).
#[derive(Clone, Copy)]
struct Field<'f> {
    text: &'f str,
    /// [`short_word`] of `text` where it has at most eight bytes, else 0.
    word: u64,
}

impl<'f> Field<'f> {
    fn new(text: &'f str) -> Field<'f> {
        let word = if text.len() <= 8 { short_word(text.as_bytes()) } else { 0 };
        Field { text, word }
    }

    /// Field `data[start..end]`, trimmed. Where it has at most eight bytes, its word is read
    /// as one load of the eight bytes at `start` (masked to its length) when the text goes on
    /// that far.
    #[inline]
    fn at(data: &'f str, start: usize, end: usize) -> Field<'f> {
        let bytes = data.as_bytes();
        let printable = |byte: u8| (b'!'..=b'~').contains(&byte);
        if !(end > start && printable(bytes[start]) && printable(bytes[end - 1])) {
            return Field::new(data[start..end].trim());
        }
        let length = end - start;
        let word = match bytes.get(start..start + 8) {
            Some(eight) if length <= 8 => {
                u64::from_le_bytes(eight.try_into().expect("eight bytes")) & (u64::MAX >> (64 - 8 * length))
            }
            _ if length <= 8 => short_word(&bytes[start..end]),
            _ => 0,
        };
        Field { text: &data[start..end], word }
    }

    #[inline]
    fn is_short(&self) -> bool {
        self.text.len() <= 8
    }

    /// Whether the two fields have the same text.
    #[inline]
    fn same(&self, other: Field) -> bool {
        self.text.len() == other.text.len()
            && if self.is_short() { self.word == other.word } else { self.text == other.text }
    }
}

/// Reads the records of `data` (the text after the header, whose first line is `first_line`)
/// in one pass over its bytes: the separators (`,` and `\n`) are found eight bytes at a time
/// ([`Separators`]), each field is a slice of `data` (validated as UTF-8 once, as a whole), and
/// only the columns the analysis reads are looked at. The whole reading where the file has no
/// quote and no `\r` but before a `\n`; returns `Ok(false)` where it has (the caller then reads
/// the file with the csv crate instead). Empty lines are skipped (and not counted in line
/// numbers) and rows of the wrong length refused, all as the csv crate does.
fn read_unquoted(data: &str, first_line: u64, n_columns: usize, rows: &mut RowReader) -> Result<bool> {
    let bytes = data.as_bytes();
    // One search for either; where a `\r` comes first, the rest is checked more closely.
    let crlf = match memchr::memchr2(b'"', b'\r', bytes) {
        None => false,
        Some(at) if bytes[at] == b'"' => return Ok(false),
        Some(at) => {
            if memchr::memchr(b'"', &bytes[at..]).is_some()
                || !memchr::memchr_iter(b'\r', &bytes[at..]).all(|k| bytes.get(at + k + 1) == Some(&b'\n'))
            {
                return Ok(false);
            }
            true
        }
    };
    // Room for every row, from the length of the first.
    let first_length = memchr::memchr(b'\n', bytes).unwrap_or(bytes.len()) + 1;
    rows.judgments.rows.reserve(bytes.len() / first_length.max(8) + 1);
    // starts[k]: where field k of the line begins; field k ends one byte before starts[k + 1].
    let mut starts = vec![0usize; n_columns + 1];
    let mut line_number = first_line;
    let mut line_end = |line_start: usize, end: usize, n_fields: usize, starts: &mut [usize]| -> Result<()> {
        // Empty lines are skipped and, as the csv crate counts, not counted.
        if end > line_start {
            if n_fields != n_columns {
                return Err(AnalysisError::MalformedCsv {
                    source_name: rows.source_name.to_string(),
                    line: line_number,
                    message: format!("the row has {n_fields} fields but the header has {n_columns}"),
                });
            }
            starts[0] = line_start;
            starts[n_columns] = end + 1;
            rows.row(line_number, |k| Field::at(data, starts[k], starts[k + 1] - 1))?;
            line_number += 1;
        }
        Ok(())
    };
    let mut separators = Separators::new(bytes);
    let mut line_start = 0;
    loop {
        // A line as expected has n_columns − 1 commas, then a `\n` (or the end of the text):
        // the loop over them ends where the count says, with few mispredicted branches.
        let mut n_fields = 1;
        let mut next = separators.next();
        while n_fields < n_columns {
            match next {
                Some((at, false)) => {
                    starts[n_fields] = at + 1;
                    n_fields += 1;
                    next = separators.next();
                }
                _ => break,
            }
        }
        // Fields beyond the header's, counted for the error.
        while let Some((_, false)) = next {
            n_fields += 1;
            next = separators.next();
        }
        let end = match next {
            Some((at, _)) => at,
            None if line_start < bytes.len() => bytes.len(),
            None => break,
        };
        let content_end = if crlf && end > line_start && bytes[end - 1] == b'\r' { end - 1 } else { end };
        line_end(line_start, content_end, n_fields, &mut starts)?;
        if next.is_none() {
            break;
        }
        line_start = end + 1;
    }
    Ok(true)
}

/// The positions of `,` and `\n` in a text, in order, each with whether it is a `\n`. Sixty-four
/// bytes at a time become one bit mask (eight bytes tested at once as one integer: a byte
/// equal to a separator becomes zero after an exclusive or, and zero bytes are found exactly
/// by Mycroft's test; a multiplication gathers their high bits), so the cost is a few
/// operations per eight bytes and a bit scan and a byte read per separator.
struct Separators<'a> {
    bytes: &'a [u8],
    /// Where the current block starts.
    base: usize,
    /// Bit k: byte `base + k` is a `,` or `\n` (found, not yet returned).
    separators: u64,
}

impl<'a> Separators<'a> {
    const BLOCK: usize = 64;

    fn new(bytes: &'a [u8]) -> Separators<'a> {
        let mut separators = Separators { bytes, base: 0, separators: 0 };
        separators.load();
        separators
    }

    /// The high bit of every byte of `word` that equals `byte`.
    #[inline]
    fn equal(word: u64, byte: u8) -> u64 {
        const LOW: u64 = 0x7f7f_7f7f_7f7f_7f7f;
        let x = word ^ (0x0101_0101_0101_0101 * u64::from(byte));
        !(((x & LOW) + LOW) | x | LOW)
    }

    /// Byte k's high bit (of a mask with only high bits set) as bit k.
    #[inline]
    fn gather(high_bits: u64) -> u64 {
        (high_bits >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56
    }

    #[inline]
    fn load(&mut self) {
        let mut separators = 0;
        match self.bytes.get(self.base..self.base + Self::BLOCK) {
            Some(block) => {
                for (k, chunk) in block.chunks_exact(8).enumerate() {
                    let word = u64::from_le_bytes(chunk.try_into().expect("eight bytes"));
                    separators |= Self::gather(Self::equal(word, b'\n') | Self::equal(word, b',')) << (8 * k);
                }
            }
            None => {
                for (k, &byte) in self.bytes[self.base.min(self.bytes.len())..].iter().enumerate() {
                    separators |= u64::from(byte == b'\n' || byte == b',') << k;
                }
            }
        }
        self.separators = separators;
    }
}

impl Iterator for Separators<'_> {
    type Item = (usize, bool);

    #[inline]
    fn next(&mut self) -> Option<(usize, bool)> {
        while self.separators == 0 {
            self.base += Self::BLOCK;
            if self.base >= self.bytes.len() {
                return None;
            }
            self.load();
        }
        let bit = self.separators.trailing_zeros();
        self.separators &= self.separators - 1;
        let at = self.base + bit as usize;
        Some((at, self.bytes[at] == b'\n'))
    }
}

/// A name of up to eight bytes as an integer (little-endian, zero-padded). With the length, it
/// tells any two such names apart.
/// Built from two overlapping loads (no copy through memory, which would stall the load after it).
#[inline]
fn short_word(name: &[u8]) -> u64 {
    let length = name.len();
    debug_assert!(length <= 8);
    if length >= 4 {
        let low = u32::from_le_bytes(name[..4].try_into().expect("four bytes"));
        let high = u32::from_le_bytes(name[length - 4..length].try_into().expect("four bytes"));
        u64::from(low) | u64::from(high) << (8 * (length - 4))
    } else if length > 0 {
        let byte = |k: usize| u64::from(name[k]) << (8 * k);
        byte(0) | byte(length / 2) | byte(length - 1)
    } else {
        0
    }
}

/// A perfect hash of the condition names of up to eight bytes: slot
/// `((word + length) · multiplier) >> shift` of a table four times as long as the names holds
/// the name's word, length and index, and no two names share a slot (a multiplier is searched
/// for when the table is built: a few tries for a study's handful of conditions). `complete` is
/// false where there are more than [`ShortNames::MAX_NAMES`] short names or no multiplier was
/// found; then every name goes through the hash map.
struct ShortNames {
    multiplier: u64,
    shift: u32,
    /// `(word, length, index)`; an empty slot has length `u32::MAX`.
    slots: Vec<(u64, u32, u32)>,
    complete: bool,
}

impl ShortNames {
    /// Odd constants (SplitMix64 outputs) tried in turn as the multiplier.
    const TRIES: usize = 64;
    const MAX_NAMES: usize = 32;

    fn new(names: &[String]) -> ShortNames {
        let short: Vec<(u64, u32, u32)> = names
            .iter()
            .enumerate()
            .filter(|(_, name)| name.len() <= 8)
            .map(|(k, name)| (short_word(name.as_bytes()), name.len() as u32, k as u32))
            .collect();
        let bits = (4 * short.len()).next_power_of_two().max(4).trailing_zeros();
        let shift = 64 - bits;
        if short.len() > Self::MAX_NAMES {
            return ShortNames { multiplier: 1, shift, slots: Vec::new(), complete: false };
        }
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..Self::TRIES {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            let multiplier = (z ^ (z >> 31)) | 1;
            let mut slots = vec![(0, u32::MAX, 0); 1 << bits];
            let placed = short.iter().all(|&(word, length, index)| {
                let slot = &mut slots[Self::slot(word, length, multiplier, shift)];
                let free = slot.1 == u32::MAX;
                *slot = (word, length, index);
                free
            });
            if placed {
                return ShortNames { multiplier, shift, slots, complete: true };
            }
        }
        ShortNames { multiplier: 1, shift, slots: Vec::new(), complete: false }
    }

    #[inline]
    fn slot(word: u64, length: u32, multiplier: u64, shift: u32) -> usize {
        (word.wrapping_add(u64::from(length)).wrapping_mul(multiplier) >> shift) as usize
    }

    /// The index of a name of up to eight bytes, if it is a known condition.
    #[inline]
    fn find(&self, name: Field) -> Option<u32> {
        let (word, length) = (name.word, name.text.len() as u32);
        let (slot_word, slot_length, index) = self.slots[Self::slot(word, length, self.multiplier, self.shift)];
        (slot_word == word && slot_length == length).then_some(index)
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
    let scene_columns = match (
        headers.iter().position(|h| h.trim() == "scene_left"),
        headers.iter().position(|h| h.trim() == "scene_right"),
    ) {
        (Some(left), Some(right)) if options.scenes => Some((left, right)),
        _ => None,
    };
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
        scenes: scene_columns,
    };
    let n_columns = headers.len();
    let data_start = reader.position().clone();
    let mut rows = RowReader::new(source_name, conditions, columns, options.allow_ground_truth);
    // The fast path reads the common file (no quotes, `\n` or `\r\n` line ends) by splitting
    // bytes; a file it cannot read that way is read again, from the start, by the csv crate.
    if !read_unquoted(&text[data_start.byte() as usize..], data_start.line(), n_columns, &mut rows)? {
        rows = RowReader::new(source_name, conditions, columns, options.allow_ground_truth);
        let mut record = csv::StringRecord::new();
        loop {
            match reader.read_record(&mut record) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(csv_error(source_name, e)),
            }
            let line = record.position().map(|p| p.line()).unwrap_or(0);
            rows.row(line, |k| Field::new(record.get(k).unwrap_or("").trim()))?;
        }
    }
    let RowReader { mut judgments, marks, mut condition_names, scenes, .. } = rows;
    let mut scenes = scene_columns.map(|_| scenes);
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
        let all_scenes = scenes.as_mut().map(|scenes| std::mem::take(&mut scenes.rows));
        for (k, row) in all_rows.into_iter().enumerate() {
            match reason[row.participant as usize] {
                Some(Reason::Pilot) => left_out.pilot_judgments += row.count,
                Some(Reason::Excluded) => left_out.excluded_judgments += row.count,
                None => {
                    judgments.rows.push(row);
                    if let (Some(kept), Some(all)) = (scenes.as_mut(), all_scenes.as_ref()) {
                        kept.rows.push(all[k]);
                    }
                }
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
    Ok(ParsedTrials { judgments, left_out, scenes })
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

    #[test]
    fn scenes_are_read_per_row_and_follow_the_rows_left_out() {
        let text = "participant,left,right,chosen,scene_left,scene_right,pilot,excluded\n\
                    p1,A,B,A,s1,s2,false,false\np2,B,A,A,s3,s1,true,false\np3,A,B,B,s2,,false,false\n";
        let options = TrialsOptions { scenes: true, ..TrialsOptions::default() };
        for text in [text.to_string(), text.replacen("p1,", "\"p1\",", 1)] {
            let parsed = parse_trials_with(&text, "t.csv", None, &options).unwrap();
            let scenes = parsed.scenes.unwrap();
            assert_eq!(scenes.names, ["s1", "s2", "s3"]);
            assert_eq!(scenes.rows, [[0, 1], [1, TrialScenes::EMPTY]], "the pilot's row goes with the pilot");
            assert_eq!(parsed.judgments.rows.len(), 2);
        }
        let without = parse_trials_with(text, "t.csv", None, &TrialsOptions::default()).unwrap();
        assert!(without.scenes.is_none(), "only when asked for");
        let no_columns =
            parse_trials_with("participant,left,right,chosen\np,A,B,A\n", "t.csv", None, &options).unwrap();
        assert!(no_columns.scenes.is_none());
    }

    #[test]
    fn ground_truth_is_accepted_beyond_a_conditions_file_only_when_allowed() {
        let conditions = parse_conditions("condition,gi\nLQ,0\nGI,1\n", "c.csv").unwrap();
        let text = "participant,left,right,chosen\np,LQ,GI,GI\np,ground-truth,LQ,LQ\n";
        let message = parse_trials(text, "t.csv", Some(&conditions), None).unwrap_err().to_string();
        assert_eq!(message, "t.csv: line 3: condition `ground-truth` is not in the conditions file");
        let options = TrialsOptions { allow_ground_truth: true, ..TrialsOptions::default() };
        let judgments = parse_trials_with(text, "t.csv", Some(&conditions), &options).unwrap().judgments;
        assert_eq!(judgments.conditions, ["LQ", "GI", "ground-truth"]);
        let subset = judgments.subset(judgments.rows[..1].iter().copied(), |c| c < 2);
        assert_eq!((subset.conditions.len(), subset.participants.len(), subset.rows[0].left), (2, 1, 0));
    }

    /// The separators found a block at a time are those a byte-by-byte scan finds, for every
    /// byte value and text length (blocks and their tails).
    #[test]
    fn separators_are_those_a_byte_scan_finds() {
        let bytes: Vec<u8> = (0..300u32)
            .map(|k| [b',', b'\n', b'a', 0x80 | b',', 0x80 | b'\n', (k * 37) as u8][k as usize % 6])
            .collect();
        for length in 0..bytes.len() {
            let text = &bytes[..length];
            let found: Vec<(usize, bool)> = Separators::new(text).collect();
            let expected: Vec<(usize, bool)> = text
                .iter()
                .enumerate()
                .filter(|&(_, &b)| b == b',' || b == b'\n')
                .map(|(k, &b)| (k, b == b'\n'))
                .collect();
            assert_eq!(found, expected, "length {length}");
        }
    }

    #[test]
    fn short_names_find_every_condition_and_nothing_else() {
        let names: Vec<String> =
            ["LQ", "GI", "CM", "GI+CM", "CA", "GI+CA", "CM+CA", "HQ", "", "A\0"].map(String::from).to_vec();
        let table = ShortNames::new(&names);
        assert!(table.complete);
        for (k, name) in names.iter().enumerate() {
            assert_eq!(table.find(Field::new(name)), Some(k as u32), "{name:?}");
        }
        for other in ["A", "HQ ", "GI+C", "CM+CA+", "lq"] {
            assert_eq!(table.find(Field::new(other)), None, "{other:?}");
        }
        let many: Vec<String> = (0..40).map(|k| format!("C{k}")).collect();
        assert!(!ShortNames::new(&many).complete, "more than MAX_NAMES go through the hash map");
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
            // Long lines and names across the 64-byte blocks, flags in any case, a name that is
            // not ASCII, short fields at the very end of the text (no last newline).
            "participant,left,right,chosen,pilot,excluded,gender\np1,Condition number one,B,B,FALSE,false,f\n\
             a participant with a long name,B,Condition number one,Condition number one,false,False,m\n\
             φ,A,B,A,false,false,f\np1,B,A,A,false,false,\u{3a3}\np2,B,A,A,false,TRUE,f",
            "participant,left,right,chosen,pilot,excluded\np1,A,B,A,false,maybe\n",
            "participant,left,right,chosen\np1,A,B,A,extra\n",
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
        let options = TrialsOptions { include_excluded: true, ..TrialsOptions::default() };
        let kept = parse_trials_with(texts[5], "t.csv", None, &options).unwrap().judgments;
        assert_eq!(kept.participants, ["p1", "a participant with a long name", "φ", "p2"]);
        assert_eq!(kept.conditions, ["A", "B", "Condition number one"]);
        let error = parse_trials(texts[2], "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(error, "t.csv: line 3: the row has 3 fields but the header has 4", "the csv crate's count");
    }
}
