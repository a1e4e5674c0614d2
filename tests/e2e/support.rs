//! What the end-to-end tests share: the binary (`mrstudy()`, `binary()`), a fresh temporary
//! folder per test (`temp_dir`), the repository's studies and a copy of the demo study, a
//! `mrstudy serve` on a real socket (`Server`), an HTTP client, demographics that pass the demo
//! study's form, and `mrstudy export`.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde_json::{Value, json};

/// The binary under test, as a command to add arguments to.
pub fn mrstudy() -> Command {
    Command::new(binary())
}

/// A fresh, empty folder `mrstudy-e2e-<area>-<name>-<pid>` under the system's temporary folder.
pub fn temp_dir(area: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mrstudy-e2e-{area}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `mrstudy bench render <flags> --quick --json J --plot-dir dir`: its JSON document, or None
/// after saying why when no GPU adapter opens.
pub fn bench_render_quick(dir: &Path, flags: &[&str]) -> Option<Value> {
    let json = dir.join("bench.json");
    let out = mrstudy()
        .args(["bench", "render"])
        .args(flags)
        .args(["--quick", "--json"])
        .arg(&json)
        .arg("--plot-dir")
        .arg(dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() && stderr.contains("could be opened") {
        eprintln!("skipping: no GPU adapter ({stderr})");
        return None;
    }
    assert!(out.status.success(), "{stderr}");
    Some(serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap())
}

pub fn binary() -> &'static str {
    env!("CARGO_BIN_EXE_mrstudy")
}

/// The repository's `studies/` folder.
pub fn repo_studies_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("studies")
}

/// A study `slug` of two conditions (gi off and on) on the built-in scene `dir-lamp-box`,
/// rendered at `size` with `spp` samples per pixel, written into `dir` as `<slug>.toml`.
pub fn write_rendered_study(dir: &Path, slug: &str, title: &str, size: [u32; 2], spp: u32, code: &str) {
    let texts = demo_texts();
    let [width, height] = size;
    let study = format!(
        r#"slug = "{slug}"
title = "{title}"
kind = "paired-comparison"
question = "Which fits better?"

{texts}
[[factors]]
name = "gi"

[[conditions]]
name = "LQ"
levels = {{ gi = 0 }}

[[conditions]]
name = "GI"
levels = {{ gi = 1 }}

[render]
size = [{width}, {height}]
spp = {spp}
vpls = 16

[[scenes]]
name = "box"
render = "dir-lamp-box"

[design]
pairs = "all"
repetitions = 1
scenes = "same"

[completion]
code = "{code}"
"#
    );
    std::fs::write(dir.join(format!("{slug}.toml")), study).unwrap();
}

/// The demo study's `[texts]` section (welcome, consent, instructions, thanks), for the study
/// files the tests write.
pub fn demo_texts() -> String {
    let demo = std::fs::read_to_string(repo_studies_dir().join("shadows-demo.toml")).unwrap();
    demo[demo.find("[texts]").unwrap()..demo.find("[[demographics]]").unwrap()].to_string()
}

/// A server on `studies` whose study `slug` renders its stimuli at start-up, once it is open;
/// `None` (said on stderr) where no GPU adapter renders them.
pub fn start_rendered(data_dir: &Path, studies: &Path, slug: &str) -> Option<Server> {
    let server = Server::try_start(data_dir, "127.0.0.1:0", studies).unwrap();
    match server.wait_open(slug, std::time::Duration::from_secs(300)) {
        Err(warning) if warning.contains("adapter") => {
            eprintln!("skipping: no GPU adapter ({warning})");
            None
        }
        result => {
            result.unwrap();
            Some(server)
        }
    }
}

/// An export CSV without quoted cells split plainly: its header and its rows.
pub fn split_csv(csv: &str) -> (Vec<&str>, Vec<Vec<&str>>) {
    let mut lines = csv.lines();
    let header = lines.next().unwrap().split(',').collect();
    (header, lines.map(|line| line.split(',').collect()).collect())
}

