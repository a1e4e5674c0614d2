//! Simulated studies: active selection against random pairs on simulated observers with known
//! log-worths, scored by the RMSE of the posterior mean log-worths (both centred) against the
//! truth at given trial counts, averaged over seeded runs.
//!
//! An observer judges a pair by the study's link at their own log-worths: the true ones plus,
//! per participant, N(0, taste_sd²) taste noise per condition (Thurstone observers: `Link::Probit`,
//! Φ(λᵢ − λⱼ)). Participants come one after another and ask for batches of `batch` pairs;
//! the posterior absorbs every judgment as it arrives. Both designs use the same posterior
//! (so only the pairs differ), the same observers and the same outcome stream (common random
//! numbers); random pairs are uniform over the unordered pairs, never the participant's
//! previous one. Everything is a pure function of the config.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use serde::Serialize;

use super::{ActiveError, Link, Posterior, Result, Target, tie_stream};

/// How the pairs are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Design {
    /// [`Posterior::best_pairs`].
    Active,
    /// Uniform over the unordered pairs.
    Random,
}

/// A simulated study.
#[derive(Debug, Clone)]
pub struct SimulationConfig {
    /// The observers' mean log-worths, one per condition, on the link's scale.
    pub true_log_worths: Vec<f64>,
    /// The model the posterior fits (log-worths, or factor effects).
    pub target: Target,
    pub link: Link,
    pub prior_sd: f64,
    /// ρ of the active score EIG(ρ·m, v) ([`Posterior::with_mean_weight`]).
    pub mean_weight: f64,
    /// Per-participant taste noise (sd of each condition's log-worth offset); 0 for none.
    pub taste_sd: f64,
    pub trials_per_participant: usize,
    /// Pairs per request.
    pub batch: usize,
    /// Trial counts at which the RMSE is recorded; the study runs to the largest.
    pub checkpoints: Vec<usize>,
    pub runs: usize,
    pub seed: u64,
}

/// Mean RMSE over the runs at one trial count.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimulationRow {
    pub design: Design,
    pub conditions: usize,
    pub trials: usize,
    pub runs: usize,
    pub rmse: f64,
    /// Standard error of `rmse` over the runs.
    pub rmse_se: f64,
}

/// The 2^k factorial with 0/1 levels (condition c has factor k at level (c >> k) & 1, as the
/// analysis benchmark's synthetic studies) and its log-worths λ = X·effects.
pub fn factorial(effects: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>) {
    let k = effects.len();
    let design: Vec<Vec<f64>> = (0..1usize << k).map(|c| (0..k).map(|f| ((c >> f) & 1) as f64).collect()).collect();
    let worths = design.iter().map(|row| row.iter().zip(effects).map(|(x, b)| x * b).sum()).collect();
    (design, worths)
}

/// A uniform draw in [0, 1) from 53 bits of one `next_u64`.
pub(crate) fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A standard normal draw by Box–Muller (two `next_u64`).
pub(crate) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = 1.0 - uniform(rng);
    let u2 = uniform(rng);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A stream keyed by (seed, run, purpose), laid out by hand.
fn stream(seed: u64, run: u64, purpose: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[0..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&run.to_le_bytes());
    key[16..24].copy_from_slice(&purpose.to_le_bytes());
    ChaCha8Rng::from_seed(key)
}

/// The RMSE of `estimate` against `truth`, both centred (log-worths are identified up to their
/// mean): what [`simulate`] scores at each checkpoint.
pub fn centred_rmse(estimate: &[f64], truth: &[f64]) -> f64 {
    let n = truth.len() as f64;
    let (me, mt) = (estimate.iter().sum::<f64>() / n, truth.iter().sum::<f64>() / n);
    (estimate.iter().zip(truth).map(|(e, t)| ((e - me) - (t - mt)).powi(2)).sum::<f64>() / n).sqrt()
}

/// The mean of `values` (one per run) and its standard error (0 for a single run).
pub fn mean_and_standard_error(values: &[f64]) -> (f64, f64) {
    let runs = values.len() as f64;
    let mean = values.iter().sum::<f64>() / runs;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (runs - 1.0).max(1.0);
    (mean, (variance / runs).sqrt())
}

/// One judgment of a simulated study: the pair as chosen, and whether its first condition won.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoggedJudgment {
    pub first: usize,
    pub second: usize,
    pub first_won: bool,
}

/// The judgments of run `run` of `config` with `design`, in order: what [`simulate`] scores, for
/// scoring by another estimator (the side-by-side with a published scheduler does that).
pub fn judgment_log(config: &SimulationConfig, design: Design, run: u64) -> Result<Vec<LoggedJudgment>> {
    let mut log = Vec::new();
    run_once(config, design, run, Some(&mut log))?;
    Ok(log)
}

