//! Reference values from R 4.2.2 (`friedman.test`, `wilcox.test`, `p.adjust`, `quantile`)
//! written by `analysis/tests/reference/task_stats.R` with jsonlite 1.8.4 (15 significant
//! digits).

use super::*;
use crate::error::AnalysisError;
use serde_json::Value;

/// Statistics computed by the same arithmetic as R (χ², V, W, ranks, descriptives); the
/// reference JSON itself carries 15 significant digits.
const REL_TOL_STATISTIC: f64 = 1e-13;
/// χ² tail p (statrs via `PValue::chi2_upper` against R's `pchisq`), exact signed-rank p
/// (our exact counts against R's `psignrank`) and Holm on them.
const REL_TOL_P: f64 = 1e-13;
/// Normal-approximation p (statrs' `erfc` via `PValue::normal_two_sided` against R's `pnorm`):
/// statrs' erfc is good to about 5e-11 relative at |z| ≈ 2.5.
const REL_TOL_P_NORMAL: f64 = 1e-10;

fn p_tolerance(method: WilcoxonMethod) -> f64 {
    match method {
        WilcoxonMethod::Exact => REL_TOL_P,
        WilcoxonMethod::Normal => REL_TOL_P_NORMAL,
    }
}

const ROUNDING_TIMES: &str = include_str!("../../tests/reference/task_stats_friedman_roundingtimes.json");
const FRIEDMAN_TIES: &str = include_str!("../../tests/reference/task_stats_friedman_ties.json");
const WILCOXON_EXACT: &str = include_str!("../../tests/reference/task_stats_wilcoxon_exact.json");
const WILCOXON_NORMAL: &str = include_str!("../../tests/reference/task_stats_wilcoxon_normal.json");
const WILCOXON_MIN_P: &str = include_str!("../../tests/reference/task_stats_wilcoxon_min_p.json");
const HOLM: &str = include_str!("../../tests/reference/task_stats_holm.json");
const PIPELINE: &str = include_str!("../../tests/reference/task_stats_pipeline.json");

fn json(text: &str) -> Value {
    serde_json::from_str(text).expect("reference JSON parses")
}

fn number(value: &Value) -> f64 {
    value.as_f64().unwrap_or_else(|| panic!("not a number: {value}"))
}

fn numbers(value: &Value) -> Vec<f64> {
    value.as_array().expect("an array").iter().map(number).collect()
}

fn assert_close(actual: f64, expected: f64, rel_tol: f64, what: &str) {
    let scale = expected.abs().max(f64::MIN_POSITIVE);
    assert!(
        (actual - expected).abs() <= rel_tol * scale,
        "{what}: got {actual:e}, R 4.2.2 gives {expected:e} (relative error {:e}, tolerance {rel_tol:e})",
        (actual - expected).abs() / scale
    );
}

fn blocks(reference: &Value) -> Vec<Vec<f64>> {
    reference["blocks"].as_array().expect("blocks").iter().map(numbers).collect()
}

fn check_friedman(reference: &Value) {
    let blocks = blocks(reference);
    let expected = &reference["friedman"];
    let test = friedman_test(&blocks).expect("the test is defined");
    assert_close(test.statistic, number(&expected["statistic"]), REL_TOL_STATISTIC, "Friedman χ²");
    assert_eq!(test.df as f64, number(&expected["df"]));
    assert_close(test.p.p, number(&expected["p"]), REL_TOL_P, "Friedman p");
    assert_close(test.p.log10_p, number(&expected["log10_p"]), REL_TOL_P, "Friedman log10 p");
    assert_close(test.kendall_w, number(&expected["kendall_w"]), REL_TOL_STATISTIC, "Kendall's W");
    for (sum, mean_rank) in test.rank_sums.iter().zip(numbers(&expected["mean_ranks"])) {
        assert_close(sum / blocks.len() as f64, mean_rank, REL_TOL_STATISTIC, "mean rank");
    }
}

