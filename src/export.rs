//! `mrstudy export`: a study's trials (or JSON, conditions, task) from the database, by
//! `mrstudy_server::serve::export`, to a file or stdout.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, anyhow};
use mrstudy_server::export::Include;
use mrstudy_server::serve::ExportFormat;

flags! {
    ExportArgs {
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

pub fn run(args: ExportArgs) -> Result<()> {
    let output = mrstudy_server::serve::export(
        &args.data_dir,
        args.database.as_deref(),
        &args.study,
        args.format,
        args.include.into(),
    )
    .map_err(|message| anyhow!("{message}"))?;
    output.left_out.iter().for_each(|line| eprintln!("{line}"));
    match &args.out {
        Some(path) => crate::write_file(path, &output.text),
        None => std::io::stdout().write_all(output.text.as_bytes()).context("cannot write to stdout"),
    }
}
