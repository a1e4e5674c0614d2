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
//! Reference values come from R 4.2.2, by `analysis/tests/reference/task_stats.R`.

use std::cmp::Ordering;
use std::collections::HashMap;
use std::fmt::Write as _;

use serde::Serialize;
use serde::ser::{SerializeMap, Serializer};

use crate::error::{AnalysisError, Result};
use crate::pvalue::PValue;

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
    /// Two-sided p-value; omitted when all differences are zero (R reports `NA`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p: Option<PValue>,
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

// ---------------------------------------------------------------------------------------------
// Parsing
// ---------------------------------------------------------------------------------------------

/// The measurements of one group, keyed by participant and condition indices.
#[derive(Debug, Default)]
struct MeasureData {
    group: GroupKey,
    participants: Vec<String>,
    participant_index: HashMap<String, usize>,
    conditions: Vec<String>,
    condition_index: HashMap<String, usize>,
    /// (participant, condition) → every value given, in file order.
    cells: HashMap<(usize, usize), Vec<f64>>,
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
struct ParsedCsv {
    rows: usize,
    grouped_by: Vec<String>,
    measures: Vec<MeasureData>,
}

fn parse_task_csv(text: &str, source_name: &str, measure_column: Option<&str>) -> Result<ParsedCsv> {
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

// ---------------------------------------------------------------------------------------------
// One measure
// ---------------------------------------------------------------------------------------------

fn analyze_measure(data: &MeasureData) -> MeasureAnalysis {
    let n_conditions = data.conditions.len();
    let mut warnings = Vec::new();

    // The participant × condition table, duplicates averaged.
    let mut table: Vec<Vec<Option<f64>>> = vec![vec![None; n_conditions]; data.participants.len()];
    let mut averaged = Vec::new();
    for (participant_idx, row) in table.iter_mut().enumerate() {
        for (condition_idx, cell) in row.iter_mut().enumerate() {
            if let Some(values) = data.cells.get(&(participant_idx, condition_idx)) {
                *cell = Some(mean(values));
                if values.len() > 1 {
                    averaged.push(AveragedCell {
                        participant: data.participants[participant_idx].clone(),
                        condition: data.conditions[condition_idx].clone(),
                        values: values.len(),
                    });
                }
            }
        }
    }
    if !averaged.is_empty() {
        let cells: Vec<String> = averaged
            .iter()
            .map(|cell| format!("{} {} ({} values)", cell.participant, cell.condition, cell.values))
            .collect();
        warnings.push(format!(
            "{} participant–condition cell{} had several values and {} averaged: {}.",
            averaged.len(),
            plural(averaged.len()),
            if averaged.len() == 1 { "was" } else { "were" },
            cells.join(", ")
        ));
    }

    // Complete blocks for the Friedman test; everyone else is excluded, by name.
    let mut blocks: Vec<Vec<f64>> = Vec::new();
    let mut complete_participants: Vec<&str> = Vec::new();
    let mut excluded_participants = Vec::new();
    let mut exclusion_notes = Vec::new();
    for (participant_idx, row) in table.iter().enumerate() {
        let participant = &data.participants[participant_idx];
        if let Some(block) = row.iter().copied().collect::<Option<Vec<f64>>>() {
            blocks.push(block);
            complete_participants.push(participant);
        } else {
            let missing: Vec<&str> = row
                .iter()
                .zip(&data.conditions)
                .filter(|(cell, _)| cell.is_none())
                .map(|(_, condition)| condition.as_str())
                .collect();
            exclusion_notes.push(format!("{participant} (no {})", missing.join(", ")));
            excluded_participants.push(participant.clone());
        }
    }

    let rank_sums = (n_conditions >= 2 && !blocks.is_empty()).then(|| rank_sums(&blocks).0);
    let conditions: Vec<ConditionSummary> = data
        .conditions
        .iter()
        .enumerate()
        .map(|(condition_idx, condition)| {
            let values: Vec<f64> = table.iter().filter_map(|row| row[condition_idx]).collect();
            let mean_rank = rank_sums.as_ref().map(|sums| sums[condition_idx] / blocks.len() as f64);
            describe(condition, &values, mean_rank)
        })
        .collect();

    if n_conditions < 2 {
        warnings.push(format!(
            "Only one condition (`{}`): there is nothing to compare, so the Friedman test and the post \
            hoc tests are omitted.",
            data.conditions.first().map_or("", String::as_str)
        ));
        return MeasureAnalysis {
            group: data.group.clone(),
            participants: data.participants.len(),
            conditions,
            averaged,
            excluded_participants: Vec::new(),
            friedman: None,
            post_hoc: Vec::new(),
            warnings,
        };
    }

    if !excluded_participants.is_empty() {
        warnings.push(format!(
            "{} of {} participant{} {} a condition and {} excluded from the Friedman test: {}. Each \
            post hoc pair uses every participant who has both of its conditions.",
            excluded_participants.len(),
            data.participants.len(),
            plural(data.participants.len()),
            if excluded_participants.len() == 1 { "lacks" } else { "lack" },
            if excluded_participants.len() == 1 { "is" } else { "are" },
            exclusion_notes.join(", ")
        ));
    }

    let friedman = match blocks.len() {
        0 => {
            warnings.push(format!("Friedman test omitted: no participant has all {n_conditions} conditions."));
            None
        }
        1 => {
            warnings.push(format!(
                "Friedman test omitted: only one participant ({}) has all {n_conditions} conditions; a \
                rank test across participants needs at least two.",
                complete_participants[0]
            ));
            None
        }
        _ => {
            let test = friedman_test(&blocks);
            if test.is_none() {
                warnings.push(
                    "Friedman test omitted: every participant gave all conditions the same value (zero \
                    variance within participants), so the ranks carry no information and the statistic is \
                    undefined (0/0)."
                        .to_string(),
                );
            }
            test
        }
    };

    // Post hoc: every pair of conditions, pairwise complete, Holm over the pairs with a p.
    let mut post_hoc = Vec::new();
    for idx_a in 0..n_conditions {
        for idx_b in idx_a + 1..n_conditions {
            let (x, y): (Vec<f64>, Vec<f64>) = table.iter().filter_map(|row| Some((row[idx_a]?, row[idx_b]?))).unzip();
            let (condition_a, condition_b) = (&data.conditions[idx_a], &data.conditions[idx_b]);
            let test = wilcoxon_signed_rank_paired(&x, &y);
            match &test {
                None => warnings.push(format!(
                    "Wilcoxon {condition_a} vs {condition_b} omitted: no participant has both conditions."
                )),
                Some(test) if test.p.is_none() => warnings.push(format!(
                    "Wilcoxon {condition_a} vs {condition_b}: all {} differences are zero, so there is no \
                    test (R reports p = NA); the pair is left out of the Holm adjustment.",
                    x.len()
                )),
                Some(_) => {}
            }
            post_hoc.push(WilcoxonPair {
                condition_a: condition_a.clone(),
                condition_b: condition_b.clone(),
                n: x.len(),
                test,
                p_holm: None,
            });
        }
    }
    let tested: Vec<usize> =
        (0..post_hoc.len()).filter(|&idx| post_hoc[idx].test.as_ref().is_some_and(|test| test.p.is_some())).collect();
    let raw: Vec<PValue> = tested.iter().filter_map(|&idx| post_hoc[idx].test.as_ref()?.p).collect();
    for (&idx, adjusted) in tested.iter().zip(holm_adjust(&raw)) {
        post_hoc[idx].p_holm = Some(adjusted);
    }

    MeasureAnalysis {
        group: data.group.clone(),
        participants: data.participants.len(),
        conditions,
        averaged,
        excluded_participants,
        friedman,
        post_hoc,
        warnings,
    }
}

fn plural(count: usize) -> &'static str {
    if count == 1 { "" } else { "s" }
}

// ---------------------------------------------------------------------------------------------
// Descriptives
// ---------------------------------------------------------------------------------------------

/// Descriptives of one condition's values (at least one value).
fn describe(condition: &str, values: &[f64], mean_rank: Option<f64>) -> ConditionSummary {
    let mut sorted = values.to_vec();
    sorted.sort_by(compare);
    let mean = mean(values);
    ConditionSummary {
        condition: condition.to_string(),
        n: values.len(),
        mean,
        sd: sample_sd(values, mean),
        median: quantile_type7(&sorted, 0.5),
        q1: quantile_type7(&sorted, 0.25),
        q3: quantile_type7(&sorted, 0.75),
        min: sorted.first().copied().unwrap_or(0.0),
        max: sorted.last().copied().unwrap_or(0.0),
        mean_rank,
    }
}

/// Arithmetic mean; finite for finite values even where their sum would overflow.
fn mean(values: &[f64]) -> f64 {
    let n = values.len() as f64;
    let plain = values.iter().sum::<f64>() / n;
    if plain.is_finite() { plain } else { values.iter().map(|value| value / n).sum() }
}

/// Sample standard deviation (n − 1 denominator); `None` for fewer than two values or where it
/// is not representable.
fn sample_sd(values: &[f64], mean: f64) -> Option<f64> {
    if values.len() < 2 {
        return None;
    }
    let denominator = (values.len() - 1) as f64;
    let plain = (values.iter().map(|value| (value - mean).powi(2)).sum::<f64>() / denominator).sqrt();
    if plain.is_finite() {
        return Some(plain);
    }
    // Overflow: work in units of the largest magnitude.
    let scale = values.iter().fold(0.0_f64, |acc, value| acc.max(value.abs()));
    let scaled: Vec<f64> = values.iter().map(|value| value / scale).collect();
    let scaled_mean = scaled.iter().sum::<f64>() / values.len() as f64;
    let scaled_sd = (scaled.iter().map(|value| (value - scaled_mean).powi(2)).sum::<f64>() / denominator).sqrt();
    Some(scaled_sd * scale).filter(|sd| sd.is_finite())
}

/// Quantile of sorted values as R's `quantile(x, prob, type = 7)`: linear interpolation between
/// order statistics at (n − 1)·prob, written as R writes it.
pub fn quantile_type7(sorted: &[f64], prob: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let index = (sorted.len() - 1) as f64 * prob;
    let lo = index.floor();
    let hi = index.ceil() as usize;
    let low_value = sorted[lo as usize];
    let high_value = sorted[hi.min(sorted.len() - 1)];
    if index > lo && high_value != low_value {
        let h = index - lo;
        // A convex combination: it cannot overflow.
        (1.0 - h) * low_value + h * high_value
    } else {
        low_value
    }
}

fn compare(a: &f64, b: &f64) -> Ordering {
    // Values are never NaN here (finite input; differences of finite values); -0 ties with 0 as
    // in R.
    a.partial_cmp(b).unwrap_or(Ordering::Equal)
}

// ---------------------------------------------------------------------------------------------
// Ranks and the Friedman test
// ---------------------------------------------------------------------------------------------

/// Average ranks (1-based, ties get the mean of their ranks, as R's `rank`) and the sizes of the
/// tie groups (1 for untied values).
pub fn average_ranks(values: &[f64]) -> (Vec<f64>, Vec<usize>) {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&i, &j| compare(&values[i], &values[j]));
    let mut ranks = vec![0.0; values.len()];
    let mut tie_sizes = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let mut end = start + 1;
        while end < order.len() && values[order[end]] == values[order[start]] {
            end += 1;
        }
        // Positions start..end hold ranks start+1 ..= end; their mean is (start + 1 + end) / 2.
        let rank = (start + 1 + end) as f64 / 2.0;
        for &idx in &order[start..end] {
            ranks[idx] = rank;
        }
        tie_sizes.push(end - start);
        start = end;
    }
    (ranks, tie_sizes)
}

