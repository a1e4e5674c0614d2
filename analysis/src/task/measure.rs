//! One measure: the participant × condition table (several values for a cell averaged, incomplete
//! participants left out of the Friedman test), its descriptives, the Friedman test and the
//! post hoc tests, with warnings saying what was averaged, left out or omitted.

use super::descriptives::{describe, mean};
use super::friedman::{friedman_test, rank_sums};
use super::parse::MeasureData;
use super::posthoc::{holm_adjust, wilcoxon_signed_rank_paired};
use super::{AveragedCell, ConditionSummary, MeasureAnalysis, POST_HOC_ALPHA, WilcoxonPair};
use crate::pvalue::PValue;

pub(super) fn analyze_measure(data: &MeasureData) -> MeasureAnalysis {
    let n_conditions = data.conditions.len();
    let mut warnings = Vec::new();

    // The participant × condition table, duplicates averaged.
    let mut table: Vec<Vec<Option<f64>>> = vec![vec![None; n_conditions]; data.participants.len()];
    let mut averaged = Vec::new();
    for (participant_idx, row) in table.iter_mut().enumerate() {
        for (condition_idx, cell) in row.iter_mut().enumerate() {
            if let Some(values) = data.cells.get(&(participant_idx, condition_idx)) {
                *cell = Some(mean(values));
                if values.len() > 1 {
                    averaged.push(AveragedCell {
                        participant: data.participants[participant_idx].clone(),
                        condition: data.conditions[condition_idx].clone(),
                        values: values.len(),
                    });
                }
            }
        }
    }
    if !averaged.is_empty() {
        let cells: Vec<String> = averaged
            .iter()
            .map(|cell| format!("{} {} ({} values)", cell.participant, cell.condition, cell.values))
            .collect();
        warnings.push(format!(
            "{} participant–condition cell{} had several values and {} averaged: {}.",
            averaged.len(),
            plural(averaged.len()),
            if averaged.len() == 1 { "was" } else { "were" },
            cells.join(", ")
        ));
    }

    // Complete blocks for the Friedman test; everyone else is excluded, by name.
    let mut blocks: Vec<Vec<f64>> = Vec::new();
    let mut complete_participants: Vec<&str> = Vec::new();
    let mut excluded_participants = Vec::new();
    let mut exclusion_notes = Vec::new();
    for (participant_idx, row) in table.iter().enumerate() {
        let participant = &data.participants[participant_idx];
        if let Some(block) = row.iter().copied().collect::<Option<Vec<f64>>>() {
            blocks.push(block);
            complete_participants.push(participant);
        } else {
            let missing: Vec<&str> = row
                .iter()
                .zip(&data.conditions)
                .filter(|(cell, _)| cell.is_none())
                .map(|(_, condition)| condition.as_str())
                .collect();
            exclusion_notes.push(format!("{participant} (no {})", missing.join(", ")));
            excluded_participants.push(participant.clone());
        }
    }

    let rank_sums = (n_conditions >= 2 && !blocks.is_empty()).then(|| rank_sums(&blocks).0);
    let conditions: Vec<ConditionSummary> = data
        .conditions
        .iter()
        .enumerate()
        .map(|(condition_idx, condition)| {
            let values: Vec<f64> = table.iter().filter_map(|row| row[condition_idx]).collect();
            let mean_rank = rank_sums.as_ref().map(|sums| sums[condition_idx] / blocks.len() as f64);
            describe(condition, &values, mean_rank)
        })
        .collect();

    if n_conditions < 2 {
        warnings.push(format!(
            "Only one condition (`{}`): there is nothing to compare, so the Friedman test and the post \
            hoc tests are omitted.",
            data.conditions.first().map_or("", String::as_str)
        ));
        return MeasureAnalysis {
            group: data.group.clone(),
            participants: data.participants.len(),
            conditions,
            averaged,
            excluded_participants: Vec::new(),
            friedman: None,
            post_hoc: Vec::new(),
            warnings,
        };
    }

    if !excluded_participants.is_empty() {
        warnings.push(format!(
            "{} of {} participant{} {} a condition and {} excluded from the Friedman test: {}. Each \
            post hoc pair uses every participant who has both of its conditions.",
            excluded_participants.len(),
            data.participants.len(),
            plural(data.participants.len()),
            if excluded_participants.len() == 1 { "lacks" } else { "lack" },
            if excluded_participants.len() == 1 { "is" } else { "are" },
            exclusion_notes.join(", ")
        ));
    }

    let friedman = match blocks.len() {
        0 => {
            warnings.push(format!("Friedman test omitted: no participant has all {n_conditions} conditions."));
            None
        }
        1 => {
            warnings.push(format!(
                "Friedman test omitted: only one participant ({}) has all {n_conditions} conditions; a \
                rank test across participants needs at least two.",
                complete_participants[0]
            ));
            None
        }
        _ => {
            let test = friedman_test(&blocks);
            if test.is_none() {
                warnings.push(
                    "Friedman test omitted: every participant gave all conditions the same value (zero \
                    variance within participants), so the ranks carry no information and the statistic is \
                    undefined (0/0)."
                        .to_string(),
                );
            }
            test
        }
    };

    // Post hoc: every pair of conditions, pairwise complete, Holm over the pairs with a p.
    let mut post_hoc = Vec::new();
    for idx_a in 0..n_conditions {
        for idx_b in idx_a + 1..n_conditions {
            let (x, y): (Vec<f64>, Vec<f64>) = table.iter().filter_map(|row| Some((row[idx_a]?, row[idx_b]?))).unzip();
            let (condition_a, condition_b) = (&data.conditions[idx_a], &data.conditions[idx_b]);
            let mut test = wilcoxon_signed_rank_paired(&x, &y);
            let mut not_estimable = None;
            if let Some(test) = test.as_mut()
                && let Some(min_p) = test.min_p
                && min_p.p > POST_HOC_ALPHA
            {
                let differences = test.n_nonzero;
                let reason = format!(
                    "with {differences} non-zero difference{} the smallest two-sided p any outcome could give is {} > α = \
                    {POST_HOC_ALPHA}, so the test cannot find a difference (it needs at least 6)",
                    plural(differences),
                    min_p.display(),
                );
                warnings.push(format!(
                    "Wilcoxon {condition_a} vs {condition_b} not estimable: {reason}; no p-value is reported and the \
                    pair is left out of the Holm adjustment."
                ));
                test.p = None;
                test.z = None;
                not_estimable = Some(reason);
            }
            match &test {
                None => warnings.push(format!(
                    "Wilcoxon {condition_a} vs {condition_b} omitted: no participant has both conditions."
                )),
                Some(test) if test.p.is_none() && not_estimable.is_none() => warnings.push(format!(
                    "Wilcoxon {condition_a} vs {condition_b}: all {} differences are zero, so there is no \
                    test (R reports p = NA); the pair is left out of the Holm adjustment.",
                    x.len()
                )),
                Some(_) => {}
            }
            post_hoc.push(WilcoxonPair {
                condition_a: condition_a.clone(),
                condition_b: condition_b.clone(),
                n: x.len(),
                test,
                p_holm: None,
                not_estimable,
            });
        }
    }
    let tested: Vec<usize> =
        (0..post_hoc.len()).filter(|&idx| post_hoc[idx].test.as_ref().is_some_and(|test| test.p.is_some())).collect();
    let raw: Vec<PValue> = tested.iter().filter_map(|&idx| post_hoc[idx].test.as_ref()?.p).collect();
    for (&idx, adjusted) in tested.iter().zip(holm_adjust(&raw)) {
        post_hoc[idx].p_holm = Some(adjusted);
    }

    MeasureAnalysis {
        group: data.group.clone(),
        participants: data.participants.len(),
        conditions,
        averaged,
        excluded_participants,
        friedman,
        post_hoc,
        warnings,
    }
}

pub(super) fn plural(count: usize) -> &'static str {
    if count == 1 { "" } else { "s" }
}
