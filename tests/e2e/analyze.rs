//! `mrstudy analyze` end to end: the binary reads files, prints the table or the Analysis JSON,
//! writes the worth plot, and refuses bad input with one sentence and a non-zero exit, writing
//! nothing.

use std::path::{Path, PathBuf};
use std::process::Output;

fn mrstudy(args: &[&str]) -> Output {
    super::support::mrstudy().args(args).output().expect("run mrstudy")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A thesis-like anchored design: every condition against LQ and HQ, plus LQ–HQ.
fn thesis_like(dir: &Path) -> (PathBuf, PathBuf) {
    let conditions =
        "condition,gi,cm,ca\nLQ,0,0,0\nGI,1,0,0\nCM,0,1,0\nCA,0,0,1\nGI+CM,1,1,0\nGI+CA,1,0,1\nCM+CA,0,1,1\nHQ,1,1,1\n";
    let lambda = |c: &str| -> f64 {
        let x: Vec<f64> = conditions
            .lines()
            .find(|l| l.starts_with(&format!("{c},")))
            .unwrap()
            .split(',')
            .skip(1)
            .map(|v| v.parse().unwrap())
            .collect();
        0.54 * x[0] - 0.44 * x[1] + 0.86 * x[2]
    };
    let names = ["LQ", "GI", "CM", "CA", "GI+CM", "GI+CA", "CM+CA", "HQ"];
    let mut pairs = vec![("LQ", "HQ")];
    for c in &names[1..7] {
        pairs.push(("LQ", c));
        pairs.push((c, "HQ"));
    }
    let mut trials = String::from("participant,left,right,chosen,gender\n");
    let mut state = 12345u64;
    for p in 0..40 {
        let gender = if p % 3 == 0 { "female" } else { "male" };
        for rep in 0..5 {
            for &(a, b) in &pairs {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let uniform = (state >> 11) as f64 / (1u64 << 53) as f64;
                let p_a = 1.0 / (1.0 + (lambda(b) - lambda(a)).exp());
                let chosen = if uniform < p_a { a } else { b };
                let (left, right) = if (p + rep) % 2 == 0 { (a, b) } else { (b, a) };
                trials += &format!("p{p},{left},{right},{chosen},{gender}\n");
            }
        }
    }
    (write(dir, "trials.csv", &trials), write(dir, "conditions.csv", conditions))
}

#[test]
fn analyze_prints_a_table_and_json_and_draws_the_worth_plot() {
    let dir = tempfile::tempdir().unwrap();
    let (trials, conditions) = thesis_like(dir.path());
    let plot = dir.path().join("worth.svg");
    let out = mrstudy(&[
        "analyze",
        "--trials",
        trials.to_str().unwrap(),
        "--conditions",
        conditions.to_str().unwrap(),
        "--group-by",
        "gender",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("2600 judgments by 40 participants on 8 conditions; reference LQ"), "{table}");
    assert!(table.contains("factor model gi+cm+ca"));
    assert!(table.contains("=== group: female ==="));
    assert!(table.contains("Equal effects in every group"));
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"));
    for name in ["GI+CA", "female", "male"] {
        assert!(svg.contains(name), "plot lacks {name}");
    }

    let analyze_json = |extra: &[&str]| {
        let mut args = vec!["analyze", "--trials", trials.to_str().unwrap()];
        args.extend(["--conditions", conditions.to_str().unwrap(), "--format", "json"]);
        args.extend(extra);
        mrstudy(&args)
    };
    let out = analyze_json(&[]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(!text.contains("NaN") && !text.contains("null") && !text.contains("inf"));
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["judgments"], 2600);
    assert_eq!(json["reference"], "LQ");
    assert_eq!(json["items"][0]["log_worth"], 0.0);
    let worth: f64 = json["items"].as_array().unwrap().iter().map(|i| i["worth"].as_f64().unwrap()).sum();
    assert!((worth - 1.0).abs() < 1e-12);
    let names: Vec<&str> = json["covariates"].as_array().unwrap().iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(names, vec!["gi", "cm", "ca"]);
    assert!(json["covariate_model"]["lr_vs_items"]["p"].is_number());
    assert!(json["agreement"]["u"].is_number());
    assert!(json.get("groups").is_none(), "no groups asked for, none printed");
    // the centred MAP log-worths beside them, shrunk more with a smaller --prior-sd
    let map = |json: &serde_json::Value| -> Vec<f64> {
        json["items"].as_array().unwrap().iter().map(|i| i["log_worth_map"].as_f64().unwrap()).collect()
    };
    let wide = map(&json);
    assert!(wide.iter().sum::<f64>().abs() < 1e-9, "centred: {wide:?}");
    let out = analyze_json(&["--prior-sd", "0.1"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let narrow = map(&serde_json::from_slice(&out.stdout).unwrap());
    let spread = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
    assert!(spread(&narrow) < spread(&wide), "{narrow:?} against {wide:?}");
}

#[test]
fn analyze_reads_a_task_csv_and_runs_friedman() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("participant,condition,value\n");
    for p in 0..8 {
        for (k, condition) in ["none", "shadows", "shadows+indirect"].iter().enumerate() {
            text += &format!("p{p},{condition},{}\n", 10.0 + k as f64 * 0.5 + ((p * 7 + k * 3) % 5) as f64 * 0.3);
        }
    }
    let trials = write(dir.path(), "task.csv", &text);
    let out = mrstudy(&["analyze", "--trials", trials.to_str().unwrap(), "--format", "json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let friedman = &json["measures"][0]["friedman"];
    assert!(friedman["statistic"].is_number() && friedman["kendall_w"].is_number(), "{json}");
}

#[test]
fn bad_input_is_one_sentence_with_non_zero_exit_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("never.svg");
    let cases = [
        (
            "participant,left,right,chosen\np1,LQ,HQ,HQ\np2,LQ,HQ\n",
            None,
            "line 3: the row has 3 fields but the header has 4",
        ),
        (
            "participant,left,right,chosen\np1,LQ,HQ,GI\n",
            None,
            "line 2, column `chosen`: `GI` is neither the left (`LQ`) nor the right (`HQ`) condition",
        ),
        (
            "participant,left,right,chosen\np1,LQ,HQ,HQ\n",
            Some("condition,gi\nLQ,0\n"),
            "line 2: condition `HQ` is not in the conditions file",
        ),
        (
            "participant,left,right,chosen\np1,LQ,HQ,HQ\n",
            Some("condition,gi\nLQ,0\nHQ,1\nLQ,1\n"),
            "line 4: condition `LQ` is listed twice (first on line 2)",
        ),
        (
            "participant,left,right,chosen\np1,LQ,HQ,HQ\n",
            Some("condition,gi\nLQ,off\nHQ,1\n"),
            "line 2, column `gi`: the factor level `off` is not a finite number",
        ),
    ];
    for (k, (trials, conditions, expected)) in cases.iter().enumerate() {
        let trials_path = write(dir.path(), &format!("t{k}.csv"), trials);
        let mut args = vec![
            "analyze".to_string(),
            "--trials".into(),
            trials_path.to_str().unwrap().into(),
            "--plot".into(),
            plot.to_str().unwrap().into(),
        ];
        if let Some(conditions) = conditions {
            let path = write(dir.path(), &format!("c{k}.csv"), conditions);
            args.extend(["--conditions".to_string(), path.to_str().unwrap().to_string()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = mrstudy(&args);
        assert!(!out.status.success(), "case {k} succeeded");
        assert!(out.stdout.is_empty(), "case {k} printed output");
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert!(stderr.contains(expected), "case {k}: {stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "case {k}: one line: {stderr}");
        assert!(!plot.exists(), "case {k} wrote a plot");
    }
    let out = mrstudy(&["analyze", "--trials", "/nonexistent/trials.csv"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read /nonexistent/trials.csv"));
}

/// Issue 12: an export-like trials CSV with pilot and excluded participants and the columns
/// `analyze` must ignore.
fn export_with_pilots(dir: &Path) -> PathBuf {
    let mut text =
        String::from("participant,left,right,chosen,status,completion_code,too_fast,PROLIFIC_PID,pilot,excluded\n");
    let wins = |a: &str, b: &str, k: usize| {
        if (a.len() + b.len() + k).is_multiple_of(3) { a.to_string() } else { b.to_string() }
    };
    let names = ["LQ", "GI", "HQ"];
    for (participant, pilot, excluded) in [
        ("p1", false, false),
        ("p2", false, false),
        ("p3", false, false),
        ("p4", false, false),
        ("pilot", true, false),
        ("gone", false, true),
    ] {
        for k in 0..6 {
            for a in 0..3 {
                for b in a + 1..3 {
                    let chosen = wins(names[a], names[b], k + participant.len());
                    text += &format!(
                        "{participant},{},{},{chosen},completed,XYZ,false,pid-{participant},{pilot},{excluded}\n",
                        names[a], names[b]
                    );
                }
            }
        }
    }
    write(dir, "export.csv", &text)
}

#[test]
fn analyze_leaves_out_pilots_and_excluded_by_default_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let trials = export_with_pilots(dir.path());
    let trials = trials.to_str().unwrap();
    let out = mrstudy(&["analyze", "--trials", trials, "--format", "json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((json["participants"].as_u64(), json["judgments"].as_u64()), (Some(4), Some(72)));
    assert_eq!(json["left_out"]["pilots"], 1);
    assert_eq!(json["left_out"]["excluded"], 1);
    assert_eq!(
        json["warnings"][0],
        "left out 2 participants and 36 judgments: 1 pilot participant with 18 judgments (pilot = true); 1 excluded participant with 18 judgments (excluded = true)"
    );
    let out = mrstudy(&["analyze", "--trials", trials]);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.starts_with("72 judgments by 4 participants"), "{table}");
    assert!(table.contains("warning: left out 2 participants and 36 judgments"), "{table}");

    let out = mrstudy(&["analyze", "--trials", trials, "--format", "json", "--include-pilots"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((json["participants"].as_u64(), json["left_out"]["pilots"].as_u64()), (Some(5), Some(0)));
    let out = mrstudy(&["analyze", "--trials", trials, "--format", "json", "--include-pilots", "--include-excluded"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["participants"], 6);
    assert!(json.get("left_out").is_none());
    assert!(!json["warnings"].as_array().unwrap().iter().any(|w| w.as_str().unwrap().starts_with("left out")));
}

#[test]
fn analyze_refuses_a_pilot_value_other_than_true_or_false() {
    let dir = tempfile::tempdir().unwrap();
    let trials = write(
        dir.path(),
        "t.csv",
        "participant,left,right,chosen,pilot,excluded\np1,LQ,HQ,HQ,false,false\np2,LQ,HQ,LQ,no,false\n",
    );
    let out = mrstudy(&["analyze", "--trials", trials.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(out.stdout.is_empty());
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains(&format!("{}: line 3, column `pilot`: `no` is neither `true` nor `false`", trials.display())),
        "{stderr}"
    );
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
}

/// A group of one participant's four judgments is estimated by Firth's likelihood (before
/// issue 44 its fit did not converge and the group was "not estimable"); the test across
/// groups, which Firth fits lack, is reported as not estimable with its reason, everything else
/// is printed, and the exit is 0.
#[test]
fn analyze_group_by_reports_what_it_cannot_estimate_and_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let (trials, conditions) = thesis_like(dir.path());
    let mut text = std::fs::read_to_string(&trials).unwrap();
    text += "solo,LQ,HQ,HQ,diverse\nsolo,LQ,GI,GI,diverse\nsolo,GI,HQ,HQ,diverse\nsolo,LQ,CA,CA,diverse\n";
    std::fs::write(&trials, text).unwrap();
    let plot = dir.path().join("worth.svg");
    let args = [
        "analyze",
        "--trials",
        trials.to_str().unwrap(),
        "--conditions",
        conditions.to_str().unwrap(),
        "--group-by",
        "gender",
    ];
    let out = mrstudy(&[&args[..], &["--format", "json", "--plot", plot.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(!text.contains("NaN") && !text.contains("null"));
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["groups"]["diverse"]["judgments"], 4);
    assert_eq!(json["groups"]["diverse"]["method"], "firth");
    assert!(json["groups"]["female"]["covariates"].is_array() && json["groups"]["male"]["covariates"].is_array());
    assert!(json.get("group_test").is_none());
    assert_eq!(json["not_estimable"][0]["part"], "group_test");
    assert!(std::fs::read_to_string(&plot).unwrap().contains(">female<"));
    let out = mrstudy(&args);
    assert!(out.status.success());
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("=== group: diverse ===\n4 judgments by 1 participants"), "{table}");
    assert!(
        table.contains(
            "warning: test of equal effects across groups not estimable: a fit needed Firth's bias reduction"
        ),
        "{table}"
    );
    assert!(!table.contains("-0.000"), "{table}");
}

/// Early data of a survey with rendered stimuli (issue 44): seven stimuli judged once or twice,
/// most only winning or only losing, and one in the metrics CSV nobody judged yet. `analyze
/// --stimuli` prints everything with the stimulus model fitted by Firth and exits 0 (before,
/// it exited 1: "the stimulus model of the metrics analysis did not converge in 200
/// iterations").
#[test]
fn analyze_with_stimuli_on_early_data_exits_zero() {
    let dir = tempfile::tempdir().unwrap();
    let condition = ["A", "B", "B", "A", "A", "C", "B"];
    let tallies = [(0, 1, 6, 4), (0, 2, 1, 0), (1, 3, 0, 1), (2, 4, 1, 0), (3, 5, 0, 2), (1, 5, 1, 0), (0, 6, 0, 1)];
    let mut trials = String::from("participant,left,right,chosen,scene_left,scene_right\n");
    for (n, &(k, l, wins_k, wins_l)) in tallies.iter().enumerate() {
        for judgment in 0..wins_k + wins_l {
            let chosen = if judgment < wins_k { condition[k] } else { condition[l] };
            trials += &format!("p{},{},{},{chosen},s{k},s{l}\n", (n + judgment) % 3, condition[k], condition[l]);
        }
    }
    let mut metrics = String::from("stimulus,scene,condition,metric,region,value\n");
    for (k, condition) in condition.iter().chain(["A"].iter()).enumerate() {
        metrics += &format!("h{k},s{k},{condition},flip_mean,image,{}\n", 0.1 + 0.07 * k as f64);
    }
    let trials = write(dir.path(), "trials.csv", &trials);
    let metrics = write(dir.path(), "stimuli.csv", &metrics);
    let out = mrstudy(&["analyze", "--trials", trials.to_str().unwrap(), "--stimuli", metrics.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("image metrics against perceived preference, per stimulus"), "{table}");
    assert!(table.contains("7 items fitted by Firth bias-reduced (penalised) likelihood"), "{table}");
    assert!(table.contains("warning: separation among the stimuli ("), "{table}");
}
