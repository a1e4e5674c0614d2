//! Lab-task statistics: the repeated-measures analysis of timed task trials, where every
//! participant works under each of several conditions (Knecht 2013, Section 6.3: Friedman tests
//! across three rendering conditions).
//!
//! Input is a long CSV, one row per measurement, `participant,condition,value` (extra columns are
//! ignored). The lab-task export of the server writes `participant,task,measure,condition,value`;
//! when `task` and/or `measure` columns exist the analysis runs once per distinct combination of
//! them, and [`analyze_task_csv_by`] takes any other grouping column by name.
//!
//! Per measure it reports
//! - descriptives per condition: n, mean, sd, median, quartiles (R's `quantile` type 7), min, max;
//! - the Friedman rank-sum test with tie correction, as R's `friedman.test`, and Kendall's
//!   W = χ²_F / (n·(k − 1)) from the same tie-corrected statistic;
//! - pairwise Wilcoxon signed-rank post hoc tests, as R's `wilcox.test(x, y, paired = TRUE)`
//!   defaults, with Holm-adjusted p-values as R's `p.adjust(method = "holm")`.
//!
//! How the data are shaped into a participant × condition table, explicitly:
//! - **Several values for one participant and condition are averaged** (arithmetic mean) into one
//!   cell, and a warning lists the cells that were averaged.
//! - **Participants lacking a condition are excluded from the Friedman test** (it needs complete
//!   blocks), with a warning listing them and what they lack. The descriptives use every value
//!   of a condition, and each post hoc pair uses every participant who has both of its conditions
//!   (pairwise complete, as R's `wilcox.test` does with `NA` pairs).
//! - Conditions and participants keep the order of their first appearance in the file; post hoc
//!   pair (a, b) has a before b in that order and its V is computed from the differences a − b.
//!
//! Where a test is undefined (fewer than two conditions, one participant, all values tied, all
//! differences zero) it is omitted with a warning saying why; nothing is ever NaN or infinite.
//! A post hoc pair whose smallest attainable two-sided p exceeds [`POST_HOC_ALPHA`] (fewer than
//! 6 non-zero differences for the exact test: 2/2⁵ = 0.0625) is reported as not estimable, with
//! the reason and V but no p-value, and is left out of the Holm adjustment.
//! Reference values come from R 4.2.2, by `analysis/tests/reference/task_stats.R`.
//!
//! The sections live in submodules: `parse` (the CSV into groups of measurements), `measure`
//! (one measure: the participant × condition table and its tests), `descriptives`, `friedman`
//! (ranks, the Friedman test, Kendall's W), `posthoc` (Wilcoxon signed-rank, Holm) and `report`
//! (the plain-text table); the public items are re-exported here.

mod descriptives;
mod friedman;
mod measure;
mod parse;
mod posthoc;
mod report;
#[cfg(test)]
mod tests;

pub use friedman::{average_ranks, friedman_test};
pub use posthoc::{holm_adjust, wilcoxon_signed_rank_paired};
pub use report::render_table;

use serde::Serialize;
use serde::ser::{SerializeMap, Serializer};

use crate::error::Result;
use crate::pvalue::PValue;
use measure::analyze_measure;
use parse::parse_task_csv;

/// The column naming the participant.
pub const PARTICIPANT_COLUMN: &str = "participant";
/// The column naming the condition.
pub const CONDITION_COLUMN: &str = "condition";
/// The column holding the measured value.
pub const VALUE_COLUMN: &str = "value";
/// Grouping columns used automatically when present, in this order (the lab-task export).
pub const AUTO_GROUP_COLUMNS: [&str; 2] = ["task", "measure"];
/// R's `wilcox.test` default: the exact null distribution is used below this many non-zero
/// differences (when there are no ties and no zeros).
pub const WILCOXON_EXACT_BELOW: usize = 50;
/// The significance level a post hoc test must be able to reach: a Wilcoxon test whose smallest
/// attainable two-sided p (`min_p`) exceeds it is reported as not estimable, without a p-value,
/// and left out of the Holm adjustment (exactly: fewer than 6 non-zero differences).
pub const POST_HOC_ALPHA: f64 = 0.05;

// ---------------------------------------------------------------------------------------------
// Result types
// ---------------------------------------------------------------------------------------------

/// The analysis of one task CSV: one [`MeasureAnalysis`] per group (one in all when the file has
/// no grouping column).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskAnalysis {
    /// The source name the CSV was given under.
    pub source: String,
    /// Data rows read.
    pub rows: usize,
    /// The grouping columns, in order; empty when the whole file is one measure.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub grouped_by: Vec<String>,
    /// One analysis per distinct group, in order of first appearance.
    pub measures: Vec<MeasureAnalysis>,
}

impl TaskAnalysis {
    /// Every warning of every measure, each prefixed with its group where there are groups.
    pub fn warnings(&self) -> Vec<String> {
        self.measures
            .iter()
            .flat_map(|measure| {
                let prefix =
                    if measure.group.is_empty() { String::new() } else { format!("{}: ", measure.group.label()) };
                measure.warnings.iter().map(move |warning| format!("{prefix}{warning}"))
            })
            .collect()
    }
}

/// The values of the grouping columns that identify one measure, e.g. `task = placement`,
/// `measure = time_s`. Serialised as a JSON object in column order.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct GroupKey(pub Vec<(String, String)>);

impl GroupKey {
    /// Whether there is no grouping (the whole file is one measure).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// A short label for tables and warnings: `task placement, measure time_s`.
    pub fn label(&self) -> String {
        let parts: Vec<String> = self.0.iter().map(|(column, value)| format!("{column} {value}")).collect();
        parts.join(", ")
    }
}