/// The index of the column `name` in `header`.
pub fn column(header: &[&str], name: &str) -> usize {
    header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("{name}: {header:?}"))
}

/// A studies folder holding only the demo study (copied once per test process): the repository's
/// folder also holds the thesis survey, whose 48 stimuli `serve` would render at start-up.
pub fn studies_dir() -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("mrstudy-e2e-demo-studies-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        copy_demo_study(&dir);
        dir
    })
    .clone()
}

/// Copies the demo study (its file and its images) from the repository into `dir`.
pub fn copy_demo_study(dir: &Path) {
    let repo = repo_studies_dir();
    std::fs::create_dir_all(dir.join("shadows-demo")).unwrap();
    std::fs::copy(repo.join("shadows-demo.toml"), dir.join("shadows-demo.toml")).unwrap();
    for entry in std::fs::read_dir(repo.join("shadows-demo")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, dir.join("shadows-demo").join(path.file_name().unwrap())).unwrap();
    }
}

/// A running `mrstudy serve`.
pub struct Server {
    pub child: Child,
    pub base: String,
    pub admin_token: String,
    pub stderr: mpsc::Receiver<String>,
    /// stdout lines after the admin link (e.g. the lab's lines, printed once it has started).
    pub stdout: mpsc::Receiver<String>,
}

impl Server {
    /// Starts `mrstudy serve` and waits for its links (at most 60 s).
    pub fn start(data_dir: &Path, addr: &str) -> Server {
        Server::try_start(data_dir, addr, &studies_dir()).unwrap_or_else(|error| panic!("{error}"))
    }

    pub fn try_start(data_dir: &Path, addr: &str, studies: &Path) -> Result<Server, String> {
        Server::try_start_with_env(data_dir, addr, studies, &[], Duration::from_secs(60))
    }

    /// [`Server::try_start`] with extra environment variables, waiting at most `wait`.
    pub fn try_start_with_env(
        data_dir: &Path,
        addr: &str,
        studies: &Path,
        env: &[(&str, &str)],
        wait: Duration,
    ) -> Result<Server, String> {
        Server::try_start_with_args(data_dir, addr, studies, env, &[], wait)
    }

