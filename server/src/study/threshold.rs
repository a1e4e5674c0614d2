//! Threshold study files (`kind = "threshold"`): how much of a rendering knob is enough. The
//! `[threshold]` table names a renderer knob ([`Knob`]: `vpls`, `ism_size`, `spp`, …), the
//! levels of it that can be shown, QUEST+'s model (intensity of a level, scale, psychometric
//! function, the threshold, slope and lapse grids, the guess rate) and the trials per
//! participant; each trial shows the stimulus at one level beside the ground truth of the same
//! scene configuration, and the participant picks the ground truth.
//!
//! A threshold study is resolved into the survey's [`Study`] so that everything after loading
//! (stimuli, preparing, joining, answers, catch trials, screen requirements, pilots, exclusion,
//! deletion, export, the admin page) is the paired comparisons' own code: its conditions are the
//! levels (`vpls-64`: the base condition's factor levels, rendered with the knob at that value,
//! [`Condition::knob`](super::survey::Condition::knob)), its design is a detection design against the ground truth
//! (`reference = "ground-truth"`, `scenes = "same"`), and [`Study::threshold`] keeps the
//! [`ThresholdDesign`] that chooses each trial's level (`crate::participant::threshold`).

use std::collections::BTreeMap;
use std::path::Path;

use mrstudy_renderer::gpu::GiLevel;
use mrstudy_renderer::knob::{Knob, KnobSetting};
use mrstudy_renderer::metrics::STIMULUS_METRICS;
use mrstudy_renderer::stimulus::{FactorLevel, Factors};
use serde::Deserialize;

use super::StudyError;
use super::checks::{Fail, kind_table};
use super::made::{check_export_fits, parse_made};
use super::survey::{GROUND_TRUTH, Study, StudyKind};
pub use super::threshold_design::{
    DEFAULT_RENDER_AHEAD, Function, Intensity, REGIONS, RenderWhen, Scale, ThresholdDesign,
};

/// The raw `[threshold]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ThresholdFile {
    knob: String,
    levels: Vec<i64>,
    intensity: String,
    scale: String,
    function: String,
    threshold: Vec<toml::Value>,
    slope: Vec<toml::Value>,
    lapse: Vec<toml::Value>,
    guess: toml::Value,
    trials: i64,
    #[serde(default)]
    reference: Option<String>,
    /// The factor levels every level's stimulus is rendered under (default `{ gi = 1 }`).
    #[serde(default)]
    condition: Option<BTreeMap<String, FactorLevel>>,
    #[serde(default)]
    seed: Option<u64>,
    /// Sensor-noise realisations per scene configuration, as a detection design's.
    #[serde(default)]
    realisations: Option<i64>,
    /// What the reference image is, in words, as a detection design's.
    #[serde(default)]
    reference_label: Option<String>,
    /// `ahead` (default) or `on-demand`.
    #[serde(default)]
    render: Option<String>,
    /// With `render = "on-demand"`: the first trials whose levels are rendered at start-up.
    #[serde(default)]
    render_ahead: Option<i64>,
}

/// The tables of a paired-comparison file a threshold study makes itself from `[threshold]`.
const MADE_FROM_THRESHOLD: [(&str, &str); 3] = [
    ("factors", "its factor levels are [threshold] condition"),
    ("conditions", "its conditions are the levels of [threshold]"),
    ("design", "its design is [threshold]"),
];

