//! Issue 12, "Trustworthy responses", on the analysis side: pilot and excluded participants
//! are left out by default and counted; a group that cannot be estimated is reported as such
//! while the other groups and the test across them go on; printed tables never show `-0.000`.

use mrstudy_analysis::analysis::{Analysis, Options, Screening, analyze};
use mrstudy_analysis::data::{LeftOut, TrialsOptions, parse_trials_with};
use mrstudy_analysis::fit::Method;
use mrstudy_analysis::table;

fn options() -> Options {
    Options { screening: Screening::Off, agreement_simulations: 200, ..Options::default() }
}

/// Log-worths of the simulated conditions.
const TRUTH: [(&str, f64); 4] = [("A", 0.0), ("B", 0.6), ("C", -0.4), ("D", 1.1)];

/// Every pair of [`TRUTH`] judged `repetitions` times by `participant`, choices drawn from the
/// Bradley–Terry model by a fixed LCG; `extra` is appended to each row (the trailing columns).
fn judgments(participant: &str, repetitions: usize, extra: &str, state: &mut u64) -> String {
    let mut text = String::new();
    for rep in 0..repetitions {
        for a in 0..TRUTH.len() {
            for b in a + 1..TRUTH.len() {
                *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let uniform = (*state >> 11) as f64 / (1u64 << 53) as f64;
                let p_a = 1.0 / (1.0 + (TRUTH[b].1 - TRUTH[a].1).exp());
                let chosen = if uniform < p_a { TRUTH[a].0 } else { TRUTH[b].0 };
                let (left, right) = if rep % 2 == 0 { (TRUTH[a].0, TRUTH[b].0) } else { (TRUTH[b].0, TRUTH[a].0) };
                text += &format!("{participant},{left},{right},{chosen}{extra}\n");
            }
        }
    }
    text
}

/// An export-like trials CSV: six ordinary participants, two pilots (one also excluded), one
/// excluded participant; a pilot also compared a condition nobody else saw.
fn export_like() -> (String, String) {
    let header = "participant,left,right,chosen,status,completion_code,too_fast,PROLIFIC_PID,pilot,excluded";
    let mut state = 99;
    let mut full = format!("{header}\n");
    let mut kept = String::from("participant,left,right,chosen\n");
    for p in 0..6 {
        let name = format!("p{p}");
        let rows = judgments(&name, 3, "", &mut state);
        kept += &rows;
        for row in rows.lines() {
            full += &format!("{row},completed,C0DE,false,pid{p},false,false\n");
        }
    }
    let mut junk = 7;
    full += &judgments("pilot1", 2, ",completed,C0DE,false,,true,false", &mut junk);
    full += "pilot1,A,X,X,completed,C0DE,false,,true,false\npilot1,X,A,A,completed,C0DE,false,,true,false\n";
    full += &judgments("pilot2", 1, ",started,,true,,TRUE,true", &mut junk);
    full += &judgments("ex1", 1, ",completed,C0DE,false,pid9,false,true", &mut junk);
    (full, kept)
}

fn json(analysis: &Analysis) -> serde_json::Value {
    let text = serde_json::to_string(analysis).unwrap();
    assert!(!text.contains("null") && !text.contains("NaN") && !text.contains("inf"), "{text}");
    serde_json::from_str(&text).unwrap()
}

#[test]
fn pilots_and_excluded_participants_are_left_out_by_default_and_counted() {
    let (full, kept) = export_like();
    let analysis = analyze(&full, None, &options()).unwrap();
    let expected = analyze(&kept, None, &options()).unwrap();
    assert_eq!((analysis.participants, analysis.judgments), (6, 6 * 3 * 6));
    assert_eq!(analysis.conditions, 4, "X was compared by a pilot only");
    for (item, expected) in analysis.items.iter().zip(&expected.items) {
        assert_eq!(item.condition, expected.condition);
        assert_eq!(item.log_worth, expected.log_worth);
    }
    assert_eq!(
        analysis.left_out,
        Some(LeftOut { pilots: 2, pilot_judgments: 12 + 2 + 6, excluded: 1, excluded_judgments: 6 })
    );
    assert_eq!(
        analysis.warnings[0],
        "left out 3 participants and 26 judgments: 2 pilot participants with 20 judgments (pilot = true); \
         1 excluded participant with 6 judgments (excluded = true)"
    );
    let value = json(&analysis);
    assert_eq!(value["left_out"]["pilots"], 2);
    assert!(value["warnings"][0].as_str().unwrap().starts_with("left out 3 participants"));
    let text = table::render(&analysis);
    assert!(text.contains("\nwarning: left out 3 participants and 26 judgments"), "{text}");
    assert!(text.starts_with("108 judgments by 6 participants on 4 conditions"), "{text}");
}

