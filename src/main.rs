//! The `tessera` binary: parses the command line and runs it (see `cli`). Every failure
//! prints a message and exits with status 2; a reader that went away ends it quietly.

mod cli;

fn main() {
    require_build_features();
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

/// A build made for AVX2 (see `.cargo/config.toml`) would die of an illegal instruction on a
/// CPU without it; say so instead, before anything runs.
fn require_build_features() {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    if !std::is_x86_feature_detected!("avx2") {
        cli::note(format_args!(
            "tessera: error: this build needs a CPU with AVX2; build a portable one with \
             RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release"
        ));
        std::process::exit(2);
    }
}
