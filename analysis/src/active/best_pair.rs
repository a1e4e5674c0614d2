//! The argmax of a batch's pair search with seeded tie-breaks, shared by the targets' searches
//! (`posterior`'s worths and effects, `both`).

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::Rng;

/// The highest-scoring pair of a batch's search so far. A pair scoring within 1e-12 (relative)
/// of the best ties with it, and each of the tied pairs is kept with equal chance by the
/// participant's seeded stream (one `next_u64` per further tie: reservoir sampling), so a
/// seed gives the same batch.
pub(super) struct BestPair {
    pub(super) pair: Option<(usize, usize)>,
    score: f64,
    ties: u64,
}

impl BestPair {
    pub(super) fn new() -> BestPair {
        BestPair { pair: None, score: f64::NEG_INFINITY, ties: 0 }
    }

    /// Offers `pair` with its `score`.
    pub(super) fn offer(&mut self, pair: (usize, usize), score: f64, rng: &mut ChaCha8Rng) {
        if score > self.score * (1.0 + 1e-12) + 1e-300 {
            self.pair = Some(pair);
            self.score = score;
            self.ties = 1;
        } else if score >= self.score * (1.0 - 1e-12) {
            self.ties += 1;
            if rng.next_u64().is_multiple_of(self.ties) {
                self.pair = Some(pair);
            }
        }
    }
}
