//! The context of a benchmark result: the build (version, commit, compiler, SIMD path) and
//! the host (CPU, cores, memory, OS, kernel, load, and the container and CPU limit it ran
//! under), read from `/proc`, `/sys` and `/etc` on Linux; what cannot be read is left empty
//! rather than guessed.

use crate::confinement::{self, read_file};
use crate::simd;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
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
#[serde(deny_unknown_fields)]
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
    /// the same hash of the same facts when read (`BenchResult::machine_id`).
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

/// The first `digits` of a commit, keeping its `-dirty` mark: `9e648ea3-dirty`.
pub fn short_commit(commit: &str, digits: usize) -> String {
    let (hash, dirty) = match commit.strip_suffix("-dirty") {
        Some(hash) => (hash, "-dirty"),
        None => (commit, ""),
    };
    format!("{}{dirty}", hash.chars().take(digits).collect::<String>())
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

/// Whether the machine was busy while a benchmark ran: a result measured beside other work
/// is slower, and scales worse, than the machine itself.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Busy {
    /// True when any of the reasons holds.
    pub busy: bool,
    /// What made it busy, in words; empty when it was not.
    pub reasons: Vec<String>,
    /// The CPUs other processes kept busy, on average, on the CPUs this run could use,
    /// while it ran; absent where /proc could not be read.
    pub others_cpus: Option<f64>,
    /// The share of those CPUs' time the hypervisor gave to other machines (steal time).
    pub steal: Option<f64>,
}

/// Other processes keeping this many of `cpus` CPUs busy on average, or more, make a run
/// busy: a quarter of a CPU, or a twentieth of them on a large machine.
fn busy_others_cpus(cpus: usize) -> f64 {
    f64::max(0.25, 0.05 * cpus as f64)
}
/// Steal time above this share of the CPUs' time makes a run busy.
const BUSY_STEAL: f64 = 0.02;

impl Busy {
    /// Judges a run on `host` (read as it started) from the CPU times read before and after
    /// its renders.
    pub fn judge(host: &Host, before: Option<&CpuTimes>, after: Option<&CpuTimes>) -> Self {
        let mut reasons = Vec::new();
        let used = before.zip(after).and_then(|(a, b)| b.since(a));
        match &used {
            Some(u) => {
                // Measured on the CPUs this run could use: a paired measurement confined to
                // one core is not busy because the other core is, and the load average
                // (which counts this bench's own earlier renders) is not needed.
                if u.others_cpus >= busy_others_cpus(u.cpus) {
                    reasons.push(format!(
                        "other processes kept {:.2} of its {} busy while it ran",
                        u.others_cpus,
                        crate::text::count(u.cpus as u64, "CPU")
                    ));
                }
                if u.steal >= BUSY_STEAL {
                    reasons.push(format!(
                        "the hypervisor took {:.1}% of its CPUs' time (steal)",
                        100.0 * u.steal
                    ));
                }
            }
            // Without /proc/stat, the machine's load average as it started, against all of
            // its CPUs.
            None => {
                if let Some([load, ..]) = host.load_average
                    && load > host.logical_cpus as f64
                {
                    reasons.push(format!(
                        "a load average of {load:.2} on {} when it started",
                        crate::text::count(host.logical_cpus as u64, "CPU")
                    ));
                }
            }
        }
        Self {
            busy: !reasons.is_empty(),
            reasons,
            others_cpus: used.as_ref().map(|u| round3(u.others_cpus)),
            steal: used.as_ref().map(|u| round3(u.steal)),
        }
    }
}

fn round3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

/// CPU time counters at one moment: per CPU this process may run on (from /proc/stat), and
/// this process's own (from /proc/self/stat), all in clock ticks.
#[derive(Clone, Debug, PartialEq)]
pub struct CpuTimes {
    /// Per CPU: (busy, total, steal) ticks.
    cpus: Vec<(u64, u64, u64)>,
    /// This process's user and system ticks, all its threads.
    own: u64,
}

/// CPU time used between two `CpuTimes`.
struct Used {
    /// CPUs watched.
    cpus: usize,
    /// CPUs other processes kept busy on average.
    others_cpus: f64,
    /// The share of the time stolen.
    steal: f64,
}

