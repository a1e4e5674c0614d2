//! Active pair selection (issue 14): for a participant's next trials, the condition pairs that
//! maximise the expected information gain (EIG) about the target, under a Bayesian
//! Bradley–Terry or Thurstone posterior that absorbs one judgment at a time.
//!
//! **Model.** Each condition i has a log-worth λᵢ; a judgment "w chosen over l" has likelihood
//! F(λ_w − λ_l), with F the logistic function σ ([`Link::Logit`], Bradley–Terry on the logit
//! scale of the analysis and docs/design.md) or the normal CDF Φ ([`Link::Probit`], Thurstone's case
//! V with unit-variance differences, on the probit scale). The **target** ([`Target`]) is
//! either the log-worths themselves (θ = λ, one parameter per condition) or the **factor
//! effects** of a factorial study (λ = X·β with the condition × factor matrix X, θ = β; with
//! 0/1 factor levels, as the conditions CSV and `design::term_values` code them).
//!
//! **Prior.** θ ~ N(0, σ²·I) with σ = [`DEFAULT_PRIOR_SD`] = 1.0 unless the caller says
//! otherwise: weakly informative on the logit scale (a log-worth difference has prior sd 1.4,
//! so preferences up to 80 : 20 are within one sd; the thesis' factor effects are 0.2–0.9) and
//! proper, so the log-worths need no reference condition (the prior identifies their mean,
//! which no judgment informs) and the posterior exists before the first judgment and under
//! separation. A wider prior (1.5) made every design's early estimates worse in simulation
//! (their spread overshoots small true effects) and active selection more so.
//!
//! **Update** ([`posterior`]): assumed-density filtering (ADF), the one-pass form of
//! expectation propagation that TrueSkill and ASAP use, on the full covariance. A judgment
//! with direction a = x_w − x_l projects the Gaussian posterior onto d = aᵀθ ~ N(m, v), matches
//! the first two moments of N(d; m, v)·F(d) (closed form for the probit, 48-point
//! Gauss–Hermite for the logistic: [`quadrature`]), and carries the change back by one
//! rank-one update of mean and covariance: O(p²) per judgment, never a refit. The benchmark
//! ([`bench`](mod@bench)) compares it with an online Laplace (extended-Kalman) rank-one step and with a
//! Laplace refit from scratch (exact MAP by Newton); see its module doc for the numbers. ADF is
//! within a few hundredths of the exact posterior mean on tiny designs (grid integration,
//! tested) and closer to the refit than the online Laplace step in most measured cases, but it
//! never revisits a judgment: with strongly separated conditions its mean can stay up to half a
//! posterior sd off the refit after 10⁴ judgments. [`Posterior::reanchor`] sets the posterior
//! to a refit's; the served design does not call it (the `early_gap` example measures re-anchoring
//! before every batch: with the plain EIG it matches ASAP at 20 conditions and loses to random
//! pairs at 8 — README, "What closes the gap").
//!
//! **Choice.** y depends on θ only through d = aᵀθ, so the EIG of a pair is the mutual
//! information of y and d: EIG(m, v) = H[E F(d)] − E H[F(d)], a function of the projected mean
//! m and variance v = aᵀΣa alone (for the log-worths v = Σᵢᵢ + Σⱼⱼ − 2Σᵢⱼ; for factors
//! v = xᵢⱼᵀΣxᵢⱼ). It is computed by 20-point Gauss–Hermite quadrature (within 1e-4 nats of
//! dense quadrature for v ≤ 2, 5e-4 for v ≤ 4.5, tested), so scoring every pair costs O(n²) once the covariance
//! of the log-worths is formed: 19 900 pairs at 200 conditions. [`Posterior::eig`] is that EIG.
//!
//! The batch scores a pair by EIG(ρ·m, v): the mean difference enters with a weight ρ that
//! rises from 0 to [`DEFAULT_MEAN_WEIGHT`] = ½ over the first [`MEAN_WEIGHT_RAMP`] = 20
//! judgments per condition. Why not the plain EIG (ρ = 1): in simulation (`simulate`) it was
//! *worse* than random pairs at 8 conditions with the small factor effects of the thesis, at
//! every trial count up to 320. Greedy EIG compares conditions whose estimates are close, like
//! a Swiss tournament; early estimates are mostly noise, their spread overshoots, and the
//! comparisons of far-apart estimates that would correct it are the ones it avoids. ρ = 0
//! (variance only, a balanced design) wins there but loses to random pairs at 20 conditions
//! with log-worths N(0, 1), where comparing close conditions is what pays. The ramp to ½ won
//! against random pairs in both (numbers in the issue-14 report). It is a tuned heuristic,
//! not a derivation; [`Posterior::with_mean_weight`] sets ρ_max (1 gives the plain EIG once
//! the ramp is over).
//!
//! **The spread of the log-worths** ([`spread`], issue 48): [`Posterior::with_spread_prior`]
//! scores under a hierarchical prior instead, τ ~ Gamma(2, 2/σ) on the log-worths' prior sd, by
//! EIG(ρ·m, v) on the moment-matched Gaussian of the posterior mixture over τ: cautious while
//! the data cannot tell a small spread from a large one, the plain EIG once they can. Alone,
//! under the MAP scorer of the side-by-side with ASAP, it meets issue 48's 20-condition goal
//! at 100–400 trials and misses it narrowly from 800 (0.731 of random's trials against
//! ≤ 0.727), where the ramp is better; [`Posterior::with_spread_switch`] hands over to the ramp
//! after [`SPREAD_SWITCH`] judgments per condition, and that hybrid meets the goal at every
//! count from 100 to 1600 (0.70–0.72). In what a study's analysis reports it is worse than the
//! ramp early (docs/simulate/README.md), so the default keeps the ramp; a study opts in with
//! `prior = "spread"` (target worths; ρ = 1 before the switch), and `mrstudy analyze` reports
//! the centred MAP it optimises as `log_worth_map`.
//!
//! [`Posterior::best_pairs`] returns a batch for one participant greedily: the best pair, then
//! a *fantasy* update (mean unchanged, covariance shrunk by the outcome-averaged ADF update,
//! which is what the real update does in expectation), then the next best, so concurrent
//! participants each get a batch at once. Rules on top of the score: a batch never repeats the
//! participant's previous pair back to back; until the comparison graph (judged pairs plus the
//! batch so far) is connected, only pairs that join two components are candidates, so no
//! condition is starved and the graph is connected after n − 1 judgments of a sequential
//! study.
//!
//! **Sides** ([`sides`]): per participant, the condition with the lower left-minus-right count
//! goes on the left; ties by a seeded coin.
//!
//! **Reproducible.** The state after a judgment log is a pure function of the log; its
//! [`StateId`] (judgments absorbed and a 64-bit fingerprint of the log) names it in the
//! server's log. Ties between pairs of equal EIG (every pair at the start) are broken by a
//! ChaCha8 stream drawn from (seed, state, participant) by [`tie_stream`], using only
//! `next_u64`. [`replay`] runs a log of judgments and batch requests and returns the same
//! schedule every time.
//!
//! **Failure.** Bad input is an [`ActiveError`] with one sentence; a posterior that stops being
//! usable (non-finite values, a variance that is not positive) is [`ActiveError::Degenerate`]:
//! the server then falls back to its fixed design and warns.
//!
//! [`simulate`] compares active and random pairs on simulated observers.

