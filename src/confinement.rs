//! What confines this process on Linux: the container it runs in (if one is recognised),
//! the CPU quota of its cgroup (v1 or v2) and the CPUs its affinity allows. The default
//! thread count (`std::thread::available_parallelism`) follows the quota and the affinity;
//! this module only reports them, so that a benchmark result says it ran in a container
//! under `--cpus=2` rather than on a machine with two CPUs, and an output that cannot be
//! written in a container says what to mount.
//!
//! Files are read through a `Files` function so that tests can give any cgroup layout.

use std::collections::BTreeSet;

/// Reads a file's text; `None` where it cannot.
pub type Files<'a> = &'a dyn Fn(&str) -> Option<String>;

/// The real files.
pub fn read_file(path: &str) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

/// The container this process runs in, if one is recognised.
pub fn this_container() -> Option<String> {
    container(&read_file, &|name| std::env::var(name).ok())
}

/// The container whose entry point this process is (process 1 of its container, as
/// `podman run IMAGE render …` makes it), if one is recognised: where advice about what
/// to mount helps, unlike a shell's child in a development container.
pub fn entry_point_of_container() -> Option<String> {
    (std::process::id() == 1).then(this_container).flatten()
}

/// The container runtime this process runs in, where one is recognised: `kubernetes`,
/// `podman`, `docker`, or what `$container` names (systemd-nspawn, lxc, …).
pub fn container(files: Files, var: &dyn Fn(&str) -> Option<String>) -> Option<String> {
    if var("KUBERNETES_SERVICE_HOST").is_some() {
        return Some("kubernetes".into());
    }
    // Podman writes /run/.containerenv into every container, Docker /.dockerenv.
    if files("/run/.containerenv").is_some() {
        return Some("podman".into());
    }
    if files("/.dockerenv").is_some() {
        return Some("docker".into());
    }
    if let Some(name) = var("container").filter(|n| !n.is_empty()) {
        return Some(name.chars().take(64).collect());
    }
    let cgroups = files("/proc/self/cgroup").unwrap_or_default();
    [
        ("kubepods", "kubernetes"),
        ("libpod", "podman"),
        ("docker", "docker"),
    ]
    .into_iter()
    .find(|(mark, _)| cgroups.contains(mark))
    .map(|(_, name)| name.to_owned())
}

/// A mount of a cgroup hierarchy, from /proc/self/mountinfo.
struct CgroupMount {
    /// The cgroup path that appears at `point` (`/` unless a container sees a subtree).
    root: String,
    point: String,
}

/// The cgroup2 mount (`v1 == None`) or the v1 mount carrying `controller`.
fn cgroup_mount(mountinfo: &str, controller: Option<&str>) -> Option<CgroupMount> {
    mountinfo.lines().find_map(|line| {
        // `id parent major:minor root point options [optional…] - fstype source super`
        let (before, after) = line.split_once(" - ")?;
        let fields: Vec<&str> = before.split(' ').collect();
        let after: Vec<&str> = after.split(' ').collect();
        let (root, point) = (*fields.get(3)?, *fields.get(4)?);
        let fstype = *after.first()?;
        let matches = match controller {
            None => fstype == "cgroup2",
            Some(c) => fstype == "cgroup" && after.get(2)?.split(',').any(|option| option == c),
        };
        matches.then(|| CgroupMount {
            root: unescape_mount_path(root),
            point: unescape_mount_path(point),
        })
    })
}

/// mountinfo writes a space, tab, newline and backslash in a path as octal escapes.
fn unescape_mount_path(path: &str) -> String {
    path.replace("\\040", " ")
        .replace("\\011", "\t")
        .replace("\\012", "\n")
        .replace("\\134", "\\")
}

/// The directories from this process's cgroup up to the hierarchy's top, innermost first.
fn cgroup_dirs(mount: &CgroupMount, path: &str) -> Vec<String> {
    // A path outside the mount's root is one a container cannot see: only the top is.
    let relative = if mount.root == "/" {
        Some(path)
    } else {
        path.strip_prefix(mount.root.as_str())
            .filter(|rest| rest.is_empty() || rest.starts_with('/'))
    };
    let mut dirs = Vec::new();
    let mut rel = relative.unwrap_or("").trim_end_matches('/').to_owned();
    loop {
        dirs.push(format!("{}{rel}", mount.point.trim_end_matches('/')));
        match rel.rfind('/') {
            Some(i) => rel.truncate(i),
            None => break,
        }
    }
    if dirs.last().is_some_and(|d| d.is_empty()) {
        dirs.pop();
        dirs.push("/".into());
    }
    dirs
}

/// CPUs a `quota` of CPU time per `period` allows; `None` for no limit or nonsense.
fn cpus(quota: &str, period: &str) -> Option<f64> {
    let quota: f64 = quota.trim().parse().ok()?;
    let period: f64 = period.trim().parse().ok()?;
    (quota > 0.0 && period > 0.0).then(|| quota / period)
}

