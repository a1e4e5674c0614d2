//! Scores and mean opinion scores. ACR and DCR score each rating as given (DCR's ratings are
//! its impairment scale, 5 = imperceptible). ACR-HR scores the differential viewer score of
//! ITU-T P.910 (2008 and later, clause on ACR-HR): DV = V(PVS) − V(REF) + 5, per participant
//! and scene configuration, V(REF) that participant's rating of the hidden reference in that
//! scene (their mean rating where they rated it more than once); the reference's own ratings
//! are not scores, and DV above 5 is kept (P.910: such values are valid). A MOS is the mean
//! of the scores, its 95 % interval mean ± t(0.975, n − 1)·s/√n (s the sample standard
//! deviation); with one score there is no interval.

use std::collections::BTreeMap;

use statrs::distribution::{ContinuousCDF, StudentsT};

use super::parse::{Method, Row};

/// One score: a rating, or for ACR-HR a differential viewer score.
#[derive(Debug, Clone, PartialEq)]
pub struct Score {
    pub participant: String,
    pub scene: String,
    pub condition: String,
    pub score: f64,
}

/// The scores of `rows` (golden questions already left out) and, for ACR-HR, how many
/// ratings had no reference rating of the same participant and scene to subtract.
pub fn scores(method: Method, rows: &[&Row]) -> (Vec<Score>, usize) {
    let score = |row: &Row, value: f64| Score {
        participant: row.participant.clone(),
        scene: row.scene.clone(),
        condition: row.condition.clone(),
        score: value,
    };
    if method != Method::AcrHr {
        return (rows.iter().map(|row| score(row, f64::from(row.rating))).collect(), 0);
    }
    let reference_of = |row: &Row| {
        if row.reference.is_empty() { crate::data::GROUND_TRUTH.to_string() } else { row.reference.clone() }
    };
    let mut references: BTreeMap<(&str, &str), (f64, usize)> = BTreeMap::new();
    for row in rows.iter().filter(|row| row.condition == reference_of(row)) {
        let entry = references.entry((&row.participant, &row.scene)).or_default();
        entry.0 += f64::from(row.rating);
        entry.1 += 1;
    }
    let mut missing = 0;
    let mut out = Vec::new();
    for row in rows.iter().filter(|row| row.condition != reference_of(row)) {
        match references.get(&(row.participant.as_str(), row.scene.as_str())) {
            Some(&(sum, n)) => out.push(score(row, f64::from(row.rating) - sum / n as f64 + 5.0)),
            None => missing += 1,
        }
    }
    (out, missing)
}

/// A MOS with its 95 % t-interval (none from one score).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mos {
    pub n: usize,
    pub mean: f64,
    pub ci: Option<[f64; 2]>,
}

/// The MOS of `scores` (at least one).
pub fn mos(scores: &[f64]) -> Mos {
    let n = scores.len();
    let mean = scores.iter().sum::<f64>() / n as f64;
    let ci = (n >= 2).then(|| {
        let variance = scores.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / (n as f64 - 1.0);
        let t = StudentsT::new(0.0, 1.0, n as f64 - 1.0).expect("n − 1 ≥ 1 degrees of freedom").inverse_cdf(0.975);
        let half = t * (variance / n as f64).sqrt();
        [mean - half, mean + half]
    });
    Mos { n, mean, ci }
}
