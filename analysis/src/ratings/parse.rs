//! A rating export's rows: `participant,scene,condition,rating,method` and, where present,
//! `reference`, `scale`, `catch`, `expected`, `pilot`, `excluded` (docs/design.md, "Rating
//! trials CSV"). A row with an empty `rating` is a trial not answered and is skipped; a rating
//! that is not an integer from 1 to 5, a method other than `acr`, `dcr`, `acr-hr`, or a method
//! that changes between rows is one sentence naming the line.

use crate::error::{AnalysisError, Result};

/// The columns that make a trials CSV a rating export.
pub const COLUMNS: [&str; 5] = ["participant", "scene", "condition", "rating", "method"];

/// The rating method of a study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Method {
    /// Absolute category rating: one stimulus, the quality scale.
    #[serde(rename = "acr")]
    Acr,
    /// Degradation category rating: reference, then stimulus; the impairment scale.
    #[serde(rename = "dcr")]
    Dcr,
    /// ACR with hidden reference: differential scores against the reference's own rating.
    #[serde(rename = "acr-hr")]
    AcrHr,
}

impl Method {
    fn parse(text: &str) -> Option<Method> {
        match text {
            "acr" => Some(Method::Acr),
            "dcr" => Some(Method::Dcr),
            "acr-hr" => Some(Method::AcrHr),
            _ => None,
        }
    }

    /// The scale the ratings are given on.
    pub fn scale(self) -> &'static str {
        match self {
            Method::Acr | Method::AcrHr => "quality",
            Method::Dcr => "impairment",
        }
    }
}

/// One answered rating trial.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub participant: String,
    pub scene: String,
    pub condition: String,
    pub rating: u8,
    /// A golden question (`catch` = `true`) with its expected rating: never data.
    pub expected: Option<u8>,
    /// For ACR-HR, the hidden reference's condition (`ground-truth`).
    pub reference: String,
}

/// The rows of an export, pilots and excluded participants left out unless kept.
#[derive(Debug, Clone, PartialEq)]
pub struct Rows {
    pub method: Method,
    pub rows: Vec<Row>,
    /// Participants left out as pilots and as excluded (counted once each).
    pub pilots: usize,
    pub excluded: usize,
}

/// Whether a trials CSV's header has every rating column.
pub fn is_rating_csv(text: &str) -> bool {
    let columns = crate::data::header_columns(text);
    COLUMNS.iter().all(|column| columns.contains(column))
}

/// Reads the rating rows of `text` (`name` for messages).
pub fn parse(text: &str, name: &str, include_pilots: bool, include_excluded: bool) -> Result<Rows> {
    let bad = |line: usize, column: &str, message: String| AnalysisError::BadValue {
        source_name: name.to_string(),
        line: line as u64,
        column: column.to_string(),
        message,
    };
    let mut reader = csv::ReaderBuilder::new().flexible(false).from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|error| AnalysisError::MalformedCsv {
            source_name: name.to_string(),
            line: 1,
            message: format!("cannot read the header: {error}"),
        })?
        .clone();
    let column = |wanted: &str| headers.iter().position(|header| header.trim() == wanted);
    let required = |wanted: &str| {
        column(wanted).ok_or_else(|| AnalysisError::MissingColumn {
            source_name: name.to_string(),
            column: wanted.to_string(),
            found: headers.iter().collect::<Vec<_>>().join(", "),
        })
    };
    let [participant, scene, condition, rating, method] = COLUMNS.map(required);
    let (participant, scene, condition, rating, method) = (participant?, scene?, condition?, rating?, method?);
    let (catch, expected, reference) = (column("catch"), column("expected"), column("reference"));
    let (pilot, excluded) = (column("pilot"), column("excluded"));
    let mut rows = Vec::new();
    let mut found: Option<(Method, usize)> = None;
    let mut pilots = std::collections::BTreeSet::new();
    let mut excluded_ids = std::collections::BTreeSet::new();
    for (index, record) in reader.records().enumerate() {
        let line = index + 2;
        let record = record.map_err(|error| AnalysisError::MalformedCsv {
            source_name: name.to_string(),
            line: line as u64,
            message: format!("cannot read the row: {error}"),
        })?;
        let cell = |column: usize| record.get(column).unwrap_or("").trim();
        let flag = |column: Option<usize>| column.is_some_and(|column| cell(column) == "true");
        if flag(pilot) && !include_pilots {
            pilots.insert(cell(participant).to_string());
            continue;
        }
        if flag(excluded) && !include_excluded {
            excluded_ids.insert(cell(participant).to_string());
            continue;
        }
        if cell(rating).is_empty() {
            continue; // a trial not answered
        }
        let this = Method::parse(cell(method))
            .ok_or_else(|| bad(line, "method", format!("expected acr, dcr or acr-hr, found \"{}\"", cell(method))))?;
        match found {
            None => found = Some((this, line)),
            Some((first, first_line)) if first != this => {
                return Err(bad(
                    line,
                    "method",
                    format!(
                        "the method must be the same on every row: \"{}\" here, \"{}\" on line {first_line}",
                        cell(method),
                        serde_json::to_value(first)
                            .ok()
                            .and_then(|v| v.as_str().map(str::to_string))
                            .unwrap_or_default()
                    ),
                ));
            }
            Some(_) => {}
        }
        let score =
            |column: usize, what: &str| -> Result<u8> {
                cell(column).parse::<u8>().ok().filter(|value| (1..=5).contains(value)).ok_or_else(|| {
                    bad(line, what, format!("expected an integer from 1 to 5, found \"{}\"", cell(column)))
                })
            };
        let is_catch = flag(catch);
        let expected = match (is_catch, expected) {
            (true, Some(column)) => Some(score(column, "expected")?),
            (true, None) => {
                return Err(bad(
                    line,
                    "catch",
                    "a golden question (`catch` = true) needs the column `expected`".into(),
                ));
            }
            (false, _) => None,
        };
        // a golden question shown as an image has no scene configuration
        let needed: &[(usize, &str)] = if is_catch {
            &[(participant, "participant")]
        } else {
            &[(participant, "participant"), (scene, "scene"), (condition, "condition")]
        };
        if let Some((_, which)) = needed.iter().find(|(column, _)| cell(*column).is_empty()) {
            return Err(bad(line, which, "the cell is empty".into()));
        }
        rows.push(Row {
            participant: cell(participant).to_string(),
            scene: cell(scene).to_string(),
            condition: cell(condition).to_string(),
            rating: score(rating, "rating")?,
            expected,
            reference: reference.map(|column| cell(column).to_string()).unwrap_or_default(),
        });
    }
    let Some((method, _)) = found else {
        return Err(AnalysisError::Empty(format!("{name}: no answered rating trials (every `rating` cell is empty)")));
    };
    Ok(Rows { method, rows, pilots: pilots.len(), excluded: excluded_ids.len() })
}
