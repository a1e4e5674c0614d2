//! `mrstudy serve`: from a data directory and a studies directory to a listening server.
//!
//! On start: create the data directory, open and migrate `mrstudy.db`, settle the admin token
//! (`MRSTUDY_ADMIN_TOKEN`, else `<data-dir>/admin-token`, generated once), load and check every
//! study file (an invalid one stops the start with its file, key and expectation), copy each
//! study's image stimuli into `<data-dir>/stimuli/`, record the studies whose stimuli are all in
//! the store in the database ([`load`]), bind, and print one participant link per study and the
//! admin link. Nothing is rendered before listening: the stimuli of studies that name scenes
//! for the renderer and are not in the store yet render in the background afterwards, one study
//! after another ([`prepare_pending`], [`crate::stimuli`]; progress through
//! [`ServeConfig::progress`]); until a study's stimuli are complete its participants are told
//! it opens in a few minutes and the admin page shows its progress ([`crate::preparing`]), and
//! then it is served without a restart (one `study "…" is open` line). A study whose stimuli
//! cannot be rendered here (no GPU adapter, a scene that fails) is not served, with one warning
//! line naming it and why. Task studies start in the background before the stimuli render
//! ([`start_lab`]): one line per study with its frame rate (a warning when too slow for
//! interactive rates) and its `lab link:`, or one warning line naming why they are not served
//! (no GPU adapter).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::auth::{WeakToken, admin_token_strength};
use crate::prepared::{PrepareError, PreparedStudy};
use crate::storage::{Database, OpenError, Storage};
use crate::study::TaskStudy;
use crate::study::{LoadedStudy, Study, StudyError, load_studies};
use crate::{AppState, app};

/// Told how rendering a study's stimuli goes: the study's slug and the step.
pub type RenderProgress = Arc<dyn Fn(&str, &crate::stimuli::Progress) + Send + Sync>;

/// Where and what to serve: `mrstudy serve`'s flags (the binary holds their clap definitions).
#[derive(Clone)]
pub struct ServeConfig {
    /// Address to listen on (port 0: any free port).
    pub addr: String,
    /// Data directory: mrstudy.db, stimuli/, admin-token.
    pub data_dir: PathBuf,
    /// The database: a PostgreSQL URL (postgres://user:password@host:port/database), which
    /// several servers may share, or a sqlite file (default: mrstudy.db in the data directory).
    pub database: Option<String>,
    /// Directory of study files (*.toml).
    pub studies_dir: PathBuf,
    /// A stimulus store shared by several servers (default: `<data-dir>/stimuli`), rendered
    /// beforehand by `mrstudy stimuli` (with --shard on a cluster; docs/cluster.md).
    pub stimuli_dir: Option<PathBuf>,
    /// Called while missing stimuli are rendered at start-up (None: quietly).
    pub progress: Option<RenderProgress>,
    /// What one client address may do ([`crate::limits`]).
    pub limits: crate::limits::Limits,
    /// How long the server waits for a client, and for how many at once.
    pub connections: Connections,
    /// The lab's origins and sessions per address.
    pub lab: crate::lab::LabConfig,
    /// How the log on stderr (one line per request, warnings and errors) is written: text or
    /// json (one object per line); `RUST_LOG` filters it (unset: info for mrstudy, warn for the
    /// rest).
    pub log_format: crate::logs::LogFormat,
}

/// How long the server waits for a client and how many connections it keeps at once, so that
/// idle, slow-header (slowloris), slow-body and never-reading clients cannot hold its
/// connections, and one address cannot take them all ([`crate::connections`]). Also
/// `mrstudy serve`'s flags (times in whole seconds; the binary holds their clap definitions).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Connections {
    /// Seconds a connection may take to send a request's headers, from its start or the end of
    /// its last response (also how long an idle keep-alive connection is kept).
    pub header_timeout: std::time::Duration,
    /// Seconds a request may take to send its whole body after the headers (else 400, and the
    /// connection closes).
    pub body_timeout: std::time::Duration,
    /// Seconds a whole request (headers and body together) may take, from the connection's
    /// start or the end of its last response; a slower one is cut off and its connection closed.
    pub request_timeout: std::time::Duration,
    /// Seconds a response may wait for the client to read any of it before the connection is
    /// closed.
    pub write_timeout: std::time::Duration,
    /// Connections served at once; when full, a new one takes the place of the oldest
    /// connection of the address holding the most (if it holds more than the newcomer's).
    pub max_connections: usize,
    /// Connections one client address (an IPv6 /64) may hold at once; more are refused with 503
    /// (0: no cap; behind a reverse proxy every connection comes from the proxy, so there is none).
    pub max_connections_per_address: usize,
    /// Seconds a lab WebSocket session may go without a message before it is closed.
    pub lab_idle_timeout: std::time::Duration,
}

