//! `mrstudy serve`: its flags (into `mrstudy_server::serve::ServeConfig`), then
//! `mrstudy_server::serve::run` with the stimulus progress bars.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Result;
use mrstudy_server::connections::parse_seconds;
use mrstudy_server::lab::{LabConfig, parse_origin};
use mrstudy_server::limits::Limits;
use mrstudy_server::logs::LogFormat;
use mrstudy_server::serve::{Connections, ServeConfig};

flags! {
    ServeFlags => ServeConfig { progress: None } {
        /// Address to listen on (port 0: any free port).
        #[arg(long, default_value = "127.0.0.1:8080")] addr: String,
        /// Data directory: mrstudy.db, stimuli/, admin-token.
        #[arg(long, default_value = "./mrstudy-data")] data_dir: PathBuf,
        /// The database: a PostgreSQL URL (postgres://user:password@host:port/database), which several servers may share, or a sqlite file (default: mrstudy.db in the data directory).
        #[arg(long, env = "MRSTUDY_DATABASE_URL", hide_env_values = true)] database: Option<String>,
        /// Directory of study files (*.toml).
        #[arg(long = "studies", default_value = "./studies")] studies_dir: PathBuf,
        /// A stimulus store shared by several servers (default: `<data-dir>/stimuli`), rendered beforehand by `mrstudy stimuli` (with --shard on a cluster; docs/cluster.md).
        #[arg(long)] stimuli_dir: Option<PathBuf>,
        #[command(flatten)] limits: LimitsFlags,
        #[command(flatten)] connections: ConnectionsFlags,
        #[command(flatten)] lab: LabFlags,
        /// How the log on stderr (one line per request, warnings and errors) is written: text or json (one object per line); `RUST_LOG` filters it (unset: info for mrstudy, warn for the rest).
        #[arg(long, default_value = "text", value_parser = crate::values(LogFormat::NAMES))] log_format: LogFormat,
    }
}

flags! {
    /// [`Limits`]' flags; their defaults are its `Default`.
    LimitsFlags => Limits {} {
        /// Joins (new participants), and screen checks, per client address per minute, with bursts of twice that; 0: no limit.
        #[arg(long = "join-limit", default_value_t = Limits::default().joins_per_minute)] joins_per_minute: u32,
        /// Responses per participant per minute, with bursts of twice that (and per client address for answers without valid credentials); 0: no limit.
        #[arg(long = "response-limit", default_value_t = Limits::default().responses_per_minute)] responses_per_minute: u32,
        /// Wrong admin tokens (and admin calls refused with 403) per client address per 15 minutes before more are refused (429; the right token still works); 0: no limit.
        #[arg(long = "admin-failure-limit", default_value_t = Limits::default().admin_failures)] admin_failures: u32,
        /// Behind a TLS-terminating reverse proxy: the client address is the last X-Forwarded-For address, and the admin cookie is Secure.
        #[arg(long)] behind_tls: bool,
    }
}

flags! {
    /// [`Connections`]' flags (times in whole seconds); their defaults are its `Default` (a test checks).
    ConnectionsFlags => Connections {} {
        /// Seconds a connection may take to send a request's headers, from its start or the end of its last response (also how long an idle keep-alive connection is kept).
        #[arg(long, default_value = "20", value_parser = parse_seconds)] header_timeout: Duration,
        /// Seconds a request may take to send its whole body after the headers (else 400, and the connection closes).
        #[arg(long, default_value = "30", value_parser = parse_seconds)] body_timeout: Duration,
        /// Seconds a whole request (headers and body together) may take, from the connection's start or the end of its last response; a slower one is cut off and its connection closed.
        #[arg(long, default_value = "30", value_parser = parse_seconds)] request_timeout: Duration,
        /// Seconds a response may wait for the client to read any of it before the connection is closed.
        #[arg(long, default_value = "20", value_parser = parse_seconds)] write_timeout: Duration,
        /// Connections served at once; when full, a new one takes the place of the oldest connection of the address holding the most (if it holds more than the newcomer's).
        #[arg(long, default_value_t = Connections::default().max_connections)] max_connections: usize,
        /// Connections one client address (an IPv6 /64) may hold at once; more are refused with 503 (0: no cap; behind a reverse proxy every connection comes from the proxy, so there is none).
        #[arg(long, default_value_t = Connections::default().max_connections_per_address)] max_connections_per_address: usize,
        /// Seconds a lab WebSocket session may go without a message before it is closed.
        #[arg(long, default_value = "600", value_parser = parse_seconds)] lab_idle_timeout: Duration,
    }
}

flags! {
    /// [`LabConfig`]'s flags; their defaults are its `Default`.
    LabFlags => LabConfig {} {
        /// An origin (`https://lab.example.org`, `http://192.0.2.7:8080`) whose pages may open lab sessions, besides the address serve listens on (and, on a loopback or wildcard address, `http://localhost:PORT` and `http://127.0.0.1:PORT`); repeat for more. A browser's WebSocket from any other origin is refused (403), whatever its Host.
        #[arg(long = "origin", value_parser = parse_origin)] origins: Vec<String>,
        /// Open lab sessions per client address; 0: no cap.
        #[arg(long = "lab-sessions-per-address", default_value_t = LabConfig::default().sessions_per_address)] sessions_per_address: usize,
    }
}

pub fn run(flags: ServeFlags) -> Result<()> {
    let progress = Some(mrstudy_server::console::stimulus_bars());
    Ok(mrstudy_server::serve::run(ServeConfig { progress, ..flags.into() })?)
}
