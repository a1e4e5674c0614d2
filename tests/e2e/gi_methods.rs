//! Issue 18, Deliver 4: a study whose `gi` factor names its methods (studies/examples/
//! gi-methods.toml, made small): `mrstudy stimuli` renders DIR on the GPU and DIT, EM and VCT
//! on the CPU, each with its errors against the ground truth, and the analysis's columns code
//! the methods against `off`.

use std::collections::BTreeMap;

use super::support::{bench_render_quick, mrstudy, repo_studies_dir, temp_dir};

/// The example study at 64×48 pixels, 4 samples, one scene configuration.
fn small_example(dir: &std::path::Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo_studies_dir().join("examples/gi-methods.toml")).unwrap();
    let text = text.replace("size = [640, 480]\nspp = 32", "size = [64, 48]\nspp = 4\nvpls = 16");
    let cut = text.find("[[scenes]]\nname = \"survey-2\"").unwrap();
    let design = text.find("[design]").unwrap();
    let text = format!("{}{}", &text[..cut], &text[design..]);
    let file = dir.join("gi-methods.toml");
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn a_study_names_its_gi_methods_and_gets_each_method_s_stimuli_and_errors() {
    let dir = temp_dir("gi-methods", "stimuli");
    let study = small_example(&dir);
    let (data, named, metrics) = (dir.join("data"), dir.join("named"), dir.join("stimuli.csv"));
    let output = mrstudy()
        .args(["stimuli", "--study"])
        .arg(&study)
        .arg("--data-dir")
        .arg(&data)
        .arg("--out")
        .arg(&named)
        .arg("--metrics")
        .arg(&metrics)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    if !output.status.success() && stderr.contains("adapter") {
        eprintln!("skipping: no GPU adapter ({stderr})");
        return;
    }
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("rendered 5 stimuli"), "{stderr}");
    // five different images, one per method
    let mut images = BTreeMap::new();
    for entry in std::fs::read_dir(&named).unwrap() {
        let path = entry.unwrap().path();
        images.insert(path.file_name().unwrap().to_string_lossy().to_string(), std::fs::read(&path).unwrap());
    }
    let names: Vec<&String> = images.keys().collect();
    assert_eq!(
        names,
        ["survey-1__DIR.png", "survey-1__DIT.png", "survey-1__EM.png", "survey-1__OFF.png", "survey-1__VCT.png"]
    );
    let distinct: std::collections::BTreeSet<&Vec<u8>> = images.values().collect();
    assert_eq!(distinct.len(), 5);
    // every stimulus has its errors against the ground truth, the coherent ones included
    let csv = std::fs::read_to_string(&metrics).unwrap();
    for condition in ["OFF", "DIR", "EM", "DIT", "VCT"] {
        let row = csv
            .lines()
            .find(|line| line.contains(&format!(",survey-1,{condition},flip_mean,affected,")))
            .unwrap_or_else(|| panic!("no affected FLIP for {condition}:\n{csv}"));
        let value: f64 = row.rsplit(',').next().unwrap().parse().unwrap();
        assert!(value.is_finite() && value > 0.0 && value < 1.0, "{row}");
    }
    // a second run renders nothing again
    let again = mrstudy().args(["stimuli", "--study"]).arg(&study).arg("--data-dir").arg(&data).output().unwrap();
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(again.status.success() && stderr.contains("rendered 0 stimuli"), "{stderr}");
}

