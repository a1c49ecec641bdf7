//! The `tessera` binary: the command line (see `cli`) and its exit status.

#![forbid(unsafe_code)]

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
