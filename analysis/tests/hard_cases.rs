//! The hard cases of a paired-comparison analysis: each must give an honest, finite answer
//! that says what happened, never NaN, infinity or a runaway estimate.

use mrstudy_analysis::analysis::{Analysis, Options, Part, Screening, analyze};
use mrstudy_analysis::fit::Method;

fn options() -> Options {
    Options { screening: Screening::Off, ..Options::default() }
}

fn trials(rows: &[(&str, &str, &str, &str, u64)]) -> String {
    let mut text = String::from("participant,left,right,chosen,count\n");
    for (participant, left, right, chosen, count) in rows {
        text += &format!("{participant},{left},{right},{chosen},{count}\n");
    }
    text
}

/// Serialises and checks that no number is NaN or infinite (serde_json would write `null`).
fn json(analysis: &Analysis) -> String {
    let text = serde_json::to_string(analysis).unwrap();
    assert!(!text.contains("null") && !text.contains("NaN") && !text.contains("inf"), "{text}");
    text
}

#[test]
fn disconnected_design_names_components_and_reports_no_cross_difference() {
    let text = trials(&[
        ("p1", "A", "B", "A", 7),
        ("p1", "A", "B", "B", 3),
        ("p2", "C", "D", "C", 4),
        ("p2", "C", "D", "D", 6),
    ]);
    let analysis = analyze(&text, None, &options()).unwrap();
    let components = analysis.components.as_ref().unwrap();
    assert_eq!(components.len(), 2);
    assert_eq!(components[0].conditions, vec!["A", "B"]);
    assert_eq!(components[1].conditions, vec!["C", "D"]);
    assert_eq!(components[1].reference, "C");
    let c = analysis.items.iter().find(|i| i.condition == "C").unwrap();
    assert_eq!((c.log_worth, c.component), (Some(0.0), Some(1)));
    // Worth is normalised within each component.
    let sum_cd: f64 = analysis.items.iter().filter(|i| i.component == Some(1)).filter_map(|i| i.worth).sum();
    assert!((sum_cd - 1.0).abs() < 1e-12);
    assert!(
        analysis.warnings.iter().any(|w| w.contains("disconnected into 2 components: {A, B}, {C, D}")),
        "{:?}",
        analysis.warnings
    );
    json(&analysis);
}

#[test]
fn condition_never_compared_is_listed_not_estimated() {
    let conditions = "condition,gi\nLQ,0\nGI,1\nHQ,1\n";
    let text = trials(&[("p", "LQ", "GI", "GI", 6), ("p", "LQ", "GI", "LQ", 4)]);
    let analysis = analyze(&text, Some(conditions), &options()).unwrap();
    let hq = analysis.items.iter().find(|i| i.condition == "HQ").unwrap();
    assert_eq!((hq.log_worth, hq.se, hq.comparisons), (None, None, 0));
    assert!(analysis.warnings.iter().any(|w| w == "never compared, so not estimated: HQ"));
    json(&analysis);
}

#[test]
fn all_judgments_identical_is_separation_with_a_finite_bias_reduced_estimate() {
    let text = trials(&[("p1", "A", "B", "A", 1), ("p2", "B", "A", "A", 1), ("p3", "A", "B", "A", 1)]);
    let analysis = analyze(&text, None, &options()).unwrap();
    assert_eq!(analysis.method, Method::Firth);
    let b = analysis.items.iter().find(|i| i.condition == "B").unwrap();
    // Firth on one binomial: logit((0 + ½)/(3 + 1)) = ln(0.5/3.5).
    assert!((b.log_worth.unwrap() - (0.5f64 / 3.5).ln()).abs() < 1e-9);
    assert!(analysis.warnings.iter().any(|w| w.contains("{A} never lost") && w.contains("{B} never won")));
    json(&analysis);
}

#[test]
fn single_participant_is_analysed_and_screening_says_why_it_is_skipped() {
    let text = trials(&[
        ("only", "A", "B", "A", 5),
        ("only", "A", "B", "B", 2),
        ("only", "B", "C", "B", 4),
        ("only", "B", "C", "C", 3),
        ("only", "A", "C", "C", 1),
        ("only", "A", "C", "A", 2),
    ]);
    let analysis =
        analyze(&text, None, &Options { screening: Screening::On, bootstrap: 50, ..Options::default() }).unwrap();
    assert_eq!(analysis.participants, 1);
    assert!(
        analysis
            .warnings
            .iter()
            .any(|w| w.contains("observer screening not estimable: it needs at least three participants"))
    );
    assert!(
        analysis.warnings.iter().any(|w| w.contains("bootstrap not estimable: it needs at least two participants"))
    );
    let parts: Vec<Part> = analysis.not_estimable.iter().map(|part| part.part).collect();
    assert_eq!(parts, [Part::ObserverScreening, Part::Bootstrap]);
    let value: serde_json::Value = serde_json::from_str(&json(&analysis)).unwrap();
    assert_eq!(value["not_estimable"][0]["part"], "observer_screening");
    assert_eq!(value["not_estimable"][1]["reason"], "it needs at least two participants");
}