#[test]
fn the_methods_are_the_analysis_s_columns_against_off() {
    // the simulation takes effects by the design's columns: gi_dir, gi_em, gi_dit, gi_vct
    let study = repo_studies_dir().join("examples/gi-methods.toml");
    let output = mrstudy()
        .args(["simulate", "--study"])
        .arg(&study)
        .args(["--truth", "gi_dir=0.8,gi_dit=0.6,gi_em=0.2", "--participants", "4", "--runs", "2", "--format", "json"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let effects = report["truth"]["effects"].as_array().unwrap();
    let names: Vec<&str> = effects.iter().map(|e| e["factor"].as_str().unwrap()).collect();
    assert_eq!(names, ["gi_dir", "gi_em", "gi_dit", "gi_vct", "cm", "ca"]);
    let worths = report["truth"]["log_worths"].as_array().unwrap();
    assert_eq!(worths[1]["condition"], "DIR");
    assert_eq!(worths[1]["log_worth"], 0.8);
    // a factor name is refused, naming the columns
    let output = mrstudy()
        .args(["simulate", "--study"])
        .arg(&study)
        .args(["--truth", "gi=0.5", "--runs", "1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && stderr.contains("gi_dit"), "{stderr}");
}

#[test]
fn bench_render_gi_methods_times_each_stage_and_measures_each_method_against_the_ground_truth() {
    let dir = temp_dir("gi-methods", "bench");
    let Some(doc) = bench_render_quick(&dir, &["--gi-methods"]) else { return };
    let rows = doc["rows"].as_array().unwrap();
    let methods: Vec<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    assert_eq!(methods, ["dir", "off", "em", "dit", "vct"]);
    for row in rows {
        assert_eq!(row["scene"], "survey-1");
        let flip = row["flip"].as_f64().unwrap();
        assert!(flip > 0.0 && flip < 1.0 && row["rmse"].as_f64().unwrap().is_finite(), "{row}");
        assert!(row["ms"].as_f64().unwrap() > 0.0 && row["frame_ms"].as_f64().unwrap() > 0.0, "{row}");
        if row["method"] == "dir" {
            assert!(row["vpls"].as_u64().is_some() && row["quality"].is_null(), "{row}");
        } else {
            // the coherent stages: capture, representation, object, background (a frame on the
            // GPU runs its object and background in one pass: no split, and its own counters)
            assert_eq!(row["quality"], "med", "{row}");
            for stage in ["capture_ms", "representation_ms"] {
                assert!(row[stage].as_f64().unwrap() > 0.0, "{stage}: {row}");
            }
            let on_gpu = row["device"].as_str().unwrap().starts_with("representation and frame");
            assert_eq!(row["object_ms"].is_null(), on_gpu, "{row}");
            if on_gpu {
                assert_eq!(
                    (&row["counters"]["submits"], &row["counters"]["host_waits"]),
                    (&1.into(), &1.into()),
                    "{row}"
                );
            } else {
                assert!(row["object_ms"].as_f64().unwrap() > 0.0, "{row}");
            }
            // off builds the light probe only; the others an impostor or a voxel volume too
            assert_eq!(row["representation_bytes"].as_u64().unwrap() > 0, row["method"] != "off", "{row}");
        }
    }
    // the coherent methods beat gi off against the ground truth (as the renderer's tests check
    // at a larger size)
    let flip = |method: &str| rows.iter().find(|r| r["method"] == method).unwrap()["flip"].as_f64().unwrap();
    for method in ["em", "dit"] {
        assert!(flip(method) < flip("off"), "{method}: {} against off {}", flip(method), flip("off"));
    }
    let svg = std::fs::read_to_string(dir.join("render_gi_methods_survey-1.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("DIR (VPLs)") && svg.contains("DIT"), "{svg}");
}

#[test]
fn bench_render_paper_tables_measures_rohmer_s_tables_beside_the_paper_s_numbers() {
    let dir = temp_dir("gi-methods", "paper-tables");
    let Some(doc) = bench_render_quick(&dir, &["--paper-tables"]) else { return };
    let rows = doc["rows"].as_array().unwrap();
    let table = |k: u64| rows.iter().filter(move |r| r["table"] == k);
    // quick: Table 2's DIT med and high; Tables 3 and 4 at their first and last N
    assert_eq!(table(2).count(), 2);
    assert_eq!(table(3).count(), 3 * 2 * 2);
    assert_eq!(table(4).count(), 3 * 3 * 2);
    for row in rows {
        assert_eq!((row["scene"].as_str(), row["width"].as_u64()), (Some("survey-1"), Some(160)), "{row}");
        let ms = row["ms"].as_f64().unwrap();
        assert!(ms > 0.0 && row["frame_ms"].as_f64().unwrap() >= ms, "{row}");
        // every cell measured here has the paper's PC number beside it
        assert!(row["paper_ms"].as_f64().is_some_and(|p| p > 0.0), "{row}");
    }
    // Table 2 reports the representation's build; Table 4 is the background alone
    assert!(table(2).all(|r| r["representation_ms"].as_f64().is_some_and(|m| m > 0.0)));
    assert!(table(4).all(|r| r["ms"] == r["background_ms"] && r["visibility"] == true));
    // Table 3's paper numbers: DIT with visibility at N = 64 is 51.86 ms
    let dit64 = table(3).find(|r| r["method"] == "dit" && r["samples"] == 64 && r["visibility"] == true).unwrap();
    assert_eq!(dit64["paper_ms"].as_f64(), Some(51.86));
    // more directions cost more background time (N = 8 against 128, cache 32)
    for method in ["em", "dit", "vct"] {
        let at = |n: u64| {
            table(4).find(|r| r["method"] == method && r["cache"] == 32 && r["samples"] == n).unwrap()["ms"]
                .as_f64()
                .unwrap()
        };
        assert!(at(128) > at(8), "{method}: {} against {}", at(128), at(8));
    }
    let svg = std::fs::read_to_string(dir.join("render_paper_table4.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("paper, GTX 980"), "{svg}");
}
