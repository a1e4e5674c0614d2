//! SUREAL's full model, MLE (`sureal` 0.9.0's `MaximumLikelihoodEstimationModel`): MLE_CO
//! ([`super::sureal`]) plus an ambiguity a_c per content (here: per scene configuration),
//!
//! X_es = x_e + B_es + A_es,  B_es ~ N(b_s, v_s²),  A_es ~ N(0, a_c(e)²),
//!
//! so a score's variance is v_s² + a_c². Fitted by SUREAL's damped iteration (b, v, a, x in
//! turn, refresh rate 0.1, from x = MOS, b = 0, v_s and a_c the population standard deviations
//! of the residuals from the MOS per subject and per content).
//!
//! Only what depends on the sums v_s² + a_c² is returned: quality, bias and their standard
//! errors (1/√Σ_s 1/(v_s² + a_c²) and 1/√Σ_e 1/(v_s² + a_c²), SUREAL's). Moving a constant from
//! every a_c² to every v_s² leaves the likelihood unchanged, so SUREAL's own v_s and a_c are one
//! point of a ridge of equal likelihood, chosen by where its iteration stops; they are not
//! reported.

use super::sureal::{DELTA, Degenerate, Observation};

const REFRESH_RATE: f64 = 0.1;
const MAX_ITERATIONS: usize = 10_000;
/// A score variance v_s² + a_c² below this fraction of the squared spread counts as gone to 0.
const DEGENERATE_FRACTION: f64 = 1e-12;

/// The full model's identifiable part.
#[derive(Debug, Clone, PartialEq)]
pub struct FullFit {
    pub quality: Vec<f64>,
    pub quality_se: Vec<f64>,
    pub bias: Vec<f64>,
    pub bias_se: Vec<f64>,
    pub iterations: usize,
    pub converged: bool,
}

/// The data of a fit: stimuli, subjects, the content of each stimulus, the ratings.
#[derive(Debug, Clone, Copy)]
pub struct FullData<'a> {
    pub stimuli: usize,
    pub subjects: usize,
    /// Content index (scene configuration) of each stimulus.
    pub content: &'a [usize],
    pub observations: &'a [Observation],
}

