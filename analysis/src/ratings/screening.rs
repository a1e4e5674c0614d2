//! P.910's crowdsourcing screening (ITU-T P.910 (2021/2022), the crowdsourcing annex, as the
//! microsoft/P.910 toolkit applies it in `src/result_parser.py` with its shipped
//! `result_parser_template.cfg`):
//!
//! - **golden questions**: a `catch` row is answered correctly when the rating is within
//!   [`GOLDEN_TOLERANCE`] of `expected` (the toolkit's `[gold_question] variance: 1`); a
//!   participant with any golden question answered wrongly is screened
//!   (`gold_standard_bigger_equal: 1` per session);
//! - **straight-lining**: the sample variance of a participant's ratings (golden questions
//!   left out) below [`STRAIGHT_LINING_VARIANCE`] (`variance_bigger_equal: 0.15`) screens them;
//!   a participant with one rating is not judged (the toolkit counts its variance as 1);
//! - **outlier votes**: within one stimulus, a vote with |z| ≥ [`OUTLIER_Z`] (z from the
//!   stimulus' mean and population standard deviation, as `scipy.stats.zscore`) is left out
//!   (the toolkit's `outliers_z_score`); a stimulus with one vote or votes all equal has none.
//!   Outlier votes do not screen a participant; they are counted per participant.

/// A golden question's rating may be this far from the expected one.
pub const GOLDEN_TOLERANCE: u8 = 1;
/// A participant whose ratings vary less than this (sample variance) is straight-lining.
pub const STRAIGHT_LINING_VARIANCE: f64 = 0.15;
/// A vote this many standard deviations from its stimulus' mean is an outlier.
pub const OUTLIER_Z: f64 = 3.29;

/// Why a participant is screened, or not.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParticipantScreen {
    pub golden_answered: usize,
    pub golden_failed: usize,
    /// Sample variance of the ratings (golden questions left out); none with fewer than two.
    pub variance: Option<f64>,
    /// The reason, when screened.
    pub reason: Option<String>,
}

/// Screens one participant from their ratings (golden questions left out) and their golden
/// questions as (rating, expected).
pub fn screen_participant(ratings: &[u8], golden: &[(u8, u8)]) -> ParticipantScreen {
    let failed: Vec<&(u8, u8)> =
        golden.iter().filter(|(rating, expected)| rating.abs_diff(*expected) > GOLDEN_TOLERANCE).collect();
    let variance = (ratings.len() >= 2).then(|| {
        let n = ratings.len() as f64;
        let mean = ratings.iter().map(|&r| f64::from(r)).sum::<f64>() / n;
        ratings.iter().map(|&r| (f64::from(r) - mean).powi(2)).sum::<f64>() / (n - 1.0)
    });
    let mut reasons = Vec::new();
    if let Some((rating, expected)) = failed.first() {
        reasons.push(format!(
            "golden question: {} of {} answered more than {GOLDEN_TOLERANCE} from the expected rating (e.g. {rating} for {expected})",
            failed.len(),
            golden.len()
        ));
    }
    if let Some(variance) = variance.filter(|&v| v < STRAIGHT_LINING_VARIANCE) {
        reasons.push(if variance == 0.0 {
            format!("straight-lining: all {} ratings are the same", ratings.len())
        } else {
            format!("straight-lining: rating variance {variance:.3} below {STRAIGHT_LINING_VARIANCE}")
        });
    }
    ParticipantScreen {
        golden_answered: golden.len(),
        golden_failed: failed.len(),
        variance,
        reason: (!reasons.is_empty()).then(|| reasons.join("; ")),
    }
}

/// Which of one stimulus' votes are outliers (|z| ≥ [`OUTLIER_Z`]).
pub fn outlier_votes(votes: &[f64]) -> Vec<bool> {
    let n = votes.len() as f64;
    if votes.len() < 2 {
        return vec![false; votes.len()];
    }
    let mean = votes.iter().sum::<f64>() / n;
    let sd = (votes.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    if sd == 0.0 {
        return vec![false; votes.len()];
    }
    votes.iter().map(|v| ((v - mean) / sd).abs() >= OUTLIER_Z).collect()
}
