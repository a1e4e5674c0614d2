//! `mrstudy serve` and `mrstudy export`: argument parsing and printing
//! around `mrstudy-server`, which does the work.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Args;
use mrstudy_server::limits::Limits;
use mrstudy_server::serve::{Connections, ExportFormat};

#[derive(Args)]
pub struct ServeArgs {
    /// Address to listen on (port 0: any free port).
    #[arg(long, default_value = "127.0.0.1:8080")]
    addr: String,
    /// Data directory: mrstudy.db, stimuli/, admin-token.
    #[arg(long, default_value = "./mrstudy-data")]
    data_dir: PathBuf,
    /// Directory of study files (*.toml).
    #[arg(long, default_value = "./studies")]
    studies: PathBuf,
    /// A stimulus store shared by several servers (default: `<data-dir>/stimuli`), rendered
    /// beforehand by `mrstudy stimuli` (with --shard on a cluster; docs/cluster.md).
    #[arg(long)]
    stimuli_dir: Option<PathBuf>,
    /// Behind a TLS-terminating reverse proxy: the client address is the last X-Forwarded-For
    /// address, and the admin cookie is Secure.
    #[arg(long)]
    behind_tls: bool,
    /// Joins per client address per minute (bursts of twice that); 0: no limit.
    #[arg(long, default_value_t = Limits::default().joins_per_minute)]
    join_limit: u32,
    /// Responses per client address per minute (bursts of twice that); 0: no limit.
    #[arg(long, default_value_t = Limits::default().responses_per_minute)]
    response_limit: u32,
    /// Wrong admin tokens per client address per 15 minutes before it is refused (429); 0: no limit.
    #[arg(long, default_value_t = Limits::default().admin_failures)]
    admin_failure_limit: u32,
    /// Seconds a connection may take to send a request's headers (also how long an idle
    /// keep-alive connection is kept).
    #[arg(long, default_value_t = Connections::default().header_timeout.as_secs())]
    header_timeout: u64,
    /// Seconds a request may take to send its body after the headers.
    #[arg(long, default_value_t = Connections::default().body_timeout.as_secs())]
    body_timeout: u64,
    /// Connections served at once; more wait in the listen queue.
    #[arg(long, default_value_t = Connections::default().max_connections)]
    max_connections: usize,
    /// Seconds a lab WebSocket session may go without a message before it is closed.
    #[arg(long, default_value_t = Connections::default().lab_idle_timeout.as_secs())]
    lab_idle_timeout: u64,
}

pub fn run_serve(args: ServeArgs) -> Result<()> {
    if args.header_timeout == 0 || args.body_timeout == 0 || args.lab_idle_timeout == 0 {
        bail!("--header-timeout, --body-timeout and --lab-idle-timeout must be at least 1 second");
    }
    mrstudy_server::serve::run(mrstudy_server::serve::ServeConfig {
        addr: args.addr,
        data_dir: args.data_dir,
        studies_dir: args.studies,
        stimuli_dir: args.stimuli_dir,
        progress: Some(crate::stimuli::progress_bars()),
        limits: Limits {
            joins_per_minute: args.join_limit,
            responses_per_minute: args.response_limit,
            admin_failures: args.admin_failure_limit,
            behind_tls: args.behind_tls,
        },
        connections: Connections {
            header_timeout: Duration::from_secs(args.header_timeout),
            body_timeout: Duration::from_secs(args.body_timeout),
            max_connections: args.max_connections,
            lab_idle_timeout: Duration::from_secs(args.lab_idle_timeout),
        },
    })?;
    Ok(())
}

#[derive(Args)]
pub struct ExportArgs {
    /// The study's slug.
    #[arg(long)]
    study: String,
    /// csv (the trials CSV of DESIGN.md), json (every participant with the whole schedule),
    /// conditions (the conditions CSV), task (a task study's long CSV), task-trials.
    #[arg(long, default_value = "csv", value_parser = crate::choice(ExportFormat::parse, ExportFormat::NAMES))]
    format: ExportFormat,
    /// Write here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Data directory that `mrstudy serve` used.
    #[arg(long, default_value = "./mrstudy-data")]
    data_dir: PathBuf,
    /// Keep pilot participants (joined through an admin preview link); left out by default.
    #[arg(long)]
    include_pilots: bool,
    /// Keep participants the researcher excluded; left out by default.
    #[arg(long)]
    include_excluded: bool,
}

pub fn run_export(args: ExportArgs) -> Result<()> {
    let include = mrstudy_server::export::Include { pilots: args.include_pilots, excluded: args.include_excluded };
    let output = match mrstudy_server::serve::export(&args.data_dir, &args.study, args.format, include) {
        Ok(output) => output,
        Err(message) => bail!("{message}"),
    };
    if let Some(line) = &output.left_out {
        eprintln!("{line}");
    }
    let text = output.text;
    match &args.out {
        Some(path) => std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?,
        None => {
            use std::io::Write;
            std::io::stdout().write_all(text.as_bytes()).context("cannot write to stdout")?;
        }
    }
    Ok(())
}
