//! QUEST+ (Watson, JoV 2017) exactly as the `questplus` PyPI package 2023.1 runs it: a grid
//! posterior over (threshold, slope, lapse) with the guess rate fixed, a uniform prior, the next
//! stimulus by minimum expected entropy, a Bayesian update per answer.
//!
//! # API (stable; the server builds on it)
//!
//! ```text
//! PsychFunction::{Weibull, Logistic, Normal}    serde/FromStr "weibull" | "logistic" | "normal"
//! StimScale::{Log10, Db, Linear}                serde/FromStr "log10" | "dB" | "linear"
//! IntensityRule::{Knob, InverseKnob}            serde/FromStr "knob" | "inverse-knob"
//!
//! StimulusDomain::from_levels(&levels, IntensityRule, StimScale) -> Result<StimulusDomain>
//! StimulusDomain::from_intensities(&levels, &intensities, StimScale) -> Result<StimulusDomain>
//!     { levels, intensities, x }: sorted by intensity, lowest first (for "inverse-knob" the
//!     largest knob value comes first); `x` is what QUEST+ sees; `index_of_level(level)`.
//!
//! QuestPlusConfig { x, thresholds, slopes, lapses, guess, function, scale }   (serde)
//!     `x`: the stimulus domain on the function's scale, strictly increasing (StimulusDomain::x);
//!     grids in x units; `guess` fixed (0.5 for 2AFC).
//! QuestPlus::new(&config) -> Result<QuestPlus, ThresholdError>
//! q.next_index() -> usize          index into config.x (= into the StimulusDomain's vectors)
//! q.update(index, correct) -> Result<(), ThresholdError>
//! QuestPlus::replay(&config, &[(index, correct)]) -> Result<QuestPlus>   bit-identical to updates
//! q.posterior() -> &[f64]          over (threshold, slope, lapse), lapse fastest
//! q.mode() -> Params, q.mean() -> Params, q.answers(), q.config(), q.entropy()
//! serde: a QuestPlus serialises as {config, answers, posterior}; deserialising replays the
//!     answers (exact) and refuses a stored posterior that differs from the replay's by more
//!     than 1e-12 relative (JSON may round a float's last bit; the replay's is kept).
//! ```
//!
//! # What questplus does, and what this module matches
//!
//! - Psychometric functions (questplus `psychometric_function`): with guess γ, lapse δ,
//!   threshold t, slope β on the stimulus value x,
//!   - `weibull`, scale `log10`: p = 1 − δ − (1 − γ − δ)·exp(−10^(β(x − t)));
//!     scale `dB`: p = 1 − δ − (1 − γ − δ)·exp(−10^(β(x − t)/20));
//!     scale `linear`: p = 1 − δ − (1 − γ − δ)·exp(−(x/t)^β);
//!   - `normal` is questplus's `norm_cdf`: p = γ + (1 − γ − δ)·Φ((x − t)/β), with t its `mean`
//!     and β its `sd` (so for `normal` the slope grid holds standard deviations in x units;
//!     questplus allows it only with `stim_scale="linear"`, i.e. on x as given, which is what
//!     this module does for every scale);
//!   - `logistic` is not in questplus 2023.1; here p = γ + (1 − γ − δ)/(1 + exp(−β(x − t))),
//!     checked against questplus's own selection code with this function plugged in
//!     (`analysis/reference/questplus_reference.py`).
//! - Stimulus domain: questplus takes the x values themselves (Watson's Example 1 passes
//!   −40…0 dB). mrstudy maps a knob level to an intensity (the knob value or its inverse) and
//!   the intensity to x = log10(intensity), 20·log10(intensity) or the intensity itself.
//! - Prior: uniform over the grid. Update: posterior ← posterior · P(answer | x, θ), normalised.
//! - Selection (`min_entropy`): for every stimulus, the expected entropy of the posterior after
//!   the answer, EH(x) = Σ_answers P(answer | x)·H(posterior | x, answer) with 0·ln 0 = 0; the
//!   first minimum in the domain's order (xarray's `argmin`, i.e. numpy's first index). The
//!   domain is sorted by intensity, lowest first, so ties go to the lowest intensity.
//! - Mode: the first maximum of the posterior in (threshold, slope, lapse) order; mean: the
//!   posterior-weighted mean of each parameter.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::ThresholdError;

/// The psychometric function's shape (questplus 2023.1's names: `weibull`, `norm_cdf`; the
/// logistic is ours).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PsychFunction {
    Weibull,
    Logistic,
    Normal,
}

