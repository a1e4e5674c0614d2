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

/// Aggregates judgments into one tally per unordered pair `(i < j)`, sorted by `(i, j)`.
/// `rows` yields `(left, right, left_chosen, count)`. Sort-based, so its cost does not depend
/// on the number of conditions (a hash map is several times slower at a million pairs).
pub fn tally<I>(rows: I) -> Vec<PairTally>
where
    I: IntoIterator<Item = (u32, u32, bool, u64)>,
{
    // Key: i in the high 32 bits, j in the low; the flag says whether i won.
    let mut keyed: Vec<(u64, bool, u64)> = rows
        .into_iter()
        .map(|(left, right, left_chosen, count)| {
            let (i, j, i_won) = if left < right { (left, right, left_chosen) } else { (right, left, !left_chosen) };
            ((u64::from(i) << 32) | u64::from(j), i_won, count)
        })
        .collect();
    keyed.sort_unstable_by_key(|&(key, _, _)| key);
    let mut pairs: Vec<PairTally> = Vec::new();
    let mut last_key = u64::MAX;
    for (key, i_won, count) in keyed {
        if key != last_key {
            pairs.push(PairTally { i: (key >> 32) as usize, j: (key & 0xffff_ffff) as usize, wins_i: 0, wins_j: 0 });
            last_key = key;
        }
        let pair = pairs.last_mut().expect("pushed above");
        if i_won {
            pair.wins_i += count;
        } else {
            pair.wins_j += count;
        }
    }
    pairs
}

/// Faster tally for few conditions: a dense t×t table, no hashing.
pub fn tally_dense<I>(n_conditions: usize, rows: I) -> Vec<PairTally>
where
    I: IntoIterator<Item = (u32, u32, bool, u64)>,
{
    let t = n_conditions;
    let mut wins = vec![0u64; t * t];
    for (left, right, left_chosen, count) in rows {
        let (winner, loser) = if left_chosen { (left, right) } else { (right, left) };
        wins[winner as usize * t + loser as usize] += count;
    }
    from_dense(&wins, t)
}

/// The pairs judged in a dense t×t table (`wins[i·t + j]`: i chosen over j), sorted by `(i, j)`.
fn from_dense(wins: &[u64], t: usize) -> Vec<PairTally> {
    let mut pairs = Vec::new();
    for i in 0..t {
        for j in i + 1..t {
            let (wins_i, wins_j) = (wins[i * t + j], wins[j * t + i]);
            if wins_i + wins_j > 0 {
                pairs.push(PairTally { i, j, wins_i, wins_j });
            }
        }
    }
    pairs
}

/// Every participant's judgments as tallies per pair (`i < j`), contiguous per participant,
/// each participant's pairs in the order of their first judgment. Built once from the
/// judgments, it is what everything per participant reads (consistence, observer screening,
/// the bootstrap, the pooled tallies of a set of participants): a few dozen pairs per
/// participant instead of every judgment, in one flat array.
#[derive(Debug, Clone, Default)]
pub struct ParticipantTallies {
    /// `pairs[spans[p].0..spans[p].1]` are participant `p`'s.
    spans: Vec<(usize, usize)>,
    pairs: Vec<PairTally>,
    /// Whether participant `p` has any judgment (row) at all.
    present: Vec<bool>,
}

/// Up to this many conditions a participant's pairs are summed in a dense t×t table.
const DENSE_PARTICIPANT_CONDITIONS: usize = 64;
/// Up to this many conditions pooled tallies are summed in a dense t×t table.
const DENSE_POOLED_CONDITIONS: usize = 512;

impl ParticipantTallies {
    /// The tallies of `rows` (participant and condition indices below `n_participants` and
    /// `n_conditions`). One pass where each participant's rows are contiguous (as exports list
    /// them); otherwise the rows are first put in participant order by a stable counting sort.
    pub fn new<'a, I>(n_participants: usize, n_conditions: usize, rows: I) -> ParticipantTallies
    where
        I: Iterator<Item = &'a crate::data::Judgment> + Clone,
    {
        let mut builder = Builder::new(n_participants, n_conditions);
        if builder.add_runs(rows.clone()) {
            return builder.finish();
        }
        let mut offsets = vec![0usize; n_participants + 1];
        for row in rows.clone() {
            offsets[row.participant as usize + 1] += 1;
        }
        for p in 0..n_participants {
            offsets[p + 1] += offsets[p];
        }
        let mut sorted: Vec<Option<&crate::data::Judgment>> = vec![None; offsets[n_participants]];
        for row in rows {
            let slot = &mut offsets[row.participant as usize];
            sorted[*slot] = Some(row);
            *slot += 1;
        }
        let mut builder = Builder::new(n_participants, n_conditions);
        let contiguous = builder.add_runs(sorted.into_iter().flatten());
        debug_assert!(contiguous, "sorted by participant");
        builder.finish()
    }

