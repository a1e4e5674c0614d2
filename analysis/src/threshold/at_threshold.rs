//! What the threshold costs and how large the error is there: the render time (`render_ms`,
//! region `image`) and the mean FLIP in the region `affected` (`flip_mean`) of the levels'
//! stimuli, from the stimulus metrics CSV (`mrstudy analyze --stimuli`), at each fit's threshold.
//!
//! **A level's value** is the mean over the export's scene configurations of its stimulus
//! records (condition `<knob>-<value>`, e.g. `vpls-64`); a fit per scene configuration uses that
//! scene configuration's record alone. **At the threshold** the value is interpolated between
//! the two levels around it, as `knob_at_threshold` is: linearly in x of its log10 (so a value
//! that is a power of the knob — a render time ∝ VPLs, a FLIP ∝ VPLs^−½ — is exact for
//! `inverse-knob` or `knob` intensities on a log scale), linearly in x where a value is 0. Absent
//! outside the levels shown, or where a level around the threshold has no record.

use crate::error::{AnalysisError, Result};

use super::report::{LevelShown, ThresholdAnalysis, ThresholdFit};

/// One stimulus record's cost and error (the caller reads them from the stimulus metrics CSV,
/// `crate::stimulus_metrics`, which this module does not import: no module cycle).
#[derive(Debug, Clone, PartialEq)]
pub struct StimulusCost {
    pub scene: String,
    pub condition: String,
    /// `render_ms` in region `image`.
    pub render_ms: Option<f64>,
    /// `flip_mean` in region `affected`.
    pub flip_mean: Option<f64>,
}

/// Fills `render_ms_at_threshold` and `flip_mean_at_threshold` of every fit from the stimulus
/// records `costs`. Refused with one sentence when they (`source_name`) hold no record of any
/// level of the export.
pub fn fill_at_threshold(analysis: &mut ThresholdAnalysis, costs: &[StimulusCost], source_name: &str) -> Result<()> {
    let conditions: Vec<&str> = analysis.levels.iter().filter_map(|level| level.condition.as_deref()).collect();
    if !conditions.iter().any(|condition| costs.iter().any(|cost| cost.condition == *condition)) {
        let shown = if conditions.is_empty() {
            "the export names no condition per level (no `knob` or `left,right` columns)".to_string()
        } else {
            format!("the export's levels are the conditions {}", conditions.join(", "))
        };
        return Err(AnalysisError::BadOption {
            option: "--stimuli".to_string(),
            message: format!("{source_name} has no stimulus record of any level of the threshold export: {shown}"),
        });
    }
    let scenes: Vec<String> = analysis.scenes.iter().filter_map(|fit| fit.scene.clone()).collect();
    let levels = analysis.levels.clone();
    let all_scenes: Vec<&str> = scenes.iter().map(String::as_str).collect();
    let fill = |fit: &mut ThresholdFit, scenes: &[&str]| {
        let Some(threshold) = fit.threshold else { return };
        let at = |value: fn(&StimulusCost) -> Option<f64>| {
            let values: Vec<Option<f64>> =
                levels.iter().map(|level| level_value(costs, level, scenes, value)).collect();
            interpolate(&levels, &values, threshold)
        };
        fit.render_ms_at_threshold = at(|cost| cost.render_ms);
        fit.flip_mean_at_threshold = at(|cost| cost.flip_mean);
    };
    fill(&mut analysis.pooled, &all_scenes);
    for fit in &mut analysis.participants {
        fill(fit, &all_scenes);
    }
    for fit in &mut analysis.scenes {
        let scene = fit.scene.clone().unwrap_or_default();
        fill(fit, &[scene.as_str()]);
    }
    Ok(())
}

