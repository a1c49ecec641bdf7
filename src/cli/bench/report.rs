//! A benchmark result as JSON (schema `tessera-bench/1`, documented in docs/benchmark-json.md): its
//! context, measurements and validation; reading results back, and comparing two.

use super::host::{Build, Host};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::io::Read;
use std::path::Path;

/// The schema this build writes and reads.
pub const SCHEMA: &str = "tessera-bench/1";
/// The largest result file read: real ones are a few kilobytes.
const MAX_FILE: u64 = 16 << 20;

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Report {
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

impl Report {
    /// Reads a result file, refusing anything that is not a result of this schema.
    pub fn read(path: &Path) -> Result<Self> {
        let what = || format!("{}", path.display());
        let file =
            std::fs::File::open(path).with_context(|| format!("could not open {}", what()))?;
        let mut text = String::new();
        file.take(MAX_FILE + 1)
            .read_to_string(&mut text)
            .with_context(|| format!("could not read {} (is it a JSON text file?)", what()))?;
        if text.len() as u64 > MAX_FILE {
            bail!(
                "{}: larger than {} MiB: not a tessera bench result",
                what(),
                MAX_FILE >> 20
            );
        }
        let value: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| anyhow::anyhow!("{}: not JSON: {e}", what()))?;
        match value.get("schema").and_then(|s| s.as_str()) {
            Some(SCHEMA) => {}
            Some(other) => bail!(
                "{}: schema `{other}`, this tessera reads `{SCHEMA}`",
                what()
            ),
            None => bail!("{}: not a tessera bench result (no `schema` field)", what()),
        }
        serde_json::from_value(value)
            .map_err(|e| anyhow::anyhow!("{}: not a valid `{SCHEMA}` result: {e}", what()))
    }

    /// A short label: workload, CPU, SIMD path and commit.
    pub fn label(&self) -> String {
        let commit: String = self.build.commit.chars().take(8).collect();
        format!(
            "{} · {} · {} · {commit}",
            self.workload.name,
            self.host.cpu_model.as_deref().unwrap_or("unknown CPU"),
            self.build.simd
        )
    }
}

/// `new` against `old`, thread count by thread count: the ratio of medians, and whether it
/// lies within the runs' own spread (the two min–max ranges overlap) or beyond it.
pub fn compare(old: &Report, new: &Report) -> Result<String> {
    if old.workload.id != new.workload.id {
        bail!(
            "the results measure different workloads ({} {} and {} {}): their speeds do not compare",
            old.workload.name,
            old.workload.id,
            new.workload.name,
            new.workload.id
        );
    }
    let mut text = format!(
        "workload {} ({}x{}, {} spp; {})\nold: {}\nnew: {}\n",
        new.workload.name,
        new.workload.width,
        new.workload.height,
        new.workload.spp,
        new.workload.id,
        old.label(),
        new.label()
    );
    for (which, r) in [("old", old), ("new", new)] {
        if r.validation.status != "valid" {
            text.push_str(&format!(
                "warning: the {which} result is {}\n",
                r.validation.status
            ));
        }
    }
    text.push_str("threads  old M samples/s [min-max]  new M samples/s [min-max]  new/old\n");
    let mut shared = 0;
    for n in &new.scaling {
        let Some(o) = old.scaling.iter().find(|o| o.threads == n.threads) else {
            continue;
        };
        shared += 1;
        let (a, b) = (o.samples_per_sec, n.samples_per_sec);
        let ratio = b.median / a.median;
        let verdict = if b.min <= a.max && a.min <= b.max {
            "within the runs' spread"
        } else if ratio > 1.0 {
            "faster, beyond the spread"
        } else {
            "slower, beyond the spread"
        };
        let cell = |s: Spread| {
            format!(
                "{:.3} [{:.3}-{:.3}]",
                s.median / 1e6,
                s.min / 1e6,
                s.max / 1e6
            )
        };
        text.push_str(&format!(
            "{:>7}  {:<25}  {:<25}  {ratio:.3}  {verdict}\n",
            n.threads,
            cell(a),
            cell(b)
        ));
    }
    if shared == 0 {
        bail!("the results share no thread count");
    }
    Ok(text)
}
