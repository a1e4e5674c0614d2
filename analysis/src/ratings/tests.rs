//! The rating analysis: MOS and t-intervals against direct computation, ACR-HR's differential
//! scores, P.910's screening rules, the hard cases (one rating, zero variance, a condition
//! rated once, missing cells) and the JSON's shape.

use super::*;

/// t(0.975, df) from scipy.stats.t.ppf (scipy 1.x), df = 1, 2, 3.
const T975: [f64; 3] = [12.706204736174694, 4.302652729749462, 3.1824463052837078];

fn csv(method: &str, rows: &[(&str, &str, &str, u8)]) -> String {
    let mut text = String::from("study,trial,participant,scene,condition,rating,method,pilot,excluded\n");
    for (index, (participant, scene, condition, rating)) in rows.iter().enumerate() {
        text.push_str(&format!("s,{index},{participant},{scene},{condition},{rating},{method},false,false\n"));
    }
    text
}

fn analyze(text: &str) -> RatingsAnalysis {
    analyze_rating_csv(text, "r.csv", RatingOptions::default()).unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-12
}

#[test]
fn mos_and_t_intervals_are_the_direct_computation() {
    // condition A in scene x: 5, 4, 3 (mean 4, s = 1, n = 3); condition B: 2, 1, 2, 2
    let text = csv(
        "acr",
        &[
            ("p1", "x", "A", 5),
            ("p2", "x", "A", 4),
            ("p3", "x", "A", 3),
            ("p1", "x", "B", 2),
            ("p2", "x", "B", 1),
            ("p3", "x", "B", 2),
            ("p1", "y", "B", 2),
        ],
    );
    let analysis = analyze(&text);
    assert_eq!(analysis.scale, "quality");
    let a = &analysis.stimuli[0];
    assert_eq!((a.scene.as_str(), a.condition.as_str(), a.ratings), ("x", "A", 3));
    assert!(close(a.mos, 4.0));
    let half = T975[1] * (1.0f64 / 3.0).sqrt();
    let ci = a.mos_ci.unwrap();
    assert!(close(ci[0], 4.0 - half) && close(ci[1], 4.0 + half), "{ci:?}");
    // condition B over both scenes: 2, 1, 2, 2 → mean 1.75, s² = 0.25
    let b = analysis.conditions.iter().find(|c| c.condition == "B").unwrap();
    assert_eq!(b.ratings, 4);
    let half = T975[2] * (0.25 / 4.0f64).sqrt();
    let ci = b.mos_ci.unwrap();
    assert!(close(b.mos, 1.75) && close(ci[0], 1.75 - half) && close(ci[1], 1.75 + half), "{ci:?}");
    // stimulus (y, B) has one score: no interval, said so
    let one = analysis.stimuli.iter().find(|s| s.scene == "y").unwrap();
    assert_eq!((one.ratings, one.mos_ci, one.note), (1, None, Some("one score: no interval")));
    // three participants: MLE_CO's iteration drives one inconsistency to 0, and says so
    let reason = analysis.model.not_estimable.as_deref().unwrap();
    assert!(reason.contains("the likelihood grows without bound"), "{reason}");
    assert!(analysis.stimuli.iter().all(|s| s.quality.is_none()));
    assert!(analysis.participants.iter().all(|p| p.note == Some("the model has no estimate")));
}

#[test]
fn acr_hr_scores_are_differential_per_participant_and_scene() {
    let text = "participant,scene,condition,rating,method,reference,scale\n\
                p1,x,ground-truth,4,acr-hr,ground-truth,quality\n\
                p1,x,A,3,acr-hr,ground-truth,quality\n\
                p1,y,ground-truth,5,acr-hr,ground-truth,quality\n\
                p1,y,A,5,acr-hr,ground-truth,quality\n\
                p2,x,ground-truth,3,acr-hr,ground-truth,quality\n\
                p2,x,A,4,acr-hr,ground-truth,quality\n\
                p2,y,A,2,acr-hr,ground-truth,quality\n";
    let analysis = analyze(text);
    assert_eq!(analysis.scores, "dv");
    // DV: p1 x A = 3 − 4 + 5 = 4; p1 y A = 5; p2 x A = 4 − 3 + 5 = 6 (above 5: kept);
    // p2 y A has no reference rating of p2 in y: left out and said so
    let x = analysis.stimuli.iter().find(|s| s.scene == "x").unwrap();
    assert_eq!((x.condition.as_str(), x.ratings), ("A", 2));
    assert!(close(x.mos, 5.0));
    let y = analysis.stimuli.iter().find(|s| s.scene == "y").unwrap();
    assert!(close(y.mos, 5.0) && y.ratings == 1);
    assert!(analysis.stimuli.iter().all(|s| s.condition != "ground-truth"));
    assert!(analysis.warnings.iter().any(|w| w.starts_with("1 rating(s) left out: ACR-HR")), "{:?}", analysis.warnings);
}

