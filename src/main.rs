//! `mrstudy`: the command line. Thin by design: it parses arguments (the clap definitions of
//! every command live here, the libraries take plain requests), calls the library crates'
//! command functions and turns one `anyhow::Result` into an exit code. Errors are printed to
//! stderr as one sentence.

use std::process::ExitCode;

use anyhow::Result;
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Parser, Subcommand};

/// A clap struct written compactly (one line per flag under its help: rustfmt leaves a braced
/// macro call as written), and with `=> Target { … }` its conversion into the library's plain
/// struct of the same field names: each field by `Into` (a nested flag struct converts the same
/// way), then what the braces add (the fields without a flag).
macro_rules! flags {
    ($(#[$meta:meta])* $name:ident { $($(#[$field_meta:meta])* $field:ident: $ty:ty,)* }) => {
        $(#[$meta])*
        #[derive(clap::Args)]
        pub struct $name { $($(#[$field_meta])* pub $field: $ty,)* }
    };
    ($(#[$meta:meta])* $name:ident => $target:ident { $($rest:tt)* } { $($(#[$field_meta:meta])* $field:ident: $ty:ty,)* }) => {
        flags! { $(#[$meta])* $name { $($(#[$field_meta])* $field: $ty,)* } }
        impl From<$name> for $target {
            #[allow(clippy::needless_update, clippy::useless_conversion)]
            fn from(flags: $name) -> $target {
                $target { $($field: flags.$field.into(),)* $($rest)* }
            }
        }
    };
}

mod analyze;
mod capture;
mod export;
mod render;
mod serve;
mod simulate;
mod stimuli;

#[derive(Parser)]
#[command(
    name = "mrstudy",
    version,
    about = "Perceptual studies of mixed-reality rendering: render stimuli, run studies, analyse judgments."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Analyse paired-comparison trials (Bradley–Terry worth, factor effects, agreement) or lab-task results (Friedman tests).
    Analyze(analyze::AnalyzeArgs),
    /// Measure speed (and error against a reference) of a part of mrstudy.
    Bench(mrstudy_bench::BenchArgs),
    /// Simulate an RGB-D capture of a scene's real objects (depth sensor, plane-fit normals, hash grid of environment samples) and report its error against the true geometry.
    Capture(capture::CaptureArgs),
    /// Render a scene: the reference photograph or ground-truth composite (CPU path tracer); `--list` names the built-in scenes.
    Render(render::RenderArgs),
    /// Run the web survey server: migrate the database, load the studies, print the participant and admin links.
    Serve(serve::ServeFlags),
    /// Render every stimulus a study needs (the photograph by the path tracer, each condition on the GPU), with a progress bar.
    Stimuli(stimuli::StimuliArgs),
    /// Write a study's trials CSV (or JSON, or conditions CSV) from the database.
    Export(export::ExportArgs),
    /// Simulate a study (its real scheduler and analysis, simulated observers): RMSE, coverage and power per design and participant count.
    Simulate(simulate::SimulateArgs),
    /// The participants a study needs per factor for a target power, by simulation.
    Power(simulate::PowerArgs),
}

/// A clap value parser from a library's `parse` (the names it accepts are listed on refusal).
fn choice<T: Clone + Send + Sync + 'static>(
    parse: fn(&str) -> Option<T>,
    names: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    move |text| parse(text).ok_or_else(|| format!("`{text}` is not one of {names}"))
}

/// A clap value parser over (name, help, value): `--help` lists each name with its help.
fn values<T: Copy + Send + Sync + 'static>(
    values: &'static [(&'static str, &'static str, T)],
) -> impl TypedValueParser<Value = T> {
    let names = values.iter().map(|&(name, help, _)| match help {
        "" => PossibleValue::new(name),
        help => PossibleValue::new(name).help(help),
    });
    let value = |name: String| values.iter().find(|(known, _, _)| *known == name).map(|(_, _, value)| *value);
    PossibleValuesParser::new(names).map(move |name| value(name).expect("clap accepts only the names listed"))
}

/// Where a command says what it does: the console (`mrstudy_server::console::Console`).
type Say<'a> = &'a (dyn Fn(mrstudy_renderer::command::Said) + Sync);

fn main() -> ExitCode {
    let cli = Cli::parse();
    let console = mrstudy_server::console::Console::default();
    let say = |said: mrstudy_renderer::command::Said<'_>| console.say(said);
    let result = match cli.command {
        Command::Analyze(args) => analyze::run(args),
        Command::Bench(args) => mrstudy_bench::run_to_files(&args, &say).map_err(Into::into),
        Command::Render(args) => render::run(args, &say),
        Command::Capture(args) => capture::run(args, &say),
        Command::Serve(flags) => serve::run(flags),
        Command::Export(args) => export::run(args, &say),
        Command::Stimuli(args) => stimuli::run(args, &say),
        Command::Simulate(args) => simulate::run_simulate(args, &say),
        Command::Power(args) => simulate::run_power(args, &say),
    };
    drop(console); // its bar is cleared before an error is printed
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // One sentence: the outermost context, then its causes.
            let causes: Vec<String> = error.chain().map(|e| e.to_string()).collect();
            eprintln!("error: {}", causes.join(": "));
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{Cli, Command};
    use clap::Parser;

    /// Each command's flags, parsed from `args` after the command's name.
    fn parse(args: &[&str]) -> Command {
        Cli::try_parse_from(std::iter::once("mrstudy").chain(args.iter().copied())).unwrap().command
    }

    /// The libraries' `Default`s are the flags' defaults: an empty command line gives them.
    #[test]
    fn an_empty_command_line_gives_the_libraries_defaults() {
        let Command::Analyze(analyze) = parse(&["analyze", "--trials", "t.csv"]) else { unreachable!() };
        assert_eq!(mrstudy_analysis::analysis::Options::from(analyze.options), Default::default());
        let Command::Render(render) = parse(&["render"]) else { unreachable!() };
        assert_eq!(mrstudy_renderer::stimulus::RenderKnobs::from(render.request.knobs), Default::default());
        let Command::Export(export) = parse(&["export", "--study", "s"]) else { unreachable!() };
        assert_eq!(mrstudy_server::export::Include::from(export.include), Default::default());
        let Command::Serve(serve) = parse(&["serve"]) else { unreachable!() };
        let config = mrstudy_server::serve::ServeConfig::from(serve);
        assert_eq!((config.limits, config.connections, config.lab, config.log_format), Default::default());
    }

    #[test]
    fn serve_refuses_zero_seconds_and_a_path_as_origin() {
        let flags = ["serve", "--join-limit", "0", "--header-timeout", "5", "--origin", "HTTPS://Lab.Example.org/"];
        let Command::Serve(serve) = parse(&flags) else { unreachable!() };
        let config = mrstudy_server::serve::ServeConfig::from(serve);
        assert_eq!(config.limits.joins_per_minute, 0);
        assert_eq!(config.connections.header_timeout, std::time::Duration::from_secs(5));
        assert_eq!(config.lab.origins, ["https://lab.example.org"]);
        let refused = |args: &[&str]| Cli::try_parse_from(args).map(|_| ()).unwrap_err().to_string();
        let error = refused(&["mrstudy", "serve", "--body-timeout", "0"]);
        assert!(error.contains("`0` is not a whole number of seconds"), "{error}");
        let error = refused(&["mrstudy", "serve", "--origin", "https://a.org/path"]);
        assert!(error.contains("is not an origin"), "{error}");
    }
}