/// The mean of a level's records over `scenes` (every record of its condition when none of
/// them is among `scenes`).
fn level_value(
    costs: &[StimulusCost],
    level: &LevelShown,
    scenes: &[&str],
    value: fn(&StimulusCost) -> Option<f64>,
) -> Option<f64> {
    let condition = level.condition.as_deref()?;
    let of_condition = || costs.iter().filter(move |cost| cost.condition == condition);
    let mut values: Vec<f64> =
        of_condition().filter(|cost| scenes.contains(&cost.scene.as_str())).filter_map(value).collect();
    if values.is_empty() && scenes.len() > 1 {
        values = of_condition().filter_map(value).collect();
    }
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// The value at x between the two levels around it (levels sorted by x).
fn interpolate(levels: &[LevelShown], values: &[Option<f64>], x: f64) -> Option<f64> {
    let k = (0..levels.len().saturating_sub(1)).find(|&k| levels[k].x <= x && x <= levels[k + 1].x)?;
    let (x0, x1) = (levels[k].x, levels[k + 1].x);
    let (v0, v1) = (values[k]?, values[k + 1]?);
    let t = if x1 > x0 { (x - x0) / (x1 - x0) } else { 0.0 };
    let value =
        if v0 > 0.0 && v1 > 0.0 { 10f64.powf(v0.log10() + t * (v1.log10() - v0.log10())) } else { v0 + t * (v1 - v0) };
    value.is_finite().then_some(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::threshold::report::{Overrides, analyze_threshold_csv};

    /// A perfect observer at threshold x = −1.5 (≈ 32 VPLs) on a 1…512 grid, with a `knob`
    /// column; scenes a and b.
    fn export() -> String {
        let mut text = String::from("participant,scene,knob,level,intensity,x,correct,function,scale,guess\n");
        for participant in ["p1", "p2"] {
            for repeat in 0..6 {
                for (k, level) in [1u32, 2, 4, 8, 16, 32, 64, 128, 256, 512].iter().enumerate() {
                    let x = -f64::from(*level).log10();
                    // correct above the threshold, and one miss per level below it so the
                    // fit lands between levels
                    let correct = x > -1.5 || (repeat + k) % 2 == 0;
                    let scene = if repeat % 2 == 0 { "a" } else { "b" };
                    text += &format!(
                        "{participant},{scene},vpls,{level},{},{x},{correct},weibull,log10,0.5\n",
                        1.0 / f64::from(*level)
                    );
                }
            }
        }
        text
    }

    /// render_ms = 2 · VPLs in scene a, 4 · VPLs in scene b; flip_mean = VPLs^−½.
    fn metrics() -> Vec<StimulusCost> {
        let mut costs = Vec::new();
        for level in [1u32, 2, 4, 8, 16, 32, 64, 128, 256, 512] {
            let v = f64::from(level);
            for (scene, ms) in [("a", 2.0 * v), ("b", 4.0 * v)] {
                costs.push(StimulusCost {
                    scene: scene.into(),
                    condition: format!("vpls-{level}"),
                    render_ms: Some(ms),
                    flip_mean: Some(v.powf(-0.5)),
                });
            }
        }
        costs
    }

    #[test]
    fn render_time_and_flip_at_the_threshold_follow_the_knob_between_levels() {
        let mut analysis = analyze_threshold_csv(&export(), "t.csv", Overrides::default(), false, false, 0, 1).unwrap();
        fill_at_threshold(&mut analysis, &metrics(), "m.csv").unwrap();
        let pooled = &analysis.pooled;
        let knob = pooled.knob_at_threshold.unwrap();
        // pooled: the mean of scene a and b, 3 · VPLs; exact for a power of the knob
        let ms = pooled.render_ms_at_threshold.unwrap();
        assert!((ms - 3.0 * knob).abs() < 1e-9 * ms, "render {ms} at knob {knob}");
        let flip = pooled.flip_mean_at_threshold.unwrap();
        assert!((flip - knob.powf(-0.5)).abs() < 1e-9, "flip {flip} at knob {knob}");
        let a = analysis.scenes.iter().find(|fit| fit.scene.as_deref() == Some("a")).unwrap();
        let ms_a = a.render_ms_at_threshold.unwrap();
        assert!((ms_a - 2.0 * a.knob_at_threshold.unwrap()).abs() < 1e-9 * ms_a, "scene a alone: {ms_a}");
        assert!(analysis.participants.iter().all(|fit| fit.render_ms_at_threshold.is_some()));
        let json = serde_json::to_string(&analysis).unwrap();
        assert!(json.contains("\"render_ms_at_threshold\"") && json.contains("\"flip_mean_at_threshold\""));
    }

    #[test]
    fn metrics_of_other_conditions_are_one_sentence() {
        let mut analysis = analyze_threshold_csv(&export(), "t.csv", Overrides::default(), false, false, 0, 1).unwrap();
        let other = [StimulusCost { scene: "a".into(), condition: "LQ".into(), render_ms: Some(3.0), flip_mean: None }];
        let error = fill_at_threshold(&mut analysis, &other, "other.csv").unwrap_err().to_string();
        assert!(
            error.contains("other.csv has no stimulus record of any level") && error.contains("vpls-64"),
            "{error}"
        );
    }
}
