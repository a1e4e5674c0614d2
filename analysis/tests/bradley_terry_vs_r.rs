//! Bradley–Terry fits compared with R 4.2.2, BradleyTerry2 1.1.2 (BTm) and brglm 0.7.2.
//! The reference values and the script that produced them are in `tests/reference/`
//! (`bradley_terry.R`, one JSON file per case); the data go through the public CSV path, so
//! parsing, tallying and fitting are all exercised.

use mrstudy_analysis::analysis::{Analysis, Options, Screening, analyze};
use serde_json::Value;

/// Agreement required with R for estimates, standard errors, deviance and log-likelihood.
const TOLERANCE: f64 = 1e-6;

fn load(name: &str) -> Value {
    let path = format!("{}/tests/reference/{name}.json", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

/// The reference case as a trials CSV (with a `count` column) and a conditions CSV whose row
/// order is R's factor-level order.
fn csvs(case: &Value, factors: &[&str]) -> (String, String) {
    let mut trials = String::from("participant,left,right,chosen,count\n");
    for pair in case["pairs"].as_array().unwrap() {
        let (a, b) = (pair[0].as_str().unwrap(), pair[1].as_str().unwrap());
        let (wins_a, wins_b) = (pair[2].as_u64().unwrap(), pair[3].as_u64().unwrap());
        if wins_a > 0 {
            trials += &format!("\"{a}-{b}\",{a},{b},{a},{wins_a}\n");
        }
        if wins_b > 0 {
            trials += &format!("\"{a}-{b}\",{a},{b},{b},{wins_b}\n");
        }
    }
    let mut conditions = String::from("condition");
    for factor in factors {
        conditions += &format!(",{factor}");
    }
    conditions.push('\n');
    for (k, name) in case["conditions"].as_array().unwrap().iter().enumerate() {
        conditions += name.as_str().unwrap();
        for factor in factors {
            conditions += &format!(",{}", case["covariates"][factor][k]);
        }
        conditions.push('\n');
    }
    (trials, conditions)
}

fn run(case: &Value, factors: &[&str], model: Option<&str>, firth: bool) -> Analysis {
    let (trials, conditions) = csvs(case, factors);
    let options = Options {
        reference: Some(case["reference"].as_str().unwrap().to_string()),
        model: model.map(str::to_string),
        screening: Screening::Off,
        always_firth: firth,
        tolerance: 1e-12,
        ..Options::default()
    };
    analyze(&trials, Some(&conditions), &options).unwrap()
}

fn close(what: &str, actual: f64, expected: f64) {
    assert!(
        (actual - expected).abs() <= TOLERANCE,
        "{what}: mrstudy {actual} vs R {expected} (|Δ| = {:.2e})",
        (actual - expected).abs()
    );
}

fn check_items(analysis: &Analysis, reference: &Value) {
    for (name, expected) in reference["coefficients"].as_object().unwrap() {
        let item = analysis.items.iter().find(|i| &i.condition == name).unwrap();
        close(&format!("log-worth of {name}"), item.log_worth.unwrap(), expected.as_f64().unwrap());
        close(&format!("se of {name}"), item.model_se.unwrap(), reference["se"][name].as_f64().unwrap());
        assert!(item.se.unwrap() >= item.model_se.unwrap(), "se of {name} below the model's");
    }
    let reference_item = analysis.items.iter().find(|i| i.condition == analysis.reference).unwrap();
    assert_eq!(reference_item.log_worth, Some(0.0));
    let total: f64 = analysis.items.iter().filter_map(|i| i.worth).sum();
    close("worth sums to 1", total, 1.0);
}

fn check_summary(what: &str, summary: &mrstudy_analysis::analysis::ModelSummary, reference: &Value) {
    close(&format!("{what} deviance"), summary.deviance, reference["deviance"].as_f64().unwrap());
    assert_eq!(summary.df_residual, reference["df_residual"].as_i64().unwrap(), "{what} residual df");
    if let Some(loglik) = reference.get("loglik") {
        close(&format!("{what} log-likelihood"), summary.log_likelihood, loglik.as_f64().unwrap());
        close(&format!("{what} AIC"), summary.aic, reference["aic"].as_f64().unwrap());
    }
}

fn check_covariates(analysis: &Analysis, reference: &Value) {
    let covariates = analysis.covariates.as_ref().expect("factor model fitted");
    for (name, expected) in reference["coefficients"].as_object().unwrap() {
        let c = covariates.iter().find(|c| &c.name == name).unwrap_or_else(|| panic!("no covariate {name}"));
        close(&format!("estimate of {name}"), c.estimate, expected.as_f64().unwrap());
        // BradleyTerry2's standard error, z and p are the model's; the reported `se` (and its z
        // and p) is the larger of it and the participant-cluster robust one (`robust.rs`
        // checks that against R), so R's z and p are checked where the model's is the larger.
        close(&format!("se of {name}"), c.model_se, reference["se"][name].as_f64().unwrap());
        assert!(c.se >= c.model_se, "se of {name}: {} below the model's {}", c.se, c.model_se);
        if let Some(z) = reference.get("z").filter(|_| c.se == c.model_se) {
            close(&format!("z of {name}"), c.z, z[name].as_f64().unwrap());
            let p = z[name].as_f64().map(|_| reference["p"][name].as_f64().unwrap()).unwrap();
            assert!(
                (c.p.p - p).abs() <= TOLERANCE * p.max(1e-300) * 1e3 || (c.p.p - p).abs() < 1e-12,
                "p of {name}: {} vs {p}",
                c.p.p
            );
        } else if reference.get("z").is_some() {
            close(&format!("z of {name}"), c.z, c.estimate / c.se);
        }
    }
    assert_eq!(covariates.len(), reference["coefficients"].as_object().unwrap().len());
}

#[test]
fn citations_item_model_matches_bradleyterry2() {
    let case = load("citations");
    let analysis = run(&case, &[], None, false);
    check_items(&analysis, &case["models"]["item"]);
    check_summary("item model", &analysis.item_model, &case["models"]["item"]);
}

#[test]
fn citations_with_jasa_reference_matches_bradleyterry2() {
    let case = load("reference_choice");
    let analysis = run(&case, &[], None, false);
    assert_eq!(analysis.reference, "JASA");
    check_items(&analysis, &case["models"]["item"]);
}

#[test]
fn baseball_item_model_matches_bradleyterry2() {
    let case = load("baseball");
    let analysis = run(&case, &[], None, false);
    check_items(&analysis, &case["models"]["item"]);
    check_summary("item model", &analysis.item_model, &case["models"]["item"]);
}

#[test]
fn anchored_factor_models_match_bradleyterry2() {
    let case = load("factors");
    let analysis = run(&case, &["gi", "cm", "ca"], None, false);
    check_items(&analysis, &case["models"]["item"]);
    check_summary("item model", &analysis.item_model, &case["models"]["item"]);
    let factor = &case["models"]["factor"];
    check_covariates(&analysis, factor);
    let model = analysis.covariate_model.as_ref().unwrap();
    check_summary("factor model", &model.summary, factor);
    let lr = model.lr_vs_items.as_ref().unwrap();
    close("LR χ²", lr.chi2, factor["lr_vs_items"]["chi2"].as_f64().unwrap());
    assert_eq!(lr.df, factor["lr_vs_items"]["df"].as_i64().unwrap());
    close("LR p", lr.p.p, factor["lr_vs_items"]["p"].as_f64().unwrap());

    let interaction = &case["models"]["factor_interaction"];
    let analysis = run(&case, &["gi", "cm", "ca"], Some("gi+cm+ca+gi:ca"), false);
    check_covariates(&analysis, interaction);
    let model = analysis.covariate_model.as_ref().unwrap();
    check_summary("interaction model", &model.summary, interaction);
    close(
        "LR χ² (interaction)",
        model.lr_vs_items.as_ref().unwrap().chi2,
        interaction["lr_vs_items"]["chi2"].as_f64().unwrap(),
    );
}

#[test]
fn full_design_factor_model_matches_bradleyterry2() {
    let case = load("full_design");
    let analysis = run(&case, &["gi", "cm", "ca"], None, false);
    check_items(&analysis, &case["models"]["item"]);
    check_covariates(&analysis, &case["models"]["factor"]);
    check_summary("factor model", &analysis.covariate_model.as_ref().unwrap().summary, &case["models"]["factor"]);
}

#[test]
fn separation_gives_firth_estimate_matching_brglm() {
    let case = load("separation");
    let analysis = run(&case, &[], None, false);
    assert_eq!(analysis.method, mrstudy_analysis::fit::Method::Firth);
    check_items(&analysis, &case["models"]["item_br"]);
    close(
        "bias-reduced deviance",
        analysis.item_model.deviance,
        case["models"]["item_br"]["deviance"].as_f64().unwrap(),
    );
    let components = analysis.components.as_ref().expect("separation is reported per component");
    assert_eq!(components[0].never_lost, vec!["A".to_string()]);
    assert!(analysis.warnings.iter().any(|w| w.contains("{A} never lost")), "{:?}", analysis.warnings);
    // Never the runaway ML numbers (R: 22 ± 5613).
    let a = analysis.items.iter().find(|i| i.condition == "A").unwrap();
    assert!(a.log_worth.unwrap() < 10.0 && a.se.unwrap() < 10.0);
}

#[test]
fn factor_separation_gives_firth_estimate_matching_brglm() {
    let case = load("separation_factor");
    let analysis = run(&case, &["gi", "cm", "ca"], None, false);
    let model = analysis.covariate_model.as_ref().unwrap();
    assert_eq!(model.summary.method, mrstudy_analysis::fit::Method::Firth);
    check_covariates(&analysis, &case["models"]["factor_br"]);
    assert!(model.lr_vs_items.is_none(), "no LR test for bias-reduced fits");
    assert!(analysis.warnings.iter().any(|w| w.contains("separation in the factor model")));
    check_items(&analysis, &case["models"]["item_br"]);
}
