//! The analysis as a readable plain-text report for the terminal (`mrstudy analyze` without
//! `--format json`). Numbers are rounded for reading; the JSON carries full precision. Every
//! number with a fixed count of decimals goes through [`fixed`], which never writes `-0.000`,
//! `NaN` or `inf`.

use std::fmt::Write;

use crate::analysis::{Analysis, GroupResult, LrTest};
use crate::pvalue::PValue;

/// `value` with `digits` decimals. A value that rounds to zero is written without a sign
/// (`0.000`, never `-0.000`); a non-finite value (which the analysis never produces) as `—`.
pub fn fixed(value: f64, digits: usize) -> String {
    if !value.is_finite() {
        return "—".to_string();
    }
    let text = format!("{value:.digits$}");
    match text.strip_prefix('-') {
        Some(unsigned) if unsigned.bytes().all(|b| b == b'0' || b == b'.') => unsigned.to_string(),
        _ => text,
    }
}

fn lr(test: &LrTest) -> String {
    format!("χ² = {}, df = {}, {}", fixed(test.chi2, 3), test.df, test.p.equation())
}

fn optional(value: Option<f64>, digits: usize) -> String {
    value.map(|v| fixed(v, digits)).unwrap_or_else(|| "—".to_string())
}

/// `n` and the noun, plural unless `n` is 1.
fn counted(n: u64, noun: &str) -> String {
    if n == 1 { format!("1 {noun}") } else { format!("{n} {noun}s") }
}

fn interval([low, high]: [f64; 2]) -> String {
    format!("[{}, {}]", fixed(low, 3), fixed(high, 3))
}

/// Renders the whole analysis, groups included.
pub fn render(analysis: &Analysis) -> String {
    let mut out = String::new();
    render_into(&mut out, analysis, "");
    if let Some(groups) = &analysis.groups {
        for (name, group) in groups {
            let _ = writeln!(out, "\n=== group: {name} ===");
            match group {
                GroupResult::Estimated(group) => render_into(&mut out, group, ""),
                GroupResult::NotEstimable(group) => {
                    let _ = writeln!(
                        out,
                        "not estimable ({} by {}): {}",
                        counted(group.judgments, "judgment"),
                        counted(group.participants as u64, "participant"),
                        group.reason
                    );
                }
            }
        }
        if let Some(test) = &analysis.group_test {
            let _ = write!(out, "\nEqual effects in every group (likelihood ratio): {}", lr(test));
            if !analysis.group_test_left_out.is_empty() {
                let _ = write!(out, " (estimable groups only; left out: {})", analysis.group_test_left_out.join(", "));
            }
            out.push('\n');
        }
    }
    out
}

