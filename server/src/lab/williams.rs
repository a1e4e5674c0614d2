//! Counterbalanced condition orders: Williams designs (Williams 1949, "Experimental designs
//! balanced for the estimation of residual effects of treatments") and cyclic Latin squares.
//!
//! A Williams design for n conditions is a set of sequences in which every condition appears
//! equally often in every position and every ordered pair (a, b), a ≠ b, appears as adjacent
//! neighbours (a directly before b) equally often — balanced for first-order carry-over. For
//! even n one n × n Latin square does it: the first row is 0, 1, n−1, 2, n−2, 3, …, and row i
//! adds i to each entry modulo n. For odd n no single square can be balanced; the square and its
//! mirror image (each row reversed) together are, so the design has 2n sequences. Participant k
//! gets sequence k mod (number of sequences), so full balance needs a multiple of that many
//! participants.

/// The sequences of a Williams design for `n` conditions (indices 0..n): n sequences for even
/// n, 2n for odd n ≥ 3 (one for n = 1, none for n = 0).
pub fn williams(n: usize) -> Vec<Vec<usize>> {
    if n == 0 {
        return Vec::new();
    }
    // first row 0, 1, n-1, 2, n-2, 3, …
    let first: Vec<usize> = (0..n)
        .map(|position| match position {
            0 => 0,
            p if p % 2 == 1 => p.div_ceil(2),
            p => n - p / 2,
        })
        .collect();
    let square: Vec<Vec<usize>> = (0..n).map(|row| first.iter().map(|c| (c + row) % n).collect()).collect();
    if n.is_multiple_of(2) || n == 1 {
        square
    } else {
        let mirror: Vec<Vec<usize>> = square.iter().map(|row| row.iter().rev().copied().collect()).collect();
        square.into_iter().chain(mirror).collect()
    }
}

/// A cyclic Latin square: row i is i, i+1, …, modulo n.
pub fn latin(n: usize) -> Vec<Vec<usize>> {
    (0..n).map(|row| (0..n).map(|c| (c + row) % n).collect()).collect()
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    /// Counts: per (condition, position) and per ordered adjacent pair.
    fn counts(design: &[Vec<usize>], n: usize) -> (Vec<Vec<usize>>, Vec<Vec<usize>>) {
        let mut position = vec![vec![0; n]; n];
        let mut pairs = vec![vec![0; n]; n];
        for row in design {
            assert_eq!(row.len(), n);
            let mut seen = row.clone();
            seen.sort();
            assert_eq!(seen, (0..n).collect::<Vec<_>>(), "each sequence is a permutation: {row:?}");
            for (p, &c) in row.iter().enumerate() {
                position[c][p] += 1;
            }
            for w in row.windows(2) {
                pairs[w[0]][w[1]] += 1;
            }
        }
        (position, pairs)
    }

    #[test]
    fn williams_designs_are_balanced_for_position_and_carry_over() {
        for n in 2..=9 {
            let design = williams(n);
            let rows = if n % 2 == 0 { n } else { 2 * n };
            assert_eq!(design.len(), rows, "n = {n}");
            let (position, pairs) = counts(&design, n);
            let per_position = rows / n;
            for c in 0..n {
                for p in 0..n {
                    assert_eq!(position[c][p], per_position, "n = {n}: condition {c} at position {p}");
                }
            }
            let per_pair = (rows * (n - 1)) / (n * (n - 1));
            for a in 0..n {
                for b in 0..n {
                    let expected = if a == b { 0 } else { per_pair };
                    assert_eq!(pairs[a][b], expected, "n = {n}: {a} directly before {b} in {design:?}");
                }
            }
        }
    }

    #[test]
    fn the_three_condition_design_is_the_textbook_one() {
        // Williams (1949) for three treatments: ABC, BCA, CAB and their mirrors.
        assert_eq!(
            williams(3),
            vec![vec![0, 1, 2], vec![1, 2, 0], vec![2, 0, 1], vec![2, 1, 0], vec![0, 2, 1], vec![1, 0, 2]]
        );
        assert_eq!(williams(4)[0], vec![0, 1, 3, 2]);
        assert!(williams(0).is_empty());
        assert_eq!(williams(1), vec![vec![0]]);
    }

    #[test]
    fn a_latin_square_has_each_condition_once_per_position() {
        for n in 2..=6 {
            let (position, _) = counts(&latin(n), n);
            assert!(position.iter().flatten().all(|&count| count == 1));
        }
    }
}
