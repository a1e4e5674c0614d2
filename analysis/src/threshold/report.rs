//! The analysis of a threshold study's export (`kind = "threshold"`, issue 48 item 3): the
//! trials CSV with the columns `participant,scene,level,intensity,x,correct` (`correct` is
//! `true`/`false`) and the model's `function,scale,guess`, the same on every row. The
//! psychometric function is fitted by maximum likelihood ([`super::fit`]) per participant, per
//! scene configuration and pooled, each with its bootstrap interval, deviance and goodness of
//! fit; a degenerate set of answers (all correct, all wrong, one level) is reported with its
//! reason and never fails the run. The threshold is given in x units (as the export's `x`) and
//! as the knob value there (`knob_at_threshold`: log10 of the knob interpolated linearly in x
//! between the levels shown, so it is exact for `inverse-knob` and `knob` intensities on a log
//! scale; absent outside the levels). Given the stimulus metrics CSV (`--stimuli`), the render
//! time and the FLIP error at the threshold come from the levels' stimulus records
//! ([`super::at_threshold`]).

use std::collections::BTreeMap;

use serde::Serialize;

use super::fit::{FitOptions, Model, Point, aggregate, fit};
use super::{Params, PsychFunction, StimScale};
use crate::error::{AnalysisError, Result};

/// The columns that make a trials CSV a threshold export.
pub const COLUMNS: [&str; 6] = ["participant", "scene", "level", "intensity", "x", "correct"];

/// Bootstrap replicates per fit unless `--bootstrap` says otherwise.
pub const DEFAULT_BOOTSTRAP: usize = 200;

/// Whether a trials CSV's header has every threshold column.
pub fn is_threshold_csv(text: &str) -> bool {
    let columns = crate::data::header_columns(text);
    COLUMNS.iter().all(|column| columns.contains(column))
}

/// The model given on the command line instead of the export's (`--function`, `--scale` as
/// log10|dB|linear, `--guess`).
#[derive(Debug, Clone, Copy, Default)]
pub struct Overrides {
    pub function: Option<PsychFunction>,
    pub scale: Option<StimScale>,
    pub guess: Option<f64>,
}

/// One fit: of a participant, a scene configuration, or all trials.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThresholdFit {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub participant: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
    pub trials: u32,
    pub correct: u32,
    /// Trials (`n`) and correct answers (`k`) at each x shown.
    pub points: Vec<Point>,
    /// The fitted parameters (x units); absent when the fit is degenerate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slope: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lapse: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold_ci: Option<[f64; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slope_ci: Option<[f64; 2]>,
    /// The knob value at the threshold (absent outside the levels shown).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub knob_at_threshold: Option<f64>,
    /// The stimuli's render time (ms) and mean FLIP in the region `affected` at the threshold,
    /// interpolated between the levels' stimulus records (`--stimuli`; [`super::at_threshold`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub render_ms_at_threshold: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flip_mean_at_threshold: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deviance: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p_fit: Option<f64>,
    /// Why there is no fit (all correct, all wrong, one level, …).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub degenerate: Option<&'static str>,
    /// A remark on the fit (e.g. the slope at its search bound).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<&'static str>,
}

/// The JSON section `threshold`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThresholdAnalysis {
    pub function: PsychFunction,
    pub scale: StimScale,
    pub guess: f64,
    pub bootstrap: usize,
    pub pooled: ThresholdFit,
    pub participants: Vec<ThresholdFit>,
    pub scenes: Vec<ThresholdFit>,
    /// The levels shown, sorted by x (not in the JSON: each fit's `points` hold the x).
    #[serde(skip)]
    pub levels: Vec<LevelShown>,
}

/// A level of the export: its x, its knob value and its condition (`<knob>-<value>`, from the
/// `knob` column, else the non-ground-truth side of `left,right`; absent without either).
#[derive(Debug, Clone, PartialEq)]
pub struct LevelShown {
    pub x: f64,
    pub level: f64,
    pub condition: Option<String>,
}