fn render_into(out: &mut String, analysis: &Analysis, _indent: &str) {
    let _ = writeln!(
        out,
        "{} judgments by {} participants on {} conditions; reference {}; {}",
        analysis.judgments,
        analysis.participants,
        analysis.conditions,
        analysis.reference,
        analysis.method.describe()
    );
    let width = analysis.items.iter().map(|i| i.condition.chars().count()).max().unwrap_or(9).max(9);
    let fitted = analysis.items.iter().any(|i| i.fitted_log_worth.is_some());
    let ci = analysis.items.iter().any(|i| i.ci.is_some());
    let jod = analysis.items.iter().any(|i| i.jod.is_some());
    let jod_ci = analysis.items.iter().any(|i| i.jod_ci.is_some());
    let _ = write!(
        out,
        "\n{:<width$}  {:>9}  {:>7}  {:>7}  {:>9}  {:>11}",
        "condition", "log-worth", "se", "worth", "wins", "comparisons"
    );
    if ci {
        let _ = write!(out, "  {:>19}", "bootstrap 95 %");
    }
    if fitted {
        let _ = write!(out, "  {:>12}  {:>7}", "fitted λ", "fitted π");
    }
    if jod {
        let _ = write!(out, "  {:>7}", "JOD");
    }
    if jod_ci {
        let _ = write!(out, "  {:>19}", "JOD 95 %");
    }
    out.push('\n');
    for item in &analysis.items {
        let _ = write!(
            out,
            "{:<width$}  {:>9}  {:>7}  {:>7}  {:>9}  {:>11}",
            item.condition,
            optional(item.log_worth, 4),
            optional(item.se, 4),
            optional(item.worth, 4),
            item.wins,
            item.comparisons
        );
        if ci {
            let text = item.ci.map(interval).unwrap_or_else(|| "—".into());
            let _ = write!(out, "  {text:>19}");
        }
        if fitted {
            let _ = write!(out, "  {:>12}  {:>7}", optional(item.fitted_log_worth, 4), optional(item.fitted_worth, 4));
        }
        if jod {
            let _ = write!(out, "  {:>7}", optional(item.jod, 3));
        }
        if jod_ci {
            let text = item.jod_ci.map(interval).unwrap_or_else(|| "—".into());
            let _ = write!(out, "  {text:>19}");
        }
        if let Some(component) = item.component {
            let _ = write!(out, "  (component {})", component + 1);
        }
        out.push('\n');
    }
    if let Some(section) = &analysis.jod_scale {
        let outliers = if section.outliers.is_empty() { "none".to_string() } else { section.outliers.join(", ") };
        let _ = writeln!(out, "JOD (pwcmp, 1 JOD = 75 %): outliers by dist_L > 1.5: {outliers}");
    }
    if let Some(davidson) = &analysis.davidson {
        let se = davidson.nu_se.map(|se| format!(" (se {})", fixed(se, 4))).unwrap_or_default();
        let worths: Vec<String> =
            davidson.items.iter().map(|item| format!("{} {}", item.condition, optional(item.log_worth, 4))).collect();
        let _ = writeln!(
            out,
            "Davidson tie model over {} ties: ν = {}{se}; log-worth {}",
            davidson.ties,
            fixed(davidson.nu, 4),
            worths.join(", ")
        );
    }
    let m = &analysis.item_model;
    let _ = writeln!(
        out,
        "item model: log-likelihood {}, deviance {}, AIC {}, residual df {}",
        fixed(m.log_likelihood, 4),
        fixed(m.deviance, 4),
        fixed(m.aic, 4),
        m.df_residual
    );

    if let (Some(covariates), Some(model)) = (&analysis.covariates, &analysis.covariate_model) {
        let _ = writeln!(out, "\nfactor model {} ({})", model.formula, model.summary.method.describe());
        let width = covariates.iter().map(|c| c.name.chars().count()).max().unwrap_or(6).max(6);
        let _ = write!(out, "{:<width$}  {:>9}  {:>7}  {:>8}  {:>10}", "factor", "estimate", "se", "z", "p");
        let ci = covariates.iter().any(|c| c.ci.is_some());
        if ci {
            let _ = write!(out, "  {:>19}", "bootstrap 95 %");
        }
        out.push('\n');
        for c in covariates {
            let _ = write!(
                out,
                "{:<width$}  {:>9}  {:>7}  {:>8}  {:>10}",
                c.name,
                fixed(c.estimate, 4),
                fixed(c.se, 4),
                fixed(c.z, 3),
                c.p.display()
            );
            if let Some(ci) = c.ci {
                let _ = write!(out, "  {:>19}", interval(ci));
            }
            out.push('\n');
        }
        let s = &model.summary;
        let _ = writeln!(
            out,
            "log-likelihood {}, deviance {}, AIC {}, residual df {}",
            fixed(s.log_likelihood, 4),
            fixed(s.deviance, 4),
            fixed(s.aic, 4),
            s.df_residual
        );
        if let Some(test) = &model.lr_vs_items {
            let _ = writeln!(out, "factor model against item model: {}", lr(test));
        }
    }

    let a = &analysis.agreement;
    match a.u {
        Some(u) => {
            let _ = write!(out, "\ncoefficient of agreement u = {}", fixed(u, 4));
            if let (Some(chi2), Some(df)) = (a.chi2, a.df) {
                let _ = write!(out, ", χ² = {}, df = {}", fixed(chi2, 3), fixed(df, 2));
            }
            if let Some(p) = &a.p {
                let method = match (a.method, a.simulations) {
                    (crate::agreement::AgreementMethod::Simulation, Some(b)) => format!("Monte-Carlo, {b} simulations"),
                    (crate::agreement::AgreementMethod::Chi2, _) => "χ² approximation".to_string(),
                    (crate::agreement::AgreementMethod::Chi2Generalised, _) => {
                        "generalised χ², three matched cumulants".to_string()
                    }
                    _ => "—".to_string(),
                };
                let _ = write!(out, ", {} ({method})", PValue::equation(p));
            }
            out.push('\n');
        }
        None => {
            let _ = writeln!(
                out,
                "\ncoefficient of agreement: not defined ({})",
                a.note.as_deref().unwrap_or("no pair judged twice")
            );
        }
    }
    if !analysis.consistence.is_empty() {
        let zetas: Vec<f64> = analysis.consistence.iter().filter_map(|c| c.consistence.zeta).collect();
        if !zetas.is_empty() {
            let mean = zetas.iter().sum::<f64>() / zetas.len() as f64;
            let _ = writeln!(
                out,
                "coefficient of consistence ζ: mean {} over {} participants who compared every pair",
                fixed(mean, 3),
                zetas.len()
            );
        }
    }
    if let Some(screening) = &analysis.observers {
        if screening.flagged.is_empty() {
            let _ = writeln!(out, "observer screening: no participant flagged (leave-one-out p < {})", screening.alpha);
        } else {
            let _ = writeln!(
                out,
                "observer screening: flagged (leave-one-out p < {}), not dropped: {}",
                screening.alpha,
                screening.flagged.join(", ")
            );
        }
    }
    if let Some(bootstrap) = &analysis.bootstrap {
        let _ = writeln!(
            out,
            "bootstrap over participants: {} replicates, seed {}, {} failed",
            bootstrap.replicates, bootstrap.seed, bootstrap.failed
        );
    }
    for warning in &analysis.warnings {
        let _ = writeln!(out, "warning: {warning}");
    }
}