#[test]
fn dcr_is_scored_as_rated_on_the_impairment_scale() {
    let text = csv("dcr", &[("p1", "x", "A", 5), ("p2", "x", "A", 3), ("p1", "x", "B", 2), ("p2", "x", "B", 1)]);
    let analysis = analyze(&text);
    assert_eq!((analysis.scale, analysis.scores), ("impairment", "rating"));
    assert!(close(analysis.conditions[0].mos, 4.0) && close(analysis.conditions[1].mos, 1.5));
}

#[test]
fn golden_questions_are_never_data_and_screen_who_fails_them() {
    let text = "participant,scene,condition,rating,method,catch,expected\n\
                p1,x,A,5,acr,false,\np1,x,B,2,acr,false,\np1,g,gold,1,acr,true,1\n\
                p2,x,A,4,acr,false,\np2,x,B,1,acr,false,\np2,g,gold,2,acr,true,1\n\
                p3,x,A,3,acr,false,\np3,x,B,2,acr,false,\np3,g,gold,5,acr,true,1\n";
    let analysis = analyze(text);
    assert!(analysis.stimuli.iter().all(|s| s.scene != "g"), "golden rows are not data");
    let p = |id: &str| analysis.participants.iter().find(|p| p.participant == id).unwrap().clone();
    assert!(!p("p1").screened && !p("p2").screened, "within 1 of the expected rating passes");
    let p3 = p("p3");
    assert!(p3.screened && p3.reason.as_deref().unwrap().starts_with("golden question: 1 of 1"), "{p3:?}");
    assert_eq!((p3.golden_answered, p3.golden_failed, p3.bias), (1, 1, None));
    // p3's ratings are left out of the MOS
    assert_eq!(analysis.ratings, 4);
    assert!(close(analysis.conditions[0].mos, 4.5));
}