impl Default for Connections {
    fn default() -> Connections {
        Connections {
            header_timeout: std::time::Duration::from_secs(20),
            body_timeout: std::time::Duration::from_secs(30),
            request_timeout: std::time::Duration::from_secs(30),
            write_timeout: std::time::Duration::from_secs(20),
            max_connections: 4096,
            max_connections_per_address: 512,
            lab_idle_timeout: crate::lab::session::IDLE_TIMEOUT,
        }
    }
}

/// Why the server could not start; each displays as one sentence.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServeError {
    #[error("cannot create the data directory {path}: {source}")]
    DataDir { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Open(#[from] OpenError),
    /// Its sentence names the file and what is wrong, so it is no `source` (one sentence, printed once).
    #[error("invalid study file {0}")]
    Study(StudyError),
    #[error(transparent)]
    Prepare(PrepareError),
    #[error(
        "MRSTUDY_ADMIN_TOKEN is too weak: {0}; leave it unset and mrstudy makes a random one, or use e.g. `openssl rand -hex 32`"
    )]
    WeakAdminToken(WeakToken),
    #[error("cannot read or write the admin token file {path}: {source}")]
    AdminToken { path: PathBuf, source: std::io::Error },
    #[error("cannot record study \"{slug}\" in the database: {source}")]
    RecordStudy { slug: String, source: sqlx::Error },
    #[error("cannot listen on {addr}: {source}")]
    Bind { addr: String, source: std::io::Error },
    #[error("the server stopped with an error: {0}")]
    Server(std::io::Error),
    #[error("cannot start the async runtime: {0}")]
    Runtime(std::io::Error),
    #[error(transparent)]
    Log(crate::logs::LogFilterError),
}

impl From<StudyError> for ServeError {
    fn from(error: StudyError) -> ServeError {
        ServeError::Study(error)
    }
}

/// The admin token: `MRSTUDY_ADMIN_TOKEN` if set, else the one kept in `<data-dir>/admin-token`,
/// generated (256 random bits, hex) and written there (mode 0600) the first time.
pub fn admin_token(data_dir: &Path) -> Result<String, ServeError> {
    if let Ok(token) = std::env::var("MRSTUDY_ADMIN_TOKEN") {
        admin_token_strength(&token).map_err(ServeError::WeakAdminToken)?;
        return Ok(token);
    }
    let path = data_dir.join("admin-token");
    let io_error = |source| ServeError::AdminToken { path: path.clone(), source };
    match std::fs::read_to_string(&path) {
        Ok(token) if !token.trim().is_empty() => return Ok(token.trim().to_string()),
        Ok(_) => {}
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
        Err(error) => return Err(io_error(error)),
    }
    let token = crate::random_hex(32);
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(0o600);
    }
    use std::io::Write;
    let mut file = options.open(&path).map_err(io_error)?;
    file.write_all(format!("{token}\n").as_bytes()).map_err(io_error)?;
    file.sync_all().map_err(io_error)?;
    Ok(token)
}

/// A data directory opened and studies loaded: everything but the socket.
pub struct Prepared {
    pub state: AppState,
    pub admin_token: String,
    /// One line per study that is not served, to print as a warning.
    pub skipped: Vec<String>,
    /// One line per study served whose stimuli are smaller than its `min_viewport` would show
    /// them ([`small_stimuli`]), to print as a warning.
    pub small: Vec<String>,
    /// One line per scene configuration of a study served now whose stored stimulus records
    /// carry a warning (the statistics colour mapping's ratios outside [0.5, 2]:
    /// [`crate::stimuli::warnings::stored_warnings`]), to print as a warning.
    pub stimulus_warnings: Vec<String>,
    /// The studies served now, in load order.
    pub slugs: Vec<String>,
    /// Studies whose stimuli are still to render, to serve with [`prepare_pending`] (`state`
    /// knows them as being prepared: their participants are told they open in a few minutes).
    pub pending: Vec<PendingStudy>,
    /// Task studies, to start with [`start_lab`] once listening.
    pub tasks: Vec<TaskStudy>,
}

/// A study whose stimuli are not all in the store yet: its plan, and how many stimuli the
/// scene configurations still to render have.
pub struct PendingStudy {
    pub study: Study,
    pub plan: crate::stimuli::StimulusPlan,
    pub stimuli: usize,
}

