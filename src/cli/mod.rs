//! The command line: `args` is what was typed, `settings` checks it into what runs, and each
//! command runs from its settings. Output goes through `print_out` and `note`, which never
//! panic on a full disk or a closed pipe.

mod args;
mod bench;
mod preview;
mod render;
mod reproduce;
mod results;
mod settings;

use anyhow::{Context, Result};
use args::{Cli, Command};
use clap::{CommandFactory, FromArgMatches};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use results::ResultsMode;
use settings::{BenchMode, RenderSettings};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use tessera::image_file::Format;
use tessera::render::RenderStats;
use tessera::simd;

/// Parses the command line, or prints help or a usage error and exits.
pub fn parse() -> Command {
    // `--version` says which build this is and what this CPU runs, so that a binary or an
    // image found in a cluster can be identified.
    let version = format!("{} ({})", env!("CARGO_PKG_VERSION"), short_commit());
    let command = Cli::command()
        .version(version.leak() as &str)
        .long_version(long_version().leak() as &str);
    let parsed = command
        .try_get_matches()
        .and_then(|matches| Cli::from_arg_matches(&matches));
    let cli = parsed.unwrap_or_else(|e| {
        // Written without the panic `Cli::parse` risks on a full disk.
        match e.print() {
            Ok(()) => std::process::exit(e.exit_code()),
            Err(io) if io.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
            Err(io) => {
                note(format_args!(
                    "tessera: error: could not write the message: {io}"
                ));
                std::process::exit(2);
            }
        }
    });
    cli.command
}

fn short_commit() -> &'static str {
    let commit = env!("TESSERA_GIT_COMMIT");
    commit.get(..12).unwrap_or(commit)
}

/// `tessera --version`: the version, the commit, the target and the SIMD paths.
fn long_version() -> String {
    let paths: Vec<&str> = (simd::Path::supported().iter().rev())
        .map(|p| p.name())
        .collect();
    format!(
        "{}\ncommit {}\ntarget {} ({} build, {})\nSIMD paths this CPU runs: {} (auto takes {})\n  because {} ({})",
        env!("CARGO_PKG_VERSION"),
        env!("TESSERA_GIT_COMMIT"),
        env!("TESSERA_TARGET"),
        env!("TESSERA_PROFILE"),
        env!("TESSERA_RUSTC_VERSION"),
        paths.join(", "),
        simd::Path::best().name(),
        simd::Path::auto().1,
        simd::cpu_identity().unwrap_or_else(|| std::env::consts::ARCH.into()),
    )
}

/// Runs `command`.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Render(args) => render::run(RenderSettings::new(args)?),
        Command::Bench(args) => bench::run(BenchMode::new(args)?),
        Command::Merge {
            parts,
            output,
            no_provenance,
        } => merge(&parts, &output, no_provenance),
        Command::Info { image, json } => reproduce::info(&image, json),
        Command::Reproduce(args) => reproduce::run(args),
        Command::Compare { a, b } => compare(&a, &b),
        Command::Results(args) => results::run(ResultsMode::new(args)?),
    }
}

fn merge(paths: &[PathBuf], output: &Path, no_provenance: bool) -> Result<()> {
    Format::from_path(output)?;
    let paths = part_files(paths)?;
    let (film, render) = tessera::partial::merge_files(&paths)?;
    let recipe = match render.recipe.as_ref().filter(|_| !no_provenance) {
        Some(source) => {
            let recipe = reproduce::merged_recipe(source, &render, &film, &paths[0]);
            if recipe.is_none() {
                note(format_args!(
                    "tessera: warning: the parts' recipe does not describe them; {} carries none",
                    output.display()
                ));
            }
            recipe
        }
        None if no_provenance => None,
        None => {
            note(format_args!(
                "tessera: note: the parts carry no common recipe, so {} carries none",
                output.display()
            ));
            None
        }
    };
    film.save(output, render.gamma, recipe.as_ref())?;
    note(format_args!(
        "{}: merged {} parts, {}x{}, {} spp",
        output.display(),
        paths.len(),
        film.width,
        film.height,
        film.samples_per_pixel
    ));
    Ok(())
}

/// The part files `paths` name: a directory stands for every `*.part` file in it (sorted),
/// as a shared volume holds a job's parts where no shell expands `*.part`.
fn part_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for path in paths {
        if !path.is_dir() {
            files.push(path.clone());
            continue;
        }
        let entries = std::fs::read_dir(path)
            .with_context(|| format!("{}: could not list the directory", path.display()))?;
        let mut parts = Vec::new();
        for entry in entries {
            let entry = entry
                .with_context(|| format!("{}: could not list the directory", path.display()))?;
            let file = entry.path();
            if file.extension().is_some_and(|e| e == "part") && file.is_file() {
                parts.push(file);
            }
        }
        if parts.is_empty() {
            anyhow::bail!("{}: no .part files in the directory", path.display());
        }
        parts.sort();
        files.extend(parts);
    }
    Ok(files)
}

fn compare(a: &Path, b: &Path) -> Result<()> {
    let d = tessera::compare::compare_files(a, b)?;
    print_out(&format!(
        "RMSE {:.6}  PSNR {:.2} dB  mean abs error {:.6}\n",
        d.rmse, d.psnr_db, d.mean_abs
    ))
}

/// True when `e` comes from writing to a pipe whose reader has gone.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Writes `text` to standard output. Unlike `print!`, which panics, a failure (a full disk, a
/// closed pipe) is an error for the caller to report.
fn print_out(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .context("could not write to standard output")
}

/// Writes a line to standard error. Unlike `eprintln!`, which panics, a failure is ignored:
/// when standard error cannot be written there is nobody left to tell.
pub fn note(line: std::fmt::Arguments) {
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(line).and_then(|()| err.write_all(b"\n"));
}

/// A progress bar with ETA on standard error when it is a terminal, else a hidden one.
fn progress_bar(total: u64, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{wide_bar}] {percent:>3}% of the estimated work, ETA {eta_precise}",
        )
        .expect("progress template is valid")
        .progress_chars("=> "),
    );
    bar
}

/// Wall time, samples/s, Mrays/s, rays per sample and threads of a render.
fn summary(stats: &RenderStats) -> String {
    format!(
        "{:.2} s wall, {:.3} M samples/s, {:.2} Mrays/s, {:.3} rays/sample, {} threads",
        stats.wall.as_secs_f64(),
        stats.samples_per_sec() / 1e6,
        stats.mrays_per_sec(),
        stats.rays_per_sample(),
        stats.threads
    )
}