    /// Participant `p`'s pairs.
    #[inline]
    pub fn of(&self, participant: usize) -> &[PairTally] {
        let (start, end) = self.spans[participant];
        &self.pairs[start..end]
    }

    /// The participants with any judgment, in index order.
    pub fn present(&self) -> Vec<usize> {
        (0..self.present.len()).filter(|&p| self.present[p]).collect()
    }

    /// The tallies of `participants` together, as [`tally`] or [`tally_dense`] give them for
    /// their judgments: one per pair judged, sorted by `(i, j)`.
    pub fn pooled(&self, n_conditions: usize, participants: &[usize]) -> Vec<PairTally> {
        let t = n_conditions;
        let pairs_of = || participants.iter().flat_map(|&p| self.of(p));
        if t <= DENSE_POOLED_CONDITIONS {
            let mut wins = vec![0u64; t * t];
            for pair in pairs_of() {
                wins[pair.i * t + pair.j] += pair.wins_i;
                wins[pair.j * t + pair.i] += pair.wins_j;
            }
            from_dense(&wins, t)
        } else {
            let mut keyed: Vec<PairTally> = pairs_of().copied().collect();
            keyed.sort_unstable_by_key(|pair| (pair.i, pair.j));
            keyed.dedup_by(|next, kept| {
                let same = (next.i, next.j) == (kept.i, kept.j);
                if same {
                    kept.wins_i += next.wins_i;
                    kept.wins_j += next.wins_j;
                }
                same
            });
            keyed
        }
    }

    /// Participant `p`'s pairs as rows `(i, j, i won, count)` for [`tally`] and [`tally_dense`]
    /// (one per direction that has judgments).
    pub fn rows_of(&self, participant: usize) -> impl Iterator<Item = (u32, u32, bool, u64)> + '_ {
        self.of(participant).iter().flat_map(|pair| {
            let (i, j) = (pair.i as u32, pair.j as u32);
            [(i, j, true, pair.wins_i), (i, j, false, pair.wins_j)].into_iter().filter(|row| row.3 > 0)
        })
    }
}

/// Builds [`ParticipantTallies`] from runs of one participant's rows.
struct Builder {
    n_conditions: usize,
    dense: bool,
    tallies: ParticipantTallies,
    /// Dense: `grid[i * t + j]` of the current participant (i < j: wins of i, wins of j), and
    /// the cells touched, in order, in `touched[..n_touched]`. Sparse: the current
    /// participant's rows as pairs, with their order of arrival.
    grid: Vec<[u64; 2]>,
    touched: Vec<usize>,
    n_touched: usize,
    scratch: Vec<(PairTally, usize)>,
}

impl Builder {
    fn new(n_participants: usize, n_conditions: usize) -> Builder {
        let dense = n_conditions <= DENSE_PARTICIPANT_CONDITIONS;
        Builder {
            n_conditions,
            dense,
            tallies: ParticipantTallies {
                spans: vec![(0, 0); n_participants],
                pairs: Vec::new(),
                present: vec![false; n_participants],
            },
            grid: vec![[0, 0]; if dense { n_conditions * n_conditions } else { 0 }],
            touched: vec![0; if dense { n_conditions * n_conditions } else { 0 }],
            n_touched: 0,
            scratch: Vec::new(),
        }
    }

