//! Generated command lines through the binary, and shard and sample specs in the library.

use super::harness::*;
use super::parts::part_scene;
use crate::common::*;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};
use tessera::scene::{Overrides, Scene};
use tessera::shard::{self, Shard};

/// Flags, values that make sense with them, and values that do not. None makes a valid render
/// longer than a moment (`--preview-hold`, which waits for Ctrl-C, is left out).
#[rustfmt::skip]
const FLAGS: &[(&str, &[&str], &[&str])] = &[
    ("--width", &["1", "7", "12"], &["0", "-1", "x", "4294967296", "9000000", "1e3", ""]),
    ("--spp", &["1", "2", "3"], &["0", "-3", "x", "4294967296", "99999999999"]),
    ("--depth", &["1", "3", "50"], &["0", "-1", "4294967296"]),
    ("--seed", &["0", "7", "18446744073709551615"], &["18446744073709551616", "-1", "x"]),
    ("--threads", &["1", "2", "3", "64"], &["0", "-1", "x"]),
    ("--tile", &["1", "3", "16", "100000"], &["0", "-1"]),
    ("--shard", &["0/1", "1/2", "0/2", "env", "env/2"], &["2/2", "0/0", "3/2", "a/b", "0/4294967295", "1", "/", ""]),
    ("--split", &["samples", "rows"], &["columns", ""]),
    ("--samples", &["0..1", "0..2", "1..2"], &["1..0", "0..100", "5..9", "x", "..", "0..4294967295"]),
    ("--checkpoint", &["ck", "ck2"], &["no/dir/ck", "dir", "p0.part", "bad.part", "good.toml"]),
    ("--checkpoint-every", &["0", "0.01", "1e300", "2e19"], &["-1", "nan", "inf", "x"]),
    ("-o", &["out.png", "out.ppm", "out.exr", "part.bin"], &["out.jpg", "out", "no/dir/x.png", "dir"]),
    ("--repeat", &["1", "2"], &["0", "x"]),
    ("--json", &[], &[]),
    ("--simd", &["auto", "portable"], &["avx9", "", "AVX2"]),
    ("--warmup", &["0", "1"], &["-1", "x"]),
    ("--workload", &["quick", "cover"], &["nope", ""]),
    ("--out", &["r.json"], &["no/dir/r.json", "dir"]),
    ("--compare", &["a.png"], &["good.toml"]),
    ("--chart", &["c.svg"], &["no/dir/c.svg"]),
    ("--list", &[], &[]),
    ("--no-scaling", &[], &[]),
    ("--quiet", &[], &[]),
    ("--preview=127.0.0.1:0", &[], &[]),
    ("--preview=nonsense", &[], &[]),
    ("--preview", &[], &[]),
    ("--preview-file", &["pv.png"], &["pv.jpg", "no/dir/pv.png", "dir", ""]),
    ("--preview-every", &["0.5", "1e300"], &["0", "-1", "nan", "x"]),
    ("--db", &["res.db", "res2.db"], &["no/dir/r.db", "dir", "good.toml", "a.png", ""]),
    ("--no-save", &[], &[]),
    ("--all", &[], &[]),
    ("--jsonl", &[], &[]),
    ("--machine", &["m-", "amd"], &["", "%", "\u{1b}"]),
    ("--commit", &["0", "abc"], &["", "_"]),
    ("--limit", &["1", "5"], &["-1", "x", "99999999999"]),
    ("--bogus", &[], &[]),
];

/// Positional arguments: scenes, images, parts, and things that are none of those.
const POSITIONALS: &[&str] = &[
    "good.toml",
    "tiny-cover.toml",
    "junk.toml",
    "utf8.toml",
    "missing.toml",
    "dir",
    "empty",
    "a.png",
    "a.exr",
    "a.ppm",
    "p0.part",
    "p1.part",
    "bad.part",
    "good.toml",
];

