//! The comparison design as the models see it: judgments aggregated into pair tallies, the
//! comparison graph and its connected components.

use serde::Serialize;

/// How often each of two conditions was chosen when they were compared (in either position).
/// Indices refer to the condition list of the data set; `i < j` is not required.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct PairTally {
    pub i: usize,
    pub j: usize,
    /// Judgments in which `i` was chosen over `j`.
    pub wins_i: u64,
    /// Judgments in which `j` was chosen over `i`.
    pub wins_j: u64,
}

impl PairTally {
    /// Number of judgments of this pair.
    pub fn n(&self) -> u64 {
        self.wins_i + self.wins_j
    }
}