/// Renders everything `mrstudy analyze` reports: the preference analysis (as [`render`]), then
/// the detection and the stimulus-metrics sections where present.
pub fn render_report(report: &crate::report::Report) -> String {
    let mut out = report.preference.as_ref().map(render).unwrap_or_default();
    if let Some(detection) = &report.detection {
        if !out.is_empty() {
            out.push('\n');
        }
        render_detection(&mut out, detection);
    }
    if let Some(metrics) = &report.metrics {
        if !out.is_empty() {
            out.push('\n');
        }
        render_metrics(&mut out, metrics);
    }
    if let Some(threshold) = &report.threshold {
        if !out.is_empty() {
            out.push('\n');
        }
        render_threshold(&mut out, threshold);
    }
    if let Some(ratings) = &report.ratings {
        out.push_str(&crate::ratings::report::render_table(ratings));
    }
    out
}

/// The threshold fits: pooled, per scene configuration, per participant (x units; the knob
/// value at the threshold; the reason where a fit is degenerate).
fn render_threshold(out: &mut String, analysis: &crate::threshold::report::ThresholdAnalysis) {
    let _ = writeln!(
        out,
        "threshold ({} on {}, guess {}; 95 % intervals from {} parametric bootstrap replicates)",
        analysis.function, analysis.scale, analysis.guess, analysis.bootstrap
    );
    let _ = writeln!(
        out,
        "{:<24}  {:>6}  {:>9}  {:>19}  {:>7}  {:>6}  {:>10}  {:>6}",
        "fit", "trials", "threshold", "interval", "slope", "lapse", "knob there", "p_fit"
    );
    let rows = std::iter::once(("pooled".to_string(), &analysis.pooled))
        .chain(analysis.scenes.iter().map(|fit| (format!("scene {}", fit.scene.as_deref().unwrap_or("")), fit)))
        .chain(
            analysis
                .participants
                .iter()
                .map(|fit| (format!("participant {}", fit.participant.as_deref().unwrap_or("")), fit)),
        );
    for (name, fit) in rows {
        let name: String = name.chars().take(24).collect();
        match (fit.threshold, fit.degenerate) {
            (Some(threshold), _) => {
                let interval = fit
                    .threshold_ci
                    .map(|[low, high]| format!("[{}, {}]", fixed(low, 3), fixed(high, 3)))
                    .unwrap_or_else(|| "-".to_string());
                let _ = writeln!(
                    out,
                    "{:<24}  {:>6}  {:>9}  {:>19}  {:>7}  {:>6}  {:>10}  {:>6}",
                    name,
                    fit.trials,
                    fixed(threshold, 3),
                    interval,
                    fit.slope.map_or("-".to_string(), |slope| fixed(slope, 2)),
                    fit.lapse.map_or("-".to_string(), |lapse| fixed(lapse, 3)),
                    fit.knob_at_threshold.map_or("-".to_string(), |knob| fixed(knob, 1)),
                    fit.p_fit.map_or("-".to_string(), |p| fixed(p, 3)),
                );
                if fit.render_ms_at_threshold.is_some() || fit.flip_mean_at_threshold.is_some() {
                    let at = |value: Option<f64>, digits: usize| value.map_or("-".to_string(), |v| fixed(v, digits));
                    let _ = writeln!(
                        out,
                        "{:<24}  there (--stimuli): render {} ms, FLIP mean (affected) {}",
                        "",
                        at(fit.render_ms_at_threshold, 1),
                        at(fit.flip_mean_at_threshold, 4)
                    );
                }
                if let Some(note) = fit.note {
                    let _ = writeln!(out, "{:<24}  note: {note}", "");
                }
            }
            (None, reason) => {
                let _ = writeln!(out, "{:<24}  {:>6}  no fit: {}", name, fit.trials, reason.unwrap_or("not estimable"));
            }
        }
    }
}

