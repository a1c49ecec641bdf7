//! What the commands write for people: standard output through `out`, notes on standard
//! error through `note`, the progress bar, numbers and counts in words, and the exit status
//! of an outcome. Nothing here panics on a full disk or a closed pipe: a reader that went
//! away ends the program quietly, as it does any Unix tool.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::process::ExitCode;
use tessera::render::RenderStats;
use tessera::text::{message_safe, terminal_safe_lines};

/// The exit status of a verdict that is not an error: `reproduce` found a difference,
/// `bench` an invalid image.
pub const NEGATIVE: u8 = 1;
/// The exit status of an error: bad input, a file that cannot be read or written.
pub const ERROR: u8 = 2;
/// The exit status of a render stopped by Ctrl-C or SIGTERM, its progress saved (128 + SIGINT).
pub const INTERRUPTED: u8 = 130;

/// The exit status of a command's outcome; an error is printed first (a closed pipe
/// silently ends with 0).
pub fn exit_code(outcome: Result<ExitCode>) -> ExitCode {
    match outcome {
        Ok(code) => code,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            // One line, whatever the message quotes: a newline in a stranger's key or name
            // would otherwise start a line of its own, such as a forged `identical:`; and of
            // bounded length, whatever the length of what it quotes.
            let message = message_safe(&format!("{e:#}"));
            note(format_args!("tessera: error: {message}"));
            ExitCode::from(ERROR)
        }
    }
}

/// Prints clap's help, version or usage error and gives its exit status, without the panic
/// clap's own `exit` risks on a full disk or closed pipe.
pub fn clap_error(e: &clap::Error) -> ExitCode {
    match e.print() {
        Ok(()) => ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(ERROR)),
        Err(io) if io.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(io) => {
            note(format_args!(
                "tessera: error: could not write the message: {io}"
            ));
            ExitCode::from(ERROR)
        }
    }
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
/// closed pipe) is an error for the caller to return.
/// Every character that could rewrite a terminal or hide text (`text::is_unsafe`) is
/// shown as a `\u{…}` escape: what a stranger wrote (a recipe's scene, an imported CPU
/// model) reaches the terminal only so. Machine-read output (JSON) is ASCII already.
pub fn out(text: &str) -> Result<()> {
    let text = terminal_safe_lines(text);
    let mut stdout = std::io::stdout().lock();
    stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
        .context("could not write to standard output")
}

/// Writes a line to standard error. Unlike `eprintln!`, which panics, a failure is ignored:
/// when standard error cannot be written there is nobody left to tell.
/// Unsafe characters are escaped as `out` escapes them: every error message passes here,
/// whatever stranger-made text it quotes, however deep.
pub fn note(line: std::fmt::Arguments) {
    let text = terminal_safe_lines(&line.to_string());
    let mut err = std::io::stderr().lock();
    let _ = err
        .write_all(text.as_bytes())
        .and_then(|()| err.write_all(b"\n"));
}

/// A progress bar with ETA on standard error when it is a terminal, else a hidden one.
pub fn progress_bar(total: u64, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(
        "{elapsed_precise} [{wide_bar}] {percent:>3}% of the estimated work, ETA {eta_precise}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

pub use tessera::text::{count, significant};

/// Wall time, samples/s, Mrays/s, rays per sample and threads of a render.
pub fn render_summary(stats: &RenderStats) -> String {
    format!(
        "{:.2} s wall, {:.3} M samples/s, {:.2} Mrays/s, {:.3} rays/sample, {}",
        stats.wall.as_secs_f64(),
        stats.samples_per_sec() / 1e6,
        stats.mrays_per_sec(),
        stats.rays_per_sample(),
        count(stats.threads as u64, "thread")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_singular_for_one() {
        assert_eq!(count(1u32, "thread"), "1 thread");
        assert_eq!(count(0u32, "thread"), "0 threads");
        assert_eq!(count(16u32, "thread"), "16 threads");
    }

    #[test]
    fn small_differences_keep_their_significant_digits() {
        assert_eq!(significant(0.0, 4), "0");
        assert_eq!(significant(0.000_000_123_456, 4), "0.0000001235");
        assert_eq!(significant(0.012_345_6, 4), "0.01235");
        assert_eq!(significant(1.5, 4), "1.500");
        assert_eq!(significant(1234.5, 4), "1234");
        assert_eq!(significant(3e-12, 3), "3.00e-12");
        assert_eq!(significant(f64::INFINITY, 4), "inf");
    }
}