#[test]
fn friedman_matches_r_4_2_2_roundingtimes() {
    // R's friedman.test help page: Friedman chi-squared = 11.143, df = 2, p-value = 0.003805.
    check_friedman(&json(ROUNDING_TIMES));
}

#[test]
fn friedman_matches_r_4_2_2_with_ties() {
    check_friedman(&json(FRIEDMAN_TIES));
}

fn check_wilcoxon_cases(reference: &Value, expected_method: WilcoxonMethod) {
    for case in reference["cases"].as_array().expect("cases") {
        let (x, y) = (numbers(&case["x"]), numbers(&case["y"]));
        let test = wilcoxon_signed_rank_paired(&x, &y).expect("a test");
        let what = format!("wilcox.test({x:?}, {y:?}, paired = TRUE)");
        let method = if case["method"] == "exact" { WilcoxonMethod::Exact } else { WilcoxonMethod::Normal };
        assert_eq!(method, expected_method, "{what}: the reference case is of the intended kind");
        assert_eq!(test.method, Some(method), "{what}: method");
        assert_eq!(test.n_nonzero as f64, number(&case["n_nonzero"]), "{what}: non-zero differences");
        assert_close(test.v, number(&case["v"]), REL_TOL_STATISTIC, &format!("{what}: V"));
        let p = test.p.expect("a p-value");
        assert_close(p.p, number(&case["p"]), p_tolerance(method), &format!("{what}: p"));
    }
}

#[test]
fn wilcoxon_exact_matches_r_4_2_2_wilcox_test_paired() {
    check_wilcoxon_cases(&json(WILCOXON_EXACT), WilcoxonMethod::Exact);
}

#[test]
fn wilcoxon_ties_and_zeros_match_r_4_2_2_normal_approximation() {
    check_wilcoxon_cases(&json(WILCOXON_NORMAL), WilcoxonMethod::Normal);
}

#[test]
fn holm_matches_r_4_2_2_p_adjust() {
    let reference = json(HOLM);
    let p: Vec<PValue> = numbers(&reference["p"]).into_iter().map(|p| PValue::from_ln(p.ln())).collect();
    for (adjusted, expected) in holm_adjust(&p).iter().zip(numbers(&reference["holm"])) {
        assert_close(adjusted.p, expected, REL_TOL_P, "Holm-adjusted p");
    }
}

#[test]
fn holm_keeps_tiny_p_exact() {
    let tiny = PValue::from_ln(-400.0 * std::f64::consts::LN_10);
    let adjusted = holm_adjust(&[tiny, PValue::from_ln(0.5_f64.ln())]);
    assert!((adjusted[0].log10_p - (-400.0 + 2.0_f64.log10())).abs() < 1e-9);
    assert_eq!(adjusted[1].p, 0.5);
}

