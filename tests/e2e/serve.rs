//! `mrstudy serve` and `mrstudy export` as a user runs them: the binary on a real socket, a
//! whole participant flow over HTTP, resuming, the export, and start-up errors.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use serde_json::{Value, json};

use super::support::{Server, binary, client, copy_demo_study, demographics, export, repo_studies_dir};

#[test]
fn a_participant_completes_the_demo_study_over_a_real_socket() {
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let http = client();
    let base = &server.base;

    let studies: Value = http.get(format!("{base}/api/studies")).send().unwrap().json().unwrap();
    assert_eq!(studies[0]["slug"], "shadows-demo");
    assert_eq!(studies.as_array().unwrap().len(), 1);

    let joined = http
        .post(format!("{base}/api/studies/shadows-demo/participants"))
        .json(&json!({"demographics": demographics(), "client": {"viewport": [800, 600], "devicePixelRatio": 1.5}}))
        .send()
        .unwrap();
    assert_eq!(joined.status(), 201);
    let joined: Value = joined.json().unwrap();
    let id = joined["participant"].as_str().unwrap();
    let token = joined["token"].as_str().unwrap();
    assert_eq!(joined["trials"], 7);

    for trial in 1..=7 {
        // Asking twice (a reload) gives the same trial.
        for _ in 0..2 {
            let next: Value = http
                .get(format!("{base}/api/participants/{id}/next"))
                .bearer_auth(token)
                .send()
                .unwrap()
                .json()
                .unwrap();
            assert_eq!(next["trial"], trial, "{next}");
            let image = http.get(format!("{base}{}", next["left"]["url"].as_str().unwrap())).send().unwrap();
            assert_eq!(image.status(), 200);
        }
        let stored = http
            .post(format!("{base}/api/participants/{id}/responses"))
            .bearer_auth(token)
            .json(&json!({"trial": trial, "chosen": if trial % 3 == 0 { "right" } else { "left" }, "rt_ms": 1000 + trial}))
            .send()
            .unwrap();
        assert_eq!(stored.status(), 201);
    }
    let done: Value =
        http.get(format!("{base}/api/participants/{id}/next")).bearer_auth(token).send().unwrap().json().unwrap();
    assert_eq!(done, json!({"done": true, "completion_code": "DEMO-7F3A"}));

    // The admin CSV over HTTP and `mrstudy export` agree.
    let over_http = http
        .get(format!("{base}/api/admin/studies/shadows-demo/export.csv"))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .text()
        .unwrap();
    let from_cli = export(data_dir.path(), "shadows-demo", "csv");
    assert_eq!(over_http, from_cli);
    assert_eq!(from_cli.lines().count(), 7, "six judgments and the header:\n{from_cli}");
    assert!(
        from_cli.lines().nth(1).unwrap().contains(",800x600,1.5,,,1,completed,DEMO-7F3A,false,false,true,"),
        "answered at once: too fast by the server's clock {from_cli}"
    );
    assert!(from_cli.lines().nth(1).unwrap().contains(",male,44,"), "{from_cli}");
    assert_eq!(
        export(data_dir.path(), "shadows-demo", "conditions"),
        "condition,shadow,ca\nLQ,0,0\nSH,1,0\nCA,0,1\nSH+CA,1,1\n"
    );
    let json: Value = serde_json::from_str(&export(data_dir.path(), "shadows-demo", "json")).unwrap();
    assert_eq!(json["participants"][0]["answered"], 7);

    // The admin token was generated once and kept in the data directory.
    let kept = std::fs::read_to_string(data_dir.path().join("admin-token")).unwrap();
    assert_eq!(kept.trim(), server.admin_token);
    assert!(server.admin_token.len() >= 32);
}

/// A study of two conditions (gi off and on) on one built-in scene, rendered tiny.
fn write_rendered_study(dir: &Path) {
    super::support::write_rendered_study(dir, "rendered-mini", "Rendered", [48, 36], 2, "MINI");
}

/// Waits until `slug` is open (its stimuli rendered in the background); false, after saying so,
/// when it cannot be for want of a GPU adapter.
fn opened(server: &Server, slug: &str) -> bool {
    match server.wait_open(slug, Duration::from_secs(180)) {
        Err(warning) if warning.contains("adapter") => {
            eprintln!("skipping: no GPU adapter ({warning})");
            false
        }
        result => {
            result.unwrap();
            true
        }
    }
}