/// Sixteen participants (`p0` … `p15`, biases −0.4 … 0.35) rating 3 scenes × 3 conditions
/// (quality 4.2, 3, 1.8) with normal noise (sd 0.5 … 1.1 by participant; xorshift64* and
/// Box–Muller from a fixed seed), rounded and clipped to 1…5.
fn simulated() -> Vec<(String, &'static str, &'static str, u8)> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        ((state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut rows = vec![];
    for s in 0..16usize {
        for scene in ["x", "y", "z"] {
            for (condition, quality) in [("A", 4.2), ("B", 3.0), ("C", 1.8)] {
                let normal = (-2.0 * uniform().ln()).sqrt() * (2.0 * std::f64::consts::PI * uniform()).cos();
                let sd = 0.5 + 0.04 * s as f64;
                let value = quality + (s as f64 - 8.0) * 0.05 + sd * normal;
                rows.push((format!("p{s}"), scene, condition, value.round().clamp(1.0, 5.0) as u8));
            }
        }
    }
    rows
}

#[test]
fn straight_lining_and_zero_variance_screen_a_participant_and_one_rating_does_not() {
    let simulated = simulated();
    let mut rows: Vec<(&str, &str, &str, u8)> = simulated.iter().map(|(p, s, c, r)| (p.as_str(), *s, *c, *r)).collect();
    for (scene, condition) in [("x", "A"), ("x", "B"), ("y", "A"), ("y", "B")] {
        rows.push(("flat", scene, condition, 3));
    }
    rows.push(("once", "x", "A", 4));
    let analysis = analyze(&csv("acr", &rows));
    let p = |id: &str| analysis.participants.iter().find(|p| p.participant == id).unwrap().clone();
    let flat = p("flat");
    assert!(flat.screened);
    assert_eq!(flat.reason.as_deref(), Some("straight-lining: all 4 ratings are the same"));
    let once = p("once");
    assert!(!once.screened && once.reason.is_none(), "one rating has no variance to judge");
    assert_eq!((once.bias, once.note), (None, Some("fewer than two scores: not in the model")));
    assert!(analysis.model.not_estimable.is_none(), "{:?}", analysis.model);
    assert!(p("p1").bias.is_some() && p("p1").inconsistency_se.is_some());
    assert!(analysis.stimuli.iter().all(|s| s.quality.is_some() && s.quality_se.is_some()));
    let full = &analysis.full_model;
    assert!(full.not_estimable.is_none() && full.stimuli.len() == 9 && full.participants.len() == 16, "{full:?}");
    assert!(full.stimuli.iter().all(|s| s.quality.is_some() && s.quality_se.is_some()));
    // screening off: reported, nobody left out
    let off =
        analyze_rating_csv(&csv("acr", &rows), "r.csv", RatingOptions { screening: false, ..RatingOptions::default() })
            .unwrap();
    let flat = off.participants.iter().find(|p| p.participant == "flat").unwrap();
    assert!(!flat.screened && flat.reason.is_some() && flat.bias.is_some(), "{off:?}");
    assert_eq!(off.ratings, 16 * 9 + 5);
}

#[test]
fn outlier_votes_are_those_with_z_at_least_3_29() {
    // 14 votes of 5 and one of 1: z = (1 − mean)/sd with the population sd
    let mut votes = vec![5.0; 14];
    votes.push(1.0);
    let flags = screening::outlier_votes(&votes);
    let mean = votes.iter().sum::<f64>() / 15.0;
    let sd = (votes.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 15.0).sqrt();
    assert!(((1.0 - mean) / sd).abs() >= 3.29);
    assert_eq!(flags.iter().filter(|&&f| f).count(), 1);
    assert!(flags[14]);
    // too few votes can never reach 3.29: |z| ≤ √(n − 1) < 3.29 for n ≤ 11
    let mut few = vec![5.0; 10];
    few.push(1.0);
    assert!(screening::outlier_votes(&few).iter().all(|f| !f));
    assert!(screening::outlier_votes(&[3.0, 3.0]).iter().all(|f| !f));
}

#[test]
fn missing_cells_and_a_condition_rated_once_print_no_nan() {
    let text = csv("acr", &[("p1", "x", "A", 5), ("p1", "x", "B", 3), ("p2", "x", "A", 4), ("p2", "y", "C", 2)]);
    let analysis = analyze(&text);
    let c = analysis.conditions.iter().find(|c| c.condition == "C").unwrap();
    assert_eq!((c.ratings, c.mos_ci, c.note), (1, None, Some("one score: no interval")));
    let json = serde_json::to_string(&analysis).unwrap();
    assert!(!json.contains("NaN") && !json.contains("null") && !json.contains("inf"), "{json}");
    let table = report::render_table(&analysis);
    assert!(!table.contains("NaN") && !table.contains("inf"), "{table}");
}

#[test]
fn the_json_has_the_designed_keys() {
    let text = csv("acr", &[("p1", "x", "A", 5), ("p1", "x", "B", 3), ("p2", "x", "A", 4), ("p2", "x", "B", 1)]);
    let json = serde_json::to_value(analyze(&text)).unwrap();
    for key in ["scene", "condition", "mos", "mos_ci", "quality", "quality_se"] {
        assert!(json["stimuli"][0].get(key).is_some(), "stimuli[0].{key}: {json}");
    }
    for key in ["condition", "mos", "mos_ci"] {
        assert!(json["conditions"][0].get(key).is_some(), "conditions[0].{key}");
    }
    for key in ["participant", "bias", "inconsistency", "screened"] {
        assert!(json["participants"][0].get(key).is_some(), "participants[0].{key}");
    }
}

#[test]
fn bad_cells_are_one_sentence_naming_the_line() {
    let error = |text: &str| analyze_rating_csv(text, "r.csv", RatingOptions::default()).unwrap_err().to_string();
    let header = "participant,scene,condition,rating,method\n";
    assert_eq!(
        error(&format!("{header}p1,x,A,6,acr\n")),
        "r.csv: line 2, column `rating`: expected an integer from 1 to 5, found \"6\""
    );
    assert_eq!(
        error(&format!("{header}p1,x,A,3,acr\np1,x,B,3,dcr\n")),
        "r.csv: line 3, column `method`: the method must be the same on every row: \"dcr\" here, \"acr\" on line 2"
    );
    assert_eq!(
        error(&format!("{header}p1,x,A,3,ccr\n")),
        "r.csv: line 2, column `method`: expected acr, dcr or acr-hr, found \"ccr\""
    );
    assert!(error(&format!("{header}p1,x,A,,acr\n")).starts_with("r.csv: no answered rating trials"));
}

#[test]
fn analyze_reads_a_rating_export_by_its_header() {
    let text = csv("acr", &[("p1", "x", "A", 5), ("p1", "x", "B", 3), ("p2", "x", "A", 4), ("p2", "x", "B", 1)]);
    let options = crate::analysis::Options::default();
    let drawings = crate::command::Drawings { scatter: true, ..Default::default() };
    let printed = crate::command::analyze_files((&text, "r.csv"), None, None, &options, true, drawings).unwrap();
    let json: serde_json::Value = serde_json::from_str(&printed.text).unwrap();
    assert_eq!(json["ratings"]["conditions"][0]["condition"], "A");
    assert!(json.get("items").is_none());
    assert_eq!(printed.scatter_plots.len(), 1);
    assert_eq!(printed.scatter_plots[0].0, "ratings-mos.svg");
    let table =
        crate::command::analyze_files((&text, "r.csv"), None, None, &options, false, Default::default()).unwrap();
    assert!(table.text.starts_with("ratings (ACR, quality scale 1–5; 4 ratings"), "{}", table.text);
}

/// The header `mrstudy export` writes for a rating study (docs/design.md): the trials CSV's
/// own columns, then the rating columns; a golden question shown as an image has no scene.
#[test]
fn the_export_s_own_layout_is_read_with_its_catch_rows() {
    let text = "study,trial,participant,status,pilot,excluded,left,right,chosen,scene_left,catch_answered,catch_failed,scene,condition,rating,method,reference,scale,catch,expected\n\
                s,1,p1,complete,false,false,A,,,x,1,0,x,A,5,dcr,ground-truth,impairment,false,\n\
                s,2,p1,complete,false,false,B,,,x,1,0,x,B,2,dcr,ground-truth,impairment,false,\n\
                s,3,p1,complete,false,false,catch:blur,,,,1,0,,catch:blur,2,dcr,ground-truth,impairment,true,1\n\
                s,4,p2,complete,false,false,A,,,x,1,1,x,A,4,dcr,ground-truth,impairment,false,\n\
                s,5,p2,complete,false,false,B,,,x,1,1,x,B,1,dcr,ground-truth,impairment,false,\n\
                s,6,p2,complete,false,false,catch:blur,,,,1,1,,catch:blur,5,dcr,ground-truth,impairment,true,1\n";
    let analysis = analyze(text);
    assert_eq!((analysis.method, analysis.scale), (Method::Dcr, "impairment"));
    assert!(analysis.stimuli.iter().all(|s| !s.condition.starts_with("catch:")));
    let p2 = analysis.participants.iter().find(|p| p.participant == "p2").unwrap();
    assert!(p2.screened && p2.golden_failed == 1);
    assert_eq!(analysis.ratings, 2);
    // the report path the admin's live analysis takes (a conditions table given) reads it too
    let table = crate::data::ConditionTable {
        conditions: vec!["A".into(), "B".into()],
        factors: vec![],
        levels: vec![vec![], vec![]],
    };
    let options = crate::analysis::Options::default();
    let report = crate::report::analyze_with_table(text, "t.csv", Some(&table), None, &options).unwrap();
    assert_eq!(report.ratings.map(|r| r.ratings), Some(2));
}
