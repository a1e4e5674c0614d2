//! `mrstudy simulate` and `mrstudy power` end to end: the demo study's scheduler and analysis on
//! simulated observers, the table, the JSON, the plots, reproducibility per seed, and refusals
//! of bad input with one sentence and a non-zero exit.

use std::process::Output;

use serde_json::Value;

fn mrstudy(args: &[&str]) -> Output {
    super::support::mrstudy().args(args).output().expect("run mrstudy")
}

fn demo() -> String {
    super::support::repo_studies_dir().join("shadows-demo.toml").display().to_string()
}

fn stdout(output: &Output) -> String {
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout.clone()).unwrap()
}

#[test]
fn simulate_prints_json_and_a_table_reproducibly_and_draws_the_plots() {
    let dir = super::support::temp_dir("simulate", "json");
    let study = demo();
    let plots = dir.display().to_string();
    let args = [
        "simulate",
        "--study",
        &study,
        "--truth",
        "shadow=0.8,ca=-0.3",
        "--participants",
        "3,6",
        "--runs",
        "4",
        "--designs",
        "study,all,active",
        "--format",
        "json",
        "--seed",
        "5",
        "--plot-dir",
        &plots,
    ];
    let first = stdout(&mrstudy(&args));
    assert_eq!(first, stdout(&mrstudy(&args)), "the same seed gives the same report");
    let report: Value = serde_json::from_str(&first).unwrap();
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    assert_eq!(rows[0]["design"], "study");
    assert_eq!(rows[0]["judgments_per_participant"]["mean"], 6.0, "6 pairs; the catch trial is no judgment");
    assert_eq!(rows[4]["design"], "active");
    assert_eq!(rows[4]["pairs"], "active");
    assert_eq!(report["truth"]["effects"][1]["effect"], -0.3);
    assert_eq!(rows[5]["power"][0]["factor"], "shadow");
    for name in ["simulate-rmse.svg", "simulate-power.svg"] {
        assert!(std::fs::read_to_string(dir.join(name)).unwrap().starts_with("<svg"), "{name}");
    }
    let table = stdout(&mrstudy(&[
        "simulate",
        "--study",
        &study,
        "--truth",
        "shadow=0.8",
        "--participants",
        "4",
        "--runs",
        "3",
    ]));
    assert!(table.contains("RMSE log-worth") && table.contains("power shadow"), "{table}");
    assert!(!table.contains("NaN") && !table.contains("inf"), "{table}");
}

#[test]
fn power_names_the_participants_per_factor_or_says_none_reached_it() {
    let study = demo();
    let text = stdout(&mrstudy(&[
        "power",
        "--study",
        &study,
        "--truth",
        "shadow=1.5,ca=0",
        "--participants",
        "2,8",
        "--runs",
        "8",
    ]));
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2, "{text}");
    assert!(lines[0].starts_with("study shadow (effect 1.50): "), "{text}");
    assert!(lines[1].contains("none of the participant counts reached power 0.80"), "{text}");
}

#[test]
fn bad_input_is_refused_with_one_sentence() {
    let dir = super::support::temp_dir("simulate", "bad");
    let study = demo();
    let worths = dir.join("worths.csv");
    std::fs::write(&worths, "condition,log_worth\nLQ,0\nSH,0.5\nCA,0.1\n").unwrap();
    let worths = worths.display().to_string();
    let two = dir.join("two.toml");
    let demo_text = std::fs::read_to_string(demo()).unwrap();
    let images = super::support::repo_studies_dir().join("shadows-demo").display().to_string();
    let two_conditions = demo_text
        .replace("shadows-demo/", &format!("{images}/"))
        .replace("[[conditions]]\nname = \"CA\"\nlevels = { shadow = 0, ca = 1 }\n", "")
        .replace("[[conditions]]\nname = \"SH+CA\"\nlevels = { shadow = 1, ca = 1 }\n", "");
    // Scenes map every condition to an image; keep only LQ and SH.
    let two_conditions: String = two_conditions
        .lines()
        .map(|line| match line.strip_prefix("images = { ") {
            Some(rest) => {
                let kept: Vec<&str> = rest.trim_end_matches(" }").split(", ").take(2).collect();
                format!("images = {{ {} }}", kept.join(", "))
            }
            None => line.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&two, two_conditions).unwrap();
    let two = two.display().to_string();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--truth", "gi=0.3"], "`gi` is not a factor of the study (factors: shadow, ca)"),
        (vec![], "not the thesis's gi, cm, ca, so there is no default truth"),
        (vec!["--truth", "shadow=0.3", "--participants", "0"], "--participants"),
        (vec!["--truth", "shadow=0.3", "--participants", "ten"], "--participants"),
        (vec!["--truth", "shadow=0.3", "--runs", "0"], "--runs must be at least 1"),
        (vec!["--truth", "shadow=0.3", "--lapse", "1"], "--lapse must be in [0, 1)"),
        (vec!["--truth", "shadow=0.3", "--dropout", "-0.5"], "--dropout must be in [0, 1)"),
        (vec!["--truth-worth", &worths], "no value for condition `SH+CA`"),
    ];
    for (extra, words) in cases {
        let mut args = vec!["simulate", "--study", study.as_str()];
        if !extra.contains(&"--runs") {
            args.extend(["--runs", "2"]);
        }
        args.extend(extra);
        let output = mrstudy(&args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(words), "{args:?}: {stderr}");
        assert!(output.stdout.is_empty(), "{args:?} printed {}", String::from_utf8_lossy(&output.stdout));
    }
    let output = mrstudy(&["simulate", "--study", &two, "--truth", "shadow=0.3", "--designs", "active", "--runs", "2"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(stderr.contains("the active design needs at least 3 conditions and the study has 2"), "{stderr}");
}
