//! Every example of the README and of `docs/` works as written: each ```toml block is a
//! scene that renders, and each command of each ```sh block runs, in document order, in a
//! scratch copy of the repository as a new user has it (`tessera` on the `PATH`, `cargo run
//! --release --` meaning the same binary), and succeeds. Commands this test cannot run are
//! listed here with the test that runs them instead; a command nobody runs fails the test.
//! The slowest examples (full-size renders of the cover) run only with the heavy tests.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A fenced block of a markdown file.
struct Block {
    file: String,
    /// The line of its opening fence.
    line: usize,
    lang: String,
    text: String,
}

/// The fenced blocks of `file` (relative to the repository).
fn blocks(file: &str) -> Vec<Block> {
    let text = std::fs::read_to_string(root().join(file)).unwrap();
    let mut blocks = Vec::new();
    let mut open: Option<(usize, String, String)> = None;
    for (i, line) in text.lines().enumerate() {
        match &mut open {
            None => {
                if let Some(lang) = line.strip_prefix("```") {
                    open = Some((i + 1, lang.trim().to_owned(), String::new()));
                }
            }
            Some((start, lang, body)) => {
                if line.starts_with("```") {
                    blocks.push(Block {
                        file: file.to_owned(),
                        line: *start,
                        lang: std::mem::take(lang),
                        text: std::mem::take(body),
                    });
                    open = None;
                } else {
                    body.push_str(line);
                    body.push('\n');
                }
            }
        }
    }
    assert!(open.is_none(), "{file}: a code block is not closed");
    blocks
}

