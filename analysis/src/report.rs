//! The analysis of a whole trials CSV, as `mrstudy analyze` prints it: the trials are split by
//! the reserved condition [`GROUND_TRUTH`] into preference trials (the usual Bradley–Terry
//! [`Analysis`], only where there are any) and detection trials ([`Detection`], only where
//! there are any), and, given a stimulus metrics CSV, the preference trials are set beside the
//! stimuli's image metrics ([`StimulusAnalysis`]).
//!
//! JSON: a [`Report`] is the Analysis JSON of the preference trials, with a `detection` and a
//! `metrics` section added where they apply; a file without detection trials and without
//! metrics gives exactly the Analysis JSON of before. A file of detection trials only gives
//! `{"detection": {…}}`, with the participants left out (pilots, excluded) said in it.

use serde::Serialize;

use crate::analysis::{Analysis, Options, Part, analyze_judgments_with_ties, not_estimable_part};
use crate::data::{ConditionTable, GROUND_TRUTH, TrialsOptions};
use crate::detection::{Detection, DetectionOptions, analyze_detection_by_scene};
use crate::error::{AnalysisError, Result};
use crate::stimulus_metrics::{StimulusAnalysis, StimulusMetrics, StimulusOptions};

/// Everything `mrstudy analyze` reports on a trials CSV.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The preference analysis (its fields at the top level of the JSON); absent when every
    /// trial is a detection trial.
    #[serde(flatten)]
    pub preference: Option<Analysis>,
    /// Detection rates of the conditions shown beside the ground truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detection: Option<Detection>,
    /// The stimuli's image metrics against the perceived preference (`--stimuli`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metrics: Option<StimulusAnalysis>,
    /// A threshold export's psychometric fits ([`crate::threshold::report`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold: Option<crate::threshold::report::ThresholdAnalysis>,
    /// A rating export's MOS, screening and SUREAL model ([`crate::ratings`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratings: Option<crate::ratings::RatingsAnalysis>,
}

/// Parses the trials, conditions and stimulus metrics CSV text and analyses them; the names
/// are used in error messages (e.g. file paths).
pub fn analyze_named(
    trials_csv: &str,
    trials_name: &str,
    conditions: Option<(&str, &str)>,
    stimuli: Option<(&str, &str)>,
    options: &Options,
) -> Result<Report> {
    let table = conditions.map(|(text, name)| crate::data::parse_conditions(text, name)).transpose()?;
    let metrics =
        stimuli.map(|(text, name)| crate::stimulus_metrics::parse_stimulus_metrics(text, name)).transpose()?;
    analyze_with_table(trials_csv, trials_name, table.as_ref(), metrics.as_ref(), options)
}

/// As [`analyze_named`], with the conditions and the stimulus metrics parsed already.
pub fn analyze_with_table(
    trials_csv: &str,
    trials_name: &str,
    table: Option<&ConditionTable>,
    stimuli: Option<&StimulusMetrics>,
    options: &Options,
) -> Result<Report> {
    if crate::ratings::is_rating_csv(trials_csv) {
        let rating_options = crate::ratings::RatingOptions {
            include_pilots: options.include_pilots,
            include_excluded: options.include_excluded,
            screening: options.screening != crate::analysis::Screening::Off,
        };
        let ratings = crate::ratings::analyze_rating_csv(trials_csv, trials_name, rating_options)?;
        return Ok(Report {
            preference: None,
            detection: None,
            metrics: None,
            threshold: None,
            ratings: Some(ratings),
        });
    }
    let trials_options = TrialsOptions {
        group_by: options.group_by.clone(),
        include_pilots: options.include_pilots,
        include_excluded: options.include_excluded,
        // the metrics join trials by scene; the detection analysis breaks its rates down by scene
        scenes: true,
        allow_ground_truth: true,
    };
    let mut parsed = crate::data::parse_trials_with(trials_csv, trials_name, table, &trials_options)?;
    let left_out = parsed.left_out.clone();
    let ties = std::mem::take(&mut parsed.ties);
    let split = crate::detection::split(parsed, table.map(|t| t.conditions.len()));
    let mut detection = split
        .detection
        .as_ref()
        .map(|j| analyze_detection_by_scene(j, split.detection_scenes.as_ref(), &DetectionOptions::default()))
        .transpose()?;
    let mut preference = None;
    let mut metrics = None;
    match &split.preference {
        Some((judgments, scenes)) => {
            // Detection trials renumber the preference trials' conditions: ties are analysed
            // only in a file without them.
            let tie_rows: &[crate::data::Judgment] = if detection.is_none() { &ties } else { &[] };
            let mut analysis = analyze_judgments_with_ties(judgments, tie_rows, table, options)?;
            if detection.is_some() && !ties.is_empty() {
                analysis.warnings.push(format!(
                    "{} ties (`chosen` = `tie`) are left out: a file with detection trials is analysed without its ties",
                    ties.len()
                ));
            }
            if let Some(detection) = &detection {
                analysis.warnings.push(format!(
                    "{} detection {} (one side `{GROUND_TRUTH}`) {} analysed apart, in `detection`",
                    detection.judgments,
                    if detection.judgments == 1 { "trial" } else { "trials" },
                    if detection.judgments == 1 { "is" } else { "are" },
                ));
            }
            if !left_out.is_empty() {
                analysis.warnings.insert(0, left_out.describe());
                analysis.left_out = Some(left_out);
            }
            if let Some(stimuli) = stimuli {
                let stimulus_options = StimulusOptions::from_analysis(options);
                match crate::stimulus_metrics::analyze_judgments(judgments, scenes.as_ref(), stimuli, &stimulus_options)
                {
                    Ok(section) => metrics = Some(section),
                    // A wrong option is the caller's to fix; anything else is the data so far.
                    Err(error @ AnalysisError::BadOption { .. }) => return Err(error),
                    Err(error) => not_estimable_part(
                        &mut analysis.warnings,
                        &mut analysis.not_estimable,
                        Part::Metrics,
                        error.to_string(),
                    ),
                }
            }
            preference = Some(analysis);
        }
        None => {
            let detection = detection.as_mut().expect("a split without preference trials has detection trials");
            if !left_out.is_empty() {
                detection.warnings.insert(0, left_out.describe());
                detection.left_out = Some(left_out);
            }
            if stimuli.is_some() && !crate::threshold::report::is_threshold_csv(trials_csv) {
                detection.warnings.push(
                    "the stimulus metrics are set beside preference trials, and every trial is a detection trial: no `metrics` section"
                        .to_string(),
                );
            }
        }
    }
    let threshold = if crate::threshold::report::is_threshold_csv(trials_csv) {
        let function = options
            .function
            .as_deref()
            .map(|text| {
                text.parse::<crate::threshold::PsychFunction>().map_err(|_| crate::error::AnalysisError::BadOption {
                    option: "--function".to_string(),
                    message: format!("expected weibull, logistic or normal, found \"{text}\""),
                })
            })
            .transpose()?;
        let overrides = crate::threshold::report::Overrides {
            function,
            scale: options.scale.stimulus_scale(),
            guess: options.guess,
        };
        let bootstrap =
            if options.bootstrap > 0 { options.bootstrap } else { crate::threshold::report::DEFAULT_BOOTSTRAP };
        let mut analysis = crate::threshold::report::analyze_threshold_csv(
            trials_csv,
            trials_name,
            overrides,
            options.include_pilots,
            options.include_excluded,
            bootstrap,
            options.seed,
        )?;
        if let Some(stimuli) = stimuli {
            let costs = stimulus_costs(stimuli);
            crate::threshold::at_threshold::fill_at_threshold(&mut analysis, &costs, "the --stimuli metrics CSV")?;
        }
        Some(analysis)
    } else {
        None
    };
    Ok(Report { preference, detection, metrics, threshold, ratings: None })
}

