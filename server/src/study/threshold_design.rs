//! A threshold study's design, as the survey's [`Study`](super::survey::Study) keeps it
//! (`Study::threshold`): the knob and its levels, QUEST+'s intensity rule, scale, psychometric
//! function and grids. Apart from [`threshold`](super::threshold), which reads the `[threshold]`
//! table and builds on the survey's study, so that the survey's model can hold this one without
//! a module cycle.

use mrstudy_renderer::knob::Knob;
use serde::{Deserialize, Serialize};

/// The regions a stimulus's metrics are measured in (`metric:<metric>:<region>`).
pub const REGIONS: [&str; 3] = ["image", "affected", "virtual"];

/// QUEST+'s intensity of a level: the knob's value, its inverse (more of the knob, less
/// visible), or a measured error of the level's stimulus against the ground truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Intensity {
    Knob,
    InverseKnob,
    /// `metric:<metric>:<region>`: the level's intensity is the mean over the study's scene
    /// configurations of the metric of its stimuli in the region (their stimulus records).
    Metric {
        metric: String,
        region: String,
    },
}

impl Intensity {
    /// The intensity as the study file writes it.
    pub fn name(&self) -> String {
        match self {
            Intensity::Knob => "knob".into(),
            Intensity::InverseKnob => "inverse-knob".into(),
            Intensity::Metric { metric, region } => format!("metric:{metric}:{region}"),
        }
    }
}

/// How an intensity becomes QUEST+'s stimulus value x, as questplus's `stim_scale`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Scale {
    /// x = log10 intensity.
    #[serde(rename = "log10")]
    Log10,
    /// x = 20 · log10 intensity.
    #[serde(rename = "dB")]
    Decibel,
    /// x = intensity.
    #[serde(rename = "linear")]
    Linear,
}

impl Scale {
    pub fn name(self) -> &'static str {
        match self {
            Scale::Log10 => "log10",
            Scale::Decibel => "dB",
            Scale::Linear => "linear",
        }
    }

    /// x of `intensity` on this scale (`None` for a non-positive intensity on a log scale).
    pub fn x(self, intensity: f64) -> Option<f64> {
        let x = match self {
            Scale::Log10 => intensity.log10(),
            Scale::Decibel => 20.0 * intensity.log10(),
            Scale::Linear => intensity,
        };
        x.is_finite().then_some(x)
    }
}

/// The psychometric function, as questplus 2023.1 defines it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Function {
    Weibull,
    Logistic,
    Normal,
}

impl Function {
    pub fn name(self) -> &'static str {
        match self {
            Function::Weibull => "weibull",
            Function::Logistic => "logistic",
            Function::Normal => "normal",
        }
    }
}

/// When a threshold study's levels are rendered (`[threshold] render`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RenderWhen {
    /// Every level of every scene configuration before the study opens (`serve` at start-up).
    #[default]
    Ahead,
    /// At start-up only the levels QUEST+ can choose in the first `render_ahead` trials; any
    /// other level when a participant first needs it, through the server's render queue
    /// (`crate::render_queue`).
    OnDemand,
}

impl RenderWhen {
    fn is_ahead(&self) -> bool {
        *self == RenderWhen::Ahead
    }
}

/// A checked `[threshold]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThresholdDesign {
    pub knob: Knob,
    /// The knob values that can be shown, increasing; condition `k` of the study is level `k`.
    pub levels: Vec<u32>,
    pub intensity: Intensity,
    pub scale: Scale,
    pub function: Function,
    /// QUEST+'s grids, in x units (thresholds), and the fixed guess rate.
    pub threshold: Vec<f64>,
    pub slope: Vec<f64>,
    pub lapse: Vec<f64>,
    pub guess: f64,
    /// Threshold trials per participant (catch trials come on top).
    pub trials: u32,
    /// What each level is shown beside: `ground-truth`.
    pub reference: String,
    /// Each level's intensity: from the knob value when the study is loaded, from the stimulus
    /// records when it is prepared (`metric:…`); `None` until then.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensities: Option<Vec<f64>>,
    /// When the levels are rendered: all ahead (default) or on demand. (Left out of the stored
    /// definition when default, so a study file without the key records as before.)
    #[serde(default, skip_serializing_if = "RenderWhen::is_ahead")]
    pub render: RenderWhen,
    /// With `render = "on-demand"`: the first trials whose every possible level is rendered at
    /// start-up (default 3).
    #[serde(default = "default_render_ahead", skip_serializing_if = "is_default_render_ahead")]
    pub render_ahead: u32,
}

/// `render_ahead`'s default: the levels of the first three trials.
pub const DEFAULT_RENDER_AHEAD: u32 = 3;

fn default_render_ahead() -> u32 {
    DEFAULT_RENDER_AHEAD
}

fn is_default_render_ahead(trials: &u32) -> bool {
    *trials == DEFAULT_RENDER_AHEAD
}

impl ThresholdDesign {
    /// The condition name of the level with knob value `value`: `vpls-64`.
    pub fn condition_name(knob: Knob, value: u32) -> String {
        format!("{knob}-{value}")
    }

    /// The level (index) of the condition called `name`.
    pub fn level_of(&self, name: &str) -> Option<usize> {
        self.levels.iter().position(|&value| Self::condition_name(self.knob, value) == name)
    }

    /// The intensity of each level where it follows from the knob value alone (`knob`,
    /// `inverse-knob`); `None` for a metric intensity, which needs the stimulus records.
    pub fn knob_intensities(&self) -> Option<Vec<f64>> {
        match self.intensity {
            Intensity::Knob => Some(self.levels.iter().map(|&value| f64::from(value)).collect()),
            Intensity::InverseKnob => Some(self.levels.iter().map(|&value| 1.0 / f64::from(value)).collect()),
            Intensity::Metric { .. } => None,
        }
    }
}
