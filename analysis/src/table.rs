//! The analysis as a readable plain-text report for the terminal (`mrstudy analyze` without
//! `--format json`). Numbers are rounded for reading; the JSON carries full precision.

use std::fmt::Write;

use crate::analysis::{Analysis, LrTest};
use crate::pvalue::PValue;

fn lr(test: &LrTest) -> String {
    format!("χ² = {:.3}, df = {}, p = {}", test.chi2, test.df, test.p.display())
}

fn optional(value: Option<f64>, digits: usize) -> String {
    value.map(|v| format!("{v:.digits$}")).unwrap_or_else(|| "—".to_string())
}

/// Renders the whole analysis, groups included.
pub fn render(analysis: &Analysis) -> String {
    let mut out = String::new();
    render_into(&mut out, analysis, "");
    if let Some(groups) = &analysis.groups {
        for (name, group) in groups {
            let _ = writeln!(out, "\n=== group: {name} ===");
            render_into(&mut out, group, "");
        }
        if let Some(test) = &analysis.group_test {
            let _ = writeln!(out, "\nEqual effects in every group (likelihood ratio): {}", lr(test));
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
    let _ = write!(out, "\n{:<width$}  {:>9}  {:>7}  {:>7}  {:>9}  {:>11}", "condition", "log-worth", "se", "worth", "wins", "comparisons");
    if ci {
        let _ = write!(out, "  {:>19}", "bootstrap 95 %");
    }
    if fitted {
        let _ = write!(out, "  {:>12}  {:>7}", "fitted λ", "fitted π");
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
            let text = item.ci.map(|[lo, hi]| format!("[{lo:.3}, {hi:.3}]")).unwrap_or_else(|| "—".into());
            let _ = write!(out, "  {text:>19}");
        }
        if fitted {
            let _ = write!(out, "  {:>12}  {:>7}", optional(item.fitted_log_worth, 4), optional(item.fitted_worth, 4));
        }
        if let Some(component) = item.component {
            let _ = write!(out, "  (component {})", component + 1);
        }
        out.push('\n');
    }
    let m = &analysis.item_model;
    let _ = writeln!(out, "item model: log-likelihood {:.4}, deviance {:.4}, AIC {:.4}, residual df {}", m.log_likelihood, m.deviance, m.aic, m.df_residual);

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
            let _ = write!(out, "{:<width$}  {:>9.4}  {:>7.4}  {:>8.3}  {:>10}", c.name, c.estimate, c.se, c.z, c.p.display());
            if let Some([lo, hi]) = c.ci {
                let _ = write!(out, "  {:>19}", format!("[{lo:.3}, {hi:.3}]"));
            }
            out.push('\n');
        }
        let s = &model.summary;
        let _ = writeln!(out, "log-likelihood {:.4}, deviance {:.4}, AIC {:.4}, residual df {}", s.log_likelihood, s.deviance, s.aic, s.df_residual);
        if let Some(test) = &model.lr_vs_items {
            let _ = writeln!(out, "factor model against item model: {}", lr(test));
        }
    }

    let a = &analysis.agreement;
    match a.u {
        Some(u) => {
            let _ = write!(out, "\ncoefficient of agreement u = {u:.4}");
            if let (Some(chi2), Some(df)) = (a.chi2, a.df) {
                let _ = write!(out, ", χ² = {chi2:.3}, df = {df:.2}");
            }
            if let Some(p) = &a.p {
                let method = match (a.method, a.simulations) {
                    (crate::agreement::AgreementMethod::Simulation, Some(b)) => format!("Monte-Carlo, {b} simulations"),
                    (crate::agreement::AgreementMethod::Chi2, _) => "χ² approximation".to_string(),
                    (crate::agreement::AgreementMethod::Chi2Generalised, _) => "generalised χ², three matched cumulants".to_string(),
                    _ => "—".to_string(),
                };
                let _ = write!(out, ", p = {} ({method})", PValue::display(p));
            }
            out.push('\n');
        }
        None => {
            let _ = writeln!(out, "\ncoefficient of agreement: not defined ({})", a.note.as_deref().unwrap_or("no pair judged twice"));
        }
    }
    if !analysis.consistence.is_empty() {
        let zetas: Vec<f64> = analysis.consistence.iter().filter_map(|c| c.consistence.zeta).collect();
        if !zetas.is_empty() {
            let mean = zetas.iter().sum::<f64>() / zetas.len() as f64;
            let _ = writeln!(out, "coefficient of consistence ζ: mean {mean:.3} over {} participants who compared every pair", zetas.len());
        }
    }
    if let Some(screening) = &analysis.observers {
        if screening.flagged.is_empty() {
            let _ = writeln!(out, "observer screening: no participant flagged (leave-one-out p < {})", screening.alpha);
        } else {
            let _ = writeln!(out, "observer screening: flagged (leave-one-out p < {}), not dropped: {}", screening.alpha, screening.flagged.join(", "));
        }
    }
    if let Some(bootstrap) = &analysis.bootstrap {
        let _ = writeln!(out, "bootstrap over participants: {} replicates, seed {}, {} failed", bootstrap.replicates, bootstrap.seed, bootstrap.failed);
    }
    for warning in &analysis.warnings {
        let _ = writeln!(out, "warning: {warning}");
    }
}
