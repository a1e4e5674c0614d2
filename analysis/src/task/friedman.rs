//! Average ranks with ties (as R's `rank`), the Friedman rank-sum test with tie correction (as
//! R's `friedman.test`) and Kendall's W from the same statistic.

use super::FriedmanTest;
use super::descriptives::compare;
use crate::pvalue::PValue;

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
pub(super) fn rank_sums(blocks: &[Vec<f64>]) -> (Vec<f64>, f64) {
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