/// Opens the data directory and loads the studies (see the module doc), rendering missing
/// stimuli quietly.
pub async fn prepare(data_dir: &Path, studies_dir: &Path) -> Result<Prepared, ServeError> {
    prepare_with_progress(&Database::in_data_dir(data_dir), data_dir, studies_dir, None, None).await
}

/// [`prepare`] with the data in `database` instead of `<data-dir>/mrstudy.db`.
pub async fn prepare_on(database: &Database, data_dir: &Path, studies_dir: &Path) -> Result<Prepared, ServeError> {
    prepare_with_progress(database, data_dir, studies_dir, None, None).await
}

/// [`prepare`], telling `progress` how rendering missing stimuli goes: [`load`], then
/// [`prepare_pending`] before returning (`serve` itself listens in between).
pub async fn prepare_with_progress(
    database: &Database,
    data_dir: &Path,
    studies_dir: &Path,
    stimuli_dir: Option<&Path>,
    progress: Option<&RenderProgress>,
) -> Result<Prepared, ServeError> {
    let mut prepared = load(database, data_dir, studies_dir, stimuli_dir).await?;
    let pending = std::mem::take(&mut prepared.pending);
    let mut skipped = Vec::new();
    prepare_pending(&prepared.state, pending, progress.cloned(), |outcome| {
        if let Err(line) = outcome {
            skipped.push(line);
        }
    })
    .await;
    prepared.skipped.extend(skipped);
    prepared.slugs = prepared.state.studies().map(|study| study.study.slug.clone()).collect();
    Ok(prepared)
}

/// Opens the data directory and loads the studies without rendering anything: a study whose
/// stimuli are all in the store (or that shows image files) is served at once, one with
/// stimuli still to render is left in [`Prepared::pending`] for [`prepare_pending`].
pub async fn load(
    database: &Database,
    data_dir: &Path,
    studies_dir: &Path,
    stimuli_dir: Option<&Path>,
) -> Result<Prepared, ServeError> {
    std::fs::create_dir_all(data_dir).map_err(|source| ServeError::DataDir { path: data_dir.to_path_buf(), source })?;
    let storage = Storage::open(database).await?;
    let admin_token = admin_token(data_dir)?;
    let studies = load_studies(studies_dir)?;
    let stimuli_dir = stimuli_dir.map(Path::to_path_buf).unwrap_or_else(|| data_dir.join("stimuli"));
    let mut prepared = Vec::new();
    let mut pending = Vec::new();
    let mut skipped = Vec::new();
    let mut tasks = Vec::new();
    let mut small = Vec::new();
    let mut stimulus_warnings = Vec::new();
    let mut on_demand = Vec::new();
    for study in studies {
        let study = match study {
            LoadedStudy::Survey(study) => study,
            LoadedStudy::Task(task) => {
                tasks.push(task);
                continue;
            }
        };
        small.extend(small_stimuli(&study));
        let plan = match crate::stimuli::StimulusPlan::of(&study) {
            Ok(plan) => plan,
            Err(error) => {
                skipped.push(format!("{error}; not serving it"));
                continue;
            }
        };
        if study.needs_renderer() {
            // an on-demand threshold study opens once what its first trials need is rendered
            let startup = crate::render_queue::startup_plan(&study, &plan);
            let incomplete = startup.incomplete(&stimuli_dir);
            if !incomplete.is_empty() {
                let stimuli = startup.stimuli_in(&incomplete);
                pending.push(PendingStudy { study, plan, stimuli });
                continue;
            }
        }
        match PreparedStudy::prepare(study, &plan, &stimuli_dir) {
            Ok(study) => {
                // a study still to render warns as it renders, not here
                stimulus_warnings.extend(crate::stimuli::warnings::stored_warnings(&study.study, &plan, &stimuli_dir));
                let study = Arc::new(study);
                if crate::render_queue::on_demand(&study.study) {
                    on_demand.push((study.clone(), plan));
                }
                prepared.push(study);
            }
            Err(
                error @ (PrepareError::NeedsRendering { .. }
                | PrepareError::TaskStudy { .. }
                | PrepareError::Stimuli(_)
                | PrepareError::Threshold { .. }),
            ) => {
                skipped.push(format!("{error}; not serving it"));
            }
            Err(error) => return Err(ServeError::Prepare(error)),
        }
    }
    for study in &prepared {
        storage
            .upsert_study(&study.record())
            .await
            .map_err(|source| ServeError::RecordStudy { slug: study.study.slug.clone(), source })?;
    }
    let slugs = prepared.iter().map(|study| study.study.slug.clone()).collect();
    // the fewest stimuli first: more studies open sooner
    pending.sort_by_key(|study: &PendingStudy| study.stimuli);
    let state = AppState::new(storage, prepared, &admin_token, stimuli_dir)
        .with_pending(pending.iter().map(|study| (study.study.slug.clone(), study.study.title.clone(), study.stimuli)));
    for (study, plan) in on_demand {
        state.render_queue().register(study, plan);
    }
    Ok(Prepared { state, admin_token, skipped, small, stimulus_warnings, slugs, pending, tasks })
}

