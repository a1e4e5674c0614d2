//! Issue 16: `mrstudy stimuli --shard K/N` renders a disjoint share of a study; the shards'
//! stores, merged by copying, hold the same images, ground truths and index entries as a store
//! rendered on one machine, and `serve --stimuli-dir` serves from such a shared store without
//! rendering anything.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use super::ground_truth::write_chain_study;
use super::support::{Server, binary, client};

fn stimuli(study: &Path, data_dir: &Path, extra: &[&str]) -> Output {
    Command::new(binary())
        .args(["stimuli", "--study"])
        .arg(study)
        .arg("--data-dir")
        .arg(data_dir)
        .args(extra)
        .output()
        .unwrap()
}

/// Every file under `dir` by its path relative to `dir`, with its bytes.
fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut found = BTreeMap::new();
    let mut folders = vec![dir.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else {
                found.insert(path.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&path).unwrap());
            }
        }
    }
    found
}

#[test]
fn the_union_of_the_shards_is_the_single_machine_store_and_serve_uses_it_as_is() {
    let work = tempfile::tempdir().unwrap();
    write_chain_study(work.path());
    let study = work.path().join("chain-mini.toml");
    let single = work.path().join("single");
    let output = stimuli(&study, &single, &[]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    if !output.status.success() && stderr.contains("adapter") {
        eprintln!("skipping: no GPU adapter ({stderr})");
        return;
    }
    assert!(output.status.success(), "{stderr}");

    // two shards, one scene configuration each, into stores of their own
    let merged = work.path().join("merged/stimuli");
    for (shard, scene) in [("1/2", "box"), ("2/2", "shadow")] {
        let dir = work.path().join(format!("shard{}", &shard[..1]));
        let output = stimuli(&study, &dir, &["--shard", shard]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{stderr}");
        assert!(
            stderr.contains(&format!("shard {shard}: 1 of the study's 2 rendered scene configurations: {scene}")),
            "{stderr}"
        );
        assert!(stderr.contains("rendered 3 stimuli, 0 were already"), "{stderr}");
        // merging is copying
        for (path, bytes) in files(&dir.join("stimuli")) {
            std::fs::create_dir_all(merged.join(&path).parent().unwrap()).unwrap();
            std::fs::write(merged.join(&path), bytes).unwrap();
        }
    }
    let (single_files, merged_files) = (files(&single.join("stimuli")), files(&merged));
    assert_eq!(
        single_files.keys().filter(|p| !is_record(p)).collect::<Vec<_>>(),
        merged_files.keys().filter(|p| !is_record(p)).collect::<Vec<_>>()
    );
    for (path, bytes) in &single_files {
        if !is_record(path) {
            assert!(merged_files[path] == *bytes, "{} differs", path.display());
        }
    }
    // the records hold measured render times, so their bytes differ; there is one per stimulus
    let records = |files: &BTreeMap<PathBuf, Vec<u8>>| {
        files.keys().filter(|p| p.extension().is_some_and(|x| x == "metrics")).count()
    };
    assert_eq!(records(&single_files), 6);
    assert_eq!(records(&merged_files), 6);
    let again = stimuli(&study, &work.path().join("merged"), &[]);
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(
        stderr.contains("rendered 0 stimuli, 6 were already")
            && stderr.contains("0 ground truths and 0 stimulus records made"),
        "{stderr}"
    );

    // bad shards and a shard with --out are one sentence each
    for (args, says) in [
        (vec!["--shard", "3/2"], "K must be 1 to N"),
        (vec!["--shard", "two"], "not K/N"),
        (vec!["--shard", "1/2", "--metrics", "m.csv"], "merge the shards' stores first"),
    ] {
        let output = stimuli(&study, &work.path().join("bad"), &args);
        assert!(!output.status.success());
        assert!(
            String::from_utf8_lossy(&output.stderr).contains(says),
            "{args:?}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }

    // a server on its own data directory serves from the shared store and renders nothing
    let studies = work.path().join("studies");
    std::fs::create_dir_all(&studies).unwrap();
    std::fs::copy(&study, studies.join("chain-mini.toml")).unwrap();
    let before = files(&merged);
    let server = Server::try_start_with_args(
        &work.path().join("server-data"),
        "127.0.0.1:0",
        &studies,
        &[],
        &["--stimuli-dir", merged.to_str().unwrap()],
        Duration::from_secs(60),
    )
    .unwrap();
    let listed: serde_json::Value =
        client().get(format!("{}/api/studies", server.base)).send().unwrap().json().unwrap();
    assert_eq!(listed[0]["slug"], "chain-mini", "{listed}");
    drop(server);
    assert_eq!(files(&merged), before, "serve wrote nothing into the shared store");
    assert!(!work.path().join("server-data/stimuli").exists());
}

fn is_record(path: &Path) -> bool {
    path.extension().is_some_and(|x| x == "metrics" || x == "json")
}