/// The files command lines refer to, in a fresh directory.
fn cli_workspace() -> PathBuf {
    let dir = temp_dir("fuzz-cli");
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).unwrap();
    write("good.toml", part_scene().as_bytes());
    let cover = std::fs::read_to_string(scene_path("cover.toml")).unwrap();
    let tiny = cover
        .replace("width = 1200", "width = 24")
        .replace("height = 800", "height = 16")
        .replace("samples_per_pixel = 500", "samples_per_pixel = 2");
    assert_ne!(
        tiny, cover,
        "the cover's size lines changed; update this test"
    );
    write("tiny-cover.toml", tiny.as_bytes());
    write(
        "junk.toml",
        &(0..600u32)
            .map(|i| (i * 7919 % 251) as u8)
            .collect::<Vec<_>>(),
    );
    write("utf8.toml", b"[image]\nwidth = 4 # \xff\n");
    write("empty", b"");
    std::fs::create_dir_all(dir.join("dir")).unwrap();
    let tessera = |args: &[&str]| {
        let o = tessera().args(args).current_dir(&dir).output().unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    for out in ["a.png", "a.exr", "a.ppm"] {
        tessera(&["render", "good.toml", "-q", "-o", out]);
    }
    // A result for `results import`.
    tessera(&[
        "bench",
        "tiny-cover.toml",
        "--repeat",
        "1",
        "--warmup",
        "0",
        "--no-scaling",
        "--no-save",
        "--out",
        "r.json",
    ]);
    tessera(&[
        "render",
        "good.toml",
        "-q",
        "--shard",
        "0/2",
        "-o",
        "p0.part",
    ]);
    tessera(&[
        "render",
        "good.toml",
        "-q",
        "--shard",
        "1/2",
        "-o",
        "p1.part",
    ]);
    let mut bad = std::fs::read(dir.join("p1.part")).unwrap();
    let middle = bad.len() / 2;
    bad[middle] ^= 0x40;
    write("bad.part", &bad);
    dir
}

/// A random command line: mostly sensible, with a nonsensical value one time in five.
fn command_line(g: &mut Gen) -> Vec<String> {
    let command = g.pick(&[
        "render", "render", "render", "render", "bench", "merge", "compare", "help", "renderr", "",
        "results",
    ]);
    let mut args = vec![command.to_owned()];
    if command == "results" {
        let sub = [
            "list", "list", "import", "import", "rank", "compare", "history", "export", "",
        ];
        args.push(g.pick(&sub).to_owned());
    }
    let positionals = match command {
        "merge" => 1 + g.below(4),
        "compare" => g.below(4),
        "results" => g.below(3),
        // Always a scene: `bench` alone runs the standard quick workload (seconds), which
        // tests/bench.rs covers.
        "bench" => 1,
        _ => usize::from(g.chance(80)),
    };
    for _ in 0..positionals {
        let sensible = match command {
            "render" | "bench" => g.pick(&["good.toml", "tiny-cover.toml"]),
            "merge" => g.pick(&["p0.part", "p1.part"]),
            "results" => g.pick(&["r.json", "a.png", "junk.toml", "1", "m-", "commit:0"]),
            _ => g.pick(&["a.png", "a.exr", "a.ppm"]),
        };
        let any = g.pick(POSITIONALS);
        args.push(if g.chance(80) { sensible } else { any }.to_owned());
    }
    for _ in 0..g.below(5) {
        let (flag, good, bad) = FLAGS[g.below(FLAGS.len())];
        args.push(flag.to_owned());
        let values = if bad.is_empty() || (g.chance(80) && !good.is_empty()) {
            good
        } else {
            bad
        };
        if !values.is_empty() {
            args.push(g.pick(values).to_owned());
        }
    }
    if command == "merge" && g.chance(80) {
        args.extend(["-o".to_owned(), "merged.png".to_owned()]);
    }
    args
}