#[test]
fn include_options_keep_pilots_and_excluded_participants() {
    let (full, _) = export_like();
    let pilots = analyze(&full, None, &Options { include_pilots: true, ..options() }).unwrap();
    // pilot2 is also excluded, so only pilot1 comes back.
    assert_eq!((pilots.participants, pilots.conditions), (7, 5));
    assert_eq!(pilots.left_out, Some(LeftOut { pilots: 0, pilot_judgments: 0, excluded: 2, excluded_judgments: 12 }));
    let excluded = analyze(&full, None, &Options { include_excluded: true, ..options() }).unwrap();
    assert_eq!(excluded.participants, 7);
    assert_eq!(excluded.left_out.as_ref().map(|l| (l.pilots, l.excluded)), Some((2, 0)));
    let everyone =
        analyze(&full, None, &Options { include_pilots: true, include_excluded: true, ..options() }).unwrap();
    assert_eq!((everyone.participants, everyone.judgments), (9, 108 + 26));
    assert_eq!(everyone.left_out, None);
    assert!(!everyone.warnings.iter().any(|w| w.starts_with("left out")), "{:?}", everyone.warnings);
    assert!(json(&everyone).get("left_out").is_none());
}

#[test]
fn a_csv_without_pilot_or_excluded_columns_is_analysed_as_before() {
    let (_, kept) = export_like();
    let parsed = parse_trials_with(&kept, "t.csv", None, &TrialsOptions::default()).unwrap();
    assert!(parsed.left_out.is_empty());
    assert_eq!(parsed.judgments.participants.len(), 6);
    let analysis = analyze(&kept, None, &options()).unwrap();
    assert_eq!(analysis.left_out, None);
    assert!(!analysis.warnings.iter().any(|w| w.contains("left out")), "{:?}", analysis.warnings);
}

#[test]
fn left_out_participants_leave_their_groups_and_participant_numbering() {
    let text = "participant,left,right,chosen,gender,pilot\n\
                a,A,B,A,f,false\nz,A,B,B,x,true\nb,A,B,B,m,false\na,B,A,A,f,false\n";
    let options = TrialsOptions { group_by: Some("gender".into()), ..TrialsOptions::default() };
    let parsed = parse_trials_with(text, "t.csv", None, &options).unwrap();
    assert_eq!(parsed.judgments.participants, ["a", "b"]);
    assert_eq!(parsed.judgments.groups, ["f", "m"]);
    let rows: Vec<(u32, u32)> = parsed.judgments.rows.iter().map(|r| (r.participant, r.group)).collect();
    assert_eq!(rows, [(0, 0), (1, 1), (0, 0)]);
}

#[test]
fn flag_values_other_than_true_or_false_name_file_line_and_column() {
    let cases = [
        (
            "participant,left,right,chosen,pilot\np,A,B,A,false\np,A,B,B,yes\n",
            "t.csv: line 3, column `pilot`: `yes` is neither `true` nor `false`",
        ),
        (
            "participant,left,right,chosen,excluded\np,A,B,A,\n",
            "t.csv: line 2, column `excluded`: `` is neither `true` nor `false`",
        ),
        (
            "participant,left,right,chosen,pilot,excluded\np,A,B,A,false,1\n",
            "t.csv: line 2, column `excluded`: `1` is neither `true` nor `false`",
        ),
    ];
    for (text, expected) in cases {
        let error = parse_trials_with(text, "t.csv", None, &TrialsOptions::default()).unwrap_err();
        assert_eq!(error.to_string(), expected);
    }
    // Spreadsheets write TRUE/FALSE.
    let parsed = parse_trials_with(
        "participant,left,right,chosen,pilot\np,A,B,A,FALSE\nq,A,B,B,True\n",
        "t.csv",
        None,
        &TrialsOptions::default(),
    )
    .unwrap();
    assert_eq!(parsed.judgments.participants, ["p"]);
}

#[test]
fn nothing_left_after_leaving_out_is_one_clear_error() {
    let text = "participant,left,right,chosen,pilot,excluded\np,A,B,A,true,false\nq,A,B,B,false,true\n";
    let error = analyze(text, None, &options()).unwrap_err().to_string();
    assert_eq!(
        error,
        "trials CSV: every participant is a pilot or excluded, so no trials are left to analyse \
         (left out 2 participants and 2 judgments: 1 pilot participant with 1 judgment (pilot = true); \
         1 excluded participant with 1 judgment (excluded = true))"
    );
}

/// Two groups of five participants and one group of a single participant with four judgments,
/// too few for any model: the ML estimate does not exist and the bias-reduced one does not
/// converge within the iteration limit.
fn groups_with_one_too_small() -> (String, String) {
    let mut state = 5;
    let mut estimable = String::from("participant,left,right,chosen,group\n");
    for p in 0..10 {
        let group = if p % 2 == 0 { ",even" } else { ",odd" };
        estimable += &judgments(&format!("p{p}"), 4, group, &mut state);
    }
    let mut all = estimable.clone();
    all += "solo,A,B,B,solo\nsolo,A,D,D,solo\nsolo,B,D,D,solo\nsolo,A,C,A,solo\n";
    (all, estimable)
}