/// The CPUs this process's cgroup quota allows (quota ÷ period, the tightest along the path
/// to the hierarchy's top), under cgroup v2 or v1; `None` where there is no quota.
pub fn cpu_quota(files: Files) -> Option<f64> {
    let cgroups = files("/proc/self/cgroup")?;
    let mountinfo = files("/proc/self/mountinfo")?;
    let mut tightest: Option<f64> = None;
    for line in cgroups.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(id), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let limits: Vec<f64> = if id == "0" && controllers.is_empty() {
            let Some(mount) = cgroup_mount(&mountinfo, None) else {
                continue;
            };
            (cgroup_dirs(&mount, path).iter())
                .filter_map(|dir| {
                    let max = files(&format!("{dir}/cpu.max"))?;
                    let (quota, period) = max.trim().split_once(' ')?;
                    (quota != "max").then(|| cpus(quota, period))?
                })
                .collect()
        } else if controllers.split(',').any(|c| c == "cpu") {
            let Some(mount) = cgroup_mount(&mountinfo, Some("cpu")) else {
                continue;
            };
            (cgroup_dirs(&mount, path).iter())
                .filter_map(|dir| {
                    cpus(
                        &files(&format!("{dir}/cpu.cfs_quota_us"))?,
                        &files(&format!("{dir}/cpu.cfs_period_us"))?,
                    )
                })
                .collect()
        } else {
            continue;
        };
        for limit in limits {
            tightest = Some(tightest.map_or(limit, |t| t.min(limit)));
        }
    }
    tightest
}

/// The CPUs in a list such as `0-3,8,10-11`; `None` if it does not parse.
pub fn cpu_list(list: &str) -> Option<BTreeSet<u32>> {
    let mut set = BTreeSet::new();
    for range in list.trim().split(',').filter(|r| !r.is_empty()) {
        let (a, b) = range.split_once('-').unwrap_or((range, range));
        let (a, b): (u32, u32) = (a.trim().parse().ok()?, b.trim().parse().ok()?);
        // A list beyond any machine's CPUs is not one to expand.
        if b < a || b - a > 1 << 16 {
            return None;
        }
        set.extend(a..=b);
    }
    Some(set)
}

/// The machine's online CPUs, from /sys (or /proc/cpuinfo's processors).
pub fn online_cpus(files: Files) -> Option<usize> {
    if let Some(set) = files("/sys/devices/system/cpu/online").and_then(|l| cpu_list(&l)) {
        return Some(set.len()).filter(|&n| n > 0);
    }
    let cpuinfo = files("/proc/cpuinfo")?;
    let n = (cpuinfo.lines())
        .filter(|l| l.split(':').next().is_some_and(|k| k.trim() == "processor"))
        .count();
    (n > 0).then_some(n)
}

