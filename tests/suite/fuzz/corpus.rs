//! The coverage-guided fuzzers' inputs replayed without a fuzzer: every file of
//! fuzz/corpus/TARGET/ and fuzz/findings/TARGET/ goes through the same check as the fuzz
//! target TARGET (fuzz/checks.rs, shared with the fuzzer), so a finding once fixed stays
//! fixed in every `cargo test`. The fuzzers themselves (libFuzzer) run from fuzz/ci.sh.

#[path = "../../../fuzz/checks.rs"]
mod checks;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

/// The files of fuzz/corpus/`target`/ and fuzz/findings/`target`/, sorted.
fn inputs(target: &str) -> Vec<PathBuf> {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut files = Vec::new();
    for dir in ["corpus", "findings"] {
        let Ok(entries) = std::fs::read_dir(fuzz.join(dir).join(target)) else {
            continue;
        };
        files.extend(
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file()),
        );
    }
    files.sort();
    files
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic".to_owned())
}

/// Runs `target`'s check on each of its inputs; fails naming every input that broke it.
fn replay(target: &str) {
    let check = checks::check_of(target).expect("a target of checks.rs");
    let files = inputs(target);
    assert!(
        !files.is_empty() || target == "request",
        "fuzz/corpus/{target}/ has no inputs"
    );
    let mut failures = Vec::new();
    for file in &files {
        let bytes = std::fs::read(file).unwrap();
        match catch_unwind(AssertUnwindSafe(|| check(&bytes))) {
            Ok(Ok(())) => {}
            Ok(Err(broken)) => failures.push(format!("{}: {broken}", file.display())),
            Err(p) => failures.push(format!("{}: panicked: {}", file.display(), panic_text(&*p))),
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} {target} inputs broke the contract:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
}

#[test]
fn fuzz_corpus_of_scenes_replays_cleanly() {
    replay("scene");
}

#[test]
fn fuzz_corpus_of_png_recipes_replays_cleanly() {
    replay("png_recipe");
}

#[test]
fn fuzz_corpus_of_exr_headers_replays_cleanly() {
    replay("exr_header");
}

#[test]
fn fuzz_corpus_of_part_files_replays_cleanly() {
    replay("part");
}

/// The part seeds are real parts, read whole as they are: their checksums had gone stale
/// with their headers' format 4, so every seed was refused "checksum mismatch" before its
/// sums were read, and only the check's mended copy reached past it. A seed made to be
/// refused for its header (`gamma-zero`) is refused for that, not for its checksum.
#[test]
fn fuzz_part_seeds_carry_their_own_checksums() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/part");
    let mut stale = Vec::new();
    for file in inputs("part").iter().filter(|f| f.starts_with(&dir)) {
        let bytes = std::fs::read(file).unwrap();
        if checks::with_part_checksum(&bytes) != bytes {
            stale.push(file.display().to_string());
        }
        let read = tessera::partial::Part::from_bytes(&bytes, file);
        let refused = read.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(!refused.contains("checksum"), "{refused}");
    }
    assert!(stale.is_empty(), "stale checksums: {stale:?}");
}

#[test]
fn fuzz_corpus_of_bench_results_replays_cleanly() {
    replay("result");
}

#[test]
fn fuzz_corpus_of_images_replays_cleanly() {
    replay("image");
}

#[test]
fn every_fuzz_target_has_a_check_and_a_corpus() {
    for target in checks::TARGETS {
        let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
        assert!(
            fuzz.join("fuzz_targets")
                .join(format!("{target}.rs"))
                .is_file(),
            "fuzz/fuzz_targets/{target}.rs is missing"
        );
        assert!(!inputs(target).is_empty(), "fuzz/corpus/{target}/ is empty");
        if *target != "request" || cfg!(feature = "preview") {
            assert!(checks::check_of(target).is_some(), "no check for {target}");
        }
    }
}

/// The server runs the requests on its own thread, where tokio catches a panic and closes
/// the connection: a hook counts the panics of that thread, and the server must still answer
/// at the end.
#[cfg(feature = "preview")]
#[test]
fn fuzz_corpus_of_viewer_requests_replays_cleanly() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static SERVER_PANICS: AtomicUsize = AtomicUsize::new(0);
    let before = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if std::thread::current().name() == Some("preview-server") {
            SERVER_PANICS.fetch_add(1, Ordering::Relaxed);
        }
        before(info);
    }));
    replay("request");
    checks::request::alive().unwrap();
    assert_eq!(
        SERVER_PANICS.load(Ordering::Relaxed),
        0,
        "the viewer's server panicked on a request of fuzz/corpus/request or fuzz/findings/request"
    );
}
