//! The results database as a user meets it: `bench` records every run (in `--db`,
//! `TESSERA_DB` or the XDG data directory), `results list` shows and filters them, `results
//! import` adds others' results once each; hostile imports are refused with the reason and
//! add nothing; databases it cannot use (not SQLite, damaged, another program's, a newer
//! tessera's, on a full or read-only disk) are refused and left as they were; concurrent and
//! killed writers lose nothing.

use crate::common::*;
use serde_json::Value;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// A quick custom bench of the cover, recorded in `db` (or not, with `None`), its result
/// also written to `out`.
fn bench(dir: &Path, db: Option<&Path>, out: &str) -> Output {
    let mut c = tessera();
    c.args(["bench", &cover()])
        .args("--width 48 --spp 1 --repeat 1 --warmup 0 --no-scaling".split(' '))
        .args(["--out", out])
        .current_dir(dir);
    match db {
        Some(db) => c.env("TESSERA_DB", db),
        None => c.arg("--no-save"),
    };
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    o
}

/// `tessera results ARGS` on `db`.
fn results(dir: &Path, db: &Path, args: &[&str]) -> Output {
    tessera()
        .arg("results")
        .args(args)
        .env("TESSERA_DB", db)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// A database `r.db` in `dir` holding one run, imported from the corpus's one-thread result
/// (written beside it as `quick.json`), and that result.
fn database_of_one_run(dir: &Path) -> (PathBuf, Value) {
    let db = dir.join("r.db");
    let v = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    write_json(&dir.join("quick.json"), &v);
    let o = results(dir, &db, &["import", "quick.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    (db, v)
}

/// Sets each run's digest in `conn` to its stored result's, as an import keeps it: a test
/// that changes a result (`json_set`) keeps the run one that every reader takes.
fn redigest(conn: &rusqlite::Connection) {
    let runs: Vec<(i64, String)> = (conn.prepare("SELECT id, result FROM runs").unwrap())
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    for (id, result) in runs {
        let digest = format!("{:032x}", xxhash_rust::xxh3::xxh3_128(result.as_bytes()));
        conn.execute(
            "UPDATE runs SET digest = ?1 WHERE id = ?2",
            rusqlite::params![digest, id],
        )
        .unwrap();
    }
}

/// A database of tessera's first schema at `db` (in WAL mode where `wal`, as tessera 0.1.0
/// left it), holding one run of the corpus's `tessera-bench/1` result on an `Old CPU`: the
/// result imported by this build into a database beside it, its rows copied, so that its
/// columns are what its result says.
fn first_schema_database(dir: &Path, db: &Path, wal: bool) {
    let mut v = json(&root().join("fuzz/corpus/result/schema-1.json"));
    v["host"]["cpu_model"] = Value::from("Old CPU");
    write_json(&dir.join("old.json"), &v);
    let made = dir.join("old-made.db");
    let o = results(dir, &made, &["import", "old.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let conn = rusqlite::Connection::open(db).unwrap();
    let mode = if wal {
        "PRAGMA journal_mode = WAL;"
    } else {
        ""
    };
    conn.execute_batch(&format!("{mode} {FIRST_SCHEMA}"))
        .unwrap();
    conn.execute("ATTACH ?1 AS made", [made.to_str().unwrap()])
        .unwrap();
    conn.execute_batch(
        "INSERT INTO runs SELECT id, digest, added_unix_s, source, started_unix_s, machine_id,
            cpu_model, logical_cpus, version, commit_id, simd, workload, workload_id, threads,
            sps_median, sps_min, sps_max, validation, result FROM made.runs;
         INSERT INTO scaling SELECT * FROM made.scaling;
         DETACH made;",
    )
    .unwrap();
    conn.close().unwrap();
    std::fs::remove_file(&made).unwrap();
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The runs `results list` shows (its lines less the heading).
fn listed(dir: &Path, db: &Path, filter: &[&str]) -> Vec<String> {
    let o = results(dir, db, &[&["list"][..], filter].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    if text.trim() == "no results" {
        return Vec::new();
    }
    text.lines().skip(1).map(str::to_owned).collect()
}

fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn write_json(path: &Path, value: &Value) {
    std::fs::write(path, serde_json::to_vec_pretty(value).unwrap()).unwrap();
}

/// Two results of this machine that are not recorded anywhere yet.
fn two_results(dir: &Path) -> (PathBuf, PathBuf) {
    bench(dir, None, "a.json");
    bench(dir, None, "b.json");
    (dir.join("a.json"), dir.join("b.json"))
}

#[test]
fn bench_records_every_run_and_list_shows_and_filters_them() {
    let dir = temp_dir("results-record");
    let db = dir.join("r.db");
    bench(&dir, Some(&db), "one.json");
    let o = bench(&dir, Some(&db), "two.json");
    assert!(stderr(&o).contains("recorded in"), "{}", stderr(&o));
    bench(&dir, None, "unsaved.json");
    let all = listed(&dir, &db, &[]);
    assert_eq!(all.len(), 2, "{all:?}");
    assert!(
        all[0].contains("custom") && all[0].contains("unvalidated"),
        "{}",
        all[0]
    );
    let mode = std::fs::metadata(&db).unwrap().permissions().mode();
    assert_eq!(mode & 0o777, 0o600, "the database is readable by others");
    let one = json(&dir.join("one.json"));
    let machine = one["host"]["machine_id"].as_str().unwrap();
    let commit = one["build"]["commit"].as_str().unwrap();
    assert_eq!(listed(&dir, &db, &["--machine", &machine[..6]]).len(), 2);
    let cpu = one["host"]["cpu_model"].as_str().unwrap_or("unknown");
    let word = cpu.split_whitespace().next().unwrap().to_lowercase();
    assert_eq!(listed(&dir, &db, &["--machine", &word]).len(), 2);
    assert_eq!(
        listed(&dir, &db, &["--machine", "no-such-machine"]).len(),
        0
    );
    assert_eq!(listed(&dir, &db, &["--commit", &commit[..7]]).len(), 2);
    assert_eq!(listed(&dir, &db, &["--workload", "quick"]).len(), 0);
    assert_eq!(listed(&dir, &db, &["--limit", "1"]).len(), 1);
    // A LIKE pattern's own characters match only themselves.
    assert_eq!(listed(&dir, &db, &["--commit", "%"]).len(), 0);
}

/// `bench` made its database (and its directory) before it rendered: a bench stopped or
/// killed while it rendered left a database of no runs, beside a -wal and -shm file. It
/// makes one now only when it has a result to add: here a bench is killed once its renders
/// run (its thread pool's threads are there), and nothing is left where its database would
/// be; one that ends records its run.
#[test]
fn a_bench_killed_while_it_renders_leaves_no_database() {
    let dir = temp_dir("results-bench-killed");
    let db = dir.join("new").join("r.db");
    let mut child = tessera()
        .args(["bench", &cover()])
        .args("--width 400 --spp 256 --repeat 9 --warmup 0 --no-scaling --threads 2".split(' '))
        .env("TESSERA_DB", &db)
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Its renders run once its pool's two threads are there beside the main one.
    let tasks = PathBuf::from(format!("/proc/{}/task", child.id()));
    let mut rendering = false;
    for _ in 0..60_000 {
        if std::fs::read_dir(&tasks).map_or(0, Iterator::count) >= 3 {
            rendering = true;
            break;
        }
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert!(rendering, "the bench never rendered ({status})");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .chain(std::fs::read_dir(dir.join("new")).into_iter().flatten())
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(!db.exists(), "a killed bench left a database: {left:?}");
    assert!(
        left.iter().all(|name| name == "new"),
        "a killed bench left {left:?}"
    );
    // One that ends makes it, with its run.
    bench(&dir, Some(&db), "one.json");
    assert_eq!(listed(&dir, &db, &[]).len(), 1);
}

#[test]
fn the_default_database_is_in_the_data_directory() {
    let dir = temp_dir("results-default");
    let run = |env: &[(&str, &Path)]| {
        let mut c = tessera();
        c.env_remove("TESSERA_DB").env_remove("XDG_DATA_HOME");
        for (k, v) in env {
            c.env(k, v);
        }
        c.args([
            "bench",
            &cover(),
            "--width",
            "32",
            "--spp",
            "1",
            "--repeat",
            "1",
        ])
        .args(["--warmup", "0", "--no-scaling"])
        .current_dir(&dir)
        .output()
        .unwrap()
    };
    let xdg = dir.join("xdg");
    let o = run(&[("XDG_DATA_HOME", &xdg), ("HOME", &dir.join("home"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    let db = xdg.join("tessera/results.db");
    assert!(db.is_file(), "{}", stderr(&o));
    let mode = std::fs::metadata(xdg.join("tessera"))
        .unwrap()
        .permissions()
        .mode();
    assert_eq!(mode & 0o777, 0o700);
    let o = run(&[("HOME", &dir.join("home"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("home/.local/share/tessera/results.db").is_file());
    // A data directory that cannot be made (here: under a file) only costs the record.
    std::fs::write(dir.join("file"), "").unwrap();
    let o = run(&[("XDG_DATA_HOME", &dir.join("file"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("will not be recorded"),
        "{}",
        stderr(&o)
    );
    // One named with --db or TESSERA_DB must work.
    let o = tessera()
        .args(["results", "--db"])
        .arg(dir.join("file/r.db"))
        .arg("list")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn imports_add_each_result_once_and_a_bad_file_adds_nothing() {
    let dir = temp_dir("results-import");
    let db = dir.join("r.db");
    let (a, b) = two_results(&dir);
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());
    let o = results(&dir, &db, &["import", a, b]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o), "imported 2 new results, 0 already present\n");
    let o = results(&dir, &db, &["import", b, a]);
    assert_eq!(stdout(&o), "imported 0 new results, 2 already present\n");
    // A result recorded by bench and then imported from its --out file is one run.
    bench(&dir, Some(&db), "c.json");
    let o = results(&dir, &db, &["import", "c.json"]);
    assert_eq!(stdout(&o), "imported 0 new results, 1 already present\n");
    std::fs::write(dir.join("bad.json"), "{}").unwrap();
    let mut fresh = json(&dir.join("a.json"));
    fresh["method"]["started_unix_s"] = Value::from(1_700_000_000u64);
    write_json(&dir.join("fresh.json"), &fresh);
    let o = results(&dir, &db, &["import", "fresh.json", "bad.json"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("bad.json"), "{}", stderr(&o));
    assert_eq!(listed(&dir, &db, &[]).len(), 3, "a bad file let others in");
    let o = results(&dir, &db, &["import", "fresh.json"]);
    assert_eq!(stdout(&o), "imported 1 new result, 0 already present\n");
}

#[test]
fn hostile_imports_are_refused_with_the_reason() {
    let dir = temp_dir("results-hostile");
    let db = dir.join("r.db");
    let (a, _) = two_results(&dir);
    let good = json(&a);
    let text = std::fs::read_to_string(&a).unwrap();
    let edited = |edit: &dyn Fn(&mut Value)| {
        let mut v = good.clone();
        edit(&mut v);
        serde_json::to_vec(&v).unwrap()
    };
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "huge",
            [vec![b' '; 2 << 20], text.clone().into_bytes()].concat(),
            "larger than",
        ),
        ("deep", "[".repeat(100_000).into_bytes(), "not JSON"),
        ("binary", vec![0xff, 0xfe, 0x00, 0x7b], "not UTF-8"),
        (
            "infinite",
            text.replacen("\"median\": ", "\"median\": 1e999, \"x\": ", 1)
                .into_bytes(),
            "not JSON",
        ),
        (
            "type",
            edited(&|v| v["method"]["threads"] = Value::from("two")),
            "not a valid result",
        ),
        (
            "unknown-field",
            edited(&|v| v["surprise"] = Value::from(1)),
            "not a valid result",
        ),
        // serde_json kept the last of two, where other readers keep the first: imported.
        (
            "key-twice",
            text.replacen('{', "{\"schema\": \"something-else\", ", 1)
                .into_bytes(),
            "the key `schema` twice in one object",
        ),
        (
            "future",
            edited(&|v| v["schema"] = Value::from("tessera-bench/99")),
            "newer tessera",
        ),
        (
            "billion-threads",
            edited(&|v| {
                v["method"]["threads"] = Value::from(1_000_000_000u64);
                v["result"]["threads"] = Value::from(1_000_000_000u64);
            }),
            "not 1 to 65536",
        ),
        (
            "negative-time",
            edited(&|v| v["result"]["wall_s"]["min"] = Value::from(-1.0)),
            "not a positive number",
        ),
        (
            "unordered",
            edited(&|v| v["result"]["samples_per_sec"]["max"] = Value::from(1.0)),
            "out of order",
        ),
        (
            "thread-count-twice",
            edited(&|v| {
                let row = v["scaling"][0].clone();
                v["scaling"].as_array_mut().unwrap().push(row);
            }),
            "threads twice",
        ),
        (
            "headline-of-its-own",
            edited(&|v| {
                let fast = serde_json::json!({"median": 9e11, "min": 9e11, "max": 9e11});
                v["result"]["samples_per_sec"] = fast;
                v["result"]["runs"] = serde_json::json!([9e11]);
            }),
            "the headline is not the scaling table's row",
        ),
        (
            "speed-beyond-any-run",
            edited(&|v| v["result"]["samples_per_sec"]["max"] = Value::from(1.7e308)),
            "more than any run makes",
        ),
        (
            "long-text",
            edited(&|v| v["host"]["cpu_model"] = Value::from("x".repeat(10_000))),
            "longer than",
        ),
        (
            "long-listed-text",
            edited(&|v| v["build"]["simd_supported"][0] = Value::from("x".repeat(300_000))),
            "build.simd_supported holds a text longer than 256",
        ),
        (
            "long-image-hashes",
            edited(&|v| {
                v["validation"]["status"] = Value::from("invalid");
                v["validation"]["images"] = Value::from(vec!["z".repeat(900); 1024]);
            }),
            "validation.images holds a text longer than 256",
        ),
        (
            "long-expected-hash",
            edited(&|v| {
                v["validation"]["status"] = Value::from("invalid");
                v["validation"]["expected"] = Value::from("y".repeat(300_000));
            }),
            "validation.expected is longer than 256",
        ),
        (
            "forged-validation",
            edited(&|v| {
                v["validation"]["status"] = Value::from("valid");
                v["validation"]["expected"] = Value::from("xxh3-128:00");
            }),
            "does not agree",
        ),
        (
            "from-the-past",
            edited(&|v| v["method"]["started_unix_s"] = Value::from(0)),
            "not a time a run took place",
        ),
        (
            "headless",
            edited(&|v| v["scaling"] = Value::Array(Vec::new())),
            "scaling rows is 0",
        ),
    ];
    for (name, bytes, reason) in &cases {
        let file = dir.join(format!("{name}.json"));
        std::fs::write(&file, bytes).unwrap();
        let o = results(&dir, &db, &["import", file.to_str().unwrap()]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(&format!("{name}.json")), "{name}: {err}");
        assert!(err.contains(reason), "{name}: expected `{reason}` in {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
    assert!(!db.exists() || listed(&dir, &db, &[]).is_empty());
}

#[test]
fn what_a_result_says_is_shown_escaped_in_the_terminal() {
    let dir = temp_dir("results-escape");
    let db = dir.join("r.db");
    let (a, _) = two_results(&dir);
    let mut v = json(&a);
    v["host"]["cpu_model"] = Value::from("Evil\u{1b}[2J\u{1b}]0;pwned\u{7} CPU\u{202e}");
    write_json(&dir.join("evil.json"), &v);
    let o = results(&dir, &db, &["import", "evil.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = results(&dir, &db, &["list"]);
    let text = stdout(&o);
    assert!(!text.contains('\u{1b}') && !text.contains('\u{7}') && !text.contains('\u{202e}'));
    assert!(text.contains("Evil\\u{1b}[2J"), "{text}");
}

/// Runs `results ARGS` on `db`, killing it after a minute: an answer, not a hang.
fn results_within_a_minute(dir: &Path, db: &Path, args: &[&str]) -> Output {
    output_within_a_minute(
        tessera()
            .arg("results")
            .args(args)
            .env("TESSERA_DB", db)
            .current_dir(dir),
        &format!("results {args:?}"),
    )
}

/// A speed near the largest `f64` was positive and finite, so an import took it; the
/// report's axis rounded its top up to infinity and drew ticks without end (2.1 GB in 10 s,
/// until memory ran out). An import now refuses it (`hostile_imports_are_refused_with_the_reason`);
/// a database made elsewhere may still hold it, and every command that reads it refuses it
/// at once, naming the run.
#[test]
fn a_report_of_speeds_near_the_largest_number_ends() {
    let dir = temp_dir("results-huge-speed");
    let (db, _) = database_of_one_run(&dir);
    let conn = rusqlite::Connection::open(&db).unwrap();
    conn.execute(
        "UPDATE runs SET sps_max = 1.7e308,
            result = json_set(json_set(result, '$.result.samples_per_sec.max', 1.7e308),
                '$.scaling[0].samples_per_sec.max', 1.7e308)",
        [],
    )
    .unwrap();
    drop(conn);
    let o = results_within_a_minute(&dir, &db, &["report", "-o", "r.html"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("run 1: sps_max is 1.7e308"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("r.html").exists());
}

/// The columns are STRICT, so each holds a number, but any number: a database made
/// elsewhere may say a run had 0 or -5 threads, a rate of 0, a negative one or infinity, or
/// min above max. Every command took them: the report drew `NaN%` and `-inf` into its page,
/// `rank` ranked a 300-digit negative rate, `compare` printed a ratio of NaN. Each is now
/// refused (exit 2) by every command that reads the runs, naming the run and the column.
#[test]
fn a_database_whose_numbers_no_import_takes_is_refused() {
    let dir = temp_dir("results-unsound-rows");
    let v = json(&root().join("fuzz/corpus/result/quick-scaling.json"));
    write_json(&dir.join("q.json"), &v);
    for (name, sql, says) in [
        (
            "zero-rate",
            "UPDATE runs SET sps_median = 0, sps_min = 0, sps_max = 0",
            "sps_median is 0e0",
        ),
        (
            "infinite-rate",
            "UPDATE runs SET sps_max = 1e999",
            "sps_max is inf",
        ),
        (
            "negative-rate",
            "UPDATE runs SET sps_min = -1e300",
            "sps_min is -1e300",
        ),
        (
            "out-of-order",
            "UPDATE runs SET sps_min = sps_max * 2",
            "sps_min, sps_median and sps_max are out of order",
        ),
        (
            "negative-threads",
            "UPDATE runs SET threads = -5",
            "threads is -5",
        ),
        (
            "no-cpus",
            "UPDATE runs SET logical_cpus = 0",
            "logical_cpus is 0",
        ),
        (
            "scaling-zero-threads",
            "UPDATE scaling SET threads = 0 WHERE threads = 1",
            "a scaling row's threads is 0",
        ),
        (
            "scaling-infinite-rate",
            "UPDATE scaling SET sps_max = 1e999",
            "a scaling row's sps_max is inf",
        ),
        // Each of 900 rows is sound, and every one was read and pooled; a run of 3 million
        // rows was read whole (4.8 s, 103 MB) before one out of bounds refused it.
        (
            "scaling-too-many-rows",
            "WITH RECURSIVE n(i) AS (SELECT 100 UNION ALL SELECT i + 1 FROM n WHERE i < 999)
             INSERT INTO scaling SELECT 1, i, 1e6, 1e6, 1e6 FROM n",
            "more than 64 scaling rows",
        ),
        (
            "subnormal-rate",
            "UPDATE runs SET sps_median = 5e-324, sps_min = 5e-324, sps_max = 5e-324",
            "sps_median is 5e-324",
        ),
        // A run dated in the year 292277026596 was the newest of every later one (`latest`,
        // the workload shown first), and a busy flag of -7 read as busy.
        (
            "far-future",
            "UPDATE runs SET started_unix_s = 9223372036854775807",
            "started_unix_s is 9223372036854775807, not a time a run took place",
        ),
        (
            "before-tessera",
            "UPDATE runs SET started_unix_s = -1",
            "started_unix_s is -1, not a time a run took place",
        ),
        (
            "busy-not-0-or-1",
            "UPDATE runs SET busy = -7",
            "busy is -7, not 0 or 1",
        ),
    ] {
        let db = dir.join(format!("{name}.db"));
        let o = results(&dir, &db, &["import", "q.json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let conn = rusqlite::Connection::open(&db).unwrap();
        conn.execute(sql, []).unwrap();
        drop(conn);
        let html = dir.join(format!("{name}.html"));
        // `rank` and `history` read no scaling rows; `report` and `compare` read both.
        let readers = [
            &["report", "-o", html.to_str().unwrap()][..],
            &["compare", "1", "1"],
            &["rank"],
            &["history"],
        ];
        let readers = if name.starts_with("scaling-") {
            &readers[..2]
        } else {
            &readers[..]
        };
        for args in readers {
            let o = results_within_a_minute(&dir, &db, args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{name} {args:?}: {err}");
            assert!(
                err.contains(&format!("{name}.db: run 1: {says}")),
                "{name} {args:?}: {err}"
            );
        }
        assert!(!html.exists(), "{name}");
    }
}

/// Each run keeps columns (what `list`, `rank`, `history`, `compare` and `report` show)
/// beside its whole result (what `export` writes) and the result's digest, and a database
/// made elsewhere may make them disagree: columns saying `valid`, 900 M samples/s, beside a
/// result saying `invalid`, 1 M samples/s, were ranked and reported as the columns said,
/// exit 0, and ranked otherwise once exported and imported elsewhere. Every reader now
/// checks each run it reads against its result and refuses one that disagrees (exit 2),
/// naming the run, the column, and both values.
#[test]
fn a_database_whose_columns_contradict_its_results_is_refused() {
    let dir = temp_dir("results-contradicted");
    let v = json(&root().join("fuzz/corpus/result/quick-scaling.json"));
    write_json(&dir.join("q.json"), &v);
    for (name, sql, says) in [
        (
            "valid",
            "UPDATE runs SET validation = 'invalid'",
            "column validation says `invalid`, its result says `valid`",
        ),
        (
            "faster",
            "UPDATE runs SET sps_median = 9e8, sps_min = 9e8, sps_max = 9e8",
            "column sps_median says 900000000, its result says 9655541.134770188",
        ),
        (
            "machine",
            "UPDATE runs SET machine_id = 'm-0000000000000000'",
            "column machine_id says `m-0000000000000000`, its result says \
             `m-8b6ff694dced7be1`",
        ),
        (
            "no-cpu",
            "UPDATE runs SET cpu_model = NULL",
            "column cpu_model says nothing, its result says `AMD EPYC`",
        ),
        (
            "commit",
            "UPDATE runs SET commit_id = 'abc'",
            "column commit_id says `abc`, its result says `ba4a7032",
        ),
        (
            "workload",
            "UPDATE runs SET workload = 'cover'",
            "column workload says `cover`, its result says `quick`",
        ),
        (
            "threads",
            "UPDATE runs SET threads = 1",
            "column threads says 1, its result says 2",
        ),
        (
            "started",
            "UPDATE runs SET started_unix_s = started_unix_s + 1",
            "column started_unix_s says 1796327354, its result says 1796327353",
        ),
        (
            "busy",
            "UPDATE runs SET busy = 1",
            "column busy says 1, its result says 0",
        ),
        (
            "digest",
            "UPDATE runs SET digest = '00000000000000000000000000000000'",
            "column digest says `00000000000000000000000000000000`, its result's is ",
        ),
        // The result changed and its digest with it: the columns are what is not its.
        (
            "result-invalid",
            "UPDATE runs SET result = json_set(result, '$.validation.status', 'invalid',
                '$.validation.images', json_array('xxh3-128:0'))",
            "column validation says `valid`, its result says `invalid`",
        ),
        (
            "result-not-a-result",
            "UPDATE runs SET result = '{}'",
            "its result: not a tessera bench result (no `schema` field)",
        ),
        (
            "scaling-faster",
            "UPDATE scaling SET sps_median = 6e6, sps_max = 6e6 WHERE threads = 1",
            "the scaling row of 1 threads: column sps_median says 6000000, its result says \
             5145687.415658214",
        ),
        (
            "scaling-missing",
            "DELETE FROM scaling WHERE threads = 1",
            "no scaling row of 1 threads, where its result has one",
        ),
        (
            "scaling-more",
            "INSERT INTO scaling VALUES (1, 4, 1e7, 1e7, 1e7)",
            "a scaling row of 4 threads, where its result has none",
        ),
    ] {
        let db = dir.join(format!("{name}.db"));
        let o = results(&dir, &db, &["import", "q.json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let html = dir.join(format!("{name}.html"));
        let readers = [
            &["list"][..],
            &["rank"],
            &["history"],
            &["compare", "1", "1"],
            &["report", "-o", html.to_str().unwrap()],
        ];
        // Before it is changed, every reader takes it.
        for args in readers {
            let o = results(&dir, &db, args);
            assert!(o.status.success(), "{name} {args:?}: {}", stderr(&o));
        }
        let _ = std::fs::remove_file(&html);
        let conn = rusqlite::Connection::open(&db).unwrap();
        conn.execute(sql, []).unwrap();
        if name.starts_with("result-") {
            redigest(&conn);
        }
        drop(conn);
        for args in readers {
            let o = results_within_a_minute(&dir, &db, args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{name} {args:?}: {err}");
            assert!(
                err.contains(&format!("{name}.db: run 1: {says}")),
                "{name} {args:?}: {err}"
            );
            assert!(o.stdout.is_empty(), "{name} {args:?}: {}", stdout(&o));
        }
        assert!(!html.exists(), "{name}");
    }
}

/// A filter (`--workload`, `--machine`, `--commit`, `--limit`) once chose runs by their
/// columns before any was checked against its result: a column that lied hid its run from
/// a filtered command (`list --workload quick` said "no results" of a run whose workload
/// column said `cover`, its result `quick`; `--limit 1` left the older run unread) or showed
/// it under a filter its result does not meet, while the unfiltered command refused the
/// database. Every run is checked now, whatever the filter, so each refuses alike.
#[test]
fn a_filter_refuses_a_database_whose_columns_lie_as_no_filter_does() {
    let dir = temp_dir("results-filter-lie");
    let v = json(&root().join("fuzz/corpus/result/quick-scaling.json"));
    write_json(&dir.join("old.json"), &v);
    let mut newer = v.clone();
    newer["method"]["started_unix_s"] =
        Value::from(v["method"]["started_unix_s"].as_u64().unwrap() + 60);
    write_json(&dir.join("new.json"), &newer);
    let db = dir.join("r.db");
    let o = results(&dir, &db, &["import", "old.json", "new.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let machine = v["host"]["machine_id"].as_str().unwrap();
    let commit = v["build"]["commit"].as_str().unwrap();
    let filters: [&[&str]; 9] = [
        &["list"],
        &["list", "--workload", "quick"],
        &["list", "--workload", "cover"],
        &["list", "--machine", &machine[..6]],
        &["list", "--machine", "m-0000"],
        &["list", "--commit", &commit[..7]],
        &["list", "--limit", "1"],
        &["rank", "--workload", "quick"],
        &["history", "--machine", machine, "--workload", "quick"],
    ];
    // Before it is changed, every filter takes it, and each selects what it did.
    for args in filters {
        let o = results(&dir, &db, args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
    assert_eq!(listed(&dir, &db, &["--workload", "quick"]).len(), 2);
    assert_eq!(listed(&dir, &db, &["--workload", "cover"]).len(), 0);
    assert_eq!(
        listed(&dir, &db, &["--machine", &machine[..6].to_uppercase()]).len(),
        2
    );
    assert_eq!(listed(&dir, &db, &["--machine", "epyc"]).len(), 2);
    assert_eq!(listed(&dir, &db, &["--machine", "m-0000"]).len(), 0);
    assert_eq!(listed(&dir, &db, &["--commit", &commit[..7]]).len(), 2);
    assert_eq!(listed(&dir, &db, &["--commit", "%"]).len(), 0);
    assert_eq!(listed(&dir, &db, &["--limit", "1"]).len(), 1);
    for (name, sql, says) in [
        (
            "workload",
            "UPDATE runs SET workload = 'cover' WHERE id = 1",
            "column workload says `cover`, its result says `quick`",
        ),
        (
            "machine",
            "UPDATE runs SET machine_id = 'm-0000000000000000' WHERE id = 1",
            "column machine_id says `m-0000000000000000`, its result says",
        ),
        (
            "commit",
            "UPDATE runs SET commit_id = 'abc' WHERE id = 1",
            "column commit_id says `abc`, its result says",
        ),
    ] {
        let lied = dir.join(format!("{name}.db"));
        std::fs::copy(&db, &lied).unwrap();
        let conn = rusqlite::Connection::open(&lied).unwrap();
        conn.execute(sql, []).unwrap();
        drop(conn);
        for args in filters {
            let o = results(&dir, &lied, args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{name} {args:?}: {}", stdout(&o));
            assert!(
                err.contains(&format!("{name}.db: run 1: {says}")),
                "{name} {args:?}: {err}"
            );
            assert!(o.stdout.is_empty(), "{name} {args:?}: {}", stdout(&o));
        }
    }
}

/// A run dated over a day past the reader's clock (recorded by a clock ahead of it, or read
/// on one behind) made every command refuse the whole database, its owner's own too: the
/// reading held each run to a day past its own clock, as an import does. On reading, only a
/// date no clock makes is refused (before 2020, after 2100); `far-future` above is one.
#[test]
fn a_run_dated_past_the_reader_s_clock_still_reads() {
    let dir = temp_dir("results-ahead");
    let (db, _) = database_of_one_run(&dir);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs();
    let conn = rusqlite::Connection::open(&db).unwrap();
    conn.execute(
        "UPDATE runs SET started_unix_s = ?1,
             result = json_set(result, '$.method.started_unix_s', ?1)",
        [now as i64 + 30 * 86_400],
    )
    .unwrap();
    redigest(&conn);
    drop(conn);
    let html = dir.join("r.html");
    for args in [
        &["list"][..],
        &["rank"],
        &["history"],
        &["compare", "1", "1"],
        &["report", "-o", html.to_str().unwrap()],
        &["export", "--jsonl"],
    ] {
        let o = results(&dir, &db, args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
    assert_eq!(listed(&dir, &db, &[]).len(), 1);
}

/// A result of the smallest positive rates a double holds (5e-324 samples/s, where the
/// slowest run makes a sample in a year, 3.1e-8) was imported, and its M samples/s, 0,
/// drew `NaN%` and `inf%` into the report's efficiency table. Such a rate is refused, in a
/// result (naming the row) and in a database (naming the run and column).
#[test]
fn a_rate_slower_than_any_run_is_refused() {
    let dir = temp_dir("results-subnormal-rate");
    let mut v = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    let tiny = Value::from(5e-324);
    for key in ["samples_per_sec", "mrays_per_sec"] {
        for at in ["min", "median", "max"] {
            v["result"][key][at] = tiny.clone();
        }
    }
    v["result"]["runs"] = Value::from(vec![tiny.clone()]);
    v["scaling"][0] = v["result"].clone();
    write_json(&dir.join("slow.json"), &v);
    let db = dir.join("r.db");
    let o = results(&dir, &db, &["import", "slow.json"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 threads: samples/s is 5e-324, less than any run makes"),
        "{}",
        stderr(&o)
    );
    assert!(!db.exists() || listed(&dir, &db, &[]).is_empty());
}

/// A STRICT text column holds text, but SQLite keeps its bytes as given, so a database made
/// elsewhere may hold text that is not UTF-8 (`CAST(x'ff41' AS TEXT)`). Every command
/// refused it with "invalid utf-8 sequence of 1 bytes from index 0 at index 8", naming
/// neither the database, the run nor the column (8 was the column's place in a query).
/// Each says them now (exit 2).
#[test]
fn a_database_whose_text_is_not_utf_8_is_refused_naming_the_run_and_column() {
    let dir = temp_dir("results-not-utf-8");
    let v = json(&root().join("fuzz/corpus/result/quick-scaling.json"));
    write_json(&dir.join("q.json"), &v);
    for (column, readers) in [
        (
            "workload",
            &[
                &["list"][..],
                &["rank"],
                &["history"],
                &["compare", "1", "1"],
            ][..],
        ),
        ("cpu_model", &[&["list"][..], &["rank"]][..]),
        // Read with the result, in one query, by every check of a run.
        (
            "digest",
            &[&["list"][..], &["report", "-o", "digest.html"]][..],
        ),
        ("result", &[&["export", "--jsonl"][..]][..]),
    ] {
        let db = dir.join(format!("{column}.db"));
        let o = results(&dir, &db, &["import", "q.json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let conn = rusqlite::Connection::open(&db).unwrap();
        let sql = format!("UPDATE runs SET {column} = CAST(x'ff41' AS TEXT)");
        conn.execute(&sql, []).unwrap();
        drop(conn);
        for args in readers {
            let o = results_within_a_minute(&dir, &db, args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{column} {args:?}: {err}");
            assert!(
                err.contains(&format!(
                    "{column}.db: run 1: {column} cannot be read (not UTF-8 text)"
                )),
                "{column} {args:?}: {err}"
            );
        }
    }
}

/// `n` results in `dir/many.jsonl`, one a line: the corpus's one-thread result, each a
/// second later than the one before and each of its own workload id or its own machine
/// (`own`), what 50,000 imported results of as many scenes or machines leave.
fn many_results(dir: &Path, n: usize, own: &str) -> PathBuf {
    let base = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    let started = base["method"]["started_unix_s"].as_u64().unwrap();
    let mut lines = String::new();
    for i in 1..=n {
        let mut v = base.clone();
        v["method"]["started_unix_s"] = Value::from(started - (n - i) as u64);
        if i > 1 {
            let at = if own == "machine" {
                &mut v["host"]["machine_id"]
            } else {
                &mut v["workload"]["id"]
            };
            *at = Value::from(format!("{own}-{i:08}"));
        }
        lines.push_str(&serde_json::to_string(&v).unwrap());
        lines.push('\n');
    }
    let path = dir.join("many.jsonl");
    std::fs::write(&path, lines).unwrap();
    path
}

/// `rank` and `report` found each run's workload by looking through the workloads so far,
/// and `report` each ranked machine's runs by looking through every run: time grew with
/// the square of the runs (50,000 runs of as many workloads took 105 s to rank). Each is
/// found in a map now, and the unit test `grouping_compares_each_item_with_few_others`
/// counts the comparisons that takes. This runs both commands on many workloads and
/// machines, and checks what they make: a table for each workload, a section for each.
/// (It once asserted they took under 30 s: a bound a busy machine can break, which the
/// count replaces.)
#[test]
fn rank_and_report_of_many_workloads_and_machines_show_each() {
    const RUNS: usize = 5_000;
    let dir = temp_dir("results-many");
    for own in ["workload", "machine"] {
        let db = dir.join(format!("{own}.db"));
        let many = many_results(&dir, RUNS, own);
        let o = results(&dir, &db, &["import", many.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let o = results_within_a_minute(&dir, &db, &["rank"]);
        assert!(o.status.success(), "{own} rank: {}", stderr(&o));
        let tables = stdout(&o)
            .lines()
            .filter(|l| l.starts_with("workload "))
            .count();
        assert_eq!(
            tables,
            if own == "workload" { RUNS } else { 1 },
            "{own} rank"
        );
        let o = results_within_a_minute(&dir, &db, &["report", "-o", "r.html"]);
        assert!(o.status.success(), "{own} report: {}", stderr(&o));
        let page = std::fs::read_to_string(dir.join("r.html")).unwrap();
        let (sections, machines) = if own == "workload" {
            (RUNS, 1)
        } else {
            (1, RUNS)
        };
        assert_eq!(page.matches("<h2>Workload ").count(), sections, "{own}");
        if own == "machine" {
            assert!(
                page.contains(&format!("machine-{machines:08}")),
                "the last machine is not in the report"
            );
        }
        let _ = std::fs::remove_file(&db);
    }
    let _ = std::fs::remove_file(dir.join("r.html"));
}

/// Bytes of `path`, to check a refused database was left as it was.
fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap()
}

/// Runs `results list`, `results import a` and `bench` on `db` (from `dir`): each must be
/// refused (exit 2) for `reason`, and `db` left as it was.
fn assert_refused(dir: &Path, db: &Path, a: &str, reason: &str) {
    let name = db.file_name().unwrap().to_string_lossy();
    let before = bytes(db);
    for args in [&["list"][..], &["import", a]] {
        let o = results(dir, db, args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name} {args:?}: {err}");
        assert!(err.contains(reason), "{name}: expected `{reason}` in {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
    let o = tessera()
        .args([
            "bench",
            &cover(),
            "--width",
            "16",
            "--spp",
            "1",
            "--repeat",
            "1",
        ])
        .env("TESSERA_DB", db)
        .current_dir(dir)
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "bench on {name}: {err}");
    assert!(
        err.contains(reason),
        "bench on {name}: expected `{reason}` in {err}"
    );
    assert!(bytes(db) == before, "{name} was changed");
}

#[test]
fn databases_it_cannot_use_are_refused_and_left_as_they_were() {
    let dir = temp_dir("results-refused");
    let (a, _) = two_results(&dir);
    let a = a.to_str().unwrap();
    let refuse = |name: &str, reason: &str| assert_refused(&dir, &dir.join(name), a, reason);
    std::fs::write(dir.join("text.db"), "my notes, not a database\n").unwrap();
    refuse("text.db", "not an SQLite database");
    let other = rusqlite::Connection::open(dir.join("other.db")).unwrap();
    other
        .execute_batch("CREATE TABLE photos (id INTEGER)")
        .unwrap();
    drop(other);
    refuse("other.db", "an SQLite database of another program");
    // A newer tessera's database carries tessera's application_id ("TSRA").
    let newer = rusqlite::Connection::open(dir.join("newer.db")).unwrap();
    newer
        .execute_batch(
            "CREATE TABLE runs (id INTEGER); PRAGMA application_id = 1414746689;
             PRAGMA user_version = 99;",
        )
        .unwrap();
    drop(newer);
    refuse("newer.db", "newer tessera");
    // A real database, damaged in the middle.
    let good = dir.join("good.db");
    assert!(results(&dir, &good, &["import", a]).status.success());
    let mut damaged = bytes(&good);
    for b in &mut damaged[4096..8192] {
        *b = 0xa5;
    }
    std::fs::write(dir.join("damaged.db"), damaged).unwrap();
    refuse("damaged.db", "damaged");
}

/// A database path that is a symbolic link to nothing is refused, saying so, by every command
/// that opens it; nothing is made at either end.
#[test]
fn a_link_to_a_missing_database_is_refused_saying_so() {
    let dir = temp_dir("results-dangling");
    let (a, _) = two_results(&dir);
    let link = dir.join("link.db");
    std::os::unix::fs::symlink("elsewhere/r.db", &link).unwrap();
    for args in [&["list"][..], &["import", a.to_str().unwrap()], &["rank"]] {
        let o = results(&dir, &link, args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("link.db: a symbolic link to elsewhere/r.db, which does not exist"),
            "{args:?}: {err}"
        );
    }
    assert!(!dir.join("elsewhere").exists(), "made through the link");
    assert_eq!(
        std::fs::read_link(&link).unwrap(),
        Path::new("elsewhere/r.db")
    );
}

/// A file with tessera's header but SQL of its own (a trigger on its inserts, a view in
/// place of a table, a computed column) is refused before any of it runs: its schema must
/// be tessera's, statement for statement. Each is left as it was.
#[test]
fn a_database_with_tessera_s_header_but_sql_of_its_own_is_refused() {
    let dir = temp_dir("results-crafted-schema");
    let (a, _) = two_results(&dir);
    let a = a.to_str().unwrap();
    let good = dir.join("good.db");
    assert!(results(&dir, &good, &["import", a]).status.success());
    let craft = |name: &str, sql: &str| {
        let path = dir.join(name);
        std::fs::copy(&good, &path).unwrap();
        let conn = rusqlite::Connection::open(&path).unwrap();
        conn.execute_batch(sql).unwrap();
        conn.close().unwrap();
        path
    };
    let cases = [
        (
            "trigger.db",
            "CREATE TRIGGER forget AFTER INSERT ON runs BEGIN DELETE FROM scaling; END;",
            "trigger `forget`, which tessera does not make",
        ),
        (
            "view.db",
            "ALTER TABLE runs RENAME TO kept;
             CREATE VIEW runs AS WITH RECURSIVE c(x) AS
                 (SELECT 1 UNION ALL SELECT x + 1 FROM c WHERE x < 3)
             SELECT kept.* FROM kept, c;",
            "tessera's application_id, but not its schema 3",
        ),
        (
            "column.db",
            "ALTER TABLE runs ADD COLUMN extra TEXT AS (hex(zeroblob(1000)));",
            "its table `runs` is not tessera's",
        ),
    ];
    for (name, sql, reason) in cases {
        let path = craft(name, sql);
        assert_refused(&dir, &path, a, reason);
    }
    // The database they were made from still opens, and a schema 1 one laid out otherwise
    // (a_database_of_the_first_schema_still_opens_with_its_runs) too.
    assert_eq!(listed(&dir, &good, &[]).len(), 1);
}

/// The first schema (user_version 1) as tessera 0.1.0 made it: never edit this copy (the
/// Python package's tests read it too).
const FIRST_SCHEMA: &str = include_str!("../data/results-schema-1.sql");

/// A database someone else made may hold a result that is not JSON, JSON over several
/// lines, or JSON that is no result: export once wrote it out as it was, lines that are no
/// results, and exited 0.
#[test]
fn export_refuses_a_result_that_is_not_one_line_of_json() {
    let dir = temp_dir("results-export-not-json");
    for (name, result, says) in [
        (
            "garbage",
            "{not json",
            "result 1 (oldest first) is not one line of JSON (not JSON:",
        ),
        (
            "lines",
            "{\"a\":\n1}",
            "result 1 (oldest first) is not one line of JSON (it spans",
        ),
        // One line of JSON but no result: exported (exit 0), an export that no import took.
        (
            "not-a-result",
            "{\"a\":1}",
            "result 1 (oldest first) is not a result an import takes (it: not a tessera bench \
             result (no `schema` field))",
        ),
    ] {
        let db = dir.join(format!("{name}.db"));
        let conn = rusqlite::Connection::open(&db).unwrap();
        conn.execute_batch(FIRST_SCHEMA).unwrap();
        conn.execute(
            "INSERT INTO runs VALUES (1, 'd', 1, 'import', 1700000000, 'm-0', 'Old CPU', 4,
             '0.1.0', 'abc', 'avx2', 'cover', 'id', 4, 1e6, 9e5, 1.1e6, 'valid', ?1)",
            [result],
        )
        .unwrap();
        drop(conn);
        let o = results(&dir, &db, &["export", "--jsonl"]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{name}: {}", stderr(&o));
        assert!(o.stdout.is_empty(), "{name}: {}", stdout(&o));
    }
}

#[test]
fn a_database_of_the_first_schema_still_opens_with_its_runs() {
    let dir = temp_dir("results-first-schema");
    let db = dir.join("first.db");
    let (a, _) = two_results(&dir);
    first_schema_database(&dir, &db, false);
    let runs = listed(&dir, &db, &[]);
    assert_eq!(runs.len(), 1);
    assert!(runs[0].contains("Old CPU"), "{}", runs[0]);
    let o = results(&dir, &db, &["import", a.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(listed(&dir, &db, &[]).len(), 2);
    // Brought up to the latest schema, which carries tessera's application_id.
    let head = bytes(&db);
    assert_eq!(&head[68..72], b"TSRA", "no application_id");
    assert_eq!(head[60..64], [0, 0, 0, 3], "not schema 3");
}

/// The names, bytes and modification times of the files in `dir`, sorted.
fn listing(dir: &Path) -> Vec<(String, Vec<u8>, std::time::SystemTime)> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let meta = e.metadata().unwrap();
            let bytes = if meta.is_file() {
                bytes(&e.path())
            } else {
                Vec::new()
            };
            (
                e.file_name().to_string_lossy().into_owned(),
                bytes,
                meta.modified().unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

/// Another program's SQLite databases, however like tessera's they look, are recognised by
/// their header (tessera's application_id, "TSRA") or, for tessera's first two schemas,
/// which had none, by their tables read as an immutable file; they are refused before
/// SQLite writes anything, and the file and its directory are left byte for byte as they
/// were: no switch to WAL, no -wal or -shm file.
#[test]
fn another_programs_databases_are_refused_before_anything_is_written() {
    let dir = temp_dir("results-foreign");
    let (a, _) = two_results(&dir);
    let a = a.to_str().unwrap();
    let dbs = dir.join("dbs");
    std::fs::create_dir(&dbs).unwrap();
    let make = |name: &str, sql: &str| {
        let conn = rusqlite::Connection::open(dbs.join(name)).unwrap();
        conn.execute_batch(sql).unwrap();
        conn.close().unwrap();
    };
    let cases = [
        (
            "notes-v1.db",
            "CREATE TABLE notes (id INTEGER, text TEXT); PRAGMA user_version = 1;".to_owned(),
            "user_version 1 but not tessera's tables",
        ),
        (
            "notes-v2-wal.db",
            "PRAGMA journal_mode = WAL; CREATE TABLE notes (id INTEGER);
             PRAGMA user_version = 2;"
                .to_owned(),
            "user_version 2 but not tessera's tables",
        ),
        (
            "lookalike-v2.db",
            format!("{FIRST_SCHEMA} CREATE TABLE photos (id INTEGER); PRAGMA user_version = 2;"),
            "user_version 2 but not tessera's tables",
        ),
        (
            "other-app.db",
            format!("{FIRST_SCHEMA} PRAGMA application_id = 305419896;"),
            "an SQLite database of another program (application_id 0x12345678",
        ),
        (
            "other-app-wal.db",
            "PRAGMA journal_mode = WAL; PRAGMA application_id = -559038737;
             CREATE TABLE t (x); PRAGMA user_version = 1;"
                .to_owned(),
            "an SQLite database of another program (application_id 0xdeadbeef",
        ),
        (
            "photos-v0.db",
            "CREATE TABLE photos (id INTEGER);".to_owned(),
            "an SQLite database of another program (application_id 0, user_version 0",
        ),
        (
            "runs-v99.db",
            "CREATE TABLE runs (id INTEGER); PRAGMA user_version = 99;".to_owned(),
            "an SQLite database of another program (application_id 0, user_version 99",
        ),
        ("empty.db", String::new(), "an empty file"),
    ];
    for (name, sql, _) in &cases {
        if sql.is_empty() {
            std::fs::write(dbs.join(name), "").unwrap();
        } else {
            make(name, sql);
        }
    }
    let before = listing(&dbs);
    assert_eq!(before.len(), cases.len(), "a -wal or -shm file was left");
    for (name, _, reason) in &cases {
        assert_refused(&dir, &dbs.join(name), a, reason);
        assert!(
            listing(&dbs) == before,
            "{name}: the directory of refused databases changed"
        );
    }
}

/// Eight processes import at once into a database that does not exist yet, many times over,
/// each time at a new path: every import lands, and no temporary name, -wal or -shm file is
/// left. A new database is made whole under a temporary name and published with a hard
/// link, so nobody sees one half-made.
#[test]
fn eight_imports_at_once_into_a_new_database_all_land() {
    let dir = temp_dir("results-first-use");
    let (a, _) = two_results(&dir);
    let files = variants(&dir, &json(&a), 1_730_000_000, 8, "f");
    let started = std::time::Instant::now();
    let mut rounds = 0;
    // 40 rounds, or fewer (but at least 10) where the machine is slow.
    while rounds < 40 && (rounds < 10 || started.elapsed().as_secs() < 12) {
        let round = dir.join(format!("round-{rounds}"));
        let db = round.join("r.db");
        let children: Vec<_> = (files.iter())
            .map(|f| {
                tessera()
                    .args(["results", "import", f])
                    .env("TESSERA_DB", &db)
                    .current_dir(&dir)
                    .stdout(Stdio::piped())
                    .stderr(Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for c in children {
            let o = c.wait_with_output().unwrap();
            assert!(o.status.success(), "round {rounds}: {}", stderr(&o));
            assert_eq!(stdout(&o), "imported 1 new result, 0 already present\n");
        }
        let names: Vec<String> = listing(&round).into_iter().map(|f| f.0).collect();
        assert_eq!(names, ["r.db"], "round {rounds}");
        assert_eq!(listed(&dir, &db, &[]).len(), files.len(), "round {rounds}");
        rounds += 1;
    }
    let o = results(&dir, &dir.join("round-0/r.db"), &["export", "--jsonl"]);
    assert_eq!(stdout(&o).lines().count(), files.len());
}

/// `n` distinct results made from `base` (each started a second apart, from `first`), as
/// files in `dir`.
fn variants(dir: &Path, base: &Value, first: u64, n: usize, tag: &str) -> Vec<String> {
    (0..n)
        .map(|i| {
            let mut v = base.clone();
            v["method"]["started_unix_s"] = Value::from(first + i as u64);
            let name = format!("{tag}-{i}.json");
            write_json(&dir.join(&name), &v);
            name
        })
        .collect()
}

#[test]
fn concurrent_writers_all_land_and_a_killed_one_loses_nothing() {
    let dir = temp_dir("results-concurrent");
    let db = dir.join("r.db");
    let (a, _) = two_results(&dir);
    let base = json(&a);
    // Four importers and a bench at once, on a new database.
    let import = |files: &[String]| {
        tessera()
            .args(["results", "import"])
            .args(files)
            .env("TESSERA_DB", &db)
            .current_dir(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let mut children: Vec<std::process::Child> = (0..4)
        .map(|k| {
            import(&variants(
                &dir,
                &base,
                1_700_000_000 + k * 1000,
                25,
                &format!("w{k}"),
            ))
        })
        .collect();
    bench(&dir, Some(&db), "bench.json");
    for c in children.drain(..) {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    assert_eq!(listed(&dir, &db, &[]).len(), 101);
    // An importer killed mid-way: its transaction is all or nothing, and what was there
    // stays.
    let mut child = import(&variants(&dir, &base, 1_710_000_000, 2000, "k"));
    std::thread::sleep(std::time::Duration::from_millis(150));
    let _ = Command::new("kill")
        .args(["-KILL", &child.id().to_string()])
        .status();
    let _ = child.wait();
    let n = listed(&dir, &db, &[]).len();
    assert!(n == 101 || n == 2101, "{n} runs after the kill");
}

/// `base` as machine `machine` measured it at build `commit`, started at `started`, with
/// every samples/s scaled by `speed` and spread 2% either side.
fn as_if(base: &Value, machine: &str, commit: &str, started: u64, speed: f64) -> Value {
    let mut v = base.clone();
    // Measured on an idle machine, whatever this one was doing.
    v.as_object_mut().unwrap().remove("busy");
    v["host"]["machine_id"] = Value::from(machine);
    v["build"]["commit"] = Value::from(commit);
    v["method"]["started_unix_s"] = Value::from(started);
    // Each row as if its runs spread 2% either side of the median.
    let scale = |row: &mut Value| {
        let median = row["samples_per_sec"]["median"].as_f64().unwrap() * speed;
        for (key, x) in [("median", 1.0), ("min", 0.98), ("max", 1.02)] {
            row["samples_per_sec"][key] = Value::from(median * x);
        }
    };
    scale(&mut v["result"]);
    for row in v["scaling"].as_array_mut().unwrap() {
        scale(row);
    }
    v
}

#[test]
fn rank_compare_history_and_export_read_the_kept_runs() {
    let dir = temp_dir("results-analysis");
    let db = dir.join("r.db");
    let (a, _) = two_results(&dir);
    let base = json(&a);
    // Machine m-fast at twice the speed; machine m-slow over three commits, the third 30%
    // slower (beyond any spread of one run), the second 0.1% slower (within).
    let made = [
        as_if(&base, "m-fast000000000000", "aaaa", 1_700_000_000, 2.0),
        as_if(&base, "m-slow000000000000", "c1c1", 1_700_000_100, 1.0),
        as_if(&base, "m-slow000000000000", "c2c2", 1_700_000_200, 0.999),
        as_if(&base, "m-slow000000000000", "c3c3", 1_700_000_300, 0.7),
    ];
    let mut files = Vec::new();
    for (i, v) in made.iter().enumerate() {
        let name = format!("r{i}.json");
        write_json(&dir.join(&name), v);
        files.push(name);
    }
    let files: Vec<&str> = files.iter().map(String::as_str).collect();
    assert!(
        results(&dir, &db, &[&["import"][..], &files].concat())
            .status
            .success()
    );

    // A custom workload is unvalidated: ranked only with --all.
    let o = results(&dir, &db, &["rank", "--workload", "custom"]);
    assert!(stdout(&o).contains("no valid runs"), "{}", stdout(&o));
    let o = results(&dir, &db, &["rank", "--workload", "custom", "--all"]);
    let text = stdout(&o);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2 + 4, "{text}");
    assert_eq!(lines[0], "workload custom: 4 runs", "{text}");
    assert!(
        lines[2].contains("m-fast") && lines[2].trim_start().starts_with('1'),
        "{text}"
    );
    assert!(
        lines[5].contains("c3c3"),
        "the slowest build ranks last: {text}"
    );

    let o = results(&dir, &db, &["compare", "m-slow", "m-fast"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("faster, beyond the spread"), "{text}");
    // A slow portable run of c2c2, older than its newest: compare keeps each side to one
    // SIMD path (its newest run's), so it does not drag c2c2 down.
    let mut portable = as_if(&base, "m-slow000000000000", "c2c2", 1_700_000_150, 0.5);
    portable["build"]["simd"] = Value::from("portable");
    write_json(&dir.join("portable.json"), &portable);
    assert!(
        results(&dir, &db, &["import", "portable.json"])
            .status
            .success()
    );
    let o = results(&dir, &db, &["compare", "commit:c1c1", "commit:c2c2"]);
    let text = stdout(&o);
    assert!(text.contains("0.999  within the runs' spread"), "{text}");
    let path = base["build"]["simd"].as_str().unwrap();
    assert!(
        text.contains(&format!("commit:c2c2 (1 run on {path}, ")),
        "{text}"
    );
    let only_portable = [
        "compare",
        "commit:c1c1",
        "commit:c2c2",
        "--simd",
        "portable",
    ];
    let o = results(&dir, &db, &only_portable);
    assert!(
        stderr(&o).contains("no runs of that workload on SIMD path portable"),
        "{}",
        stderr(&o)
    );
    let o = results(&dir, &db, &["compare", "run:1", "nothing-like-this"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("selects no runs"), "{}", stderr(&o));

    let o = results(
        &dir,
        &db,
        &["history", "--machine", "m-slow", "--workload", "custom"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    let flagged: Vec<&str> = text.lines().filter(|l| l.contains("REGRESSION")).collect();
    assert_eq!(flagged.len(), 1, "{text}");
    assert!(flagged[0].contains("c3c3"), "{text}");
    let o = results(
        &dir,
        &db,
        &["history", "--machine", "m-", "--workload", "custom"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("matches 2 machines"), "{}", stderr(&o));

    // Export gives every result back, one per line, and importing it adds nothing.
    let o = results(&dir, &db, &["export", "--jsonl"]);
    let text = stdout(&o);
    assert_eq!(text.lines().count(), 5);
    std::fs::write(dir.join("export.jsonl"), &text).unwrap();
    let o = results(&dir, &db, &["import", "export.jsonl"]);
    assert_eq!(stdout(&o), "imported 0 new results, 5 already present\n");
}

/// The docs promise that importing an export into another database recreates its runs, but
/// `results import export.jsonl` refused the file ("not JSON: trailing characters at line 2
/// column 1"): each line had to be written to a file of its own first. A file whose first
/// line is a whole JSON value is read as JSON lines, each line a result checked as a file
/// is, a refused one named by its line, and one bad line adds nothing.
#[test]
fn an_export_imports_into_another_database_as_it_is() {
    let dir = temp_dir("results-export-imports");
    let (a, b) = two_results(&dir);
    let from = dir.join("from.db");
    let o = results(
        &dir,
        &from,
        &["import", a.to_str().unwrap(), b.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = results(&dir, &from, &["export", "--jsonl"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    std::fs::write(dir.join("export.jsonl"), &text).unwrap();

    let to = dir.join("to.db");
    let o = results(&dir, &to, &["import", "export.jsonl"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o), "imported 2 new results, 0 already present\n");
    let o = results(&dir, &to, &["export", "--jsonl"]);
    assert_eq!(
        stdout(&o),
        text,
        "the runs recreated are not the runs exported"
    );
    let o = results(&dir, &from, &["import", "export.jsonl"]);
    assert_eq!(stdout(&o), "imported 0 new results, 2 already present\n");
    // Blank lines before the first are skipped as those after it are: the file was read as
    // one result over many lines ("not JSON: trailing characters at line 3 column 1").
    std::fs::write(dir.join("blank.jsonl"), format!("\n\r\n{text}\n")).unwrap();
    let o = results(&dir, &from, &["import", "blank.jsonl"]);
    assert_eq!(
        stdout(&o),
        "imported 0 new results, 2 already present\n",
        "{}",
        stderr(&o)
    );

    // A line no result makes refuses the file, naming the line; nothing is added.
    let lines: Vec<&str> = text.lines().collect();
    let bad = format!(
        "{}\n\n{}\n{{\"schema\": \"tessera-bench/3\"}}\n",
        lines[0], lines[1]
    );
    std::fs::write(dir.join("bad.jsonl"), bad).unwrap();
    let fresh = dir.join("fresh.db");
    let o = results(&dir, &fresh, &["import", "bad.jsonl"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("bad.jsonl:4: not a valid result"),
        "{}",
        stderr(&o)
    );
    assert!(!fresh.exists() || listed(&dir, &fresh, &[]).is_empty());
    // A line longer than a result file may be is refused before it is read whole.
    let long = format!("{}\n{}\n", lines[0], " ".repeat(4 << 20));
    std::fs::write(dir.join("long.jsonl"), long).unwrap();
    let o = results(&dir, &fresh, &["import", "long.jsonl"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("long.jsonl:2: a line longer than 3072 KiB"),
        "{}",
        stderr(&o)
    );
    // So is one before the first result: 5 MiB of spaces, then a result on the same line
    // (or the next), was skipped as blank and imported, a file five times the bound.
    for (file, sep) in [("lead.json", ""), ("lead.jsonl", "\n")] {
        let lead = format!("{}{sep}{}\n", " ".repeat(5 << 20), lines[0]);
        std::fs::write(dir.join(file), lead).unwrap();
        let o = results(&dir, &fresh, &["import", file]);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", stderr(&o));
        let reason = format!("{file}:1: a line longer than 3072 KiB");
        assert!(stderr(&o).contains(&reason), "{}", stderr(&o));
        assert!(!fresh.exists() || listed(&dir, &fresh, &[]).is_empty());
    }
}

/// A result file, as `bench --out` writes it over many lines, is held to 1 MiB with the
/// blank lines before it counted, as those after it are: 5,000,000 line ends and then the
/// result (5,002,716 bytes) imported (exit 0), where the same line ends after it, and
/// `bench --compare` of the same file, were refused as larger than 1024 KiB.
#[test]
fn blank_lines_before_a_result_of_many_lines_count_toward_its_file_s_bound() {
    let dir = temp_dir("results-lead-lines");
    bench(&dir, None, "r.json");
    let result = std::fs::read_to_string(dir.join("r.json")).unwrap();
    assert!(result.lines().count() > 1, "{result}");
    let db = dir.join("r.db");
    for (file, text) in [
        ("before.json", format!("{}{result}", "\n".repeat(5_000_000))),
        ("after.json", format!("{result}{}", "\n".repeat(5_000_000))),
    ] {
        std::fs::write(dir.join(file), text).unwrap();
        let o = results(&dir, &db, &["import", file]);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", stderr(&o));
        let reason = format!("{file}: larger than 1024 KiB: not a tessera bench result");
        assert!(stderr(&o).contains(&reason), "{}", stderr(&o));
        assert!(!db.exists() || listed(&dir, &db, &[]).is_empty());
    }
    // A few blank lines before it are no reason to refuse it.
    std::fs::write(dir.join("few.json"), format!("\n \r\n{result}")).unwrap();
    let o = results(&dir, &db, &["import", "few.json"]);
    assert_eq!(
        stdout(&o),
        "imported 1 new result, 0 already present\n",
        "{}",
        stderr(&o)
    );
}

/// An export of a database without results is empty, and an import refused it ("not JSON:
/// EOF"), and with it every other file of the same import: it imports as no results.
#[test]
fn an_empty_export_imports_as_no_results() {
    let dir = temp_dir("results-export-empty");
    std::fs::write(dir.join("blank.jsonl"), "\n \r\n").unwrap();
    let empty = dir.join("empty.db");
    let o = results(&dir, &empty, &["import", "blank.jsonl"]);
    assert_eq!(
        stdout(&o),
        "imported 0 new results, 0 already present\n",
        "{}",
        stderr(&o)
    );
    let o = results(&dir, &empty, &["export", "--jsonl"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    std::fs::write(dir.join("export.jsonl"), &o.stdout).unwrap();
    let (a, _) = two_results(&dir);
    let to = dir.join("to.db");
    let o = results(&dir, &to, &["import", "export.jsonl", a.to_str().unwrap()]);
    assert_eq!(
        stdout(&o),
        "imported 1 new result, 0 already present\n",
        "{}",
        stderr(&o)
    );
}

/// An import took a result of 1,030,063 bytes (1,000 image hashes of 256 emoji each), but its
/// export, every character past ASCII a `\u` escape, was a line of 3,076,905 bytes that the
/// next import refused ("larger than 1024 KiB"): what one import takes, its export gives
/// again.
#[test]
fn an_export_of_a_result_of_any_text_an_import_took_imports_again() {
    let dir = temp_dir("results-export-escaped");
    let mut v = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    v["validation"]["status"] = "invalid".into();
    v["validation"]["images"] = (0..1000).map(|_| "\u{1F600}".repeat(256)).collect();
    let text = serde_json::to_string(&v).unwrap();
    assert!(text.len() > 1_000_000 && text.len() < 1 << 20);
    std::fs::write(dir.join("wide.json"), text).unwrap();
    let from = dir.join("from.db");
    let o = results(&dir, &from, &["import", "wide.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = results(&dir, &from, &["export", "--jsonl"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.is_ascii() && o.stdout.len() > 3_000_000);
    std::fs::write(dir.join("export.jsonl"), &o.stdout).unwrap();
    let to = dir.join("to.db");
    let o = results(&dir, &to, &["import", "export.jsonl"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o), "imported 1 new result, 0 already present\n");
}

/// The database keeps a result written again, compact, and `results export` checks what it
/// kept as an import checks a file. A result file of 1,001,976 bytes whose 200,000 runs were
/// each `1e11` was kept as 3,001,976 bytes (each run `100000000000.0`), and a line of JSON
/// lines of 1,053,620 bytes (1,024 image hashes of 256 emoji) as itself: both imported, and
/// then `results export` refused the whole database ("larger than 1024 KiB ... nothing
/// exported"). More runs than a bench keeps, and a result kept over 1 MiB, are refused.
#[test]
fn a_result_the_database_would_keep_larger_than_an_export_takes_is_refused() {
    let dir = temp_dir("results-kept-larger");
    let base = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    let mut runs = base.clone();
    runs["result"]["runs"] = vec![1e11; 100_000].into();
    runs["scaling"][0] = runs["result"].clone();
    let text = serde_json::to_string(&runs)
        .unwrap()
        .replace("100000000000.0", "1e11");
    assert!(text.len() < 1 << 20);
    std::fs::write(dir.join("runs.json"), text).unwrap();
    let mut wide = base.clone();
    wide["validation"]["status"] = "invalid".into();
    wide["validation"]["images"] = (0..1024u32)
        .map(|i| char::from_u32(0x1F000 + i).unwrap().to_string() + &"\u{1F600}".repeat(255))
        .collect();
    let line = serde_json::to_string(&wide).unwrap() + "\n";
    assert!(line.len() > 1 << 20 && line.len() < 3 << 20);
    std::fs::write(dir.join("wide.jsonl"), line).unwrap();
    for (file, reason) in [
        (
            "runs.json",
            "200000 runs, more than the 16384 a bench keeps",
        ),
        ("wide.jsonl", "wide.jsonl:1: 1053"),
    ] {
        let db = dir.join("r.db");
        let o = results(&dir, &db, &["import", file]);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", stderr(&o));
        assert!(stderr(&o).contains(reason), "{file}: {}", stderr(&o));
        assert!(!db.exists() || listed(&dir, &db, &[]).is_empty());
    }
    let o = results(&dir, &dir.join("r.db"), &["import", "wide.jsonl"]);
    assert!(
        stderr(&o).contains("as the results database keeps it, larger than 1024 KiB"),
        "{}",
        stderr(&o)
    );
}

/// `compare m-3f2a …` pooled the runs of every machine whose id begins so, and `commit:aaaa`
/// those of every such commit, under the newest one's name: a result imported from a
/// machine `m-3f2a9…` at 100 times the speed made the user's own machine "1.980 within the
/// runs' spread" of itself. A start shared by several is refused, naming them (as
/// `history --machine` refuses one); a whole id selects its own runs, a clean commit apart
/// from its `-dirty` build.
#[test]
fn a_machine_or_commit_start_shared_by_several_is_refused_by_compare() {
    let dir = temp_dir("results-shared-start");
    let db = dir.join("r.db");
    let base = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    let made = [
        as_if(&base, "m-3f2a111111111111", "aaaa1111", 1_700_000_000, 1.0),
        as_if(
            &base,
            "m-3f2a111111111111",
            "aaaa1111-dirty",
            1_700_000_050,
            1.0,
        ),
        as_if(
            &base,
            "m-3f2a999999999999",
            "aaaa9999",
            1_700_000_100,
            100.0,
        ),
    ];
    let mut files = Vec::new();
    for (i, v) in made.iter().enumerate() {
        files.push(format!("r{i}.json"));
        write_json(&dir.join(&files[i]), v);
    }
    let files: Vec<&str> = files.iter().map(String::as_str).collect();
    let o = results(&dir, &db, &[&["import"][..], &files].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    for (a, says) in [
        (
            "m-3f2a",
            "`m-3f2a` is the start of 2 machines (m-3f2a111111111111, m-3f2a999999999999)",
        ),
        ("machine:m-", "`machine:m-` is the start of 2 machines"),
        ("commit:aaaa", "`commit:aaaa` is the start of 3 commits"),
        (
            "aaaa1",
            "`aaaa1` is the start of 2 commits (aaaa1111, aaaa1111-dirty)",
        ),
    ] {
        let o = results(&dir, &db, &["compare", a, "latest"]);
        assert_eq!(o.status.code(), Some(2), "{a}: {}", stdout(&o));
        assert!(stderr(&o).contains(says), "{a}: {}", stderr(&o));
        assert!(stdout(&o).is_empty(), "{a}: {}", stdout(&o));
    }
    // Spelt out whole, or begun as only one, each names its own runs.
    for (a, b) in [
        ("m-3f2a1", "m-3f2a9"),
        ("m-3f2a111111111111", "latest"),
        ("commit:aaaa1111", "commit:aaaa1111-dirty"),
        ("aaaa1111", "aaaa9"),
    ] {
        let o = results(&dir, &db, &["compare", a, b]);
        assert!(o.status.success(), "{a} {b}: {}", stderr(&o));
    }
    let o = results(&dir, &db, &["compare", "m-3f2a1", "m-3f2a9"]);
    let text = stdout(&o);
    assert!(text.contains("m-3f2a1 (2 runs on "), "{text}");
    assert!(
        text.contains("100.000  faster, beyond the spread"),
        "{text}"
    );
}

/// `history --machine ID` took ID as a start and as part of a CPU model: a result imported
/// from a machine whose id begins with the user's (`m-3f2a111111111111x`), or whose CPU
/// model is the user's id, made the user's own machine "match 2 machines" however much of
/// its id was given, its history shown no more (and the message cut both ids to the same 18
/// characters). A whole id is that machine, as `compare` takes one; a start shared by
/// several is still refused, naming them whole.
#[test]
fn history_of_a_machine_spelt_out_whole_is_that_machine_s() {
    let dir = temp_dir("results-history-whole");
    let db = dir.join("r.db");
    let base = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    let mine = "m-3f2a111111111111";
    let mut model = as_if(&base, "m-0000000000000000", "bbbb", 1_700_000_200, 50.0);
    model["host"]["cpu_model"] = Value::from(mine);
    let made = [
        as_if(&base, mine, "aaaa", 1_700_000_000, 1.0),
        as_if(&base, "m-3f2a111111111111x", "cccc", 1_700_000_100, 50.0),
        model,
    ];
    let mut files = Vec::new();
    for (i, v) in made.iter().enumerate() {
        files.push(format!("r{i}.json"));
        write_json(&dir.join(&files[i]), v);
    }
    let files: Vec<&str> = files.iter().map(String::as_str).collect();
    let o = results(&dir, &db, &[&["import"][..], &files].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let o = results(&dir, &db, &["history", "--machine", mine]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("aaaa") && !text.contains("cccc"), "{text}");
    let o = results(&dir, &db, &["history", "--machine", "m-3f2a"]);
    assert_eq!(o.status.code(), Some(2), "{}", stdout(&o));
    let says = "matches 3 machines (m-0000000000000000, m-3f2a111111111111, m-3f2a111111111111x)";
    assert!(stderr(&o).contains(says), "{}", stderr(&o));
}

/// An empty selector (`--machine ""`, as a script's unset variable gives) is refused, not
/// taken as a prefix of every machine, commit or workload.
#[test]
fn an_empty_selector_is_refused() {
    let dir = temp_dir("results-empty-selector");
    let (db, _) = database_of_one_run(&dir);
    for args in [
        &["history", "--machine", ""][..],
        &["list", "--machine", ""],
        &["list", "--commit", ""],
        &["list", "--workload", ""],
        &["rank", "--workload", ""],
        &["history", "--workload", ""],
    ] {
        let o = results(&dir, &db, args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stdout(&o));
        let flag = args[1];
        assert!(
            stderr(&o).contains(&format!("a value is required for '{flag}")),
            "{args:?}: {}",
            stderr(&o)
        );
    }
}

/// The README's steps as a new user takes them: `bench` records the quick workload, and then
/// `results rank`, `history` and `report` with no flags show that run; two runs on
/// different SIMD paths compare by their numbers (or `latest~1 latest`).
#[test]
fn with_no_flags_results_show_the_runs_the_user_has() {
    let dir = temp_dir("results-defaults");
    let db = dir.join("r.db");
    let quick = tessera()
        .args("bench --repeat 1 --warmup 0 --no-scaling --threads 1".split(' '))
        .args(["--simd", "portable", "--out", "quick.json"])
        .env("TESSERA_DB", &db)
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(quick.status.success(), "{}", stderr(&quick));
    let o = results(&dir, &db, &["rank"]);
    let text = stdout(&o);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(text.starts_with("workload quick: 1 run\n"), "{text}");
    assert!(
        text.lines()
            .nth(2)
            .is_some_and(|l| l.trim_start().starts_with("1 ")),
        "{text}"
    );
    let o = results(&dir, &db, &["history"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let machine = json(&dir.join("quick.json"))["host"]["machine_id"]
        .as_str()
        .unwrap()
        .to_owned();
    assert!(
        stdout(&o).starts_with(&format!(
            "machine {machine}, workload quick, 1 thread, SIMD portable"
        )),
        "{}",
        stdout(&o)
    );
    let o = results(&dir, &db, &["report", "-o", "report.html"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let page = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(page.contains("Workload quick"), "{page}");
    assert_eq!(page.matches("<td class=\"n rankno\">").count(), 1, "{page}");

    // A second run on another path; the two compare by number, whatever their paths.
    let mut other = json(&dir.join("quick.json"));
    other["build"]["simd"] = Value::from("avx2");
    other["method"]["started_unix_s"] =
        Value::from(other["method"]["started_unix_s"].as_u64().unwrap() + 60);
    write_json(&dir.join("avx2.json"), &other);
    assert!(
        results(&dir, &db, &["import", "avx2.json"])
            .status
            .success()
    );
    for (a, b) in [("1", "2"), ("latest~1", "latest"), ("run:2", "run:1")] {
        let o = results(&dir, &db, &["compare", a, b]);
        assert!(o.status.success(), "compare {a} {b}: {}", stderr(&o));
        let text = stdout(&o);
        assert!(
            text.contains("run on portable") && text.contains("run on avx2"),
            "{text}"
        );
    }
    let o = results(&dir, &db, &["compare", "latest~2", "latest"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("the database holds 2 runs"),
        "{}",
        stderr(&o)
    );
    // A busy run is marked as such.
    let mut busy = json(&dir.join("quick.json"));
    busy["method"]["started_unix_s"] =
        Value::from(busy["method"]["started_unix_s"].as_u64().unwrap() + 120);
    busy["busy"] = serde_json::json!({
        "busy": true,
        "reasons": ["other processes kept 1.70 of its 2 CPUs busy while it ran"],
        "others_cpus": 1.7,
        "steal": 0.0
    });
    write_json(&dir.join("busy.json"), &busy);
    assert!(
        results(&dir, &db, &["import", "busy.json"])
            .status
            .success()
    );
    assert!(listed(&dir, &db, &["--limit", "1"])[0].contains("valid (busy)"));
}

/// A result's "busy" record is checked like the rest of a stranger's file.
#[test]
fn a_busy_record_that_no_run_makes_is_refused() {
    let dir = temp_dir("results-busy-hostile");
    let db = dir.join("r.db");
    let (a, _) = two_results(&dir);
    let base = json(&a);
    for (name, busy) in [
        (
            "nan",
            serde_json::json!({"busy": true, "reasons": [], "others_cpus": -1.0, "steal": 0.0}),
        ),
        (
            "long",
            serde_json::json!({"busy": true, "reasons": ["x".repeat(5000)], "others_cpus": 1.0, "steal": 0.0}),
        ),
        (
            "many",
            serde_json::json!({"busy": true, "reasons": vec!["r"; 100], "others_cpus": 1.0, "steal": 0.0}),
        ),
        (
            "steal",
            serde_json::json!({"busy": true, "reasons": ["r"], "others_cpus": 1.0, "steal": 2.0}),
        ),
        (
            "field",
            serde_json::json!({"busy": false, "reasons": [], "others_cpus": 0.0, "steal": 0.0, "x": 1}),
        ),
    ] {
        let mut v = base.clone();
        v["busy"] = busy;
        write_json(&dir.join(format!("{name}.json")), &v);
        let o = results(&dir, &db, &["import", &format!("{name}.json")]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("{name}.json")),
            "{name}: {}",
            stderr(&o)
        );
    }
}

#[test]
fn a_result_of_the_first_schema_imports_on_the_same_machine() {
    let dir = temp_dir("results-schema-1");
    let db = dir.join("r.db");
    let (a, _) = two_results(&dir);
    let now = json(&a);
    // What tessera-bench/1 wrote: no machine id, SMT, clocks or SIMD reason.
    let mut old = now.clone();
    old["schema"] = Value::from("tessera-bench/1");
    old["method"]["started_unix_s"] = Value::from(1_700_000_000u64);
    for field in ["machine_id", "smt", "cpu_base_mhz", "cpu_max_mhz"] {
        old["host"].as_object_mut().unwrap().remove(field);
    }
    old["build"].as_object_mut().unwrap().remove("simd_reason");
    write_json(&dir.join("old.json"), &old);
    let o = results(&dir, &db, &["import", "old.json", a.to_str().unwrap()]);
    assert_eq!(
        stdout(&o),
        "imported 2 new results, 0 already present\n",
        "{}",
        stderr(&o)
    );
    // The old result's machine id comes from the same facts: one machine.
    let machine = now["host"]["machine_id"].as_str().unwrap();
    assert_eq!(listed(&dir, &db, &["--machine", machine]).len(), 2);
}

/// A new database on a disk with too little room for it: at every amount of room, the import
/// either lands or fails with exit 2, and a failure leaves nothing behind (no temporary name,
/// no -wal or -shm file, no published file without its schema).
#[test]
fn a_new_database_on_a_nearly_full_disk_is_made_whole_or_not_at_all() {
    let test = "a_new_database_on_a_nearly_full_disk_is_made_whole_or_not_at_all";
    let dir = temp_dir("results-nearly-full");
    let (a, _) = two_results(&dir);
    let tessera = env!("CARGO_BIN_EXE_tessera");
    // The same 256 KiB file system, refilled for each amount of room left, 0 to 120 KiB.
    let script = format!(
        "for free in 0 8 16 24 32 40 48 56 64 72 80 88 96 104 112 120; do \
           rm -rf small/* small/.[!.]*; head -c $((256 - free))K /dev/zero > small/filler 2>/dev/null; \
           TESSERA_DB=small/r.db {tessera} results import '{a}' >/dev/null 2>small.err; rc=$?; \
           left=$(ls -A small | tr '\\n' ' '); \
           [ $rc = 0 ] && TESSERA_DB=small/r.db {tessera} results list >/dev/null 2>>small.err; \
           echo \"$free $rc $? $left| $(head -c 200 small.err)\"; \
         done",
        a = a.display()
    );
    let Some(o) = in_a_small_filesystem(&dir, 256, &script) else {
        return skip(
            test,
            "this machine cannot make a private filesystem (unshare -rm)",
        );
    };
    let out = stdout(&o);
    let (mut landed, mut failed) = (0, 0);
    for line in out.lines() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let (rc, listed) = (fields[1], fields[2]);
        let left = line.split_once("| ").map_or("", |(l, _)| l);
        let files: Vec<&str> = left.split_whitespace().skip(3).collect();
        match rc {
            "0" => {
                landed += 1;
                assert_eq!(listed, "0", "{line}: the new database does not list");
                assert_eq!(files, ["filler", "r.db"], "{line}");
            }
            "2" => {
                failed += 1;
                assert_eq!(files, ["filler"], "{line}: something was left behind");
                assert!(line.contains("disk"), "{line}: the reason is not the disk");
            }
            _ => panic!("{line}: neither landed nor refused"),
        }
    }
    assert!(landed > 0 && failed > 0, "{out}{}", stderr(&o));
}

/// A first import that fails to add its results (a file size limit, `ulimit -f`, as a full
/// disk) leaves no database: one was made and published empty before the rows were added,
/// and stayed, of no runs. The new database is filled before it is published. At each
/// limit, from room for the empty database but not the result (a result of 240 KB) to room
/// for both, the import lands whole or fails leaving nothing.
#[test]
fn a_first_import_that_fails_leaves_no_empty_database() {
    let dir = temp_dir("results-first-import-fails");
    let mut v = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    v["validation"]["status"] = "invalid".into();
    v["validation"]["images"] = (0..1000).map(|i| format!("{i:04}").repeat(60)).collect();
    write_json(&dir.join("big.json"), &v);
    let (mut landed, mut failed) = (0, 0);
    for blocks in [64, 96, 128, 192, 256, 4096] {
        let sub = dir.join(format!("f{blocks}"));
        std::fs::create_dir_all(&sub).unwrap();
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "ulimit -f {blocks} && exec '{}' results import ../big.json",
                env!("CARGO_BIN_EXE_tessera")
            ))
            .env("TESSERA_DB", sub.join("r.db"))
            .current_dir(&sub)
            .output()
            .unwrap();
        let left: Vec<String> = (std::fs::read_dir(&sub).unwrap())
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        match o.status.code() {
            Some(0) => {
                landed += 1;
                assert_eq!(listed(&sub, &sub.join("r.db"), &[]).len(), 1, "{blocks}");
            }
            Some(2) => {
                failed += 1;
                assert!(
                    left.is_empty(),
                    "ulimit -f {blocks}: a failed first import left {left:?}: {}",
                    stderr(&o)
                );
            }
            _ => panic!(
                "ulimit -f {blocks}: neither landed nor refused: {}",
                stderr(&o)
            ),
        }
    }
    assert!(landed > 0 && failed > 0, "landed {landed}, failed {failed}");
}

#[test]
fn a_full_or_read_only_disk_is_an_error_that_keeps_what_was_there() {
    let test = "a_full_or_read_only_disk_is_an_error_that_keeps_what_was_there";
    let dir = temp_dir("results-disk");
    let (a, _) = two_results(&dir);
    let base = json(&a);
    // Enough results to outgrow 256 KiB: their JSON is kept whole.
    let many = variants(&dir, &base, 1_720_000_000, 200, "m").join(" ");
    let tessera = env!("CARGO_BIN_EXE_tessera");
    let script = format!(
        "export TESSERA_DB=small/r.db; {tessera} results import a.json && {tessera} results import {many}; echo \"full=$?\"; \
         {tessera} results list | tail -n +2 | wc -l; \
         mount -o remount,ro small && {tessera} results import b.json; echo \"ro=$?\"; \
         {tessera} results list | tail -n +2 | wc -l"
    );
    let Some(o) = in_a_small_filesystem(&dir, 256, &script) else {
        return skip(
            test,
            "this machine cannot make a private filesystem (unshare -rm)",
        );
    };
    let (out, err) = (stdout(&o), stderr(&o));
    let lines: Vec<&str> = (out.lines())
        .filter(|l| !l.starts_with("imported"))
        .collect();
    assert_eq!(lines.first(), Some(&"full=2"), "{out}{err}");
    assert!(err.contains("disk is full"), "{err}");
    assert_eq!(
        lines.get(1).map(|l| l.trim()),
        Some("1"),
        "the first import was lost: {out}"
    );
    assert_eq!(lines.get(2), Some(&"ro=2"), "{out}{err}");
    assert!(err.contains("read-only"), "{err}");
    assert_eq!(lines.get(3).map(|l| l.trim()), Some("1"), "{out}");
    assert!(!err.contains("panicked"), "{err}");
}

/// A database on a read-only file system reads (`list`, `export`), though SQLite cannot make
/// the -shm file a WAL database needs: it is read as an immutable file, which it is there.
/// A database of the first schema, which cannot be brought up to date there, reads as it
/// is. Nothing is written: the file system keeps the same files, byte for byte.
#[test]
fn a_database_on_a_read_only_file_system_reads() {
    let test = "a_database_on_a_read_only_file_system_reads";
    let dir = temp_dir("results-read-only");
    let (a, b) = two_results(&dir);
    // A first-schema database as tessera 0.1.0 left it: in WAL mode, closed.
    let legacy = dir.join("legacy.db");
    first_schema_database(&dir, &legacy, true);
    assert_eq!(bytes(&legacy)[18..20], [2, 2], "not in WAL mode");
    let tessera = env!("CARGO_BIN_EXE_tessera");
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());
    let script = format!(
        "export TESSERA_DB=small/r.db; {tessera} results import {a} >/dev/null || exit 10; \
         cp legacy.db small/legacy.db || exit 11; \
         ls -lA --time-style=full-iso small > before.ls; cp small/r.db before.db; \
         mount -o remount,ro small || exit 12; \
         {tessera} results list > list.out; echo \"list=$?\"; \
         {tessera} results export --jsonl > export.out; echo \"export=$?\"; \
         {tessera} results --db small/legacy.db list > legacy.out; echo \"legacy=$?\"; \
         {tessera} results import {b}; echo \"import=$?\"; \
         ls -lA --time-style=full-iso small > after.ls; \
         cmp -s small/r.db before.db; echo \"same=$?\"; cmp -s small/legacy.db legacy.db; \
         echo \"legacy-same=$?\""
    );
    let Some(o) = in_a_small_filesystem(&dir, 1024, &script) else {
        return skip(
            test,
            "this machine cannot make a private filesystem (unshare -rm)",
        );
    };
    let (out, err) = (stdout(&o), stderr(&o));
    assert!(o.status.success(), "{out}{err}");
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap();
    for want in [
        "list=0",
        "export=0",
        "legacy=0",
        "import=2",
        "same=0",
        "legacy-same=0",
    ] {
        assert!(out.lines().any(|l| l == want), "no {want}: {out}{err}");
    }
    assert_eq!(read("list.out").lines().count(), 2, "{}", read("list.out"));
    assert_eq!(read("export.out").lines().count(), 1);
    assert!(
        read("legacy.out").contains("Old CPU"),
        "{}",
        read("legacy.out")
    );
    assert!(err.contains("read-only"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        read("before.ls"),
        read("after.ls"),
        "the file system changed"
    );
}

/// SQLite reads a -wal file's pages in place of the database's (and writes them into it at
/// the next checkpoint), and a -wal file is valid by its own checksums alone. In a directory
/// others may write to, another user left `r.db-wal`, made from a database of their own,
/// beside a database of this user's that they cannot read: `list` showed their machine and
/// CPU (`m-evil`) as run 1's, exit 0. A -wal, -shm or -journal file of another user's is
/// refused now, naming it, and the database is left as it was. Changing a file's owner needs
/// root: elsewhere the test is skipped.
#[test]
fn another_user_s_wal_file_beside_the_database_is_refused() {
    let dir = temp_dir("results-strangers-wal");
    let (db, _) = database_of_one_run(&dir);
    // Their database: a copy, changed in a transaction left in its WAL.
    let theirs = dir.join("theirs.db");
    std::fs::copy(&db, &theirs).unwrap();
    let conn = rusqlite::Connection::open(&theirs).unwrap();
    conn.pragma_update(None, "wal_autocheckpoint", 0).unwrap();
    conn.execute("UPDATE runs SET machine_id = 'm-evil'", [])
        .unwrap();
    let wal = dir.join("r.db-wal");
    std::fs::copy(dir.join("theirs.db-wal"), &wal).unwrap();
    drop(conn);
    if std::os::unix::fs::chown(&wal, Some(65534), Some(65534)).is_err() {
        return skip(
            "another_user_s_wal_file_beside_the_database_is_refused",
            "changing a file's owner needs root",
        );
    }
    let before = bytes(&db);
    for args in [&["list"][..], &["import", "quick.json"]] {
        let o = results(&dir, &db, args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("r.db-wal: belongs to another user (uid 65534"),
            "{args:?}: {err}"
        );
        assert!(!stdout(&o).contains("m-evil"), "{args:?}");
    }
    // Through a link to the database, whose -wal SQLite names after the file the link
    // leads to: the -wal beside the link's name (none) was looked at, and `list` showed
    // `m-evil`.
    let link = dir.join("link.db");
    std::os::unix::fs::symlink("r.db", &link).unwrap();
    for args in [&["list"][..], &["import", "quick.json"]] {
        let o = results(&dir, &link, args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "link {args:?}: {err}");
        assert!(
            err.contains("r.db-wal: belongs to another user (uid 65534"),
            "link {args:?}: {err}"
        );
        assert!(!stdout(&o).contains("m-evil"), "link {args:?}");
    }
    assert_eq!(bytes(&db), before);
    // The user's own -wal file is theirs to keep.
    std::fs::remove_file(&wal).unwrap();
    let o = results(&dir, &db, &["list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stdout(&o).contains("m-evil"));
}

/// A database another user left under the name `--db` gives, readable and writable by all
/// (mode 666 in a shared directory), took this user's runs: `import` said "imported 1 new
/// result" into their file, where they read this user's machine and results and chose the
/// runs beside them. Writing to another user's database is refused (exit 2), the file left
/// as it was and no -wal or -shm file made; reading it still works. Changing a file's owner
/// needs root: elsewhere the test is skipped.
#[test]
fn another_user_s_database_is_read_but_never_written() {
    let dir = temp_dir("results-strangers-db");
    let (db, v) = database_of_one_run(&dir);
    let mine = as_if(&v, "m-mine000000000000", "abcd", 1_700_000_000, 1.0);
    write_json(&dir.join("mine.json"), &mine);
    std::fs::set_permissions(&db, std::fs::Permissions::from_mode(0o666)).unwrap();
    if std::os::unix::fs::chown(&db, Some(65534), Some(65534)).is_err() {
        return skip(
            "another_user_s_database_is_read_but_never_written",
            "changing a file's owner needs root",
        );
    }
    let before = bytes(&db);
    let o = results(&dir, &db, &["import", "mine.json"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}{}", stdout(&o));
    assert!(
        err.contains("r.db: belongs to another user (uid 65534"),
        "{err}"
    );
    assert_eq!(bytes(&db), before);
    for companion in ["r.db-wal", "r.db-shm"] {
        assert!(!dir.join(companion).exists(), "{companion}");
    }
    assert_eq!(listed(&dir, &db, &[]).len(), 1);
    // The same file, this user's again, takes the run (root's read made its -wal and -shm
    // files as SQLite makes them, the database owner's).
    let me = std::fs::metadata("/proc/self").map(|m| std::os::unix::fs::MetadataExt::uid(&m));
    let me = me.ok();
    for name in ["r.db", "r.db-wal", "r.db-shm"] {
        let _ = std::os::unix::fs::chown(dir.join(name), me, None);
    }
    let o = results(&dir, &db, &["import", "mine.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(listed(&dir, &db, &[]).len(), 2);
}

/// Reading a database SQLite keeps in WAL mode makes its -wal and -shm files where they
/// are missing, even on a read-only connection, and a -wal of another user's beside a
/// database is refused: one `results list` by mallory of alice's database, readable by
/// all in a sticky shared directory, left his -wal and -shm there, and alice's every
/// command was refused ("lab.db-wal: belongs to another user"), the files hers to remove
/// only by root. Another user's database is now read as an immutable file where no -wal
/// holds changes, and nothing is made beside it; one whose -wal holds changes without a
/// -shm is refused, left as it is. Changing a file's owner needs root: elsewhere the test
/// is skipped.
#[test]
fn reading_another_user_s_database_leaves_nothing_beside_it() {
    let dir = temp_dir("results-strangers-read");
    let (db, _) = database_of_one_run(&dir);
    // Changes kept in a -wal file, as a writer that has not yet checkpointed leaves them.
    let conn = rusqlite::Connection::open(&db).unwrap();
    conn.pragma_update(None, "wal_autocheckpoint", 0).unwrap();
    conn.execute(
        "UPDATE runs SET cpu_model = 'In the WAL',
            result = json_set(result, '$.host.cpu_model', 'In the WAL')",
        [],
    )
    .unwrap();
    redigest(&conn);
    std::fs::copy(dir.join("r.db-wal"), dir.join("kept-wal")).unwrap();
    drop(conn);
    std::fs::set_permissions(&db, std::fs::Permissions::from_mode(0o644)).unwrap();
    if std::os::unix::fs::chown(&db, Some(65534), Some(65534)).is_err() {
        return skip(
            "reading_another_user_s_database_leaves_nothing_beside_it",
            "changing a file's owner needs root",
        );
    }
    let before = bytes(&db);
    let o = results(&dir, &db, &["list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("In the WAL"), "{}", stdout(&o));
    for companion in ["r.db-wal", "r.db-shm"] {
        assert!(!dir.join(companion).exists(), "{companion} made by a read");
    }
    std::fs::copy(dir.join("kept-wal"), dir.join("r.db-wal")).unwrap();
    std::os::unix::fs::chown(dir.join("r.db-wal"), Some(65534), Some(65534)).unwrap();
    let o = results(&dir, &db, &["list"]);
    assert_eq!(o.status.code(), Some(2), "{}", stdout(&o));
    assert!(
        stderr(&o).contains("holds changes but has no -shm"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("r.db-shm").exists());
    assert_eq!(bytes(&db), before);
}

/// `bench --out F` with F the database it records in (`--db F`, `TESSERA_DB=F`, or a link to
/// it), and `results report -o F` on database F, replaced the database with the JSON result
/// or the page (exit 0, "recorded in same.db"): every earlier run was lost, and the next
/// command said "not an SQLite database". `-o r.db-wal` replaced its write-ahead log, and
/// with it the runs not yet checkpointed into the database. All are refused now, the
/// database left as it was.
#[test]
fn an_output_naming_the_database_is_refused() {
    let dir = temp_dir("results-output-is-db");
    let (db, _) = database_of_one_run(&dir);
    std::os::unix::fs::symlink("r.db", dir.join("link.db")).unwrap();
    let before = bytes(&db);
    for (name, what) in [
        ("r.db", "names the results database"),
        ("link.db", "names the results database"),
        ("./r.db", "names the results database"),
        ("r.db-wal", "names the results database's wal file"),
        ("./r.db-shm", "names the results database's shm file"),
        ("r.db-journal", "names the results database's journal file"),
    ] {
        let o = results(&dir, &db, &["report", "-o", name]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(what), "{name}: {}", stderr(&o));
        let mut c = tessera();
        c.args(["bench", &cover()])
            .args("--width 8 --spp 1 --repeat 1 --warmup 0 --no-scaling".split(' '))
            .args(["--out", name])
            .env("TESSERA_DB", &db)
            .current_dir(&dir);
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(what), "{name}: {}", stderr(&o));
        assert_eq!(bytes(&db), before, "{name}");
        assert!(name.ends_with("db") || !dir.join(name).exists(), "{name}");
    }
    // Named through a link, the database's -wal lies beside the link's target, where SQLite
    // puts it: `-o r.db-wal` with TESSERA_DB=link.db was written.
    let o = results(&dir, &dir.join("link.db"), &["report", "-o", "r.db-wal"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the results database's wal file"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("r.db-wal").exists());
    let o = results(&dir, &db, &["list"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A database made elsewhere may hold text longer than any import takes (256 characters):
/// a machine id of 50,001 made `history` fail with SQLite's "could not read it: LIKE or
/// GLOB pattern too complex", and a CPU model of 100 MB was carried into every table. Each
/// reader refuses such a run, naming it and the column (exit 2).
#[test]
fn a_database_whose_text_no_import_takes_is_refused_naming_the_run_and_column() {
    let dir = temp_dir("results-long-text");
    let v = json(&root().join("fuzz/corpus/result/quick-scaling.json"));
    write_json(&dir.join("q.json"), &v);
    for column in ["machine_id", "cpu_model", "commit_id"] {
        let db = dir.join(format!("{column}.db"));
        let o = results(&dir, &db, &["import", "q.json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let conn = rusqlite::Connection::open(&db).unwrap();
        let sql = format!("UPDATE runs SET {column} = 'm-' || hex(zeroblob(25000)) || 'a'");
        conn.execute(&sql, []).unwrap();
        drop(conn);
        for args in [&["history"][..], &["list"], &["rank"]] {
            let o = results_within_a_minute(&dir, &db, args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{column} {args:?}: {err}");
            assert!(
                err.contains(&format!(
                    "{column}.db: run 1: {column} is longer than 256 characters"
                )),
                "{column} {args:?}: {err}"
            );
        }
    }
}

/// `results ARGS` on `db` with its address space capped at `mib` MiB (`ulimit -v`): a
/// command that reads what a database holds before it checks its length runs out there,
/// where a large machine would only slow down.
fn results_capped(dir: &Path, db: &Path, args: &[&str], mib: u64) -> Output {
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {}; exec '{}' results {}",
            mib << 10,
            env!("CARGO_BIN_EXE_tessera"),
            quoted.join(" ")
        ))
        .env("TESSERA_DB", db)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// A database whose one result held 300 MB of text: `results export` read every result
/// whole, and built the export whole, before it checked any, and refused it as larger than
/// 1024 KiB after 1.77 GB and 11 s. A result's length is read first, from its record, and
/// one longer than any import keeps is refused unread, naming the run; the export is
/// written a result at a time, after every result is checked, so a bad result after good
/// ones still writes nothing. Here 40 MB, in 128 MiB of address space: "out of memory"
/// before.
#[test]
fn a_result_longer_than_any_import_keeps_is_refused_unread() {
    let dir = temp_dir("results-long-result");
    let (db, _) = database_of_one_run(&dir);
    let conn = rusqlite::Connection::open(&db).unwrap();
    conn.execute("UPDATE runs SET result = hex(zeroblob(20000000))", [])
        .unwrap();
    drop(conn);
    let o = results_capped(&dir, &db, &["export", "--jsonl"], 128);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("r.db: run 1: result is 40000000 bytes, more than any result tessera keeps"),
        "{err}"
    );
    assert!(o.stdout.is_empty());

    // A good result, then one that is not JSON: nothing is written.
    let two = dir.join("two.db");
    let v = json(&root().join("fuzz/corpus/result/quick-scaling.json"));
    write_json(&dir.join("q.json"), &v);
    let o = results(&dir, &two, &["import", "quick.json", "q.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = results(&dir, &two, &["export", "--jsonl"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 2);
    let conn = rusqlite::Connection::open(&two).unwrap();
    conn.execute(
        "UPDATE runs SET result = '{not json' WHERE id =
         (SELECT id FROM runs ORDER BY started_unix_s DESC, id DESC LIMIT 1)",
        [],
    )
    .unwrap();
    drop(conn);
    let o = results(&dir, &two, &["export", "--jsonl"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("result 2 (oldest first) is not one line of JSON"),
        "{}",
        stderr(&o)
    );
    assert!(o.stdout.is_empty(), "{}", stdout(&o));
}

/// A run's text column of 300 MB (a CPU model, a machine id) took 1.2 GB, four times its
/// length, before `list` or `rank` refused it as longer than 256 characters: the text, its
/// copy, and for `--machine` SQLite's `lower` of it. Each text's length is read first, from
/// its record, and one longer than any import takes is refused unread, whatever the filter.
/// Here 40 MB, in 128 MiB of address space: "out of memory" before.
#[test]
fn a_run_s_text_longer_than_any_import_takes_is_refused_unread() {
    let dir = temp_dir("results-long-text-unread");
    let (db, _) = database_of_one_run(&dir);
    for column in ["cpu_model", "machine_id", "workload"] {
        let long = dir.join(format!("{column}.db"));
        std::fs::copy(&db, &long).unwrap();
        let conn = rusqlite::Connection::open(&long).unwrap();
        let sql = format!("UPDATE runs SET {column} = hex(zeroblob(20000000))");
        conn.execute(&sql, []).unwrap();
        drop(conn);
        for args in [
            &["list"][..],
            &["list", "--machine", "epyc"],
            &["list", "--workload", "quick"],
            &["rank"],
            &["history"],
        ] {
            let o = results_capped(&dir, &long, args, 128);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{column} {args:?}: {err}");
            assert!(
                err.contains(&format!(
                    "{column}.db: run 1: {column} is longer than 256 characters"
                )),
                "{column} {args:?}: {err}"
            );
        }
    }
}

/// `results import` gathered every result of its files, and then each one's JSON, before
/// it added any: 100 MB of results of 1,024 one-letter image hashes each took 1.1 GB, and a
/// file may hold a million results (and an import names any number of files). Each result
/// is added as it is read now, in the import's one transaction, so memory follows one
/// result. Here 4,000 such results (24 MB) in 128 MiB of address space, which held about
/// 280 MB of them before ("out of memory"); and a bad line after them still adds nothing.
#[test]
fn an_import_keeps_one_result_at_a_time_in_memory() {
    let dir = temp_dir("results-import-memory");
    let db = dir.join("r.db");
    let base = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    let started = base["method"]["started_unix_s"].as_u64().unwrap();
    // 4,000 results, the first `first` seconds before the corpus's.
    let results_from = |first: u64| {
        let mut lines = String::new();
        for i in first..first + 4_000 {
            let mut v = base.clone();
            v["method"]["started_unix_s"] = Value::from(started - i);
            v["validation"]["status"] = "invalid".into();
            v["validation"]["images"] = vec![Value::from("a"); 1024].into();
            lines.push_str(&serde_json::to_string(&v).unwrap());
            lines.push('\n');
        }
        lines
    };
    std::fs::write(dir.join("many.jsonl"), results_from(0)).unwrap();
    let o = results_capped(&dir, &db, &["import", "many.jsonl"], 128);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o), "imported 4000 new results, 0 already present\n");
    let o = results(&dir, &db, &["import", "many.jsonl"]);
    assert_eq!(stdout(&o), "imported 0 new results, 4000 already present\n");

    // 4,000 others, then a line that is no result: nothing is added, and a first import of
    // them makes no database.
    std::fs::write(
        dir.join("bad.jsonl"),
        format!("{}{{}}\n", results_from(10_000)),
    )
    .unwrap();
    for target in [&db, &dir.join("new.db")] {
        let o = results(&dir, target, &["import", "many.jsonl", "bad.jsonl"]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("bad.jsonl:4001"), "{}", stderr(&o));
    }
    assert!(
        !dir.join("new.db").exists(),
        "a refused import made a database"
    );
    let o = results(&dir, &db, &["export", "--jsonl"]);
    assert_eq!(stdout(&o).lines().count(), 4000, "a bad file let others in");
}

/// A database of the user's own that they may not write (made read-only, `chmod a-w`, to
/// keep it as it is) was read through a -shm file SQLite made with the database's mode,
/// read-only, and left beside it: once the database was writable again, every import was
/// refused ("attempt to write a readonly database") until the -shm was removed by hand. In a
/// directory the user may not write to, where SQLite cannot make one, `results list` was
/// refused so. Both are read as immutable files now, nothing made beside them. Another
/// user (65534) is needed, as root writes every file: elsewhere the test is skipped.
#[test]
fn a_database_of_one_s_own_that_cannot_be_written_reads_and_leaves_nothing_behind() {
    use std::os::unix::process::CommandExt;
    let test = "a_database_of_one_s_own_that_cannot_be_written_reads_and_leaves_nothing_behind";
    let dir = temp_dir("results-own-read-only");
    let (db, _) = database_of_one_run(&dir);
    std::fs::copy(
        root().join("fuzz/corpus/result/quick-scaling.json"),
        dir.join("scaling.json"),
    )
    .unwrap();
    if std::os::unix::fs::chown(&db, Some(65534), Some(65534)).is_err() {
        return skip(test, "changing a file's owner needs root");
    }
    let binary = binary_for_others(&dir);
    let mode = |path: &Path, mode: u32| {
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
    };
    mode(&dir, 0o777);
    mode(&dir.join("scaling.json"), 0o644);
    let as_its_owner = |args: &[&str]| {
        output_within_a_minute(
            Command::new(&binary)
                .arg("results")
                .args(args)
                .env("TESSERA_DB", &db)
                .current_dir(&dir)
                .uid(65534)
                .gid(65534),
            "results, as the database's owner",
        )
    };
    let nothing_beside = |when: &str| {
        for companion in ["r.db-wal", "r.db-shm"] {
            assert!(!dir.join(companion).exists(), "{companion} made by {when}");
        }
    };
    mode(&db, 0o444);
    let o = as_its_owner(&["list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 2, "{}", stdout(&o));
    nothing_beside("a read of a read-only database");
    mode(&db, 0o644);
    let o = as_its_owner(&["import", "scaling.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Closed by its writer: its -wal and -shm are gone with it.
    nothing_beside("an import");
    mode(&dir, 0o755);
    let o = as_its_owner(&["list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 3, "{}", stdout(&o));
    nothing_beside("a read in a read-only directory");
}

/// A result's number far out of range was quoted in full: a rays per sample of 1e300 in a
/// message of 422 bytes, 301 of them its digits. It is shown as 1e300 now.
#[test]
fn a_number_far_out_of_range_is_quoted_short() {
    let dir = temp_dir("results-far-numbers");
    let db = dir.join("r.db");
    let base = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    type Edit = fn(&mut Value);
    let cases: [(&str, Edit, &str); 2] = [
        (
            "many-rays",
            |v| v["result"]["rays_per_sample"] = Value::from(1e300),
            "rays per sample is 1e300, more than any run makes",
        ),
        (
            "time-before-time",
            |v| v["result"]["wall_s"]["min"] = Value::from(-1e300),
            "wall time is -1e300, not a positive number",
        ),
    ];
    for (name, edit, reason) in cases {
        let mut v = base.clone();
        edit(&mut v);
        write_json(&dir.join(format!("{name}.json")), &v);
        let o = results(&dir, &db, &["import", &format!("{name}.json")]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(reason), "{name}: {}", stderr(&o));
        assert!(stderr(&o).len() < 200, "{name}: {}", stderr(&o));
    }
}

/// A result saved with a byte order mark before it (as some editors save text) was refused
/// as "not JSON: expected value at line 1 column 1", which names nothing there to fix. The
/// mark is named now, in a file and in a line of JSON lines, and nothing is added.
#[test]
fn a_result_after_a_byte_order_mark_is_refused_naming_it() {
    let dir = temp_dir("results-bom");
    let db = dir.join("r.db");
    let v = json(&root().join("fuzz/corpus/result/quick-one-thread.json"));
    let text = serde_json::to_string(&v).unwrap();
    std::fs::write(dir.join("bom.json"), format!("\u{feff}{text}")).unwrap();
    std::fs::write(dir.join("bom.jsonl"), format!("\u{feff}{text}\n")).unwrap();
    for name in ["bom.json", "bom.jsonl"] {
        let o = results(&dir, &db, &["import", name]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("starts with a byte order mark (EF BB BF)"),
            "{name}: {}",
            stderr(&o)
        );
        assert!(stderr(&o).contains(name), "{name}: {}", stderr(&o));
    }
    assert!(!db.exists() || listed(&dir, &db, &[]).is_empty());
}

/// A copy of tessera in `dir`, where another user may run it. A test beside this one that
/// starts a process while the copy is open to write hands it the copy's descriptor, and the
/// copy cannot run ("text file busy") until that process has run its own program: it is
/// tried until it runs.
fn binary_for_others(dir: &Path) -> PathBuf {
    let binary = dir.join("tessera");
    std::fs::copy(env!("CARGO_BIN_EXE_tessera"), &binary).unwrap();
    for tries in 1.. {
        match Command::new(&binary).arg("--version").output() {
            Err(e) if e.raw_os_error() == Some(26) && tries < 100 => {
                std::thread::sleep(std::time::Duration::from_millis(50));
            }
            ran => {
                ran.unwrap();
                break;
            }
        }
    }
    binary
}

/// Another user's database, readable by all, whose -wal and -shm files (its owner's, made
/// with a umask of 077) this user may not read, was refused as "the database or its
/// directory is read-only (unable to open database file)", which it is not. The file this
/// user may not read is named now, and nothing is made beside it. Two other users (65533
/// and 65534) are needed: elsewhere the test is skipped.
#[test]
fn another_user_s_database_whose_wal_this_user_may_not_read_says_so() {
    use std::os::unix::process::CommandExt;
    let test = "another_user_s_database_whose_wal_this_user_may_not_read_says_so";
    let dir = temp_dir("results-strangers-wal-unread");
    let (db, _) = database_of_one_run(&dir);
    // Held open, as its owner's process in use holds it: its -wal and -shm are there.
    let conn = rusqlite::Connection::open(&db).unwrap();
    conn.query_row("SELECT count(*) FROM runs", [], |r| r.get::<_, i64>(0))
        .unwrap();
    for name in ["r.db", "r.db-wal", "r.db-shm"] {
        let path = dir.join(name);
        if std::os::unix::fs::chown(&path, Some(65533), Some(65533)).is_err() {
            return skip(test, "changing a file's owner needs root");
        }
        let mode = if name == "r.db" { 0o644 } else { 0o600 };
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
    }
    let binary = binary_for_others(&dir);
    let o = output_within_a_minute(
        Command::new(&binary)
            .args(["results", "list"])
            .env("TESSERA_DB", &db)
            .current_dir(&dir)
            .uid(65534)
            .gid(65534),
        "results list, as another user",
    );
    assert_eq!(o.status.code(), Some(2), "{}", stdout(&o));
    assert!(
        stderr(&o).contains(
            "r.db: another user's database (uid 65533) whose -wal file this user may not read"
        ),
        "{}",
        stderr(&o)
    );
    assert!(!stderr(&o).contains("read-only"), "{}", stderr(&o));
    drop(conn);
}