impl Serialize for GroupKey {
    fn serialize<S: Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.0.len()))?;
        for (column, value) in &self.0 {
            map.serialize_entry(column, value)?;
        }
        map.end()
    }
}

/// The analysis of one measure: descriptives, the Friedman test and the post hoc tests.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeasureAnalysis {
    /// The grouping values of this measure; omitted when the file is not grouped.
    #[serde(skip_serializing_if = "GroupKey::is_empty")]
    pub group: GroupKey,
    /// Distinct participants with at least one value.
    pub participants: usize,
    /// Descriptives per condition, in order of first appearance.
    pub conditions: Vec<ConditionSummary>,
    /// Participant–condition cells with several values, which were averaged.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub averaged: Vec<AveragedCell>,
    /// Participants lacking at least one condition, excluded from the Friedman test.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub excluded_participants: Vec<String>,
    /// The Friedman test; omitted where it is undefined (see `warnings`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friedman: Option<FriedmanTest>,
    /// One Wilcoxon signed-rank test per pair of conditions; empty with fewer than two.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub post_hoc: Vec<WilcoxonPair>,
    /// Everything the reader must know about how the data were handled, one sentence each.
    pub warnings: Vec<String>,
}

/// Descriptive statistics of one condition over the participants who have it (one averaged value
/// per participant).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConditionSummary {
    pub condition: String,
    /// Participants with a value for this condition.
    pub n: usize,
    pub mean: f64,
    /// Sample standard deviation (n − 1 denominator); omitted for n < 2.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sd: Option<f64>,
    pub median: f64,
    /// First quartile, R's `quantile(type = 7)`.
    pub q1: f64,
    /// Third quartile, R's `quantile(type = 7)`.
    pub q3: f64,
    pub min: f64,
    pub max: f64,
    /// Mean within-participant rank over the participants in the Friedman test (1 = smallest
    /// value); omitted when no participant has all conditions or there is only one condition.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_rank: Option<f64>,
}

/// A participant–condition cell that had several values; its value is their mean.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct AveragedCell {
    pub participant: String,
    pub condition: String,
    /// How many values were averaged.
    pub values: usize,
}

/// The Friedman rank-sum test with tie correction, as R's `friedman.test`, and Kendall's W.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FriedmanTest {
    /// Blocks (participants with every condition), R's n.
    pub participants: usize,
    /// Treatments (conditions), R's k.
    pub conditions: usize,
    /// The tie-corrected Friedman χ² statistic.
    pub statistic: f64,
    /// Degrees of freedom, k − 1.
    pub df: usize,
    /// Upper-tail χ² p-value.
    pub p: PValue,
    /// Kendall's coefficient of concordance W = statistic / (n·(k − 1)), tie-corrected because
    /// the statistic is.
    pub kendall_w: f64,
    /// Sum of within-block ranks per condition, in input order.
    #[serde(skip)]
    pub rank_sums: Vec<f64>,
}

/// How a Wilcoxon signed-rank p-value was computed (as R's `wilcox.test` chooses by default).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum WilcoxonMethod {
    /// The exact null distribution of V: fewer than 50 non-zero differences, no ties, no zeros.
    Exact,
    /// The normal approximation with continuity correction and tie correction.
    Normal,
}

/// One paired Wilcoxon signed-rank test, as R's `wilcox.test(x, y, paired = TRUE)`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WilcoxonTest {
    /// Non-zero differences (R drops zero differences before ranking).
    pub n_nonzero: usize,
    /// R's statistic V: the sum of the ranks of |x − y| over the positive differences.
    pub v: f64,
    /// How p was computed; omitted when all differences are zero.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub method: Option<WilcoxonMethod>,
    /// The standardised statistic of the normal approximation, after continuity correction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
    /// Two-sided p-value; omitted when all differences are zero (R reports `NA`), and in a post
    /// hoc pair that is not estimable (see [`WilcoxonPair::not_estimable`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p: Option<PValue>,
    /// The smallest two-sided p these differences could give by the same method (all of one
    /// sign): 2/2ⁿ when exact; omitted when all differences are zero.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_p: Option<PValue>,
}

/// A post hoc comparison of two conditions over the participants who have both.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WilcoxonPair {
    pub condition_a: String,
    pub condition_b: String,
    /// Participants with both conditions.
    pub n: usize,
    /// The test on the differences a − b; omitted when no participant has both conditions.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub test: Option<WilcoxonTest>,
    /// Holm-adjusted p over the pairs of this measure that have a p-value.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p_holm: Option<PValue>,
    /// Why the pair has no p-value although it has non-zero differences: too few participants
    /// for any outcome to reach [`POST_HOC_ALPHA`]. Omitted where the test is estimable.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_estimable: Option<String>,
}

// ---------------------------------------------------------------------------------------------
// Entry points
// ---------------------------------------------------------------------------------------------

/// Analyses a long task CSV `participant,condition,value`, grouped automatically by `task`
/// and/or `measure` columns when they exist. `source_name` names the text in error messages.
pub fn analyze_task_csv(text: &str, source_name: &str) -> Result<TaskAnalysis> {
    analyze_task_csv_by(text, source_name, None)
}

/// Analyses a long task CSV, once per distinct value of `measure_column` when it is given (it
/// must exist), else once per distinct combination of the [`AUTO_GROUP_COLUMNS`] present, else
/// once for the whole file.
pub fn analyze_task_csv_by(text: &str, source_name: &str, measure_column: Option<&str>) -> Result<TaskAnalysis> {
    let parsed = parse_task_csv(text, source_name, measure_column)?;
    let measures = parsed.measures.iter().map(analyze_measure).collect();
    Ok(TaskAnalysis { source: source_name.to_string(), rows: parsed.rows, grouped_by: parsed.grouped_by, measures })
}