#[test]
fn billion_judgments_per_pair_keep_full_precision() {
    let text = trials(&[
        ("p", "A", "B", "A", 3_000_000_000),
        ("p", "A", "B", "B", 1_000_000_000),
        ("p", "B", "C", "B", 2_000_000_000),
        ("p", "B", "C", "C", 2_000_000_000),
    ]);
    let analysis = analyze(&text, None, &options()).unwrap();
    let b = analysis.items.iter().find(|i| i.condition == "B").unwrap();
    let c = analysis.items.iter().find(|i| i.condition == "C").unwrap();
    // A chain design is saturated: the MLE reproduces the empirical logits exactly.
    assert!((b.log_worth.unwrap() - (1.0f64 / 3.0).ln()).abs() < 1e-12);
    assert!((c.log_worth.unwrap() - (1.0f64 / 3.0).ln()).abs() < 1e-12);
    assert_eq!(analysis.judgments, 8_000_000_000);
    assert!(analysis.item_model.deviance.abs() < 1e-3);
    json(&analysis);
}

#[test]
fn tiny_p_values_are_printed_as_a_bound_with_their_order_of_magnitude() {
    let conditions = "condition,gi\nLQ,0\nGI,1\n";
    let text = trials(&[("p", "LQ", "GI", "GI", 600_000), ("p", "LQ", "GI", "LQ", 400_000)]);
    let analysis = analyze(&text, Some(conditions), &options()).unwrap();
    let gi = &analysis.covariates.as_ref().unwrap()[0];
    assert!(gi.z > 190.0);
    assert_eq!(gi.p.p, 1e-300);
    assert!(gi.p.log10_p < -7000.0, "{}", gi.p.log10_p);
    let table = mrstudy_analysis::table::render(&analysis);
    assert!(table.contains("< 1e-300"), "{table}");
    json(&analysis);
}

#[test]
fn constant_and_collinear_factors_are_dropped_with_named_warnings() {
    // `lamp` is constant over the compared conditions; `cm2` duplicates `cm`.
    let conditions = "condition,gi,cm,lamp,cm2\nLQ,0,0,1,0\nGI,1,0,1,0\nCM,0,1,1,1\nHQ,1,1,1,1\n";
    let mut rows = Vec::new();
    for (a, b) in [("LQ", "GI"), ("LQ", "CM"), ("LQ", "HQ"), ("GI", "HQ"), ("CM", "HQ"), ("GI", "CM")] {
        rows.push(("p1", a, b, a, 4));
        rows.push(("p2", a, b, b, 6));
    }
    let analysis = analyze(&trials(&rows), Some(conditions), &options()).unwrap();
    let names: Vec<&str> = analysis.covariates.as_ref().unwrap().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, vec!["gi", "cm"]);
    let dropped = &analysis.covariate_model.as_ref().unwrap().dropped;
    assert_eq!(dropped[0].name, "lamp");
    assert_eq!(dropped[0].reason, "constant over the compared conditions");
    assert_eq!(dropped[1].name, "cm2");
    assert_eq!(dropped[1].reason, "collinear with cm");
    assert!(
        analysis.warnings.iter().any(|w| w == "factor model: `lamp` dropped, constant over the compared conditions")
    );
    json(&analysis);
}

#[test]
fn factors_constant_within_a_group_are_dropped_in_that_group_only() {
    let conditions = "condition,gi,ca\nLQ,0,0\nGI,1,0\nCA,0,1\n";
    let mut rows = Vec::new();
    for (a, b, w, l) in [("LQ", "GI", 3, 7), ("LQ", "CA", 2, 8), ("GI", "CA", 5, 5)] {
        rows.push(format!("x,{a},{b},{a},{w},f"));
        rows.push(format!("y,{a},{b},{b},{l},f"));
    }
    // Group m only compared LQ with GI: ca is constant there.
    rows.push("z,LQ,GI,LQ,4,m".to_string());
    rows.push("w,LQ,GI,GI,6,m".to_string());
    let text = format!("participant,left,right,chosen,count,gender\n{}\n", rows.join("\n"));
    let analysis = analyze(&text, Some(conditions), &Options { group_by: Some("gender".into()), ..options() }).unwrap();
    let groups = analysis.groups.as_ref().unwrap();
    let (f, m) = (groups["f"].analysis().unwrap(), groups["m"].analysis().unwrap());
    assert_eq!(f.covariates.as_ref().unwrap().len(), 2);
    assert_eq!(m.covariates.as_ref().unwrap().len(), 1);
    assert!(m.warnings.iter().any(|w| w.contains("`ca` dropped")));
    let test = analysis.group_test.as_ref().unwrap();
    assert_eq!(test.df, 1, "3 group parameters against 2 pooled");
    json(&analysis);
}

