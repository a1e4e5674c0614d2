//! What `mrstudy analyze` prints and draws for a rating export: the text table (conditions,
//! stimuli with MLE_CO's and the full model's quality, participants, the models) and, with `--plot-dir`, `ratings-mos.svg`: the MOS per
//! condition and per stimulus with their 95 % intervals. Numbers are formatted here (not by
//! `crate::table`, which calls this: no module cycle).

use std::fmt::Write as _;

use super::{Method, RatingsAnalysis};

/// `value` with `digits` decimals, never `-0.000`.
fn fixed(value: f64, digits: usize) -> String {
    let text = format!("{value:.digits$}");
    if text.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        text.trim_start_matches('-').to_string()
    } else {
        text
    }
}

fn interval(ci: Option<[f64; 2]>) -> String {
    ci.map_or("-".to_string(), |[low, high]| format!("[{}, {}]", fixed(low, 2), fixed(high, 2)))
}

fn optional(value: Option<f64>, digits: usize) -> String {
    value.map_or("-".to_string(), |value| fixed(value, digits))
}

/// The rating analysis as a text table.
pub fn render_table(analysis: &RatingsAnalysis) -> String {
    let mut out = String::new();
    let scores = match analysis.method {
        Method::AcrHr => "differential viewer scores DV = V(PVS) − V(REF) + 5",
        Method::Acr | Method::Dcr => "ratings",
    };
    let method = match analysis.method {
        Method::Acr => "ACR",
        Method::Dcr => "DCR",
        Method::AcrHr => "ACR-HR",
    };
    let _ = writeln!(
        out,
        "ratings ({method}, {} scale 1–5; {} {scores}; MOS with 95 % t-intervals)",
        analysis.scale, analysis.ratings
    );
    let _ = writeln!(out, "{:<24} {:>7} {:>7} {:>16}", "condition", "n", "MOS", "95 % interval");
    for condition in &analysis.conditions {
        let _ = writeln!(
            out,
            "{:<24} {:>7} {:>7} {:>16}{}",
            condition.condition,
            condition.ratings,
            fixed(condition.mos, 2),
            interval(condition.mos_ci),
            condition.note.map(|n| format!("  ({n})")).unwrap_or_default()
        );
    }
    out.push('\n');
    let _ = writeln!(
        out,
        "{:<16} {:<16} {:>5} {:>7} {:>16} {:>8} {:>7} {:>8} {:>7}",
        "scene", "condition", "n", "MOS", "95 % interval", "quality", "se", "MLE q", "se"
    );
    for stimulus in &analysis.stimuli {
        let full = analysis
            .full_model
            .stimuli
            .iter()
            .find(|full| full.scene == stimulus.scene && full.condition == stimulus.condition);
        let _ = writeln!(
            out,
            "{:<16} {:<16} {:>5} {:>7} {:>16} {:>8} {:>7} {:>8} {:>7}{}",
            stimulus.scene,
            stimulus.condition,
            stimulus.ratings,
            fixed(stimulus.mos, 2),
            interval(stimulus.mos_ci),
            optional(stimulus.quality, 3),
            optional(stimulus.quality_se, 3),
            optional(full.and_then(|f| f.quality), 3),
            optional(full.and_then(|f| f.quality_se), 3),
            stimulus.note.map(|n| format!("  ({n})")).unwrap_or_default()
        );
    }
    out.push('\n');
    let _ = writeln!(
        out,
        "{:<20} {:>7} {:>7} {:>7} {:>13} {:>7} {:>8}  screened",
        "participant", "ratings", "bias", "se", "inconsistency", "se", "outliers"
    );
    for participant in &analysis.participants {
        let screened = match (&participant.reason, participant.screened) {
            (Some(reason), true) => format!("yes: {reason}"),
            (Some(reason), false) => format!("no (screening off; would be: {reason})"),
            (None, _) => "no".to_string(),
        };
        let _ = writeln!(
            out,
            "{:<20} {:>7} {:>7} {:>7} {:>13} {:>7} {:>8}  {screened}{}",
            participant.participant,
            participant.ratings,
            optional(participant.bias, 3),
            optional(participant.bias_se, 3),
            optional(participant.inconsistency, 3),
            optional(participant.inconsistency_se, 3),
            participant.outlier_votes,
            participant.note.map(|n| format!(" ({n})")).unwrap_or_default()
        );
    }
    let model = &analysis.model;
    match (&model.not_estimable, model.log_likelihood) {
        (Some(reason), _) => {
            let _ = writeln!(out, "\nSUREAL {}: no estimate: {reason}", model.name);
        }
        (None, Some(log_likelihood)) => {
            let _ = writeln!(
                out,
                "\nSUREAL {} (quality, bias, inconsistency; standard errors as SUREAL's): log-likelihood {}, {} iterations{}",
                model.name,
                fixed(log_likelihood, 3),
                model.iterations,
                if model.converged { "" } else { ", NOT converged" }
            );
        }
        (None, None) => {}
    }
    let full = &analysis.full_model;
    match &full.not_estimable {
        Some(reason) => {
            let _ = writeln!(
                out,
                "SUREAL {} (content ambiguity per scene configuration): no estimate: {reason}",
                full.name
            );
        }
        None => {
            let _ = writeln!(
                out,
                "SUREAL {} (content ambiguity per scene configuration; `MLE q` above): {} iterations{}; {}",
                full.name,
                full.iterations,
                if full.converged { "" } else { ", NOT converged" },
                full.note
            );
        }
    }
    for warning in &analysis.warnings {
        let _ = writeln!(out, "warning: {warning}");
    }
    out
}

impl RatingsAnalysis {
    /// `ratings-mos.svg`: the MOS per condition (all scene configurations) and per stimulus,
    /// with 95 % t-intervals (none where one score).
    pub fn plots(&self) -> Vec<(String, String)> {
        use crate::plot::{EffectPoint, EffectSeries, mos_plot};
        let rows: Vec<String> = self.conditions.iter().map(|c| c.condition.clone()).collect();
        let point = |row: &str, mos: f64, ci: Option<[f64; 2]>| EffectPoint {
            factor: row.to_string(),
            estimate: mos,
            low: ci.map(|ci| ci[0]),
            high: ci.map(|ci| ci[1]),
        };
        let mut series = vec![EffectSeries {
            name: "all scene configurations".to_string(),
            points: self.conditions.iter().map(|c| point(&c.condition, c.mos, c.mos_ci)).collect(),
        }];
        let mut scenes: Vec<&str> = self.stimuli.iter().map(|s| s.scene.as_str()).collect();
        scenes.dedup();
        for scene in scenes {
            series.push(EffectSeries {
                name: format!("scene {scene}"),
                points: self
                    .stimuli
                    .iter()
                    .filter(|s| s.scene == scene)
                    .map(|s| point(&s.condition, s.mos, s.mos_ci))
                    .collect(),
            });
        }
        let label = match self.method {
            Method::AcrHr => "DMOS (DV = V(PVS) − V(REF) + 5)",
            Method::Acr => "MOS (5 Excellent … 1 Bad)",
            Method::Dcr => "MOS (5 Imperceptible … 1 Very annoying)",
        };
        vec![("ratings-mos.svg".to_string(), mos_plot("Mean opinion scores, 95 % t-intervals", label, &rows, &series))]
    }
}