/// Reads a `kind = "threshold"` file (already parsed as TOML into `table`) into a [`Study`].
pub(super) fn parse(
    mut table: toml::Table,
    file: &Path,
    base: &Path,
    file_sha256: String,
) -> Result<Study, StudyError> {
    let fail = Fail(file);
    let raw: ThresholdFile =
        kind_table(&mut table, fail, "threshold", &MADE_FROM_THRESHOLD, "knob, levels, intensity, …")?;
    let made_keys = [
        ("realisations", raw.realisations.map(toml::Value::Integer)),
        ("reference_label", raw.reference_label.clone().map(toml::Value::String)),
    ];
    let (design, condition, seed) = check(fail, raw)?;
    // the survey's tables, made from [threshold]: one factor per level the condition gives,
    // one condition per level, a detection design against the ground truth
    let mut factors = toml::value::Array::new();
    let mut levels = toml::Table::new();
    for (name, level) in &condition {
        let mut factor = toml::Table::new();
        factor.insert("name".into(), toml::Value::String(name.clone()));
        factors.push(toml::Value::Table(factor));
        levels.insert(
            name.clone(),
            match level {
                FactorLevel::Number(number) => toml::Value::Float(*number),
                FactorLevel::Name(level) => toml::Value::String(level.clone()),
            },
        );
    }
    let mut conditions = toml::value::Array::new();
    for &value in &design.levels {
        let mut made = toml::Table::new();
        made.insert("name".into(), toml::Value::String(ThresholdDesign::condition_name(design.knob, value)));
        made.insert("levels".into(), toml::Value::Table(levels.clone()));
        conditions.push(toml::Value::Table(made));
    }
    let mut made_design = toml::Table::new();
    made_design.insert("reference".into(), toml::Value::String(GROUND_TRUTH.into()));
    made_design.insert("repetitions".into(), toml::Value::Integer(1));
    made_design.insert("scenes".into(), toml::Value::String("same".into()));
    if let Some(seed) = seed {
        made_design.insert("seed".into(), toml::Value::Integer(seed as i64));
    }
    for (key, value) in made_keys {
        if let Some(value) = value {
            made_design.insert(key.into(), value);
        }
    }
    table.insert("factors".into(), toml::Value::Array(factors));
    table.insert("conditions".into(), toml::Value::Array(conditions));
    table.insert("design".into(), toml::Value::Table(made_design));
    // the detection design's own checks speak of [design]; here its keys are [threshold]'s
    let mut study = parse_made(fail, &table, "threshold", file, base, file_sha256)?;
    for (condition, &value) in study.conditions.iter_mut().zip(&design.levels) {
        condition.knob = Some(KnobSetting { knob: design.knob, value });
    }
    study.kind = StudyKind::Threshold;
    let trials = design.trials as usize + study.catch.iter().map(|c| c.repetitions as usize).sum::<usize>();
    check_export_fits(fail, &study, "threshold.trials", trials, "threshold", &CSV_COLUMNS)?;
    study.threshold = Some(design);
    Ok(study)
}

/// The threshold export's own columns, after the trials CSV's (docs/design.md): the scene
/// configuration, the level (knob value) shown, its intensity and x, whether the reference was
/// picked (`true`/`false`), and the model, the same on every row.
pub const CSV_COLUMNS: [&str; 9] =
    ["scene", "knob", "level", "intensity", "x", "correct", "function", "scale", "guess"];