#[test]
fn unknown_reference_and_bad_model_are_clear_errors() {
    let text = trials(&[("p", "A", "B", "A", 1)]);
    let error = analyze(&text, None, &Options { reference: Some("Z".into()), ..options() }).unwrap_err().to_string();
    assert_eq!(error, "reference: `Z` is not a condition of the data (conditions: A, B)");
    let error = analyze(&text, None, &Options { model: Some("gi".into()), ..options() }).unwrap_err().to_string();
    assert_eq!(error, "model `gi`: a factor model needs a conditions file with factor columns");
}

#[test]
fn bootstrap_is_reproducible_for_a_seed() {
    let mut rows = Vec::new();
    let names = ["A", "B", "C"];
    for p in 0..12 {
        for (x, y) in [(0, 1), (1, 2), (0, 2)] {
            let chosen = if (p + x + y) % 3 == 0 { names[y] } else { names[x] };
            rows.push((format!("p{p}"), names[x], names[y], chosen));
        }
    }
    let text = format!(
        "participant,left,right,chosen\n{}\n",
        rows.iter().map(|(p, a, b, c)| format!("{p},{a},{b},{c}")).collect::<Vec<_>>().join("\n")
    );
    let run = |seed| analyze(&text, None, &Options { bootstrap: 200, seed, ..options() }).unwrap();
    let (a, b, c) = (run(5), run(5), run(6));
    let ci = |x: &Analysis| x.items.iter().map(|i| i.ci).collect::<Vec<_>>();
    assert_eq!(ci(&a), ci(&b));
    assert_ne!(ci(&a), ci(&c));
    for item in &a.items[1..] {
        let [lo, hi] = item.ci.unwrap();
        assert!(lo < item.log_worth.unwrap() && item.log_worth.unwrap() < hi);
    }
}

#[test]
fn observer_screening_flags_a_contrarian_and_drops_nobody() {
    // 20 participants prefer A > B > C > D; one always chooses the opposite.
    let names = ["A", "B", "C", "D"];
    let mut text = String::from("participant,left,right,chosen\n");
    for p in 0..21 {
        for x in 0..4 {
            for y in x + 1..4 {
                for rep in 0..3 {
                    let consensus = if (p + x + y + rep) % 5 == 0 { names[y] } else { names[x] };
                    let chosen =
                        if p == 20 { if consensus == names[x] { names[y] } else { names[x] } } else { consensus };
                    text += &format!("p{p},{},{},{chosen}\n", names[x], names[y]);
                }
            }
        }
    }
    let analysis = analyze(&text, None, &Options { screening: Screening::On, ..Options::default() }).unwrap();
    let screening = analysis.observers.as_ref().unwrap();
    assert_eq!(screening.flagged, vec!["p20".to_string()]);
    assert_eq!(screening.participants.len(), 21, "everyone is listed");
    assert_eq!(analysis.participants, 21, "nobody is dropped");
}

#[test]
fn consistence_uses_each_participants_majority_per_pair() {
    // p1 is transitive by majority (A > B > C, A > C) with large repeated counts; p2 is circular.
    let text = trials(&[
        ("p1", "A", "B", "A", 5000),
        ("p1", "A", "B", "B", 1200),
        ("p1", "B", "C", "B", 3),
        ("p1", "B", "C", "C", 1),
        ("p1", "A", "C", "A", 2),
        ("p2", "A", "B", "A", 1),
        ("p2", "B", "C", "B", 1),
        ("p2", "A", "C", "C", 1),
        ("p3", "A", "B", "A", 1),
        ("p3", "A", "B", "B", 1),
        ("p3", "B", "C", "B", 1),
        ("p3", "A", "C", "C", 1),
    ]);
    let analysis = analyze(&text, None, &options()).unwrap();
    let zeta = |name: &str| analysis.consistence.iter().find(|c| c.participant == name).unwrap().consistence.clone();
    assert_eq!(zeta("p1").zeta, Some(1.0));
    assert_eq!(zeta("p2").zeta, Some(0.0));
    assert_eq!(zeta("p2").circular_triads, Some(1));
    assert!(zeta("p3").zeta.is_none() && zeta("p3").reason.is_some(), "a tied pair leaves no ζ");
}
