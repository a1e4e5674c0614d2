//! A rating study's design, as the survey's [`Study`](super::survey::Study) keeps it
//! (`Study::rating`): the ITU-T P.910 method (ACR, DCR, ACR-HR), its 5-point scale with the
//! standard labels, the presentation (display time, grey interval, voting after the stimulus),
//! repetitions and catch trials. Apart from [`rating`](super::rating), which reads the
//! `[rating]` table and builds on the survey's study, so that the survey's model can hold this
//! one without a module cycle.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// The rating method, as ITU-T P.910 (2023) names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Absolute category rating: one stimulus at a time, rated on the quality scale.
    Acr,
    /// Degradation category rating (BT.500's DSIS): the reference (the scene configuration's
    /// ground truth), then the stimulus, rated on the impairment scale.
    Dcr,
    /// ACR with hidden reference: ACR in which each scene configuration's ground truth is rated
    /// as one more stimulus (condition `ground-truth`), for differential scores.
    AcrHr,
}

impl Method {
    /// The method as the study file and the export write it.
    pub fn name(self) -> &'static str {
        match self {
            Method::Acr => "acr",
            Method::Dcr => "dcr",
            Method::AcrHr => "acr-hr",
        }
    }

    /// The method a study file names, if it is one.
    pub fn parse(name: &str) -> Option<Method> {
        match name {
            "acr" => Some(Method::Acr),
            "dcr" => Some(Method::Dcr),
            "acr-hr" => Some(Method::AcrHr),
            _ => None,
        }
    }

    /// The scale the method rates on.
    pub fn scale(self) -> RatingScale {
        match self {
            Method::Acr | Method::AcrHr => RatingScale::Quality,
            Method::Dcr => RatingScale::Impairment,
        }
    }

    /// The export's `reference`: `ground-truth` for DCR (the reference shown) and ACR-HR (the
    /// hidden reference rated), empty for ACR.
    pub fn reference(self) -> &'static str {
        match self {
            Method::Acr => "",
            Method::Dcr | Method::AcrHr => super::GROUND_TRUTH,
        }
    }
}

/// A 5-point scale: ratings 5 (best) to 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RatingScale {
    /// P.910's ACR scale: Excellent, Good, Fair, Poor, Bad.
    Quality,
    /// P.910's DCR (impairment) scale: Imperceptible … Very annoying.
    Impairment,
}

impl RatingScale {
    pub fn name(self) -> &'static str {
        match self {
            RatingScale::Quality => "quality",
            RatingScale::Impairment => "impairment",
        }
    }

    /// The standard labels, index 0 for rating 5 down to index 4 for rating 1.
    pub fn labels(self) -> [&'static str; 5] {
        match self {
            RatingScale::Quality => ["Excellent", "Good", "Fair", "Poor", "Bad"],
            RatingScale::Impairment => {
                ["Imperceptible", "Perceptible but not annoying", "Slightly annoying", "Annoying", "Very annoying"]
            }
        }
    }
}

/// How a DCR trial shows the reference and the stimulus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// The reference, a grey interval, then the stimulus (P.910's DCR presentation).
    #[default]
    Sequential,
    /// The reference and the stimulus side by side, reference on the left (P.910 allows this for
    /// still pictures).
    SideBySide,
}

/// P.910's presentation rules a study can set.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Presentation {
    /// How long the stimulus (and in sequential DCR the reference) is shown, in ms; 0: until the
    /// vote (the image stays).
    pub stimulus_ms: u32,
    /// Sequential DCR: the mid-grey interval between the reference and the stimulus, in ms.
    pub grey_ms: u32,
    /// The rating buttons are offered only once the stimulus has disappeared (P.910's voting
    /// after the presentation); needs `stimulus_ms` > 0.
    pub vote_after: bool,
    /// DCR only: sequential or side by side.
    pub layout: Layout,
}

/// Where a catch trial's image comes from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CatchSource {
    /// An image file (e.g. an obviously broken stimulus); in DCR shown after `reference`.
    Image { image: PathBuf, reference: Option<PathBuf> },
    /// The ground truth of scene configuration `scene` (index into the study's scenes); in DCR
    /// shown after itself, so its expected rating is 5, Imperceptible.
    GroundTruth { scene: usize },
}

/// A catch (golden) trial: a stimulus whose expected rating is known.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RatingCatch {
    pub name: String,
    pub source: CatchSource,
    /// The expected rating, 1 to 5; an answer more than one category away fails the catch
    /// trial ([`CATCH_TOLERANCE`]).
    pub expected: u8,
    pub repetitions: u32,
}

/// A rating catch trial fails when the rating is more than this many categories from the
/// expected one (so an expected 5 accepts 4 and 5), as the gold questions of crowdsourced
/// P.808/P.910 tests.
pub const CATCH_TOLERANCE: u8 = 1;

/// A checked `[rating]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RatingDesign {
    pub method: Method,
    /// Times each stimulus (scene configuration × condition, and the hidden reference in
    /// ACR-HR) is rated by each participant.
    pub repetitions: u32,
    pub presentation: Presentation,
    #[serde(default)]
    pub catch: Vec<RatingCatch>,
}

impl RatingDesign {
    /// Trials per participant: every stimulus `repetitions` times (in ACR-HR each scene
    /// configuration's ground truth too), plus the catch trials.
    pub fn trial_count(&self, scenes: usize, conditions: usize) -> usize {
        let hidden = usize::from(self.method == Method::AcrHr);
        scenes * (conditions + hidden) * self.repetitions as usize
            + self.catch.iter().map(|catch| catch.repetitions as usize).sum::<usize>()
    }
}

impl RatingDesign {
    /// Refuses a catch trial's image file that is not inside `folder` once `..` and symbolic
    /// links are followed (as `Study::check_images_inside` does for the others).
    pub(crate) fn check_images_inside(
        &self,
        fail: super::checks::Fail,
        folder: &std::path::Path,
    ) -> Result<(), super::StudyError> {
        for (index, catch) in self.catch.iter().enumerate() {
            if let CatchSource::Image { image, reference } = &catch.source {
                super::checks::check_inside(fail, &format!("rating.catch[{index}].image"), image, folder)?;
                if let Some(reference) = reference {
                    super::checks::check_inside(fail, &format!("rating.catch[{index}].reference"), reference, folder)?;
                }
            }
        }
        Ok(())
    }
}
