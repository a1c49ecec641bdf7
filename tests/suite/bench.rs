//! `tessera bench` as a benchmark to trust: the standard workloads produce the images whose
//! hashes the repository keeps; a result carries its context and is valid; results compare
//! and chart; bad input is refused.

use crate::common::*;
use serde_json::Value;
use std::path::Path;

/// The quick workload, measured once on one thread: the fastest valid result.
const ONE_QUICK_RUN: [&str; 8] = [
    "bench",
    "--repeat",
    "1",
    "--warmup",
    "0",
    "--no-scaling",
    "--threads",
    "1",
];

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Keeps `benches/workloads.toml` true: regenerating it renders every standard workload
/// (the full cover included) and must give the very file in the repository. With the heavy
/// tests on, two of them render the full cover and check its hash (docs.rs, the README's
/// set-up render; container.rs, the indexed job's merged image), so this one renders the
/// others only (`--workload` repeated), which also checks that a workload not named keeps
/// its hash.
#[test]
fn the_standard_workloads_produce_the_images_the_repository_expects() {
    let dir = temp_dir("bench-workloads");
    let mut args = vec!["bench", "--write-workloads", "workloads.toml"];
    if heavy_on() {
        for name in ["quick", "cornell", "next-week"] {
            args.extend(["--workload", name]);
        }
    }
    ok(&args, &dir);
    let regenerated = std::fs::read_to_string(dir.join("workloads.toml")).unwrap();
    let kept = std::fs::read_to_string(root().join("benches/workloads.toml")).unwrap();
    assert!(
        regenerated == kept,
        "an image changed: if on purpose, run `cargo run --release -- bench \
         --write-workloads benches/workloads.toml` and commit it\n{regenerated}"
    );
}