/// A warning when a study's stimuli are smaller than the smallest window it admits
/// (`min_viewport`) has room for: with `display = "native"` or `"css"` the page never enlarges
/// them, so on every admitted screen part of the space stays empty. The room is estimated from
/// the trial page's layout (two images side by side under the question, with the hints below:
/// about 60 CSS pixels of width and 190 of height go to margins, borders and text). None for
/// `display = "fit"`, without `min_viewport`, or when the stimulus size cannot be read.
pub fn small_stimuli(study: &Study) -> Option<String> {
    use crate::study::{Display, StimulusSource};
    if study.participation.display == Display::Fit {
        return None;
    }
    let [min_width, min_height] = study.participation.min_viewport?;
    let mut largest: Option<[u32; 2]> = None;
    for scene in &study.scenes {
        let sizes: Vec<[u32; 2]> = match &scene.source {
            StimulusSource::Images(paths) => paths
                .iter()
                .filter_map(|path| image::image_dimensions(path).ok())
                .map(|(width, height)| [width, height])
                .collect(),
            StimulusSource::Render(_) => study.render.as_ref().map(|render| render.size).into_iter().collect(),
        };
        for [width, height] in sizes {
            let [w, h] = largest.get_or_insert([width, height]);
            *w = (*w).max(width);
            *h = (*h).max(height);
        }
    }
    let [width, height] = largest?;
    let room = [(f64::from(min_width) - 60.0) / 2.0, f64::from(min_height) - 190.0];
    let scale = (room[0] / f64::from(width)).min(room[1] / f64::from(height));
    if scale <= 1.0 {
        return None;
    }
    let shown = |scale: f64| format!("{}×{}", (f64::from(width) * scale) as u32, (f64::from(height) * scale) as u32);
    let display = match study.participation.display {
        Display::Native => {
            "\"native\" never enlarges them (at device pixel ratio 2 they take half that size in CSS pixels)"
        }
        _ => "\"css\" never enlarges them beyond one image pixel per CSS pixel",
    };
    Some(format!(
        "study \"{}\": its stimuli ({width}×{height} pixels) are smaller than its min_viewport ({min_width} × {min_height}) has room for (about {} CSS pixels each); display = {display}: render larger stimuli, lower min_viewport or set display = \"fit\"",
        study.slug,
        shown(scale)
    ))
}

/// Renders the stimuli of the pending studies one study after another (each in a blocking task,
/// its steps told to `state`'s preparation and to `progress`), and serves each as soon as all its
/// stimuli are in the store: recorded in the database, then installed in `state`. `outcome` is
/// told each study's end: `Ok(slug)` when it is served, `Err(line)` (a warning) when it is not
/// (no GPU adapter, a scene that fails); such a study stays listed as failed, with the reason.
pub async fn prepare_pending(
    state: &AppState,
    pending: Vec<PendingStudy>,
    progress: Option<RenderProgress>,
    mut outcome: impl FnMut(Result<&str, String>),
) {
    let store = state.stimuli_dir().to_path_buf();
    for PendingStudy { study, plan, .. } in pending {
        let slug = study.slug.clone();
        let (state_for, progress, store) = (state.clone(), progress.clone(), store.clone());
        let rendered = tokio::task::spawn_blocking(move || {
            let slug = study.slug.clone();
            let report = |step: crate::stimuli::Progress| {
                state_for.preparation().record(&slug, &step);
                if let Some(progress) = &progress {
                    progress(&slug, &step);
                }
            };
            let startup = crate::render_queue::startup_plan(&study, &plan);
            crate::stimuli::render_missing(&study, &startup, &store, &report).map_err(|error| error.to_string())?;
            let prepared = PreparedStudy::prepare(study, &plan, &store).map_err(|error| error.to_string())?;
            Ok((Arc::new(prepared), plan))
        })
        .await;
        let served = match rendered {
            Ok(Ok((prepared, plan))) => match state.storage().upsert_study(&prepared.record()).await {
                Ok(()) => {
                    state.render_queue().register(prepared.clone(), plan);
                    state.install(prepared);
                    Ok(())
                }
                Err(source) => Err(ServeError::RecordStudy { slug: slug.clone(), source }.to_string()),
            },
            Ok(Err(reason)) => Err(reason),
            Err(error) => Err(format!("study \"{slug}\": rendering its stimuli stopped ({error})")),
        };
        match served {
            Ok(()) => outcome(Ok(&slug)),
            Err(reason) => {
                state.preparation().fail(&slug, reason.clone());
                outcome(Err(format!("{reason}; not serving it")));
            }
        }
    }
}