/// A group of one participant's four judgments, each pair judged once: before issue 44 its
/// Firth fit circled its maximum and the group was reported as not estimable ("did not
/// converge"); it is estimated now, by Firth's bias-reduced likelihood, and the test across
/// groups, which Firth fits do not have, is reported as not estimable with that reason while
/// every group is printed.
#[test]
fn a_group_of_one_participant_is_estimated_and_the_test_across_groups_says_why_not() {
    let (all, _) = groups_with_one_too_small();
    let grouped = Options { group_by: Some("group".into()), ..options() };
    let analysis = analyze(&all, None, &grouped).unwrap();
    let groups = analysis.groups.as_ref().unwrap();
    assert_eq!(groups.len(), 3);
    assert!(groups["even"].analysis().is_some() && groups["odd"].analysis().is_some());
    let solo = groups["solo"].analysis().expect("solo is estimated");
    assert_eq!((solo.method, solo.judgments, solo.participants), (Method::Firth, 4, 1));
    assert!(analysis.group_test.is_none() && analysis.group_test_left_out.is_empty());
    let reason = "a fit needed Firth's bias reduction, which has no likelihood-ratio test";
    assert!(
        analysis.warnings.iter().any(|w| w == &format!("test of equal effects across groups not estimable: {reason}")),
        "{:?}",
        analysis.warnings
    );
    let value = json(&analysis);
    assert_eq!(value["not_estimable"][0]["part"], "group_test");
    assert_eq!(value["not_estimable"][0]["reason"], reason);
    assert!(value["groups"]["solo"]["items"].is_array() && value["groups"]["even"]["items"].is_array());
    let text = table::render(&analysis);
    assert!(text.contains("=== group: solo ===\n4 judgments by 1 participants"), "{text}");
    assert!(text.contains(&format!("warning: test of equal effects across groups not estimable: {reason}")), "{text}");
    let svg = analysis.worth_plot();
    assert!(svg.contains(">even<") && svg.contains(">solo<"));
}

#[test]
fn a_group_fitted_by_firth_gives_no_test_and_says_why() {
    let mut state = 11;
    let mut text = String::from("participant,left,right,chosen,group\n");
    for p in 0..4 {
        text += &judgments(&format!("p{p}"), 4, ",big", &mut state);
    }
    text += "solo,A,B,B,solo\nsolo,A,D,D,solo\nsolo,B,D,D,solo\nsolo,A,C,A,solo\n";
    let analysis = analyze(&text, None, &Options { group_by: Some("group".into()), ..options() }).unwrap();
    assert!(analysis.group_test.is_none());
    assert!(analysis.group_test_left_out.is_empty());
    assert!(
        analysis.warnings.iter().any(|w| w == "test of equal effects across groups not estimable: a fit needed Firth's bias reduction, which has no likelihood-ratio test"),
        "{:?}",
        analysis.warnings
    );
}

#[test]
fn tables_never_print_negative_zero() {
    let (_, kept) = export_like();
    let conditions = "condition,x,y\nA,0,0\nB,1,0\nC,0,1\nD,1,1\n";
    let mut analysis = analyze(&kept, Some(conditions), &Options { bootstrap: 20, ..options() }).unwrap();
    // Values a fit can produce on symmetric data: tiny negatives that round to zero.
    analysis.items[1].log_worth = Some(-1e-9);
    analysis.items[1].ci = Some([-2e-5, 0.4]);
    analysis.items[2].fitted_log_worth = Some(-3e-6);
    let covariate = &mut analysis.covariates.as_mut().unwrap()[0];
    covariate.estimate = -4e-6;
    covariate.z = -1e-5;
    covariate.ci = Some([-0.0004, 0.2]);
    let text = table::render(&analysis);
    assert!(!text.contains("-0.0") && !text.contains("−0.0"), "{text}");
    assert!(text.contains("[0.000, 0.400]"), "{text}");
}

#[test]
fn fixed_drops_the_sign_of_zero_only() {
    assert_eq!(table::fixed(-0.0004, 3), "0.000");
    assert_eq!(table::fixed(-0.0, 2), "0.00");
    assert_eq!(table::fixed(-0.0006, 3), "-0.001");
    assert_eq!(table::fixed(-12.5, 1), "-12.5");
    assert_eq!(table::fixed(-3e-7, 0), "0");
    assert_eq!(table::fixed(f64::NAN, 2), "—");
    assert_eq!(table::fixed(f64::NEG_INFINITY, 2), "—");
}