/// How x is made from an intensity, and which Weibull parameterisation applies
/// (questplus's `stim_scale`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum StimScale {
    /// x = log10(intensity).
    #[serde(rename = "log10")]
    Log10,
    /// x = 20·log10(intensity).
    #[serde(rename = "dB")]
    Db,
    /// x = intensity.
    #[serde(rename = "linear")]
    Linear,
}

/// How a knob level becomes a QUEST+ intensity (the study's `intensity`; the
/// `metric:<metric>:<region>` rule needs stimulus records and is the server's, through
/// [`StimulusDomain::from_intensities`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum IntensityRule {
    /// The knob value itself.
    #[serde(rename = "knob")]
    Knob,
    /// 1 / knob value: more of the knob, less visible.
    #[serde(rename = "inverse-knob")]
    InverseKnob,
}

impl PsychFunction {
    /// The study-file name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Weibull => "weibull",
            Self::Logistic => "logistic",
            Self::Normal => "normal",
        }
    }

    /// P(correct) at x, computed in the order questplus writes the formula.
    pub fn prob(self, scale: StimScale, x: f64, p: Params, guess: f64) -> f64 {
        let (t, b, d, g) = (p.threshold, p.slope, p.lapse, guess);
        match self {
            Self::Weibull => match scale {
                StimScale::Linear => 1.0 - d - (1.0 - g - d) * (-((x / t).powf(b))).exp(),
                StimScale::Log10 => 1.0 - d - (1.0 - g - d) * (-(10f64.powf(b * (x - t)))).exp(),
                StimScale::Db => 1.0 - d - (1.0 - g - d) * (-(10f64.powf(b * (x - t) / 20.0))).exp(),
            },
            Self::Normal => g + (1.0 - g - d) * normal_cdf((x - t) / b),
            Self::Logistic => g + (1.0 - g - d) / (1.0 + (-b * (x - t)).exp()),
        }
    }
}

/// Φ(z) as scipy's `ndtr`: ½·erfc(−z/√2).
pub(crate) fn normal_cdf(z: f64) -> f64 {
    0.5 * statrs::function::erf::erfc(-z / std::f64::consts::SQRT_2)
}

impl StimScale {
    /// The study-file name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Log10 => "log10",
            Self::Db => "dB",
            Self::Linear => "linear",
        }
    }

    /// x of an intensity on this scale.
    pub fn x_of(self, intensity: f64) -> f64 {
        match self {
            Self::Log10 => intensity.log10(),
            Self::Db => 20.0 * intensity.log10(),
            Self::Linear => intensity,
        }
    }

    /// The intensity of an x on this scale (the inverse of [`StimScale::x_of`]).
    pub fn intensity_of(self, x: f64) -> f64 {
        match self {
            Self::Log10 => 10f64.powf(x),
            Self::Db => 10f64.powf(x / 20.0),
            Self::Linear => x,
        }
    }
}

impl IntensityRule {
    /// The study-file name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Knob => "knob",
            Self::InverseKnob => "inverse-knob",
        }
    }

    /// The intensity of a knob level.
    pub fn intensity_of(self, level: f64) -> f64 {
        match self {
            Self::Knob => level,
            Self::InverseKnob => 1.0 / level,
        }
    }

    /// The knob level of an intensity (the inverse of [`IntensityRule::intensity_of`]).
    pub fn level_of(self, intensity: f64) -> f64 {
        match self {
            Self::Knob => intensity,
            Self::InverseKnob => 1.0 / intensity,
        }
    }
}

macro_rules! names {
    ($ty:ty, $what:literal, [$($v:expr),*]) => {
        impl FromStr for $ty {
            type Err = ThresholdError;
            fn from_str(s: &str) -> Result<Self, ThresholdError> {
                [$($v),*].into_iter().find(|v| v.name() == s).ok_or_else(|| {
                    ThresholdError::UnknownName {
                        what: $what,
                        value: s.to_string(),
                        expected: [$($v.name()),*].join(", "),
                    }
                })
            }
        }
        impl fmt::Display for $ty {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}
names!(PsychFunction, "function", [PsychFunction::Weibull, PsychFunction::Logistic, PsychFunction::Normal]);
names!(StimScale, "scale", [StimScale::Log10, StimScale::Db, StimScale::Linear]);
names!(IntensityRule, "intensity", [IntensityRule::Knob, IntensityRule::InverseKnob]);

/// One point of the parameter grid (or an estimate).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Params {
    pub threshold: f64,
    pub slope: f64,
    pub lapse: f64,
}

/// The stimuli QUEST+ chooses from: knob levels with their intensities and x, sorted by
/// intensity, lowest first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StimulusDomain {
    pub levels: Vec<f64>,
    pub intensities: Vec<f64>,
    pub x: Vec<f64>,
}

