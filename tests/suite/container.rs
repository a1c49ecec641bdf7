//! The container image and the Kubernetes manifests, used as a cluster would use them.
//!
//! The manifests in `deploy/k8s/` are read, never copied: the tests check that they agree
//! with each other and with the build, validate them against Kubernetes' schemas
//! (`kubernetes-validate`, from PyPI), and run the Indexed Job under Podman as the control
//! plane and kubelet would: one container per completion index with `JOB_COMPLETION_INDEX`
//! set, the pod's security context and resource limits, the shared volume mounted; two of
//! them are killed mid-render (SIGKILL, as a lost node or the OOM killer does, and SIGTERM,
//! as an eviction does) and started again, as `restartPolicy: OnFailure` does; then the merge
//! job. The merged image must be the single render's bytes.
//!
//! The image is `TESSERA_IMAGE` (built by `deploy/container/build.sh`, as `.ci/run` does).
//! Without Podman, the image or `kubernetes-validate` the tests that need them are skipped,
//! saying why; under `CI=true` they fail instead.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use yaml_rust2::{Yaml, YamlLoader};

/// How long the Indexed Job and its merge may take before the test gives up.
const PATIENCE: Duration = Duration::from_secs(300);

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A manifest of `deploy/k8s/`, parsed.
fn manifest(name: &str) -> Yaml {
    let path = root().join("deploy/k8s").join(name);
    let source = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
    let mut docs = YamlLoader::load_from_str(&source).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(docs.len(), 1, "{name}: one object per file");
    docs.remove(0)
}

fn string(y: &Yaml, what: &str) -> String {
    match y {
        Yaml::String(s) | Yaml::Real(s) => s.clone(),
        Yaml::Integer(i) => i.to_string(),
        other => panic!("{what}: expected a string, found {other:?}"),
    }
}

fn integer(y: &Yaml, what: &str) -> i64 {
    y.as_i64()
        .unwrap_or_else(|| panic!("{what}: expected an integer, found {y:?}"))
}

fn strings(y: &Yaml, what: &str) -> Vec<String> {
    match y {
        Yaml::BadValue => Vec::new(),
        Yaml::Array(items) => items.iter().map(|i| string(i, what)).collect(),
        other => panic!("{what}: expected a list, found {other:?}"),
    }
}

/// A CPU quantity (`2`, `"1.5"`, `500m`) in CPUs.
fn cpus(quantity: &str) -> f64 {
    match quantity.strip_suffix('m') {
        Some(milli) => milli.parse::<f64>().unwrap() / 1000.0,
        None => quantity.parse().unwrap(),
    }
}

/// A memory quantity (`256Mi`, `1Gi`) as Podman's `--memory` takes it.
fn podman_memory(quantity: &str) -> String {
    for (suffix, unit) in [("Ki", "k"), ("Mi", "m"), ("Gi", "g")] {
        if let Some(n) = quantity.strip_suffix(suffix) {
            return format!("{n}{unit}");
        }
    }
    quantity.to_owned()
}

/// What a Job's pod template asks of its one container.
struct Pod {
    image: String,
    command: Vec<String>,
    args: Vec<String>,
    working_dir: Option<String>,
    env: Vec<(String, String)>,
    restart_policy: String,
    run_as_non_root: bool,
    user: i64,
    group: i64,
    fs_group: Option<i64>,
    read_only_root: bool,
    no_privilege_escalation: bool,
    drop_all_capabilities: bool,
    cpu_request: f64,
    cpu_limit: f64,
    memory_request: String,
    memory_limit: String,
    /// (claim name, mount path) of each volume from a PersistentVolumeClaim.
    claims: Vec<(String, String)>,
}

/// A Job manifest.
struct Job {
    completion_mode: Option<String>,
    completions: Option<i64>,
    parallelism: Option<i64>,
    backoff_limit: i64,
    ttl_after_finished: Option<i64>,
    pod: Pod,
}

