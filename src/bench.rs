//! `mrstudy bench`: runs a benchmark of `mrstudy-bench` (the renderer's, the analysis's or the
//! server's load generator), prints its table as it goes and, with `--json FILE`, writes
//! `{"adapter": ..., "rows": [...]}` (docs/design.md); `--plot-dir DIR` writes its curves as SVG.

use std::path::PathBuf;

use anyhow::Result;
use mrstudy_bench::{Options, Target};

flags! {
    BenchArgs {
        #[arg(value_enum)] target: Target,
        /// Write the rows as JSON here.
        #[arg(long)] json: Option<PathBuf>,
        /// Write SVG plots of the curves into this directory.
        #[arg(long)] plot_dir: Option<PathBuf>,
        #[command(flatten)] options: Options,
    }
}

pub fn run(args: BenchArgs) -> Result<()> {
    let measured = mrstudy_bench::run(args.target, &args.options, &crate::progress::Printer::default())?;
    if let Some(path) = &args.json {
        crate::write_file(path, &(serde_json::to_string_pretty(&measured.json)? + "\n"))?;
    }
    if let Some(dir) = &args.plot_dir {
        crate::write_into(dir, measured.plots)?;
    }
    Ok(())
}
