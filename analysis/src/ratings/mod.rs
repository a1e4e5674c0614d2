//! The analysis of a rating study's export (`kind = "rating"`, issue 49 item 2): ITU-T P.910's
//! ACR, DCR and ACR-HR. In order:
//!
//! 1. [`parse`]: the rows (`participant,scene,condition,rating,method`, golden questions as
//!    `catch`/`expected`), pilots and excluded participants left out unless kept;
//! 2. [`screening`]: P.910's crowdsourcing rules per participant (golden questions,
//!    straight-lining); a screened participant's ratings are left out of everything below;
//! 3. [`mos`]: the scores (ratings; ACR-HR's differential viewer scores), P.910's outlier votes
//!    (|z| ≥ 3.29 within a stimulus) left out, and the MOS with its 95 % t-interval per
//!    stimulus (scene configuration × condition) and per condition;
//! 4. [`sureal`]: SUREAL's content-oblivious maximum-likelihood model MLE_CO on the same
//!    scores: quality per stimulus, bias and inconsistency per participant, standard errors;
//!    [`sureal_full`]: the full model's identifiable part (quality, bias) with an ambiguity per
//!    scene configuration.
//!
//! [`report`] prints it as a table and draws the MOS plot. JSON: the `ratings` section of the
//! Analysis JSON (docs/design.md).

pub mod mos;
pub mod parse;
pub mod report;
pub mod screening;
pub mod sureal;
pub mod sureal_full;
#[cfg(test)]
mod sureal_tests;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;

use serde::Serialize;

pub use parse::{Method, is_rating_csv};

use crate::error::Result;

/// What the rating analysis may leave in or out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RatingOptions {
    pub include_pilots: bool,
    pub include_excluded: bool,
    /// P.910's screening applied (screened participants and outlier votes left out); when
    /// false the rules are still reported.
    pub screening: bool,
}

impl Default for RatingOptions {
    fn default() -> Self {
        RatingOptions { include_pilots: false, include_excluded: false, screening: true }
    }
}

/// The JSON section `ratings`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RatingsAnalysis {
    pub method: Method,
    /// `quality` (ACR, ACR-HR: Excellent … Bad = 5 … 1) or `impairment` (DCR: Imperceptible …
    /// Very annoying = 5 … 1).
    pub scale: &'static str,
    /// `rating`, or `dv` for ACR-HR's differential viewer scores.
    pub scores: &'static str,
    /// Scores in the MOS and the model.
    pub ratings: usize,
    pub stimuli: Vec<StimulusRating>,
    pub conditions: Vec<ConditionRating>,
    pub participants: Vec<ParticipantRating>,
    pub model: ModelSummary,
    /// SUREAL's full model (with content ambiguity): its identifiable part.
    pub full_model: FullModel,
    pub warnings: Vec<String>,
}

/// One stimulus: a scene configuration under a condition.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StimulusRating {
    pub scene: String,
    pub condition: String,
    pub ratings: usize,
    pub mos: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mos_ci: Option<[f64; 2]>,
    /// MLE_CO's quality and its standard error; absent where the model has no estimate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality_se: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<&'static str>,
}

/// One condition over all its scene configurations.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConditionRating {
    pub condition: String,
    pub ratings: usize,
    pub mos: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mos_ci: Option<[f64; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<&'static str>,
}

/// One participant: MLE_CO's bias and inconsistency, P.910's screening.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParticipantRating {
    pub participant: String,
    /// Ratings given (golden questions left out).
    pub ratings: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias_se: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inconsistency: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inconsistency_se: Option<f64>,
    pub screened: bool,
    /// Why screened (with screening off: why it would be).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    pub golden_answered: usize,
    pub golden_failed: usize,
    /// Votes left out as outliers within their stimulus (|z| ≥ 3.29).
    pub outlier_votes: usize,
    /// Why the model has no bias and inconsistency for them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<&'static str>,
}

/// The MLE_CO fit as a whole.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelSummary {
    /// `MLE_CO`.
    pub name: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub log_likelihood: Option<f64>,
    pub iterations: usize,
    pub converged: bool,
    /// Why there is no estimate (too few ratings, an inconsistency gone to 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_estimable: Option<String>,
}

