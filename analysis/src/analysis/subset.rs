//! One fit of the analysis over a subset of the judgments (all of them, or one group's): the
//! item model per connected component (Firth's estimate under separation), the factor model
//! over the identifiable terms, agreement, consistence per participant, and the optional JOD
//! scale, observer screening and bootstrap.

use crate::agreement::{self, AgreementOptions};
use crate::data::{ConditionTable, Judgment, Judgments};
use crate::design::{self, Dropped, PairTally, ParticipantTallies, Term};
use crate::fit::{self, Fit, FitFailure, FitOptions, Method, ModelMatrix};
use crate::pvalue::PValue;
use crate::{AnalysisError, Result};

use super::bootstrap::run_bootstrap;
use super::robust::{cluster_robust_covariance, robust_variance_of};
use super::screen::screen_observers;
use super::{
    Analysis, Component, Covariate, CovariateModel, DroppedTerm, Item, LrTest, ModelSummary, Options, Part,
    ParticipantConsistence, SCREENING_AUTO_LIMIT, Scale, Screening, not_estimable_part,
};

pub(crate) struct ItemFit {
    /// Per component: members, reference, fit, separation SCCs.
    pub(crate) components: Vec<(Vec<usize>, usize, Fit, Option<Vec<Vec<usize>>>)>,
}

pub(crate) fn fit_items(
    n_conditions: usize,
    pairs: &[PairTally],
    reference: usize,
    options: &Options,
) -> std::result::Result<ItemFit, FitFailure> {
    let fit_options = FitOptions { tolerance: options.tolerance, ..FitOptions::default() };
    let mut components = Vec::new();
    for members in design::components(n_conditions, pairs) {
        let component_reference = if members.contains(&reference) { reference } else { members[0] };
        let x = ModelMatrix::items(n_conditions, &members, component_reference);
        let in_component: Vec<PairTally> =
            pairs.iter().filter(|p| members.binary_search(&p.i).is_ok()).copied().collect();
        let separated = design::separation(&members, &in_component);
        let fit = if separated.is_some() || options.always_firth {
            fit::fit_firth(&in_component, &x, fit_options)?
        } else {
            fit::fit_ml(&in_component, &x, None, fit_options)?
        };
        components.push((members, component_reference, fit, separated));
    }
    Ok(ItemFit { components })
}

pub(crate) fn failure_message(what: &str, failure: FitFailure) -> AnalysisError {
    let message = match failure {
        FitFailure::Singular => format!("the {what} is not identifiable (singular information matrix)"),
        FitFailure::Separation => {
            format!("the {what} has no finite maximum-likelihood estimate (separation) and its bias-reduced fit failed")
        }
        FitFailure::NotConverged { iterations, last_change } => {
            format!("the {what} did not converge in {iterations} iterations (last change {last_change:.3e})")
        }
    };
    AnalysisError::Empty(message)
}

/// What every fit of one analysis shares: the judgments, the conditions' factor table, the
/// factor model's formula and terms, the reference condition and the options.
#[derive(Clone, Copy)]
pub(super) struct Inputs<'a> {
    pub(super) judgments: &'a Judgments,
    pub(super) table: Option<&'a ConditionTable>,
    pub(super) terms: Option<&'a (String, Vec<Term>)>,
    pub(super) reference: usize,
    pub(super) options: &'a Options,
}

/// The judgments one fit is of: the participants `active` with their `tallies` (all of them,
/// or one group's), and the judgments among them answered `tie`.
#[derive(Clone, Copy)]
pub(super) struct Subset<'a> {
    pub(super) tallies: &'a ParticipantTallies,
    pub(super) active: &'a [usize],
    pub(super) ties: &'a [Judgment],
}