/// Column rank sums over blocks ranked within themselves, and Σ(t³ − t) over all tie groups.
fn rank_sums(blocks: &[Vec<f64>]) -> (Vec<f64>, f64) {
    let n_conditions = blocks.first().map_or(0, Vec::len);
    let mut sums = vec![0.0; n_conditions];
    let mut tie_term = 0.0;
    for block in blocks {
        let (ranks, tie_sizes) = average_ranks(block);
        for (sum, rank) in sums.iter_mut().zip(ranks) {
            *sum += rank;
        }
        tie_term += tie_sizes.iter().map(|&t| (t * t * t - t) as f64).sum::<f64>();
    }
    (sums, tie_term)
}

/// The Friedman rank-sum test on complete blocks (rows: participants, columns: conditions), as
/// R's `friedman.test(matrix)`:
///
/// χ²_F = 12·Σⱼ(Rⱼ − n(k+1)/2)² / (n·k·(k+1) − Σ(t³ − t)/(k − 1)),  df = k − 1,
///
/// with Rⱼ the rank sums and t the sizes of the tie groups within blocks. `None` when there is no
/// block, fewer than two conditions, blocks of unequal length, or every block is tied throughout
/// (the statistic is 0/0).
pub fn friedman_test(blocks: &[Vec<f64>]) -> Option<FriedmanTest> {
    let k = blocks.first()?.len();
    if k < 2 || blocks.iter().any(|block| block.len() != k) {
        return None;
    }
    let n = blocks.len() as f64;
    let kf = k as f64;
    let (rank_sums, tie_term) = rank_sums(blocks);
    let expected = n * (kf + 1.0) / 2.0;
    let numerator = 12.0 * rank_sums.iter().map(|sum| (sum - expected).powi(2)).sum::<f64>();
    let denominator = n * kf * (kf + 1.0) - tie_term / (kf - 1.0);
    if denominator <= 0.0 {
        return None;
    }
    let statistic = numerator / denominator;
    let df = k - 1;
    Some(FriedmanTest {
        participants: blocks.len(),
        conditions: k,
        statistic,
        df,
        p: PValue::chi2_upper(statistic, df as f64),
        kendall_w: statistic / (n * (kf - 1.0)),
        rank_sums,
    })
}

