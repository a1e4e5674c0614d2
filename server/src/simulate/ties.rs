//! "Not sure" in simulated studies (`allow_tie = true`): each simulated observer answers by
//! Davidson's tie model on their own log-worths (Davidson 1970, as the analysis fits it in
//! `mrstudy_analysis::scales::davidson`): with d = (λ_left − λ_right)/2,
//! P(left) = eᵈ / (eᵈ + e⁻ᵈ + ν), P(right) = e⁻ᵈ / (eᵈ + e⁻ᵈ + ν), P(tie) = ν / (eᵈ + e⁻ᵈ + ν),
//! ν = `--tie-nu` (between equal conditions "not sure" is ν/(2 + ν) of the answers; ν = 0 is
//! Bradley–Terry). A lapse is a coin flip between the two sides, never a tie. Ties go to the
//! analysis as the export gives them (`chosen = tie`): the Bradley–Terry models, and so the
//! power per factor, use the other judgments; the `davidson` section all of them.

/// A simulated answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Answer {
    Left,
    Right,
    Tie,
}

/// Davidson's [P(left), P(right), P(tie)] for the log-worths shown and ν.
pub(super) fn davidson_probabilities(left: f64, right: f64, nu: f64) -> [f64; 3] {
    let d = (left - right) / 2.0;
    // divided by e^|d| so nothing overflows
    let m = d.abs();
    let (l, r, t) = ((d - m).exp(), (-d - m).exp(), nu * (-m).exp());
    let total = l + r + t;
    [l / total, r / total, t / total]
}

/// Davidson's answer to a pair for the log-worths shown, ν and a uniform draw `u` in [0, 1).
pub(super) fn davidson_answer(u: f64, left: f64, right: f64, nu: f64) -> Answer {
    let [p_left, p_right, _] = davidson_probabilities(left, right, nu);
    if u < p_left {
        Answer::Left
    } else if u < p_left + p_right {
        Answer::Right
    } else {
        Answer::Tie
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{DesignChoice, simulate};

    #[test]
    fn davidson_probabilities_are_the_model_and_bradley_terry_without_ties() {
        let [l, r, t] = davidson_probabilities(0.8, -0.4, 0.7);
        let (a, b) = (0.8f64.exp(), (-0.4f64).exp());
        let total = a + b + 0.7 * (a * b).sqrt();
        assert!((l - a / total).abs() < 1e-12 && (r - b / total).abs() < 1e-12);
        assert!((t - 0.7 * (a * b).sqrt() / total).abs() < 1e-12);
        let [l, r, t] = davidson_probabilities(1.2, 0.0, 0.0);
        assert!((l - 1.0 / (1.0 + (-1.2f64).exp())).abs() < 1e-12 && (l + r - 1.0).abs() < 1e-12 && t == 0.0);
        let [l, r, t] = davidson_probabilities(800.0, -800.0, 1.0);
        assert!(l == 1.0 && r == 0.0 && t == 0.0);
    }

    /// A study with `allow_tie = true`: about the share of "not sure" answers the model predicts,
    /// power per factor reported as for forced choices, and below the forced-choice power of the
    /// same study at the same seed (the ties carry no Bradley–Terry direction).
    #[test]
    fn a_tie_design_is_simulated_with_power_per_factor() {
        let dir = tempfile::tempdir().unwrap();
        let forced = super::super::tests::factorial_study(dir.path(), super::super::tests::ANCHORED);
        let mut tied = forced.clone();
        tied.participation.allow_tie = true;
        let mut config = super::super::tests::config(&forced, &[DesignChoice::Study], &[12], 40);
        config.options.tie_nu = 2.0;
        let quiet = |_: u64, _: u64| {};
        // ν = 2 between conditions 0.3–0.9 apart: about half the answers are "not sure"
        let (rows, ties) = super::super::observer::collect_judgments(&tied, &config, 12, 5).unwrap();
        let share = ties.len() as f64 / (rows.len() + ties.len()) as f64;
        assert!((0.35..0.6).contains(&share), "tie share {share}");
        assert!(super::super::observer::collect_judgments(&forced, &config, 12, 5).unwrap().1.is_empty());
        let with_ties = simulate(&tied, &config, &quiet).unwrap();
        let without = simulate(&forced, &config, &quiet).unwrap();
        let (row, plain) = (&with_ties.rows[0], &without.rows[0]);
        assert_eq!(row.failed, 0, "{:?}", row.failure);
        assert_eq!(row.power.len(), 2);
        // judgments per participant count the ties too: the same trials as without
        assert!((row.judgments_per_participant.mean - plain.judgments_per_participant.mean).abs() < 1e-9);
        for (a, b) in row.power.iter().zip(&plain.power) {
            assert!(a.power <= b.power + 0.1, "{}: {} with ties, {} without", a.factor, a.power, b.power);
        }
    }
}