    /// Adds `rows` run by run; false (and nothing sure) where a participant comes back after
    /// another's rows.
    fn add_runs<'a>(&mut self, rows: impl Iterator<Item = &'a crate::data::Judgment>) -> bool {
        let (t, dense) = (self.n_conditions, self.dense);
        let mut current: Option<usize> = None;
        for row in rows {
            let p = row.participant as usize;
            if current != Some(p) {
                if let Some(previous) = current {
                    self.flush(previous);
                }
                if self.tallies.present[p] {
                    return false;
                }
                self.tallies.present[p] = true;
                current = Some(p);
            }
            if row.count == 0 {
                continue;
            }
            // Without branches on the data (they would be mispredicted half the time).
            let (i, j) = (row.left.min(row.right) as usize, row.left.max(row.right) as usize);
            let i_won = row.left_chosen ^ (row.left > row.right);
            if dense {
                let cell = i * t + j;
                let tally = &mut self.grid[cell];
                self.touched[self.n_touched] = cell;
                self.n_touched += usize::from(*tally == [0, 0]);
                tally[usize::from(!i_won)] += row.count;
            } else {
                let (wins_i, wins_j) = if i_won { (row.count, 0) } else { (0, row.count) };
                let order = self.scratch.len();
                self.scratch.push((PairTally { i, j, wins_i, wins_j }, order));
            }
        }
        if let Some(previous) = current {
            self.flush(previous);
        }
        true
    }

    /// Ends participant `p`'s run: their pairs, in the order of first judgment, to the tallies.
    fn flush(&mut self, participant: usize) {
        let t = self.n_conditions;
        let start = self.tallies.pairs.len();
        for &cell in &self.touched[..self.n_touched] {
            let [wins_i, wins_j] = std::mem::take(&mut self.grid[cell]);
            self.tallies.pairs.push(PairTally { i: cell / t, j: cell % t, wins_i, wins_j });
        }
        self.n_touched = 0;
        if !self.scratch.is_empty() {
            // Stable: within a pair the first row stays first, and keeps its order of arrival.
            self.scratch.sort_by_key(|(pair, _)| (pair.i, pair.j));
            self.scratch.dedup_by(|next, kept| {
                let same = (next.0.i, next.0.j) == (kept.0.i, kept.0.j);
                if same {
                    kept.0.wins_i += next.0.wins_i;
                    kept.0.wins_j += next.0.wins_j;
                }
                same
            });
            self.scratch.sort_unstable_by_key(|&(_, order)| order);
            self.tallies.pairs.extend(self.scratch.drain(..).map(|(pair, _)| pair));
        }
        self.tallies.spans[participant] = (start, self.tallies.pairs.len());
    }

    fn finish(self) -> ParticipantTallies {
        self.tallies
    }
}

/// Union–find over conditions (`parent[x] == x` at a root): the root of `x`'s component, with
/// path halving. The comparison graph's components here and the active designs' pair choice.
pub fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

/// Joins the components of `a` and `b` (the larger root under the smaller); true if they were
/// apart.
pub fn union(parent: &mut [usize], a: usize, b: usize) -> bool {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra == rb {
        return false;
    }
    parent[ra.max(rb)] = ra.min(rb);
    true
}

/// Connected components of the comparison graph over the conditions that were compared at
/// least once. Each component lists its conditions in increasing index order; components are
/// ordered by their smallest condition. Conditions never compared belong to no component.
pub fn components(n_conditions: usize, pairs: &[PairTally]) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..n_conditions).collect();
    let mut compared = vec![false; n_conditions];
    for pair in pairs.iter().filter(|pair| pair.n() > 0) {
        compared[pair.i] = true;
        compared[pair.j] = true;
        union(&mut parent, pair.i, pair.j);
    }
    let mut by_root: std::collections::BTreeMap<usize, Vec<usize>> = std::collections::BTreeMap::new();
    for condition in 0..n_conditions {
        if compared[condition] {
            let root = find(&mut parent, condition);
            by_root.entry(root).or_default().push(condition);
        }
    }
    let mut list: Vec<Vec<usize>> = by_root.into_values().collect();
    list.sort_by_key(|members| members[0]);
    list
}

/// Zermelo's condition for the existence of the item-model MLE within one connected component:
/// the directed "beat at least once" graph must be strongly connected. Returns the strongly
/// connected components in topological order (winners first) when it is not, else `None`.
/// With more than one, the first never lost to anyone outside it and the last never won
/// against anyone outside it.
pub fn separation(members: &[usize], pairs: &[PairTally]) -> Option<Vec<Vec<usize>>> {
    let n = members.len();
    if n < 2 {
        return None;
    }
    let local: std::collections::HashMap<usize, usize> = members.iter().enumerate().map(|(k, &m)| (m, k)).collect();
    let mut beats: Vec<Vec<usize>> = vec![Vec::new(); n];
    for pair in pairs {
        let (Some(&a), Some(&b)) = (local.get(&pair.i), local.get(&pair.j)) else { continue };
        if pair.wins_i > 0 {
            beats[a].push(b);
        }
        if pair.wins_j > 0 {
            beats[b].push(a);
        }
    }
    let sccs = tarjan(&beats);
    if sccs.len() == 1 {
        return None;
    }
    // Tarjan yields SCCs in reverse topological order of the condensation.
    Some(
        sccs.into_iter()
            .rev()
            .map(|scc| {
                let mut scc: Vec<usize> = scc.into_iter().map(|k| members[k]).collect();
                scc.sort_unstable();
                scc
            })
            .collect(),
    )
}

