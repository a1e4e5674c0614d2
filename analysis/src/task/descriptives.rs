//! Descriptives of one condition: n, mean, sample sd, median and quartiles by R's `quantile`
//! type 7, min, max.

use std::cmp::Ordering;

use super::ConditionSummary;
use crate::quantile::type7;

/// Descriptives of one condition's values (at least one value).
pub(super) fn describe(condition: &str, values: &[f64], mean_rank: Option<f64>) -> ConditionSummary {
    let mut sorted = values.to_vec();
    sorted.sort_by(compare);
    let mean = mean(values);
    ConditionSummary {
        condition: condition.to_string(),
        n: values.len(),
        mean,
        sd: sample_sd(values, mean),
        median: type7(&sorted, 0.5),
        q1: type7(&sorted, 0.25),
        q3: type7(&sorted, 0.75),
        min: sorted.first().copied().unwrap_or(0.0),
        max: sorted.last().copied().unwrap_or(0.0),
        mean_rank,
    }
}

/// Arithmetic mean; finite for finite values even where their sum would overflow.
pub(super) fn mean(values: &[f64]) -> f64 {
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

pub(super) fn compare(a: &f64, b: &f64) -> Ordering {
    // Values are never NaN here (finite input; differences of finite values); -0 ties with 0 as
    // in R.
    a.partial_cmp(b).unwrap_or(Ordering::Equal)
}
