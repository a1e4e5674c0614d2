//! The resolved web-survey study ([`Study`]) and its parts, as everything after loading uses
//! them. [`Study`] is also the schema of the definition stored in the database: serialised when
//! the study is recorded, read back by the export and the admin pages. Keys added after the
//! first stored definitions have serde defaults, so older databases still read.

use std::path::PathBuf;

use mrstudy_renderer::stimulus::Factors;
use serde::{Deserialize, Serialize};

/// What kind of study a file describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StudyKind {
    /// Forced-choice paired comparisons on the web.
    PairedComparison,
    /// Timed task trials in the lab against the live renderer (not served by the web survey).
    Task,
    /// How much of a rendering knob is enough: each trial a level beside the ground truth, the
    /// level chosen by QUEST+ (`crate::study::threshold`).
    Threshold,
    /// Each stimulus rated on a 5-point scale (ITU-T P.910's ACR, DCR or ACR-HR;
    /// `crate::study::rating`).
    Rating,
}

impl StudyKind {
    pub fn as_str(self) -> &'static str {
        match self {
            StudyKind::PairedComparison => "paired-comparison",
            StudyKind::Task => "task",
            StudyKind::Threshold => "threshold",
            StudyKind::Rating => "rating",
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The raw file shape.

pub(super) fn default_min_response_ms() -> i64 {
    300
}

pub(super) fn default_answer_lock_ms() -> i64 {
    500
}

pub(super) fn default_abandon_after_minutes() -> u32 {
    30
}

/// A kind of device a participant may use (`devices = ["desktop"]`); told apart on the client by
/// its pointer and screen (see `web/static/survey.js`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    Desktop,
    Tablet,
    Phone,
}

impl Device {
    /// The device as a participant reads it ("a desktop or laptop computer").
    pub fn described(self) -> &'static str {
        match self {
            Device::Desktop => "a desktop or laptop computer",
            Device::Tablet => "a tablet",
            Device::Phone => "a phone",
        }
    }
}

/// The screen orientation a study requires.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    Landscape,
    Portrait,
}

/// How stimuli are scaled on screen: `native` never shows an image larger than one image pixel
/// per device pixel (CSS size = image size / devicePixelRatio at most, so no resampling upward; on
/// a screen of device pixel ratio 2 that is half the CSS size), `css` never larger than one image
/// pixel per CSS pixel (the same CSS size on every screen, enlarged by the browser on HiDPI
/// screens), `fit` scaled to the space available. All shrink to fit the window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Display {
    #[default]
    Native,
    Css,
    Fit,
}

/// Who may take part and how answers are checked: the response-time floor, one run per
/// external id, the screen requirements, and when an unfinished participant counts as abandoned.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default)]
pub struct Participation {
    /// Responses faster than this (client response time or server time since serving the trial)
    /// are stored and flagged `too_fast`; the page accepts no answer before it.
    pub min_response_ms: u32,
    /// After an answer (and after "Start") the page takes no press that begins sooner than this,
    /// nor one before the next pair is painted: the second click of a slow double click, or a
    /// double tap, never answers the next trial.
    pub answer_lock_ms: u32,
    /// `allow_tie`: paired comparisons offer a third answer, "not sure" (↓ or its button),
    /// stored and exported as `chosen = "tie"`; off by default (forced choice).
    pub allow_tie: bool,
    /// One run per value of the study's first URL parameter (its declared id, e.g.
    /// `PROLIFIC_PID`; never another), normalised: a second join with the same value resumes the
    /// first run only with that run's token, else it is refused.
    pub unique_external_id: bool,
    /// Smallest viewport in CSS pixels, `[width, height]`.
    pub min_viewport: Option<[u32; 2]>,
    /// Devices allowed (all when empty).
    pub devices: Vec<Device>,
    pub orientation: Option<Orientation>,
    pub display: Display,
    /// An unfinished participant with no activity for this long counts as abandoned.
    pub abandon_after_minutes: u32,
}

impl Default for Participation {
    /// The defaults of a study file that gives none of the keys.
    fn default() -> Self {
        Participation {
            min_response_ms: default_min_response_ms() as u32,
            answer_lock_ms: default_answer_lock_ms() as u32,
            allow_tie: false,
            unique_external_id: false,
            min_viewport: None,
            devices: Vec::new(),
            orientation: None,
            display: Display::Native,
            abandon_after_minutes: default_abandon_after_minutes(),
        }
    }
}

pub(super) fn default_true() -> bool {
    true
}