#[test]
fn pipeline_matches_r_4_2_2_per_measure() {
    let reference = json(PIPELINE);
    let csv = reference["csv"].as_str().expect("csv text");
    let analysis = analyze_task_csv(csv, "pipeline.csv").expect("analysis");
    assert_eq!(analysis.grouped_by, ["task", "measure"]);
    let groups = reference["groups"].as_array().expect("groups");
    assert_eq!(analysis.measures.len(), groups.len());
    for (measure, expected) in analysis.measures.iter().zip(groups) {
        let label = measure.group.label();
        assert_eq!(
            measure.group.0,
            vec![
                ("task".to_string(), expected["task"].as_str().unwrap().to_string()),
                ("measure".to_string(), expected["measure"].as_str().unwrap().to_string()),
            ]
        );
        assert_eq!(measure.participants as f64, number(&expected["participants"]), "{label}");
        let excluded: Vec<&str> =
            expected["excluded_participants"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
        assert_eq!(measure.excluded_participants, excluded, "{label}");

        for (summary, expected) in measure.conditions.iter().zip(expected["descriptives"].as_array().unwrap()) {
            let what = format!("{label}, {}", summary.condition);
            assert_eq!(summary.condition, expected["condition"].as_str().unwrap());
            assert_eq!(summary.n as f64, number(&expected["n"]), "{what}: n");
            assert_close(summary.mean, number(&expected["mean"]), REL_TOL_STATISTIC, &format!("{what}: mean"));
            assert_close(summary.sd.unwrap(), number(&expected["sd"]), REL_TOL_STATISTIC, &format!("{what}: sd"));
            for (actual, key) in [
                (summary.median, "median"),
                (summary.q1, "q1"),
                (summary.q3, "q3"),
                (summary.min, "min"),
                (summary.max, "max"),
            ] {
                assert_close(actual, number(&expected[key]), REL_TOL_STATISTIC, &format!("{what}: {key}"));
            }
        }

        let friedman = measure.friedman.as_ref().expect("a Friedman test");
        let expected_friedman = &expected["friedman"];
        assert_eq!(friedman.participants as f64, number(&expected_friedman["participants"]), "{label}");
        assert_close(friedman.statistic, number(&expected_friedman["statistic"]), REL_TOL_STATISTIC, &label);
        assert_close(friedman.p.p, number(&expected_friedman["p"]), REL_TOL_P, &label);
        assert_close(friedman.kendall_w, number(&expected_friedman["kendall_w"]), REL_TOL_STATISTIC, &label);
        for (summary, mean_rank) in measure.conditions.iter().zip(numbers(&expected_friedman["mean_ranks"])) {
            assert_close(summary.mean_rank.unwrap(), mean_rank, REL_TOL_STATISTIC, &label);
        }

        let expected_pairs = expected["post_hoc"].as_array().unwrap();
        assert_eq!(measure.post_hoc.len(), expected_pairs.len());
        for (pair, expected) in measure.post_hoc.iter().zip(expected_pairs) {
            let what = format!("{label}, {} vs {}", pair.condition_a, pair.condition_b);
            assert_eq!(pair.condition_a, expected["condition_a"].as_str().unwrap());
            assert_eq!(pair.condition_b, expected["condition_b"].as_str().unwrap());
            assert_eq!(pair.n as f64, number(&expected["n"]), "{what}: n");
            let test = pair.test.as_ref().unwrap();
            let method = if expected["method"] == "exact" { WilcoxonMethod::Exact } else { WilcoxonMethod::Normal };
            assert_eq!(test.method, Some(method), "{what}: method");
            assert_eq!(test.n_nonzero as f64, number(&expected["n_nonzero"]), "{what}");
            assert_close(test.v, number(&expected["v"]), REL_TOL_STATISTIC, &format!("{what}: V"));
            let tolerance = p_tolerance(method);
            assert_close(test.p.unwrap().p, number(&expected["p"]), tolerance, &format!("{what}: p"));
            assert_close(pair.p_holm.unwrap().p, number(&expected["p_holm"]), tolerance, &format!("{what}: Holm"));
        }
    }
    // The pipeline's handling is reported, not silent.
    let time = &analysis.measures[0];
    assert_eq!(time.averaged, [AveragedCell { participant: "p03".into(), condition: "HQ".into(), values: 2 }]);
    assert!(time.warnings.iter().any(|w| w.contains("averaged") && w.contains("p03 HQ (2 values)")));
    assert!(time.warnings.iter().any(|w| w.contains("excluded from the Friedman test") && w.contains("p07 (no HQ)")));
}

/// Serialises and checks that no NaN or infinity slipped through (serde_json writes them as
/// `null`).
fn to_json_checked(analysis: &TaskAnalysis) -> String {
    let text = serde_json::to_string(analysis).expect("serialises");
    assert!(!text.contains("null"), "no NaN/inf placeholders: {text}");
    text
}

#[test]
fn zero_variance_omits_friedman_with_a_warning() {
    let csv = "participant,condition,value\n\
               a,LQ,5\na,GI,5\na,HQ,5\nb,LQ,5\nb,GI,5\nb,HQ,5\nc,LQ,5\nc,GI,5\nc,HQ,5\n";
    let analysis = analyze_task_csv(csv, "flat.csv").unwrap();
    let measure = &analysis.measures[0];
    assert!(measure.friedman.is_none());
    assert!(measure.warnings.iter().any(|w| w.contains("zero variance") && w.contains("undefined")));
    assert_eq!(measure.conditions[0].sd, Some(0.0));
    assert_eq!(measure.conditions[0].mean_rank, Some(2.0));
    // Every pair has only zero differences: V = 0 and no p, as R (p = NA).
    for pair in &measure.post_hoc {
        let test = pair.test.as_ref().unwrap();
        assert_eq!((test.v, test.p, pair.p_holm), (0.0, None, None));
    }
    let text = to_json_checked(&analysis);
    assert!(!text.contains("\"friedman\""));
    assert!(render_table(&analysis).contains("zero variance"));
}

#[test]
fn single_participant_gives_descriptives_and_no_friedman() {
    let csv = "participant,condition,value\nsolo,LQ,3.5\nsolo,GI,2.0\nsolo,HQ,1.25\n";
    let analysis = analyze_task_csv(csv, "solo.csv").unwrap();
    let measure = &analysis.measures[0];
    assert_eq!(measure.participants, 1);
    assert!(measure.friedman.is_none());
    assert!(measure.warnings.iter().any(|w| w.contains("only one participant (solo)")));
    assert_eq!(measure.conditions[0].sd, None);
    assert_eq!(measure.conditions[0].q3, 3.5);
    // R 4.2.2: wilcox.test(3.5, 2, paired = TRUE) gives V = 1, p-value = 1 (exact): no outcome
    // of one pair can be significant, so the pair is not estimable and shows no p.
    let first = &measure.post_hoc[0];
    let test = first.test.as_ref().unwrap();
    assert_eq!((test.v, test.method, test.p, first.p_holm), (1.0, Some(WilcoxonMethod::Exact), None, None));
    assert_eq!(test.min_p.unwrap().p, 1.0);
    assert!(first.not_estimable.as_ref().unwrap().contains("1 non-zero difference the smallest two-sided p"));
    let text = to_json_checked(&analysis);
    assert!(text.contains("\"not_estimable\"") && !text.contains("\"p\":{"), "{text}");
    let table = render_table(&analysis);
    assert!(table.contains("not estimable") && table.contains("Wilcoxon LQ vs GI not estimable"), "{table}");
}

#[test]
fn fewer_than_two_conditions_omits_tests_with_a_warning() {
    let csv = "participant,condition,value\na,LQ,1\nb,LQ,2\nc,LQ,4\n";
    let analysis = analyze_task_csv(csv, "one.csv").unwrap();
    let measure = &analysis.measures[0];
    assert!(measure.friedman.is_none() && measure.post_hoc.is_empty());
    assert!(measure.warnings.iter().any(|w| w.contains("Only one condition (`LQ`)")));
    assert_eq!(measure.conditions[0].median, 2.0);
    assert_eq!(measure.conditions[0].mean_rank, None);
    to_json_checked(&analysis);
}

#[test]
fn wilcoxon_all_differences_zero_has_no_p() {
    let test = wilcoxon_signed_rank_paired(&[1.0, 2.0, 3.0], &[1.0, 2.0, 3.0]).unwrap();
    assert_eq!((test.n_nonzero, test.v, test.method, test.p), (0, 0.0, None, None));

    // In an analysis, the all-zero pair is reported and left out of the Holm family.
    // Six participants, so that the A–C and B–C tests can reach α (2/2⁶ < 0.05).
    let csv = "participant,condition,value\n\
               a,A,1\na,B,1\na,C,3\nb,A,2\nb,B,2\nb,C,5\nc,A,4\nc,B,4\nc,C,4.5\n\
               d,A,5\nd,B,5\nd,C,5.25\ne,A,6\ne,B,6\ne,C,10\nf,A,7\nf,B,7\nf,C,6\n";
    let analysis = analyze_task_csv(csv, "zeros.csv").unwrap();
    let measure = &analysis.measures[0];
    let ab = &measure.post_hoc[0];
    assert!(ab.test.as_ref().unwrap().p.is_none() && ab.p_holm.is_none());
    assert!(measure.warnings.iter().any(|w| w.contains("Wilcoxon A vs B: all 6 differences are zero")));
    // Two tested pairs: Holm multiplies the smaller p by 2.
    let (ac, bc) = (&measure.post_hoc[1], &measure.post_hoc[2]);
    let p_ac = ac.test.as_ref().unwrap().p.unwrap().p;
    let p_bc = bc.test.as_ref().unwrap().p.unwrap().p;
    assert_close(ac.p_holm.unwrap().p, (2.0 * p_ac.min(p_bc)).min(1.0), 1e-12, "Holm of two");
    to_json_checked(&analysis);
}

fn bad_value_error(csv: &str) -> (u64, String, String) {
    match analyze_task_csv(csv, "bad.csv") {
        Err(AnalysisError::BadValue { line, column, message, .. }) => (line, column, message),
        other => panic!("expected BadValue, got {other:?}"),
    }
}

#[test]
fn nan_inf_and_text_values_are_errors_naming_line_and_column() {
    for (cell, expected) in [
        ("NaN", "not a finite number"),
        ("inf", "not a finite number"),
        ("-infinity", "not a finite number"),
        ("fast", "not a number"),
        ("NA", "not a number"),
        ("", "is empty"),
    ] {
        let csv = format!("participant,condition,value\na,LQ,1\na,GI,{cell}\n");
        let (line, column, message) = bad_value_error(&csv);
        assert_eq!((line, column.as_str()), (3, "value"), "cell `{cell}`");
        assert!(message.contains(expected), "cell `{cell}`: {message}");
    }
    let error = analyze_task_csv("participant,condition,value\na,LQ,1\nb,GI,NaN\n", "bad.csv").unwrap_err();
    assert_eq!(error.to_string(), "bad.csv: line 3, column `value`: `NaN` is not a finite number");
}

#[test]
fn empty_participant_or_condition_is_an_error() {
    let (line, column, _) = bad_value_error("participant,condition,value\na,LQ,1\n,GI,2\n");
    assert_eq!((line, column.as_str()), (3, "participant"));
    let (line, column, _) = bad_value_error("participant,condition,value\na,LQ,1\na,,2\n");
    assert_eq!((line, column.as_str()), (3, "condition"));
}

#[test]
fn missing_columns_and_ragged_rows_are_errors() {
    match analyze_task_csv("participant,condition,score\na,LQ,1\n", "x.csv") {
        Err(AnalysisError::MissingColumn { column, found, .. }) => {
            assert_eq!(column, "value");
            assert_eq!(found, "participant, condition, score");
        }
        other => panic!("expected MissingColumn, got {other:?}"),
    }
    match analyze_task_csv("participant,condition,value\na,LQ,1\na,GI\n", "x.csv") {
        Err(AnalysisError::MalformedCsv { line, message, .. }) => {
            assert_eq!(line, 3);
            assert!(message.contains("2 fields") && message.contains("header has 3"), "{message}");
        }
        other => panic!("expected MalformedCsv, got {other:?}"),
    }
    assert!(matches!(analyze_task_csv("participant,condition,value\n", "x.csv"), Err(AnalysisError::Empty(_))));
    assert!(matches!(analyze_task_csv("", "x.csv"), Err(AnalysisError::Empty(_))));
}

#[test]
fn extra_columns_are_ignored_and_header_is_matched_loosely() {
    let csv = "\u{feff}Participant , Value,note,Condition\na,1,x,LQ\na,2,y,GI\nb,2,,LQ\nb,4,,GI\n";
    let analysis = analyze_task_csv(csv, "loose.csv").unwrap();
    assert!(analysis.grouped_by.is_empty());
    let measure = &analysis.measures[0];
    assert_eq!(measure.conditions.iter().map(|c| c.condition.as_str()).collect::<Vec<_>>(), ["LQ", "GI"]);
    assert_eq!(measure.conditions[1].mean, 3.0);
}

#[test]
fn duplicate_cells_are_averaged_and_reported() {
    let csv = "participant,condition,value\na,LQ,1\na,LQ,3\na,GI,5\nb,LQ,2\nb,GI,1\n";
    let measure = &analyze_task_csv(csv, "dup.csv").unwrap().measures[0];
    assert_eq!(measure.conditions[0].mean, 2.0); // a: (1 + 3) / 2 = 2, b: 2
    assert_eq!(measure.averaged, [AveragedCell { participant: "a".into(), condition: "LQ".into(), values: 2 }]);
    assert!(measure.warnings.iter().any(|w| w.contains("a LQ (2 values)")));
}

#[test]
fn incomplete_participants_are_excluded_from_friedman_by_name() {
    let csv = "participant,condition,value\n\
               a,A,1\na,B,2\na,C,3\nb,A,2\nb,B,3\nb,C,1\nc,A,1\nc,C,2\nd,B,5\n";
    let measure = &analyze_task_csv(csv, "gaps.csv").unwrap().measures[0];
    assert_eq!(measure.excluded_participants, ["c", "d"]);
    assert_eq!(measure.friedman.as_ref().unwrap().participants, 2);
    let warning = measure.warnings.iter().find(|w| w.contains("excluded")).unwrap();
    assert!(warning.contains("2 of 4 participants") && warning.contains("c (no B)") && warning.contains("d (no A, C)"));
    // Pairwise complete: A–C has a, b, c.
    assert_eq!(measure.post_hoc[1].n, 3);
}

#[test]
fn explicit_grouping_column() {
    let csv = "participant,block,condition,value\n\
               a,1,A,1\na,1,B,2\nb,1,A,2\nb,1,B,4\na,2,A,9\na,2,B,3\nb,2,A,8\nb,2,B,1\n";
    let analysis = analyze_task_csv_by(csv, "blocks.csv", Some("block")).unwrap();
    assert_eq!(analysis.grouped_by, ["block"]);
    assert_eq!(analysis.measures.len(), 2);
    assert_eq!(analysis.measures[1].group.label(), "block 2");
    assert_eq!(analysis.measures[1].conditions[0].mean, 8.5);
    let text = to_json_checked(&analysis);
    assert!(text.contains(r#""group":{"block":"2"}"#), "{text}");

    match analyze_task_csv_by(csv, "blocks.csv", Some("measure")) {
        Err(AnalysisError::MissingColumn { column, .. }) => assert_eq!(column, "measure"),
        other => panic!("expected MissingColumn, got {other:?}"),
    }
    assert!(matches!(analyze_task_csv_by(csv, "blocks.csv", Some("value")), Err(AnalysisError::BadOption { .. })));
}

#[test]
fn render_table_shows_tests_and_warnings() {
    let reference = json(PIPELINE);
    let analysis = analyze_task_csv(reference["csv"].as_str().unwrap(), "pipeline.csv").unwrap();
    let table = render_table(&analysis);
    assert!(table.contains("task placement, measure time_s: 12 participants, 3 conditions"), "{table}");
    assert!(table.contains("Friedman χ²(2) = 17.64, p = 0.0001"), "{table}");
    assert!(table.contains("LQ – GI"), "{table}");
    assert!(table.contains("warning: 1 of 12 participants lacks a condition"), "{table}");
    assert_eq!(analysis.warnings().len(), 2);
    assert!(analysis.warnings()[0].starts_with("task placement, measure time_s: "));
    to_json_checked(&analysis);
}

/// R 4.2.2: `wilcox.test(x, 0, paired = TRUE)` with every difference positive gives the smallest
/// p of n differences, 2/2ⁿ exactly without ties; `min_p` is that bound.
#[test]
fn smallest_attainable_p_matches_r_4_2_2_all_differences_positive() {
    let reference = json(WILCOXON_MIN_P);
    let mut checked_exact = 0;
    for case in reference["cases"].as_array().expect("cases") {
        let (x, y) = (numbers(&case["x"]), numbers(&case["y"]));
        let test = wilcoxon_signed_rank_paired(&x, &y).expect("a test");
        let what = format!("wilcox.test({x:?}, {y:?}, paired = TRUE)");
        let n = x.len();
        assert_close(test.min_p.unwrap().p, (2.0 / 2.0_f64.powi(n as i32)).min(1.0), REL_TOL_P, &what);
        if case["method"] == "exact" {
            // All positive: the p is the smallest there is, and equals R's.
            assert_close(test.p.unwrap().p, number(&case["p"]), REL_TOL_P, &format!("{what}: p"));
            assert_close(test.min_p.unwrap().p, number(&case["p"]), REL_TOL_P, &format!("{what}: min p"));
            checked_exact += 1;
        }
    }
    assert_eq!(checked_exact, 7);
}

/// A pair is estimable exactly when some outcome could reach α: from 6 non-zero differences on.
/// Each n from 1 to 7 in an analysis, every difference positive (the most extreme outcome).
#[test]
fn wilcoxon_with_fewer_than_six_differences_is_not_estimable_and_left_out_of_holm() {
    for n in 1..=7_usize {
        let mut csv = String::from("participant,condition,value\n");
        for k in 0..n {
            csv.push_str(&format!("p{k},A,{}\np{k},B,0\np{k},C,{}\n", 1.0 + k as f64 * 1.1, -(k as f64) - 0.5));
        }
        let analysis = analyze_task_csv(&csv, "small.csv").unwrap();
        let measure = &analysis.measures[0];
        let table = render_table(&analysis);
        for pair in &measure.post_hoc {
            let test = pair.test.as_ref().unwrap();
            assert_eq!(test.n_nonzero, n);
            if n < 6 {
                assert_eq!((test.p, pair.p_holm), (None, None), "n = {n}");
                let reason = pair.not_estimable.as_ref().expect("a reason");
                assert!(reason.contains(&format!("{} > α = 0.05", test.min_p.unwrap().display())), "{reason}");
            } else {
                assert!(test.p.unwrap().p <= POST_HOC_ALPHA && pair.p_holm.is_some(), "n = {n}: {pair:?}");
                assert_eq!(pair.not_estimable, None);
            }
        }
        assert_eq!(table.contains("not estimable"), n < 6, "n = {n}: {table}");
        to_json_checked(&analysis);
    }
}

/// With ties R switches to the normal approximation, which gives five equal differences
/// p = 0.0369 (R 4.2.2, `task_stats_wilcoxon_min_p.json`) although under the exact sign-flip
/// distribution no outcome of five differences goes below 2/2⁵ = 0.0625: not estimable.
#[test]
fn five_tied_differences_are_not_estimable_although_r_prints_p_below_alpha() {
    let reference = json(WILCOXON_MIN_P);
    let case =
        reference["cases"].as_array().unwrap().iter().find(|c| c["x"] == serde_json::json!([1, 1, 1, 1, 1])).unwrap();
    assert!(number(&case["p"]) < POST_HOC_ALPHA);
    let test = wilcoxon_signed_rank_paired(&numbers(&case["x"]), &numbers(&case["y"])).unwrap();
    assert_close(test.p.unwrap().p, number(&case["p"]), REL_TOL_P_NORMAL, "normal approximation p");
    assert_eq!(test.min_p.unwrap().p, 0.0625);
    let csv = "participant,condition,value\na,A,2\na,B,1\nb,A,2\nb,B,1\nc,A,2\nc,B,1\nd,A,2\nd,B,1\ne,A,2\ne,B,1\n";
    let analysis = analyze_task_csv(csv, "ties.csv").unwrap();
    let pair = &analysis.measures[0].post_hoc[0];
    assert!(pair.not_estimable.is_some() && pair.test.as_ref().unwrap().p.is_none());
}
