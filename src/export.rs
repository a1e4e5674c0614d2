//! `mrstudy export`: its flags, run by `mrstudy_server::serve::export_command` (a study's
//! trials, JSON, conditions or task export from the database) to a file or stdout.

use std::io::Write;
use std::path::PathBuf;

use crate::Say;
use anyhow::{Context, Result, anyhow};
use mrstudy_server::export::Include;
use mrstudy_server::serve::{ExportFormat, ExportRequest, export_command};

flags! {
    ExportArgs => ExportRequest {} {
        /// The study's slug.
        #[arg(long)] study: String,
        /// csv (the trials CSV of docs/design.md), json (every participant with the whole schedule), conditions (the conditions CSV), task (a task study's long CSV), task-trials.
        #[arg(long, default_value = "csv", value_parser = crate::choice(ExportFormat::parse, ExportFormat::NAMES))] format: ExportFormat,
        /// Write here instead of stdout.
        #[arg(long)] out: Option<PathBuf>,
        /// Data directory that `mrstudy serve` used.
        #[arg(long, default_value = "./mrstudy-data")] data_dir: PathBuf,
        /// The database that `mrstudy serve --database` used (a postgres:// URL or a sqlite file; default: mrstudy.db in the data directory).
        #[arg(long, env = "MRSTUDY_DATABASE_URL", hide_env_values = true)] database: Option<String>,
        #[command(flatten)] include: IncludeFlags,
    }
}

flags! {
    IncludeFlags => Include {} {
        /// Keep pilot participants (joined through an admin preview link); left out by default.
        #[arg(long = "include-pilots")] pilots: bool,
        /// Keep participants the researcher excluded; left out by default.
        #[arg(long = "include-excluded")] excluded: bool,
    }
}

pub fn run(args: ExportArgs, say: Say) -> Result<()> {
    let text = export_command(&args.into(), say).map_err(|message| anyhow!("{message}"))?;
    text.map_or(Ok(()), |text| std::io::stdout().write_all(text.as_bytes()).context("cannot write to stdout"))
}