    /// [`Server::try_start_with_env`] with extra arguments to `serve`.
    pub fn try_start_with_args(
        data_dir: &Path,
        addr: &str,
        studies: &Path,
        env: &[(&str, &str)],
        args: &[&str],
        wait: Duration,
    ) -> Result<Server, String> {
        let database = match args.contains(&"--database") {
            true => None,
            false => test_database(data_dir),
        };
        let mut child = Command::new(binary())
            .envs(env.iter().copied())
            // the tests' many participants all come from 127.0.0.1: no limits per client
            .args(["serve", "--join-limit", "0", "--response-limit", "0", "--addr", addr, "--data-dir"])
            .arg(data_dir)
            .arg("--studies")
            .arg(studies)
            .args(args)
            .args(database_args(database.as_deref()))
            .env_remove("MRSTUDY_ADMIN_TOKEN")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|error| format!("cannot start {}: {error}", binary()))?;
        let (stdout_lines, stdout_receiver) = mpsc::channel();
        let stdout = child.stdout.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = stdout_lines.send(line);
            }
        });
        let (stderr_lines, stderr_receiver) = mpsc::channel();
        let stderr = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                let _ = stderr_lines.send(line);
            }
        });
        let deadline = Instant::now() + wait;
        let mut base = None;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match stdout_receiver.recv_timeout(left) {
                Ok(line) => {
                    if let Some(rest) = line.strip_prefix("mrstudy serving on ") {
                        base = rest.split_whitespace().next().map(str::to_string);
                    }
                    if let Some(link) = line.strip_prefix("admin link: ") {
                        let admin_token = link.split("token=").nth(1).unwrap_or_default().to_string();
                        return Ok(Server {
                            child,
                            base: base.expect("base before admin link"),
                            admin_token,
                            stderr: stderr_receiver,
                            stdout: stdout_receiver,
                        });
                    }
                }
                Err(_) => {
                    let _ = child.kill();
                    let _ = child.wait();
                    let errors: Vec<String> = stderr_receiver.try_iter().collect();
                    return Err(format!("mrstudy serve did not print its links: {}", errors.join(" | ")));
                }
            }
        }
    }

    /// Waits until `slug` is among the open studies (its stimuli render in the background after
    /// the server listens), at most `wait`; `Err` with the server's warning lines about it when
    /// it is not served (e.g. no GPU adapter), or when the time is up.
    pub fn wait_open(&self, slug: &str, wait: Duration) -> Result<(), String> {
        let deadline = Instant::now() + wait;
        let http = client();
        loop {
            let listed: Value = http
                .get(format!("{}/api/studies", self.base))
                .send()
                .and_then(|response| response.json())
                .map_err(|error| error.to_string())?;
            if listed.as_array().is_some_and(|studies| studies.iter().any(|study| study["slug"] == slug)) {
                return Ok(());
            }
            let warnings: Vec<String> =
                self.stderr.try_iter().filter(|line| line.starts_with("warning") && line.contains(slug)).collect();
            if !warnings.is_empty() {
                return Err(warnings.join(" | "));
            }
            if Instant::now() >= deadline {
                return Err(format!("study \"{slug}\" did not open within {wait:?}"));
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    pub fn kill(&mut self) {
        let _ = self.child.kill(); // SIGKILL on Unix
        let _ = self.child.wait();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.kill();
    }
}

pub fn client() -> reqwest::blocking::Client {
    reqwest::blocking::Client::builder().timeout(Duration::from_secs(20)).build().unwrap()
}

pub fn demographics() -> Value {
    json!({"gender": "male", "age": 44, "cg_experience": "some (hobby, courses)", "vision": "corrected to normal (glasses, lenses)"})
}

pub fn export(data_dir: &Path, study: &str, format: &str) -> String {
    export_from(data_dir, test_database(data_dir).as_deref(), study, format)
}

/// `mrstudy export` of the data in `database` (a postgres:// URL; `None`: the data directory's
/// sqlite file).
pub fn export_from(data_dir: &Path, database: Option<&str>, study: &str, format: &str) -> String {
    let output = Command::new(binary())
        .args(["export", "--study", study, "--format", format, "--data-dir"])
        .arg(data_dir)
        .args(database_args(database))
        .output()
        .unwrap();
    assert!(output.status.success(), "export failed: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).unwrap()
}

/// The PostgreSQL database of a test's data directory when the environment says
/// `MRSTUDY_TEST_DATABASE=postgres` (scripts/test.sh runs the serving tests a second time so):
/// made on first use on the server of `MRSTUDY_TEST_POSTGRES` and remembered in the data
/// directory, so that a restarted server and `mrstudy export` find the same one. `None`: sqlite.
pub fn test_database(data_dir: &Path) -> Option<String> {
    if std::env::var("MRSTUDY_TEST_DATABASE").as_deref() != Ok("postgres") {
        return None;
    }
    let remembered = data_dir.join("test-database-url");
    if let Ok(url) = std::fs::read_to_string(&remembered) {
        return Some(url);
    }
    let url = new_postgres().expect("MRSTUDY_TEST_DATABASE=postgres needs MRSTUDY_TEST_POSTGRES");
    std::fs::create_dir_all(data_dir).unwrap();
    std::fs::write(&remembered, &url).unwrap();
    Some(url)
}

/// `--database URL` for `mrstudy serve` or `mrstudy export` (none for the data directory's sqlite).
pub fn database_args(database: Option<&str>) -> Vec<String> {
    database.iter().flat_map(|url| ["--database".to_string(), url.to_string()]).collect()
}

/// A new database on the PostgreSQL server of `MRSTUDY_TEST_POSTGRES` (a URL of the server's
/// `postgres` database), or `None` when that is not set (scripts/test.sh sets it).
pub fn new_postgres() -> Option<String> {
    let server = std::env::var("MRSTUDY_TEST_POSTGRES").ok()?;
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    Some(runtime.block_on(mrstudy_server::storage::new_postgres_database(&server, "mrstudy_test")).unwrap())
}