impl Job {
    fn read(name: &str) -> Job {
        let m = manifest(name);
        assert_eq!(m["kind"].as_str(), Some("Job"), "{name}");
        assert_eq!(m["apiVersion"].as_str(), Some("batch/v1"), "{name}");
        let spec = &m["spec"];
        let template = &spec["template"]["spec"];
        let containers = template["containers"].as_vec().expect("containers");
        assert_eq!(containers.len(), 1, "{name}: one container");
        let c = &containers[0];
        let security = &template["securityContext"];
        let resources = &c["resources"];
        let volumes = template["volumes"].as_vec().cloned().unwrap_or_default();
        let claims = (c["volumeMounts"]
            .as_vec()
            .cloned()
            .unwrap_or_default()
            .iter())
        .map(|mount| {
            let volume = (volumes.iter())
                .find(|v| v["name"] == mount["name"])
                .unwrap_or_else(|| panic!("{name}: no volume {:?}", mount["name"]));
            let claim = string(&volume["persistentVolumeClaim"]["claimName"], "claimName");
            (claim, string(&mount["mountPath"], "mountPath"))
        })
        .collect();
        let env = (c["env"].as_vec().cloned().unwrap_or_default().iter())
            .filter(|e| !e["value"].is_badvalue())
            .map(|e| {
                (
                    string(&e["name"], "env name"),
                    string(&e["value"], "env value"),
                )
            })
            .collect();
        let q = |y: &Yaml, what: &str| string(y, what);
        Job {
            completion_mode: spec["completionMode"].as_str().map(str::to_owned),
            completions: spec["completions"].as_i64(),
            parallelism: spec["parallelism"].as_i64(),
            backoff_limit: spec["backoffLimit"].as_i64().unwrap_or(6),
            ttl_after_finished: spec["ttlSecondsAfterFinished"].as_i64(),
            pod: Pod {
                image: string(&c["image"], "image"),
                command: strings(&c["command"], "command"),
                args: strings(&c["args"], "args"),
                working_dir: c["workingDir"].as_str().map(str::to_owned),
                env,
                restart_policy: string(&template["restartPolicy"], "restartPolicy"),
                run_as_non_root: security["runAsNonRoot"].as_bool() == Some(true),
                user: integer(&security["runAsUser"], "runAsUser"),
                group: integer(&security["runAsGroup"], "runAsGroup"),
                fs_group: security["fsGroup"].as_i64(),
                read_only_root: c["securityContext"]["readOnlyRootFilesystem"].as_bool()
                    == Some(true),
                no_privilege_escalation: c["securityContext"]["allowPrivilegeEscalation"].as_bool()
                    == Some(false),
                drop_all_capabilities: strings(
                    &c["securityContext"]["capabilities"]["drop"],
                    "drop",
                )
                .contains(&"ALL".to_owned()),
                cpu_request: cpus(&q(&resources["requests"]["cpu"], "cpu request")),
                cpu_limit: cpus(&q(&resources["limits"]["cpu"], "cpu limit")),
                memory_request: q(&resources["requests"]["memory"], "memory request"),
                memory_limit: q(&resources["limits"]["memory"], "memory limit"),
                claims,
            },
        }
    }
}

/// The value after `flag` in `args`.
fn flag_value<'a>(args: &'a [String], flag: &str) -> Option<&'a str> {
    let i = args.iter().position(|a| a == flag)?;
    args.get(i + 1).map(String::as_str)
}

/// `args` without `flag` and its value.
fn without_flag(args: &[String], flag: &str) -> Vec<String> {
    match args.iter().position(|a| a == flag) {
        Some(i) => [&args[..i], &args[(i + 2).min(args.len())..]].concat(),
        None => args.to_vec(),
    }
}

/// Kubernetes' expansion of `$(NAME)` in a container's command and arguments: a variable of
/// the container's environment is replaced, `$$` is a `$`, anything else stays as written.
fn expand(arg: &str, env: &[(String, String)]) -> String {
    let mut out = String::new();
    let mut rest = arg;
    while let Some(i) = rest.find('$') {
        out.push_str(&rest[..i]);
        rest = &rest[i..];
        if let Some(after) = rest.strip_prefix("$$") {
            out.push('$');
            rest = after;
        } else if let Some((name, after)) = (rest.strip_prefix("$("))
            .and_then(|r| r.split_once(')'))
            .filter(|(name, _)| env.iter().any(|(k, _)| k == name))
        {
            let value = &env.iter().find(|(k, _)| k == name).unwrap().1;
            out.push_str(value);
            rest = after;
        } else {
            out.push('$');
            rest = &rest[1..];
        }
    }
    out.push_str(rest);
    out
}