/// The CPUs this process may run on (its affinity), from /proc/self/status.
pub fn allowed_cpus(files: Files) -> Option<usize> {
    let status = files("/proc/self/status")?;
    let list = status
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))?;
    Some(cpu_list(list)?.len()).filter(|&n| n > 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn files(list: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> + use<> {
        let map: HashMap<String, String> = (list.iter())
            .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
            .collect();
        move |path| map.get(path).cloned()
    }

    fn no_vars(_: &str) -> Option<String> {
        None
    }

    const V2_MOUNT: &str = "30 23 0:26 / /sys/fs/cgroup rw,nosuid,nodev,noexec,relatime shared:4 - cgroup2 cgroup2 rw\n";

    #[test]
    fn a_v2_quota_is_quota_over_period() {
        let f = files(&[
            ("/proc/self/cgroup", "0::/\n"),
            ("/proc/self/mountinfo", V2_MOUNT),
            ("/sys/fs/cgroup/cpu.max", "150000 100000\n"),
        ]);
        assert_eq!(cpu_quota(&f), Some(1.5));
    }

    #[test]
    fn a_v2_cgroup_without_a_quota_has_none() {
        let f = files(&[
            ("/proc/self/cgroup", "0::/user.slice/session-1.scope\n"),
            ("/proc/self/mountinfo", V2_MOUNT),
            (
                "/sys/fs/cgroup/user.slice/session-1.scope/cpu.max",
                "max 100000\n",
            ),
            ("/sys/fs/cgroup/user.slice/cpu.max", "max 100000\n"),
        ]);
        assert_eq!(cpu_quota(&f), None);
    }

    #[test]
    fn the_tightest_quota_on_the_path_up_counts() {
        // A Kubernetes pod's limit sits on the pod's cgroup, above the container's.
        let f = files(&[
            ("/proc/self/cgroup", "0::/kubepods/pod1/ctr\n"),
            ("/proc/self/mountinfo", V2_MOUNT),
            ("/sys/fs/cgroup/kubepods/pod1/ctr/cpu.max", "max 100000\n"),
            ("/sys/fs/cgroup/kubepods/pod1/cpu.max", "400000 100000\n"),
            ("/sys/fs/cgroup/kubepods/cpu.max", "800000 100000\n"),
        ]);
        assert_eq!(cpu_quota(&f), Some(4.0));
    }

    #[test]
    fn a_v1_quota_is_found_through_the_cpu_controller_mount() {
        // Podman on a cgroup v1 host: no cgroup namespace, so /proc/self/cgroup names the
        // host's path while the container sees that subtree mounted at /sys/fs/cgroup/cpu.
        let scope = "/machine.slice/libpod-abc.scope";
        let mountinfo = format!(
            "900 800 0:50 {scope} /sys/fs/cgroup/cpu,cpuacct ro,nosuid - cgroup cgroup rw,cpu,cpuacct\n\
             901 800 0:51 {scope} /sys/fs/cgroup/memory ro,nosuid - cgroup cgroup rw,memory\n"
        );
        let f = files(&[
            (
                "/proc/self/cgroup",
                &format!("5:memory:{scope}\n4:cpu,cpuacct:{scope}\n0::{scope}\n"),
            ),
            ("/proc/self/mountinfo", &mountinfo),
            ("/sys/fs/cgroup/cpu,cpuacct/cpu.cfs_quota_us", "200000\n"),
            ("/sys/fs/cgroup/cpu,cpuacct/cpu.cfs_period_us", "100000\n"),
        ]);
        assert_eq!(cpu_quota(&f), Some(2.0));
    }

    #[test]
    fn a_v1_quota_of_minus_one_is_no_limit() {
        let f = files(&[
            ("/proc/self/cgroup", "2:cpu:/\n"),
            (
                "/proc/self/mountinfo",
                "40 30 0:33 / /sys/fs/cgroup/cpu rw - cgroup cgroup rw,cpu\n",
            ),
            ("/sys/fs/cgroup/cpu/cpu.cfs_quota_us", "-1\n"),
            ("/sys/fs/cgroup/cpu/cpu.cfs_period_us", "100000\n"),
        ]);
        assert_eq!(cpu_quota(&f), None);
    }

    #[test]
    fn mount_paths_with_escaped_spaces_are_read() {
        let f = files(&[
            ("/proc/self/cgroup", "0::/a b\n"),
            (
                "/proc/self/mountinfo",
                "30 23 0:26 / /mnt/my\\040cgroup rw - cgroup2 cgroup2 rw\n",
            ),
            ("/mnt/my cgroup/a b/cpu.max", "50000 100000"),
        ]);
        assert_eq!(cpu_quota(&f), Some(0.5));
    }

    #[test]
    fn garbage_gives_no_quota_rather_than_a_wrong_one() {
        for (cgroup, max) in [
            ("0::/\n", "lots 100000"),
            ("0::/\n", "100000 0"),
            ("0::/\n", "-5 100000"),
            ("nonsense", "100000 100000"),
            ("", "100000 100000"),
        ] {
            let f = files(&[
                ("/proc/self/cgroup", cgroup),
                ("/proc/self/mountinfo", V2_MOUNT),
                ("/sys/fs/cgroup/cpu.max", max),
            ]);
            assert_eq!(cpu_quota(&f), None, "{cgroup:?} {max:?}");
        }
        assert_eq!(cpu_quota(&files(&[])), None);
    }

    #[test]
    fn cpu_lists_count_their_cpus() {
        assert_eq!(cpu_list("0-3,8,10-11\n").map(|s| s.len()), Some(7));
        assert_eq!(cpu_list("0").map(|s| s.len()), Some(1));
        assert_eq!(cpu_list("3-1"), None);
        assert_eq!(cpu_list("0-4000000000"), None);
        assert_eq!(cpu_list("x"), None);
        let f = files(&[
            ("/sys/devices/system/cpu/online", "0-15\n"),
            (
                "/proc/self/status",
                "Name:\ttessera\nCpus_allowed_list:\t2-3\n",
            ),
        ]);
        assert_eq!(online_cpus(&f), Some(16));
        assert_eq!(allowed_cpus(&f), Some(2));
        let cpuinfo = files(&[("/proc/cpuinfo", "processor\t: 0\nx : y\nprocessor\t: 1\n")]);
        assert_eq!(online_cpus(&cpuinfo), Some(2));
    }

    #[test]
    fn containers_are_recognised_by_their_marks() {
        let none = files(&[("/proc/self/cgroup", "0::/user.slice\n")]);
        assert_eq!(container(&none, &no_vars), None);
        let podman = files(&[("/run/.containerenv", "engine=\"podman-4.3.1\"\n")]);
        assert_eq!(container(&podman, &no_vars).as_deref(), Some("podman"));
        let docker = files(&[("/.dockerenv", "")]);
        assert_eq!(container(&docker, &no_vars).as_deref(), Some("docker"));
        let k8s = |name: &str| (name == "KUBERNETES_SERVICE_HOST").then(|| "10.0.0.1".into());
        assert_eq!(container(&podman, &k8s).as_deref(), Some("kubernetes"));
        let nspawn = |name: &str| (name == "container").then(|| "systemd-nspawn".into());
        assert_eq!(container(&none, &nspawn).as_deref(), Some("systemd-nspawn"));
        let pods = files(&[("/proc/self/cgroup", "0::/kubepods.slice/pod1/cri-1\n")]);
        assert_eq!(container(&pods, &no_vars).as_deref(), Some("kubernetes"));
    }
}