fn gpu_available(server: &Result<Server, String>) -> bool {
    match server {
        Err(error) if error.contains("adapter") => {
            eprintln!("skipping: no GPU adapter ({error})");
            false
        }
        _ => true,
    }
}

#[test]
fn serve_renders_missing_stimuli_on_first_start_and_reuses_them_after() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_rendered_study(studies.path());
    let first = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path());
    if !gpu_available(&first) {
        return;
    }
    let server = first.unwrap();
    // the stimuli render in the background once the server listens
    if !opened(&server, "rendered-mini") {
        return;
    }
    let http = client();

    // two stimuli rendered, indexed, and shown to a participant as 48×36 PNGs; beside them the
    // scene configuration's ground truth and each stimulus's record of its errors
    let index = data_dir.path().join("stimuli/rendered");
    let entries: Vec<PathBuf> = std::fs::read_dir(&index).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(entries.len(), 5, "{entries:?}");
    assert_eq!(entries.iter().filter(|e| e.extension().is_some_and(|x| x == "metrics")).count(), 2);
    let joined: Value = http
        .post(format!("{}/api/studies/rendered-mini/participants", server.base))
        .json(&json!({"demographics": {}}))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let next: Value = http
        .get(format!("{}/api/participants/{}/next", server.base, joined["participant"].as_str().unwrap()))
        .bearer_auth(joined["token"].as_str().unwrap())
        .send()
        .unwrap()
        .json()
        .unwrap();
    let mut images = Vec::new();
    for side in ["left", "right"] {
        let url = next[side]["url"].as_str().unwrap();
        let bytes = http.get(format!("{}{url}", server.base)).send().unwrap().bytes().unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), 48);
        assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().unwrap()), 36);
        images.push(bytes);
    }
    assert_ne!(images[0], images[1], "gi on and off must differ on dir-lamp-box");
    drop(server);

    // a second start renders nothing: the index entries are untouched
    let modified: Vec<_> = entries.iter().map(|e| std::fs::metadata(e).unwrap().modified().unwrap()).collect();
    let again = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    let listed: Value = http.get(format!("{}/api/studies", again.base)).send().unwrap().json().unwrap();
    assert_eq!(listed[0]["slug"], "rendered-mini");
    let after: Vec<_> = entries.iter().map(|e| std::fs::metadata(e).unwrap().modified().unwrap()).collect();
    assert_eq!(modified, after);
}

#[test]
fn stimuli_renders_a_study_once_and_writes_named_copies() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_rendered_study(studies.path());
    let run = || {
        Command::new(binary())
            .args(["stimuli", "--study"])
            .arg(studies.path().join("rendered-mini.toml"))
            .arg("--data-dir")
            .arg(data_dir.path())
            .arg("--out")
            .arg(data_dir.path().join("named"))
            .arg("--metrics")
            .arg(data_dir.path().join("stimuli.csv"))
            .output()
            .unwrap()
    };
    let first = run();
    let stderr = String::from_utf8_lossy(&first.stderr);
    if !first.status.success() && stderr.contains("adapter") {
        eprintln!("skipping: no GPU adapter ({stderr})");
        return;
    }
    assert!(first.status.success(), "{stderr}");
    assert!(stderr.contains("rendered 2 stimuli, 0 were already"), "{stderr}");
    assert!(stderr.contains("1 ground truths and 2 stimulus records made"), "{stderr}");
    for name in ["box__LQ.png", "box__GI.png"] {
        let bytes = std::fs::read(data_dir.path().join("named").join(name)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "{name}");
    }
    let metrics = std::fs::read_to_string(data_dir.path().join("stimuli.csv")).unwrap();
    let check_metrics = |metrics: &str| {
        let mut lines = metrics.lines();
        assert_eq!(lines.next(), Some("stimulus,scene,condition,metric,region,value"));
        let rows: Vec<Vec<&str>> = lines.map(|line| line.split(',').collect()).collect();
        for condition in ["LQ", "GI"] {
            let of: Vec<&Vec<&str>> = rows.iter().filter(|row| row[2] == condition).collect();
            // 7 metrics in the image and in the affected region (never empty: the virtual objects
            // are in it) and on the virtual objects when they are seen, and the render time
            assert!(of.len() == 7 * 3 + 1 || of.len() == 7 * 2 + 1, "{condition}: {}", of.len());
            assert!(of.iter().all(|row| row[0].len() == 68 && row[0].ends_with(".png") && row[1] == "box"));
            for row in &of {
                let value: f64 = row[5].parse().unwrap();
                assert!(value.is_finite() && value >= 0.0, "{row:?}");
            }
            assert!(of.iter().any(|row| row[3] == "render_ms" && row[4] == "image"));
        }
        let value = |condition: &str, metric: &str| -> f64 {
            rows.iter().find(|r| r[2] == condition && r[3] == metric && r[4] == "affected").unwrap()[5].parse().unwrap()
        };
        // LQ has no shadows or indirect light: further from the ground truth where the objects
        // change the scene than GI
        assert!(value("LQ", "rmse_linear") > value("GI", "rmse_linear"), "{metrics}");
    };
    check_metrics(&metrics);
    // A second run renders nothing and still writes every stimulus (they were already stored).
    std::fs::remove_dir_all(data_dir.path().join("named")).unwrap();
    let second = run();
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(second.status.success() && stderr.contains("rendered 0 stimuli, 2 were already"), "{stderr}");
    assert!(stderr.contains("wrote 2 stimuli into"), "{stderr}");
    for name in ["box__LQ.png", "box__GI.png"] {
        let bytes = std::fs::read(data_dir.path().join("named").join(name)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "{name}");
    }
    assert_eq!(std::fs::read_to_string(data_dir.path().join("stimuli.csv")).unwrap(), metrics);
    // A store from before stimulus records existed: the records are made, the images kept.
    for entry in std::fs::read_dir(data_dir.path().join("stimuli/rendered")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|x| x == "metrics") {
            std::fs::remove_file(path).unwrap();
        }
    }
    let third = run();
    let stderr = String::from_utf8_lossy(&third.stderr);
    assert!(third.status.success() && stderr.contains("rendered 0 stimuli, 2 were already"), "{stderr}");
    assert!(stderr.contains("0 ground truths and 2 stimulus records made"), "{stderr}");
    check_metrics(&std::fs::read_to_string(data_dir.path().join("stimuli.csv")).unwrap());
}