/// Runs tessera in `dir` with a deadline; `None` if it ran past it.
fn run_bounded(
    args: &[String],
    dir: &Path,
    env: &[(&str, &str)],
    deadline: Duration,
) -> Option<std::process::Output> {
    let mut child = tessera()
        .args(args)
        .envs(env.iter().copied())
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    Some(child.wait_with_output().unwrap())
}

/// Runs one command line in `dir` and checks how it ended: success, or exit 2 with a
/// message; never a signal (an abort), another status, a panic or a hang.
fn check_command_line(
    dir: &Path,
    args: &[String],
    env: &[(&str, &str)],
) -> Result<Outcome, String> {
    let Some(o) = run_bounded(args, dir, env, Duration::from_secs(30)) else {
        return Err("ran for over 30 s: a hang".to_owned());
    };
    let err = String::from_utf8_lossy(&o.stderr);
    match o.status.code() {
        None => Err(format!("killed by a signal ({:?}): {err}", o.status)),
        _ if err.contains("panicked") => Err(format!("panicked: {err}")),
        Some(0) => Ok(Outcome::Accepted),
        Some(2) if !err.trim().is_empty() => Ok(Outcome::Refused),
        Some(2) => Err("exit 2 without a message".to_owned()),
        Some(c) => Err(format!("exit status {c}: {err}")),
    }
}

/// Job-system environments a command line may run in.
const ENVIRONMENTS: &[&[(&str, &str)]] = &[
    &[],
    &[
        ("SLURM_ARRAY_TASK_ID", "1"),
        ("SLURM_ARRAY_TASK_COUNT", "2"),
    ],
    &[("SLURM_ARRAY_TASK_ID", "x"), ("SLURM_ARRAY_TASK_MIN", "3")],
    &[("JOB_COMPLETION_INDEX", "4294967295")],
];

#[test]
fn generated_command_lines_end_in_success_or_a_clear_refusal() {
    let dir = cli_workspace();
    run_family(
        "cli",
        2000,
        usize::MAX,
        |g| {
            let args = command_line(g);
            let env = g.pick(ENVIRONMENTS);
            let shown = format!("{env:?} tessera {}", args.join(" "));
            ((args, env), shown)
        },
        |(args, env)| check_command_line(&dir, args, env),
    );
}

/// Shard and sample-range specs, as the command line and job systems give them.
#[test]
fn shard_and_sample_specs_never_panic() {
    let pieces = [
        "0",
        "1",
        "2",
        "/",
        "..",
        "env",
        "4294967295",
        "4294967296",
        "-1",
        " ",
        "x",
        "18446744073709551615",
    ];
    let scene = Scene::parse(&part_scene(), Path::new("part.toml"), &Overrides::default()).unwrap();
    for i in cases("spec", count(20_000)) {
        let mut g = Gen::for_case("spec", i);
        let spec: String = (0..1 + g.below(4)).map(|_| g.pick(&pieces)).collect();
        let value = |g: &mut Gen| g.pick(&pieces).to_owned();
        let (id, min, count, index) = (value(&mut g), value(&mut g), value(&mut g), value(&mut g));
        let var = |k: &str| match k {
            "SLURM_ARRAY_TASK_ID" => Some(id.clone()),
            "SLURM_ARRAY_TASK_MIN" => Some(min.clone()),
            "SLURM_ARRAY_TASK_COUNT" => Some(count.clone()),
            "JOB_COMPLETION_INDEX" => Some(index.clone()),
            _ => None,
        };
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            let shard = Shard::parse(&spec, var).ok();
            let samples = tessera::shard::parse_samples(&spec).ok();
            let split = if g.chance(50) {
                shard::Split::Rows
            } else {
                shard::Split::Samples
            };
            let _ = shard::job(&scene, shard, split, samples);
        }));
        assert!(
            outcome.is_ok(),
            "spec:{i}: `{spec}` with {id} {min} {count} {index} panicked"
        );
    }
}