impl StimulusDomain {
    /// The domain of a study's `levels` (strictly increasing, positive where the rule or the
    /// scale takes a reciprocal or a logarithm) under `intensity` and `scale`.
    pub fn from_levels(levels: &[f64], rule: IntensityRule, scale: StimScale) -> Result<Self, ThresholdError> {
        check_increasing("levels", levels)?;
        if rule == IntensityRule::InverseKnob
            && let Some(&level) = levels.iter().find(|&&l| l <= 0.0)
        {
            return Err(ThresholdError::NotPositive {
                what: "level",
                value: level,
                why: "intensity = \"inverse-knob\" takes 1/level",
            });
        }
        let intensities: Vec<f64> = levels.iter().map(|&l| rule.intensity_of(l)).collect();
        Self::from_intensities(levels, &intensities, scale)
    }

    /// The domain of levels with intensities given (e.g. a measured error per level), sorted by
    /// intensity; intensities must be distinct and finite, and positive on a log scale.
    pub fn from_intensities(levels: &[f64], intensities: &[f64], scale: StimScale) -> Result<Self, ThresholdError> {
        if levels.is_empty() {
            return Err(ThresholdError::EmptyGrid { grid: "levels" });
        }
        if levels.len() != intensities.len() {
            return Err(ThresholdError::LengthMismatch {
                what: "intensities",
                got: intensities.len(),
                expected: levels.len(),
            });
        }
        for (index, &v) in intensities.iter().enumerate() {
            if !v.is_finite() {
                return Err(ThresholdError::NonFinite { grid: "intensities", index, value: v });
            }
            if scale != StimScale::Linear && v <= 0.0 {
                return Err(ThresholdError::NotPositive {
                    what: "intensity",
                    value: v,
                    why: "a log10 or dB scale takes its logarithm",
                });
            }
        }
        let mut order: Vec<usize> = (0..levels.len()).collect();
        order.sort_by(|&a, &b| intensities[a].total_cmp(&intensities[b]));
        let levels: Vec<f64> = order.iter().map(|&i| levels[i]).collect();
        let intensities: Vec<f64> = order.iter().map(|&i| intensities[i]).collect();
        let x: Vec<f64> = intensities.iter().map(|&v| scale.x_of(v)).collect();
        check_increasing("x", &x)?;
        Ok(Self { levels, intensities, x })
    }

    /// The index of a knob level in this domain.
    pub fn index_of_level(&self, level: f64) -> Option<usize> {
        self.levels.iter().position(|&l| l == level)
    }
}

fn check_finite(grid: &'static str, values: &[f64]) -> Result<(), ThresholdError> {
    if values.is_empty() {
        return Err(ThresholdError::EmptyGrid { grid });
    }
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(ThresholdError::NonFinite { grid, index, value: values[index] }),
        None => Ok(()),
    }
}

fn check_increasing(grid: &'static str, values: &[f64]) -> Result<(), ThresholdError> {
    check_finite(grid, values)?;
    for (index, w) in values.windows(2).enumerate() {
        if w[1] <= w[0] {
            return Err(ThresholdError::NotIncreasing { grid, index: index + 1, value: w[1], previous: w[0] });
        }
    }
    Ok(())
}

/// A QUEST+ run's fixed part: the stimulus domain, the parameter grids and the model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QuestPlusConfig {
    /// The stimulus domain in x units (the function's scale), strictly increasing.
    pub x: Vec<f64>,
    /// Threshold grid (x units).
    pub thresholds: Vec<f64>,
    /// Slope grid (β; for `normal`, standard deviations in x units).
    pub slopes: Vec<f64>,
    /// Lapse-rate grid (δ), each in [0, 1 − guess).
    pub lapses: Vec<f64>,
    /// The guess rate γ (lower asymptote), fixed; 0.5 for 2AFC.
    pub guess: f64,
    pub function: PsychFunction,
    pub scale: StimScale,
}