/// Tarjan's strongly-connected-components algorithm, iterative (no recursion limit).
fn tarjan(edges: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let n = edges.len();
    let mut index = vec![usize::MAX; n];
    let mut low = vec![0; n];
    let mut on_stack = vec![false; n];
    let mut stack = Vec::new();
    let mut result = Vec::new();
    let mut counter = 0;
    for start in 0..n {
        if index[start] != usize::MAX {
            continue;
        }
        let mut call: Vec<(usize, usize)> = vec![(start, 0)];
        index[start] = counter;
        low[start] = counter;
        counter += 1;
        stack.push(start);
        on_stack[start] = true;
        while let Some(&mut (v, ref mut next)) = call.last_mut() {
            if *next < edges[v].len() {
                let w = edges[v][*next];
                *next += 1;
                if index[w] == usize::MAX {
                    index[w] = counter;
                    low[w] = counter;
                    counter += 1;
                    stack.push(w);
                    on_stack[w] = true;
                    call.push((w, 0));
                } else if on_stack[w] {
                    low[v] = low[v].min(index[w]);
                }
            } else {
                call.pop();
                if let Some(&(parent, _)) = call.last() {
                    low[parent] = low[parent].min(low[v]);
                }
                if low[v] == index[v] {
                    let mut scc = Vec::new();
                    while let Some(w) = stack.pop() {
                        on_stack[w] = false;
                        scc.push(w);
                        if w == v {
                            break;
                        }
                    }
                    result.push(scc);
                }
            }
        }
    }
    result
}

/// One term of a factor model: a factor, or a product of factors (an interaction).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Term {
    /// Indices into the factor list; one for a main effect, several for an interaction.
    pub factors: Vec<usize>,
    /// Display name: factor names joined by `:`.
    pub name: String,
}

/// Parses a model formula such as `gi+cm+ca+gi:ca` or `gi*ca + cm` over the given factors.
/// `a*b` expands to `a + b + a:b`. Duplicate terms are kept once.
pub fn parse_formula(formula: &str, factors: &[String]) -> crate::Result<Vec<Term>> {
    let bad = |message: String| crate::AnalysisError::BadModel { formula: formula.to_string(), message };
    let mut terms: Vec<Term> = Vec::new();
    let push = |factor_indices: Vec<usize>, terms: &mut Vec<Term>| {
        let mut sorted = factor_indices;
        sorted.sort_unstable();
        sorted.dedup();
        if !terms.iter().any(|t| t.factors == sorted) {
            let name = sorted.iter().map(|&k| factors[k].as_str()).collect::<Vec<_>>().join(":");
            terms.push(Term { factors: sorted, name });
        }
    };
    for raw in formula.split('+') {
        let raw = raw.trim();
        if raw.is_empty() {
            return Err(bad("a term is empty (two `+` in a row, or one at an end)".to_string()));
        }
        let lookup = |name: &str| -> crate::Result<usize> {
            let name = name.trim();
            factors.iter().position(|f| f == name).ok_or_else(|| {
                bad(format!("`{name}` is not a factor of the conditions file (factors: {})", factors.join(", ")))
            })
        };
        if raw.contains('*') {
            let parts: Vec<usize> = raw.split('*').map(lookup).collect::<crate::Result<_>>()?;
            // All non-empty subsets, in order of size, as R expands a*b*c.
            let n = parts.len();
            let mut subsets: Vec<Vec<usize>> = (1..(1u32 << n))
                .map(|mask| (0..n).filter(|&k| mask & (1 << k) != 0).map(|k| parts[k]).collect())
                .collect();
            subsets.sort_by_key(Vec::len);
            for subset in subsets {
                push(subset, &mut terms);
            }
        } else {
            let parts: Vec<usize> = raw.split(':').map(lookup).collect::<crate::Result<_>>()?;
            push(parts, &mut terms);
        }
    }
    Ok(terms)
}

/// The covariate value of each term for each condition: `values[condition][term]`.
pub fn term_values(levels: &[Vec<f64>], terms: &[Term]) -> Vec<Vec<f64>> {
    levels.iter().map(|row| terms.iter().map(|term| term.factors.iter().map(|&k| row[k]).product()).collect()).collect()
}