/// One run: the RMSE at each checkpoint (and, when asked, every judgment).
fn run_once(
    config: &SimulationConfig,
    design: Design,
    run: u64,
    mut log: Option<&mut Vec<LoggedJudgment>>,
) -> Result<Vec<f64>> {
    let n = config.true_log_worths.len();
    let mut posterior =
        Posterior::new(&config.target, config.link, config.prior_sd)?.with_mean_weight(config.mean_weight)?;
    let mut outcomes = stream(config.seed, run, 0);
    let mut tastes = stream(config.seed, run, 1);
    let mut random_pairs = stream(config.seed, run, 2);
    let total = config.checkpoints.iter().copied().max().unwrap_or(0);
    let mut rmse = Vec::new();
    let mut participant = 0u64;
    let mut judged = 0;
    while judged < total {
        let worths: Vec<f64> =
            config.true_log_worths.iter().map(|&w| w + config.taste_sd * normal(&mut tastes)).collect();
        let mut previous: Option<(usize, usize)> = None;
        let mut done = 0;
        while done < config.trials_per_participant && judged < total {
            let k = config.batch.min(config.trials_per_participant - done).min(total - judged);
            let pairs = match design {
                Design::Active => {
                    let mut rng = tie_stream(config.seed ^ run, posterior.state_id(), participant);
                    posterior.best_pairs(k, previous, &mut rng)?
                }
                Design::Random => {
                    let n_pairs = (n * (n - 1) / 2) as u64;
                    let mut pairs = Vec::with_capacity(k);
                    let mut last = previous;
                    while pairs.len() < k {
                        let mut index = random_pairs.next_u64() % n_pairs;
                        let mut i = 0;
                        while index >= (n - 1 - i) as u64 {
                            index -= (n - 1 - i) as u64;
                            i += 1;
                        }
                        let pair = (i, i + 1 + index as usize);
                        if Some(pair) != last {
                            pairs.push(pair);
                            last = Some(pair);
                        }
                    }
                    pairs
                }
            };
            for (i, j) in pairs {
                let i_won = uniform(&mut outcomes) < config.link.probability(worths[i] - worths[j]);
                let (winner, loser) = if i_won { (i, j) } else { (j, i) };
                posterior.update(winner, loser)?;
                if let Some(log) = log.as_deref_mut() {
                    log.push(LoggedJudgment { first: i, second: j, first_won: i_won });
                }
                previous = Some((i, j));
                judged += 1;
                done += 1;
                if config.checkpoints.contains(&judged) {
                    rmse.push((judged, centred_rmse(&posterior.log_worths(), &config.true_log_worths)));
                }
            }
        }
        participant += 1;
    }
    Ok(config.checkpoints.iter().map(|c| rmse.iter().find(|(j, _)| j == c).map_or(f64::NAN, |r| r.1)).collect())
}

/// Simulates `config.runs` studies with `design`; one row per checkpoint.
pub fn simulate(config: &SimulationConfig, design: Design) -> Result<Vec<SimulationRow>> {
    let bad = |option: &'static str, message: String| ActiveError::BadOption { option, message };
    let n = config.true_log_worths.len();
    if n != config.target.conditions() {
        let message = format!("{n} true log-worths for {} conditions", config.target.conditions());
        return Err(bad("true_log_worths", message));
    }
    if config.runs == 0 || config.batch == 0 || config.trials_per_participant == 0 {
        return Err(bad("runs, batch, trials_per_participant", "each must be at least 1".into()));
    }
    if config.checkpoints.is_empty() || config.checkpoints.contains(&0) {
        return Err(bad("checkpoints", "give at least one trial count, each at least 1".into()));
    }
    if !(config.taste_sd >= 0.0 && config.taste_sd.is_finite()) {
        return Err(bad("taste_sd", format!("must be finite and not negative, got {}", config.taste_sd)));
    }
    let per_run: Vec<Vec<f64>> =
        (0..config.runs as u64).map(|run| run_once(config, design, run, None)).collect::<Result<_>>()?;
    Ok(config
        .checkpoints
        .iter()
        .enumerate()
        .map(|(c, &trials)| {
            let values: Vec<f64> = per_run.iter().map(|r| r[c]).collect();
            let (rmse, rmse_se) = mean_and_standard_error(&values);
            SimulationRow { design, conditions: n, trials, runs: config.runs, rmse, rmse_se }
        })
        .collect())
}