impl QuestPlusConfig {
    /// Checks the grids: non-empty, finite, x strictly increasing, slopes positive, guess in
    /// [0, 1), lapses in [0, 1 − guess), a threshold grid that meets the stimuli's range, and
    /// positive x and thresholds for a linear-scale Weibull.
    pub fn validate(&self) -> Result<(), ThresholdError> {
        check_increasing("x", &self.x)?;
        check_finite("thresholds", &self.thresholds)?;
        check_finite("slopes", &self.slopes)?;
        check_finite("lapses", &self.lapses)?;
        if let Some(&s) = self.slopes.iter().find(|&&s| s <= 0.0) {
            return Err(ThresholdError::NotPositive {
                what: "slope",
                value: s,
                why: "a psychometric function rises with x",
            });
        }
        if !(0.0..1.0).contains(&self.guess) {
            return Err(ThresholdError::OutOfRange { what: "guess", value: self.guess, expected: "in [0, 1)" });
        }
        if let Some(&d) = self.lapses.iter().find(|&&d| !(d >= 0.0 && d < 1.0 - self.guess)) {
            return Err(ThresholdError::OutOfRange { what: "lapse", value: d, expected: "in [0, 1 − guess)" });
        }
        if self.function == PsychFunction::Weibull && self.scale == StimScale::Linear {
            for (what, values) in [("x", &self.x), ("threshold", &self.thresholds)] {
                if let Some(&v) = values.iter().find(|&&v| v <= 0.0) {
                    return Err(ThresholdError::NotPositive {
                        what,
                        value: v,
                        why: "a linear-scale Weibull takes (x/threshold)^slope",
                    });
                }
            }
        }
        let (lo, hi) = (self.x[0], self.x[self.x.len() - 1]);
        if !self.thresholds.iter().any(|&t| t >= lo && t <= hi) {
            return Err(ThresholdError::GridOutsideStimuli {
                low: self.thresholds.iter().copied().fold(f64::INFINITY, f64::min),
                high: self.thresholds.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                x_low: lo,
                x_high: hi,
            });
        }
        Ok(())
    }

    fn params(&self) -> usize {
        self.thresholds.len() * self.slopes.len() * self.lapses.len()
    }

    /// The grid point of a flat posterior index (threshold slowest, lapse fastest).
    pub fn param_at(&self, index: usize) -> Params {
        let (ns, nl) = (self.slopes.len(), self.lapses.len());
        Params {
            threshold: self.thresholds[index / (ns * nl)],
            slope: self.slopes[(index / nl) % ns],
            lapse: self.lapses[index % nl],
        }
    }
}

/// A participant's QUEST+ state: the configuration, the answers so far and the posterior.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QuestPlus {
    config: QuestPlusConfig,
    answers: Vec<(usize, bool)>,
    posterior: Vec<f64>,
    /// P(correct | x, θ), stimulus-major: `[s * params + p]`.
    #[serde(skip)]
    p_correct: Vec<f64>,
}

/// The stored form of a [`QuestPlus`]: what `serde` reads back. The answers are replayed; the
/// posterior is optional and, when present, must equal the replay's to 1e-12 relative (a JSON
/// parser may round its last bit); the replay's, exact, is the one kept.
#[derive(Debug, Clone, Deserialize)]
pub struct QuestPlusState {
    pub config: QuestPlusConfig,
    pub answers: Vec<(usize, bool)>,
    #[serde(default)]
    pub posterior: Option<Vec<f64>>,
}

impl TryFrom<QuestPlusState> for QuestPlus {
    type Error = ThresholdError;
    fn try_from(state: QuestPlusState) -> Result<Self, ThresholdError> {
        let q = QuestPlus::replay(&state.config, &state.answers)?;
        if let Some(stored) = state.posterior {
            // JSON parsers may round the last bit of a float; the replay is exact and is kept.
            let same = stored.len() == q.posterior.len()
                && stored.iter().zip(&q.posterior).all(|(a, b)| (a - b).abs() <= 1e-12 * b.abs().max(1e-300));
            if !same {
                return Err(ThresholdError::PosteriorMismatch { answers: state.answers.len() });
            }
        }
        Ok(q)
    }
}

impl<'de> Deserialize<'de> for QuestPlus {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let state = QuestPlusState::deserialize(d)?;
        QuestPlus::try_from(state).map_err(serde::de::Error::custom)
    }
}

impl QuestPlus {
    /// A fresh run with the uniform prior.
    pub fn new(config: &QuestPlusConfig) -> Result<Self, ThresholdError> {
        config.validate()?;
        let np = config.params();
        let mut p_correct = Vec::with_capacity(config.x.len() * np);
        for &x in &config.x {
            for i in 0..np {
                p_correct.push(config.function.prob(config.scale, x, config.param_at(i), config.guess));
            }
        }
        if let Some(v) = p_correct.iter().find(|v| !v.is_finite()) {
            return Err(ThresholdError::NonFinite { grid: "psychometric function", index: 0, value: *v });
        }
        // questplus: ones / ones.sum().
        let posterior = vec![1.0 / np as f64; np];
        Ok(Self { config: config.clone(), answers: Vec::new(), posterior, p_correct })
    }