struct Row {
    participant: String,
    scene: String,
    level: f64,
    x: f64,
    correct: bool,
    condition: Option<String>,
}

/// Reads the threshold columns of `text` (pilots and excluded participants left out unless
/// kept) and fits every group.
pub fn analyze_threshold_csv(
    text: &str,
    name: &str,
    overrides: Overrides,
    include_pilots: bool,
    include_excluded: bool,
    bootstrap: usize,
    seed: u64,
) -> Result<ThresholdAnalysis> {
    let bad = |line: usize, message: String| AnalysisError::MalformedCsv {
        source_name: name.to_string(),
        line: line as u64,
        message,
    };
    let mut reader = csv::ReaderBuilder::new().flexible(false).from_reader(text.as_bytes());
    let headers = reader.headers().map_err(|error| bad(1, format!("cannot read the header: {error}")))?.clone();
    let column = |name: &str| headers.iter().position(|header| header == name);
    let required = |wanted: &str| {
        column(wanted).ok_or_else(|| AnalysisError::MissingColumn {
            source_name: name.to_string(),
            column: wanted.to_string(),
            found: headers.iter().collect::<Vec<_>>().join(", "),
        })
    };
    let [participant, scene, level, x, correct] = ["participant", "scene", "level", "x", "correct"].map(required);
    let (participant, scene, level, x, correct) = (participant?, scene?, level?, x?, correct?);
    let (function_column, scale_column, guess_column) = (column("function"), column("scale"), column("guess"));
    let (pilot_column, excluded_column) = (column("pilot"), column("excluded"));
    let (knob_column, left_column, right_column) = (column("knob"), column("left"), column("right"));
    let mut rows = Vec::new();
    let mut model: Option<(String, String, String)> = None;
    for (index, record) in reader.records().enumerate() {
        let line = index + 2;
        let record = record.map_err(|error| bad(line, format!("cannot read the row: {error}")))?;
        let cell = |column: usize| record.get(column).unwrap_or("").trim();
        let flag = |column: Option<usize>| column.is_some_and(|column| cell(column) == "true");
        if (flag(pilot_column) && !include_pilots) || (flag(excluded_column) && !include_excluded) {
            continue;
        }
        if cell(x).is_empty() {
            continue; // not a threshold trial
        }
        let number = |column: usize, what: &str| -> Result<f64> {
            cell(column)
                .parse::<f64>()
                .ok()
                .filter(|value| value.is_finite())
                .ok_or_else(|| bad(line, format!("`{what}` must be a finite number, found \"{}\"", cell(column))))
        };
        let answer = match cell(correct) {
            "true" => true,
            "false" => false,
            other => return Err(bad(line, format!("`correct` must be true or false, found \"{other}\""))),
        };
        let this_model = (
            function_column.map(|c| cell(c).to_string()).unwrap_or_default(),
            scale_column.map(|c| cell(c).to_string()).unwrap_or_default(),
            guess_column.map(|c| cell(c).to_string()).unwrap_or_default(),
        );
        match &model {
            None => model = Some(this_model),
            Some(first) if *first != this_model => {
                return Err(bad(
                    line,
                    format!(
                        "`function,scale,guess` must be the same on every row: {},{},{} here, {},{},{} on the first",
                        this_model.0, this_model.1, this_model.2, first.0, first.1, first.2
                    ),
                ));
            }
            Some(_) => {}
        }
        let level = number(level, "level")?;
        let condition = match (knob_column, left_column, right_column) {
            (Some(knob), _, _) if !cell(knob).is_empty() => Some(format!("{}-{level}", cell(knob))),
            (_, Some(left), Some(right)) => {
                let shown = if cell(left) == crate::data::GROUND_TRUTH { cell(right) } else { cell(left) };
                (!shown.is_empty()).then(|| shown.to_string())
            }
            _ => None,
        };
        rows.push(Row {
            participant: cell(participant).to_string(),
            scene: cell(scene).to_string(),
            level,
            x: number(x, "x")?,
            correct: answer,
            condition,
        });
    }
    let (function_text, scale_text, guess_text) = model.unwrap_or_default();
    let from_file = |what: &str, value: &str, flag: &str| AnalysisError::BadOption {
        option: flag.to_string(),
        message: format!("{name}: the export's `{what}` is \"{value}\"; give {flag} to say which to fit"),
    };
    let function = match overrides.function {
        Some(function) => function,
        None => function_text.parse().map_err(|_| from_file("function", &function_text, "--function"))?,
    };
    let scale = match overrides.scale {
        Some(scale) => scale,
        None => scale_text.parse().map_err(|_| from_file("scale", &scale_text, "--scale"))?,
    };
    let guess = match overrides.guess {
        Some(guess) => guess,
        None => guess_text.parse::<f64>().map_err(|_| from_file("guess", &guess_text, "--guess"))?,
    };
    if !(0.0..1.0).contains(&guess) {
        return Err(AnalysisError::BadOption {
            option: "--guess".to_string(),
            message: format!("the guess rate must be from 0 to below 1, found {guess}"),
        });
    }
    let model = Model { function, scale, guess };
    let options = FitOptions { bootstrap, seed, ..FitOptions::default() };
    // the levels shown: x → log10(knob), for the knob value at the threshold
    let mut shown: Vec<LevelShown> =
        rows.iter().map(|row| LevelShown { x: row.x, level: row.level, condition: row.condition.clone() }).collect();
    shown.sort_by(|a, b| a.x.total_cmp(&b.x));
    shown.dedup_by(|a, b| a.x == b.x);
    let levels: Vec<(f64, f64)> = shown.iter().map(|level| (level.x, level.level)).collect();
    let fit_of = |participant: Option<&str>, scene: Option<&str>, selected: Vec<&Row>| -> ThresholdFit {
        let trials = selected.len() as u32;
        let correct = selected.iter().filter(|row| row.correct).count() as u32;
        let points = aggregate(selected.iter().map(|row| (row.x, row.correct)));
        let mut entry = ThresholdFit {
            participant: participant.map(str::to_string),
            scene: scene.map(str::to_string),
            trials,
            correct,
            points: points.clone(),
            threshold: None,
            slope: None,
            lapse: None,
            threshold_ci: None,
            slope_ci: None,
            knob_at_threshold: None,
            render_ms_at_threshold: None,
            flip_mean_at_threshold: None,
            deviance: None,
            p_fit: None,
            degenerate: None,
            note: None,
        };
        match fit(model, &points, &options) {
            Ok(found) => {
                entry.knob_at_threshold = knob_at(&levels, found.threshold);
                entry.threshold = Some(found.threshold);
                entry.slope = Some(found.slope);
                entry.lapse = Some(found.lapse);
                entry.threshold_ci = found.threshold_ci;
                entry.slope_ci = found.slope_ci;
                entry.deviance = Some(found.deviance);
                entry.p_fit = found.p_fit;
                entry.note = found.note;
            }
            Err(degenerate) => entry.degenerate = Some(degenerate.reason()),
        }
        entry
    };
    let mut by_participant: BTreeMap<&str, Vec<&Row>> = BTreeMap::new();
    let mut by_scene: BTreeMap<&str, Vec<&Row>> = BTreeMap::new();
    for row in &rows {
        by_participant.entry(&row.participant).or_default().push(row);
        by_scene.entry(&row.scene).or_default().push(row);
    }
    Ok(ThresholdAnalysis {
        function,
        scale,
        guess,
        bootstrap,
        pooled: fit_of(None, None, rows.iter().collect()),
        participants: by_participant.into_iter().map(|(id, rows)| fit_of(Some(id), None, rows)).collect(),
        scenes: by_scene.into_iter().map(|(scene, rows)| fit_of(None, Some(scene), rows)).collect(),
        levels: shown,
    })
}