/// Fits the full model (every stimulus and subject with a rating, each subject with two).
pub fn fit_full(data: FullData<'_>) -> Result<FullFit, Degenerate> {
    let FullData { stimuli, subjects, content, observations } = data;
    let contents = content.iter().max().map_or(0, |c| c + 1);
    let mut per_stimulus = vec![0usize; stimuli];
    let mut per_subject = vec![0usize; subjects];
    for o in observations {
        per_stimulus[o.stimulus] += 1;
        per_subject[o.subject] += 1;
    }
    if subjects < 2 || per_stimulus.contains(&0) || per_subject.iter().any(|&n| n < 2) {
        return Err(Degenerate::TooFew {
            message: "the model needs two participants, a rating of every stimulus and two of every participant".into(),
        });
    }
    let (low, high) = observations
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), o| (low.min(o.score), high.max(o.score)));
    let floor = DEGENERATE_FRACTION * (high - low).max(1.0).powi(2);

    let mut x = vec![0.0; stimuli];
    for o in observations {
        x[o.stimulus] += o.score;
    }
    for (value, &n) in x.iter_mut().zip(&per_stimulus) {
        *value /= n as f64;
    }
    let spread = |group: &dyn Fn(&Observation) -> usize, groups: usize| {
        let mut n = vec![0.0; groups];
        let mut sum = vec![0.0; groups];
        let mut sum2 = vec![0.0; groups];
        for o in observations {
            let r = o.score - x[o.stimulus];
            let g = group(o);
            n[g] += 1.0;
            sum[g] += r;
            sum2[g] += r * r;
        }
        (0..groups)
            .map(|g| if n[g] > 0.0 { (sum2[g] / n[g] - (sum[g] / n[g]).powi(2)).max(0.0).sqrt() } else { 0.0 })
            .collect::<Vec<f64>>()
    };
    let mut v = spread(&|o| o.subject, subjects);
    let mut a = spread(&|o| content[o.stimulus], contents);
    let mut b = vec![0.0; subjects];
    let mut iterations = 0;
    let mut converged = false;
    while iterations < MAX_ITERATIONS {
        let previous = x.clone();
        // b_s
        let (mut numerator, mut denominator) = (vec![0.0; subjects], vec![0.0; subjects]);
        for o in observations {
            let s2 = v[o.subject].powi(2) + a[content[o.stimulus]].powi(2);
            numerator[o.subject] += (o.score - x[o.stimulus]) / s2;
            denominator[o.subject] += 1.0 / s2;
        }
        for s in 0..subjects {
            b[s] = b[s] * (1.0 - REFRESH_RATE) + numerator[s] / denominator[s] * REFRESH_RATE;
        }
        // v_s: SUREAL's Newton step
        let (mut first, mut second) = (vec![0.0; subjects], vec![0.0; subjects]);
        for o in observations {
            let (vs, ac) = (v[o.subject], a[content[o.stimulus]]);
            let r = o.score - x[o.stimulus] - b[o.subject];
            let (sum2, difference2) = (vs * vs + ac * ac, vs * vs - ac * ac);
            first[o.subject] += -vs / sum2 + vs * r * r / (sum2 * sum2);
            let poly = ac.powi(4) - 3.0 * vs.powi(4) - 2.0 * vs * vs * ac * ac;
            second[o.subject] += difference2 / (sum2 * sum2) + r * r * poly / sum2.powi(4);
        }
        for s in 0..subjects {
            let update = v[s] - first[s] / second[s];
            v[s] = (v[s] * (1.0 - REFRESH_RATE) + update * REFRESH_RATE).max(0.0);
        }
        // a_c
        let (mut first, mut second) = (vec![0.0; contents], vec![0.0; contents]);
        for o in observations {
            let c = content[o.stimulus];
            let (vs, ac) = (v[o.subject], a[c]);
            let r = o.score - x[o.stimulus] - b[o.subject];
            let (sum2, difference2) = (vs * vs + ac * ac, vs * vs - ac * ac);
            first[c] += -ac / sum2 + ac * r * r / (sum2 * sum2);
            let poly = vs.powi(4) - 3.0 * ac.powi(4) - 2.0 * vs * vs * ac * ac;
            second[c] += -difference2 / (sum2 * sum2) + r * r * poly / sum2.powi(4);
        }
        for c in 0..contents {
            if second[c] != 0.0 {
                let update = a[c] - first[c] / second[c];
                a[c] = (a[c] * (1.0 - REFRESH_RATE) + update * REFRESH_RATE).max(0.0);
            }
        }
        // x_e
        let (mut numerator, mut denominator) = (vec![0.0; stimuli], vec![0.0; stimuli]);
        for o in observations {
            let s2 = v[o.subject].powi(2) + a[content[o.stimulus]].powi(2);
            if !(s2 >= floor) {
                return Err(Degenerate::Unbounded { subject: o.subject, iterations: iterations + 1 });
            }
            numerator[o.stimulus] += (o.score - b[o.subject]) / s2;
            denominator[o.stimulus] += 1.0 / s2;
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
    let (mut information_x, mut information_b) = (vec![0.0; stimuli], vec![0.0; subjects]);
    for o in observations {
        let s2 = v[o.subject].powi(2) + a[content[o.stimulus]].powi(2);
        information_x[o.stimulus] += 1.0 / s2;
        information_b[o.subject] += 1.0 / s2;
    }
    Ok(FullFit {
        quality: x.iter().map(|value| value + mean_bias).collect(),
        quality_se: information_x.iter().map(|i| 1.0 / i.sqrt()).collect(),
        bias: b.iter().map(|value| value - mean_bias).collect(),
        bias_se: information_b.iter().map(|i| 1.0 / i.sqrt()).collect(),
        iterations,
        converged,
    })
}