/// The URL parameters kept when a study file declares none: the crowdsourcing platforms' ids.
pub(super) fn default_url_params() -> Vec<String> {
    ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID", "workerId", "assignmentId", "hitId"]
        .iter()
        .map(|name| name.to_string())
        .collect()
}

/// The texts shown on the participant pages; blank lines separate paragraphs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Texts {
    pub welcome: String,
    pub consent: String,
    pub instructions: String,
    pub thanks: String,
}

/// One demographic question on the entry screen.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DemographicField {
    /// Column name in the export, `[a-z][a-z0-9_]*`.
    pub name: String,
    /// The question as shown.
    pub label: String,
    /// `choice`, `integer` or `text`.
    #[serde(rename = "type")]
    pub field_type: FieldType,
    /// For `choice`: the options, shown in this order.
    #[serde(default)]
    pub options: Vec<String>,
    /// For `integer`: the inclusive bounds.
    #[serde(default)]
    pub min: Option<i64>,
    #[serde(default)]
    pub max: Option<i64>,
    #[serde(default = "default_true")]
    pub required: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FieldType {
    Choice,
    Integer,
    Text,
}

/// A rendering feature that the study switches on or off, or (named levels) sets to one of
/// several methods.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Factor {
    pub name: String,
    #[serde(default)]
    pub label: String,
    /// The names of the levels, when the conditions name them (`gi = "dit"`) instead of giving
    /// numbers; the first is the reference level the others' effects are measured from. A study
    /// file may list them to choose the order; by default the names in the order the conditions
    /// first use them, with `off` first where a condition uses it. Empty: numeric levels.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub levels: Vec<String>,
}

impl Factor {
    /// The factor's columns in the design matrix: its name for numeric levels, else one
    /// indicator `<name>_<level>` per level after the reference (treatment coding; a `-` in
    /// the level's name becomes `_`: `gi_dit_high`).
    pub fn columns(&self) -> Vec<String> {
        if self.levels.is_empty() {
            vec![self.name.clone()]
        } else {
            self.levels[1..].iter().map(|level| format!("{}_{}", self.name, level.replace('-', "_"))).collect()
        }
    }
}

/// One combination of factor levels.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Condition {
    pub name: String,
    /// The condition's row of the design matrix: one value per column of
    /// [`Study::design_columns`] (a numeric factor's level; 0/1 indicators for a factor with
    /// named levels).
    pub levels: Vec<f64>,
    /// The levels as the renderer renders them, or why it cannot (a study whose stimuli are all
    /// image files may use levels the renderer has not). Not stored: a definition read back from
    /// the database has none.
    #[serde(skip, default = "unresolved")]
    pub factors: Result<Factors, String>,
    /// A threshold study's level: the knob value its stimuli are rendered with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub knob: Option<mrstudy_renderer::knob::KnobSetting>,
}

fn unresolved() -> Result<Factors, String> {
    Err("the condition was read back from the database, not resolved from a study file".into())
}

/// Defaults for scene configurations rendered by the renderer.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDefaults {
    /// Stimulus size in pixels, `[width, height]`.
    pub size: [u32; 2],
    /// Samples per pixel for path-traced parts, if the renderer needs them.
    #[serde(default)]
    pub spp: Option<u32>,
    /// Seed of the path-traced photograph (and its camera noise).
    #[serde(default)]
    pub seed: Option<u64>,
    /// VPL budget of the gi factor.
    #[serde(default)]
    pub vpls: Option<u32>,
}

/// Where the stimuli of one scene configuration come from.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StimulusSource {
    /// One image file per condition, index-aligned with [`Study::conditions`].
    Images(Vec<PathBuf>),
    /// A scene for the renderer: a built-in scene name, or a scene file's path (joined to the
    /// study file's folder).
    Render(String),
}

/// One scene configuration: an arrangement of real and virtual objects with one camera pose.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneConfiguration {
    pub name: String,
    pub description: String,
    pub source: StimulusSource,
}

/// What an active design learns about: every condition's log-worth, the factor effects, or
/// both together.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ActiveTarget {
    Worths,
    Factors,
    /// The log-worths and the factor effects: the summed posterior variance of each, relative
    /// to its current value (`mrstudy_analysis::active::both`).
    Both,
}

impl ActiveTarget {
    /// The study-file name (`effects`, also spelt `factors`) and what the design optimises, in words.
    pub fn describe(self) -> (&'static str, &'static str) {
        match self {
            ActiveTarget::Worths => ("worths", "every condition's log-worth"),
            ActiveTarget::Factors => ("effects", "the factor effects (not the individual log-worths)"),
            ActiveTarget::Both => ("both", "the log-worths and the factor effects together"),
        }
    }

