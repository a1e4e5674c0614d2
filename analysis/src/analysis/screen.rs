//! Observer screening: each participant's choices against the consensus of the others (the item
//! model refitted without them by Newton steps from the whole data's estimate), tested with
//! [`crate::screening`]'s exact or saddlepoint null distribution.

use rayon::prelude::*;

use crate::design::PairTally;
use crate::design::ParticipantTallies;
use crate::fit::{Fit, ModelMatrix};

use super::{Observer, ObserverScreening, Options};

/// Score and (dense, q×q, lower triangle) information of the item model at `beta` over `pairs`;
/// `column[c]` is condition `c`'s parameter (`None` for the reference).
fn item_score_information(
    pairs: impl Iterator<Item = (usize, usize, f64, f64)>,
    column: &[Option<usize>],
    beta: &[f64],
    score: &mut [f64],
    information: &mut [f64],
) {
    item_score_information_with(pairs, column, |i, j| item_probability(column, beta, i, j), score, information);
}

/// The item model's probability at `beta` that condition `i` is chosen over `j`.
fn item_probability(column: &[Option<usize>], beta: &[f64], i: usize, j: usize) -> f64 {
    let lambda = |c: usize| column[c].map_or(0.0, |k| beta[k]);
    1.0 / (1.0 + (lambda(j) - lambda(i)).exp())
}

/// As [`item_score_information`], with the model's probability that `i` is chosen over `j`
/// given by `pi(i, j)` (a table, where the same estimate serves many participants).
fn item_score_information_with(
    pairs: impl Iterator<Item = (usize, usize, f64, f64)>,
    column: &[Option<usize>],
    pi: impl Fn(usize, usize) -> f64,
    score: &mut [f64],
    information: &mut [f64],
) {
    let q = score.len();
    for (i, j, wins_i, n) in pairs {
        let pi = pi(i, j);
        let residual = wins_i - n * pi;
        let weight = n * pi * (1.0 - pi);
        let (a, b) = (column[i], column[j]);
        if let Some(a) = a {
            score[a] += residual;
            information[a * q + a] += weight;
        }
        if let Some(b) = b {
            score[b] -= residual;
            information[b * q + b] += weight;
        }
        if let (Some(a), Some(b)) = (a, b) {
            information[a.max(b) * q + a.min(b)] -= weight;
        }
    }
}

/// The item model's parameters above which the leave-one-out fit takes one step with the whole
/// data's information instead of refactorising the others' (q³ per participant).
const SCREENING_EXACT_STEP_PARAMETERS: usize = 48;

