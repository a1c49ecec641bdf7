//! The command line: which commands there are, and the dispatch to each. Every command owns
//! its arguments (clap), checks them into settings that know how to run, and returns its
//! exit code; a failure is an error that `main` prints with exit status 2.

mod bench;
mod charts;
mod compare;
mod flags;
mod merge;
mod output;
mod render;
mod reproduce;
#[cfg(feature = "results")]
mod results;
mod version;
mod writable;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "tessera",
    about = "A deterministic multicore path tracer of Ray Tracing in One Weekend"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file to an image (.png, .ppm or .exr).
    Render(render::Args),
    /// Benchmark a standard workload (validated by its image hash) or a scene: samples/s
    /// with their spread over 1, 2, 4, … threads, as text or JSON; compare or chart results.
    Bench(bench::Args),
    /// Combine partial renders (shards, sample ranges) into one image, byte-identical to a
    /// single render of the same scene and settings.
    Merge(merge::Args),
    /// Print the recipe an image carries: the scene, the settings, the build, the hash of
    /// its exact sums.
    Info(reproduce::InfoArgs),
    /// Render an image again from the recipe it carries (no scene file needed) and say
    /// whether it is bit for bit what the recipe makes: exit 0 `identical`, 1 `differs`.
    Reproduce(reproduce::Args),
    /// Print the RMSE, PSNR and mean absolute error of two images of equal size (PNG, PPM,
    /// EXR or JPEG).
    Compare(compare::Args),
    /// The benchmark results kept in the local database: list, import, rank, compare,
    /// follow over commits, report and export them.
    #[cfg(feature = "results")]
    Results(results::Args),
    /// The benchmark results database: not in this build (cargo feature `results`).
    #[cfg(not(feature = "results"))]
    Results(NoResults),
}

/// `tessera results …` in a build without the results database: refused, saying why.
#[cfg(not(feature = "results"))]
#[derive(clap::Args)]
struct NoResults {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    args: Vec<std::ffi::OsString>,
}

/// Runs the command line: parses it, runs the command and turns its outcome into the exit
/// status (0 done, 1 a negative verdict, 2 an error, 130 interrupted).
pub fn main() -> ExitCode {
    if let Err(e) = file_size_limit_is_an_error() {
        output::note(format_args!(
            "tessera: warning: a file past the file size limit (ulimit -f) will end tessera \
             with no word of which file: {e}"
        ));
    }
    let command = match parse() {
        Ok(command) => command,
        Err(code) => return code,
    };
    let outcome = match command {
        Command::Render(args) => render::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Merge(args) => merge::run(args),
        Command::Info(args) => reproduce::info(args),
        Command::Reproduce(args) => reproduce::run(args),
        Command::Compare(args) => compare::run(args),
        #[cfg(feature = "results")]
        Command::Results(args) => results::run(args),
        #[cfg(not(feature = "results"))]
        Command::Results(_) => Err(anyhow::anyhow!(
            "this tessera was built without the results database (cargo feature `results`); \
             `bench --out FILE` keeps a result to import elsewhere"
        )),
    };
    output::exit_code(outcome)
}

/// Makes a write past the file size limit (`ulimit -f`, a quota of a batch system) fail
/// with "File too large", an error said and handled as a full disk is: the old file at the
/// output kept, exit 2 with the file named. By default the kernel's SIGXFSZ ended the
/// process at the first such write, with no word from tessera (the shell's "File size limit
/// exceeded", exit 153), from `render`, `merge` and `bench --out` alike. A signal that is
/// handled, as this one now is (by setting a flag nobody reads), makes the write return the
/// error instead.
fn file_size_limit_is_an_error() -> std::io::Result<()> {
    let ignored = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGXFSZ, ignored).map(drop)
}

/// The command line parsed, or the exit code of the help, version or usage error printed.
fn parse() -> Result<Command, ExitCode> {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    if args.get(1).is_some_and(|a| a == "render")
        && let Some(why) = render::preview_without_equals(&args)
    {
        output::note(format_args!("tessera: error: {why}"));
        return Err(ExitCode::from(output::ERROR));
    }
    let command = Cli::command()
        .version(version::short().leak() as &str)
        .long_version(version::long().leak() as &str);
    let parsed = command
        .try_get_matches_from(args)
        .and_then(|matches| Cli::from_arg_matches(&matches));
    match parsed {
        Ok(cli) => Ok(cli.command),
        Err(e) => Err(output::clap_error(&e)),
    }
}