/// Each stimulus record's render time and mean FLIP in the affected region, for the values at a
/// threshold ([`crate::threshold::at_threshold`]).
fn stimulus_costs(metrics: &StimulusMetrics) -> Vec<crate::threshold::at_threshold::StimulusCost> {
    use crate::stimulus_metrics::{Metric, Region};
    metrics
        .stimuli
        .iter()
        .map(|record| crate::threshold::at_threshold::StimulusCost {
            scene: record.scene.clone(),
            condition: record.condition.clone(),
            render_ms: record.value(Metric::RenderMs, Region::Image),
            flip_mean: record.value(Metric::FlipMean, Region::Affected),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_detection_or_metrics_the_json_is_the_analysis_json() {
        let trials = "participant,left,right,chosen\np1,A,B,A\np1,B,C,B\np1,A,C,C\np2,A,B,B\np2,B,C,C\np2,A,C,A\n";
        let options = Options { screening: crate::analysis::Screening::Off, ..Options::default() };
        let report = analyze_named(trials, "t.csv", None, None, &options).unwrap();
        let analysis = crate::analysis::analyze_named(trials, "t.csv", None, &options).unwrap();
        assert_eq!(serde_json::to_string_pretty(&report).unwrap(), serde_json::to_string_pretty(&analysis).unwrap());
    }

    #[test]
    fn ground_truth_rows_are_split_off_even_with_a_conditions_file() {
        let trials = "participant,left,right,chosen,pilot,excluded\n\
                      p1,A,B,A,false,false\np1,B,A,B,false,false\np1,ground-truth,A,ground-truth,false,false\n\
                      p2,A,B,B,false,false\np2,B,A,A,false,false\np2,A,ground-truth,A,false,false\n\
                      p3,A,ground-truth,A,true,false\n";
        let conditions = "condition,gi\nA,0\nB,1\n";
        let options = Options { screening: crate::analysis::Screening::Off, ..Options::default() };
        let report = analyze_named(trials, "t.csv", Some((conditions, "c.csv")), None, &options).unwrap();
        let analysis = report.preference.as_ref().unwrap();
        assert_eq!((analysis.judgments, analysis.conditions), (4, 2));
        assert!(analysis.warnings[0].starts_with("left out 1 participant"), "{:?}", analysis.warnings);
        assert!(
            analysis
                .warnings
                .iter()
                .any(|w| w == "2 detection trials (one side `ground-truth`) are analysed apart, in `detection`")
        );
        let detection = report.detection.as_ref().unwrap();
        assert_eq!(detection.conditions.len(), 1);
        assert_eq!((detection.conditions[0].trials, detection.conditions[0].correct), (2, 1));
        assert!(detection.left_out.is_none());
        let json = serde_json::to_value(&report).unwrap();
        assert!(json["items"].is_array() && json["detection"]["conditions"].is_array());

        // Detection trials only: the detection section alone, with who was left out.
        let only = "participant,left,right,chosen,pilot,excluded\np1,ground-truth,A,A,false,false\np2,A,ground-truth,A,true,false\n";
        let report = analyze_named(only, "t.csv", Some((conditions, "c.csv")), None, &options).unwrap();
        assert!(report.preference.is_none());
        let detection = report.detection.unwrap();
        assert_eq!(detection.judgments, 1);
        assert_eq!(detection.left_out.map(|l| l.pilots), Some(1));
    }
}