/// Starts the lab for the task studies (the renderer thread, scenes, photographs, frame-time
/// measurement) and installs it in `state`. Returns the lines to print: (information, warnings).
pub async fn start_lab(state: &AppState, tasks: Vec<TaskStudy>, data_dir: &Path) -> (Vec<String>, Vec<String>) {
    let start = crate::lab::start(tasks, data_dir, state.storage()).await;
    if let Some(lab) = start.lab {
        state.set_lab(lab);
    }
    state.preparation().set_lab_starting(Vec::new());
    (start.info, start.warnings)
}

/// Runs `serve` to the end (Ctrl-C or SIGTERM): prints the warnings to stderr and the links to
/// stdout once listening.
pub fn run(config: ServeConfig) -> Result<(), ServeError> {
    crate::logs::init(config.log_format).map_err(ServeError::Log)?;
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build().map_err(ServeError::Runtime)?;
    let served: Result<(), ServeError> = runtime.block_on(async {
        let database = Database::choose(config.database.as_deref(), &config.data_dir).map_err(OpenError::Choose)?;
        let started = std::time::Instant::now();
        // nothing is rendered before listening: missing stimuli render in the background below
        let mut prepared =
            load(&database, &config.data_dir, &config.studies_dir, config.stimuli_dir.as_deref()).await?;
        // before the state is shared (the lab's start-up task holds a copy)
        prepared.state = prepared.state.with_limits(config.limits);
        for line in prepared.skipped.iter().chain(&prepared.small).chain(&prepared.stimulus_warnings) {
            eprintln!("warning: {line}");
        }
        if prepared.slugs.is_empty() && prepared.pending.is_empty() && prepared.tasks.is_empty() {
            eprintln!("warning: no study to serve in {}", config.studies_dir.display());
        }
        let listener = tokio::net::TcpListener::bind(&config.addr)
            .await
            .map_err(|source| ServeError::Bind { addr: config.addr.clone(), source })?;
        let local: SocketAddr =
            listener.local_addr().map_err(|source| ServeError::Bind { addr: config.addr.clone(), source })?;
        let base = format!("http://{local}");
        match &database {
            Database::Sqlite(_) => println!("mrstudy serving on {base} (data in {})", config.data_dir.display()),
            Database::Postgres(_) => println!(
                "mrstudy serving on {base} (data in {}, responses in {})",
                config.data_dir.display(),
                database.describe()
            ),
        }
        for slug in &prepared.slugs {
            println!("participant link: {base}/studies/{slug}");
        }
        for pending in &prepared.pending {
            let slug = &pending.study.slug;
            println!(
                "participant link: {base}/studies/{slug} (opens once its {} stimuli are rendered)",
                pending.stimuli
            );
        }
        println!("admin link: {base}/admin/login?token={}", prepared.admin_token);
        use std::io::Write;
        let _ = std::io::stdout().flush();
        // in the background the lab starts first (its renderer, scene and frame times: seconds),
        // then the missing stimuli render: one after the other, as both render on the GPU
        // (lavapipe's is the CPU) and the lab measures its frame times as it starts
        let (lab_started, lab_done) = tokio::sync::oneshot::channel::<()>();
        let lab_started = (!prepared.tasks.is_empty()).then_some(lab_started);
        {
            let pending = std::mem::take(&mut prepared.pending);
            let (state, progress, base) = (prepared.state.clone(), config.progress.clone(), base.clone());
            tokio::spawn(async move {
                let _ = lab_done.await;
                prepare_pending(&state, pending, progress, |outcome| match outcome {
                    Ok(slug) => {
                        let seconds = started.elapsed().as_secs();
                        println!("study \"{slug}\" is open ({seconds} s after start): {base}/studies/{slug}");
                        let _ = std::io::stdout().flush();
                    }
                    Err(line) => eprintln!("warning: {line}"),
                })
                .await;
            });
        }
        prepared
            .state
            .preparation()
            .set_lab_starting(prepared.tasks.iter().map(|task| (task.slug.clone(), task.title.clone())).collect());
        if !prepared.tasks.is_empty() {
            // the lab starts in the background: opening the GPU and path-tracing the photograph
            // must not keep the web survey from being served
            let state = prepared.state.clone();
            let tasks = prepared.tasks;
            let data_dir = config.data_dir.clone();
            let idle_timeout = config.connections.lab_idle_timeout;
            let lab_config = config.lab.clone();
            tokio::spawn(async move {
                let slugs: Vec<String> = tasks.iter().map(|task| task.slug.clone()).collect();
                let (info, warnings) = start_lab(&state, tasks, &data_dir).await;
                if let Some(started) = lab_started {
                    let _ = started.send(());
                }
                if let Some(lab) = state.lab() {
                    lab.set_idle_timeout(idle_timeout);
                    lab.set_sessions_per_address(lab_config.sessions_per_address);
                    lab.set_origins(lab_config.allowed_origins(local));
                }
                for line in &warnings {
                    eprintln!("warning: {line}");
                }
                for line in &info {
                    println!("{line}");
                }
                if let Some(lab) = state.lab() {
                    for slug in slugs.iter().filter(|slug| lab.studies.contains_key(*slug)) {
                        println!("lab link: {base}/lab/{slug}");
                    }
                }
                let _ = std::io::stdout().flush();
            });
        }
        // behind a reverse proxy every connection comes from the proxy: no cap per address
        let connections = match config.limits.behind_tls {
            true => Connections { max_connections_per_address: 0, ..config.connections },
            false => config.connections,
        };
        serve_connections(listener, app(prepared.state), connections, shutdown_signal()).await;
        Ok(())
    });
    // Stimuli still rendering (start-up's blocking tasks) are not waited for: dropping the
    // runtime would wait for them, minutes after Ctrl-C or SIGTERM. Every file of the store is
    // renamed into place after it is written and its index entry after it, so a render cut
    // short leaves nothing half-written, and the next start renders what is missing.
    runtime.shutdown_timeout(std::time::Duration::from_secs(1));
    if served.is_ok() {
        eprintln!("mrstudy serve stopped (stimuli not rendered yet are rendered at the next start)");
    }
    served
}