#[test]
fn kubernetes_expands_variables_as_the_emulation_does() {
    let env = vec![("JOB_COMPLETION_INDEX".to_owned(), "3".to_owned())];
    assert_eq!(
        expand("/p/s-$(JOB_COMPLETION_INDEX).part", &env),
        "/p/s-3.part"
    );
    assert_eq!(
        expand("$$(JOB_COMPLETION_INDEX)", &env),
        "$(JOB_COMPLETION_INDEX)"
    );
    assert_eq!(expand("$(UNSET) $x $", &env), "$(UNSET) $x $");
}

/// `build.sh --help` prints what the script does and builds nothing: it once passed
/// `--help` to the engine's `build`, after compiling the static binary. Here no cargo and no
/// engine can be found (only `sed` is on the path), so any build fails.
#[test]
fn the_image_build_script_s_help_builds_nothing() {
    let tools = temp_dir("build-sh-help");
    let found = |name: &str| {
        let path = std::env::var_os("PATH").unwrap_or_default();
        (std::env::split_paths(&path).map(|d| d.join(name))).find(|p| p.is_file())
    };
    std::os::unix::fs::symlink(found("sed").unwrap(), tools.join("sed")).unwrap();
    let o = Command::new(found("bash").unwrap())
        .arg(root().join("deploy/container/build.sh"))
        .arg("--help")
        .env("PATH", &tools)
        .env("ENGINE", "/nonexistent/podman")
        .output()
        .unwrap();
    let out = text(&o.stdout);
    assert!(o.status.success(), "{out}{}", text(&o.stderr));
    assert!(
        out.starts_with("Builds tessera's container image")
            && out.contains("-h or --help,\nfirst, prints this.\n")
            && !out.contains('#'),
        "{out}"
    );
}

#[test]
fn the_manifests_agree_with_each_other_and_the_build() {
    let render = Job::read("render-job.yaml");
    let merge = Job::read("merge-job.yaml");
    // One pod per shard, and the shard count is the job's.
    assert_eq!(render.completion_mode.as_deref(), Some("Indexed"));
    let completions = render.completions.expect("completions");
    let shard = flag_value(&render.pod.args, "--shard").expect("--shard in the render args");
    assert_eq!(
        shard,
        format!("env/{completions}"),
        "--shard env/N must name the job's {completions} completions"
    );
    assert!(render.parallelism.unwrap_or(1) <= completions);
    assert_eq!(
        render.pod.restart_policy, "OnFailure",
        "a killed pod must resume"
    );
    let checkpoint = flag_value(&render.pod.args, "--checkpoint").expect("--checkpoint");
    let part = flag_value(&render.pod.args, "-o").expect("-o");
    for path in [checkpoint, part] {
        assert!(
            path.contains("$(JOB_COMPLETION_INDEX)"),
            "{path}: one file per index"
        );
    }
    // The merge reads the directory the render writes, on the same claim.
    let parts_dir = Path::new(part).parent().unwrap().to_str().unwrap();
    assert_eq!(render.pod.claims, merge.pod.claims);
    assert!(
        render
            .pod
            .claims
            .iter()
            .any(|(_, mount)| mount == parts_dir)
    );
    assert_eq!(merge.pod.args.get(1).map(String::as_str), Some(parts_dir));
    let pvc = manifest("pvc.yaml");
    assert_eq!(pvc["kind"].as_str(), Some("PersistentVolumeClaim"));
    assert_eq!(
        string(&pvc["metadata"]["name"], "claim name"),
        render.pod.claims[0].0
    );
    assert!(strings(&pvc["spec"]["accessModes"], "accessModes").contains(&"ReadWriteMany".into()));
    for (name, job) in [("render", &render), ("merge", &merge)] {
        let pod = &job.pod;
        // The image the build tags, never `latest`.
        assert_eq!(
            pod.image,
            format!("tessera:{}", env!("CARGO_PKG_VERSION")),
            "{name}"
        );
        // Guaranteed QoS, and whole CPUs: the thread count is the limit, rounded down.
        assert_eq!(
            pod.cpu_request, pod.cpu_limit,
            "{name}: cpu request != limit"
        );
        assert_eq!(pod.memory_request, pod.memory_limit, "{name}: memory");
        assert_eq!(pod.cpu_limit.fract(), 0.0, "{name}: whole CPUs");
        assert!(
            !pod.args.iter().any(|a| a == "--threads"),
            "{name}: the CPU limit sets the threads"
        );
        assert!(
            job.ttl_after_finished.is_some(),
            "{name}: ttlSecondsAfterFinished"
        );
        assert!(
            pod.run_as_non_root && pod.user != 0 && pod.group != 0,
            "{name}"
        );
        assert!(pod.read_only_root && pod.no_privilege_escalation, "{name}");
        assert!(pod.drop_all_capabilities, "{name}");
    }
}

