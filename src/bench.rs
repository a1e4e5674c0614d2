//! `mrstudy bench`: runs a benchmark of `mrstudy-bench` (the renderer's, the analysis's or the
//! server's load generator), prints its table as it goes and, with `--json FILE`, writes
//! `{"adapter": ..., "rows": [...]}` (docs/design.md); `--plot-dir DIR` writes its curves as SVG.

use std::path::PathBuf;

use anyhow::Result;
use mrstudy_bench::Options;
use mrstudy_bench::Target;
use mrstudy_server::console::Console;

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
    let (console, json, plot_dir) = (Console::default(), args.json.as_deref(), args.plot_dir.as_deref());
    Ok(mrstudy_bench::run_to_files(args.target, &args.options, json, plot_dir, &|said| console.say(said))?)
}