#[test]
fn a_quick_result_is_valid_and_carries_build_host_and_workload() {
    let dir = temp_dir("bench-json");
    let o = run(
        &[
            "bench", "--json", "--repeat", "2", "--warmup", "1", "--out", "r.json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let printed: Value = serde_json::from_slice(&o.stdout).unwrap();
    let r = json(&dir.join("r.json"));
    assert_eq!(printed, r, "--out writes what --json prints");
    assert_eq!(r["schema"], "tessera-bench/3");
    assert_eq!(r["validation"]["status"], "valid");
    assert_eq!(r["validation"]["images"].as_array().unwrap().len(), 1);
    assert_eq!(r["workload"]["name"], "quick");
    assert_eq!(r["workload"]["width"], 600);
    assert_eq!(r["workload"]["spp"], 16);
    assert!(
        r["workload"]["id"]
            .as_str()
            .unwrap()
            .starts_with("xxh3-128:")
    );
    let build = &r["build"];
    assert_eq!(build["version"], env!("CARGO_PKG_VERSION"));
    assert!(!build["commit"].as_str().unwrap().is_empty());
    assert!(build["rustc"].as_str().unwrap().starts_with("rustc "));
    let reason = build["simd_reason"].as_str().unwrap();
    assert!(reason.starts_with("auto on "), "{reason}");
    let supported = build["simd_supported"].as_array().unwrap();
    assert!(supported.contains(&build["simd"]));
    let host = &r["host"];
    let cpus = host["cpus_usable"].as_u64().unwrap() as usize;
    assert!(cpus >= 1);
    assert!(host["logical_cpus"].as_u64().unwrap() as usize >= cpus);
    let machine = host["machine_id"].as_str().unwrap();
    assert!(
        machine.starts_with("m-") && machine.len() == 18,
        "{machine}"
    );
    if cfg!(target_os = "linux") {
        for field in ["cpu_model", "memory_bytes", "kernel", "load_average", "os"] {
            assert!(!host[field].is_null(), "host.{field}");
        }
    }
    // Scaling: 1, 2, 4, … then every CPU, each with its spread.
    let threads: Vec<usize> = (r["scaling"].as_array().unwrap().iter())
        .map(|row| row["threads"].as_u64().unwrap() as usize)
        .collect();
    assert_eq!(threads.first(), Some(&1));
    assert_eq!(threads.last(), Some(&cpus));
    for row in r["scaling"].as_array().unwrap() {
        let s = &row["samples_per_sec"];
        let (min, median, max) = (
            s["min"].as_f64().unwrap(),
            s["median"].as_f64().unwrap(),
            s["max"].as_f64().unwrap(),
        );
        assert!(0.0 < min && min <= median && median <= max, "{row}");
        assert_eq!(row["runs"].as_array().unwrap().len(), 2);
        let rays = row["rays_per_sample"].as_f64().unwrap();
        assert!((2.68..2.71).contains(&rays), "rays per sample {rays}");
    }
    assert_eq!(r["result"]["threads"].as_u64().unwrap() as usize, cpus);
    assert_eq!(r["scaling"][0]["speedup"], 1.0);
}

#[test]
fn results_compare_and_chart() {
    let dir = temp_dir("bench-compare");
    ok(&[&ONE_QUICK_RUN[..], &["--out", "a.json"]].concat(), &dir);
    ok(
        &[
            &ONE_QUICK_RUN[..],
            &["--out", "b.json", "--simd", "portable"],
        ]
        .concat(),
        &dir,
    );
    let o = run(&["bench", "--compare", "a.json", "b.json"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.contains("A: old: ") && text.contains("B: new: "),
        "{text}"
    );
    assert!(text.contains("B/A"), "{text}");
    assert!(
        text.lines().any(|l| l.trim_start().starts_with("1 ")),
        "{text}"
    );
    ok(&["bench", "--chart", "c.svg", "a.json", "b.json"], &dir);
    let svg = std::fs::read_to_string(dir.join("c.svg")).unwrap();
    assert!(svg.starts_with("<?xml") && svg.contains("<svg"), "{svg}");
    assert!(svg.contains("portable") && svg.contains("threads") && svg.contains("M samples/s"));
}

#[test]
fn a_custom_scene_is_validated_only_when_it_is_a_standard_workload() {
    let dir = temp_dir("bench-custom");
    let cover = cover();
    let run_json = |extra: &[&str]| -> Value {
        let args = [
            &[
                "bench",
                &cover,
                "--json",
                "--repeat",
                "1",
                "--warmup",
                "0",
                "--no-scaling",
            ][..],
            extra,
        ]
        .concat();
        let o = run(&args, &dir);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let same = run_json(&["--width", "600", "--spp", "16"]);
    assert_eq!(same["workload"]["name"], "quick");
    assert_eq!(same["validation"]["status"], "valid");
    let other = run_json(&["--width", "100", "--spp", "2"]);
    assert_eq!(other["workload"]["name"], "custom");
    assert_eq!(other["validation"]["status"], "unvalidated");
    assert!(other["validation"]["expected"].is_null());
}

#[test]
fn bad_results_and_workloads_are_refused_with_status_2() {
    let dir = temp_dir("bench-bad");
    ok(&[&ONE_QUICK_RUN[..], &["--out", "a.json"]].concat(), &dir);
    ok(
        &[
            "bench",
            &cover(),
            "--width",
            "64",
            "--spp",
            "1",
            "--repeat",
            "1",
            "--warmup",
            "0",
            "--no-scaling",
            "--out",
            "other.json",
        ],
        &dir,
    );
    std::fs::write(dir.join("foreign.json"), r#"{"samples_per_sec": 1.0}"#).unwrap();
    std::fs::write(
        dir.join("corrupt.json"),
        r#"{"schema": "tessera-bench/1", "#,
    )
    .unwrap();
    let a = std::fs::read_to_string(dir.join("a.json")).unwrap();
    std::fs::write(
        dir.join("future.json"),
        a.replace("tessera-bench/3", "tessera-bench/9"),
    )
    .unwrap();
    std::fs::write(
        dir.join("field.json"),
        a.replace("\"threads\"", "\"thread\""),
    )
    .unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["--compare", "a.json", "foreign.json"],
            "not a tessera bench result",
        ),
        (&["--compare", "a.json", "corrupt.json"], "not JSON"),
        (
            &["--compare", "a.json", "future.json"],
            "schema `tessera-bench/9`",
        ),
        (&["--compare", "a.json", "field.json"], "not a valid"),
        (&["--compare", "a.json", "missing.json"], "could not open"),
        (
            &["--compare", "a.json", "other.json"],
            "different workloads",
        ),
        (
            &["--chart", "c.svg", "a.json", "other.json"],
            "different workloads",
        ),
        (&["--workload", "nope"], "unknown workload `nope`"),
        (
            &["--workload", "quick", "--workload", "cover"],
            "one workload at a time",
        ),
        (
            &["--write-workloads", "w.toml", "--workload", "nope"],
            "unknown workload `nope`",
        ),
    ];
    for (args, message) in cases {
        let o = run(&[&["bench"][..], args].concat(), &dir);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(stderr(&o).contains(message), "{args:?}: {}", stderr(&o));
    }
    assert!(!dir.join("c.svg").exists());
    assert!(!dir.join("w.toml").exists());
}

/// `bench --compare` printed the workload's name and id as the result gave them: a newline
/// in a stranger's name started lines of its own, a forged table row saying "9.000
/// faster, beyond the spread" above the real one. They are one escaped line now, as every
/// other text of a result is.
#[test]
fn a_compared_result_s_workload_cannot_forge_a_line() {
    let dir = temp_dir("bench-compare-forged");
    let mut v: Value = serde_json::from_slice(
        &std::fs::read(root().join("fuzz/corpus/result/quick-one-thread.json")).unwrap(),
    )
    .unwrap();
    let forged = "      1  1.0  9.0  9.000  faster, beyond the spread";
    v["workload"]["name"] = Value::from(format!("quick\n{forged}\n\u{1b}[2J"));
    v["workload"]["id"] = Value::from(format!("{}\n{forged}", v["workload"]["id"]));
    std::fs::write(dir.join("a.json"), serde_json::to_vec(&v).unwrap()).unwrap();
    let o = run(&["bench", "--compare", "a.json", "a.json"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        !text.lines().any(|l| l.starts_with(forged)) && !text.contains('\u{1b}'),
        "{text}"
    );
    assert!(
        text.starts_with("workload quick\\u{a}      1  1.0"),
        "{text}"
    );
}

/// `--write-workloads` with `--workload` renders only the workloads named: the quick one
/// here, the file then the repository's, the others' hashes kept as built in.
#[test]
fn writing_the_workloads_of_one_name_keeps_the_other_hashes() {
    let dir = temp_dir("bench-write-one");
    let o = run(
        &[
            "bench",
            "--write-workloads",
            "w.toml",
            "--workload",
            "quick",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let said = stderr(&o);
    // Each workload's own line says what became of it.
    let line_of = |name: &str| {
        let start = format!("{name}: xxh3-128:");
        let lines: Vec<&str> = said.lines().filter(|l| l.starts_with(&start)).collect();
        assert_eq!(lines.len(), 1, "{name}: {said}");
        lines[0].to_owned()
    };
    assert!(
        line_of("quick").ends_with("(rendered, unchanged)"),
        "{said}"
    );
    for other in ["cover", "cornell", "next-week"] {
        assert!(line_of(other).ends_with("(kept, not rendered)"), "{said}");
    }
    assert_eq!(said.matches("(rendered").count(), 1, "{said}");
    let written = std::fs::read_to_string(dir.join("w.toml")).unwrap();
    let kept = std::fs::read_to_string(root().join("benches/workloads.toml")).unwrap();
    assert_eq!(written, kept);
}

/// `bench --chart R.json R.json` wrote the chart over the result it drew (exit 0): the
/// result was lost. A chart named as one of its results (or a link to one) is refused now,
/// the result left as it was.
/// `bench s.toml --out s.toml` measured the scene and then replaced it with its result
/// (exit 0, the scene lost). The scene file, or a link to it, as --out is refused before
/// anything runs.
#[test]
fn a_result_named_as_its_scene_is_refused() {
    let dir = dir_with_scene("bench-out-over-scene", GOOD);
    std::os::unix::fs::symlink("scene.toml", dir.join("link.json")).unwrap();
    for out in ["scene.toml", "./scene.toml", "link.json"] {
        let o = run(
            &[
                "bench",
                "scene.toml",
                "--width",
                "8",
                "--spp",
                "1",
                "--no-save",
                "--out",
                out,
            ],
            &dir,
        );
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{out}: {err}");
        assert!(
            err.contains("names the scene file measured"),
            "{out}: {err}"
        );
        assert_eq!(
            std::fs::read(dir.join("scene.toml")).unwrap(),
            GOOD.as_bytes()
        );
    }
}

#[test]
fn a_chart_named_as_one_of_its_results_is_refused() {
    let dir = temp_dir("bench-chart-over-result");
    let result = root().join("fuzz/corpus/result/quick-scaling.json");
    std::fs::copy(&result, dir.join("r.json")).unwrap();
    std::os::unix::fs::symlink("r.json", dir.join("link.json")).unwrap();
    let before = std::fs::read(dir.join("r.json")).unwrap();
    for out in ["r.json", "./r.json", "link.json"] {
        let o = run(&["bench", "--chart", out, "r.json"], &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{out}: {err}");
        assert!(
            err.contains("names the same file as the result"),
            "{out}: {err}"
        );
        assert_eq!(std::fs::read(dir.join("r.json")).unwrap(), before, "{out}");
    }
    ok(&["bench", "--chart", "c.svg", "r.json"], &dir);
}

/// `bench --chart` naming the results database (here TESSERA_DB's, or a link to it, or its
/// write-ahead log) replaced it with the SVG, exit 0: every run recorded was lost;
/// `--write-workloads` with the workloads file. Both are refused, as `--out` naming it is,
/// and the database is left as it was.
#[test]
fn a_chart_or_workloads_file_named_as_the_results_database_is_refused() {
    let dir = temp_dir("bench-chart-over-database");
    let result = root().join("fuzz/corpus/result/quick-scaling.json");
    std::fs::copy(&result, dir.join("r.json")).unwrap();
    let db = dir.join("r.db");
    ok_in_env(
        &["results", "import", "r.json"],
        &[("TESSERA_DB", db.to_str().unwrap())],
        &dir,
    );
    std::os::unix::fs::symlink("r.db", dir.join("link.db")).unwrap();
    let before = std::fs::read(&db).unwrap();
    for (out, env) in [
        ("r.db", &[("TESSERA_DB", db.to_str().unwrap())][..]),
        ("./link.db", &[("TESSERA_DB", "r.db")]),
        ("r.db-wal", &[("TESSERA_DB", "r.db")]),
    ] {
        let o = run_in_env(&["bench", "--chart", out, "r.json"], env, &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{out}: {err}");
        assert!(err.contains("names the results database"), "{out}: {err}");
        assert_eq!(std::fs::read(&db).unwrap(), before, "{out}");
    }
    // `--write-workloads` replaced it with the workloads file in the same way.
    let db_env = [("TESSERA_DB", db.to_str().unwrap())];
    let o = run_in_env(
        &["bench", "--write-workloads", "r.db", "--workload", "cover"],
        &db_env,
        &dir,
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("names the results database"), "{err}");
    assert!(std::fs::read(&db).unwrap() == before);
    let o = run(
        &["bench", "--chart", "r.db", "r.json", "--db", "other.db"],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `bench --repeat 30000` of a 4-pixel render wrote a result of 1.56 MB, every run's rate in
/// it, that `results import` refused ("larger than 1024 KiB"), and recorded it in the
/// database, whose `results export` then refused every run ("not a result an import takes;
/// tessera writes none such"). A repeat whose runs a result cannot hold is refused before
/// anything renders, saying the most it takes.
#[test]
fn a_repeat_whose_runs_no_result_holds_is_refused_before_rendering() {
    let dir = temp_dir("bench-repeat-too-many");
    let db = dir.join("r.db");
    let o = run_in_env(
        &[
            "bench",
            &cover(),
            "--width",
            "4",
            "--spp",
            "1",
            "--warmup",
            "0",
            "--no-scaling",
            "--threads",
            "1",
            "--repeat",
            "30000",
            "--out",
            "r.json",
        ],
        &[("TESSERA_DB", db.to_str().unwrap())],
        &dir,
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--repeat 30000: a result keeps every run's rate"),
        "{err}"
    );
    assert!(err.contains("at most --repeat 8192"), "{err}");
    // Refused from the arguments alone (no timed assertion here: CI machines are shared):
    // neither the result nor the database it would be recorded in was made.
    assert!(!dir.join("r.json").exists() && !db.exists());
}

/// In a shared directory (`/tmp`), another user can put a file, a pipe or a directory under
/// `--out`'s name while the bench runs, after the check before it: the rename at the end
/// failed, and the measurement (6.6 s for the default workload, minutes for `cover`) was
/// lost whole: not shown, not recorded, no file, exit 2. Here a directory takes the name
/// once the bench renders (after the check): the result is shown, recorded and kept under
/// the name the error gives, and the exit is still 2.
#[test]
fn a_result_whose_out_file_is_taken_while_it_runs_is_shown_recorded_and_kept() {
    let dir = temp_dir("bench-out-taken");
    let (db, res) = (dir.join("r.db"), dir.join("res.json"));
    // More samples at each try, until the directory is made before the bench ends.
    let output = [4, 32, 256, 2048].into_iter().find_map(|spp| {
        let _ = std::fs::remove_file(&db);
        let _ = std::fs::remove_file(&res);
        let spp = spp.to_string();
        let bench = tessera()
            .args(["bench", &cover(), "--width", "64", "--spp", &spp])
            .args("--repeat 1 --warmup 0 --no-scaling --threads 1 --out res.json".split(' '))
            .env("TESSERA_DB", &db)
            .current_dir(&dir)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        // It renders, past the check of --out, once its pool's thread is there beside the
        // main one (a new database is made only at the end, with the result).
        let tasks = std::path::PathBuf::from(format!("/proc/{}/task", bench.id()));
        while std::fs::read_dir(&tasks).map_or(0, Iterator::count) < 2
            && std::time::Instant::now() < deadline
        {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        let taken = std::fs::create_dir(&res).is_ok();
        let o = bench.wait_with_output().unwrap();
        taken.then_some(o)
    });
    let o = output.expect("every bench ended before its --out name could be taken");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("samples/s"),
        "the result is not shown: {err}"
    );
    assert!(err.contains("recorded in"), "{err}");
    let (_, kept) = err
        .trim_end()
        .rsplit_once("the finished file is kept as ")
        .unwrap_or_else(|| panic!("no file kept: {err}"));
    assert_eq!(json(&dir.join(kept))["workload"]["name"], "custom", "{err}");
    let list = run_in_env(
        &["results", "list"],
        &[("TESSERA_DB", db.to_str().unwrap())],
        &dir,
    );
    assert_eq!(String::from_utf8_lossy(&list.stdout).lines().count(), 2);
}