/// The analysis of one subset of the judgments (all of them, or one group's): item model,
/// factor model, agreement, consistence, JOD, observer screening and bootstrap.
pub(super) fn analyze_subset(inputs: &Inputs, subset: &Subset) -> Result<Analysis> {
    let Inputs { judgments, table, terms, reference, options } = *inputs;
    let Subset { tallies, active, ties } = *subset;
    let n_conditions = judgments.conditions.len();
    let names = &judgments.conditions;
    let pairs = tallies.pooled(n_conditions, active);
    let mut warnings = Vec::new();
    let mut not_estimable = Vec::new();

    let mut wins = vec![0u64; n_conditions];
    let mut comparisons = vec![0u64; n_conditions];
    for pair in &pairs {
        wins[pair.i] += pair.wins_i;
        wins[pair.j] += pair.wins_j;
        comparisons[pair.i] += pair.n();
        comparisons[pair.j] += pair.n();
    }
    let never = (0..n_conditions).filter(|&c| comparisons[c] == 0).map(|c| names[c].clone()).collect::<Vec<_>>();
    if !never.is_empty() {
        warnings.push(format!("never compared, so not estimated: {}", never.join(", ")));
    }
    let mut reference = reference;
    if comparisons[reference] == 0 {
        let replacement = (0..n_conditions).find(|&c| comparisons[c] > 0).expect("at least one judgment");
        warnings.push(format!(
            "the reference `{}` was never compared; `{}` is the reference instead",
            names[reference], names[replacement]
        ));
        reference = replacement;
    }

    let item_fit = fit_items(n_conditions, &pairs, reference, options).map_err(|f| failure_message("item model", f))?;
    let multiple = item_fit.components.len() > 1;
    if multiple {
        let listed: Vec<String> = item_fit
            .components
            .iter()
            .map(|(members, ..)| {
                format!("{{{}}}", members.iter().map(|&m| names[m].as_str()).collect::<Vec<_>>().join(", "))
            })
            .collect();
        warnings.push(format!(
            "the comparison graph is disconnected into {} components: {}; log-worth is relative to each component's reference and no difference across components is reported",
            item_fit.components.len(),
            listed.join(", ")
        ));
    }

    let mut items: Vec<Item> = (0..n_conditions)
        .map(|c| Item {
            condition: names[c].clone(),
            log_worth: None,
            se: None,
            model_se: None,
            worth: None,
            wins: wins[c],
            comparisons: comparisons[c],
            component: None,
            fitted_log_worth: None,
            fitted_worth: None,
            ci: None,
            log_worth_map: None,
            jod: None,
            jod_ci: None,
        })
        .collect();
    let mut components = Vec::new();
    for (k, (members, component_reference, fit, separated)) in item_fit.components.iter().enumerate() {
        let x = ModelMatrix::items(n_conditions, members, *component_reference);
        // The participants' own tastes, as for the factor effects below (see `robust`).
        let robust = (fit.method == Method::Ml).then(|| cluster_robust_covariance(fit, &x, tallies, active)).flatten();
        let lambdas: Vec<f64> = members.iter().map(|&m| x.predict(m, &fit.beta)).collect();
        let max = lambdas.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let total: f64 = lambdas.iter().map(|l| (l - max).exp()).sum();
        for (&member, &lambda) in members.iter().zip(&lambdas) {
            let item = &mut items[member];
            item.log_worth = Some(lambda + 0.0); // + 0.0 turns −0 into 0
            let model_se = fit.variance_of(&x.rows[member]).sqrt();
            let robust_se = robust.as_ref().map_or(0.0, |v| robust_variance_of(v, &x.rows[member]).max(0.0).sqrt());
            item.se = Some(model_se.max(robust_se));
            item.model_se = Some(model_se);
            item.worth = Some((lambda - max).exp() / total);
            item.component = multiple.then_some(k);
        }
        let (mut never_lost, mut never_won) = (Vec::new(), Vec::new());
        if let Some(sccs) = separated {
            never_lost = sccs[0].iter().map(|&m| names[m].clone()).collect();
            never_won = sccs[sccs.len() - 1].iter().map(|&m| names[m].clone()).collect();
            warnings.push(format!(
                "separation: within its comparisons {{{}}} never lost and {{{}}} never won, so the maximum-likelihood estimate does not exist; the item model is Firth's bias-reduced estimate",
                never_lost.join(", "),
                never_won.join(", ")
            ));
        }
        components.push(Component {
            conditions: members.iter().map(|&m| names[m].clone()).collect(),
            reference: names[*component_reference].clone(),
            method: fit.method,
            never_lost,
            never_won,
        });
    }
    let item_fits: Vec<&Fit> = item_fit.components.iter().map(|(_, _, fit, _)| fit).collect();
    let item_model = ModelSummary::from_fits(&item_fits);

    // Factor model.
    let mut covariates = None;
    let mut covariate_model = None;
    let mut factor_fit: Option<(Fit, ModelMatrix)> = None;
    if let (Some(table), Some((formula, terms))) = (table, terms) {
        let values = design::term_values(&table.levels, terms);
        let (kept, dropped) = design::identifiable_terms(&values, terms.len(), &pairs);
        let dropped_terms: Vec<DroppedTerm> = dropped
            .iter()
            .map(|(k, why)| DroppedTerm {
                name: terms[*k].name.clone(),
                reason: match why {
                    Dropped::Constant => "constant over the compared conditions".to_string(),
                    Dropped::Collinear(with) => format!(
                        "collinear with {}",
                        with.iter().map(|&w| terms[w].name.as_str()).collect::<Vec<_>>().join(", ")
                    ),
                },
            })
            .collect();
        for term in &dropped_terms {
            warnings.push(format!("factor model: `{}` dropped, {}", term.name, term.reason));
        }
        if kept.is_empty() {
            warnings.push("factor model not fitted: no term varies over the compared conditions".into());
        } else {
            let x = ModelMatrix::covariates(&values, &kept);
            let fit_options = FitOptions { tolerance: options.tolerance, ..FitOptions::default() };
            let fit = if options.always_firth {
                fit::fit_firth(&pairs, &x, fit_options)
            } else {
                match fit::fit_ml(&pairs, &x, None, fit_options) {
                    Err(FitFailure::Separation) => {
                        warnings.push("separation in the factor model: its maximum-likelihood estimate does not exist; the factor model is Firth's bias-reduced estimate".into());
                        fit::fit_firth(&pairs, &x, fit_options)
                    }
                    other => other,
                }
            }
            .map_err(|f| failure_message("factor model", f).to_string());
            match fit {
                Err(reason) => not_estimable_part(&mut warnings, &mut not_estimable, Part::FactorModel, reason),
                Ok(fit) => {
                    let summary = ModelSummary::from_fits(&[&fit]);
                    let lr_vs_items = if summary.method == Method::Ml && item_model.method == Method::Ml {
                        LrTest::new(
                            2.0 * (item_model.log_likelihood - summary.log_likelihood),
                            item_model.parameters as i64 - summary.parameters as i64,
                        )
                    } else {
                        None
                    };
                    if multiple {
                        warnings.push(
                            "the factor model relates the disconnected components only through its factors".into(),
                        );
                    }
                    // The participants' own tastes: the larger of the model's and the
                    // participant-cluster robust standard error (see `robust`).
                    let robust = (fit.method == Method::Ml)
                        .then(|| cluster_robust_covariance(&fit, &x, tallies, active))
                        .flatten();
                    covariates = Some(
                        kept.iter()
                            .enumerate()
                            .map(|(column, &k)| {
                                let estimate = fit.beta[column];
                                let robust_se = robust.as_ref().map_or(0.0, |v| v[column][column].max(0.0).sqrt());
                                let model_se = fit.se(column);
                                let se = model_se.max(robust_se);
                                let z = if se > 0.0 { estimate / se } else { 0.0 };
                                Covariate {
                                    name: terms[k].name.clone(),
                                    estimate,
                                    se,
                                    model_se,
                                    z,
                                    p: PValue::normal_two_sided(z),
                                    ci: None,
                                }
                            })
                            .collect::<Vec<_>>(),
                    );
                    let reference_lambda = x.predict(reference, &fit.beta);
                    let fitted: Vec<Option<f64>> = (0..n_conditions)
                        .map(|c| (comparisons[c] > 0).then(|| x.predict(c, &fit.beta) - reference_lambda))
                        .collect();
                    let max = fitted.iter().flatten().cloned().fold(f64::NEG_INFINITY, f64::max);
                    let total: f64 = fitted.iter().flatten().map(|l| (l - max).exp()).sum();
                    for (item, lambda) in items.iter_mut().zip(&fitted) {
                        item.fitted_log_worth = *lambda;
                        item.fitted_worth = lambda.map(|l| (l - max).exp() / total);
                    }
                    covariate_model =
                        Some(CovariateModel { formula: formula.clone(), summary, lr_vs_items, dropped: dropped_terms });
                    factor_fit = Some((fit, x));
                }
            }
        }
    }

    let agreement = agreement::coefficient_of_agreement(
        &pairs,
        n_conditions,
        &AgreementOptions {
            simulations: options.agreement_simulations.max(1),
            seed: options.seed,
            ..AgreementOptions::default()
        },
    )?;

    let compared: Vec<usize> = (0..n_conditions).filter(|&c| comparisons[c] > 0).collect();
    let consistence = consistence_per_participant(tallies, active, &compared, &judgments.participants);

    let mut analysis = Analysis {
        judgments: pairs.iter().map(|pair| pair.n()).sum(),
        participants: active.len(),
        conditions: n_conditions,
        reference: names[reference].clone(),
        method: item_model.method,
        items,
        components: multiple
            .then_some(components.clone())
            .or_else(|| components.iter().any(|c| !c.never_lost.is_empty()).then_some(components)),
        item_model,
        covariates,
        covariate_model,
        agreement,
        consistence,
        groups: None,
        group_test: None,
        group_test_left_out: Vec::new(),
        left_out: None,
        bootstrap: None,
        observers: None,
        jod_scale: None,
        davidson: None,
        not_estimable,
        warnings,
    };

    if options.scale == Scale::Jod {
        match crate::scales::jod::analyze(
            tallies,
            ties,
            active,
            names,
            &judgments.participants,
            options.bootstrap,
            options.seed,
        ) {
            Ok((values, intervals, section)) => {
                for (c, item) in analysis.items.iter_mut().enumerate() {
                    if item.comparisons > 0 {
                        item.jod = Some(values[c]);
                        item.jod_ci = intervals.as_ref().map(|i| i[c]);
                    }
                }
                analysis.warnings.extend(section.warnings.iter().cloned());
                analysis.jod_scale = Some(section);
            }
            Err(failure) => not_estimable_part(
                &mut analysis.warnings,
                &mut analysis.not_estimable,
                Part::JodScale,
                failure.to_string(),
            ),
        }
    }
    if !ties.is_empty() {
        // Davidson's tie model over all the subset's judgments (each group's, with --group-by).
        match crate::scales::davidson::section(tallies, ties, active, names, reference, options.tolerance) {
            Ok(section) => analysis.davidson = Some(section),
            Err(failure) => not_estimable_part(
                &mut analysis.warnings,
                &mut analysis.not_estimable,
                Part::Davidson,
                failure.to_string(),
            ),
        }
    }
    let screen = match options.screening {
        Screening::On => true,
        Screening::Off => false,
        Screening::Auto => {
            let auto = n_conditions <= SCREENING_AUTO_LIMIT;
            if !auto {
                analysis.warnings.push(format!("observer screening skipped: {n_conditions} conditions exceed the automatic limit of {SCREENING_AUTO_LIMIT} (ask for it explicitly)"));
            }
            auto
        }
    };
    if screen {
        let unscreenable = if multiple || analysis.method != Method::Ml {
            Some("it needs a connected design with a maximum-likelihood item fit")
        } else if active.len() < 3 {
            Some("it needs at least three participants")
        } else {
            None
        };
        if let Some(reason) = unscreenable {
            not_estimable_part(
                &mut analysis.warnings,
                &mut analysis.not_estimable,
                Part::ObserverScreening,
                reason.into(),
            );
        } else {
            analysis.observers = Some(screen_observers(
                &pairs,
                &item_fit.components[0],
                tallies,
                active,
                &judgments.participants,
                options,
            ));
        }
    }
    if options.bootstrap > 0 {
        if active.len() < 2 {
            not_estimable_part(
                &mut analysis.warnings,
                &mut analysis.not_estimable,
                Part::Bootstrap,
                "it needs at least two participants".into(),
            );
        } else {
            run_bootstrap(
                &mut analysis,
                tallies,
                active,
                n_conditions,
                reference,
                factor_fit.as_ref().map(|(_, x)| x),
                options,
            );
        }
    }
    Ok(analysis)
}

