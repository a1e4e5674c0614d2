//! SUREAL's content-oblivious maximum-likelihood subject model, MLE_CO (Li & Bampis, "Recover
//! subjective quality scores from noisy measurements", DCC 2017; Li et al., "A simple model for
//! subject behavior in subjective experiments", HVEI 2020), as `sureal` 0.9.0's
//! `MaximumLikelihoodEstimationModelContentOblivious` computes it:
//!
//! X_es = x_e + B_es,  B_es ~ N(b_s, v_s²)
//!
//! with x_e the quality of stimulus e, b_s the bias and v_s the inconsistency of subject s, each
//! rating an independent draw (repetitions and missing cells allowed). The estimate is SUREAL's
//! damped fixed-point iteration ("simplified" gradient, refresh rate 0.1) from the same start
//! (x_e the MOS, b_s = 0, v_s the standard deviation of s's residuals from the MOS), run until
//! the step of x has norm below [`DELTA`]; its fixed point is a maximum of the likelihood. The
//! biases are then shifted to mean 0 over the subjects (SUREAL's `force_subjbias_zeromean`).
//! Standard errors are SUREAL's: one over the square root of each parameter's own observed
//! information, 1/√(Σ_s 1/v_s²) for x_e, v_s/√n_s for b_s, 1/√(Σ 3a²/v_s⁴ − 1/v_s²) for v_s
//! (a the residual).
//!
//! The likelihood has no upper bound: one subject's ratings fitted exactly (x_e = X_es − b_s,
//! v_s → 0) make it grow without limit. The iteration usually settles on an interior maximum;
//! when a subject's inconsistency falls towards 0 instead, the fit is [`Degenerate`] and says
//! whose.

/// SUREAL's damping: each step moves a tenth of the way to the update.
const REFRESH_RATE: f64 = 0.1;
/// The iteration stops when the step of x has Euclidean norm below this (SUREAL's default is
/// 1e-8, which leaves about 1e-7 of the iteration's error in x; the fixed point is the same).
pub const DELTA: f64 = 1e-13;
/// At most this many steps (SUREAL's `MAX_ITR`).
const MAX_ITERATIONS: usize = 10_000;
/// An inconsistency below this fraction of the ratings' spread counts as gone to 0.
const DEGENERATE_FRACTION: f64 = 1e-6;

/// One rating: stimulus index, subject index, score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    pub stimulus: usize,
    pub subject: usize,
    pub score: f64,
}

/// The fitted model; standard errors as SUREAL reports them (`*_std`).
#[derive(Debug, Clone, PartialEq)]
pub struct ContentObliviousFit {
    pub quality: Vec<f64>,
    pub quality_se: Vec<f64>,
    pub bias: Vec<f64>,
    pub bias_se: Vec<f64>,
    pub inconsistency: Vec<f64>,
    pub inconsistency_se: Vec<f64>,
    /// Log-likelihood of all the ratings at the estimate.
    pub log_likelihood: f64,
    pub iterations: usize,
    /// False when 10 000 steps (SUREAL's `MAX_ITR`) ran out before the step fell below [`DELTA`].
    pub converged: bool,
}

/// Why there is no MLE_CO estimate.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Degenerate {
    /// Fewer than two subjects, or a stimulus or subject without ratings.
    TooFew { message: String },
    /// The subject's inconsistency went to 0: the likelihood grows without bound.
    Unbounded { subject: usize, iterations: usize },
}