// ---------------------------------------------------------------------------------------------
// Wilcoxon signed-rank and Holm
// ---------------------------------------------------------------------------------------------

/// The paired Wilcoxon signed-rank test of x against y, as R's `wilcox.test(x, y, paired =
/// TRUE)` with its defaults (two-sided, `exact = NULL`, `correct = TRUE`): zero differences are
/// dropped; with fewer than [`WILCOXON_EXACT_BELOW`] non-zero differences, no ties among their
/// magnitudes and no zeros, p comes from the exact distribution of V; otherwise from the normal
/// approximation with tie-corrected variance and continuity correction. `None` when x and y are
/// empty or differ in length. When every difference is zero, V = 0 and there is no p.
pub fn wilcoxon_signed_rank_paired(x: &[f64], y: &[f64]) -> Option<WilcoxonTest> {
    if x.is_empty() || x.len() != y.len() {
        return None;
    }
    let all_differences: Vec<f64> = x.iter().zip(y).map(|(a, b)| a - b).collect();
    let differences: Vec<f64> = all_differences.iter().copied().filter(|&d| d != 0.0).collect();
    let zeros = differences.len() < all_differences.len();
    let n = differences.len();
    if n == 0 {
        return Some(WilcoxonTest { n_nonzero: 0, v: 0.0, method: None, z: None, p: None });
    }
    let magnitudes: Vec<f64> = differences.iter().map(|d| d.abs()).collect();
    let (ranks, tie_sizes) = average_ranks(&magnitudes);
    let v: f64 = ranks.iter().zip(&differences).filter(|(_, d)| **d > 0.0).map(|(rank, _)| rank).sum();
    let ties = tie_sizes.len() < n;
    let nf = n as f64;

    if n < WILCOXON_EXACT_BELOW && !ties && !zeros {
        let p = signed_rank_two_sided_exact(v.round() as usize, n);
        return Some(WilcoxonTest { n_nonzero: n, v, method: Some(WilcoxonMethod::Exact), z: None, p: Some(p) });
    }
    let centred = v - nf * (nf + 1.0) / 4.0;
    let tie_term: f64 = tie_sizes.iter().map(|&t| (t as f64).powi(3) - t as f64).sum();
    let sigma = (nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - tie_term / 48.0).sqrt();
    let correction = if centred > 0.0 {
        0.5
    } else if centred < 0.0 {
        -0.5
    } else {
        0.0
    };
    let z = (centred - correction) / sigma;
    Some(WilcoxonTest {
        n_nonzero: n,
        v,
        method: Some(WilcoxonMethod::Normal),
        z: Some(z),
        p: Some(PValue::normal_two_sided(z)),
    })
}

/// Two-sided exact p of the signed-rank statistic V with n untied, non-zero differences, as R:
/// 2·P(S ≥ V) when V > n(n+1)/4, else 2·P(S ≤ V), at most 1. The null distribution is counted
/// exactly (subsets of {1..n} by rank sum; n < 64 keeps every count in a u64).
fn signed_rank_two_sided_exact(v: usize, n: usize) -> PValue {
    let max_sum = n * (n + 1) / 2;
    let mut counts = vec![0_u64; max_sum + 1];
    counts[0] = 1;
    for rank in 1..=n {
        for sum in (rank..=rank * (rank + 1) / 2).rev() {
            counts[sum] += counts[sum - rank];
        }
    }
    let v = v.min(max_sum);
    let tail: u64 = if 4 * v > n * (n + 1) { counts[v..].iter().sum() } else { counts[..=v].iter().sum() };
    // Exact in binary: the count is below 2⁶³ and the division is by a power of two. The smallest
    // possible p, 2/2⁴⁹, is far above `P_FLOOR`, so the value is stored as is.
    let p = (2.0 * tail as f64 / 2.0_f64.powi(n as i32)).min(1.0);
    PValue { p, log10_p: p.log10() }
}