/// Checks the `[threshold]` table: returns the design, the base condition's factor levels and
/// the seed.
fn check(
    fail: Fail,
    raw: ThresholdFile,
) -> Result<(ThresholdDesign, BTreeMap<String, FactorLevel>, Option<u64>), StudyError> {
    let knob = Knob::parse(&raw.knob).ok_or_else(|| {
        fail.at(
            "threshold.knob",
            format!("expected one of the renderer's knobs ({}), found \"{}\"", Knob::names(), raw.knob),
        )
    })?;
    let levels = check_levels(fail, knob, &raw.levels)?;
    let intensity = check_intensity(fail, &raw.intensity)?;
    let scale = match raw.scale.as_str() {
        "log10" => Scale::Log10,
        "dB" => Scale::Decibel,
        "linear" => Scale::Linear,
        other => {
            return Err(
                fail.at("threshold.scale", format!("expected \"log10\", \"dB\" or \"linear\", found \"{other}\""))
            );
        }
    };
    let function = match raw.function.as_str() {
        "weibull" => Function::Weibull,
        "logistic" => Function::Logistic,
        "normal" => Function::Normal,
        other => {
            return Err(fail.at(
                "threshold.function",
                format!("expected \"weibull\", \"logistic\" or \"normal\", found \"{other}\""),
            ));
        }
    };
    let threshold = grid(fail, "threshold.threshold", &raw.threshold, f64::NEG_INFINITY, f64::INFINITY)?;
    let slope = grid(fail, "threshold.slope", &raw.slope, f64::MIN_POSITIVE, f64::INFINITY)?;
    let guess = number(fail, "threshold.guess", &raw.guess)?;
    if !(0.0..1.0).contains(&guess) {
        return Err(
            fail.at("threshold.guess", format!("expected a rate from 0 up to 1 (0.5 for two images), found {guess}"))
        );
    }
    let lapse = grid(fail, "threshold.lapse", &raw.lapse, 0.0, 0.5)?;
    if let Some(&lapse) = lapse.iter().find(|&&lapse| guess + lapse >= 1.0) {
        return Err(fail
            .at("threshold.lapse", format!("expected lapse rates below 1 − guess ({}), found {lapse}", 1.0 - guess)));
    }
    if !(1..=1000).contains(&raw.trials) {
        return Err(
            fail.at("threshold.trials", format!("expected 1 to 1000 trials per participant, found {}", raw.trials))
        );
    }
    let reference = raw.reference.unwrap_or_else(|| GROUND_TRUTH.to_string());
    if reference != GROUND_TRUTH {
        return Err(fail.at(
            "threshold.reference",
            format!("expected \"{GROUND_TRUTH}\" (each level beside the ground truth of its scene configuration), found \"{reference}\""),
        ));
    }
    let render = match raw.render.as_deref() {
        None | Some("ahead") => RenderWhen::Ahead,
        Some("on-demand") => RenderWhen::OnDemand,
        Some(other) => {
            return Err(fail.at("threshold.render", format!("expected \"ahead\" or \"on-demand\", found \"{other}\"")));
        }
    };
    if render == RenderWhen::OnDemand && matches!(intensity, Intensity::Metric { .. }) {
        return Err(fail.at(
            "threshold.render",
            format!(
                "expected \"ahead\" with intensity \"{}\": a measured intensity needs every level's stimulus record before the first trial",
                intensity.name()
            ),
        ));
    }
    let render_ahead = match raw.render_ahead {
        None => DEFAULT_RENDER_AHEAD,
        Some(trials) if render == RenderWhen::Ahead => {
            return Err(fail.at(
                "threshold.render_ahead",
                format!("expected render_ahead only with render = \"on-demand\" (every level is rendered ahead), found {trials}"),
            ));
        }
        Some(trials) if (1..=8).contains(&trials) => trials as u32,
        Some(trials) => {
            return Err(fail.at(
                "threshold.render_ahead",
                format!("expected 1 to 8 trials whose levels are rendered at start-up, found {trials}"),
            ));
        }
    };
    let design = ThresholdDesign {
        render,
        render_ahead,
        knob,
        levels,
        intensity,
        scale,
        function,
        threshold,
        slope,
        lapse,
        guess,
        trials: raw.trials as u32,
        reference,
        intensities: None,
    };
    let mut design = design;
    if let Some(intensities) = design.knob_intensities() {
        check_grid_covers(fail, &design, &intensities)?;
        design.intensities = Some(intensities);
    }
    let condition = raw.condition.unwrap_or_else(|| BTreeMap::from([("gi".to_string(), FactorLevel::Number(1.0))]));
    if condition.is_empty() {
        return Err(fail.at("threshold.condition", "expected at least one factor level, e.g. { gi = 1 }"));
    }
    let factors = Factors::from_study_levels(condition.iter().map(|(name, level)| (name.as_str(), level)))
        .map_err(|reason| fail.at("threshold.condition", format!("factor levels the renderer can render: {reason}")))?;
    if knob.needs_gi() && (factors.gi != GiLevel::Gi || factors.coherent.is_some()) {
        return Err(fail.at(
            "threshold.condition",
            format!(
                "expected gi = 1 (differential instant radiosity) for knob \"{knob}\", which changes only DIR's indirect light; found {}",
                factors.label()
            ),
        ));
    }
    if knob == Knob::ShadowMapSize && factors.gi == GiLevel::None {
        return Err(fail.at(
            "threshold.condition",
            "expected gi = 1 or shadows = 1 for knob \"shadow_map_size\", which changes only the shadows",
        ));
    }
    Ok((design, condition, raw.seed))
}

/// The levels: at least two knob values, increasing, each within the knob's range.
fn check_levels(fail: Fail, knob: Knob, levels: &[i64]) -> Result<Vec<u32>, StudyError> {
    if levels.len() < 2 {
        return Err(fail.at("threshold.levels", "expected at least two knob values"));
    }
    let (low, high) = knob.range();
    for (index, &value) in levels.iter().enumerate() {
        if value < i64::from(low) || value > i64::from(high) {
            return Err(fail.at(
                &format!("threshold.levels[{index}]"),
                format!("expected a value of knob \"{knob}\" from {low} to {high}, found {value}"),
            ));
        }
        if index > 0 && value <= levels[index - 1] {
            return Err(fail.at(
                &format!("threshold.levels[{index}]"),
                format!("expected levels increasing, found {value} after {}", levels[index - 1]),
            ));
        }
    }
    Ok(levels.iter().map(|&value| value as u32).collect())
}