#[test]
fn the_manifests_validate_against_the_kubernetes_schemas() {
    let name = "the_manifests_validate_against_the_kubernetes_schemas";
    if !heavy(name) {
        return;
    }
    let files: Vec<PathBuf> = ["render-job.yaml", "merge-job.yaml", "pvc.yaml"]
        .iter()
        .map(|f| root().join("deploy/k8s").join(f))
        .collect();
    // The oldest Kubernetes the package has schemas for and its newest (the default).
    for version in [Some("1.25.0"), None] {
        let mut command = Command::new("kubernetes-validate");
        command.args(["--strict", "--quiet"]);
        if let Some(v) = version {
            command.args(["--kubernetes-version", v]);
        }
        let o = match command.args(&files).output() {
            Ok(o) => o,
            Err(e) => {
                let why = format!(
                    "kubernetes-validate cannot run ({e}): `pip install kubernetes-validate`"
                );
                return skip(name, &why);
            }
        };
        assert!(
            o.status.success(),
            "kubernetes {version:?}: {}{}",
            text(&o.stdout),
            text(&o.stderr)
        );
    }
    // And it does refuse a manifest that is wrong.
    let dir = temp_dir("k8s-invalid");
    let bad = std::fs::read_to_string(&files[0])
        .unwrap()
        .replace("completionMode:", "completionMood:");
    std::fs::write(dir.join("bad.yaml"), bad).unwrap();
    let o = Command::new("kubernetes-validate")
        .args(["--strict", "--quiet"])
        .arg(dir.join("bad.yaml"))
        .output()
        .unwrap();
    assert!(!o.status.success(), "a misspelt field passed validation");
}

/// The image under test, or `None`, having said why the test is skipped.
fn image(test: &str) -> Option<String> {
    if !heavy(test) {
        return None;
    }
    container_image().map_err(|why| skip(test, &why)).ok()
}

fn podman(args: &[&str]) -> Output {
    Command::new("podman")
        .args(args)
        .output()
        .expect("run podman")
}

/// `podman run --rm` of `image` with `flags` and the arguments `args` of tessera.
fn run_image(image: &str, flags: &[&str], args: &[&str]) -> Output {
    let mut all = vec!["run", "--rm"];
    all.extend(PODMAN_FLAGS);
    all.extend(flags);
    all.push(image);
    all.extend(args);
    podman(&all)
}

/// The `N threads` of a render's summary line.
fn threads_of(log: &str) -> Option<usize> {
    let line = log.lines().rev().find(|l| l.contains(" rays/sample, "))?;
    line.rsplit(", ").next()?.split(' ').next()?.parse().ok()
}