impl ThresholdAnalysis {
    /// One SVG per fit (`threshold-pooled.svg`, `threshold-scene-<name>.svg`,
    /// `threshold-participant-<id>.svg`): the proportion correct at each x with its 95 %
    /// Clopper–Pearson interval, the fitted function and the threshold; a degenerate fit shows
    /// its points and says why there is no curve.
    pub fn plots(&self) -> Vec<(String, String)> {
        let file = |kind: &str, name: &str| {
            let safe: String =
                name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
            format!("threshold-{kind}-{safe}.svg")
        };
        let mut plots = vec![("threshold-pooled.svg".to_string(), self.plot(&self.pooled, "all participants"))];
        for fit in &self.scenes {
            let name = fit.scene.as_deref().unwrap_or("");
            plots.push((file("scene", name), self.plot(fit, &format!("scene configuration {name}"))));
        }
        for fit in &self.participants {
            let name = fit.participant.as_deref().unwrap_or("");
            plots.push((file("participant", name), self.plot(fit, &format!("participant {name}"))));
        }
        plots
    }

    fn plot(&self, fit: &ThresholdFit, what: &str) -> String {
        use crate::plot::{LinePlot, LineSeries, line_plot};
        let observed: Vec<(f64, f64)> =
            fit.points.iter().map(|point| (point.x, f64::from(point.k) / f64::from(point.n))).collect();
        let intervals: Vec<[f64; 2]> = fit
            .points
            .iter()
            .map(|point| crate::detection::clopper_pearson(u64::from(point.k), u64::from(point.n), 0.95))
            .collect();
        let mut series = vec![
            LineSeries { name: "proportion correct".to_string(), points: observed },
            LineSeries {
                name: "95 % interval, lower".to_string(),
                points: fit.points.iter().zip(&intervals).map(|(point, ci)| (point.x, ci[0])).collect(),
            },
            LineSeries {
                name: "95 % interval, upper".to_string(),
                points: fit.points.iter().zip(&intervals).map(|(point, ci)| (point.x, ci[1])).collect(),
            },
        ];
        let title = match (fit.threshold, fit.degenerate) {
            (Some(threshold), _) => {
                let params = Params { threshold, slope: fit.slope.unwrap_or(1.0), lapse: fit.lapse.unwrap_or(0.0) };
                let (low, high) = fit.points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), point| {
                    (low.min(point.x), high.max(point.x))
                });
                let curve = (0..=80)
                    .map(|step| low + (high - low) * f64::from(step) / 80.0)
                    .map(|x| (x, self.function.prob(self.scale, x, params, self.guess)))
                    .filter(|(_, p)| p.is_finite())
                    .collect();
                series.push(LineSeries { name: format!("{} fit", self.function), points: curve });
                series.push(LineSeries {
                    name: format!("threshold {threshold:.3}"),
                    points: vec![(threshold, self.guess), (threshold, 1.0)],
                });
                format!("Threshold, {what}")
            }
            (None, reason) => format!("Threshold, {what}: no fit ({})", reason.unwrap_or("not estimable")),
        };
        line_plot(&LinePlot {
            title,
            x_label: format!("x ({} of the intensity)", self.scale),
            y_label: "proportion correct".to_string(),
            x_log: false,
            y_log: false,
            series,
        })
    }
}

