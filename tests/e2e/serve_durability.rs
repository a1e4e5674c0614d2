//! Durability: `mrstudy serve` is killed with SIGKILL again and again while simulated
//! participants answer concurrently, and restarted each time; afterwards every response that was
//! acknowledged (201, or 200 for a repeat) is in the database exactly once, with its answer.
//!
//! A SIGKILL loses what the process had not handed to the kernel; what survives it is what was
//! committed. (Power loss also needs the fsync that `synchronous = FULL` does on every commit;
//! no test here pulls the plug.)
//!
//! The same on PostgreSQL with two `serve` processes on one database: every participant's
//! requests alternate between them while one of them is killed and restarted again and again.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use super::support::{Server, demographics, export_from, new_postgres, test_database};

/// Total time of the kill-and-restart phase.
const KILL_PHASE: Duration = Duration::from_secs(20);
const PARTICIPANTS: usize = 12;

#[test]
fn acknowledged_responses_survive_repeated_sigkill() {
    let data_dir = tempfile::tempdir().unwrap();
    let database = test_database(data_dir.path());
    survive_kills(data_dir.path(), database.as_deref(), 1);
}

#[test]
fn two_servers_on_one_postgres_lose_nothing_while_one_is_killed_again_and_again() {
    let Some(database) = new_postgres() else {
        eprintln!("skipped: MRSTUDY_TEST_POSTGRES is not set (scripts/test.sh starts a PostgreSQL and sets it)");
        return;
    };
    let data_dir = tempfile::tempdir().unwrap();
    survive_kills(data_dir.path(), Some(&database), 2);
}

/// `servers` processes of `mrstudy serve` on one database (each with a data directory of its
/// own under `data_dir`); participants' requests go to each in turn while the first is killed
/// and restarted; then every acknowledged response must be stored exactly once.
fn survive_kills(data_dir: &std::path::Path, database: Option<&str>, servers: usize) {
    let start = |index: usize, addr: &str| {
        let args = super::support::database_args(database);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        Server::try_start_with_args(
            &data_dir.join(format!("server-{index}")),
            addr,
            &super::support::studies_dir(),
            &[],
            &args,
            Duration::from_secs(60),
        )
        .unwrap_or_else(|error| panic!("{error}"))
    };
    let addrs: Vec<String> = (0..servers)
        .map(|_| {
            format!("127.0.0.1:{}", std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port())
        })
        .collect();
    let mut running: Vec<Server> = addrs.iter().enumerate().map(|(index, addr)| start(index, addr)).collect();
    let bases: Arc<Vec<String>> = Arc::new(addrs.iter().map(|addr| format!("http://{addr}")).collect());

    let acknowledged: Arc<Mutex<Vec<(String, i64, String)>>> = Arc::default();
    let stop = Arc::new(AtomicBool::new(false));
    let mut clients = Vec::new();
    for index in 0..PARTICIPANTS {
        let acknowledged = acknowledged.clone();
        let stop = stop.clone();
        let bases = bases.clone();
        clients.push(std::thread::spawn(move || participant_loop(index, &bases, &stop, &acknowledged)));
    }

    let started = Instant::now();
    let mut kills = 0;
    let mut pseudo_random = 0x2545_F491_4F6C_DD1Du64;
    while started.elapsed() < KILL_PHASE {
        pseudo_random ^= pseudo_random << 13;
        pseudo_random ^= pseudo_random >> 7;
        pseudo_random ^= pseudo_random << 17;
        std::thread::sleep(Duration::from_millis(300 + pseudo_random % 900));
        running[0].kill();
        kills += 1;
        running[0] = start(0, &addrs[0]);
    }
    stop.store(true, Ordering::SeqCst);
    let mut clients_acknowledged = 0;
    for client in clients {
        clients_acknowledged += client.join().unwrap();
    }
    for server in &mut running {
        server.kill();
    }

    let acknowledged = acknowledged.lock().unwrap().clone();
    assert_eq!(clients_acknowledged, acknowledged.len());
    assert!(kills >= 10, "only {kills} kills");
    assert!(acknowledged.len() >= 200, "only {} acknowledged responses in {kills} kills", acknowledged.len());

    // Read back what the database holds, through `mrstudy export`.
    let export = |format: &str| export_from(&data_dir.join("server-0"), database, "shadows-demo", format);
    let stored: Value = serde_json::from_str(&export("json")).unwrap();
    let mut answers: HashMap<(String, i64), Vec<String>> = HashMap::new();
    let mut catch_trials: HashSet<(String, i64)> = HashSet::new();
    for participant in stored["participants"].as_array().unwrap() {
        let id = participant["participant"].as_str().unwrap().to_string();
        let mut answered = 0;
        for trial in participant["schedule"].as_array().unwrap() {
            if trial["catch_expected"].is_string() {
                catch_trials.insert((id.clone(), trial["trial"].as_i64().unwrap()));
            }
            if let Some(chosen) = trial["response"]["chosen"].as_str() {
                answers.entry((id.clone(), trial["trial"].as_i64().unwrap())).or_default().push(chosen.to_string());
                answered += 1;
            }
        }
        assert_eq!(participant["answered"], answered, "the progress counter matches the responses");
    }
    let csv = export("csv");
    let mut rows: HashMap<(String, i64), usize> = HashMap::new();
    for line in csv.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        *rows.entry((fields[1].to_string(), fields[2].parse().unwrap())).or_default() += 1;
    }
    let mut seen = HashSet::new();
    for (participant, trial, chosen) in &acknowledged {
        let key = (participant.clone(), *trial);
        assert!(seen.insert(key.clone()), "acknowledged twice by the test itself: {key:?}");
        let stored =
            answers.get(&key).unwrap_or_else(|| panic!("acknowledged response {key:?} is missing after {kills} kills"));
        assert_eq!(stored, &vec![chosen.clone()], "{key:?}");
        // Judgments are rows of the trials CSV; catch trials are not (they flag the participant).
        let expected_rows = if catch_trials.contains(&key) { None } else { Some(&1) };
        assert_eq!(rows.get(&key), expected_rows, "{key:?} exactly once in the CSV");
    }
    eprintln!(
        "durability ({servers} server(s), {}): {kills} SIGKILLs, {} acknowledged responses, {} stored, all acknowledged ones present exactly once",
        if database.is_some() { "PostgreSQL" } else { "sqlite" },
        acknowledged.len(),
        answers.len()
    );
}

