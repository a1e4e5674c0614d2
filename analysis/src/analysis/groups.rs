//! `--group-by`: the analysis of each group (a group that cannot be fitted is reported as not
//! estimable, with the reason, and the others go on), and the likelihood-ratio test of equal
//! effects across the estimable groups against the model pooled over them.

use std::collections::BTreeMap;

use crate::data::Judgment;
use crate::design::ParticipantTallies;
use crate::fit::Method;

use super::subset::{Inputs, Subset, analyze_subset};
use super::{Analysis, GroupResult, LrTest, ModelSummary, NotEstimable, Options, Part, Screening, not_estimable_part};

/// Adds to `analysis` (the fit of all judgments, `tallies` over the participants `everyone`)
/// each group's analysis, the test of equal effects across the groups and its warnings.
pub(super) fn analyze_groups(
    inputs: &Inputs,
    tallies: &ParticipantTallies,
    everyone: &[usize],
    ties: &[Judgment],
    analysis: &mut Analysis,
) {
    let judgments = inputs.judgments;
    let options = inputs.options;
    let n_participants = judgments.participants.len();
    let n_conditions = judgments.conditions.len();
    // Where every participant's judgments are in one group (a column such as gender), a
    // group's tallies are its participants' in the whole data's; otherwise each group's
    // are tallied from its rows.
    let mut group_of = vec![u32::MAX; n_participants];
    let mixed = judgments.rows.iter().any(|row| {
        let group = &mut group_of[row.participant as usize];
        if *group == u32::MAX {
            *group = row.group;
        }
        *group != row.group
    });
    let subset = |in_group: &dyn Fn(u32) -> bool| -> (Option<ParticipantTallies>, Vec<usize>) {
        if mixed {
            let rows = judgments.rows.iter().filter(|row| in_group(row.group));
            let own = ParticipantTallies::new(n_participants, n_conditions, rows);
            let active = own.present();
            (Some(own), active)
        } else {
            (None, everyone.iter().copied().filter(|&p| in_group(group_of[p])).collect())
        }
    };
    let mut groups = BTreeMap::new();
    let mut grouped_ll = 0.0;
    let mut grouped_parameters = 0usize;
    let mut valid = true;
    let mut estimable = vec![false; judgments.groups.len()];
    let mut left_out = Vec::new();
    for (g, name) in judgments.groups.iter().enumerate() {
        let (own, active) = subset(&|group| group == g as u32);
        let group_tallies = own.as_ref().unwrap_or(tallies);
        let group_ties: Vec<Judgment> = ties.iter().filter(|t| t.group == g as u32).copied().collect();
        match analyze_subset(inputs, &Subset { tallies: group_tallies, active: &active, ties: &group_ties }) {
            Ok(sub) => {
                let model = sub.covariate_model.as_ref().map(|m| &m.summary).unwrap_or(&sub.item_model);
                valid &= model.method == Method::Ml;
                grouped_ll += model.kernel_log_likelihood;
                grouped_parameters += model.parameters;
                estimable[g] = true;
                groups.insert(name.clone(), GroupResult::Estimated(Box::new(sub)));
            }
            Err(error) => {
                let group_judgments = active.iter().flat_map(|&p| group_tallies.of(p)).map(|pair| pair.n()).sum();
                let reason = error.to_string();
                analysis.warnings.push(format!("group `{name}` could not be estimated: {reason}"));
                left_out.push(name.clone());
                groups.insert(
                    name.clone(),
                    GroupResult::NotEstimable(NotEstimable {
                        estimable: false,
                        judgments: group_judgments,
                        participants: active.len(),
                        reason,
                    }),
                );
            }
        }
    }
    let n_estimable = estimable.iter().filter(|&&e| e).count();
    let firth_reason = "a fit needed Firth's bias reduction, which has no likelihood-ratio test";
    if n_estimable < 2 {
        let reason = format!(
            "it needs at least two estimable groups, and {n_estimable} of {} could be estimated",
            judgments.groups.len()
        );
        not_estimable_part(&mut analysis.warnings, &mut analysis.not_estimable, Part::GroupTest, reason);
    } else if !valid {
        not_estimable_part(&mut analysis.warnings, &mut analysis.not_estimable, Part::GroupTest, firth_reason.into());
    } else {
        // The pooled model over the same judgments as the groups: all of them, or only the
        // estimable groups' (then refitted, without agreement simulation, screening or bootstrap).
        let pooled: Option<ModelSummary> = if left_out.is_empty() {
            Some(analysis.covariate_model.as_ref().map(|m| &m.summary).unwrap_or(&analysis.item_model).clone())
        } else {
            let pooled_options =
                Options { bootstrap: 0, screening: Screening::Off, agreement_simulations: 1, ..options.clone() };
            let (own, active) = subset(&|group| estimable[group as usize]);
            let pooled_tallies = own.as_ref().unwrap_or(tallies);
            let pooled_inputs = Inputs { options: &pooled_options, ..*inputs };
            match analyze_subset(&pooled_inputs, &Subset { tallies: pooled_tallies, active: &active, ties: &[] }) {
                Ok(restricted) => Some(restricted.covariate_model.map(|m| m.summary).unwrap_or(restricted.item_model)),
                Err(error) => {
                    let reason = format!("the model pooled over the estimable groups could not be fitted: {error}");
                    not_estimable_part(&mut analysis.warnings, &mut analysis.not_estimable, Part::GroupTest, reason);
                    None
                }
            }
        };
        match pooled {
            Some(pooled) if pooled.method == Method::Ml => {
                // Kernel log-likelihoods: the binomial constants depend on how judgments are pooled.
                analysis.group_test = LrTest::new(
                    2.0 * (grouped_ll - pooled.kernel_log_likelihood),
                    grouped_parameters as i64 - pooled.parameters as i64,
                );
                if !left_out.is_empty() {
                    analysis.warnings.push(format!(
                        "the test of equal effects across groups uses only the estimable groups; left out: {}",
                        left_out.iter().map(|name| format!("`{name}`")).collect::<Vec<_>>().join(", ")
                    ));
                }
            }
            Some(_) => not_estimable_part(
                &mut analysis.warnings,
                &mut analysis.not_estimable,
                Part::GroupTest,
                firth_reason.into(),
            ),
            None => {}
        }
    }
    analysis.group_test_left_out = if analysis.group_test.is_some() { left_out } else { Vec::new() };
    analysis.groups = Some(groups);
}