#[test]
fn serve_skips_a_rendered_study_it_cannot_render_with_one_warning() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_rendered_study(studies.path());
    copy_demo_study(studies.path());
    // GL llvmpipe cannot render the float targets the renderer needs: no adapter here
    let server = Server::try_start_with_env(
        data_dir.path(),
        "127.0.0.1:0",
        studies.path(),
        &[("MRSTUDY_ADAPTER", "gl")],
        Duration::from_secs(60),
    )
    .unwrap();
    // the server listens first; the warning comes when rendering in the background fails
    let warning = server.wait_open("rendered-mini", Duration::from_secs(60)).unwrap_err();
    assert!(warning.starts_with("warning: ") && warning.contains("not serving it"), "{warning}");
    assert!(!warning.contains(" | "), "one line: {warning}");
    let listed: Value = client().get(format!("{}/api/studies", server.base)).send().unwrap().json().unwrap();
    assert_eq!(listed.as_array().unwrap().len(), 1);
    assert_eq!(listed[0]["slug"], "shadows-demo");
}

#[test]
fn a_study_with_a_factor_the_renderer_lacks_is_refused_at_load() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_rendered_study(studies.path());
    let path = studies.path().join("rendered-mini.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("name = \"gi\"", "name = \"bloom\"")
        .replace("gi = ", "bloom = ");
    std::fs::write(&path, text).unwrap();
    let output = Command::new(binary())
        .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
        .arg(data_dir.path())
        .arg("--studies")
        .arg(studies.path())
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("rendered-mini.toml") && stderr.contains("conditions[0].levels") && stderr.contains("`bloom`"),
        "{stderr}"
    );
}

#[test]
fn serve_refuses_an_invalid_study_file_naming_file_and_key() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo_studies_dir().join("web-survey.toml")).unwrap();
    std::fs::write(studies.path().join("broken.toml"), text.replace("repetitions = 5", "repetitions = 0")).unwrap();
    let output = Command::new(binary())
        .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
        .arg(data_dir.path())
        .arg("--studies")
        .arg(studies.path())
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("broken.toml") && stderr.contains("design.repetitions") && stderr.contains("expected 1 to 100"),
        "{stderr}"
    );
    // said once (issue 46: the error was also its own cause, so it was printed twice)
    assert_eq!(stderr.matches("expected 1 to 100").count(), 1, "{stderr}");
}