    /// A run rebuilt from stored answers `(index into x, correct)`: the same posterior, bit for
    /// bit, as the updates one by one.
    pub fn replay(config: &QuestPlusConfig, answers: &[(usize, bool)]) -> Result<Self, ThresholdError> {
        let mut q = Self::new(config)?;
        for &(index, correct) in answers {
            q.update(index, correct)?;
        }
        Ok(q)
    }

    pub fn config(&self) -> &QuestPlusConfig {
        &self.config
    }

    /// The answers so far, in order.
    pub fn answers(&self) -> &[(usize, bool)] {
        &self.answers
    }

    /// The posterior over the grid, threshold slowest, lapse fastest ([`QuestPlusConfig::param_at`]).
    pub fn posterior(&self) -> &[f64] {
        &self.posterior
    }

    fn likelihood(&self, s: usize, correct: bool) -> impl Iterator<Item = f64> + '_ {
        let np = self.posterior.len();
        self.p_correct[s * np..(s + 1) * np].iter().map(move |&p| if correct { p } else { 1.0 - p })
    }

    /// Bayes' rule for one answer at stimulus `index`.
    pub fn update(&mut self, index: usize, correct: bool) -> Result<(), ThresholdError> {
        if index >= self.config.x.len() {
            return Err(ThresholdError::UnknownStimulus { index, stimuli: self.config.x.len() });
        }
        let new: Vec<f64> = self.posterior.iter().zip(self.likelihood(index, correct)).map(|(a, l)| a * l).collect();
        let sum: f64 = new.iter().sum();
        if !(sum > 0.0 && sum.is_finite()) {
            return Err(ThresholdError::ImpossibleAnswer { index, correct, answers: self.answers.len() });
        }
        self.posterior = new.into_iter().map(|v| v / sum).collect();
        self.answers.push((index, correct));
        Ok(())
    }

    /// The expected entropy after one more trial at each stimulus.
    pub fn expected_entropies(&self) -> Vec<f64> {
        let mut joint = vec![0.0; self.posterior.len()];
        (0..self.config.x.len())
            .map(|s| {
                let mut eh = 0.0;
                for correct in [true, false] {
                    for ((j, a), l) in joint.iter_mut().zip(&self.posterior).zip(self.likelihood(s, correct)) {
                        *j = a * l;
                    }
                    let pk: f64 = joint.iter().sum();
                    if pk > 0.0 {
                        eh += pk * entropy(joint.iter().map(|j| j / pk));
                    }
                }
                eh
            })
            .collect()
    }

    /// The next stimulus: the first minimum of the expected entropy (the lowest intensity on ties).
    pub fn next_index(&self) -> usize {
        first_minimum(&self.expected_entropies())
    }

    /// The entropy of the posterior (nats).
    pub fn entropy(&self) -> f64 {
        entropy(self.posterior.iter().copied())
    }

    /// The grid point of highest posterior (the first in grid order on ties).
    pub fn mode(&self) -> Params {
        let mut best = 0;
        for (i, &p) in self.posterior.iter().enumerate() {
            if p > self.posterior[best] {
                best = i;
            }
        }
        self.config.param_at(best)
    }

    /// The posterior mean of each parameter.
    pub fn mean(&self) -> Params {
        let mut m = Params { threshold: 0.0, slope: 0.0, lapse: 0.0 };
        for (i, &p) in self.posterior.iter().enumerate() {
            let q = self.config.param_at(i);
            m.threshold += p * q.threshold;
            m.slope += p * q.slope;
            m.lapse += p * q.lapse;
        }
        m
    }
}

/// The index of the first smallest value (numpy's `argmin`): ties go to the lowest index.
pub(crate) fn first_minimum(values: &[f64]) -> usize {
    let mut best = 0;
    for (i, &v) in values.iter().enumerate() {
        if v < values[best] {
            best = i;
        }
    }
    best
}

/// −Σ p ln p with 0·ln 0 = 0 (xarray skips the NaN numpy makes of it).
fn entropy(ps: impl Iterator<Item = f64>) -> f64 {
    -ps.filter(|&p| p > 0.0).map(|p| p * p.ln()).sum::<f64>()
}