impl CpuTimes {
    /// The counters now; `None` where /proc cannot be read (not Linux).
    pub fn now() -> Option<Self> {
        let allowed = read_file("/proc/self/status").and_then(|s| {
            let list = s
                .lines()
                .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))?;
            confinement::cpu_list(list.trim())
        });
        Self::parse(
            &read_file("/proc/stat")?,
            &read_file("/proc/self/stat")?,
            allowed.as_ref(),
        )
    }

    /// The counters in the text of /proc/stat and /proc/self/stat, over the CPUs `allowed`
    /// (all when `None`).
    fn parse(stat: &str, own: &str, allowed: Option<&BTreeSet<u32>>) -> Option<Self> {
        let mut cpus = Vec::new();
        for line in stat.lines() {
            let Some(rest) = line.strip_prefix("cpu") else {
                continue;
            };
            let Some((id, fields)) = rest.split_once(' ') else {
                continue;
            };
            // The first line, `cpu  …`, sums every CPU: only `cpuN` lines count.
            let Ok(id) = id.parse::<u32>() else {
                continue;
            };
            if allowed.is_some_and(|set| !set.contains(&id)) {
                continue;
            }
            // user nice system idle iowait irq softirq steal [guest guest_nice]: the guest
            // times are already in user and nice.
            let v: Vec<u64> = fields
                .split_whitespace()
                .take(8)
                .map_while(|x| x.parse().ok())
                .collect();
            if v.len() < 8 {
                return None;
            }
            let total = v.iter().fold(0u64, |a, &x| a.saturating_add(x));
            let idle = v[3].saturating_add(v[4]);
            cpus.push((total.saturating_sub(idle), total, v[7]));
        }
        // The process's name is in parentheses and may hold spaces: fields follow the last `)`.
        let (_, after) = own.rsplit_once(')')?;
        let f: Vec<&str> = after.split_whitespace().collect();
        // utime and stime are fields 14 and 15 of the whole line, 12 and 13 after the name.
        let own = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
        (!cpus.is_empty()).then_some(Self { cpus, own })
    }

    /// What was used between `earlier` and `self`.
    fn since(&self, earlier: &CpuTimes) -> Option<Used> {
        if self.cpus.len() != earlier.cpus.len() {
            return None;
        }
        let (mut busy, mut total, mut steal) = (0u64, 0u64, 0u64);
        for (now, then) in self.cpus.iter().zip(&earlier.cpus) {
            busy += now.0.saturating_sub(then.0);
            total += now.1.saturating_sub(then.1);
            steal += now.2.saturating_sub(then.2);
        }
        if total == 0 {
            return None;
        }
        let own = self.own.saturating_sub(earlier.own);
        // Steal counts as busy in /proc/stat: it is the hypervisor's, not another process's.
        let others = busy.saturating_sub(own).saturating_sub(steal);
        let per_cpu = total as f64 / self.cpus.len() as f64;
        Some(Used {
            cpus: self.cpus.len(),
            others_cpus: others as f64 / per_cpu,
            steal: steal as f64 / total as f64,
        })
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

    const STAT_BEFORE: &str = "cpu  100 0 100 800 0 0 0 0 0 0\n\
        cpu0 50 0 50 400 0 0 0 0 0 0\ncpu1 50 0 50 400 0 0 0 0 0 0\nintr 5\n";
    const STAT_AFTER: &str = "cpu  300 0 200 880 0 0 0 20 0 0\n\
        cpu0 150 0 100 440 0 0 0 10 0 0\ncpu1 150 0 100 440 0 0 0 10 0 0\nintr 9\n";
    const OWN_BEFORE: &str = "7 (tessera (x)) R 1 2 3 4 5 6 7 8 9 10 100 50 0 0";
    const OWN_AFTER: &str = "7 (tessera (x)) R 1 2 3 4 5 6 7 8 9 10 250 100 0 0";

    fn host(load: f64, cpus: usize) -> Host {
        let mut h = Host::this();
        h.load_average = Some([load, load, load]);
        h.logical_cpus = cpus;
        h.cpus_usable = 1;
        h
    }

    #[test]
    fn other_processes_and_steal_make_a_run_busy() {
        let before = CpuTimes::parse(STAT_BEFORE, OWN_BEFORE, None).unwrap();
        let after = CpuTimes::parse(STAT_AFTER, OWN_AFTER, None).unwrap();
        // 400 ticks on 2 CPUs: busy 320 (steal 20 in it), ours 200: others 100, 0.5 CPUs.
        let used = after.since(&before).unwrap();
        assert!((used.others_cpus - 0.5).abs() < 1e-9);
        assert!((used.steal - 0.05).abs() < 1e-9);
        // The measurement decides, whatever the load average says.
        let busy = Busy::judge(&host(0.1, 2), Some(&before), Some(&after));
        assert!(busy.busy);
        assert_eq!(busy.reasons.len(), 2, "{:?}", busy.reasons);
        assert!(busy.reasons[0].contains("other processes kept 0.50 of its 2 CPUs busy"));
        assert!(busy.reasons[1].contains("5.0% of its CPUs' time (steal)"));
        // Only CPU 0 allowed: only its line counts.
        let one = [0].into_iter().collect();
        let before = CpuTimes::parse(STAT_BEFORE, OWN_BEFORE, Some(&one)).unwrap();
        let after = CpuTimes::parse(STAT_AFTER, OWN_AFTER, Some(&one)).unwrap();
        assert_eq!(after.since(&before).unwrap().cpus, 1);
    }

    #[test]
    fn a_quiet_run_is_not_busy_but_a_high_load_at_the_start_is() {
        let quiet = CpuTimes::parse(STAT_BEFORE, OWN_BEFORE, None).unwrap();
        let ours_only = CpuTimes {
            cpus: vec![(150, 550, 0), (150, 550, 0)],
            own: 150 + 100,
        };
        // A load of 3 on 2 CPUs, from this bench's own earlier renders: not busy, as
        // nothing else ran while it measured.
        let calm = Busy::judge(&host(3.0, 2), Some(&quiet), Some(&ours_only));
        assert!(!calm.busy, "{:?}", calm.reasons);
        assert_eq!(calm.others_cpus, Some(0.0));
        assert!(!Busy::judge(&host(1.5, 2), None, None).busy);
        assert_eq!(busy_others_cpus(2), 0.25);
        assert!((busy_others_cpus(96) - 4.8).abs() < 1e-9);
        // Without /proc/stat, the load average at the start decides.
        let loaded = Busy::judge(&host(5.0, 2), None, None);
        assert!(loaded.busy);
        assert_eq!(
            loaded.reasons,
            ["a load average of 5.00 on 2 CPUs when it started"]
        );
        assert_eq!(loaded.others_cpus, None);
        assert!(CpuTimes::parse("intr 5\n", OWN_BEFORE, None).is_none());
        assert!(CpuTimes::parse(STAT_BEFORE, "garbage", None).is_none());
    }

    #[test]
    fn short_commits_keep_their_dirty_mark() {
        assert_eq!(short_commit("9e648ea39d40e67d", 8), "9e648ea3");
        assert_eq!(short_commit("9e648ea39d40e67d-dirty", 8), "9e648ea3-dirty");
        assert_eq!(short_commit("unknown", 12), "unknown");
    }

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
