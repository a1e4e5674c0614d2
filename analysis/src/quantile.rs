//! Quantiles of sorted samples, the crate's one home for them (and the server's and the bench
//! crate's): [`type7`], R's default `quantile(x, p, type = 7)`, for statistics (task
//! descriptives, percentile intervals, medians), and [`nearest_rank`], R's `type = 1` (the
//! inverse of the empirical distribution function: always one of the values), for timings such
//! as the lab's 90th-percentile frame time. Both are tested against R's values
//! (`analysis/reference/quantile.R`, `quantile.json`). An empty sample gives 0.

/// Quantile of sorted values as R's `quantile(x, prob, type = 7)`: linear interpolation between
/// order statistics at (n − 1)·prob, written as R writes it.
pub fn type7(sorted: &[f64], prob: f64) -> f64 {
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

/// Quantile of sorted values as R's `quantile(x, prob, type = 1)`: the value of nearest rank
/// ⌈n·prob⌉ (at least the first).
pub fn nearest_rank(sorted: &[f64], prob: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = ((prob * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// The median (type 7) of unsorted values; `None` for none.
pub fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(type7(&values, 0.5))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every case of `analysis/reference/quantile.json` (R 4.2.2), both types, to 1e-12 relative.
    #[test]
    fn quantiles_match_r() {
        let reference: serde_json::Value =
            serde_json::from_str(include_str!("../reference/quantile.json")).expect("the fixture is JSON");
        let numbers = |value: &serde_json::Value| -> Vec<f64> {
            value.as_array().expect("an array").iter().map(|v| v.as_f64().expect("a number")).collect()
        };
        let cases = reference["cases"].as_array().expect("cases");
        assert_eq!(cases.len(), 6);
        for case in cases {
            let mut values = numbers(&case["values"]);
            values.sort_by(f64::total_cmp);
            let probs = numbers(&case["probs"]);
            for (rule, name) in [(type7 as fn(&[f64], f64) -> f64, "type7"), (nearest_rank, "type1")] {
                for (prob, expected) in probs.iter().zip(numbers(&case[name])) {
                    let found = rule(&values, *prob);
                    assert!(
                        (found - expected).abs() <= 1e-12 * expected.abs().max(1.0),
                        "{name} of {values:?} at {prob}: {found} against R's {expected}"
                    );
                }
            }
        }
    }

    #[test]
    fn empty_samples_and_the_median() {
        assert_eq!((type7(&[], 0.5), nearest_rank(&[], 0.9)), (0.0, 0.0));
        assert_eq!(median(vec![]), None);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(vec![f64::MAX, f64::MAX]), Some(f64::MAX), "no overflow");
    }
}