/// What the full model reports and why not more.
pub const FULL_MODEL: &str = "SUREAL's full model gives a score the variance v_s² + a_c² (inconsistency of the participant, ambiguity of the scene configuration); moving a constant from every a_c² to every v_s² leaves the likelihood unchanged, so inconsistency and ambiguity are not identifiable apart and are not reported; quality and bias depend only on the sums and are reported";

/// SUREAL's full model (`MLE`), its identifiable part: quality and bias with standard errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FullModel {
    /// `MLE`.
    pub name: &'static str,
    pub note: &'static str,
    pub iterations: usize,
    pub converged: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_estimable: Option<String>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub stimuli: Vec<FullStimulus>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub participants: Vec<FullParticipant>,
}

/// A stimulus' quality under the full model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FullStimulus {
    pub scene: String,
    pub condition: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality_se: Option<f64>,
}

/// A participant's bias under the full model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FullParticipant {
    pub participant: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias_se: Option<f64>,
}

/// Analyses a rating export's text (`name` for messages).
pub fn analyze_rating_csv(text: &str, name: &str, options: RatingOptions) -> Result<RatingsAnalysis> {
    let parsed = parse::parse(text, name, options.include_pilots, options.include_excluded)?;
    let mut warnings = Vec::new();
    if parsed.pilots + parsed.excluded > 0 {
        warnings.push(format!(
            "left out {} pilot and {} excluded participant(s) (--include-pilots, --include-excluded keep them)",
            parsed.pilots, parsed.excluded
        ));
    }
    // 2. screening, per participant
    let mut by_participant: BTreeMap<&str, (Vec<u8>, Vec<(u8, u8)>)> = BTreeMap::new();
    for row in &parsed.rows {
        let entry = by_participant.entry(&row.participant).or_default();
        match row.expected {
            Some(expected) => entry.1.push((row.rating, expected)),
            None => entry.0.push(row.rating),
        }
    }
    let screens: BTreeMap<&str, screening::ParticipantScreen> = by_participant
        .iter()
        .map(|(participant, (ratings, golden))| (*participant, screening::screen_participant(ratings, golden)))
        .collect();
    let kept = |participant: &str| !options.screening || screens[participant].reason.is_none();
    if !options.screening {
        warnings.push(
            "screening is off (--screen off): P.910's rules are reported but nobody and no vote is left out".into(),
        );
    }
    // 3. scores, outlier votes, MOS
    let data: Vec<&parse::Row> =
        parsed.rows.iter().filter(|row| row.expected.is_none() && kept(&row.participant)).collect();
    let (mut scores, no_reference) = mos::scores(parsed.method, &data);
    if no_reference > 0 {
        warnings.push(format!(
            "{no_reference} rating(s) left out: ACR-HR needs the same participant's rating of the hidden reference in the same scene configuration"
        ));
    }
    let mut outliers: BTreeMap<String, usize> = BTreeMap::new();
    if options.screening {
        let mut by_stimulus: BTreeMap<(&str, &str), Vec<usize>> = BTreeMap::new();
        for (index, score) in scores.iter().enumerate() {
            by_stimulus.entry((&score.scene, &score.condition)).or_default().push(index);
        }
        let mut drop = vec![false; scores.len()];
        for indices in by_stimulus.values() {
            let votes: Vec<f64> = indices.iter().map(|&i| scores[i].score).collect();
            for (&index, outlier) in indices.iter().zip(screening::outlier_votes(&votes)) {
                drop[index] = outlier;
            }
        }
        let mut keep = drop.iter().map(|d| !d);
        for (score, dropped) in scores.iter().zip(&drop) {
            if *dropped {
                *outliers.entry(score.participant.clone()).or_default() += 1;
            }
        }
        scores.retain(|_| keep.next().unwrap_or(true));
        let total: usize = outliers.values().sum();
        if total > 0 {
            warnings.push(format!("{total} outlier vote(s) (|z| ≥ 3.29 within their stimulus) left out"));
        }
    }
    if scores.is_empty() {
        return Err(crate::error::AnalysisError::Empty(format!(
            "{name}: no rating is left to analyse ({} participant(s) screened, golden questions are not data)",
            screens.values().filter(|s| s.reason.is_some()).count()
        )));
    }
    let analysis = summarise(&scores);
    let model = fit_model(&scores);
    if model.summary.not_estimable.is_none() && !model.summary.converged {
        warnings.push(format!(
            "MLE_CO did not converge in {} iterations: its estimates are those of the last step",
            model.summary.iterations
        ));
    }
    let participants = by_participant
        .iter()
        .map(|(participant, (ratings, _))| {
            let screen = &screens[participant];
            let fitted = model.subjects.get(*participant).copied();
            let note = match (fitted, kept(participant)) {
                (Some(_), _) => None,
                (None, false) => Some("screened: not in the model"),
                (None, true) if model.summary.not_estimable.is_some() => Some("the model has no estimate"),
                (None, true) => Some("fewer than two scores: not in the model"),
            };
            ParticipantRating {
                participant: participant.to_string(),
                ratings: ratings.len(),
                bias: fitted.and_then(|f| finite(f[0])),
                bias_se: fitted.and_then(|f| finite(f[1])),
                inconsistency: fitted.and_then(|f| finite(f[2])),
                inconsistency_se: fitted.and_then(|f| finite(f[3])),
                screened: options.screening && screen.reason.is_some(),
                reason: screen.reason.clone(),
                golden_answered: screen.golden_answered,
                golden_failed: screen.golden_failed,
                outlier_votes: outliers.get(*participant).copied().unwrap_or(0),
                note,
            }
        })
        .collect();
    let stimuli = analysis
        .0
        .into_iter()
        .map(|mut stimulus| {
            if let Some(&(quality, se)) = model.stimuli.get(&(stimulus.scene.clone(), stimulus.condition.clone())) {
                stimulus.quality = finite(quality);
                stimulus.quality_se = finite(se);
            }
            stimulus
        })
        .collect();
    Ok(RatingsAnalysis {
        method: parsed.method,
        scale: parsed.method.scale(),
        scores: if parsed.method == Method::AcrHr { "dv" } else { "rating" },
        ratings: scores.len(),
        stimuli,
        conditions: analysis.1,
        participants,
        model: model.summary,
        full_model: model.full,
        warnings,
    })
}