/// The README and every page of `docs/`.
fn pages() -> Vec<String> {
    let mut pages = vec!["README.md".to_owned()];
    let mut docs: Vec<String> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

/// The commands of a shell block: continued lines joined, a `for … done` loop one command,
/// comments and blank lines left out.
fn commands(text: &str) -> Vec<String> {
    let mut commands: Vec<String> = Vec::new();
    let mut current = String::new();
    let mut depth = 0i32;
    for line in text.lines() {
        let trimmed = line.trim();
        if current.is_empty() && (trimmed.is_empty() || trimmed.starts_with('#')) {
            continue;
        }
        current.push_str(line);
        current.push('\n');
        let words: Vec<&str> = trimmed.split_whitespace().collect();
        depth += words.iter().filter(|w| **w == "do").count() as i32;
        depth -= words
            .iter()
            .filter(|w| w.trim_end_matches(';') == "done")
            .count() as i32;
        if !trimmed.ends_with('\\') && depth == 0 {
            commands.push(std::mem::take(&mut current));
        }
    }
    assert!(current.is_empty(), "an unfinished command: {current}");
    commands
}

/// How this test treats a command, by what it starts with.
enum Way {
    /// Run it (the program exists here, or the scratch directory provides it).
    Run,
    /// Run it only with the heavy tests: it takes long (a full-size render of the cover).
    Heavy,
    /// Another test runs it; this one only checks that the files it names exist.
    RunBy(&'static str),
}

/// Commands another test runs (by their start), and which.
const RUN_ELSEWHERE: &[(&str, &str)] = &[
    ("cargo test --release", "this very test suite"),
    (
        "pip install ./python",
        "python/tests (pytest), which .ci/run runs on the wheel it builds and installs into a \
         fresh virtual environment",
    ),
    (
        "python3 -m venv",
        "python/tests (pytest), in the virtual environment .ci/run makes",
    ),
    (
        "deploy/container/build.sh",
        "container::the_image_is_small_labelled_and_runs_without_privileges (.ci/run builds \
         it with this script)",
    ),
    (
        "podman run",
        "container::the_readme_s_podman_command_writes_the_cover",
    ),
    (
        "podman tag",
        "none: pushing needs a registry; container.rs runs the jobs from the local image",
    ),
    (
        "podman push",
        "none: pushing needs a registry; container.rs runs the jobs from the local image",
    ),
    (
        "kubectl",
        "container::the_indexed_job_survives_killed_pods_and_merges_to_the_single_render, \
         which runs the jobs' own commands under Podman as the control plane would",
    ),
];

/// Commands that take long, by a piece of their text, and why.
const HEAVY: &[(&str, &str)] = &[
    (
        "cargo run --release -- render     #",
        "the full cover, 1200x800 at 500 spp",
    ),
    ("--width 600 --preview", "the cover at 600x400, 500 spp"),
    ("--shard {}/8", "eight shards of the cover at 600x400"),
    (
        "tessera merge part-*.bin",
        "it merges the eight shards before it",
    ),
    ("valgrind", "a render under valgrind"),
    ("./A bench", "eight rounds of two benchmarks"),
    ("--simd avx2", "two benchmarks of the quick workload"),
    (
        "tessera bench --simd avx512",
        "a benchmark of the quick workload",
    ),
    (
        "results compare latest~1 latest",
        "it compares the two benchmarks before it",
    ),
];

fn way(command: &str) -> Way {
    let start = command.trim_start();
    if let Some((_, by)) = RUN_ELSEWHERE.iter().find(|(s, _)| start.starts_with(s)) {
        return Way::RunBy(by);
    }
    if HEAVY.iter().any(|(piece, _)| command.contains(piece)) {
        return Way::Heavy;
    }
    Way::Run
}

/// A scratch directory as a fresh clone has it (the repository's files linked in), and a
/// `bin` of programs the examples call: `tessera`, and `A` and `B` for the paired method.
fn scratch(name: &str) -> PathBuf {
    let dir = temp_dir(name);
    for entry in ["scenes", "tests", "benches", "deploy", "docs", "Cargo.toml"] {
        std::os::unix::fs::symlink(root().join(entry), dir.join(entry)).unwrap();
    }
    let bin = dir.join("bin");
    std::fs::create_dir(&bin).unwrap();
    let tessera = env!("CARGO_BIN_EXE_tessera");
    for name in ["tessera", "A", "B"] {
        std::os::unix::fs::symlink(tessera, bin.join(name)).unwrap();
    }
    // The paired method calls them as ./A and ./B.
    for name in ["A", "B"] {
        std::os::unix::fs::symlink(tessera, dir.join(name)).unwrap();
    }
    dir
}

/// `tessera ARGS` in `dir`; it must succeed.
fn run_in_dir(dir: &Path, args: &[&str]) -> std::process::Output {
    let o = tessera().args(args).current_dir(dir).output().unwrap();
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    o
}

/// Whether `program` is on the `PATH`.
fn have(program: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs `command` (bash) in `dir` with the scratch `bin` first on the `PATH`.
fn run_command(dir: &Path, command: &str) -> std::process::Output {
    let as_written = command.replace("cargo run --release -- ", "tessera ");
    let path = format!(
        "{}:{}",
        dir.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    Command::new("bash")
        .args(["-euo", "pipefail", "-c", &as_written])
        .current_dir(dir)
        .env("PATH", path)
        .env("TESSERA_DB", dir.join("results.db"))
        .output()
        .expect("run bash")
}

/// Runs every example of `page`, in order, in one scratch directory, calling `after` with
/// the directory and each command run; gives what it did not run, and why.
fn run_page(page: &str, heavy: bool, after: &mut dyn FnMut(&Path, &str)) -> Vec<String> {
    let dir = scratch(&format!("docs-{}", page.replace(['/', '.'], "-")));
    let mut skipped = Vec::new();
    // A comparison of the benchmark before it, which this CPU could not run.
    let mut no_avx512 = false;
    for block in blocks(page) {
        let at = format!("{}:{}", block.file, block.line);
        match block.lang.as_str() {
            "toml" => {
                let name = "example.toml";
                std::fs::write(dir.join(name), &block.text).unwrap();
                // The texture the examples name, as it lies next to the scenes.
                std::fs::copy(root().join("scenes/earthmap.jpg"), dir.join("earthmap.jpg"))
                    .unwrap();
                let started = std::time::Instant::now();
                let o = run_command(&dir, "tessera render example.toml -q");
                eprintln!("{at}: {:.1} s: the scene", started.elapsed().as_secs_f64());
                assert!(o.status.success(), "{at}: the scene fails: {}", stderr(&o));
                assert!(dir.join("example.png").exists(), "{at}");
            }
            "sh" => {
                for command in commands(&block.text) {
                    match way(&command) {
                        Way::RunBy(by) => {
                            for word in command.split_whitespace() {
                                if word.starts_with("deploy/") {
                                    assert!(root().join(word).exists(), "{at}: {word} is gone");
                                }
                            }
                            skipped.push(format!("{at}: `{}` (run by {by})", command.trim()));
                            continue;
                        }
                        Way::Heavy if !heavy => {
                            skipped.push(format!(
                                "{at}: `{}` (slow: TESSERA_HEAVY_TESTS=1 runs it)",
                                command.trim()
                            ));
                            continue;
                        }
                        Way::Heavy | Way::Run => {}
                    }
                    let program = command.split_whitespace().next().unwrap_or("");
                    let needs = match program {
                        "parallel" | "valgrind" => Some(program),
                        "for" if command.contains("jq") => Some("jq"),
                        _ => None,
                    };
                    if let Some(missing) = needs.filter(|p| !have(p)) {
                        skip(
                            &format!("the example at {at}"),
                            &format!("`{missing}` is not installed (.ci/run installs it)"),
                        );
                        continue;
                    }
                    if command.contains("--simd avx512")
                        && !tessera::simd::Path::supported()
                            .iter()
                            .any(|p| p.name() == "avx512")
                    {
                        skipped.push(format!(
                            "{at}: `{}` (this CPU lacks AVX-512)",
                            command.trim()
                        ));
                        no_avx512 = true;
                        continue;
                    }
                    if no_avx512 && command.contains("latest~1 latest") {
                        skipped.push(format!(
                            "{at}: `{}` (it compares the AVX-512 run this CPU could not make)",
                            command.trim()
                        ));
                        continue;
                    }
                    let started = std::time::Instant::now();
                    let o = run_command(&dir, &command);
                    // Shown with --nocapture: where a page's time goes.
                    eprintln!(
                        "{at}: {:.1} s: {}",
                        started.elapsed().as_secs_f64(),
                        command.trim()
                    );
                    assert!(
                        o.status.success(),
                        "{at}: `{}` failed ({}):\n{}{}",
                        command.trim(),
                        o.status,
                        String::from_utf8_lossy(&o.stdout),
                        stderr(&o)
                    );
                    after(&dir, &command);
                }
            }
            _ => {}
        }
    }
    skipped
}

fn heavy() -> bool {
    heavy_on()
}

#[test]
fn every_example_of_the_readme_runs_as_written() {
    // The set-up's render is the cover workload's image, and the eight shards merged are
    // the README's picture, pixel for pixel.
    let mut checked = 0;
    let skipped = run_page("README.md", heavy(), &mut |dir, command| {
        let words: Vec<&str> = command
            .split('#')
            .next()
            .unwrap()
            .split_whitespace()
            .collect();
        if words == ["cargo", "run", "--release", "--", "render"] {
            assert_eq!(
                recipe_sums(&dir.join("cover.png")),
                kept_workload_image("cover"),
                "the set-up's cover is not the cover workload's image"
            );
            checked += 1;
        }
        if command.starts_with("tessera merge part-*.bin -o cover-600.png") {
            let o = run_in_dir(dir, &["compare", "cover-600.png", "docs/cover-600x400.png"]);
            let said = String::from_utf8_lossy(&o.stdout).into_owned();
            assert!(said.contains("(identical)"), "the merged shards: {said}");
            // The same recipe too, but for the build that made it: so the picture's recipe
            // reproduces it (`the_readme_s_cover_image_reproduces_identically` without the
            // heavy tests, where these shards are not rendered).
            let [merged, kept] = ["cover-600.png", "docs/cover-600x400.png"].map(|image| {
                let o = run_in_dir(dir, &["info", "--json", image]);
                let mut recipe: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
                recipe.as_object_mut().unwrap().remove("tessera");
                recipe
            });
            assert_eq!(
                merged, kept,
                "the recipes of the merged shards and the picture"
            );
            checked += 1;
        }
    });
    assert_eq!(checked, if heavy() { 2 } else { 0 }, "the heavy checks ran");
    let _ = std::io::Write::write_all(
        &mut std::io::stderr(),
        format!(
            "README examples not run here:\n  {}\n",
            skipped.join("\n  ")
        )
        .as_bytes(),
    );
}

#[test]
fn every_example_of_the_docs_runs_as_written() {
    for page in pages().into_iter().filter(|p| p != "README.md") {
        let skipped = run_page(&page, heavy(), &mut |_, _| {});
        if !skipped.is_empty() {
            let _ = std::io::Write::write_all(
                &mut std::io::stderr(),
                format!(
                    "{page} examples not run here:\n  {}\n",
                    skipped.join("\n  ")
                )
                .as_bytes(),
            );
        }
    }
}

/// The lists of commands run elsewhere and of slow ones name what the docs hold: an entry
/// that matches no example any more is stale.
#[test]
fn the_lists_of_examples_not_run_here_are_current() {
    let all: Vec<String> = (pages().iter())
        .flat_map(|p| blocks(p))
        .filter(|b| b.lang == "sh")
        .flat_map(|b| commands(&b.text))
        .collect();
    for (start, _) in RUN_ELSEWHERE {
        assert!(
            all.iter().any(|c| c.trim_start().starts_with(start)),
            "RUN_ELSEWHERE names `{start}`, which no example holds"
        );
    }
    for (piece, _) in HEAVY {
        assert!(
            all.iter().any(|c| c.contains(piece)),
            "HEAVY names `{piece}`, which no example holds"
        );
    }
}

/// The README's picture of the cover is tessera's own render, and says how to make it again.
/// With the heavy tests on, the README's own shards render this picture, and
/// `every_example_of_the_readme_runs_as_written` finds the same pixels and the same recipe:
/// rendering it a fifth time (CI renders the quarter cover in four other tests) adds nothing.
#[test]
fn the_readme_s_cover_image_reproduces_identically() {
    if heavy() {
        return;
    }
    let o = tessera()
        .args(["reproduce", "docs/cover-600x400.png", "-q"])
        .current_dir(root())
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && out.starts_with("identical: "),
        "{out}{}",
        stderr(&o)
    );
}