/// Why a term was left out of a factor model.
#[derive(Debug, Clone, PartialEq)]
pub enum Dropped {
    /// The term takes one value over all compared conditions.
    Constant,
    /// The term is a linear combination of the named, earlier terms (over the compared pairs).
    Collinear(Vec<usize>),
}

/// Chooses the identifiable terms: in formula order, a term is kept unless its pair
/// differences (xᵢ − xⱼ over the compared pairs) are zero or a linear combination of the
/// terms kept before it. Returns the kept term indices and the dropped ones with the reason.
pub fn identifiable_terms(
    values: &[Vec<f64>],
    n_terms: usize,
    pairs: &[PairTally],
) -> (Vec<usize>, Vec<(usize, Dropped)>) {
    // Gram matrix of the pair-difference columns, each compared pair counted once.
    let mut gram = vec![vec![0.0; n_terms]; n_terms];
    for pair in pairs.iter().filter(|pair| pair.n() > 0) {
        let d: Vec<f64> = (0..n_terms).map(|k| values[pair.i][k] - values[pair.j][k]).collect();
        for a in 0..n_terms {
            for b in 0..n_terms {
                gram[a][b] += d[a] * d[b];
            }
        }
    }
    let mut kept: Vec<usize> = Vec::new();
    let mut dropped = Vec::new();
    for k in 0..n_terms {
        let own = gram[k][k];
        if own <= 0.0 {
            dropped.push((k, Dropped::Constant));
            continue;
        }
        // Project column k on the kept columns: solve G_KK c = g_K.
        let m = kept.len();
        let mut a: Vec<Vec<f64>> = kept.iter().map(|&r| kept.iter().map(|&c| gram[r][c]).collect()).collect();
        let mut c: Vec<f64> = kept.iter().map(|&r| gram[r][k]).collect();
        let solved = gauss_solve(&mut a, &mut c);
        let residual = if m == 0 {
            own
        } else if solved {
            own - kept.iter().zip(&c).map(|(&r, ci)| ci * gram[r][k]).sum::<f64>()
        } else {
            own
        };
        if residual <= 1e-9 * own {
            let partners = kept.iter().zip(&c).filter(|(_, ci)| ci.abs() > 1e-8).map(|(&r, _)| r).collect();
            dropped.push((k, Dropped::Collinear(partners)));
        } else {
            kept.push(k);
        }
    }
    (kept, dropped)
}