/// Serves HTTP/1.1 (with upgrades, for the lab's WebSocket) on `listener` until `shutdown`,
/// then lets open requests finish (at most 10 s). Each request carries its peer address
/// ([`crate::limits::ClientAddr`]); requests, bodies, idle connections and unread responses
/// are timed and connections capped per address and in all ([`Connections`],
/// [`crate::connections`]).
pub async fn serve_connections(
    listener: tokio::net::TcpListener,
    router: axum::Router,
    connections: Connections,
    shutdown: impl std::future::Future<Output = ()>,
) {
    use crate::connections::{Clock, DeadlineBody, Table, TrackedBody, WriteDeadline, refusal_response};
    use tower::ServiceExt;
    let table = Table::new(connections.max_connections, connections.max_connections_per_address);
    let (stop, stopping) = tokio::sync::watch::channel(false);
    tokio::pin!(shutdown);
    loop {
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(error) => {
                    // out of file descriptors and the like: wait, do not spin
                    tracing::warn!(%error, "cannot accept a connection");
                    tokio::time::sleep(std::time::Duration::from_millis(100)).await;
                    continue;
                }
            },
            _ = &mut shutdown => break,
        };
        let mut admitted = match table.admit(peer.ip()) {
            Ok(admitted) => admitted,
            Err(refused) => {
                crate::logs::count_refused_connection(refused);
                // one try, never waiting on a client that does not read
                let _ = stream.try_write(&refusal_response(refused));
                continue;
            }
        };
        let _ = stream.set_nodelay(true);
        let router = router.clone();
        let clock = Clock::new();
        let service = {
            let clock = clock.clone();
            hyper::service::service_fn(move |request: axum::http::Request<hyper::body::Incoming>| {
                clock.request_started();
                // the whole request by `request_timeout` from its start, its body by `body_timeout`
                let whole = clock.since() + connections.request_timeout;
                let body = tokio::time::Instant::now() + connections.body_timeout;
                let (deadline, allowed) =
                    if whole <= body { (whole, connections.request_timeout) } else { (body, connections.body_timeout) };
                let mut request = request.map(|body| axum::body::Body::new(DeadlineBody::new(body, deadline, allowed)));
                request.extensions_mut().insert(crate::limits::ClientAddr(peer.ip()));
                let clock = clock.clone();
                let response = router.clone().oneshot(request);
                async move {
                    let response = response.await?;
                    Ok::<_, std::convert::Infallible>(response.map(|body| TrackedBody::new(body, clock)))
                }
            })
        };
        let mut stopping = stopping.clone();
        let header_timeout = connections.header_timeout.min(connections.request_timeout);
        let idle_timeout = header_timeout;
        let write_timeout = connections.write_timeout;
        tokio::spawn(async move {
            let mut builder = hyper::server::conn::http1::Builder::new();
            builder.timer(hyper_util::rt::TokioTimer::new()).header_read_timeout(header_timeout);
            // hyper's own 400, 414 and 431 get the JSON error shape
            let io = hyper_util::rt::TokioIo::new(crate::parse_errors::JsonParseErrors::new(WriteDeadline::new(
                stream,
                write_timeout,
            )));
            let connection = builder.serve_connection(io, service).with_upgrades();
            tokio::pin!(connection);
            // between requests (and while one's headers come) the connection may wait
            // `idle_timeout` from the end of its last response; a request being served is
            // bounded by its body's deadline and the socket's write deadline instead
            let watchdog = tokio::time::sleep(idle_timeout);
            tokio::pin!(watchdog);
            loop {
                tokio::select! {
                    _ = connection.as_mut() => break,
                    _ = &mut admitted.closed => break,
                    _ = stopping.changed() => {
                        connection.as_mut().graceful_shutdown();
                        let _ = connection.await;
                        break;
                    }
                    _ = &mut watchdog => {
                        let until = clock.since() + idle_timeout;
                        if !clock.busy() && tokio::time::Instant::now() >= until {
                            break;
                        }
                        let next = if clock.busy() { tokio::time::Instant::now() + idle_timeout } else { until };
                        watchdog.as_mut().reset(next);
                    }
                }
            }
            drop(admitted);
            drop(stopping);
        });
    }
    drop(listener);
    let _ = stop.send(true);
    // every connection holds a receiver until it has finished; this loop's own receiver goes
    // first, or `closed` would wait out the whole timeout even with no connection open
    drop(stopping);
    let _ = tokio::time::timeout(std::time::Duration::from_secs(10), stop.closed()).await;
}

