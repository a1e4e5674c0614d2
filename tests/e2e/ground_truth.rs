//! Issue 15's whole chain: render a study and its ground truths (`mrstudy stimuli`), serve it,
//! let simulated participants whose preference follows one stimulus metric answer over HTTP,
//! export the trials, and find that metric again with `mrstudy analyze --stimuli`.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::process::Command;

use serde_json::{Value, json};

use super::support::{Server, binary, client, demo_texts, export};

/// Three conditions (gi off, gi on, gi and colour mapping on) on two built-in scenes, shown on
/// different scene configurations side by side so that all six stimuli are compared with each
/// other (a six-cycle of stimuli): the analysis fits a worth per stimulus.
pub fn write_chain_study(dir: &Path) {
    let texts = demo_texts();
    let study = format!(
        r#"slug = "chain-mini"
title = "Chain"
kind = "paired-comparison"
question = "In which image do the objects fit in better?"

{texts}
[[factors]]
name = "gi"

[[factors]]
name = "cm"

[[conditions]]
name = "LQ"
levels = {{ gi = 0, cm = 0 }}

[[conditions]]
name = "GI"
levels = {{ gi = 1, cm = 0 }}

[[conditions]]
name = "GI+CM"
levels = {{ gi = 1, cm = 1 }}

[render]
size = [48, 36]
spp = 2
vpls = 16

[[scenes]]
name = "box"
render = "dir-lamp-box"

[[scenes]]
name = "shadow"
render = "dir-double-shadow"

[design]
pairs = "all"
repetitions = 4
scenes = "different"
seed = 15

[completion]
code = "CHAIN"
"#
    );
    std::fs::write(dir.join("chain-mini.toml"), study).unwrap();
}

/// The metric the simulated participants' preference follows.
const METRIC: (&str, &str) = ("rmse_linear", "affected");
const PARTICIPANTS: u64 = 24;

/// splitmix64: the simulated participants' random numbers, seeded per participant.
fn next_random(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as f64 / u64::MAX as f64
}