/// Holm's step-down adjustment, as R's `p.adjust(p, method = "holm")`: with the m p-values in
/// ascending order, p̃₍ᵢ₎ = min(1, maxⱼ≤ᵢ (m − j + 1)·p₍ⱼ₎), returned in input order. The products
/// are formed as R forms them; p below `P_FLOOR` are scaled through their logarithms so that they
/// stay exact.
pub fn holm_adjust(p_values: &[PValue]) -> Vec<PValue> {
    let m = p_values.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| compare(&p_values[i].log10_p, &p_values[j].log10_p));
    let mut adjusted = vec![PValue { p: 1.0, log10_p: 0.0 }; m];
    // The running maximum of (m − j + 1)·p₍ⱼ₎, compared in log space: (ln of it, p₍ⱼ₎, factor).
    let mut running_max: Option<(f64, PValue, f64)> = None;
    for (position, &idx) in order.iter().enumerate() {
        let factor = (m - position) as f64;
        let ln_product = p_values[idx].log10_p * std::f64::consts::LN_10 + factor.ln();
        if running_max.is_none_or(|(ln_max, _, _)| ln_product > ln_max) {
            running_max = Some((ln_product, p_values[idx], factor));
        }
        if let Some((_, p, factor)) = running_max {
            adjusted[idx] = scale_p(p, factor);
        }
    }
    adjusted
}

/// min(1, factor·p), exact where p is a plain number and through logarithms where it is a bound.
fn scale_p(p: PValue, factor: f64) -> PValue {
    if p.is_bound() {
        PValue::from_ln(p.log10_p * std::f64::consts::LN_10 + factor.ln())
    } else {
        let scaled = (factor * p.p).min(1.0);
        PValue { p: scaled, log10_p: scaled.log10() }
    }
}

// ---------------------------------------------------------------------------------------------
// Plain-text table
// ---------------------------------------------------------------------------------------------

/// A readable plain-text report for the terminal: per measure, the descriptives, the Friedman
/// test with Kendall's W, the post hoc tests and the warnings.
pub fn render_table(analysis: &TaskAnalysis) -> String {
    let mut out = String::new();
    for (measure_idx, measure) in analysis.measures.iter().enumerate() {
        if measure_idx > 0 {
            out.push('\n');
        }
        let title = if measure.group.is_empty() { analysis.source.clone() } else { measure.group.label() };
        let _ = writeln!(
            out,
            "{title}: {} participant{}, {} condition{}",
            measure.participants,
            plural(measure.participants),
            measure.conditions.len(),
            plural(measure.conditions.len())
        );

        let mut header = vec!["condition", "n", "mean", "sd", "median", "q1", "q3", "min", "max"];
        let with_ranks = measure.conditions.iter().any(|condition| condition.mean_rank.is_some());
        if with_ranks {
            header.push("mean rank");
        }
        let rows: Vec<Vec<String>> = measure
            .conditions
            .iter()
            .map(|condition| {
                let mut row = vec![
                    condition.condition.clone(),
                    condition.n.to_string(),
                    format_number(condition.mean),
                    condition.sd.map_or_else(|| "–".to_string(), format_number),
                    format_number(condition.median),
                    format_number(condition.q1),
                    format_number(condition.q3),
                    format_number(condition.min),
                    format_number(condition.max),
                ];
                if with_ranks {
                    row.push(condition.mean_rank.map_or_else(|| "–".to_string(), |rank| format!("{rank:.2}")));
                }
                row
            })
            .collect();
        write_columns(&mut out, &header, &rows);

        if let Some(friedman) = &measure.friedman {
            let _ = writeln!(
                out,
                "Friedman χ²({}) = {}, p = {}, n = {}, Kendall's W = {:.3}",
                friedman.df,
                format_number(friedman.statistic),
                friedman.p.display(),
                friedman.participants,
                friedman.kendall_w
            );
        }
        if !measure.post_hoc.is_empty() {
            out.push_str("Post hoc: Wilcoxon signed-rank, paired, two-sided; p Holm-adjusted\n");
            let header = ["pair", "n", "V", "method", "p", "p (Holm)"];
            let rows: Vec<Vec<String>> = measure
                .post_hoc
                .iter()
                .map(|pair| {
                    let test = pair.test.as_ref();
                    vec![
                        format!("{} – {}", pair.condition_a, pair.condition_b),
                        pair.n.to_string(),
                        test.map_or_else(|| "–".to_string(), |test| format_rank_sum(test.v)),
                        match test.and_then(|test| test.method) {
                            Some(WilcoxonMethod::Exact) => "exact".to_string(),
                            Some(WilcoxonMethod::Normal) => "normal".to_string(),
                            None => "–".to_string(),
                        },
                        test.and_then(|test| test.p).map_or_else(|| "–".to_string(), |p| p.display()),
                        pair.p_holm.map_or_else(|| "–".to_string(), |p| p.display()),
                    ]
                })
                .collect();
            write_columns(&mut out, &header, &rows);
        }
        for warning in &measure.warnings {
            let _ = writeln!(out, "warning: {warning}");
        }
    }
    out
}

