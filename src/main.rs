//! The `tessera` binary: parses the command line and runs it (see `cli`). Every failure
//! prints a message and exits with status 2; a reader that went away ends it quietly.

#![forbid(unsafe_code)]

mod cli;

fn main() {
    let command = cli::parse();
    if let Err(e) = cli::run(command) {
        // A reader that went away (`tessera bench | head -1`) ends the program quietly, as
        // it does any Unix tool.
        if cli::is_broken_pipe(&e) {
            std::process::exit(0);
        }
        cli::note(format_args!("tessera: error: {e:#}"));
        std::process::exit(2);
    }
}
