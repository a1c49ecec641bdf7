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
    /// Why that path: `auto`'s rule with the CPU's vendor and family, or chosen by
    /// `--simd`. Absent in results before it was recorded.
    #[serde(default)]
    pub simd_reason: Option<String>,
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
    /// Names the machine without naming a person: a hash of its CPU model, CPU and core
    /// counts and memory (see `machine_id`). Absent in `tessera-bench/1` results, which get
    /// the same hash of the same facts when read (`Report::machine_id`).
    #[serde(default)]
    pub machine_id: Option<String>,
    /// Whether simultaneous multithreading (Hyper-Threading) is on.
    #[serde(default)]
    pub smt: Option<bool>,
    /// The CPU's base clock (cpufreq's base_frequency, or an Intel model name's "@ 2.60GHz").
    #[serde(default)]
    pub cpu_base_mhz: Option<f64>,
    /// The CPU's highest clock (cpufreq's cpuinfo_max_freq).
    #[serde(default)]
    pub cpu_max_mhz: Option<f64>,
}

impl Build {
    pub fn this(path: simd::Path, chosen: bool) -> Self {
        let cpu = simd::cpu_identity().unwrap_or_else(|| std::env::consts::ARCH.into());
        let simd_reason = if chosen {
            format!("chosen with --simd or TESSERA_SIMD on {cpu}")
        } else {
            format!("auto on {cpu}: {}", simd::Path::auto().1)
        };
        Self {
            version: env!("CARGO_PKG_VERSION").into(),
            commit: env!("TESSERA_GIT_COMMIT").into(),
            rustc: env!("TESSERA_RUSTC_VERSION").into(),
            target: env!("TESSERA_TARGET").into(),
            profile: env!("TESSERA_PROFILE").into(),
            simd: path.name().into(),
            simd_reason: Some(simd_reason),
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
        let physical_cores = (!cores.is_empty()).then_some(cores.len());
        let smt = read_file("/sys/devices/system/cpu/smt/active")
            .and_then(|t| match t.trim() {
                "1" => Some(true),
                "0" => Some(false),
                _ => None,
            })
            .or_else(|| physical_cores.map(|c| logical_cpus > c));
        let khz = |path: &str| {
            let khz: f64 = read_file(path)?.trim().parse().ok()?;
            (khz.is_finite() && khz > 0.0).then_some(khz / 1000.0)
        };
        let cpu_base_mhz =
            khz("/sys/devices/system/cpu/cpu0/cpufreq/base_frequency").or_else(|| {
                cpu_model
                    .as_deref()
                    .and_then(model_name_ghz)
                    .map(|g| g * 1000.0)
            });
        let cpu_max_mhz = khz("/sys/devices/system/cpu/cpu0/cpufreq/cpuinfo_max_freq");
        let machine_id = machine_id(&Facts {
            cpu_model: cpu_model.as_deref(),
            logical_cpus,
            physical_cores,
            memory_bytes,
        });
        Self {
            machine_id: Some(machine_id),
            smt,
            cpu_base_mhz,
            cpu_max_mhz,
            cpu_model,
            logical_cpus,
            cpus_usable,
            container: confinement::container(&read_file, &var),
            cpu_quota: confinement::cpu_quota(&read_file),
            cpus_allowed: confinement::allowed_cpus(&read_file).filter(|&n| n < logical_cpus),
            physical_cores,
            memory_bytes,
            os: os.or_else(|| Some(std::env::consts::OS.to_owned())),
            kernel,
            load_average,
        }
    }
}

/// The clock an Intel model name states: "… CPU @ 2.60GHz" is 2.6.
fn model_name_ghz(model: &str) -> Option<f64> {
    let (_, after) = model.rsplit_once('@')?;
    let ghz: f64 = after.trim().strip_suffix("GHz")?.trim().parse().ok()?;
    (ghz.is_finite() && ghz > 0.0 && ghz < 100.0).then_some(ghz)
}

/// What identifies a machine where it has no machine id.
pub struct Facts<'a> {
    pub cpu_model: Option<&'a str>,
    pub logical_cpus: usize,
    pub physical_cores: Option<usize>,
    pub memory_bytes: Option<u64>,
}

/// A machine's id: `m-` and 16 hex digits of a hash of its hardware facts (memory in whole
/// GiB, as the kernel reports a little more or less from boot to boot). The facts, not
/// /etc/machine-id, so that the same machine has the same id in a container (which has no
/// machine id), after a reinstall, and in `tessera-bench/1` results (which lack the field);
/// machines of one model, CPU count and memory size share it, as one kind of machine.
pub fn machine_id(facts: &Facts) -> String {
    let text = format!(
        "tessera machine\0{}\0{}\0{:?}\0{:?}",
        facts.cpu_model.unwrap_or(""),
        facts.logical_cpus,
        facts.physical_cores,
        facts.memory_bytes.map(|b| (b + (1 << 29)) >> 30)
    );
    format!("m-{:016x}", xxhash_rust::xxh3::xxh3_64(text.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intel_model_names_give_their_base_clock() {
        let xeon = "Intel(R) Xeon(R) Platinum 8375C CPU @ 2.90GHz";
        assert_eq!(model_name_ghz(xeon), Some(2.9));
        assert_eq!(model_name_ghz("AMD EPYC 9R45 96-Core Processor"), None);
        assert_eq!(model_name_ghz("weird @ lots GHz"), None);
        assert_eq!(model_name_ghz("@ 1e99GHz"), None);
    }

    #[test]
    fn machine_ids_hash_the_hardware_to_the_gib() {
        let facts = Facts {
            cpu_model: Some("AMD EPYC"),
            logical_cpus: 2,
            physical_cores: Some(2),
            memory_bytes: Some(24 << 30),
        };
        let a = machine_id(&facts);
        assert!(a.starts_with("m-") && a.len() == 18, "{a}");
        let slightly_less = Facts {
            memory_bytes: Some((24 << 30) - (40 << 20)),
            ..facts
        };
        assert_eq!(a, machine_id(&slightly_less));
        let more_cpus = Facts {
            logical_cpus: 4,
            ..slightly_less
        };
        assert_ne!(a, machine_id(&more_cpus));
    }
}