    /// How the pairs are chosen, in words: the criterion and what it is about.
    pub fn criterion(self) -> String {
        match self {
            ActiveTarget::Worths | ActiveTarget::Factors => {
                // (no "inf" in these words: tests look for it as a sign of a non-finite number)
                format!("by the expected drop of the posterior entropy of {} (EIG)", self.describe().1)
            }
            ActiveTarget::Both => {
                "by the expected drop of the summed posterior variance of the log-worths and of the factor \
                 effects, each relative to its current value (A-optimal for both)"
                    .to_string()
            }
        }
    }

    /// The `mrstudy simulate --designs` name that measures this target against the fixed design.
    pub fn simulate_design(self) -> &'static str {
        match self {
            ActiveTarget::Worths => "active-worths",
            ActiveTarget::Factors => "active",
            ActiveTarget::Both => "active-both",
        }
    }
}

/// `pairs = "active"`: after an optional warm-up of a fixed design ([`Design::pairs`] ×
/// [`Design::repetitions`], empty without one), each participant's trials are chosen `batch`
/// at a time by the expected information gain about the target, from every judgment so far
/// (`mrstudy_analysis::active`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ActiveDesign {
    /// Trials chosen by the posterior per participant (after the warm-up).
    pub trials: u32,
    /// Trials chosen at a time for one participant.
    pub batch: u32,
    pub target: ActiveTarget,
    /// Prior standard deviation of each log-worth or factor effect (logit scale); with
    /// `prior = "spread"` the prior mean of the log-worths' spread.
    pub prior_sd: f64,
    /// `prior`: a fixed prior sd (the default) or the hierarchical prior on the log-worths'
    /// spread (`target = "worths"` only). Absent in definitions stored before it existed.
    #[serde(default)]
    pub prior: ActivePrior,
}

impl ActiveDesign {
    /// How the pairs are chosen, in words: the target's criterion, and the prior it is scored
    /// under where that is the spread prior.
    pub fn criterion(&self) -> String {
        match self.prior {
            ActivePrior::Fixed => self.target.criterion(),
            ActivePrior::Spread => format!(
                "{} under a hierarchical prior on their spread (prior = \"spread\", the spread's prior mean {}) for \
                 the study's first {} trials per condition (all participants together), then as with the fixed prior",
                self.target.criterion(),
                format_number(self.prior_sd),
                format_number(mrstudy_analysis::active::SPREAD_SWITCH)
            ),
        }
    }

    /// What the design optimises, in words.
    pub fn optimises(&self) -> String {
        match self.prior {
            ActivePrior::Fixed => self.target.describe().1.to_string(),
            ActivePrior::Spread => format!(
                "every condition's log-worth as the centred MAP estimate with prior sd {} (`log_worth_map` of \
                 `mrstudy analyze`), not the maximum-likelihood log-worths",
                format_number(self.prior_sd)
            ),
        }
    }

    /// The `mrstudy simulate --designs` name that measures this design against the fixed design.
    pub fn simulate_design(&self) -> &'static str {
        match self.prior {
            ActivePrior::Fixed => self.target.simulate_design(),
            ActivePrior::Spread => "active-spread",
        }
    }
}

/// The prior an active design scores its pairs under (`design.prior`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ActivePrior {
    /// Every log-worth (or factor effect) N(0, `prior_sd`²), the ADF posterior, the pair score
    /// EIG(ρ·m, v) with ρ ramped to ½ (`mrstudy_analysis::active`).
    #[default]
    Fixed,
    /// The log-worths' prior sd τ unknown, τ ~ Gamma(2, 2/`prior_sd`): pairs scored by the plain
    /// EIG on the moment-matched posterior mixture over τ
    /// (`mrstudy_analysis::active::Posterior::with_spread_prior`) for the first
    /// `SPREAD_SWITCH` = 15 trials per condition, then as [`ActivePrior::Fixed`] scores them
    /// (`Posterior::with_spread_switch`). Optimises the centred MAP
    /// log-worths with prior sd `prior_sd` (`mrstudy analyze`'s `log_worth_map`), not the
    /// analysis's maximum-likelihood log-worths (docs/simulate/README.md).
    Spread,
}

impl ActivePrior {
    /// The study-file name.
    pub fn name(self) -> &'static str {
        match self {
            ActivePrior::Fixed => "fixed",
            ActivePrior::Spread => "spread",
        }
    }
}

/// How scene configurations are drawn for the two sides of a trial.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SceneDraw {
    /// Two different scene configurations, so the images are never directly comparable.
    Different,
    /// The same scene configuration on both sides.
    Same,
}