#[test]
fn the_image_is_small_labelled_and_runs_without_privileges() {
    let Some(image) = image("the_image_is_small_labelled_and_runs_without_privileges") else {
        return;
    };
    let inspect = |format: &str| {
        let o = podman(&["image", "inspect", "--format", format, &image]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        text(&o.stdout).trim().to_owned()
    };
    let size: u64 = inspect("{{.Size}}").parse().unwrap();
    assert!(size < 15_000_000, "the image is {size} bytes");
    assert_eq!(inspect("{{.Config.User}}"), "65532:65532");
    let render = Job::read("render-job.yaml");
    assert_eq!(
        format!("{}:{}", render.pod.user, render.pod.group),
        inspect("{{.Config.User}}"),
        "the manifests run the image's own user"
    );
    let label = |name: &str| {
        inspect(&format!(
            "{{{{index .Labels \"org.opencontainers.image.{name}\"}}}}"
        ))
    };
    assert_eq!(label("version"), env!("CARGO_PKG_VERSION"));
    let about = label("description");
    assert!(
        about.contains("One Weekend") && about.contains("The Next Week"),
        "the image describes both books: {about}"
    );
    // `--version` in the image names the commit its label names, and this build's.
    let o = run_image(&image, &[], &["--version"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let inside = text(&o.stdout);
    let host = text(&tessera().arg("--version").output().unwrap().stdout);
    let commit = |version: &str| {
        (version.lines())
            .find_map(|l| l.strip_prefix("commit "))
            .map(str::to_owned)
    };
    assert_eq!(commit(&inside).as_deref(), Some(label("revision").as_str()));
    assert_eq!(
        commit(&inside),
        commit(&host),
        "the image is not this build"
    );
    assert!(inside.contains("x86_64-unknown-linux-musl"), "{inside}");
    // The image's own build: its profile, render only.
    assert!(inside.contains("(container build, "), "{inside}");
    assert!(
        inside.contains("\nfeatures none (render only)\n"),
        "{inside}"
    );
    // The root filesystem is read-only, and the user cannot write to /app.
    let o = run_image(
        &image,
        &["--read-only"],
        &["render", "--width", "8", "--spp", "1"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(err.contains("cover.png"), "{err}");
    // The message says what to do: mount a directory and run as yourself.
    assert!(
        (err.contains("permission denied") || err.contains("read-only file system"))
            && err.contains("podman container")
            && err.contains("the current directory (/app)"),
        "{err}"
    );
    assert!(
        err.contains("--userns=keep-id --user \"$(id -u):$(id -g)\" -v"),
        "{err}"
    );
    // The image has no results database, and says so.
    let o = run_image(&image, &[], &["results", "list"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("built without the results database"),
        "{}",
        text(&o.stderr)
    );
    // An output directory that was not mounted: say it is missing, and what to mount.
    let o = run_image(
        &image,
        &[],
        &["render", "--width", "8", "--spp", "1", "-o", "/out/x.png"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(
        err.contains("the directory /out does not exist in this podman container")
            && err.contains("$PWD/out:/out"),
        "{err}"
    );
}

/// The README's own lines, as written, as a user of rootless Podman runs them: make the
/// output directory, run the image as yourself with it mounted, and find the cover there.
#[test]
fn the_readme_s_podman_command_writes_the_cover() {
    let test = "the_readme_s_podman_command_writes_the_cover";
    let Some(image) = image(test) else {
        return;
    };
    let Ok(user) = std::env::var("TESSERA_ROOTLESS_USER") else {
        return skip(
            test,
            "TESSERA_ROOTLESS_USER names no user with rootless Podman and the image \
             (.ci/run makes one)",
        );
    };
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let lines: Vec<&str> = readme.lines().collect();
    let run = lines
        .iter()
        .position(|l| l.starts_with("podman run "))
        .expect("the README runs the image");
    assert_eq!(
        lines[run - 1],
        "mkdir -p out",
        "the README makes the directory first"
    );
    let tag = format!("tessera:{}", env!("CARGO_PKG_VERSION"));
    assert!(lines[run].contains(&tag) && image == tag, "{}", lines[run]);
    // This machine's Podman needs runc and lower limits, which a user's does not: they go
    // right after `podman run`; the README's words stay as they are.
    let command = lines[run].replacen(
        "podman run",
        &format!("podman run {}", PODMAN_FLAGS.join(" ")),
        1,
    );
    let dir = temp_dir("container-readme");
    let chown = Command::new("chown").arg(&user).arg(&dir).status().unwrap();
    assert!(chown.success());
    let script = format!("cd '{}' && mkdir -p out && {command}", dir.display());
    let o = Command::new("su")
        .args(["-", &user, "-c", &script])
        .output()
        .unwrap();
    assert!(o.status.success(), "{script}: {}", text(&o.stderr));
    let info = tessera()
        .args(["info", "out/cover.png"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        text(&info.stdout).contains("PNG 600x400, with a recipe"),
        "{}{}",
        text(&info.stdout),
        text(&info.stderr)
    );
    assert_eq!(
        recipe_sums(&dir.join("out/cover.png")),
        recipe_sums(&root().join("docs/cover-600x400.png")),
        "the README's podman line does not render the README's picture"
    );
}

#[test]
fn the_default_thread_count_follows_the_cpu_limit() {
    let Some(image) = image("the_default_thread_count_follows_the_cpu_limit") else {
        return;
    };
    let dir = temp_dir("container-cpus");
    make_writable_by(&dir, 65532, 65532);
    let volume = format!("{}:/out", dir.display());
    let host_cpus = std::thread::available_parallelism().unwrap().get();
    // --cpus sets a CFS quota (cgroup v1 or v2); --cpuset-cpus the affinity.
    for (flag, expected) in [
        ("--cpus=1", 1),
        ("--cpus=1.5", 1),
        ("--cpuset-cpus=0", 1),
        ("--cpus=64", host_cpus),
    ] {
        let o = run_image(
            &image,
            &[flag, "-v", &volume],
            &["render", "--width", "40", "--spp", "1", "-o", "/out/x.png"],
        );
        assert!(o.status.success(), "{flag}: {}", text(&o.stderr));
        assert_eq!(
            threads_of(&text(&o.stderr)),
            Some(expected),
            "{flag}: {}",
            text(&o.stderr)
        );
    }
    // The bench's host block says where it ran and under what limit.
    let bench = "bench scenes/cover.toml --width 40 --spp 1 --repeat 1 --warmup 0 --no-scaling";
    let mut args: Vec<&str> = bench.split(' ').collect();
    args.push("--json");
    let o = run_image(&image, &["--cpus=1", "-v", &volume], &args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let result: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let host = &result["host"];
    assert_eq!(host["container"], "podman", "{host}");
    assert_eq!(host["cpu_quota"].as_f64(), Some(1.0), "{host}");
    assert_eq!(host["cpus_usable"], 1, "{host}");
    assert_eq!(result["result"]["threads"], 1, "{result}");
    assert!(
        host["logical_cpus"].as_u64().unwrap() as usize >= host_cpus,
        "{host}"
    );
}

/// Gives `dir` to `user`:`group`, as a volume's fsGroup does (root can), or to everyone.
fn make_writable_by(dir: &Path, user: i64, group: i64) {
    let owner = format!("{user}:{group}");
    let chown = Command::new("chown").arg(&owner).arg(dir).status();
    if !chown.is_ok_and(|s| s.success()) {
        let _ = Command::new("chmod").arg("0777").arg(dir).status();
    }
}

/// Containers started by one test, removed when it ends, however it ends.
struct Containers {
    prefix: String,
}

impl Drop for Containers {
    fn drop(&mut self) {
        let o = podman(&["ps", "-a", "--format", "{{.Names}}"]);
        for name in text(&o.stdout).lines() {
            if name.starts_with(&self.prefix) {
                let _ = podman(&["rm", "-f", "-t", "0", name]);
            }
        }
    }
}

/// One run of a pod's container.
struct Attempt {
    code: Option<i32>,
    log: String,
}

/// Runs `pod` as the kubelet would, with `index` as its completion index, restarting it
/// after a failure while `restartPolicy` allows, up to `backoff_limit` restarts. Returns
/// every attempt. `current` holds the name of the running container.
fn run_pod(
    pod: &Pod,
    image: &str,
    index: Option<usize>,
    volume: &Path,
    backoff_limit: i64,
    name: &str,
    current: &Mutex<Option<String>>,
) -> Vec<Attempt> {
    let mut env = pod.env.clone();
    if let Some(i) = index {
        env.push(("JOB_COMPLETION_INDEX".into(), i.to_string()));
    }
    let mut flags: Vec<String> = PODMAN_FLAGS.iter().map(|s| s.to_string()).collect();
    flags.extend([
        format!("--user={}:{}", pod.user, pod.group),
        format!("--cpus={}", pod.cpu_limit),
        format!("--memory={}", podman_memory(&pod.memory_limit)),
    ]);
    if let Some(g) = pod.fs_group {
        flags.push(format!("--group-add={g}"));
    }
    if pod.read_only_root {
        flags.push("--read-only".into());
    }
    if pod.no_privilege_escalation {
        flags.push("--security-opt=no-new-privileges".into());
    }
    if pod.drop_all_capabilities {
        flags.push("--cap-drop=all".into());
    }
    if let Some(dir) = &pod.working_dir {
        flags.push(format!("--workdir={dir}"));
    }
    for (k, v) in &env {
        flags.push(format!("--env={k}={v}"));
    }
    for (_, mount) in &pod.claims {
        flags.push(format!("--volume={}:{mount}", volume.display()));
    }
    if !pod.command.is_empty() {
        let command: Vec<String> = pod.command.iter().map(|c| expand(c, &env)).collect();
        flags.push(format!(
            "--entrypoint={}",
            serde_json::to_string(&command).unwrap()
        ));
    }
    let args: Vec<String> = pod.args.iter().map(|a| expand(a, &env)).collect();
    let mut attempts = Vec::new();
    loop {
        let container = format!("{name}-{}", attempts.len());
        *current.lock().unwrap() = Some(container.clone());
        let o = Command::new("podman")
            .args(["run", "--rm", "--name", &container])
            .args(&flags)
            .arg(image)
            .args(&args)
            .output()
            .expect("run podman");
        *current.lock().unwrap() = None;
        let failed = !o.status.success();
        attempts.push(Attempt {
            code: o.status.code(),
            log: text(&o.stderr),
        });
        let restarts = attempts.len() as i64 - 1;
        if !failed || pod.restart_policy != "OnFailure" || restarts >= backoff_limit {
            return attempts;
        }
    }
}

/// Waits until `path` exists; false if `give_up` says so first.
fn wait_for_file(path: &Path, give_up: impl Fn() -> bool) -> bool {
    let start = Instant::now();
    while !path.exists() {
        if give_up() || start.elapsed() > PATIENCE {
            return false;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    true
}

#[test]
fn the_indexed_job_survives_killed_pods_and_merges_to_the_single_render() {
    let Some(image) = image("the_indexed_job_survives_killed_pods_and_merges_to_the_single_render")
    else {
        return;
    };
    let mut render = Job::read("render-job.yaml");
    // The job's own arguments at a quarter of the cover's pixels, the README's picture, and
    // with a checkpoint every 2 s, so that a pod is caught rendering: the same code as the
    // full cover's, in a quarter of the time (the README's set-up render, in docs.rs, is the
    // full cover's check).
    let quarter = ["--width", "600", "--checkpoint-every", "2"];
    render.pod.args.extend(quarter.map(String::from));
    let merge = Job::read("merge-job.yaml");
    let completions = render.completions.unwrap() as usize;
    let dir = temp_dir("indexed-job");
    let volume = dir.join("volume");
    std::fs::create_dir_all(&volume).unwrap();
    make_writable_by(
        &volume,
        render.pod.user,
        render.pod.fs_group.unwrap_or(render.pod.group),
    );
    let containers = Containers {
        prefix: format!("tessera-test-{}-", std::process::id()),
    };
    // The pods of the job; `parallelism` of them at a time.
    let parallelism = render.parallelism.unwrap_or(1) as usize;
    let running: Vec<Mutex<Option<String>>> = (0..completions).map(|_| Mutex::new(None)).collect();
    let done: Vec<AtomicBool> = (0..completions).map(|_| AtomicBool::new(false)).collect();
    let next = Mutex::new(0usize);
    let results: Mutex<Vec<(usize, Vec<Attempt>)>> = Mutex::new(Vec::new());
    // The host path of a file the pods write as `path` on the volume.
    let parts_dir = &render.pod.claims[0].1;
    let on_host = |pattern: &str, index: usize| {
        let path = expand(
            pattern,
            &[("JOB_COMPLETION_INDEX".into(), index.to_string())],
        );
        volume.join(Path::new(&path).strip_prefix(parts_dir).unwrap())
    };
    let checkpoint = flag_value(&render.pod.args, "--checkpoint").unwrap();
    std::thread::scope(|s| {
        for _ in 0..parallelism.min(completions) {
            s.spawn(|| {
                loop {
                    let index = {
                        let mut n = next.lock().unwrap();
                        if *n == completions {
                            return;
                        }
                        *n += 1;
                        *n - 1
                    };
                    let name = format!("{}render-{index}", containers.prefix);
                    let attempts = run_pod(
                        &render.pod,
                        &image,
                        Some(index),
                        &volume,
                        render.backoff_limit,
                        &name,
                        &running[index],
                    );
                    done[index].store(true, Ordering::SeqCst);
                    results.lock().unwrap().push((index, attempts));
                }
            });
        }
        // Pod 0 is killed outright and pod 1 evicted (SIGTERM), each once its first
        // checkpoint is saved and while it is still rendering.
        for (index, signal) in [(0, "KILL"), (1, "TERM")] {
            let saved = wait_for_file(&on_host(checkpoint, index), || {
                done[index].load(Ordering::SeqCst)
            });
            assert!(
                saved,
                "pod {index} ended or stalled before saving a checkpoint"
            );
            let name = running[index].lock().unwrap().clone();
            let name = name.expect("the pod is running");
            let o = podman(&["kill", "--signal", signal, &name]);
            assert!(o.status.success(), "kill {name}: {}", text(&o.stderr));
        }
    });
    let mut results = results.into_inner().unwrap();
    results.sort_by_key(|(i, _)| *i);
    let expected_threads =
        (render.pod.cpu_limit as usize).min(std::thread::available_parallelism().unwrap().get());
    for (index, attempts) in &results {
        let last = attempts.last().unwrap();
        assert_eq!(last.code, Some(0), "pod {index} failed: {}", last.log);
        assert_eq!(
            threads_of(&last.log),
            Some(expected_threads),
            "pod {index}: {}",
            last.log
        );
        let restarted = *index < 2;
        assert_eq!(attempts.len(), if restarted { 2 } else { 1 }, "pod {index}");
        if restarted {
            let (killed, resumed) = (&attempts[0], &attempts[1]);
            let expected_code = if *index == 0 { 137 } else { 130 };
            assert_eq!(
                killed.code,
                Some(expected_code),
                "pod {index}: {}",
                killed.log
            );
            let resume_line = (resumed.log.lines())
                .find(|l| l.contains("resuming from"))
                .unwrap_or_else(|| panic!("pod {index} did not resume: {}", resumed.log));
            assert!(!resume_line.contains("(0.0% done)"), "{resume_line}");
        }
    }
    // The merge job, once every index has completed.
    let merge_attempts = run_pod(
        &merge.pod,
        &image,
        None,
        &volume,
        merge.backoff_limit,
        &format!("{}merge", containers.prefix),
        &Mutex::new(None),
    );
    let last = merge_attempts.last().unwrap();
    assert_eq!(last.code, Some(0), "merge failed: {}", last.log);
    let output = flag_value(&merge.pod.args, "-o").unwrap();
    let merged = std::fs::read(on_host(output, 0)).expect("the merged image");
    // The single render is the render job's arguments without the sharding: the cover at
    // its own settings but the width, which is the README's picture, made by `tessera
    // render scenes/cover.toml --width 600`. The merged image's sums must be that picture's,
    // on this machine a glibc build's, so this also holds the static binary to its bytes.
    let mut single: Vec<String> = render.pod.args.clone();
    for flag in ["--shard", "--checkpoint", "-o", "--checkpoint-every"] {
        single = without_flag(&single, flag);
    }
    assert_eq!(
        single,
        ["render", "scenes/cover.toml", "--width", "600"],
        "the job renders the cover"
    );
    assert_eq!(
        recipe_sums(&on_host(output, 0)),
        recipe_sums(&root().join("docs/cover-600x400.png")),
        "the merged image is not the single render's (the README's picture)"
    );
    assert!(!merged.is_empty());
    drop(containers);
}