fn render_detection(out: &mut String, detection: &crate::detection::Detection) {
    let _ = writeln!(
        out,
        "detection (real or rendered?): {} by {}; rate = share of trials in which `{}` was chosen as real, chance {}",
        counted(detection.judgments, "judgment"),
        counted(detection.participants as u64, "participant"),
        crate::detection::GROUND_TRUTH,
        detection.chance
    );
    let width = detection.conditions.iter().map(|c| c.condition.chars().count()).max().unwrap_or(9).max(9);
    let level = format!("{} % interval", fixed(100.0 * detection.level, 0));
    let _ = writeln!(
        out,
        "{:<width$}  {:>7}  {:>7}  {:>6}  {:>16}  {:>10}  {:>7}  {:>6}  {:>5}  verdict",
        "condition", "trials", "correct", "rate", level, "p", "d′", "se", "power"
    );
    for c in &detection.conditions {
        let _ = writeln!(
            out,
            "{:<width$}  {:>7}  {:>7}  {:>6}  {:>16}  {:>10}  {:>7}  {:>6}  {:>5}  {}",
            c.condition,
            c.trials,
            c.correct,
            fixed(c.rate, 3),
            interval(c.ci),
            c.p.display(),
            fixed(c.d_prime, 3),
            fixed(c.d_prime_se, 3),
            fixed(c.power, 3),
            c.verdict.describe(c.power)
        );
    }
    let _ = writeln!(
        out,
        "interval: Clopper–Pearson; p: exact two-sided binomial test against {} (R's binom.test); d′ = √2·Φ⁻¹(rate) (2AFC); \
         power: of that test at α = {} with the condition's trials against a true rate of {}; \
         indistinguishable = not significant with power ≥ {}",
        detection.chance, detection.alpha, detection.alternative_rate, detection.target_power
    );
    for c in &detection.conditions {
        for note in &c.notes {
            let _ = writeln!(out, "note: {}: {note}", c.condition);
        }
    }
    if !detection.scenes.is_empty() {
        render_detection_scenes(out, detection, &level);
    }
    for warning in &detection.warnings {
        let _ = writeln!(out, "warning: {warning}");
    }
}

/// The per-scene-configuration table of a detection analysis: each configuration's trials,
/// ground truth chosen, rate, interval and test, and its counts per condition.
fn render_detection_scenes(out: &mut String, detection: &crate::detection::Detection, level: &str) {
    let _ =
        writeln!(out, "per scene configuration (all conditions together; by condition: ground truth chosen / trials):");
    let width = detection.scenes.iter().map(|s| s.scene.chars().count()).max().unwrap_or(9).max(9);
    let _ = writeln!(
        out,
        "{:<width$}  {:>7}  {:>7}  {:>6}  {:>16}  {:>10}  by condition",
        "scene", "trials", "correct", "rate", level, "p"
    );
    for scene in &detection.scenes {
        let by_condition: Vec<String> =
            scene.conditions.iter().map(|c| format!("{} {}/{}", c.condition, c.correct, c.trials)).collect();
        let _ = writeln!(
            out,
            "{:<width$}  {:>7}  {:>7}  {:>6}  {:>16}  {:>10}  {}",
            scene.scene,
            scene.trials,
            scene.correct,
            fixed(scene.rate, 3),
            interval(scene.ci),
            scene.p.display(),
            by_condition.join(", ")
        );
    }
    if !detection.showings.is_empty() {
        let _ = writeln!(
            out,
            "by showing (a participant's 1st, 2nd, … trial of a scene configuration, in file order; a rising rate is learning):"
        );
        for showing in &detection.showings {
            let _ = writeln!(
                out,
                "{:<width$}  {:>7}  {:>7}  {:>6}  {:>16}  {:>10}",
                format!("showing {}", showing.showing),
                showing.trials,
                showing.correct,
                fixed(showing.rate, 3),
                interval(showing.ci),
                showing.p.display()
            );
        }
    }
}