/// The condition name of the ground-truth composite in a detection design's trials (and in
/// the export's `left`/`right`/`chosen` columns); no condition may take it.
pub const GROUND_TRUTH: &str = "ground-truth";

/// What a design pairs each condition with when it is not another condition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DesignReference {
    /// The path-traced ground-truth composite of the same scene configuration ("real or
    /// rendered?"): each trial shows a condition's stimulus beside it.
    GroundTruth,
}

/// The rule of a design's pairs: `design.pairs` (`all`, `anchored`, `list`, `active`), or
/// `ground-truth` for a detection design (`design.reference`). Serialised as that name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PairsRule {
    /// Every pair of conditions.
    All,
    /// Every anchor with every other anchor, then every other condition with each anchor.
    Anchored,
    /// The pairs the file lists.
    List,
    /// Chosen during the study by the posterior (after an optional fixed warm-up).
    Active,
    /// Each condition beside the ground truth ([`GROUND_TRUTH`]): a detection design.
    GroundTruth,
}

impl PairsRule {
    /// The name a study file and the stored definition give the rule.
    pub fn as_str(self) -> &'static str {
        match self {
            PairsRule::All => "all",
            PairsRule::Anchored => "anchored",
            PairsRule::List => "list",
            PairsRule::Active => "active",
            PairsRule::GroundTruth => GROUND_TRUTH,
        }
    }
}

/// The design: condition pairs (indices into [`Study::conditions`]), repetitions, scene draw.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Design {
    /// The rule that made [`Design::pairs`] (stored by its name, as the study file gives it).
    pub pairs_rule: PairsRule,
    /// The fixed design's pairs; for `active`, those of its warm-up (`warmup`, none by default).
    /// In a detection design each condition is paired with the index `conditions.len()`, which
    /// stands for the scene configuration's ground truth ([`GROUND_TRUTH`]).
    pub pairs: Vec<(usize, usize)>,
    pub repetitions: u32,
    pub scenes: SceneDraw,
    /// Study seed: when set, participant seeds are derived from it and the participant's
    /// ordinal, so a whole run of the study can be reproduced; when absent they are random.
    /// Either way each participant's seed is stored.
    pub seed: Option<u64>,
    /// Set for `pairs = "active"`.
    #[serde(default)]
    pub active: Option<ActiveDesign>,
    /// Set for `reference = "ground-truth"`.
    #[serde(default)]
    pub reference: Option<DesignReference>,
    /// Sensor-noise realisations of each scene configuration (1 unless a detection design asks
    /// for more): realisation k > 0 is the same path-traced radiance through the same simulated
    /// camera with another noise seed, with its own ground truth and its own stimuli rendered
    /// over its own photograph, so no ground-truth picture need be shown twice.
    #[serde(default = "default_realisations")]
    pub realisations: u32,
    /// What the reference of a detection design is, in words (`reference_label`): shown to
    /// researchers and available to the texts; never "a photograph" unless it is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_label: Option<String>,
}

fn default_realisations() -> u32 {
    1
}

/// The most sensor-noise realisations a detection design may ask for per scene configuration.
pub const MAX_REALISATIONS: u32 = 16;

/// A catch trial: a pair of images with a known answer (`better` should be chosen).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CatchTrial {
    pub name: String,
    pub better: PathBuf,
    pub worse: PathBuf,
    pub repetitions: u32,
}

/// The completion page: a fixed code (as crowdsourcing sites want), or a random code per
/// participant when absent, and an optional redirect URL. In `redirect`, `{code}` is replaced
/// by the completion code and `{NAME}` by the kept URL parameter `NAME`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Completion {
    #[serde(default)]
    pub code: Option<String>,
    #[serde(default)]
    pub redirect: Option<String>,
}

/// A checked study definition, resolved once from its file (and the schema of the definition
/// stored in the database).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Study {
    pub slug: String,
    pub title: String,
    pub kind: StudyKind,
    pub question: String,
    /// Whether the study accepts participants when it is first loaded (the admin can change it).
    pub open: bool,
    pub texts: Texts,
    #[serde(default)]
    pub demographics: Vec<DemographicField>,
    /// The URL parameters kept with a participant: the declared ones, else the platforms' ids.
    #[serde(default)]
    pub url_params: Vec<String>,
    /// Whether the study file declared `url_params`: then the trials CSV has a column for each,
    /// else only for those some exported participant arrived with (no empty MTurk columns for a
    /// study that never asked for them). `false` for definitions stored before this field.
    #[serde(default)]
    pub url_params_declared: bool,
    pub factors: Vec<Factor>,
    pub conditions: Vec<Condition>,
    pub render: Option<RenderDefaults>,
    pub scenes: Vec<SceneConfiguration>,
    pub design: Design,
    #[serde(default)]
    pub catch: Vec<CatchTrial>,
    #[serde(default)]
    pub completion: Completion,
    #[serde(default)]
    pub participation: Participation,
    /// The file it was read from.
    pub file: PathBuf,
    /// SHA-256 of the file's bytes, hex; stored with each participant.
    pub file_sha256: String,
    /// `kind = "threshold"`: the `[threshold]` table; the conditions are its levels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threshold: Option<crate::study::threshold_design::ThresholdDesign>,
    /// `kind = "rating"`: the `[rating]` table (method, presentation, repetitions, catch trials).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rating: Option<crate::study::rating_design::RatingDesign>,
}