pub mod bench;
mod best_pair;
pub mod both;
pub mod laplace;
pub mod posterior;
pub mod quadrature;
pub mod sides;
pub mod simulate;
pub mod spread;

#[cfg(test)]
mod tests;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;

use crate::data::ConditionTable;

pub use posterior::{Posterior, StateId};
pub use sides::{SideBalance, assign_sides};

/// The prior standard deviation of every log-worth or factor effect unless the caller sets one.
pub const DEFAULT_PRIOR_SD: f64 = 1.0;

/// The default largest weight ρ of the posterior mean difference in a pair's score EIG(ρ·m, v).
pub const DEFAULT_MEAN_WEIGHT: f64 = 0.5;

/// Judgments per condition over which ρ rises from 0 to its largest value.
pub const MEAN_WEIGHT_RAMP: f64 = 20.0;

/// Judgments per condition after which the served `prior = "spread"` scores as the fixed prior
/// does ([`Posterior::with_spread_switch`]; issue 48's hybrid, docs/simulate/README.md).
pub const SPREAD_SWITCH: f64 = 15.0;

pub use crate::error::ActiveError;

pub type Result<T, E = ActiveError> = std::result::Result<T, E>;

/// The likelihood of one judgment as a function of the log-worth difference d = λ_w − λ_l.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Link {
    /// Bradley–Terry: P = 1 / (1 + e^(−d)), the analysis's logit scale.
    Logit,
    /// Thurstone case V: P = Φ(d), the probit scale.
    Probit,
}