/// Writes rows under a header, the first column left-aligned and the others right-aligned.
fn write_columns(out: &mut String, header: &[&str], rows: &[Vec<String>]) {
    let mut widths: Vec<usize> = header.iter().map(|cell| cell.chars().count()).collect();
    for row in rows {
        for (width, cell) in widths.iter_mut().zip(row) {
            *width = (*width).max(cell.chars().count());
        }
    }
    let mut write_row = |cells: Vec<&str>| {
        let mut line = String::new();
        for (column_idx, (cell, width)) in cells.iter().zip(&widths).enumerate() {
            let padding = " ".repeat(width - cell.chars().count());
            if column_idx == 0 {
                line.push_str(cell);
                line.push_str(&padding);
            } else {
                line.push_str("  ");
                line.push_str(&padding);
                line.push_str(cell);
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
    };
    write_row(header.to_vec());
    for row in rows {
        write_row(row.iter().map(String::as_str).collect());
    }
}

/// A sum of (mid)ranks: a multiple of 0.5, shown without trailing zeros.
fn format_rank_sum(value: f64) -> String {
    if value.fract() == 0.0 { format!("{value:.0}") } else { format!("{value:.1}") }
}

/// Four significant digits in fixed notation for ordinary magnitudes, scientific otherwise.
fn format_number(value: f64) -> String {
    let magnitude = value.abs();
    if magnitude == 0.0 {
        "0".to_string()
    } else if !(1e-3..1e6).contains(&magnitude) {
        format!("{value:.3e}")
    } else {
        let decimals = (3 - magnitude.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{value:.decimals$}")
    }
}

// ---------------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    //! Reference values from R 4.2.2 (`friedman.test`, `wilcox.test`, `p.adjust`, `quantile`)
    //! written by `analysis/tests/reference/task_stats.R` with jsonlite 1.8.4 (15 significant
    //! digits).

    use super::*;
    use serde_json::Value;

    /// Statistics computed by the same arithmetic as R (χ², V, W, ranks, descriptives); the
    /// reference JSON itself carries 15 significant digits.
    const REL_TOL_STATISTIC: f64 = 1e-13;
    /// χ² tail p (statrs via `PValue::chi2_upper` against R's `pchisq`), exact signed-rank p
    /// (our exact counts against R's `psignrank`) and Holm on them.
    const REL_TOL_P: f64 = 1e-13;
    /// Normal-approximation p (statrs' `erfc` via `PValue::normal_two_sided` against R's `pnorm`):
    /// statrs' erfc is good to about 5e-11 relative at |z| ≈ 2.5.
    const REL_TOL_P_NORMAL: f64 = 1e-10;

    fn p_tolerance(method: WilcoxonMethod) -> f64 {
        match method {
            WilcoxonMethod::Exact => REL_TOL_P,
            WilcoxonMethod::Normal => REL_TOL_P_NORMAL,
        }
    }

    const ROUNDING_TIMES: &str = include_str!("../tests/reference/task_stats_friedman_roundingtimes.json");
    const FRIEDMAN_TIES: &str = include_str!("../tests/reference/task_stats_friedman_ties.json");
    const WILCOXON_EXACT: &str = include_str!("../tests/reference/task_stats_wilcoxon_exact.json");
    const WILCOXON_NORMAL: &str = include_str!("../tests/reference/task_stats_wilcoxon_normal.json");
    const HOLM: &str = include_str!("../tests/reference/task_stats_holm.json");
    const PIPELINE: &str = include_str!("../tests/reference/task_stats_pipeline.json");

    fn json(text: &str) -> Value {
        serde_json::from_str(text).expect("reference JSON parses")
    }

    fn number(value: &Value) -> f64 {
        value.as_f64().unwrap_or_else(|| panic!("not a number: {value}"))
    }

    fn numbers(value: &Value) -> Vec<f64> {
        value.as_array().expect("an array").iter().map(number).collect()
    }

    fn assert_close(actual: f64, expected: f64, rel_tol: f64, what: &str) {
        let scale = expected.abs().max(f64::MIN_POSITIVE);
        assert!(
            (actual - expected).abs() <= rel_tol * scale,
            "{what}: got {actual:e}, R 4.2.2 gives {expected:e} (relative error {:e}, tolerance {rel_tol:e})",
            (actual - expected).abs() / scale
        );
    }

    fn blocks(reference: &Value) -> Vec<Vec<f64>> {
        reference["blocks"].as_array().expect("blocks").iter().map(numbers).collect()
    }

    fn check_friedman(reference: &Value) {
        let blocks = blocks(reference);
        let expected = &reference["friedman"];
        let test = friedman_test(&blocks).expect("the test is defined");
        assert_close(test.statistic, number(&expected["statistic"]), REL_TOL_STATISTIC, "Friedman χ²");
        assert_eq!(test.df as f64, number(&expected["df"]));
        assert_close(test.p.p, number(&expected["p"]), REL_TOL_P, "Friedman p");
        assert_close(test.p.log10_p, number(&expected["log10_p"]), REL_TOL_P, "Friedman log10 p");
        assert_close(test.kendall_w, number(&expected["kendall_w"]), REL_TOL_STATISTIC, "Kendall's W");
        for (sum, mean_rank) in test.rank_sums.iter().zip(numbers(&expected["mean_ranks"])) {
            assert_close(sum / blocks.len() as f64, mean_rank, REL_TOL_STATISTIC, "mean rank");
        }
    }

    #[test]
    fn friedman_matches_r_4_2_2_roundingtimes() {
        // R's friedman.test help page: Friedman chi-squared = 11.143, df = 2, p-value = 0.003805.
        check_friedman(&json(ROUNDING_TIMES));
    }

    #[test]
    fn friedman_matches_r_4_2_2_with_ties() {
        check_friedman(&json(FRIEDMAN_TIES));
    }

    fn check_wilcoxon_cases(reference: &Value, expected_method: WilcoxonMethod) {
        for case in reference["cases"].as_array().expect("cases") {
            let (x, y) = (numbers(&case["x"]), numbers(&case["y"]));
            let test = wilcoxon_signed_rank_paired(&x, &y).expect("a test");
            let what = format!("wilcox.test({x:?}, {y:?}, paired = TRUE)");
            let method = if case["method"] == "exact" { WilcoxonMethod::Exact } else { WilcoxonMethod::Normal };
            assert_eq!(method, expected_method, "{what}: the reference case is of the intended kind");
            assert_eq!(test.method, Some(method), "{what}: method");
            assert_eq!(test.n_nonzero as f64, number(&case["n_nonzero"]), "{what}: non-zero differences");
            assert_close(test.v, number(&case["v"]), REL_TOL_STATISTIC, &format!("{what}: V"));
            let p = test.p.expect("a p-value");
            assert_close(p.p, number(&case["p"]), p_tolerance(method), &format!("{what}: p"));
        }
    }

    #[test]
    fn wilcoxon_exact_matches_r_4_2_2_wilcox_test_paired() {
        check_wilcoxon_cases(&json(WILCOXON_EXACT), WilcoxonMethod::Exact);
    }

    #[test]
    fn wilcoxon_ties_and_zeros_match_r_4_2_2_normal_approximation() {
        check_wilcoxon_cases(&json(WILCOXON_NORMAL), WilcoxonMethod::Normal);
    }

    #[test]
    fn holm_matches_r_4_2_2_p_adjust() {
        let reference = json(HOLM);
        let p: Vec<PValue> = numbers(&reference["p"]).into_iter().map(|p| PValue::from_ln(p.ln())).collect();
        for (adjusted, expected) in holm_adjust(&p).iter().zip(numbers(&reference["holm"])) {
            assert_close(adjusted.p, expected, REL_TOL_P, "Holm-adjusted p");
        }
    }

    #[test]
    fn holm_keeps_tiny_p_exact() {
        let tiny = PValue { p: crate::pvalue::P_FLOOR, log10_p: -400.0 };
        let adjusted = holm_adjust(&[tiny, PValue::from_ln(0.5_f64.ln())]);
        assert!((adjusted[0].log10_p - (-400.0 + 2.0_f64.log10())).abs() < 1e-9);
        assert_eq!(adjusted[1].p, 0.5);
    }

    #[test]
    fn quantile_type7_matches_r_4_2_2() {
        // R: quantile(c(1, 2, 4, 7, 11), c(.25, .5, .75), type = 7) = 2, 4, 7;
        //    quantile(c(1, 2, 4, 7), c(.25, .75)) = 1.75, 4.75.
        assert_eq!(quantile_type7(&[1.0, 2.0, 4.0, 7.0, 11.0], 0.25), 2.0);
        assert_eq!(quantile_type7(&[1.0, 2.0, 4.0, 7.0, 11.0], 0.5), 4.0);
        assert_eq!(quantile_type7(&[1.0, 2.0, 4.0, 7.0], 0.25), 1.75);
        assert_eq!(quantile_type7(&[1.0, 2.0, 4.0, 7.0], 0.75), 4.75);
        assert_eq!(quantile_type7(&[3.0], 0.75), 3.0);
    }

    #[test]
    fn pipeline_matches_r_4_2_2_per_measure() {
        let reference = json(PIPELINE);
        let csv = reference["csv"].as_str().expect("csv text");
        let analysis = analyze_task_csv(csv, "pipeline.csv").expect("analysis");
        assert_eq!(analysis.grouped_by, ["task", "measure"]);
        let groups = reference["groups"].as_array().expect("groups");
        assert_eq!(analysis.measures.len(), groups.len());
        for (measure, expected) in analysis.measures.iter().zip(groups) {
            let label = measure.group.label();
            assert_eq!(
                measure.group.0,
                vec![
                    ("task".to_string(), expected["task"].as_str().unwrap().to_string()),
                    ("measure".to_string(), expected["measure"].as_str().unwrap().to_string()),
                ]
            );
            assert_eq!(measure.participants as f64, number(&expected["participants"]), "{label}");
            let excluded: Vec<&str> =
                expected["excluded_participants"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
            assert_eq!(measure.excluded_participants, excluded, "{label}");

            for (summary, expected) in measure.conditions.iter().zip(expected["descriptives"].as_array().unwrap()) {
                let what = format!("{label}, {}", summary.condition);
                assert_eq!(summary.condition, expected["condition"].as_str().unwrap());
                assert_eq!(summary.n as f64, number(&expected["n"]), "{what}: n");
                assert_close(summary.mean, number(&expected["mean"]), REL_TOL_STATISTIC, &format!("{what}: mean"));
                assert_close(summary.sd.unwrap(), number(&expected["sd"]), REL_TOL_STATISTIC, &format!("{what}: sd"));
                for (actual, key) in [
                    (summary.median, "median"),
                    (summary.q1, "q1"),
                    (summary.q3, "q3"),
                    (summary.min, "min"),
                    (summary.max, "max"),
                ] {
                    assert_close(actual, number(&expected[key]), REL_TOL_STATISTIC, &format!("{what}: {key}"));
                }
            }

            let friedman = measure.friedman.as_ref().expect("a Friedman test");
            let expected_friedman = &expected["friedman"];
            assert_eq!(friedman.participants as f64, number(&expected_friedman["participants"]), "{label}");
            assert_close(friedman.statistic, number(&expected_friedman["statistic"]), REL_TOL_STATISTIC, &label);
            assert_close(friedman.p.p, number(&expected_friedman["p"]), REL_TOL_P, &label);
            assert_close(friedman.kendall_w, number(&expected_friedman["kendall_w"]), REL_TOL_STATISTIC, &label);
            for (summary, mean_rank) in measure.conditions.iter().zip(numbers(&expected_friedman["mean_ranks"])) {
                assert_close(summary.mean_rank.unwrap(), mean_rank, REL_TOL_STATISTIC, &label);
            }

            let expected_pairs = expected["post_hoc"].as_array().unwrap();
            assert_eq!(measure.post_hoc.len(), expected_pairs.len());
            for (pair, expected) in measure.post_hoc.iter().zip(expected_pairs) {
                let what = format!("{label}, {} vs {}", pair.condition_a, pair.condition_b);
                assert_eq!(pair.condition_a, expected["condition_a"].as_str().unwrap());
                assert_eq!(pair.condition_b, expected["condition_b"].as_str().unwrap());
                assert_eq!(pair.n as f64, number(&expected["n"]), "{what}: n");
                let test = pair.test.as_ref().unwrap();
                let method = if expected["method"] == "exact" { WilcoxonMethod::Exact } else { WilcoxonMethod::Normal };
                assert_eq!(test.method, Some(method), "{what}: method");
                assert_eq!(test.n_nonzero as f64, number(&expected["n_nonzero"]), "{what}");
                assert_close(test.v, number(&expected["v"]), REL_TOL_STATISTIC, &format!("{what}: V"));
                let tolerance = p_tolerance(method);
                assert_close(test.p.unwrap().p, number(&expected["p"]), tolerance, &format!("{what}: p"));
                assert_close(pair.p_holm.unwrap().p, number(&expected["p_holm"]), tolerance, &format!("{what}: Holm"));
            }
        }
        // The pipeline's handling is reported, not silent.
        let time = &analysis.measures[0];
        assert_eq!(time.averaged, [AveragedCell { participant: "p03".into(), condition: "HQ".into(), values: 2 }]);
        assert!(time.warnings.iter().any(|w| w.contains("averaged") && w.contains("p03 HQ (2 values)")));
        assert!(
            time.warnings.iter().any(|w| w.contains("excluded from the Friedman test") && w.contains("p07 (no HQ)"))
        );
    }

    /// Serialises and checks that no NaN or infinity slipped through (serde_json writes them as
    /// `null`).
    fn to_json_checked(analysis: &TaskAnalysis) -> String {
        let text = serde_json::to_string(analysis).expect("serialises");
        assert!(!text.contains("null"), "no NaN/inf placeholders: {text}");
        text
    }

    #[test]
    fn zero_variance_omits_friedman_with_a_warning() {
        let csv = "participant,condition,value\n\
                   a,LQ,5\na,GI,5\na,HQ,5\nb,LQ,5\nb,GI,5\nb,HQ,5\nc,LQ,5\nc,GI,5\nc,HQ,5\n";
        let analysis = analyze_task_csv(csv, "flat.csv").unwrap();
        let measure = &analysis.measures[0];
        assert!(measure.friedman.is_none());
        assert!(measure.warnings.iter().any(|w| w.contains("zero variance") && w.contains("undefined")));
        assert_eq!(measure.conditions[0].sd, Some(0.0));
        assert_eq!(measure.conditions[0].mean_rank, Some(2.0));
        // Every pair has only zero differences: V = 0 and no p, as R (p = NA).
        for pair in &measure.post_hoc {
            let test = pair.test.as_ref().unwrap();
            assert_eq!((test.v, test.p, pair.p_holm), (0.0, None, None));
        }
        let text = to_json_checked(&analysis);
        assert!(!text.contains("\"friedman\""));
        assert!(render_table(&analysis).contains("zero variance"));
    }

    #[test]
    fn single_participant_gives_descriptives_and_no_friedman() {
        let csv = "participant,condition,value\nsolo,LQ,3.5\nsolo,GI,2.0\nsolo,HQ,1.25\n";
        let analysis = analyze_task_csv(csv, "solo.csv").unwrap();
        let measure = &analysis.measures[0];
        assert_eq!(measure.participants, 1);
        assert!(measure.friedman.is_none());
        assert!(measure.warnings.iter().any(|w| w.contains("only one participant (solo)")));
        assert_eq!(measure.conditions[0].sd, None);
        assert_eq!(measure.conditions[0].q3, 3.5);
        // R 4.2.2: wilcox.test(3.5, 2, paired = TRUE) gives V = 1, p-value = 1 (exact).
        let first = measure.post_hoc[0].test.as_ref().unwrap();
        assert_eq!((first.v, first.method, first.p.unwrap().p), (1.0, Some(WilcoxonMethod::Exact), 1.0));
        to_json_checked(&analysis);
    }

    #[test]
    fn fewer_than_two_conditions_omits_tests_with_a_warning() {
        let csv = "participant,condition,value\na,LQ,1\nb,LQ,2\nc,LQ,4\n";
        let analysis = analyze_task_csv(csv, "one.csv").unwrap();
        let measure = &analysis.measures[0];
        assert!(measure.friedman.is_none() && measure.post_hoc.is_empty());
        assert!(measure.warnings.iter().any(|w| w.contains("Only one condition (`LQ`)")));
        assert_eq!(measure.conditions[0].median, 2.0);
        assert_eq!(measure.conditions[0].mean_rank, None);
        to_json_checked(&analysis);
    }

    #[test]
    fn wilcoxon_all_differences_zero_has_no_p() {
        let test = wilcoxon_signed_rank_paired(&[1.0, 2.0, 3.0], &[1.0, 2.0, 3.0]).unwrap();
        assert_eq!((test.n_nonzero, test.v, test.method, test.p), (0, 0.0, None, None));

        // In an analysis, the all-zero pair is reported and left out of the Holm family.
        let csv = "participant,condition,value\n\
                   a,A,1\na,B,1\na,C,3\nb,A,2\nb,B,2\nb,C,5\nc,A,4\nc,B,4\nc,C,4.5\n";
        let analysis = analyze_task_csv(csv, "zeros.csv").unwrap();
        let measure = &analysis.measures[0];
        let ab = &measure.post_hoc[0];
        assert!(ab.test.as_ref().unwrap().p.is_none() && ab.p_holm.is_none());
        assert!(measure.warnings.iter().any(|w| w.contains("Wilcoxon A vs B: all 3 differences are zero")));
        // Two tested pairs: Holm multiplies the smaller p by 2.
        let (ac, bc) = (&measure.post_hoc[1], &measure.post_hoc[2]);
        let p_ac = ac.test.as_ref().unwrap().p.unwrap().p;
        let p_bc = bc.test.as_ref().unwrap().p.unwrap().p;
        assert_close(ac.p_holm.unwrap().p, (2.0 * p_ac.min(p_bc)).min(1.0), 1e-12, "Holm of two");
        to_json_checked(&analysis);
    }

    fn bad_value_error(csv: &str) -> (u64, String, String) {
        match analyze_task_csv(csv, "bad.csv") {
            Err(AnalysisError::BadValue { line, column, message, .. }) => (line, column, message),
            other => panic!("expected BadValue, got {other:?}"),
        }
    }

    #[test]
    fn nan_inf_and_text_values_are_errors_naming_line_and_column() {
        for (cell, expected) in [
            ("NaN", "not a finite number"),
            ("inf", "not a finite number"),
            ("-infinity", "not a finite number"),
            ("fast", "not a number"),
            ("NA", "not a number"),
            ("", "is empty"),
        ] {
            let csv = format!("participant,condition,value\na,LQ,1\na,GI,{cell}\n");
            let (line, column, message) = bad_value_error(&csv);
            assert_eq!((line, column.as_str()), (3, "value"), "cell `{cell}`");
            assert!(message.contains(expected), "cell `{cell}`: {message}");
        }
        let error = analyze_task_csv("participant,condition,value\na,LQ,1\nb,GI,NaN\n", "bad.csv").unwrap_err();
        assert_eq!(error.to_string(), "bad.csv: line 3, column `value`: `NaN` is not a finite number");
    }

    #[test]
    fn empty_participant_or_condition_is_an_error() {
        let (line, column, _) = bad_value_error("participant,condition,value\na,LQ,1\n,GI,2\n");
        assert_eq!((line, column.as_str()), (3, "participant"));
        let (line, column, _) = bad_value_error("participant,condition,value\na,LQ,1\na,,2\n");
        assert_eq!((line, column.as_str()), (3, "condition"));
    }

    #[test]
    fn missing_columns_and_ragged_rows_are_errors() {
        match analyze_task_csv("participant,condition,score\na,LQ,1\n", "x.csv") {
            Err(AnalysisError::MissingColumn { column, found, .. }) => {
                assert_eq!(column, "value");
                assert_eq!(found, "participant, condition, score");
            }
            other => panic!("expected MissingColumn, got {other:?}"),
        }
        match analyze_task_csv("participant,condition,value\na,LQ,1\na,GI\n", "x.csv") {
            Err(AnalysisError::MalformedCsv { line, message, .. }) => {
                assert_eq!(line, 3);
                assert!(message.contains("2 fields") && message.contains("header has 3"), "{message}");
            }
            other => panic!("expected MalformedCsv, got {other:?}"),
        }
        assert!(matches!(analyze_task_csv("participant,condition,value\n", "x.csv"), Err(AnalysisError::Empty(_))));
        assert!(matches!(analyze_task_csv("", "x.csv"), Err(AnalysisError::Empty(_))));
    }

    #[test]
    fn extra_columns_are_ignored_and_header_is_matched_loosely() {
        let csv = "\u{feff}Participant , Value,note,Condition\na,1,x,LQ\na,2,y,GI\nb,2,,LQ\nb,4,,GI\n";
        let analysis = analyze_task_csv(csv, "loose.csv").unwrap();
        assert!(analysis.grouped_by.is_empty());
        let measure = &analysis.measures[0];
        assert_eq!(measure.conditions.iter().map(|c| c.condition.as_str()).collect::<Vec<_>>(), ["LQ", "GI"]);
        assert_eq!(measure.conditions[1].mean, 3.0);
    }

    #[test]
    fn duplicate_cells_are_averaged_and_reported() {
        let csv = "participant,condition,value\na,LQ,1\na,LQ,3\na,GI,5\nb,LQ,2\nb,GI,1\n";
        let measure = &analyze_task_csv(csv, "dup.csv").unwrap().measures[0];
        assert_eq!(measure.conditions[0].mean, 2.0); // a: (1 + 3) / 2 = 2, b: 2
        assert_eq!(measure.averaged, [AveragedCell { participant: "a".into(), condition: "LQ".into(), values: 2 }]);
        assert!(measure.warnings.iter().any(|w| w.contains("a LQ (2 values)")));
    }

    #[test]
    fn incomplete_participants_are_excluded_from_friedman_by_name() {
        let csv = "participant,condition,value\n\
                   a,A,1\na,B,2\na,C,3\nb,A,2\nb,B,3\nb,C,1\nc,A,1\nc,C,2\nd,B,5\n";
        let measure = &analyze_task_csv(csv, "gaps.csv").unwrap().measures[0];
        assert_eq!(measure.excluded_participants, ["c", "d"]);
        assert_eq!(measure.friedman.as_ref().unwrap().participants, 2);
        let warning = measure.warnings.iter().find(|w| w.contains("excluded")).unwrap();
        assert!(
            warning.contains("2 of 4 participants") && warning.contains("c (no B)") && warning.contains("d (no A, C)")
        );
        // Pairwise complete: A–C has a, b, c.
        assert_eq!(measure.post_hoc[1].n, 3);
    }

    #[test]
    fn explicit_grouping_column() {
        let csv = "participant,block,condition,value\n\
                   a,1,A,1\na,1,B,2\nb,1,A,2\nb,1,B,4\na,2,A,9\na,2,B,3\nb,2,A,8\nb,2,B,1\n";
        let analysis = analyze_task_csv_by(csv, "blocks.csv", Some("block")).unwrap();
        assert_eq!(analysis.grouped_by, ["block"]);
        assert_eq!(analysis.measures.len(), 2);
        assert_eq!(analysis.measures[1].group.label(), "block 2");
        assert_eq!(analysis.measures[1].conditions[0].mean, 8.5);
        let text = to_json_checked(&analysis);
        assert!(text.contains(r#""group":{"block":"2"}"#), "{text}");

        match analyze_task_csv_by(csv, "blocks.csv", Some("measure")) {
            Err(AnalysisError::MissingColumn { column, .. }) => assert_eq!(column, "measure"),
            other => panic!("expected MissingColumn, got {other:?}"),
        }
        assert!(matches!(analyze_task_csv_by(csv, "blocks.csv", Some("value")), Err(AnalysisError::BadOption { .. })));
    }

    #[test]
    fn render_table_shows_tests_and_warnings() {
        let reference = json(PIPELINE);
        let analysis = analyze_task_csv(reference["csv"].as_str().unwrap(), "pipeline.csv").unwrap();
        let table = render_table(&analysis);
        assert!(table.contains("task placement, measure time_s: 12 participants, 3 conditions"), "{table}");
        assert!(table.contains("Friedman χ²(2) = 17.64, p = 0.0001"), "{table}");
        assert!(table.contains("LQ – GI"), "{table}");
        assert!(table.contains("warning: 1 of 12 participants lacks a condition"), "{table}");
        assert_eq!(analysis.warnings().len(), 2);
        assert!(analysis.warnings()[0].starts_with("task placement, measure time_s: "));
        to_json_checked(&analysis);
    }
}
