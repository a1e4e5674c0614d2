//! The simulated observers: taste around the truth, Bradley–Terry answers with lapses, dropout;
//! their judgments collected from the study's real scheduler.

use crate::schedule::{ActiveHistory, PlannedKind, active_batch, active_posterior, derived_seed, plan};
use crate::study::Study;
use mrstudy_analysis::active::Posterior;
use mrstudy_analysis::data::Judgment;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

use super::Config;
use super::ties::{Answer, davidson_answer};

/// Uniform in [0, 1) from 53 bits.
pub(super) fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A standard normal draw (Box–Muller).
pub(super) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = 1.0 - uniform(rng);
    let u2 = uniform(rng);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A simulated participant: their log-worths and the stream of their answers and dropout.
pub(super) struct Observer<'a> {
    pub(super) worths: Vec<f64>,
    pub(super) rng: ChaCha8Rng,
    pub(super) config: &'a Config,
}

impl Observer<'_> {
    /// Whether the left condition is chosen.
    pub(super) fn judge(&mut self, left: usize, right: usize) -> bool {
        if uniform(&mut self.rng) < self.config.options.lapse {
            return uniform(&mut self.rng) < 0.5;
        }
        uniform(&mut self.rng) < 1.0 / (1.0 + (self.worths[right] - self.worths[left]).exp())
    }

    /// The answer to a pair: [`Observer::judge`] (the same random stream) where the study has
    /// no "not sure", else Davidson's model with ν = `--tie-nu` ([`super::ties`]); a lapse is a
    /// coin flip between the sides.
    pub(super) fn answer(&mut self, left: usize, right: usize, allow_tie: bool) -> Answer {
        if !allow_tie {
            return if self.judge(left, right) { Answer::Left } else { Answer::Right };
        }
        if uniform(&mut self.rng) < self.config.options.lapse {
            return if uniform(&mut self.rng) < 0.5 { Answer::Left } else { Answer::Right };
        }
        let u = uniform(&mut self.rng);
        davidson_answer(u, self.worths[left], self.worths[right], self.config.options.tie_nu)
    }

    /// A catch trial: right unless lapsing (nothing recorded).
    pub(super) fn catch(&mut self) {
        if uniform(&mut self.rng) < self.config.options.lapse {
            uniform(&mut self.rng);
        }
    }

    pub(super) fn drops_out(&mut self) -> bool {
        self.config.options.dropout > 0.0 && uniform(&mut self.rng) < self.config.options.dropout
    }
}

/// The judgments of one simulated study (each participant's pair trials in order), and apart
/// those answered "not sure" (`allow_tie`; numbered as the others, as the analysis takes them).
pub(super) fn collect_judgments(
    study: &Study,
    config: &Config,
    participants: usize,
    run_seed: u64,
) -> Result<(Vec<Judgment>, Vec<Judgment>), String> {
    let truth: Vec<f64> = config.truth.log_worths.iter().map(|w| w.log_worth).collect();
    let mut posterior = match active_posterior(study) {
        Some(posterior) => Some(posterior.map_err(|error| error.to_string())?),
        None => None,
    };
    let mut judgments = Vec::new();
    let mut ties = Vec::new();
    for participant in 0..participants {
        let seed = derived_seed(run_seed, participant as u64);
        let mut rng = ChaCha8Rng::seed_from_u64(derived_seed(seed, 1));
        let worths = truth.iter().map(|w| w + config.options.observer_sd * normal(&mut rng)).collect();
        let mut observer = Observer { worths, rng, config };
        let mut shown: Vec<(usize, usize)> = Vec::new();
        let mut stopped = false;
        let mut answer = |left: usize, right: usize, observer: &mut Observer, posterior: &mut Option<Posterior>| {
            let answer = observer.answer(left, right, study.participation.allow_tie);
            let left_chosen = answer == Answer::Left;
            let judgment = Judgment {
                participant: participant as u32,
                left: left as u32,
                right: right as u32,
                left_chosen,
                count: 1,
                group: 0,
            };
            if answer == Answer::Tie {
                // a "not sure" informs no Bradley–Terry direction: the posterior skips it
                ties.push(judgment);
                return Ok(());
            }
            judgments.push(judgment);
            if let Some(posterior) = posterior {
                let (winner, loser) = if left_chosen { (left, right) } else { (right, left) };
                posterior.update(winner, loser).map_err(|error| error.to_string())?;
            }
            Ok::<_, String>(())
        };
        for trial in plan(study, seed) {
            match trial.kind {
                PlannedKind::Pair { left, right } => {
                    answer(left, right, &mut observer, &mut posterior)?;
                    shown.push((left, right));
                }
                PlannedKind::Catch { .. } => observer.catch(),
            }
            if observer.drops_out() {
                stopped = true;
                break;
            }
        }
        if let (Some(active), false) = (&study.design.active, stopped) {
            let mut history = ActiveHistory::of(study.conditions.len(), &shown, 0);
            let mut done = 0;
            'batches: while done < active.trials as usize {
                let count = (active.batch as usize).min(active.trials as usize - done);
                let batch = active_batch(
                    study,
                    posterior.as_ref().expect("an active design has a posterior"),
                    seed,
                    &mut history,
                    count,
                )
                .map_err(|error| error.to_string())?;
                for trial in batch {
                    let PlannedKind::Pair { left, right } = trial.kind else { continue };
                    answer(left, right, &mut observer, &mut posterior)?;
                    done += 1;
                    if observer.drops_out() {
                        break 'batches;
                    }
                }
            }
        }
    }
    Ok((judgments, ties))
}