/// A value for the JSON: never NaN or infinity (a standard error of a fit stopped before
/// converging can be).
fn finite(value: f64) -> Option<f64> {
    value.is_finite().then_some(value)
}

const ONE_SCORE: &str = "one score: no interval";

/// MOS per stimulus and per condition.
fn summarise(scores: &[mos::Score]) -> (Vec<StimulusRating>, Vec<ConditionRating>) {
    let mut by_stimulus: BTreeMap<(&str, &str), Vec<f64>> = BTreeMap::new();
    let mut by_condition: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for score in scores {
        by_stimulus.entry((&score.scene, &score.condition)).or_default().push(score.score);
        by_condition.entry(&score.condition).or_default().push(score.score);
    }
    let stimuli = by_stimulus
        .into_iter()
        .map(|((scene, condition), values)| {
            let m = mos::mos(&values);
            StimulusRating {
                scene: scene.to_string(),
                condition: condition.to_string(),
                ratings: m.n,
                mos: m.mean,
                mos_ci: m.ci,
                quality: None,
                quality_se: None,
                note: m.ci.is_none().then_some(ONE_SCORE),
            }
        })
        .collect();
    let conditions = by_condition
        .into_iter()
        .map(|(condition, values)| {
            let m = mos::mos(&values);
            ConditionRating {
                condition: condition.to_string(),
                ratings: m.n,
                mos: m.mean,
                mos_ci: m.ci,
                note: m.ci.is_none().then_some(ONE_SCORE),
            }
        })
        .collect();
    (stimuli, conditions)
}

/// MLE_CO's estimates keyed by name.
struct Model {
    summary: ModelSummary,
    /// (scene, condition) → (quality, se).
    stimuli: BTreeMap<(String, String), (f64, f64)>,
    /// participant → [bias, bias_se, inconsistency, inconsistency_se].
    subjects: BTreeMap<String, [f64; 4]>,
    full: FullModel,
}