/// Fits MLE_CO to `observations` of `stimuli` stimuli by `subjects` subjects (every index in
/// range; each stimulus and subject with at least one rating, each subject with two).
pub fn fit_content_oblivious(
    stimuli: usize,
    subjects: usize,
    observations: &[Observation],
) -> Result<ContentObliviousFit, Degenerate> {
    let mut per_stimulus = vec![0usize; stimuli];
    let mut per_subject = vec![0usize; subjects];
    for o in observations {
        per_stimulus[o.stimulus] += 1;
        per_subject[o.subject] += 1;
    }
    if subjects < 2 {
        return Err(Degenerate::TooFew { message: "the model needs ratings from at least two participants".into() });
    }
    if let Some(e) = per_stimulus.iter().position(|&n| n == 0) {
        return Err(Degenerate::TooFew { message: format!("stimulus {e} has no ratings") });
    }
    if let Some(s) = per_subject.iter().position(|&n| n < 2) {
        return Err(Degenerate::TooFew { message: format!("subject {s} has fewer than two ratings") });
    }
    let (low, high) = observations
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), o| (low.min(o.score), high.max(o.score)));
    let floor = DEGENERATE_FRACTION * (high - low).max(1.0);

    // start: the MOS, no bias, the spread of each subject's residuals from the MOS (ddof 0)
    let mut x = vec![0.0; stimuli];
    for o in observations {
        x[o.stimulus] += o.score;
    }
    for (value, &n) in x.iter_mut().zip(&per_stimulus) {
        *value /= n as f64;
    }
    let mut b = vec![0.0; subjects];
    let mut v = subject_spread(observations, &x, &b, &per_subject);
    let mut iterations = 0;
    let mut converged = false;
    while iterations < MAX_ITERATIONS {
        let previous = x.clone();
        // b_s: the mean residual of s (SUREAL's weights 1/v_s² are the same for every e)
        let mut sum = vec![0.0; subjects];
        for o in observations {
            sum[o.subject] += o.score - x[o.stimulus];
        }
        for s in 0..subjects {
            let update = sum[s] / per_subject[s] as f64;
            b[s] = b[s] * (1.0 - REFRESH_RATE) + update * REFRESH_RATE;
        }
        // v_s: a damped Newton step on ∂ℓ/∂v_s = Σ (a²/v³ − 1/v)
        let mut first = vec![0.0; subjects];
        let mut second = vec![0.0; subjects];
        for o in observations {
            let s = o.subject;
            let a = o.score - x[o.stimulus] - b[s];
            let v2 = v[s] * v[s];
            first[s] += -v[s] / v2 + v[s] * a * a / (v2 * v2);
            second[s] += 1.0 / v2 - 3.0 * a * a / (v2 * v2);
        }
        for s in 0..subjects {
            let update = v[s] - first[s] / second[s];
            v[s] = (v[s] * (1.0 - REFRESH_RATE) + update * REFRESH_RATE).max(0.0);
        }
        if let Some(subject) = (0..subjects).find(|&s| !(v[s] >= floor)) {
            return Err(Degenerate::Unbounded { subject, iterations: iterations + 1 });
        }
        // x_e: the mean of the bias-corrected ratings weighted by 1/v_s²
        let mut numerator = vec![0.0; stimuli];
        let mut denominator = vec![0.0; stimuli];
        for o in observations {
            let weight = 1.0 / (v[o.subject] * v[o.subject]);
            numerator[o.stimulus] += (o.score - b[o.subject]) * weight;
            denominator[o.stimulus] += weight;
        }
        for e in 0..stimuli {
            x[e] = x[e] * (1.0 - REFRESH_RATE) + numerator[e] / denominator[e] * REFRESH_RATE;
        }
        iterations += 1;
        let step = previous.iter().zip(&x).map(|(p, q)| (p - q) * (p - q)).sum::<f64>().sqrt();
        if step < DELTA {
            converged = true;
            break;
        }
    }
    let mean_bias = b.iter().sum::<f64>() / subjects as f64;
    for value in &mut b {
        *value -= mean_bias;
    }
    for value in &mut x {
        *value += mean_bias;
    }
    Ok(standard_errors(observations, x, b, v, (iterations, converged), &per_subject))
}

/// Each subject's root mean square residual from x + b (ddof 0).
fn subject_spread(observations: &[Observation], x: &[f64], b: &[f64], per_subject: &[usize]) -> Vec<f64> {
    let mut sum = vec![0.0; per_subject.len()];
    let mut sum2 = vec![0.0; per_subject.len()];
    for o in observations {
        let r = o.score - x[o.stimulus] - b[o.subject];
        sum[o.subject] += r;
        sum2[o.subject] += r * r;
    }
    per_subject
        .iter()
        .enumerate()
        .map(|(s, &n)| {
            let mean = sum[s] / n as f64;
            (sum2[s] / n as f64 - mean * mean).max(0.0).sqrt()
        })
        .collect()
}

fn standard_errors(
    observations: &[Observation],
    quality: Vec<f64>,
    bias: Vec<f64>,
    inconsistency: Vec<f64>,
    (iterations, converged): (usize, bool),
    per_subject: &[usize],
) -> ContentObliviousFit {
    let mut information_x = vec![0.0; quality.len()];
    let mut information_v = vec![0.0; bias.len()];
    let mut log_likelihood = 0.0;
    for o in observations {
        let v = inconsistency[o.subject];
        let v2 = v * v;
        let a = o.score - quality[o.stimulus] - bias[o.subject];
        information_x[o.stimulus] += 1.0 / v2;
        information_v[o.subject] += 3.0 * a * a / (v2 * v2) - 1.0 / v2;
        log_likelihood += -0.5 * (2.0 * std::f64::consts::PI * v2).ln() - a * a / (2.0 * v2);
    }
    let se = |information: f64| 1.0 / information.max(0.0).sqrt();
    ContentObliviousFit {
        quality_se: information_x.iter().map(|&i| se(i)).collect(),
        bias_se: inconsistency.iter().zip(per_subject).map(|(v, &n)| v / (n as f64).sqrt()).collect(),
        inconsistency_se: information_v.iter().map(|&i| se(i)).collect(),
        quality,
        bias,
        inconsistency,
        log_likelihood,
        iterations,
        converged,
    }
}
