//! A benchmark result as JSON (schema `tessera-bench/3`, documented in docs/benchmark-json.md):
//! its context, measurements and validation, and reading results back (from a stranger's
//! machine as much as our own: sizes, types and values are checked).

use super::host::{Build, Busy, Host};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::io::{BufRead, Read};
use std::path::Path;

/// The schema this build writes.
pub const SCHEMA: &str = "tessera-bench/3";
/// The schemas this build reads: `/1` lacks the host's machine id, clocks and SMT state,
/// `/2` whether the machine was busy.
pub const READS: [&str; 3] = ["tessera-bench/1", "tessera-bench/2", SCHEMA];
/// The largest result file read: real ones are a few kilobytes.
pub const MAX_FILE: u64 = 1 << 20;
/// The longest line of JSON lines read: a result of `MAX_FILE` bytes as `results export
/// --jsonl` writes it, every character past ASCII a `\u` escape (at most three times as
/// long: four bytes of UTF-8 become a pair of six), so what one import took the next takes.
pub const MAX_LINE: u64 = 3 * MAX_FILE;
/// The most results one file of JSON lines (`results export --jsonl`) may hold: a lab's
/// database of a million runs.
pub const MAX_LINES: usize = 1 << 20;
/// The most runs a bench keeps in its result, the headline's counted twice (its row is in
/// `scaling` too): each run's rate takes at most 31 bytes of the JSON, so a result of as
/// many stays within `MAX_FILE`, and its import (and an export of it) reads it.
pub const MAX_RUNS: usize = 1 << 14;
/// The most rows a result's scaling table may hold: a bench measures a few thread counts
/// (powers of two up to the machine's CPUs, and its headline), far fewer than 64.
pub const MAX_SCALING_ROWS: usize = 64;
/// The longest text field accepted (a CPU model, a commit, a scene name).
pub const MAX_TEXT: usize = 256;
/// The most threads a result may claim; more is no machine's.
pub const MAX_THREADS: usize = 1 << 16;
/// The fastest rate a result may claim, in samples (or million rays) a second: a thousand
/// times the quick workload on 65,536 of today's cores. A rate near the largest number
/// ranked first everywhere, and once drew an axis without end in the report.
pub const MAX_SAMPLES_PER_SEC: f64 = 1e12;
/// The longest a result's run may claim to have taken, in seconds: a year.
const MAX_WALL_SECONDS: f64 = 3.2e7;
/// The slowest rate a result may claim, in samples a second: one sample in the longest run.
/// A rate of the smallest numbers a double holds (5e-324) reads as 0 in M samples/s, and
/// drew `NaN%` and `inf%` into the report's efficiency table.
pub const MIN_SAMPLES_PER_SEC: f64 = 1.0 / MAX_WALL_SECONDS;
/// The slowest in million rays a second: the slowest rate, a ray a sample.
const MIN_MRAYS_PER_SEC: f64 = MIN_SAMPLES_PER_SEC / 1e6;
/// The largest of the other measures (rays per sample, speedups, efficiencies).
const MAX_MEASURE: f64 = 1e9;

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchResult {
    pub schema: String,
    pub build: Build,
    pub host: Host,
    pub workload: WorkloadInfo,
    pub method: Method,
    /// The measurement at `method.threads`.
    pub result: Row,
    /// One row per thread count measured, fewest first (the headline's alone with
    /// `--no-scaling`).
    pub scaling: Vec<Row>,
    pub validation: Validation,
    /// Whether the machine was busy while the renders ran: what loaded it, and how much.
    /// Absent in results before it was recorded (`tessera-bench/1` and `/2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub busy: Option<Busy>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WorkloadInfo {
    /// A standard workload's name, or `custom`.
    pub name: String,
    pub scene: String,
    /// Hash of the scene text and settings: results of equal ids measured the same work.
    pub id: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Method {
    /// Threads of the headline result.
    pub threads: usize,
    /// Measured renders per thread count.
    pub repeat: u32,
    /// Renders before measuring, not counted.
    pub warmup: u32,
    /// When the benchmark started, in seconds since the Unix epoch.
    pub started_unix_s: u64,
}

/// The median, least and greatest of a measurement's runs.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spread {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Spread {
    pub fn of(values: &[f64]) -> Self {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = match n {
            0 => f64::NAN,
            _ if n % 2 == 1 => v[n / 2],
            _ => (v[n / 2 - 1] + v[n / 2]) / 2.0,
        };
        Self {
            median,
            min: v.first().copied().unwrap_or(f64::NAN),
            max: v.last().copied().unwrap_or(f64::NAN),
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Row {
    pub threads: usize,
    pub samples_per_sec: Spread,
    pub mrays_per_sec: Spread,
    pub wall_s: Spread,
    pub rays_per_sample: f64,
    /// Median samples/s over the one-thread median, when one thread was measured.
    pub speedup: Option<f64>,
    /// `speedup / threads`.
    pub efficiency: Option<f64>,
    /// Each run's samples/s, in the order run.
    pub runs: Vec<f64>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Validation {
    /// `valid`: every render's image hash is the expected one; `invalid`: some is not;
    /// `unvalidated`: a custom workload, with no expected hash.
    pub status: String,
    pub expected: Option<String>,
    /// The distinct image hashes the renders produced (one, unless something is wrong).
    pub images: Vec<String>,
}

/// The earliest time a run may be dated: 2020-01-01. tessera did not exist before.
const EARLIEST_RUN: u64 = 1_577_836_800;

/// The latest time a run kept in a database may be dated, whatever the reader's clock says:
/// 2100-01-01. A run dated later is absurd on any clock (one of the year 292277026596 stayed
/// the newest of every later run); one dated after the reader's clock is not: a database
/// recorded by a clock that ran ahead, or read on one that is behind.
pub const LATEST_KEPT_RUN: u64 = 4_102_444_800;

/// Now, by this machine's clock, in seconds since 1970.
fn now_unix_s() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(u64::MAX, |d| d.as_secs())
}

/// Whether `unix_s` is a time a run took place: from 2020-01-01 to a day from now. tessera
/// did not exist before, and clocks drift.
pub fn is_run_time(unix_s: u64) -> bool {
    (EARLIEST_RUN..=now_unix_s().saturating_add(86_400)).contains(&unix_s)
}

/// Whether `unix_s` is a time a run kept in a database may be dated, to be read: from
/// 2020-01-01 to `LATEST_KEPT_RUN` (or a day from now, on a clock past it). The import
/// held it to a day past its own clock; holding it so again on reading refused every
/// command on a whole database, its owner's too, wherever the reader's clock was over a
/// day behind the one that recorded a run.
pub fn is_kept_run_time(unix_s: u64) -> bool {
    let latest = LATEST_KEPT_RUN.max(now_unix_s().saturating_add(86_400));
    (EARLIEST_RUN..=latest).contains(&unix_s)
}

impl BenchResult {
    /// Reads a result file, refusing anything that is not a sound result of a schema this
    /// build reads.
    pub fn read(path: &Path) -> Result<Self> {
        let what = path.display().to_string();
        let file = crate::input_file::open_regular(path)
            .with_context(|| format!("could not open {what}"))?;
        let mut bytes = Vec::new();
        file.take(MAX_FILE + 1)
            .read_to_end(&mut bytes)
            .with_context(|| format!("could not read {what}"))?;
        Self::parse(&bytes, &what)
    }

    /// Reads a result file, or a file of JSON lines, one result a line, as `results export
    /// --jsonl` writes (a file whose first line is a whole JSON value), refusing the whole
    /// file where one result of it is refused, naming its line (`FILE:N`). The lines are read
    /// one at a time, each of at most `MAX_LINE` bytes, and each result is handed to `each`
    /// as it is read, so memory follows one result, not the file: an import that collected
    /// every result of a file first took 1.1 GB for 100 MB of results of 1,024 one-letter
    /// image hashes each. A file of blank lines, or none, holds no results.
    pub fn read_each(path: &Path, mut each: impl FnMut(Self) -> Result<()>) -> Result<()> {
        let what = path.display().to_string();
        let file = crate::input_file::open_regular(path)
            .with_context(|| format!("could not open {what}"))?;
        let mut reader = std::io::BufReader::new(file);
        let mut line = Vec::new();
        let read_line = |reader: &mut std::io::BufReader<std::fs::File>, line: &mut Vec<u8>| {
            line.clear();
            reader
                .by_ref()
                .take(MAX_LINE + 1)
                .read_until(b'\n', line)
                .with_context(|| format!("could not read {what}"))
        };
        // Blank lines are skipped before the first as after it (a file of JSON lines that
        // begins with one is still JSON lines), and held to a line's bound as those are.
        let too_long = |line: &[u8], n: usize| {
            if line.len() as u64 > MAX_LINE {
                bail!(
                    "{what}:{n}: a line longer than {} KiB: not a tessera bench result",
                    MAX_LINE >> 10
                );
            }
            Ok(())
        };
        let (mut first, mut blank) = (1, 0u64);
        while read_line(&mut reader, &mut line)? > 0 && line.iter().all(u8::is_ascii_whitespace) {
            too_long(&line, first)?;
            first += 1;
            blank += line.len() as u64;
        }
        // An export of a database without results is empty: it imports as no results, so
        // an import of it beside others is not refused whole.
        if line.is_empty() {
            return Ok(());
        }
        let one_value = |line: &[u8]| {
            line.len() as u64 <= MAX_LINE
                && serde_json::from_slice::<serde::de::IgnoredAny>(line).is_ok()
        };
        if !one_value(&line) {
            // One result, as `bench --out` writes it, over many lines: a file of at most
            // `MAX_FILE` bytes, the blank lines before it counted, as those after it are
            // (and as `read` counts them).
            let mut bytes = std::mem::take(&mut line);
            let left = (MAX_FILE + 1).saturating_sub(blank + bytes.len() as u64);
            (reader.take(left).read_to_end(&mut bytes))
                .with_context(|| format!("could not read {what}"))?;
            if blank + bytes.len() as u64 > MAX_FILE {
                bail!(
                    "{what}: larger than {} KiB: not a tessera bench result",
                    MAX_FILE >> 10
                );
            }
            return each(Self::parse(&bytes, &what)?);
        }
        let mut results = 0;
        for n in first.. {
            if n > first && read_line(&mut reader, &mut line)? == 0 {
                break;
            }
            too_long(&line, n)?;
            let at = format!("{what}:{n}");
            if line.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            if results == MAX_LINES {
                bail!("{at}: more than {MAX_LINES} results in one file");
            }
            results += 1;
            each(Self::parse_within(&line, &at, MAX_LINE, is_run_time)?)?;
        }
        Ok(())
    }

    /// A result from the bytes of a file named `what`.
    pub fn parse(bytes: &[u8], what: &str) -> Result<Self> {
        Self::parse_within(bytes, what, MAX_FILE, is_run_time)
    }

    /// A result kept in a database, from its bytes (`what` names it), as `parse` reads a
    /// file's, but dated as a database's runs are read (`is_kept_run_time`): an export of
    /// runs recorded by a clock ahead of this one's is that database's, not refused.
    pub fn parse_kept(bytes: &[u8], what: &str) -> Result<Self> {
        Self::parse_within(bytes, what, MAX_FILE, is_kept_run_time)
    }

    /// A result from at most `most` bytes of a file named `what`, dated within `run_time`.
    fn parse_within(
        bytes: &[u8],
        what: &str,
        most: u64,
        run_time: fn(u64) -> bool,
    ) -> Result<Self> {
        if bytes.len() as u64 > most {
            bail!(
                "{what}: larger than {} KiB: not a tessera bench result",
                most >> 10
            );
        }
        let text = std::str::from_utf8(bytes)
            .map_err(|_| anyhow::anyhow!("{what}: not UTF-8 text: not a tessera bench result"))?;
        // A byte order mark, which an editor may save before the text, is no JSON: said so,
        // where serde_json said only "expected value at line 1 column 1".
        if text.starts_with('\u{feff}') {
            bail!(
                "{what}: starts with a byte order mark (EF BB BF), which JSON does not have: \
                 not read (save it without one)"
            );
        }
        // serde_json refuses nesting deeper than 128 before it could exhaust the stack; a
        // key given twice in one object is refused (`UniqueKeys`), not its last value kept.
        let value = match serde_json::from_str::<super::unique_json::UniqueKeys>(text) {
            Ok(value) => value.0,
            Err(e) if e.classify() == serde_json::error::Category::Data => bail!("{what}: {e}"),
            Err(e) => bail!("{what}: not JSON: {e}"),
        };
        match value.get("schema").and_then(|s| s.as_str()) {
            Some(s) if READS.contains(&s) => {}
            Some(other) => bail!(
                "{what}: schema `{}`: this tessera reads {} (a newer tessera wrote it?)",
                other.escape_debug().take(64).collect::<String>(),
                READS.join(" and ")
            ),
            None => bail!("{what}: not a tessera bench result (no `schema` field)"),
        }
        let report: BenchResult = serde_json::from_value(value)
            .map_err(|e| anyhow::anyhow!("{what}: not a valid result: {e}"))?;
        report
            .check_dated(run_time)
            .map_err(|why| anyhow::anyhow!("{what}: not a sound result: {why}"))?;
        // The database keeps the result written again, compact, and an export checks what it
        // kept as a file: it is held to a file's bound too. Its numbers may take more bytes
        // than the file's (`1e11` is kept as `100000000000.0`), and a line of JSON lines, up
        // to three times a file, may hold a result of more bytes than a file.
        let kept = serde_json::to_vec(&report).map_or(u64::MAX, |json| json.len() as u64);
        if kept > MAX_FILE {
            bail!(
                "{what}: {kept} bytes as the results database keeps it, larger than {} KiB: \
                 not a tessera bench result",
                MAX_FILE >> 10
            );
        }
        Ok(report)
    }

    /// Refuses what no real run produces: absurd counts, times and speeds, overlong text,
    /// a headline missing from its table, a validation that contradicts itself.
    pub fn check(&self) -> Result<(), String> {
        self.check_dated(is_run_time)
    }

    /// `check`, with a start time within `run_time`.
    fn check_dated(&self, run_time: fn(u64) -> bool) -> Result<(), String> {
        let texts = [
            ("build.version", Some(&self.build.version)),
            ("build.commit", Some(&self.build.commit)),
            ("build.rustc", Some(&self.build.rustc)),
            ("build.target", Some(&self.build.target)),
            ("build.profile", Some(&self.build.profile)),
            ("build.simd", Some(&self.build.simd)),
            ("build.simd_reason", self.build.simd_reason.as_ref()),
            ("host.cpu_model", self.host.cpu_model.as_ref()),
            ("host.os", self.host.os.as_ref()),
            ("host.kernel", self.host.kernel.as_ref()),
            ("host.container", self.host.container.as_ref()),
            ("host.machine_id", self.host.machine_id.as_ref()),
            ("workload.name", Some(&self.workload.name)),
            ("workload.scene", Some(&self.workload.scene)),
            ("workload.id", Some(&self.workload.id)),
            ("validation.status", Some(&self.validation.status)),
            ("validation.expected", self.validation.expected.as_ref()),
        ];
        for (name, text) in texts {
            if text.is_some_and(|t| t.chars().count() > MAX_TEXT) {
                return Err(format!("{name} is longer than {MAX_TEXT} characters"));
            }
        }
        if self.build.simd_supported.len() > 16 || self.validation.images.len() > 1024 {
            return Err("a list is longer than any run makes".into());
        }
        // The texts in lists too: 1,024 image hashes of a kilobyte each passed, every one
        // kept in the database.
        let listed = [
            ("build.simd_supported", &self.build.simd_supported),
            ("validation.images", &self.validation.images),
        ];
        for (name, list) in listed {
            if list.iter().any(|t| t.chars().count() > MAX_TEXT) {
                return Err(format!(
                    "{name} holds a text longer than {MAX_TEXT} characters"
                ));
            }
        }
        let count = |name: &str, n: usize, max: usize| {
            if (1..=max).contains(&n) {
                Ok(())
            } else {
                Err(format!("{name} is {n}, not 1 to {max}"))
            }
        };
        count("host.logical_cpus", self.host.logical_cpus, MAX_THREADS)?;
        count("method.threads", self.method.threads, MAX_THREADS)?;
        count("method.repeat", self.method.repeat as usize, 1_000_000)?;
        count("workload.width", self.workload.width as usize, 1 << 16)?;
        count("workload.height", self.workload.height as usize, 1 << 16)?;
        count("workload.spp", self.workload.spp as usize, 1 << 24)?;
        count("scaling rows", self.scaling.len(), MAX_SCALING_ROWS)?;
        if let Some(busy) = &self.busy {
            check_busy(busy)?;
        }
        let runs: usize = (self.scaling.iter().chain([&self.result]))
            .map(|row| row.runs.len())
            .sum();
        if runs > MAX_RUNS {
            return Err(format!(
                "{runs} runs, more than the {MAX_RUNS} a bench keeps in a result"
            ));
        }
        for row in self.scaling.iter().chain([&self.result]) {
            count("a row's threads", row.threads, MAX_THREADS)?;
            let at_least = |name: &str, x: f64, least: f64, most: f64| {
                if !(x.is_finite() && x > 0.0) {
                    Err(format!(
                        "{} threads: {name} is {}, not a positive number",
                        row.threads,
                        shown_number(x)
                    ))
                } else if x < least {
                    Err(format!(
                        "{} threads: {name} is {x:e}, less than any run makes (at least {least:e})",
                        row.threads
                    ))
                } else if x > most {
                    Err(format!(
                        "{} threads: {name} is {x:e}, more than any run makes (at most {most:e})",
                        row.threads
                    ))
                } else {
                    Ok(())
                }
            };
            let positive = |name: &str, x: f64| at_least(name, x, 0.0, MAX_MEASURE);
            for (name, s, least, most) in [
                (
                    "samples/s",
                    row.samples_per_sec,
                    MIN_SAMPLES_PER_SEC,
                    MAX_SAMPLES_PER_SEC,
                ),
                (
                    "Mrays/s",
                    row.mrays_per_sec,
                    MIN_MRAYS_PER_SEC,
                    MAX_SAMPLES_PER_SEC,
                ),
                ("wall time", row.wall_s, 0.0, MAX_WALL_SECONDS),
            ] {
                at_least(name, s.min, least, most)?;
                at_least(name, s.median, least, most)?;
                at_least(name, s.max, least, most)?;
                if !(s.min <= s.median && s.median <= s.max) {
                    return Err(format!(
                        "{} threads: {name}'s min, median and max are out of order",
                        row.threads
                    ));
                }
            }
            positive("rays per sample", row.rays_per_sample)?;
            for &x in &row.runs {
                at_least(
                    "a run's samples/s",
                    x,
                    MIN_SAMPLES_PER_SEC,
                    MAX_SAMPLES_PER_SEC,
                )?;
            }
            for x in row.speedup.into_iter().chain(row.efficiency) {
                positive("a speedup or efficiency", x)?;
            }
        }
        if !self
            .scaling
            .iter()
            .any(|r| r.threads == self.result.threads)
            || self.result.threads != self.method.threads
        {
            return Err("the headline's thread count is not in the scaling table".into());
        }
        // A bench measures each thread count once, and its headline is that count's row:
        // `rank` reads the headline and `compare` the rows, so a headline of its own, or a
        // count twice, would show one run two ways.
        let mut counts: Vec<usize> = self.scaling.iter().map(|r| r.threads).collect();
        counts.sort_unstable();
        if let Some(w) = counts.windows(2).find(|w| w[0] == w[1]) {
            return Err(format!("the scaling table has {} threads twice", w[0]));
        }
        let row = |r: &Row| serde_json::to_value(r).ok();
        if (self.scaling.iter())
            .find(|r| r.threads == self.result.threads)
            .map(row)
            != Some(row(&self.result))
        {
            return Err(format!(
                "the headline is not the scaling table's row of {} threads",
                self.result.threads
            ));
        }
        let v = &self.validation;
        let consistent = match v.status.as_str() {
            "valid" => {
                v.expected.is_some()
                    && v.images.len() == 1
                    && v.images.first() == v.expected.as_ref()
            }
            "invalid" => {
                v.expected.is_some()
                    && (v.images.len() != 1 || v.images.first() != v.expected.as_ref())
            }
            "unvalidated" => v.expected.is_none(),
            _ => false,
        };
        if !consistent {
            return Err(format!(
                "validation `{}` does not agree with its image hashes",
                v.status.escape_debug()
            ));
        }
        let started = self.method.started_unix_s;
        if !run_time(started) {
            return Err(format!(
                "method.started_unix_s {started} is not a time a run took place"
            ));
        }
        Ok(())
    }

    /// The machine that ran it: the result's own id, or for a `tessera-bench/1` result, the
    /// one its hardware facts give.
    #[cfg_attr(not(feature = "results"), allow(dead_code))]
    pub fn machine_id(&self) -> String {
        self.host.machine_id.clone().unwrap_or_else(|| {
            let h = &self.host;
            super::host::machine_id(&super::host::Facts {
                cpu_model: h.cpu_model.as_deref(),
                logical_cpus: h.logical_cpus,
                physical_cores: h.physical_cores,
                memory_bytes: h.memory_bytes,
            })
        })
    }

    /// A short label: workload, CPU, SIMD path and commit.
    pub fn label(&self) -> String {
        let commit = super::host::short_commit(&self.build.commit, 8);
        format!(
            "{} · {} · {} · {commit}",
            self.workload.name,
            self.host.cpu_model.as_deref().unwrap_or("unknown CPU"),
            self.build.simd
        )
    }
}

/// Refuses a record of a busy machine that no run makes.
fn check_busy(busy: &Busy) -> Result<(), String> {
    if busy.reasons.len() > 8 {
        return Err("busy.reasons: more reasons than a run gives".into());
    }
    if busy.reasons.iter().any(|r| r.chars().count() > MAX_TEXT) {
        return Err(format!(
            "busy.reasons: a reason longer than {MAX_TEXT} characters"
        ));
    }
    if busy.busy == busy.reasons.is_empty() {
        return Err("busy.busy does not agree with its reasons".into());
    }
    if let Some(cpus) = busy.others_cpus
        && !(cpus.is_finite() && (0.0..=MAX_THREADS as f64).contains(&cpus))
    {
        return Err(format!(
            "busy.others_cpus is {}, not 0 to {MAX_THREADS}",
            shown_number(cpus)
        ));
    }
    if let Some(steal) = busy.steal
        && !(steal.is_finite() && (0.0..=1.0).contains(&steal))
    {
        return Err(format!(
            "busy.steal is {}, not a share from 0 to 1",
            shown_number(steal)
        ));
    }
    Ok(())
}

/// `x` as a message about a result shows it: in exponent form where its digits would run
/// long, as `{}` writes 1e300 in 301 of them.
fn shown_number(x: f64) -> String {
    if x.is_finite() && x != 0.0 && !(1e-6..1e16).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}
