//! The trials CSV: one row per judgment (see the module above for its columns), read into
//! [`Judgments`](super::Judgments) with the participants left out and, where asked for, each row's scenes.

use std::collections::HashMap;

use super::conditions::ConditionTable;
use super::csv::{Field, Records, ShortNames, csv_error, header_index, parse_flag, read_unquoted, reader};
use super::{GROUND_TRUTH, Judgment, Judgments};
use crate::error::{AnalysisError, Result};

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
    /// The rows answered `chosen = tie` ("not sure", a study with `allow_tie = true`), numbered
    /// as `judgments` (their `left_chosen` is meaningless). They are not in `judgments.rows`, so
    /// every analysis of choices leaves them out; the Davidson fit and the JOD scale read them.
    pub ties: Vec<Judgment>,
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
    /// The last participant and group seen: name, [`short_word`](super::csv::short_word) (where short), index.
    last_participant: Option<(String, u64, u32)>,
    last_group: Option<(String, u64, u32)>,
    /// Per participant (by index): marked pilot, marked excluded, in any of their rows.
    marks: Vec<(bool, bool)>,
    judgments: Judgments,
    /// Whether [`GROUND_TRUTH`] is accepted when the conditions file lacks it.
    allow_ground_truth: bool,
    scene_index: FnvMap<u32>,
    scenes: TrialScenes,
    /// Indices into `judgments.rows` of the rows answered `tie`.
    tie_rows: Vec<usize>,
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
            tie_rows: Vec::new(),
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
        } else if chosen.text == "tie" {
            self.tie_rows.push(self.judgments.rows.len());
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

impl Records for RowReader<'_> {
    #[inline]
    fn reserve(&mut self, additional: usize) {
        self.judgments.rows.reserve(additional);
    }

    #[inline]
    fn record<'f>(&mut self, line: u64, field: impl Fn(usize) -> Field<'f>) -> Result<()> {
        self.row(line, field)
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
    if !read_unquoted(&text[data_start.byte() as usize..], source_name, data_start.line(), n_columns, &mut rows)? {
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
    let RowReader { mut judgments, marks, mut condition_names, scenes, tie_rows, .. } = rows;
    let mut is_tie: Option<Vec<bool>> = (!tie_rows.is_empty()).then(|| {
        let mut flags = vec![false; judgments.rows.len()];
        for k in tie_rows {
            flags[k] = true;
        }
        flags
    });
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
        let all_ties = is_tie.as_mut().map(std::mem::take);
        for (k, row) in all_rows.into_iter().enumerate() {
            match reason[row.participant as usize] {
                Some(Reason::Pilot) => left_out.pilot_judgments += row.count,
                Some(Reason::Excluded) => left_out.excluded_judgments += row.count,
                None => {
                    judgments.rows.push(row);
                    if let (Some(kept), Some(all)) = (scenes.as_mut(), all_scenes.as_ref()) {
                        kept.rows.push(all[k]);
                    }
                    if let (Some(kept), Some(all)) = (is_tie.as_mut(), all_ties.as_ref()) {
                        kept.push(all[k]);
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
    let mut ties = Vec::new();
    if let Some(is_tie) = is_tie {
        let all_rows = std::mem::take(&mut judgments.rows);
        let all_scenes = scenes.as_mut().map(|scenes| std::mem::take(&mut scenes.rows));
        for (k, row) in all_rows.into_iter().enumerate() {
            if is_tie[k] {
                ties.push(row);
            } else {
                judgments.rows.push(row);
                if let (Some(kept), Some(all)) = (scenes.as_mut(), all_scenes.as_ref()) {
                    kept.rows.push(all[k]);
                }
            }
        }
        if judgments.rows.is_empty() {
            return Err(AnalysisError::Empty(format!(
                "{source_name}: every trial is a tie (`chosen` = `tie`), so there is no choice to analyse"
            )));
        }
    }
    Ok(ParsedTrials { judgments, left_out, scenes, ties })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::parse_conditions;

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
    fn ties_are_read_apart_from_the_choices() {
        let text = "participant,left,right,chosen,pilot\np1,A,B,tie,false\np1,A,B,A,false\np2,B,C,tie,true\n\
                    p3,C,A,C,false\np3,A,C,tie,false\n";
        let parsed = parse_trials_with(text, "t.csv", None, &TrialsOptions::default()).unwrap();
        assert_eq!(parsed.judgments.rows.len(), 2);
        assert_eq!(parsed.judgments.participants, ["p1", "p3"]);
        let ties: Vec<(u32, u32, u32)> = parsed.ties.iter().map(|t| (t.participant, t.left, t.right)).collect();
        assert_eq!(ties, [(0, 0, 1), (1, 0, 2)], "the pilot's tie goes with the pilot; indices renumbered");
        let message =
            parse_trials("participant,left,right,chosen\np,A,B,tie\n", "t.csv", None, None).unwrap_err().to_string();
        assert_eq!(message, "t.csv: every trial is a tie (`chosen` = `tie`), so there is no choice to analyse");
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