async fn shutdown_signal() {
    let interrupt = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        _ = interrupt => {},
        _ = terminate => {},
    }
}

/// What `mrstudy export` produced: the text, and the one line to print on stderr saying whom it
/// left out (pilot and excluded participants), if anyone.
#[derive(Debug, Clone)]
pub struct ExportOutput {
    pub text: String,
    pub left_out: Option<String>,
}

/// `mrstudy export`'s request (its flags).
#[derive(Debug, Clone)]
pub struct ExportRequest {
    /// The study's slug.
    pub study: String,
    pub format: ExportFormat,
    /// The file to write; none: the text is returned for stdout.
    pub out: Option<PathBuf>,
    pub data_dir: PathBuf,
    pub database: Option<String>,
    pub include: crate::export::Include,
}

/// Runs `request` as `mrstudy export` does ([`export`]): says who was left out, writes the
/// export to `out`, or returns its text for stdout.
pub fn export_command(
    request: &ExportRequest,
    say: &dyn Fn(mrstudy_renderer::command::Said),
) -> Result<Option<String>, ExportCommandError> {
    let database = request.database.as_deref();
    let output = export(&request.data_dir, database, &request.study, request.format, request.include)?;
    output.left_out.iter().for_each(|line| say(mrstudy_renderer::command::Said::Note(line)));
    let Some(path) = &request.out else { return Ok(Some(output.text)) };
    std::fs::write(path, output.text).map_err(|source| ExportCommandError::Write { path: path.clone(), source })?;
    Ok(None)
}

/// `mrstudy export`: the trials CSV, the JSON export or the conditions CSV of one study, read
/// from `database` (`serve --database`'s value; `None`: `<data-dir>/mrstudy.db`); pilot and
/// excluded participants only when `include` keeps them.
pub fn export(
    data_dir: &Path,
    database: Option<&str>,
    slug: &str,
    format: ExportFormat,
    include: crate::export::Include,
) -> Result<ExportOutput, ExportCommandError> {
    let database = Database::choose(database, data_dir)?;
    if let Database::Sqlite(path) = &database
        && !path.is_file()
    {
        return Err(ExportCommandError::NoDatabase { path: path.clone() });
    }
    let runtime =
        tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(ExportCommandError::Runtime)?;
    runtime.block_on(async {
        let storage = Storage::open(&database).await?;
        let name = database.describe();
        let pool = &storage.read;
        let kind: Option<String> = sqlx::query_scalar("SELECT kind FROM studies WHERE slug = $1")
            .bind(slug)
            .fetch_optional(pool)
            .await
            .map_err(|source| ExportCommandError::Read { name, source })?;
        if kind.as_deref() == Some("task")
            && matches!(format, ExportFormat::Csv | ExportFormat::Json | ExportFormat::Conditions)
        {
            return Err(ExportCommandError::TaskStudy { slug: slug.to_string() });
        }
        const HINT: &str = "pass --include-pilots or --include-excluded to keep them";
        let plain = |text: String| ExportOutput { text, left_out: None };
        let output = match format {
            ExportFormat::Csv => crate::export::trials_csv(pool, slug, include)
                .await
                .map(|export| ExportOutput { text: export.content, left_out: export.left_out.sentence(HINT) }),
            ExportFormat::Json => crate::export::study_json(pool, slug, include).await.map(|export| ExportOutput {
                text: serde_json::to_string_pretty(&export.content).expect("JSON serialises") + "\n",
                left_out: export.left_out.sentence(HINT),
            }),
            ExportFormat::Conditions => {
                crate::export::definition(pool, slug).await.map(|definition| plain(definition.conditions_csv()))
            }
            ExportFormat::Task => {
                return crate::lab::results::task_csv(pool, slug).await.map(plain).map_err(ExportCommandError::Lab);
            }
            ExportFormat::TaskTrials => {
                return crate::lab::results::trials_csv(pool, slug).await.map(plain).map_err(ExportCommandError::Lab);
            }
        };
        Ok(output?)
    })
}

