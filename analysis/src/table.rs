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
        if let Some(component) = item.component {
            let _ = write!(out, "  (component {})", component + 1);
        }
        out.push('\n');
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