/// The knob value at `x`: log10 of the knob interpolated linearly in x between the two levels
/// around it (levels sorted by x); `None` outside the levels or for a knob value ≤ 0.
fn knob_at(levels: &[(f64, f64)], x: f64) -> Option<f64> {
    let at = levels.windows(2).find(|pair| pair[0].0 <= x && x <= pair[1].0)?;
    let [(x0, k0), (x1, k1)] = [at[0], at[1]];
    if k0 <= 0.0 || k1 <= 0.0 {
        return None;
    }
    let t = if x1 > x0 { (x - x0) / (x1 - x0) } else { 0.0 };
    Some(10f64.powf(k0.log10() + t * (k1.log10() - k0.log10())))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An export of two participants on a 1…512 VPL grid (inverse-knob, log10: x = −log10
    /// knob) answering by a known Weibull, one of them always right.
    fn export() -> String {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut text =
            String::from("participant,scene,level,intensity,x,correct,function,scale,guess,pilot,excluded\n");
        let levels = [1.0f64, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0, 512.0];
        let (t, b, g) = (-1.5f64, 3.5f64, 0.5f64);
        for participant in ["p1", "p2"] {
            for trial in 0..200 {
                let level = levels[trial % levels.len()];
                let x = -level.log10();
                let p = 1.0 - (1.0 - g) * (-(10f64.powf(b * (x - t)))).exp();
                let correct = participant == "p2" || rng.random::<f64>() < p;
                let scene = if trial % 2 == 0 { "survey-1" } else { "survey-2" };
                text.push_str(&format!(
                    "{participant},{scene},{level},{},{x},{correct},weibull,log10,0.5,false,false\n",
                    1.0 / level
                ));
            }
        }
        text.push_str("pilot,survey-1,1,1,0,false,weibull,log10,0.5,true,false\n");
        text
    }

    #[test]
    fn a_threshold_export_is_fitted_pooled_per_participant_and_per_scene_and_a_perfect_participant_is_degenerate() {
        let text = export();
        assert!(is_threshold_csv(&text));
        let analysis = analyze_threshold_csv(&text, "t.csv", Overrides::default(), false, false, 50, 1).unwrap();
        assert_eq!(
            (analysis.function, analysis.scale, analysis.guess),
            (PsychFunction::Weibull, StimScale::Log10, 0.5)
        );
        assert_eq!(analysis.participants.len(), 2, "the pilot is left out");
        let p1 = &analysis.participants[0];
        let threshold = p1.threshold.unwrap();
        assert!((threshold + 1.5).abs() < 0.3, "{p1:?}");
        let knob = p1.knob_at_threshold.unwrap();
        assert!((knob - 10f64.powf(-threshold)).abs() < 1e-9 * knob, "inverse-knob on log10 is exact: {knob}");
        let [low, high] = p1.threshold_ci.unwrap();
        assert!(low <= threshold && threshold <= high);
        let p2 = &analysis.participants[1];
        assert_eq!(p2.degenerate, Some(super::super::fit::Degenerate::AllCorrect.reason()));
        assert!(p2.threshold.is_none());
        assert_eq!(analysis.scenes.len(), 2);
        assert_eq!(analysis.pooled.trials, 400);
        // one plot per fit; the degenerate participant's says why it has no curve
        let plots = analysis.plots();
        assert_eq!(plots.len(), 1 + 2 + 2);
        assert_eq!(plots[0].0, "threshold-pooled.svg");
        let p2_plot = &plots.iter().find(|(name, _)| name == "threshold-participant-p2.svg").unwrap().1;
        assert!(p2_plot.contains("no fit") && !p2_plot.contains("weibull fit"), "{p2_plot}");
        assert!(plots[0].1.contains("weibull fit") && plots[0].1.contains("<svg"));
        // the JSON never holds NaN or infinity
        let json = serde_json::to_string(&analysis).unwrap();
        assert!(!json.contains("NaN") && !json.contains("inf"), "{json}");
    }

    #[test]
    fn a_bad_cell_or_a_changing_model_is_one_sentence_naming_the_line() {
        let text = export().replacen(",true,weibull", ",yes,weibull", 1);
        let error = analyze_threshold_csv(&text, "t.csv", Overrides::default(), false, false, 0, 1).unwrap_err();
        assert!(error.to_string().contains("`correct` must be true or false"), "{error}");
        let text = export().replacen("weibull,log10,0.5,false,false\n", "weibull,dB,0.5,false,false\n", 2);
        let error = analyze_threshold_csv(&text, "t.csv", Overrides::default(), false, false, 0, 1).unwrap_err();
        assert!(error.to_string().contains("the same on every row"), "{error}");
        let text = export().replace("weibull,log10", "gompertz,log10");
        let error = analyze_threshold_csv(&text, "t.csv", Overrides::default(), false, false, 0, 1).unwrap_err();
        assert!(error.to_string().contains("--function"), "{error}");
        let overrides = Overrides { function: Some(PsychFunction::Logistic), ..Overrides::default() };
        assert!(analyze_threshold_csv(&text, "t.csv", overrides, false, false, 0, 1).is_ok());
    }
}
