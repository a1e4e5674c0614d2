//! Rating trials in the participant API (`kind = "rating"`): what `…/next` answers for one (the
//! stimulus, DCR's reference, the scale with its standard labels and the presentation rules the
//! page follows) and the check of a rating answer. Storing it is the paired comparisons' own
//! write ([`super::store::NewResponse`] with a [`Answer::Rating`]): durable before its 201, a
//! repeat of the same rating 200, another rating to an answered trial 409.

use serde::Serialize;

use crate::error::AppError;
use crate::study::Study;
use crate::study::rating::{Layout, RatingDesign};
use crate::trial::{Answer, Choice};

/// An image of a rating trial.
#[derive(Debug, Serialize)]
pub struct Shown {
    pub url: String,
    pub alt: String,
}

/// One point of the scale: the rating sent back and its label.
#[derive(Debug, Serialize)]
pub struct Point {
    pub rating: u8,
    pub label: &'static str,
}

/// The scale and the presentation rules of the study, as the page needs them.
#[derive(Debug, Serialize)]
pub struct Scale {
    pub method: &'static str,
    pub scale: &'static str,
    /// Best first: 5 down to 1.
    pub points: Vec<Point>,
    pub stimulus_ms: u32,
    pub grey_ms: u32,
    pub vote_after: bool,
    pub layout: Layout,
}

/// `…/next` for a rating trial.
#[derive(Debug, Serialize)]
pub struct RatingTrial {
    pub trial: i64,
    pub total: i64,
    pub question: String,
    pub rating: Scale,
    pub stimulus: Shown,
    /// DCR: the reference, shown before the stimulus (or beside it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<Shown>,
    /// Stimulus URLs of the trial after this one, to preload.
    pub preload: Vec<String>,
}

/// The scale of a rating study.
pub fn scale(design: &RatingDesign) -> Scale {
    let scale = design.method.scale();
    Scale {
        method: design.method.name(),
        scale: scale.name(),
        points: scale.labels().iter().zip((1..=5u8).rev()).map(|(&label, rating)| Point { rating, label }).collect(),
        stimulus_ms: design.presentation.stimulus_ms,
        grey_ms: design.presentation.grey_ms,
        vote_after: design.presentation.vote_after,
        layout: design.presentation.layout,
    }
}

/// The stored trial `number` (its stimulus file on the left, DCR's reference on the right, empty
/// without one) as the page shows it.
pub fn trial(
    study: &Study,
    design: &RatingDesign,
    stored: (i64, i64),
    stimulus: &str,
    reference: &str,
    preload: Vec<String>,
) -> RatingTrial {
    let (number, total) = stored;
    RatingTrial {
        trial: number,
        total,
        question: study.question.clone(),
        rating: scale(design),
        stimulus: Shown { url: super::stimulus_url(stimulus), alt: format!("The image to rate in trial {number}") },
        reference: (!reference.is_empty()).then(|| Shown {
            url: super::stimulus_url(reference),
            alt: format!("The reference image of trial {number}"),
        }),
        preload,
    }
}

/// The answer a response body gives, checked against the study: a rating study takes `rating`
/// (1 to 5) and no `chosen`; any other takes `chosen` and no `rating`.
pub fn answer(study: Option<&Study>, chosen: Option<Choice>, rating: Option<i64>) -> Result<Answer, AppError> {
    let rates = study.is_some_and(|study| study.rating.is_some());
    match (rates, chosen, rating) {
        (true, None, Some(rating)) if (1..=5).contains(&rating) => Ok(Answer::Rating(rating as u8)),
        (true, None, Some(rating)) => {
            Err(AppError::Unprocessable(format!("`rating` must be a whole number from 1 to 5, found {rating}.")))
        }
        (true, _, _) => Err(AppError::Unprocessable(
            "This is a rating study: the answer is `rating`, a whole number from 1 to 5, and no `chosen`.".into(),
        )),
        (false, Some(chosen), None) => Ok(Answer::Choice(chosen)),
        (false, _, Some(_)) => {
            Err(AppError::Unprocessable("This study asks for `chosen` (\"left\" or \"right\"), not a `rating`.".into()))
        }
        (false, None, None) => Err(AppError::Unprocessable("`chosen` is missing: \"left\" or \"right\".".into())),
    }
}