/// Observer screening. Per participant, the consensus is the item model fitted to everybody
/// else: Newton steps from the whole data's estimate on the others' score and information
/// (the whole data's minus the participant's, so a step costs the participant's pairs, not the
/// data's; from the full estimate the first step is already within O(δ²) of the refit, and
/// further steps are taken while they move a parameter by more than 1e-3, where the pairs
/// are few). Then the participant's log-likelihood under that consensus is tested against its
/// exact or saddlepoint null distribution ([`crate::screening`]).
pub(super) fn screen_observers(
    pairs: &[PairTally],
    component: &(Vec<usize>, usize, Fit, Option<Vec<Vec<usize>>>),
    tallies: &ParticipantTallies,
    active: &[usize],
    participant_names: &[String],
    options: &Options,
) -> ObserverScreening {
    let (members, reference, full_fit, _) = component;
    // `pairs` are the active participants' pairs pooled: every condition they compared.
    let n_conditions =
        members.iter().max().map_or(0, |m| m + 1).max(pairs.iter().map(|p| p.i.max(p.j) + 1).max().unwrap_or(0));
    let x = ModelMatrix::items(n_conditions, members, *reference);
    let column: Vec<Option<usize>> = x.rows.iter().map(|row| row.first().map(|&(c, _)| c)).collect();
    let q = x.n_params;
    let as_f64 = |p: &PairTally| (p.i, p.j, p.wins_i as f64, p.n() as f64);
    let (mut full_score, mut full_information) = (vec![0.0; q], vec![0.0; q * q]);
    item_score_information(pairs.iter().map(as_f64), &column, &full_fit.beta, &mut full_score, &mut full_information);
    let exact_step = q <= SCREENING_EXACT_STEP_PARAMETERS;
    let more_steps = pairs.len() <= 4096 && exact_step;
    let dense = n_conditions <= 64;
    // The whole data's model probability per pair of conditions (dense designs): every
    // participant's first step starts there, so it is computed once rather than per participant.
    let full_pi: Vec<f64> = if dense {
        (0..n_conditions * n_conditions)
            .map(|ij| item_probability(&column, &full_fit.beta, ij / n_conditions, ij % n_conditions))
            .collect()
    } else {
        Vec::new()
    };

    struct Scratch {
        sorted: Vec<PairTally>,
        terms: Vec<crate::screening::PairTerm>,
        score: Vec<f64>,
        information: Vec<f64>,
    }
    let observers: Vec<Observer> = active
        .par_iter()
        .map_init(
            || Scratch { sorted: Vec::new(), terms: Vec::new(), score: vec![0.0; q], information: vec![0.0; q * q] },
            |scratch, &p| {
                // The participant's own tallies per pair (i < j): in the order of their first
                // judgment for few conditions, else sorted by pair.
                let own = if dense {
                    tallies.of(p)
                } else {
                    scratch.sorted.clear();
                    scratch.sorted.extend_from_slice(tallies.of(p));
                    scratch.sorted.sort_unstable_by_key(|pair| (pair.i, pair.j));
                    &scratch.sorted
                };
                let own_f64 = || own.iter().map(as_f64);
                // Leave-one-out consensus by Newton steps on the others' likelihood.
                let mut beta = full_fit.beta.clone();
                for step in 0..10 {
                    let (score, information) = (&mut scratch.score, &mut scratch.information);
                    score.fill(0.0);
                    information.fill(0.0);
                    if step == 0 && dense {
                        let pi = |i: usize, j: usize| full_pi[i * n_conditions + j];
                        item_score_information_with(own_f64(), &column, pi, score, information);
                    } else {
                        item_score_information(own_f64(), &column, &beta, score, information);
                    }
                    if step == 0 {
                        for (s, f) in score.iter_mut().zip(&full_score) {
                            *s = f - *s;
                        }
                        for (a, f) in information.iter_mut().zip(&full_information) {
                            *a = f - *a;
                        }
                    } else {
                        let (mut s_all, mut i_all) = (vec![0.0; q], vec![0.0; q * q]);
                        item_score_information(pairs.iter().map(as_f64), &column, &beta, &mut s_all, &mut i_all);
                        for (s, f) in score.iter_mut().zip(&s_all) {
                            *s = f - *s;
                        }
                        for (a, f) in information.iter_mut().zip(&i_all) {
                            *a = f - *a;
                        }
                    }
                    let solved = if exact_step {
                        match crate::newton::cholesky(information, q) {
                            Some(l) => {
                                let step = crate::newton::solve(&l, score);
                                score.copy_from_slice(&step);
                                true
                            }
                            None => false,
                        }
                    } else {
                        let step: Vec<f64> =
                            (0..q).map(|a| (0..q).map(|b| full_fit.covariance[(a, b)] * score[b]).sum()).collect();
                        score.copy_from_slice(&step);
                        true
                    };
                    // The others alone may not identify the consensus (separation, a condition
                    // only this participant compared): then the whole data's estimate is used.
                    if !solved || score.iter().any(|s| !s.is_finite()) {
                        if step == 0 {
                            beta.clone_from(&full_fit.beta);
                        }
                        break;
                    }
                    let largest = score.iter().fold(0.0f64, |m, s| m.max(s.abs()));
                    if largest > 5.0 {
                        break;
                    }
                    for (b, s) in beta.iter_mut().zip(score.iter()) {
                        *b += s;
                    }
                    // From the whole data's estimate a step below 1e-3 leaves the next at O(1e-6).
                    if !more_steps || largest < 1e-3 {
                        break;
                    }
                }
                let lambda = |c: usize| column[c].map_or(0.0, |k| beta[k]);
                scratch.terms.clear();
                scratch.terms.extend(own.iter().map(|pair| crate::screening::PairTerm {
                    eta: lambda(pair.i) - lambda(pair.j),
                    n: pair.n(),
                    wins: pair.wins_i,
                }));
                let test = crate::screening::log_likelihood_test(&scratch.terms);
                let n: u64 = own.iter().map(|pair| pair.n()).sum();
                let z = if test.variance > 0.0 { (test.observed - test.mean) / test.variance.sqrt() } else { 0.0 };
                Observer {
                    participant: participant_names[p].clone(),
                    judgments: n,
                    mean_log_likelihood: test.observed / n.max(1) as f64,
                    z,
                    p: test.p,
                    flagged: test.p.p < options.screening_alpha,
                }
            },
        )
        .collect();
    let flagged = observers.iter().filter(|o| o.flagged).map(|o| o.participant.clone()).collect();
    ObserverScreening { alpha: options.screening_alpha, participants: observers, flagged }
}