#[test]
fn render_serve_answer_export_and_analyze_find_the_metric_people_followed() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    let work = tempfile::tempdir().unwrap();
    write_chain_study(studies.path());

    // 1. Render: six stimuli, two ground truths, six records; named copies to know the images by.
    let named = work.path().join("named");
    let metrics_file = work.path().join("stimuli.csv");
    let rendered = Command::new(binary())
        .args(["stimuli", "--study"])
        .arg(studies.path().join("chain-mini.toml"))
        .arg("--data-dir")
        .arg(data_dir.path())
        .arg("--out")
        .arg(&named)
        .arg("--metrics")
        .arg(&metrics_file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&rendered.stderr);
    if !rendered.status.success() && stderr.contains("adapter") {
        eprintln!("skipping: no GPU adapter ({stderr})");
        return;
    }
    assert!(rendered.status.success(), "{stderr}");
    assert!(stderr.contains("rendered 6 stimuli, 0 were already"), "{stderr}");
    assert!(stderr.contains("2 ground truths and 6 stimulus records made"), "{stderr}");
    let mut stimulus_of_image: HashMap<Vec<u8>, String> = HashMap::new();
    for entry in std::fs::read_dir(&named).unwrap() {
        let path = entry.unwrap().path();
        let stimulus = path.file_stem().unwrap().to_str().unwrap().to_string();
        stimulus_of_image.insert(std::fs::read(&path).unwrap(), stimulus);
    }
    assert_eq!(stimulus_of_image.len(), 6, "six different images: {:?}", stimulus_of_image.values());

    // 2. Serve: the store is reused, nothing is rendered again, and the admin download of the
    //    metrics is the file `stimuli --metrics` wrote.
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    let http = client();
    let listed: Value = http.get(format!("{}/api/studies", server.base)).send().unwrap().json().unwrap();
    assert_eq!(listed[0]["slug"], "chain-mini", "{listed}");
    let downloaded = http
        .get(format!("{}/api/admin/studies/chain-mini/stimuli.csv", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .text()
        .unwrap();
    assert_eq!(downloaded, std::fs::read_to_string(&metrics_file).unwrap());
    let mut metric: BTreeMap<String, f64> = BTreeMap::new();
    for line in downloaded.lines().skip(1) {
        let row: Vec<&str> = line.split(',').collect();
        if (row[3], row[4]) == METRIC {
            // named copies are `<scene>__<condition>` with `+` written `-`
            metric.insert(format!("{}__{}", row[1], row[2]).replace('+', "-"), row[5].parse().unwrap());
        }
    }
    assert_eq!(metric.len(), 6, "{downloaded}");
    // A participant's utility of a stimulus is a monotone function of its error: its rank among
    // the six (the smallest error ranks highest), so near-equal errors are still told apart.
    let mut by_error: Vec<(&String, f64)> = metric.iter().map(|(stimulus, &value)| (stimulus, value)).collect();
    by_error.sort_by(|a, b| b.1.total_cmp(&a.1));
    assert!(by_error[0].1 > by_error[5].1, "the conditions' errors differ: {metric:?}");
    let utility: HashMap<String, f64> =
        by_error.iter().enumerate().map(|(rank, (stimulus, _))| ((*stimulus).clone(), rank as f64)).collect();

    // 3. Participants: each prefers the image with the higher utility, on a logistic curve over
    //    the difference (neighbours in rank are chosen right 69 % of the time, the extremes 98 %).
    let mut judgments = 0;
    for participant in 0..PARTICIPANTS {
        let joined: Value = http
            .post(format!("{}/api/studies/chain-mini/participants", server.base))
            .json(&json!({"demographics": {}}))
            .send()
            .unwrap()
            .json()
            .unwrap();
        let (id, token) = (joined["participant"].as_str().expect("joined"), joined["token"].as_str().unwrap());
        assert_eq!(joined["trials"], 12, "{joined}");
        let mut random = 0xC0FFEE ^ participant;
        loop {
            let next: Value = http
                .get(format!("{}/api/participants/{id}/next", server.base))
                .bearer_auth(token)
                .send()
                .unwrap()
                .json()
                .unwrap();
            if next["done"] == true {
                assert_eq!(next["completion_code"], "CHAIN");
                break;
            }
            let mut shown = Vec::new();
            for side in ["left", "right"] {
                let url = next[side]["url"].as_str().unwrap_or_else(|| panic!("{next}"));
                let bytes = http.get(format!("{}{url}", server.base)).send().unwrap().bytes().unwrap();
                shown.push(stimulus_of_image.get(bytes.as_ref()).expect("a shown image is one of the study's").clone());
            }
            let of = |stimulus: &String| {
                utility.get(stimulus).copied().unwrap_or_else(|| panic!("{stimulus} not in {metric:?}"))
            };
            let difference = 0.8 * (of(&shown[0]) - of(&shown[1]));
            let chosen = if next_random(&mut random) < 1.0 / (1.0 + (-difference).exp()) { "left" } else { "right" };
            let posted = http
                .post(format!("{}/api/participants/{id}/responses", server.base))
                .bearer_auth(token)
                .json(&json!({"trial": next["trial"], "chosen": chosen, "rt_ms": 1800}))
                .send()
                .unwrap();
            assert_eq!(posted.status(), 201);
            judgments += 1;
        }
    }
    assert_eq!(judgments, 12 * PARTICIPANTS);
    drop(server);

    // 4. Export and analyse.
    let trials = work.path().join("trials.csv");
    let conditions = work.path().join("conditions.csv");
    std::fs::write(&trials, export(data_dir.path(), "chain-mini", "csv")).unwrap();
    std::fs::write(&conditions, export(data_dir.path(), "chain-mini", "conditions")).unwrap();
    let plots = work.path().join("plots");
    let analyzed = Command::new(binary())
        .arg("analyze")
        .arg("--trials")
        .arg(&trials)
        .arg("--conditions")
        .arg(&conditions)
        .arg("--stimuli")
        .arg(&metrics_file)
        .arg("--plot-dir")
        .arg(&plots)
        .args(["--format", "json"])
        .output()
        .unwrap();
    assert!(analyzed.status.success(), "{}", String::from_utf8_lossy(&analyzed.stderr));
    let analysis: Value = serde_json::from_slice(&analyzed.stdout).unwrap();
    let metrics = &analysis["metrics"];
    assert_eq!(metrics["level"], "stimulus", "{metrics}");
    assert_eq!(metrics["judgments"], 12 * PARTICIPANTS, "{metrics}");
    assert_eq!(metrics["participants"], PARTICIPANTS, "{metrics}");
    assert_eq!(metrics["items"].as_array().unwrap().len(), 6, "{metrics}");
    let followed = metrics["correlations"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["metric"] == METRIC.0 && c["region"] == METRIC.1)
        .unwrap_or_else(|| panic!("no correlation for {METRIC:?}: {metrics}"));
    // the followed metric is the best predictor (others with the same ranking of the six
    // stimuli tie with it), and it predicts well
    assert!(followed["agreement"].as_f64().unwrap() >= 0.8, "{followed}");
    assert_eq!(followed["agreement"], metrics["best"]["agreement"], "{metrics}");
    // the followed metric's scatter plot, points labelled with the stimuli
    let plot = std::fs::read_to_string(plots.join(format!("metric-{}-{}.svg", METRIC.0, METRIC.1))).unwrap();
    assert!(plot.contains("shadow/GI+CM") && plot.contains("box/LQ"), "{plot}");
}