/// `knob`, `inverse-knob` or `metric:<metric>:<region>`.
fn check_intensity(fail: Fail, text: &str) -> Result<Intensity, StudyError> {
    match text {
        "knob" => return Ok(Intensity::Knob),
        "inverse-knob" => return Ok(Intensity::InverseKnob),
        _ => {}
    }
    let expected = || {
        fail.at(
            "threshold.intensity",
            format!(
                "expected \"knob\", \"inverse-knob\" or \"metric:<metric>:<region>\" with a metric of {} and a region of {}, found \"{text}\"",
                STIMULUS_METRICS.join(", "),
                REGIONS.join(", ")
            ),
        )
    };
    let mut parts = text.split(':');
    match (parts.next(), parts.next(), parts.next(), parts.next()) {
        (Some("metric"), Some(metric), Some(region), None)
            if STIMULUS_METRICS.contains(&metric) && REGIONS.contains(&region) =>
        {
            Ok(Intensity::Metric { metric: metric.into(), region: region.into() })
        }
        _ => Err(expected()),
    }
}

/// A TOML number (integer or float) as f64.
fn number(fail: Fail, key: &str, value: &toml::Value) -> Result<f64, StudyError> {
    let number = match value {
        toml::Value::Integer(integer) => *integer as f64,
        toml::Value::Float(float) => *float,
        other => return Err(fail.at(key, format!("expected a number, found {other}"))),
    };
    if number.is_finite() { Ok(number) } else { Err(fail.at(key, "expected a finite number")) }
}

/// A grid: at least one number, increasing, each in `[low, high]`.
fn grid(fail: Fail, key: &str, values: &[toml::Value], low: f64, high: f64) -> Result<Vec<f64>, StudyError> {
    if values.is_empty() {
        return Err(fail.at(key, "expected at least one value"));
    }
    let mut grid = Vec::with_capacity(values.len());
    for (index, value) in values.iter().enumerate() {
        let item = format!("{key}[{index}]");
        let number = number(fail, &item, value)?;
        if number < low || number > high {
            let range = match (low.is_finite(), high.is_finite()) {
                (true, true) => format!("from {low} to {high}"),
                (true, false) if low > 0.0 => "above 0".to_string(),
                _ => "a finite number".to_string(),
            };
            return Err(fail.at(&item, format!("expected {range}, found {number}")));
        }
        if let Some(&before) = grid.last()
            && number <= before
        {
            return Err(fail.at(&item, format!("expected the grid increasing, found {number} after {before}")));
        }
        grid.push(number);
    }
    Ok(grid)
}

/// Every level's x exists on the scale (no zero on a log scale), and the threshold grid reaches
/// into the levels' range of x: a grid wholly beyond it could never put the threshold where the
/// levels can measure it.
pub(crate) fn check_grid_covers(fail: Fail, design: &ThresholdDesign, intensities: &[f64]) -> Result<(), StudyError> {
    let mut xs = Vec::with_capacity(intensities.len());
    for (index, &intensity) in intensities.iter().enumerate() {
        let x = design.scale.x(intensity).ok_or_else(|| {
            fail.at(
                &format!("threshold.levels[{index}]"),
                format!(
                    "expected a level with a positive intensity on scale \"{}\", found intensity {intensity} (intensity \"{}\")",
                    design.scale.name(),
                    design.intensity.name()
                ),
            )
        })?;
        xs.push(x);
    }
    let low = xs.iter().copied().fold(f64::INFINITY, f64::min);
    let high = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !design.threshold.iter().any(|&threshold| (low..=high).contains(&threshold)) {
        return Err(fail.at(
            "threshold.threshold",
            format!(
                "expected a threshold grid reaching into the levels' range of x ({} to {} on scale \"{}\"), found {} to {}",
                short(low),
                short(high),
                design.scale.name(),
                short(design.threshold[0]),
                short(*design.threshold.last().expect("a checked grid is not empty"))
            ),
        ));
    }
    Ok(())
}

/// A number in a message, to four significant decimals.
fn short(value: f64) -> String {
    let text = format!("{value:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" { "0".into() } else { text.into() }
}