/// One simulated participant after another: join, answer every trial, retrying through the
/// restarts; each request goes to the next of `bases` in turn. Returns how many responses were
/// acknowledged.
fn participant_loop(
    index: usize,
    bases: &[String],
    stop: &AtomicBool,
    acknowledged: &Mutex<Vec<(String, i64, String)>>,
) -> usize {
    let http = reqwest::blocking::Client::builder().timeout(Duration::from_secs(5)).build().unwrap();
    let mut count = 0;
    let mut choice = index as u64 + 1;
    let mut turn = index;
    let mut next_base = || {
        turn += 1;
        bases[turn % bases.len()].clone()
    };
    while !stop.load(Ordering::SeqCst) {
        let base = next_base();
        let joined = http
            .post(format!("{base}/api/studies/shadows-demo/participants"))
            .json(&json!({"demographics": demographics()}))
            .send();
        let Ok(joined) = joined else {
            std::thread::sleep(Duration::from_millis(50));
            continue;
        };
        if joined.status() != 201 {
            std::thread::sleep(Duration::from_millis(50));
            continue;
        }
        let Ok(joined) = joined.json::<Value>() else { continue };
        let id = joined["participant"].as_str().unwrap().to_string();
        let token = joined["token"].as_str().unwrap().to_string();
        let trials = joined["trials"].as_i64().unwrap();
        let mut trial = 1;
        while trial <= trials && !stop.load(Ordering::SeqCst) {
            choice = choice.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let chosen = if choice >> 63 == 1 { "left" } else { "right" };
            // Retry this answer until the server acknowledges it.
            loop {
                if stop.load(Ordering::SeqCst) {
                    return count;
                }
                // A response is accepted only for a trial the server has served: ask for it
                // first (again after a restart; serving is idempotent).
                let base = next_base();
                if http.get(format!("{base}/api/participants/{id}/next")).bearer_auth(&token).send().is_err() {
                    std::thread::sleep(Duration::from_millis(20));
                    continue;
                }
                let base = next_base();
                let sent = http
                    .post(format!("{base}/api/participants/{id}/responses"))
                    .bearer_auth(&token)
                    .json(&json!({"trial": trial, "chosen": chosen, "rt_ms": 500}))
                    .send();
                match sent {
                    Ok(response) if response.status() == 201 || response.status() == 200 => {
                        acknowledged.lock().unwrap().push((id.clone(), trial, chosen.to_string()));
                        count += 1;
                        break;
                    }
                    Ok(response) => panic!("unexpected {} for trial {trial}: {:?}", response.status(), response.text()),
                    Err(_) => std::thread::sleep(Duration::from_millis(20)),
                }
            }
            trial += 1;
        }
    }
    count
}