/// Solves a small dense system in place by Gaussian elimination with partial pivoting; the
/// solution replaces `b`. Returns false if the matrix is singular.
fn gauss_solve(a: &mut [Vec<f64>], b: &mut [f64]) -> bool {
    let n = b.len();
    for col in 0..n {
        let pivot = (col..n).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs())).unwrap();
        if a[pivot][col].abs() < 1e-300 {
            return false;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..n {
            let factor = a[row][col] / a[col][col];
            for k in col..n {
                a[row][k] -= factor * a[col][k];
            }
            b[row] -= factor * b[col];
        }
    }
    for col in (0..n).rev() {
        let sum: f64 = (col + 1..n).map(|k| a[col][k] * b[k]).sum();
        b[col] = (b[col] - sum) / a[col][col];
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(i: usize, j: usize, wins_i: u64, wins_j: u64) -> PairTally {
        PairTally { i, j, wins_i, wins_j }
    }

    /// Per-participant tallies: the same whether each participant's rows are contiguous or
    /// not, whether summed densely or by sorting, each participant's pairs in the order of
    /// their first judgment; pooled, as [`tally`] gives them.
    #[test]
    fn participant_tallies_agree_however_built() {
        use crate::data::Judgment;
        let mut state = 7u64;
        let mut next = |below: u64| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 33) % below
        };
        let mut rows = Vec::new();
        for participant in 0..5u32 {
            for _ in 0..20 + next(20) {
                let left = next(6) as u32;
                let right = (left + 1 + next(5) as u32) % 6;
                let (left_chosen, count) = (next(2) == 0, 1 + next(3));
                rows.push(Judgment { participant, left, right, left_chosen, count, group: 0 });
            }
        }
        let contiguous = ParticipantTallies::new(5, 6, rows.iter());
        let sparse = ParticipantTallies::new(5, 100, rows.iter());
        // Participants interleaved: rows k and k + 1 of different participants swapped.
        let mut interleaved = rows.clone();
        for k in (0..interleaved.len() - 1).step_by(3) {
            interleaved.swap(k, k + 1);
        }
        let sorted = |rows: &[Judgment]| {
            let mut sorted = rows.to_vec();
            sorted.sort_by_key(|row| row.participant);
            sorted
        };
        let expected = ParticipantTallies::new(5, 6, sorted(&interleaved).iter());
        let from_interleaved = ParticipantTallies::new(5, 6, interleaved.iter());
        for p in 0..5 {
            assert_eq!(contiguous.of(p), sparse.of(p));
            assert_eq!(from_interleaved.of(p), expected.of(p));
            let first = contiguous.of(p)[0];
            let first_row = rows.iter().find(|row| row.participant == p as u32).unwrap();
            assert_eq!(
                (first.i, first.j),
                (first_row.left.min(first_row.right) as usize, first_row.left.max(first_row.right) as usize)
            );
        }
        let everyone = contiguous.present();
        assert_eq!(everyone, [0, 1, 2, 3, 4]);
        let all = tally(rows.iter().map(|row| (row.left, row.right, row.left_chosen, row.count)));
        assert_eq!(contiguous.pooled(6, &everyone), all);
        assert_eq!(contiguous.pooled(600, &everyone), all);
        assert_eq!(from_interleaved.pooled(6, &everyone), all);
        let two = tally(
            rows.iter()
                .filter(|row| [1, 3].contains(&row.participant))
                .map(|row| (row.left, row.right, row.left_chosen, row.count)),
        );
        assert_eq!(contiguous.pooled(6, &[1, 3]), two);
        assert_eq!(tally(contiguous.rows_of(1).chain(contiguous.rows_of(3))), two);
    }

    #[test]
    fn tallies_agree_dense_and_sparse() {
        let rows = vec![(0, 1, true, 1), (1, 0, true, 2), (2, 0, false, 5), (1, 2, true, 1)];
        let sparse = tally(rows.clone());
        let dense = tally_dense(3, rows);
        assert_eq!(sparse, dense);
        assert_eq!(sparse, vec![t(0, 1, 1, 2), t(0, 2, 5, 0), t(1, 2, 1, 0)]);
    }

    #[test]
    fn components_of_a_disconnected_design() {
        let pairs = [t(0, 1, 1, 1), t(2, 3, 1, 0), t(3, 4, 0, 2)];
        assert_eq!(components(6, &pairs), vec![vec![0, 1], vec![2, 3, 4]]);
    }

    #[test]
    fn separation_names_the_winner() {
        // 0 never loses; 1 and 2 beat each other.
        let pairs = [t(0, 1, 3, 0), t(0, 2, 2, 0), t(1, 2, 1, 1)];
        let sccs = separation(&[0, 1, 2], &pairs).unwrap();
        assert_eq!(sccs, vec![vec![0], vec![1, 2]]);
        let pairs = [t(0, 1, 3, 1), t(0, 2, 2, 1), t(1, 2, 1, 1)];
        assert!(separation(&[0, 1, 2], &pairs).is_none());
    }

    #[test]
    fn formula_expansion_and_errors() {
        let factors: Vec<String> = ["gi", "cm", "ca"].iter().map(|s| s.to_string()).collect();
        let terms = parse_formula("gi*ca + cm", &factors).unwrap();
        let names: Vec<&str> = terms.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, vec!["gi", "ca", "gi:ca", "cm"]);
        let error = parse_formula("gi+xx", &factors).unwrap_err().to_string();
        assert_eq!(error, "model `gi+xx`: `xx` is not a factor of the conditions file (factors: gi, cm, ca)");
        assert!(parse_formula("gi++cm", &factors).is_err());
    }

    #[test]
    fn constant_and_collinear_terms_are_dropped() {
        // Factors: a, b = 1 - a (collinear with a), c constant, d independent.
        let levels = vec![vec![0.0, 1.0, 1.0, 0.0], vec![1.0, 0.0, 1.0, 0.0], vec![1.0, 0.0, 1.0, 1.0]];
        let pairs = [t(0, 1, 1, 1), t(1, 2, 1, 1), t(0, 2, 1, 1)];
        let (kept, dropped) = identifiable_terms(&levels, 4, &pairs);
        assert_eq!(kept, vec![0, 3]);
        assert_eq!(dropped, vec![(1, Dropped::Collinear(vec![0])), (2, Dropped::Constant)]);
    }
}
