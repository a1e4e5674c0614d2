//! `mrstudy serve` on a first start (issue 47): it listens before the missing stimuli are
//! rendered, tells the participants of a study still being prepared that it opens in a few
//! minutes, and opens the study once its stimuli are in the store, without a restart.

use std::path::Path;
use std::time::Duration;

use serde_json::{Value, json};

use super::support::{Server, client, copy_demo_study, write_rendered_study};

/// A study of two conditions on a built-in scene whose reference render (photograph and
/// ground truth, path-traced) takes a few seconds: long enough that the server answers before
/// it is done, short enough for a test.
fn write_slow_study(dir: &Path) {
    write_rendered_study(dir, "slow-mini", "Rendered slowly", [160, 120], 256, "SLOW");
}

/// Index entries in the data directory's stimulus store (none before anything is rendered).
fn rendered_entries(data_dir: &Path) -> usize {
    std::fs::read_dir(data_dir.join("stimuli/rendered")).map_or(0, |entries| entries.count())
}

/// On a fresh data directory the server prints its links and answers at once: the demo study
/// (image files) is open, the rendered study is not listed, joining it answers 503 "This study
/// opens in a few minutes." with `Retry-After` and its page says the same, all while its
/// stimuli are not yet in the store; then it opens by itself and takes a participant. Fails
/// where `serve` renders before it listens (the links come after the render; the study is open
/// from the first answer).
#[test]
fn serve_listens_while_a_study_is_prepared_and_opens_it_once_its_stimuli_are_rendered() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    copy_demo_study(studies.path());
    write_slow_study(studies.path());
    let server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    let http = client();
    let base = &server.base;
    let listed: Value = http.get(format!("{base}/api/studies")).send().unwrap().json().unwrap();
    let joined = http
        .post(format!("{base}/api/studies/slow-mini/participants"))
        .json(&json!({"demographics": {}}))
        .send()
        .unwrap();
    let (join_status, retry_after) = (joined.status(), joined.headers().get("retry-after").cloned());
    let join_body: Value = joined.json().unwrap();
    let page = http.get(format!("{base}/studies/slow-mini")).send().unwrap();
    let page_status = page.status();
    let page = page.text().unwrap();
    // the answers above came while the store still lacked some of the study's stimuli
    let entries_then = rendered_entries(data_dir.path());

    match server.wait_open("slow-mini", Duration::from_secs(300)) {
        Err(warning) if warning.contains("adapter") => {
            eprintln!("skipping the rest: no GPU adapter ({warning})");
            return;
        }
        result => result.unwrap(),
    }
    let entries_now = rendered_entries(data_dir.path());
    assert!(
        entries_then < entries_now,
        "the store was complete ({entries_then} of {entries_now} entries) when the server first answered"
    );
    let slugs: Vec<&str> = listed.as_array().unwrap().iter().map(|study| study["slug"].as_str().unwrap()).collect();
    assert_eq!(slugs, ["shadows-demo"], "only the demo study is open at first");
    assert_eq!(join_status, 503, "{join_body}");
    assert_eq!(join_body, json!({"error": "This study opens in a few minutes."}));
    assert!(retry_after.is_some_and(|seconds| seconds.to_str().unwrap().parse::<u64>().is_ok()));
    assert_eq!(page_status, 503);
    assert!(page.contains("This study opens in a few minutes."), "{page}");

    // open now, without a restart, and the server says so on stdout
    let joined = http
        .post(format!("{base}/api/studies/slow-mini/participants"))
        .json(&json!({"demographics": {}}))
        .send()
        .unwrap();
    assert_eq!(joined.status(), 201);
    assert_eq!(http.get(format!("{base}/studies/slow-mini")).send().unwrap().status(), 200);
    let said = std::iter::from_fn(|| server.stdout.recv_timeout(Duration::from_secs(10)).ok())
        .find(|line| line.starts_with("study \"slow-mini\" is open ("));
    assert!(said.is_some_and(|line| line.ends_with("/studies/slow-mini")));
}

/// Ctrl-C or SIGTERM while a study's stimuli are still rendering stops the server at once (the
/// render is left for the next start), with status 0 and a line saying so. Fails where the
/// server waits for the start-up renders to finish before it exits (here a path-traced
/// reference render of about a minute).
#[test]
fn sigterm_while_stimuli_render_stops_the_server_at_once() {
    let data_dir = tempfile::tempdir().unwrap();
    let studies = tempfile::tempdir().unwrap();
    write_rendered_study(studies.path(), "long-render", "Rendered for a long time", [400, 300], 1024, "LONG");
    let mut server = Server::try_start(data_dir.path(), "127.0.0.1:0", studies.path()).unwrap();
    // the render is under way (or has failed for want of an adapter: then it stops at once too)
    std::thread::sleep(Duration::from_secs(2));
    let status = std::process::Command::new("kill").args(["-TERM", &server.child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let asked = std::time::Instant::now();
    let exited = loop {
        if let Some(status) = server.child.try_wait().unwrap() {
            break Some(status);
        }
        if asked.elapsed() > Duration::from_secs(20) {
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let status = exited.expect("mrstudy serve still running 20 s after SIGTERM");
    assert!(status.success(), "{status}");
    let said: Vec<String> = server.stderr.try_iter().collect();
    assert!(said.iter().any(|line| line.starts_with("mrstudy serve stopped")), "{said:?}");
    // nothing half-written: every index entry names a file that is there
    let rendered = data_dir.path().join("stimuli/rendered");
    let entries = std::fs::read_dir(&rendered).into_iter().flatten().flatten();
    for entry in entries.filter(|entry| !entry.file_name().to_string_lossy().ends_with(".partial")) {
        let name = std::fs::read_to_string(entry.path()).unwrap();
        assert!(data_dir.path().join("stimuli").join(name.trim()).is_file(), "{:?} names {name}", entry.path());
    }
}