/// Why `mrstudy export` wrote nothing.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportCommandError {
    #[error(transparent)]
    Choose(#[from] crate::storage::ChooseError),
    /// The sqlite file at `path` does not exist.
    #[error("there is no database at {}; pass the --data-dir (or --database) that mrstudy serve used", path.display())]
    NoDatabase { path: PathBuf },
    #[error("cannot start the async runtime: {0}")]
    Runtime(std::io::Error),
    #[error(transparent)]
    Open(#[from] OpenError),
    /// The database `name` (as [`Database::describe`] gives it) could not be read.
    #[error("cannot read the database {name}: {source}")]
    Read { name: String, source: sqlx::Error },
    #[error(
        "study \"{slug}\" is a lab task study, which has no paired-comparison trials; export it with --format task (or --format task-trials)"
    )]
    TaskStudy { slug: String },
    #[error(transparent)]
    Export(#[from] crate::export::ExportError),
    /// A lab export failed (its sentence).
    #[error("{0}")]
    Lab(crate::error::AppError),
    #[error("cannot write {}: {source}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
}

/// What `mrstudy export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// The trials CSV of docs/design.md.
    Csv,
    /// Everything about each participant, with the whole schedule.
    Json,
    /// The conditions CSV of docs/design.md.
    Conditions,
    /// A task study's long CSV for `mrstudy analyze` (see [`crate::lab::results`]).
    Task,
    /// A task study's trials, one row per answered trial.
    TaskTrials,
}

impl ExportFormat {
    /// The names `mrstudy export --format` accepts.
    pub const NAMES: &str = "csv, json, conditions, task, task-trials";

    pub fn parse(name: &str) -> Option<ExportFormat> {
        match name {
            "csv" => Some(ExportFormat::Csv),
            "json" => Some(ExportFormat::Json),
            "conditions" => Some(ExportFormat::Conditions),
            "task" => Some(ExportFormat::Task),
            "task-trials" => Some(ExportFormat::TaskTrials),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    /// After the shutdown signal, `serve_connections` lets a request in flight finish (its
    /// response arrives whole), and returns as soon as none is open — not after the 10 s it
    /// allows at most (it did wait them out, holding its own receiver of the stop signal).
    #[tokio::test]
    async fn shutdown_lets_a_request_finish_then_returns_at_once() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let address = listener.local_addr().unwrap();
        let router = axum::Router::new().route(
            "/slow",
            axum::routing::get(|| async {
                tokio::time::sleep(Duration::from_millis(500)).await;
                "done"
            }),
        );
        let (signal, signalled) = tokio::sync::oneshot::channel::<()>();
        let server = tokio::spawn(serve_connections(listener, router, Connections::default(), async {
            let _ = signalled.await;
        }));
        let request = tokio::spawn(async move {
            use tokio::io::{AsyncReadExt, AsyncWriteExt};
            let mut stream = tokio::net::TcpStream::connect(address).await.unwrap();
            stream.write_all(b"GET /slow HTTP/1.1\r\nhost: x\r\n\r\n").await.unwrap();
            let mut response = Vec::new();
            let _ = stream.read_to_end(&mut response).await;
            String::from_utf8_lossy(&response).into_owned()
        });
        tokio::time::sleep(Duration::from_millis(100)).await;
        let start = Instant::now();
        signal.send(()).unwrap();
        let response = request.await.unwrap();
        assert!(response.starts_with("HTTP/1.1 200") && response.ends_with("done"), "{response}");
        server.await.unwrap();
        let took = start.elapsed();
        assert!(took < Duration::from_secs(5), "serve_connections took {took:?} to return after its requests finished");
    }
}