fn consistence_per_participant(
    tallies: &ParticipantTallies,
    active: &[usize],
    compared: &[usize],
    participant_names: &[String],
) -> Vec<ParticipantConsistence> {
    let t = compared.len();
    if t < 3 {
        return Vec::new();
    }
    let n_pairs = t * (t - 1) / 2;
    let mut local = vec![usize::MAX; compared.last().map_or(0, |&c| c + 1)];
    for (k, &c) in compared.iter().enumerate() {
        local[c] = k;
    }
    let mut score = vec![0u64; t];
    active
        .iter()
        .filter_map(|&p| {
            // A participant's pairs are distinct and among the compared conditions: as many as
            // there are pairs means every pair. One judgment per pair by majority.
            let pairs = tallies.of(p);
            if pairs.len() != n_pairs {
                return None;
            }
            score.fill(0);
            let mut tie = false;
            for pair in pairs {
                match pair.wins_i.cmp(&pair.wins_j) {
                    std::cmp::Ordering::Greater => score[local[pair.i]] += 1,
                    std::cmp::Ordering::Less => score[local[pair.j]] += 1,
                    std::cmp::Ordering::Equal => tie = true,
                }
            }
            let consistence = if tie {
                // A tie is passed on as one judgment each way, which leaves the participant
                // without ζ (and [`agreement::coefficient_of_consistence`] says why).
                let mut expanded = Vec::with_capacity(n_pairs + 1);
                for pair in pairs {
                    let (a, b) = (local[pair.i], local[pair.j]);
                    if pair.wins_i >= pair.wins_j {
                        expanded.push((a, b, true));
                    }
                    if pair.wins_j >= pair.wins_i {
                        expanded.push((a, b, false));
                    }
                }
                agreement::coefficient_of_consistence(&expanded, t).ok()?
            } else {
                agreement::consistence_of_scores(&score)
            };
            Some(ParticipantConsistence { participant: participant_names[p].clone(), consistence })
        })
        .collect()
}