/// What the posterior is about.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// One log-worth per condition, each with prior N(0, σ²).
    Worths { conditions: usize },
    /// Factor effects β of λ = X·β; `design[condition][factor]` is X (0/1 levels, or any coding;
    /// no intercept column, which paired comparisons cannot inform). Each effect has prior
    /// N(0, σ²).
    Factors { design: Vec<Vec<f64>> },
    /// Both reported quantities (issue 48): the posterior is over the log-worths, as
    /// [`Target::Worths`], and pairs are chosen by the A-optimal criterion of [`both`] over the
    /// centred log-worths and the least-squares factor effects of `design` (as for
    /// [`Target::Factors`]).
    Both { design: Vec<Vec<f64>> },
}

impl Target {
    /// The factor target for the named factors of a conditions table (main effects, the
    /// table's levels as they are).
    pub fn factors(table: &ConditionTable, factors: &[&str]) -> Result<Target> {
        let columns = factors
            .iter()
            .map(|name| {
                table.factors.iter().position(|f| f == name).ok_or_else(|| ActiveError::UnknownFactor {
                    factor: name.to_string(),
                    factors: table.factors.join(", "),
                })
            })
            .collect::<Result<Vec<usize>>>()?;
        Ok(Target::Factors {
            design: table.levels.iter().map(|row| columns.iter().map(|&k| row[k]).collect()).collect(),
        })
    }

    /// Number of conditions.
    pub fn conditions(&self) -> usize {
        match self {
            Target::Worths { conditions } => *conditions,
            Target::Factors { design } | Target::Both { design } => design.len(),
        }
    }

    /// Checks the target: at least 3 conditions; a factor design rectangular, finite, with at
    /// least one factor and no factor constant over the conditions (for [`Target::Both`] also
    /// none a combination of the others).
    pub fn check(&self) -> Result<()> {
        let conditions = self.conditions();
        if conditions < 3 {
            return Err(ActiveError::TooFewConditions { conditions });
        }
        if let Target::Factors { design } | Target::Both { design } = self {
            let p = design[0].len();
            if p == 0 {
                return Err(ActiveError::BadDesign { message: "it has no factor column".into() });
            }
            if let Some(row) = design.iter().position(|row| row.len() != p) {
                let message = format!("condition {row} has {} factor values, condition 0 has {p}", design[row].len());
                return Err(ActiveError::BadDesign { message });
            }
            if let Some(row) = design.iter().position(|row| row.iter().any(|x| !x.is_finite())) {
                return Err(ActiveError::BadDesign {
                    message: format!("condition {row} has a non-finite factor value"),
                });
            }
            if let Some(k) = (0..p).find(|&k| design.iter().all(|row| row[k] == design[0][k])) {
                let message = format!("factor {k} takes one value over all conditions, so no judgment can inform it");
                return Err(ActiveError::BadDesign { message });
            }
            if let Target::Both { design } = self {
                both::effect_projection(design)?;
            }
        }
        Ok(())
    }
}

/// The tie-breaking stream of one batch request: ChaCha8 keyed by the study's seed, the
/// posterior state and the participant (so concurrent participants at one state get different
/// tie-breaks, and a replay gets the same ones). The key is laid out by hand, not by
/// `seed_from_u64`, so it cannot change with a `rand` release.
pub fn tie_stream(seed: u64, state: StateId, participant: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[0..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&state.judgments.to_le_bytes());
    key[16..24].copy_from_slice(&state.fingerprint.to_le_bytes());
    key[24..32].copy_from_slice(&participant.to_le_bytes());
    ChaCha8Rng::from_seed(key)
}

/// One entry of a server's log, as [`replay`] reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event {
    /// A judgment: `winner` chosen over `loser`.
    Judgment { winner: usize, loser: usize },
    /// A participant asked for `trials` pairs; `previous` is the pair they judged last.
    Request { participant: u64, trials: usize, previous: Option<(usize, usize)> },
}

/// A batch handed out: to whom, by which posterior state, which pairs (each `(i, j)`, i < j;
/// sides by [`SideBalance`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Scheduled {
    pub participant: u64,
    pub state: StateId,
    pub pairs: Vec<(usize, usize)>,
}

/// Replays a log from `posterior` (usually a fresh one): judgments are absorbed in order and
/// every request is answered by [`Posterior::best_pairs`] with [`tie_stream`]. The same log
/// and seed give the same schedule.
pub fn replay(mut posterior: Posterior, seed: u64, events: &[Event]) -> Result<Vec<Scheduled>> {
    let mut schedule = Vec::new();
    for event in events {
        match *event {
            Event::Judgment { winner, loser } => posterior.update(winner, loser)?,
            Event::Request { participant, trials, previous } => {
                let state = posterior.state_id();
                let mut rng = tie_stream(seed, state, participant);
                let pairs = posterior.best_pairs(trials, previous, &mut rng)?;
                schedule.push(Scheduled { participant, state, pairs });
            }
        }
    }
    Ok(schedule)
}
