//! Rank correlations of a metric with the perceived log-worth (Spearman's ρ, Kendall's τ-b
//! in O(n log n)) and the basic bootstrap interval of a correlation.

/// The basic (reverse-percentile) bootstrap interval of a correlation, [2θ̂ − q₁₋α/₂, 2θ̂ − qα/₂]
/// with q the quantiles (R's `quantile` type 7) of the bootstrap values, clamped to [−1, 1];
/// `None` from fewer than two values.
///
/// Not the percentile interval [qα/₂, q₁₋α/₂]: the log-worths are estimates, and their noise
/// pulls a correlation with them towards 0 — the estimate θ̂ is attenuated, and a bootstrap
/// replicate, whose log-worths carry the noise once more, is attenuated again. The percentile
/// interval inherits both shifts and, in simulated studies of 48 stimuli and 40 participants,
/// covered the correlation with the true worths in 0–12 % of the studies where that correlation
/// was strong (ρ ≤ −0.75) and 76 % where it was moderate; the basic interval, which turns the
/// replicates' shift around, covered it in 86–92 % (`docs/analysis.md`).
pub(super) fn basic_interval(mut values: Vec<f64>, level: f64, estimate: f64) -> Option<[f64; 2]> {
    if values.len() < 2 {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let alpha = (1.0 - level) / 2.0;
    let (low, high) = (crate::quantile::type7(&values, alpha), crate::quantile::type7(&values, 1.0 - alpha));
    Some([(2.0 * estimate - high).max(-1.0), (2.0 * estimate - low).min(1.0)])
}

/// Pearson's correlation of two equally long series; `None` where either has no variance.
fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len() as f64;
    let (mean_x, mean_y) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        let (dx, dy) = (a - mean_x, b - mean_y);
        sxy += dx * dy;
        sxx += dx * dx;
        syy += dy * dy;
    }
    (sxx > 0.0 && syy > 0.0).then(|| (sxy / (sxx.sqrt() * syy.sqrt())).clamp(-1.0, 1.0))
}

/// Spearman's ρ: Pearson's correlation of the average ranks (ties share the mean of their
/// ranks), as scipy's `spearmanr` and R's `cor(method = "spearman")`. `None` for fewer than two
/// pairs or a series without variance.
pub fn spearman_rho(x: &[f64], y: &[f64]) -> Option<f64> {
    if x.len() != y.len() || x.len() < 2 || all_equal(x) || all_equal(y) {
        return None;
    }
    let (rank_x, _) = crate::task::average_ranks(x);
    let (rank_y, _) = crate::task::average_ranks(y);
    pearson(&rank_x, &rank_y)
}

/// Kendall's τ-b, (C − D) / √((n₀ − n₁)(n₀ − n₂)) with n₁, n₂ the pairs tied in x, y, as scipy's
/// `kendalltau` (variant b) and R's `cor(method = "kendall")`; in O(n log n) by Knight's
/// algorithm (sort by x then y, count the exchanges of a merge sort by y). `None` for fewer
/// than two pairs or a series without variance.
pub fn kendall_tau_b(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len();
    if y.len() != n || n < 2 || all_equal(x) || all_equal(y) {
        return None;
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| x[a].total_cmp(&x[b]).then(y[a].total_cmp(&y[b])));
    let pairs = |sizes: &mut dyn Iterator<Item = u64>| sizes.map(|t| t * (t.saturating_sub(1)) / 2).sum::<u64>();
    let runs = |same: &dyn Fn(usize, usize) -> bool, sequence: &[usize]| -> Vec<u64> {
        let mut sizes = Vec::new();
        let mut start = 0;
        for k in 1..=sequence.len() {
            if k == sequence.len() || !same(sequence[k - 1], sequence[k]) {
                sizes.push((k - start) as u64);
                start = k;
            }
        }
        sizes
    };
    let tied_x = pairs(&mut runs(&|a, b| x[a] == x[b], &order).into_iter());
    let tied_xy = pairs(&mut runs(&|a, b| x[a] == x[b] && y[a] == y[b], &order).into_iter());
    // Merge sort of the y values in this order, counting exchanges (discordant pairs).
    let mut values: Vec<f64> = order.iter().map(|&k| y[k]).collect();
    let mut buffer = values.clone();
    let exchanges = merge_count(&mut values, &mut buffer);
    let sorted_y: Vec<usize> = (0..n).collect();
    let tied_y = pairs(&mut runs(&|a, b| values[a] == values[b], &sorted_y).into_iter());
    let total = (n as u64) * (n as u64 - 1) / 2;
    let numerator = total as f64 - tied_x as f64 - tied_y as f64 + tied_xy as f64 - 2.0 * exchanges as f64;
    let denominator = ((total - tied_x) as f64).sqrt() * ((total - tied_y) as f64).sqrt();
    (denominator > 0.0).then(|| (numerator / denominator).clamp(-1.0, 1.0))
}

/// Sorts `values` ascending (stable merge sort) and returns the number of exchanges: pairs
/// (i < j) with values[i] > values[j].
fn merge_count(values: &mut [f64], buffer: &mut [f64]) -> u64 {
    let n = values.len();
    if n < 2 {
        return 0;
    }
    let middle = n / 2;
    let (left_buffer, right_buffer) = buffer.split_at_mut(middle);
    let mut count = {
        let (left, right) = values.split_at_mut(middle);
        merge_count(left, left_buffer) + merge_count(right, right_buffer)
    };
    let (mut i, mut j, mut k) = (0, middle, 0);
    while i < middle && j < n {
        if values[j] < values[i] {
            buffer[k] = values[j];
            count += (middle - i) as u64;
            j += 1;
        } else {
            buffer[k] = values[i];
            i += 1;
        }
        k += 1;
    }
    buffer[k..k + middle - i].copy_from_slice(&values[i..middle]);
    k += middle - i;
    buffer[k..k + n - j].copy_from_slice(&values[j..n]);
    values.copy_from_slice(&buffer[..n]);
    count
}

/// Every value the same (no variance).
pub(super) fn all_equal(values: &[f64]) -> bool {
    values.windows(2).all(|w| w[0] == w[1])
}
