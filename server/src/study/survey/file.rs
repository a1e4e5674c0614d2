//! The raw shape of a web-survey study file, as TOML gives it (unknown keys refused): the
//! `*File` structs, before [`check`](super::check) resolves them into a [`Study`](super::Study).

use std::collections::BTreeMap;

use mrstudy_renderer::stimulus::FactorLevel;
use serde::Deserialize;

use super::model::{
    Completion, DemographicField, Device, Display, Factor, Orientation, RenderDefaults, StudyKind,
    default_abandon_after_minutes, default_answer_lock_ms, default_min_response_ms, default_true,
};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct StudyFile {
    pub(super) slug: String,
    pub(super) title: String,
    pub(super) kind: StudyKind,
    pub(super) question: String,
    #[serde(default = "default_true")]
    pub(super) open: bool,
    pub(super) texts: TextsFile,
    #[serde(default)]
    pub(super) demographics: Vec<DemographicField>,
    /// `None` when the file does not declare them: [`default_url_params`] are kept then.
    #[serde(default)]
    pub(super) url_params: Option<Vec<String>>,
    pub(super) factors: Vec<Factor>,
    pub(super) conditions: Vec<ConditionFile>,
    #[serde(default)]
    pub(super) render: Option<RenderDefaults>,
    pub(super) scenes: Vec<SceneFile>,
    pub(super) design: DesignFile,
    #[serde(default)]
    pub(super) catch: Vec<CatchFile>,
    #[serde(default)]
    pub(super) completion: Completion,
    #[serde(default = "default_min_response_ms")]
    pub(super) min_response_ms: i64,
    #[serde(default = "default_answer_lock_ms")]
    pub(super) answer_lock_ms: i64,
    #[serde(default)]
    pub(super) unique_external_id: bool,
    /// A third answer, "not sure", in paired comparisons (stored as `tie`).
    #[serde(default)]
    pub(super) allow_tie: bool,
    #[serde(default)]
    pub(super) min_viewport: Option<[u32; 2]>,
    #[serde(default)]
    pub(super) devices: Option<Vec<Device>>,
    #[serde(default)]
    pub(super) orientation: Option<Orientation>,
    #[serde(default)]
    pub(super) display: Display,
    #[serde(default = "default_abandon_after_minutes")]
    pub(super) abandon_after_minutes: u32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct TextsFile {
    pub(super) welcome: String,
    pub(super) consent: String,
    pub(super) instructions: String,
    #[serde(default = "default_thanks")]
    pub(super) thanks: String,
}

pub(super) fn default_thanks() -> String {
    "Thank you for taking part.".to_string()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ConditionFile {
    pub(super) name: String,
    pub(super) levels: BTreeMap<String, FactorLevel>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneFile {
    pub(super) name: String,
    #[serde(default)]
    pub(super) description: String,
    /// Rendered: a scene file (relative to the study file) or a built-in scene name.
    #[serde(default)]
    pub(super) render: Option<String>,
    /// Image files: condition name → image path relative to the study file.
    #[serde(default)]
    pub(super) images: Option<BTreeMap<String, String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DesignFile {
    /// Required unless `reference` is given.
    #[serde(default)]
    pub(super) pairs: Option<String>,
    /// `"ground-truth"`: the detection design ("real or rendered?").
    #[serde(default)]
    pub(super) reference: Option<String>,
    /// Detection designs only: sensor-noise realisations per scene configuration (default 1).
    #[serde(default)]
    pub(super) realisations: Option<u32>,
    /// Detection designs only: what the reference image is, in words for the participant pages
    /// and the admin (default: "a path-traced render of the whole scene").
    #[serde(default)]
    pub(super) reference_label: Option<String>,
    #[serde(default)]
    pub(super) anchors: Vec<String>,
    #[serde(default)]
    pub(super) list: Vec<Vec<String>>,
    /// Required for fixed designs; for `pairs = "active"` it repeats the warm-up (default 1; with
    /// the default warm-up round(1.5 × trials / pairs), `active::default_repetitions`).
    #[serde(default)]
    pub(super) repetitions: Option<u32>,
    pub(super) scenes: String,
    #[serde(default)]
    pub(super) seed: Option<u64>,
    // `pairs = "active"` only:
    #[serde(default)]
    pub(super) trials: Option<u32>,
    #[serde(default)]
    pub(super) batch: Option<u32>,
    #[serde(default)]
    pub(super) target: Option<String>,
    #[serde(default)]
    pub(super) warmup: Option<String>,
    #[serde(default)]
    pub(super) prior_sd: Option<f64>,
    /// `"fixed"` (default) or `"spread"` (`target = "worths"` only).
    #[serde(default)]
    pub(super) prior: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CatchFile {
    pub(super) name: String,
    pub(super) better: String,
    pub(super) worse: String,
    #[serde(default = "default_one")]
    pub(super) repetitions: u32,
}

pub(super) fn default_one() -> u32 {
    1
}