/// Fits MLE_CO to the scores of participants with at least two.
fn fit_model(scores: &[mos::Score]) -> Model {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for score in scores {
        *counts.entry(&score.participant).or_default() += 1;
    }
    let subjects: Vec<&str> = counts.iter().filter(|&(_, &n)| n >= 2).map(|(p, _)| *p).collect();
    let subject_index: BTreeMap<&str, usize> = subjects.iter().enumerate().map(|(i, p)| (*p, i)).collect();
    let mut stimulus_index: BTreeMap<(&str, &str), usize> = BTreeMap::new();
    let mut observations = Vec::new();
    for score in scores {
        let Some(&subject) = subject_index.get(score.participant.as_str()) else { continue };
        let next = stimulus_index.len();
        let stimulus = *stimulus_index.entry((&score.scene, &score.condition)).or_insert(next);
        observations.push(sureal::Observation { stimulus, subject, score: score.score });
    }
    let mut model = Model {
        summary: ModelSummary {
            name: "MLE_CO",
            log_likelihood: None,
            iterations: 0,
            converged: false,
            not_estimable: None,
        },
        stimuli: BTreeMap::new(),
        subjects: BTreeMap::new(),
        full: FullModel {
            name: "MLE",
            note: FULL_MODEL,
            iterations: 0,
            converged: false,
            not_estimable: None,
            stimuli: Vec::new(),
            participants: Vec::new(),
        },
    };
    match sureal::fit_content_oblivious(stimulus_index.len(), subjects.len(), &observations) {
        Ok(fit) => {
            model.summary.log_likelihood = finite(fit.log_likelihood);
            model.summary.iterations = fit.iterations;
            model.summary.converged = fit.converged;
            for ((scene, condition), &e) in &stimulus_index {
                model.stimuli.insert((scene.to_string(), condition.to_string()), (fit.quality[e], fit.quality_se[e]));
            }
            for (s, participant) in subjects.iter().enumerate() {
                model.subjects.insert(
                    participant.to_string(),
                    [fit.bias[s], fit.bias_se[s], fit.inconsistency[s], fit.inconsistency_se[s]],
                );
            }
        }
        Err(sureal::Degenerate::TooFew { message }) => {
            model.summary.not_estimable = Some(message);
        }
        Err(sureal::Degenerate::Unbounded { subject, iterations }) => {
            model.summary.iterations = iterations;
            model.summary.not_estimable = Some(format!(
                "participant {}'s inconsistency goes to 0 (after {iterations} iterations): the likelihood grows without bound, so MLE_CO has no estimate for these data",
                subjects[subject]
            ));
        }
    }
    // the full model: contents are the scene configurations
    let mut scenes: BTreeMap<&str, usize> = BTreeMap::new();
    let mut content = vec![0; stimulus_index.len()];
    for (&(scene, _), &e) in &stimulus_index {
        let next = scenes.len();
        content[e] = *scenes.entry(scene).or_insert(next);
    }
    let data = sureal_full::FullData {
        stimuli: stimulus_index.len(),
        subjects: subjects.len(),
        content: &content,
        observations: &observations,
    };
    match sureal_full::fit_full(data) {
        Ok(fit) => {
            model.full.iterations = fit.iterations;
            model.full.converged = fit.converged;
            model.full.stimuli = stimulus_index
                .iter()
                .map(|(&(scene, condition), &e)| FullStimulus {
                    scene: scene.to_string(),
                    condition: condition.to_string(),
                    quality: finite(fit.quality[e]),
                    quality_se: finite(fit.quality_se[e]),
                })
                .collect();
            model.full.participants = subjects
                .iter()
                .enumerate()
                .map(|(s, participant)| FullParticipant {
                    participant: participant.to_string(),
                    bias: finite(fit.bias[s]),
                    bias_se: finite(fit.bias_se[s]),
                })
                .collect();
        }
        Err(sureal::Degenerate::TooFew { message }) => model.full.not_estimable = Some(message),
        Err(sureal::Degenerate::Unbounded { subject, iterations }) => {
            model.full.iterations = iterations;
            model.full.not_estimable = Some(format!(
                "the score variance of participant {} goes to 0 (after {iterations} iterations): the likelihood grows without bound",
                subjects[subject]
            ));
        }
    }
    model
}