#[test]
fn export_of_an_unknown_study_or_missing_database_is_one_clear_error() {
    let data_dir = tempfile::tempdir().unwrap();
    let output =
        Command::new(binary()).args(["export", "--study", "nope", "--data-dir"]).arg(data_dir.path()).output().unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("no database"), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1);
}

#[test]
fn exported_csv_fed_to_analyze_reproduces_the_live_analysis() {
    let data_dir = tempfile::tempdir().unwrap();
    let server = Server::start(data_dir.path(), "127.0.0.1:0");
    let http = client();
    let base = &server.base;
    for participant in 0..8u64 {
        let joined: Value = http
            .post(format!("{base}/api/studies/shadows-demo/participants"))
            .json(&json!({"demographics": demographics()}))
            .send()
            .unwrap()
            .json()
            .unwrap();
        let id = joined["participant"].as_str().unwrap();
        let token = joined["token"].as_str().unwrap();
        let mut noise = participant * 7 + 3;
        for trial in 1..=7 {
            http.get(format!("{base}/api/participants/{id}/next")).bearer_auth(token).send().unwrap();
            noise = noise.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let chosen = if noise >> 62 == 0 { "right" } else { "left" };
            let stored = http
                .post(format!("{base}/api/participants/{id}/responses"))
                .bearer_auth(token)
                .json(&json!({"trial": trial, "chosen": chosen, "rt_ms": 700}))
                .send()
                .unwrap();
            assert_eq!(stored.status(), 201);
        }
    }
    let live: Value = http
        .get(format!("{base}/api/admin/studies/shadows-demo/analysis"))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(live["judgments"], 48, "{live}");

    let trials = data_dir.path().join("trials.csv");
    let conditions = data_dir.path().join("conditions.csv");
    for (format, path) in [("csv", &trials), ("conditions", &conditions)] {
        let status = Command::new(binary())
            .args(["export", "--study", "shadows-demo", "--format", format, "--out"])
            .arg(path)
            .arg("--data-dir")
            .arg(data_dir.path())
            .args(super::support::database_args(super::support::test_database(data_dir.path()).as_deref()))
            .status()
            .unwrap();
        assert!(status.success());
    }
    let output = Command::new(binary())
        .args(["analyze", "--format", "json", "--trials"])
        .arg(&trials)
        .arg("--conditions")
        .arg(&conditions)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let offline: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(offline, live, "mrstudy analyze on the export equals the admin page's live analysis");
}

/// `rendered-mini` as a detection design: each condition beside the ground truth, twice.
fn write_detection_study(dir: &Path) {
    write_rendered_study(dir);
    let study = std::fs::read_to_string(dir.join("rendered-mini.toml")).unwrap();
    let study = study
        .replace("slug = \"rendered-mini\"", "slug = \"real-mini\"")
        .replace("pairs = \"all\"\nrepetitions = 1", "reference = \"ground-truth\"\nrepetitions = 2");
    std::fs::remove_file(dir.join("rendered-mini.toml")).unwrap();
    std::fs::write(dir.join("real-mini.toml"), study).unwrap();
}

#[test]
fn a_detection_study_with_realisations_shows_each_ground_truth_picture_once() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_detection_study(studies.path());
    let file = studies.path().join("real-mini.toml");
    let study = std::fs::read_to_string(&file).unwrap();
    std::fs::write(
        &file,
        study.replace("reference = \"ground-truth\"\n", "reference = \"ground-truth\"\nrealisations = 4\n"),
    )
    .unwrap();
    let started = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path());
    if !gpu_available(&started) {
        return;
    }
    let server = started.unwrap();
    if !opened(&server, "real-mini") {
        return;
    }
    let http = client();
    let joined: Value = http
        .post(format!("{}/api/studies/real-mini/participants", server.base))
        .json(&json!({"demographics": {}}))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    for _ in 0..4 {
        let next: Value = http
            .get(format!("{}/api/participants/{id}/next", server.base))
            .bearer_auth(token)
            .send()
            .unwrap()
            .json()
            .unwrap();
        let posted = http
            .post(format!("{}/api/participants/{id}/responses", server.base))
            .bearer_auth(token)
            .json(&json!({"trial": next["trial"], "chosen": "left", "rt_ms": 1500}))
            .send()
            .unwrap();
        assert_eq!(posted.status(), 201);
    }
    let export: Value = serde_json::from_str(&export(data_dir.path(), "real-mini", "json")).unwrap();
    let participant = &export["participants"][0];
    assert_eq!(participant["schedule_version"], 2);
    let (mut truths, mut rendered) = (std::collections::BTreeSet::new(), std::collections::BTreeSet::new());
    for trial in participant["schedule"].as_array().unwrap() {
        let (truth, stimulus) = if trial["left"] == "ground-truth" {
            (&trial["left_stimulus"], &trial["right_stimulus"])
        } else {
            (&trial["right_stimulus"], &trial["left_stimulus"])
        };
        truths.insert(truth.as_str().unwrap().to_string());
        rendered.insert(stimulus.as_str().unwrap().to_string());
    }
    // one scene configuration shown 4 times, each time in another realisation: 4 ground truths
    // and 4 stimuli, none shown twice
    assert_eq!((truths.len(), rendered.len()), (4, 4), "{participant}");
    assert!(truths.is_disjoint(&rendered));
}