fn render_metrics(out: &mut String, metrics: &crate::stimulus_metrics::StimulusAnalysis) {
    let items = metrics.items.iter().filter(|i| i.log_worth.is_some()).count();
    let _ = writeln!(out, "image metrics against perceived preference, {}", metrics.level_reason);
    if let Some(averaging) = &metrics.averaging {
        let _ = writeln!(out, "averaging: {averaging}");
    }
    let _ = write!(
        out,
        "{} fitted by {} from {} by {}; reference {}",
        counted(items as u64, "item"),
        metrics.method.describe(),
        counted(metrics.judgments, "judgment"),
        counted(metrics.participants as u64, "participant"),
        metrics.reference
    );
    if let Some(bootstrap) = &metrics.bootstrap {
        let _ = write!(
            out,
            "; intervals: {} % {} bootstrap over participants, {} replicates, seed {}, {} failed",
            fixed(100.0 * bootstrap.level, 0),
            bootstrap.method,
            bootstrap.replicates,
            bootstrap.seed,
            bootstrap.failed
        );
    }
    out.push('\n');
    if !metrics.correlations.is_empty() {
        let _ = writeln!(
            out,
            "{:>4}  {:<14}  {:<8}  {:>5}  {:>9}  {:>16}  {:>9}  {:>16}  {:>9}",
            "rank", "metric", "region", "items", "ρ", "interval", "τb", "interval", "agreement"
        );
        for c in &metrics.correlations {
            let ci = |ci: Option<[f64; 2]>| ci.map(interval).unwrap_or_else(|| "—".to_string());
            let _ = writeln!(
                out,
                "{:>4}  {:<14}  {:<8}  {:>5}  {:>9}  {:>16}  {:>9}  {:>16}  {:>9}",
                c.rank.unwrap_or_default(),
                c.metric.name(),
                c.region.name(),
                c.items,
                fixed(c.spearman_rho, 3),
                ci(c.spearman_ci),
                fixed(c.kendall_tau_b, 3),
                ci(c.kendall_ci),
                fixed(c.agreement, 3)
            );
        }
    }
    if !metrics.timings.is_empty() {
        let _ = writeln!(out, "timings (costs of making the image, not image errors; not ranked):");
        for c in &metrics.timings {
            let ci = |ci: Option<[f64; 2]>| ci.map(interval).unwrap_or_else(|| "—".to_string());
            let _ = writeln!(
                out,
                "      {:<14}  {:<8}  {:>5}  ρ {:>7} {:>16}  τb {:>7} {:>16}",
                c.metric.name(),
                c.region.name(),
                c.items,
                fixed(c.spearman_rho, 3),
                ci(c.spearman_ci),
                fixed(c.kendall_tau_b, 3),
                ci(c.kendall_ci)
            );
        }
    }
    match &metrics.best {
        Some(best) => {
            let _ = writeln!(
                out,
                "best predictor of preference: {} ({} region), agreement {}",
                best.metric.name(),
                best.region.name(),
                fixed(best.agreement, 3)
            );
        }
        None => {
            let _ = writeln!(out, "no metric could be set beside the preference (see below)");
        }
    }
    let _ = writeln!(out, "ranked by {}", metrics.ranked_by);
    if metrics.bootstrap.is_some() && !metrics.correlations.is_empty() {
        let _ = writeln!(
            out,
            "intervals: over participants, the stimuli held fixed; of the correlation with the worths themselves: noise in the estimated worths pulls ρ and τb towards 0, so an interval may lie beyond them"
        );
    }
    // Grouped by reason, in order of first appearance.
    let mut reasons: Vec<(&str, Vec<String>)> = Vec::new();
    for not in &metrics.not_computed {
        let name = format!("{} ({})", not.metric.name(), not.region.name());
        match reasons.iter_mut().find(|(reason, _)| *reason == not.reason) {
            Some((_, names)) => names.push(name),
            None => reasons.push((&not.reason, vec![name])),
        }
    }
    for (reason, names) in reasons {
        let _ = writeln!(out, "not computed: {}: {reason}", names.join(", "));
    }
    for warning in &metrics.warnings {
        let _ = writeln!(out, "warning: {warning}");
    }
}
