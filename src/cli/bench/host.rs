//! The context of a benchmark result: the build (version, commit, compiler, SIMD path) and
//! the host (CPU, cores, memory, OS, kernel, load, and the container and CPU limit it ran
//! under), read from `/proc`, `/sys` and `/etc` on Linux; what cannot be read is left empty
//! rather than guessed.

use super::confinement::{self, read_file};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use tessera::simd;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Build {
    pub version: String,
    pub commit: String,
    pub rustc: String,
    pub target: String,
    pub profile: String,
    /// The SIMD path the renders took.
    pub simd: String,
    /// Every SIMD path this CPU runs.
    pub simd_supported: Vec<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Host {
    pub cpu_model: Option<String>,
    /// The machine's online CPUs.
    pub logical_cpus: usize,
    /// The CPUs this process may use: the default thread count, which follows a container's
    /// CPU limit and the affinity (`std::thread::available_parallelism`). Absent (0) in
    /// results from before it was recorded.
    #[serde(default)]
    pub cpus_usable: usize,
    /// The container runtime the run was in, where one was recognised.
    #[serde(default)]
    pub container: Option<String>,
    /// The CPUs the cgroup's quota allowed (quota ÷ period, e.g. `--cpus=1.5`); absent
    /// without a quota.
    #[serde(default)]
    pub cpu_quota: Option<f64>,
    /// The CPUs the affinity allowed, when fewer than the machine's (`--cpuset-cpus`,
    /// `taskset`, a Slurm cgroup).
    #[serde(default)]
    pub cpus_allowed: Option<usize>,
    pub physical_cores: Option<usize>,
    pub memory_bytes: Option<u64>,
    pub os: Option<String>,
    pub kernel: Option<String>,
    /// The 1, 5 and 15 minute load averages when the benchmark started.
    pub load_average: Option<[f64; 3]>,
}

impl Build {
    pub fn this(path: simd::Path) -> Self {
        Self {
            version: env!("CARGO_PKG_VERSION").into(),
            commit: env!("TESSERA_GIT_COMMIT").into(),
            rustc: env!("TESSERA_RUSTC_VERSION").into(),
            target: env!("TESSERA_TARGET").into(),
            profile: env!("TESSERA_PROFILE").into(),
            simd: path.name().into(),
            simd_supported: simd::Path::supported()
                .iter()
                .map(|p| p.name().into())
                .collect(),
        }
    }
}

/// The value of `key` in a `key : value` listing such as /proc/cpuinfo.
fn field<'a>(line: &'a str, key: &str) -> Option<&'a str> {
    let (k, v) = line.split_once(':')?;
    (k.trim() == key).then(|| v.trim())
}

impl Host {
    pub fn this() -> Self {
        let cpuinfo = read_file("/proc/cpuinfo").unwrap_or_default();
        let cpu_model = cpuinfo
            .lines()
            .find_map(|l| field(l, "model name"))
            .map(str::to_owned);
        // Distinct (package, core) pairs; absent on some architectures and VMs.
        let mut cores = BTreeSet::new();
        let mut package = None;
        for line in cpuinfo.lines() {
            if let Some(v) = field(line, "physical id") {
                package = Some(v.to_owned());
            }
            if let Some(v) = field(line, "core id") {
                cores.insert((package.clone(), v.to_owned()));
            }
        }
        let memory_bytes = read_file("/proc/meminfo").and_then(|m| {
            let kb = m.lines().find_map(|l| field(l, "MemTotal"))?;
            Some(kb.trim_end_matches("kB").trim().parse::<u64>().ok()? * 1024)
        });
        let os = read_file("/etc/os-release").and_then(|t| {
            let line = t.lines().find(|l| l.starts_with("PRETTY_NAME="))?;
            Some(line["PRETTY_NAME=".len()..].trim_matches('"').to_owned())
        });
        let kernel = read_file("/proc/sys/kernel/osrelease").map(|k| format!("Linux {}", k.trim()));
        let load_average = read_file("/proc/loadavg").and_then(|t| {
            let v: Vec<f64> = t
                .split_whitespace()
                .take(3)
                .filter_map(|x| x.parse().ok())
                .collect();
            Some([*v.first()?, *v.get(1)?, *v.get(2)?])
        });
        let cpus_usable = std::thread::available_parallelism().map_or(1, |n| n.get());
        let logical_cpus = confinement::online_cpus(&read_file).unwrap_or(cpus_usable);
        let var = |name: &str| std::env::var(name).ok();
        Self {
            cpu_model,
            logical_cpus,
            cpus_usable,
            container: confinement::container(&read_file, &var),
            cpu_quota: confinement::cpu_quota(&read_file),
            cpus_allowed: confinement::allowed_cpus(&read_file).filter(|&n| n < logical_cpus),
            physical_cores: (!cores.is_empty()).then_some(cores.len()),
            memory_bytes,
            os: os.or_else(|| Some(std::env::consts::OS.to_owned())),
            kernel,
            load_average,
        }
    }
}