#[test]
fn a_detection_study_shows_the_ground_truth_beside_each_condition_and_exports_it_by_name() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_detection_study(studies.path());
    let started = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path());
    if !gpu_available(&started) {
        return;
    }
    let server = started.unwrap();
    if !opened(&server, "real-mini") {
        return;
    }
    let http = client();
    let listed: Value = http.get(format!("{}/api/studies", server.base)).send().unwrap().json().unwrap();
    assert_eq!(listed[0]["slug"], "real-mini");
    assert_eq!(listed[0]["trials"], 4);
    let joined: Value = http
        .post(format!("{}/api/studies/real-mini/participants", server.base))
        .json(&json!({"demographics": {}}))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let (id, token) = (joined["participant"].as_str().unwrap(), joined["token"].as_str().unwrap());
    let mut urls = std::collections::HashMap::new();
    for _ in 0..4 {
        let next: Value = http
            .get(format!("{}/api/participants/{id}/next", server.base))
            .bearer_auth(token)
            .send()
            .unwrap()
            .json()
            .unwrap();
        let trial = next["trial"].as_i64().unwrap();
        let (left, right) = (next["left"]["url"].as_str().unwrap(), next["right"]["url"].as_str().unwrap());
        assert_ne!(left, right);
        for url in [left, right] {
            *urls.entry(url.to_string()).or_insert(0) += 1;
        }
        let posted = http
            .post(format!("{}/api/participants/{id}/responses", server.base))
            .bearer_auth(token)
            .json(&json!({"trial": trial, "chosen": "left", "rt_ms": 1500}))
            .send()
            .unwrap();
        assert_eq!(posted.status(), 201);
    }
    // the ground truth in every trial, each of the two stimuli in two
    let mut counts: Vec<i32> = urls.values().copied().collect();
    counts.sort();
    assert_eq!(counts, vec![2, 2, 4], "{urls:?}");
    let csv = export(data_dir.path(), "real-mini", "csv");
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|line| line.split(',').collect()).collect();
    assert_eq!(rows.len(), 4);
    let truth_left = rows.iter().filter(|row| row[column("left")] == "ground-truth").count();
    assert_eq!(truth_left, 2, "sides balanced:\n{csv}");
    assert!(rows.iter().all(|row| (row[column("left")] == "ground-truth") != (row[column("right")] == "ground-truth")));
    assert!(rows.iter().all(|row| row[column("chosen")] == row[column("left")]));
    // the stimulus metrics download
    let metrics = http
        .get(format!("{}/api/admin/studies/real-mini/stimuli.csv", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap();
    assert_eq!(metrics.status(), 200);
    let metrics = metrics.text().unwrap();
    assert!(metrics.starts_with("stimulus,scene,condition,metric,region,value\n"), "{metrics}");
    assert!(metrics.contains(",box,GI,flip_mean,affected,"), "{metrics}");
    // the live analysis: detection rates per condition, no preference analysis
    let analysis: Value = http
        .get(format!("{}/api/admin/studies/real-mini/analysis", server.base))
        .bearer_auth(&server.admin_token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    let rates = analysis["detection"]["conditions"].as_array().unwrap();
    assert_eq!(rates.len(), 2, "{analysis}");
    assert!(rates.iter().all(|rate| rate["trials"] == 2), "{analysis}");
    assert!(analysis.get("items").is_none(), "{analysis}");
    let page =
        http.get(format!("{}/admin/studies/real-mini", server.base)).bearer_auth(&server.admin_token).send().unwrap();
    assert_eq!(page.status(), 200);
    let page = page.text().unwrap();
    assert!(page.contains("Real or rendered?") && page.contains("Detection of each condition"), "{page}");
}