impl Study {
    /// Trials per participant: pairs × repetitions (for an active design: its warm-up and its
    /// actively chosen trials), plus the catch trials.
    pub fn trial_count(&self) -> usize {
        if let Some(rating) = &self.rating {
            return rating.trial_count(self.scenes.len(), self.conditions.len());
        }
        if let Some(threshold) = &self.threshold {
            return threshold.trials as usize
                + self.catch.iter().map(|catch| catch.repetitions as usize).sum::<usize>();
        }
        self.design.pairs.len() * self.design.repetitions as usize
            + self.design.active.as_ref().map_or(0, |active| active.trials as usize)
            + self.catch.iter().map(|catch| catch.repetitions as usize).sum::<usize>()
    }

    /// The index of the condition called `name`.
    pub fn condition_index(&self, name: &str) -> Option<usize> {
        self.conditions.iter().position(|condition| condition.name == name)
    }

    /// Whether any stimulus must come from the renderer.
    pub fn needs_renderer(&self) -> bool {
        self.scenes.iter().any(|scene| matches!(scene.source, StimulusSource::Render(_)))
    }

    /// The design matrix's columns, in the order of [`Condition::levels`]: each numeric
    /// factor's name, and for a factor with named levels one indicator per level after its
    /// reference ([`Factor::columns`], e.g. `gi_dit`).
    pub fn design_columns(&self) -> Vec<String> {
        self.factors.iter().flat_map(Factor::columns).collect()
    }

    /// The conditions CSV of docs/design.md: `condition,<factor>,…`, one row per condition (a
    /// factor with named levels as its indicator columns, [`Study::design_columns`]).
    pub fn conditions_csv(&self) -> String {
        let mut writer = csv::Writer::from_writer(Vec::new());
        let mut header = vec!["condition".to_string()];
        header.extend(self.design_columns());
        writer.write_record(&header).expect("writing to memory");
        for condition in &self.conditions {
            let mut row = vec![condition.name.clone()];
            row.extend(condition.levels.iter().map(|level| format_number(*level)));
            writer.write_record(&row).expect("writing to memory");
        }
        String::from_utf8(writer.into_inner().expect("writing to memory")).expect("UTF-8")
    }
}

/// A number as CSV text: whole numbers without a decimal point.
pub(crate) fn format_number(value: f64) -> String {
    if value.fract() == 0.0 && value.abs() < 1e15 { format!("{}", value as i64) } else { format!("{value}") }
}

/// The posterior's target of an active design: the log-worths of the conditions, or the
/// effects of the study's factors (each condition's levels as the design matrix's row).
pub fn active_target(active: &ActiveDesign, conditions: &[Condition]) -> mrstudy_analysis::active::Target {
    match active.target {
        ActiveTarget::Worths => mrstudy_analysis::active::Target::Worths { conditions: conditions.len() },
        ActiveTarget::Factors => mrstudy_analysis::active::Target::Factors {
            design: conditions.iter().map(|condition| condition.levels.clone()).collect(),
        },
        ActiveTarget::Both => mrstudy_analysis::active::Target::Both {
            design: conditions.iter().map(|condition| condition.levels.clone()).collect(),
        },
    }
}

/// The trials CSV's own columns, in order (docs/design.md); the external ids and the demographic
/// fields follow them, so neither may be named like one. `export` writes this header.
pub const TRIALS_CSV_COLUMNS: &[&str] = &[
    "study",
    "participant",
    "trial",
    "left",
    "right",
    "chosen",
    "scene_left",
    "scene_right",
    "rt_ms",
    "shown_at",
    "answered_at",
    "catch_answered",
    "catch_failed",
    "viewport",
    "device_pixel_ratio",
    "display_css",
    "display_device",
    "completed",
    "status",
    "completion_code",
    "pilot",
    "excluded",
    "too_fast",
];
