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
//!
//! The model is here ([`Judgment`], [`Judgments`]); `trials` reads the trials CSV, `conditions`
//! the conditions CSV, and `csv` holds what both read cells with: the byte-splitting reader of
//! the common unquoted file and the csv crate's errors as the crate's own.

mod conditions;
mod csv;
mod trials;

pub use conditions::{ConditionTable, parse_conditions};
pub use csv::header_columns;
pub(crate) use csv::{csv_error, header_index, reader};
pub use trials::{LeftOut, ParsedTrials, TrialScenes, TrialsOptions, parse_trials, parse_trials_with};

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
