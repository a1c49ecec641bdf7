//! Helpers shared by the end-to-end tests: paths, loading scenes, rendering quietly.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tessera::film::Film;
use tessera::render::{self, RenderOptions, RenderStats};
use tessera::scene::{Overrides, Scene};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The image hash benches/workloads.toml keeps for the standard workload `name`.
pub fn kept_workload_image(name: &str) -> String {
    let workloads = std::fs::read_to_string(root().join("benches/workloads.toml")).unwrap();
    let entry = workloads
        .split(&format!("name = \"{name}\""))
        .nth(1)
        .unwrap_or_else(|| panic!("benches/workloads.toml has no workload {name}"));
    let image = entry.split("image = \"").nth(1).unwrap();
    image.split('"').next().unwrap().to_owned()
}

/// The hash of the exact sums an image's recipe records (`tessera info --json`): what makes
/// two renders the same render, whatever their files' other bytes.
pub fn recipe_sums(image: &Path) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(["info", "--json"])
        .arg(image)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "info {}: {}",
        image.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let recipe: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let sums = recipe["sums"].as_str();
    sums.unwrap_or_else(|| panic!("{} has no sums", image.display()))
        .to_owned()
}

pub fn scene_path(name: &str) -> PathBuf {
    root().join("scenes").join(name)
}

/// The book's figures (CC0, like the book), kept with the tests.
pub fn figures_dir() -> PathBuf {
    root().join("tests").join("data").join("book-figures")
}

/// The cover scene's path, as an argument.
pub fn cover() -> String {
    scene_path("cover.toml").to_string_lossy().into_owned()
}

/// A command running the `tessera` binary under test. Benchmarks record their results in
/// a database of this test process (`TESSERA_DB`), never in the user's own.
pub fn tessera() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_tessera"));
    command.env("TESSERA_DB", test_results_db());
    command
}

/// The results database of this test process.
pub fn test_results_db() -> PathBuf {
    std::env::temp_dir().join(format!("tessera-test-{}-results.db", std::process::id()))
}

/// Runs tessera with `args` in `dir`.
pub fn run(args: &[&str], dir: &Path) -> Output {
    run_in_env(args, &[], dir)
}

/// Runs tessera with `args` in `dir`, with the environment variables `env` set.
pub fn run_in_env(args: &[&str], env: &[(&str, &str)], dir: &Path) -> Output {
    tessera()
        .args(args)
        .envs(env.iter().copied())
        .current_dir(dir)
        .output()
        .expect("run tessera")
}

/// Runs tessera with `args` in `dir`; it must succeed.
/// Runs `command` to its end with its output captured, killing it and failing the test
/// after a minute: for a command that, broken, would wait forever (on a pipe nobody
/// writes, an axis without end). Its output is read as it comes, so a long one cannot
/// fill the pipe and look like a hang.
pub fn output_within_a_minute(command: &mut Command, what: &str) -> Output {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let drain = |mut pipe: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            pipe.read_to_end(&mut bytes).unwrap();
            bytes
        })
    };
    let stdout = drain(Box::new(child.stdout.take().unwrap()));
    let stderr = drain(Box::new(child.stderr.take().unwrap()));
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what} ran for a minute");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    Output {
        status: child.wait().unwrap(),
        stdout: stdout.join().unwrap(),
        stderr: stderr.join().unwrap(),
    }
}

pub fn ok(args: &[&str], dir: &Path) {
    ok_in_env(args, &[], dir);
}

/// Runs tessera with `args` in `dir` and the environment `env`; it must succeed.
pub fn ok_in_env(args: &[&str], env: &[(&str, &str)], dir: &Path) {
    let o = run_in_env(args, env, dir);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
}

/// What a run wrote to standard error.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub fn load(path: &Path, overrides: Overrides) -> Scene {
    Scene::load(path, &overrides).unwrap_or_else(|e| panic!("{e}"))
}

pub fn load_text(text: &str) -> Scene {
    Scene::parse(text, Path::new("test.toml"), &Overrides::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

pub fn render_with(scene: &Scene, threads: usize, tile: u32) -> (Film, RenderStats) {
    let opts = RenderOptions {
        threads: Some(threads),
        tile,
        ..RenderOptions::default()
    };
    render::render(scene, &opts, &|_| {}).expect("thread pool")
}

pub fn render(scene: &Scene) -> Film {
    render_with(scene, 2, 16).0
}

/// A fresh, empty temporary directory for one test. The first one a run makes removes
/// what earlier runs left (`remove_ended_runs_files`), so that a run's directories stay for a
/// look after a failure, until the next run, and no more pile up: a whole run leaves about
/// 230 of them, 350 MB.
pub fn temp_dir(name: &str) -> PathBuf {
    static SWEPT: std::sync::Once = std::sync::Once::new();
    SWEPT.call_once(|| remove_ended_runs_files(&std::env::temp_dir()));
    let dir = std::env::temp_dir().join(format!("tessera-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Removes, from `tmp`, the files and directories (`tessera-test-PID-...`) of test runs whose
/// process has ended, where they are this user's: a run still going (this one, or another
/// beside it) keeps its own, and another user's are theirs.
pub fn remove_ended_runs_files(tmp: &Path) {
    use std::os::unix::fs::MetadataExt;
    let Ok(me) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(tmp) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = (name.to_str())
            .and_then(|n| n.strip_prefix("tessera-test-"))
            .and_then(|rest| rest.split('-').next())
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        let Ok(meta) = entry.path().symlink_metadata() else {
            continue;
        };
        if pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists() {
            continue;
        }
        if meta.uid() != me {
            continue;
        }
        let _ = if meta.is_dir() {
            std::fs::remove_dir_all(entry.path())
        } else {
            std::fs::remove_file(entry.path())
        };
    }
}

/// The part or checkpoint file `part` (its bytes) with its JSON header as `edit` makes it,
/// its length and checksum made to agree: what a stranger who edits one by hand hands over.
pub fn with_part_header(part: &[u8], edit: impl FnOnce(&[u8]) -> Vec<u8>) -> Vec<u8> {
    let len = u64::from_le_bytes(part[16..24].try_into().unwrap()) as usize;
    let header = edit(&part[24..24 + len]);
    let mut edited = part[..16].to_vec();
    edited.extend((header.len() as u64).to_le_bytes());
    edited.extend(&header);
    edited.extend(&part[24 + len..part.len() - 8]);
    edited.extend(xxhash_rust::xxh3::xxh3_64(&edited).to_le_bytes());
    edited
}

/// A fresh temporary directory holding `text` as `scene.toml`.
pub fn dir_with_scene(name: &str, text: impl AsRef<[u8]>) -> PathBuf {
    let dir = temp_dir(name);
    std::fs::write(dir.join("scene.toml"), text).unwrap();
    dir
}

/// Skips the calling test for `why` (something this machine lacks), saying so on the real
/// standard error, which the test harness does not capture, so `cargo test` shows it.
/// Under `CI=true` a skip is a failure: CI must run every test.
pub fn skip(test: &str, why: &str) {
    use std::io::Write;
    assert!(
        std::env::var("CI").as_deref() != Ok("true"),
        "{test}: CI=true, but {why}"
    );
    let _ = writeln!(std::io::stderr(), "skipped {test}: {why}");
}

/// Whether the heavy tests are on (`TESSERA_HEAVY_TESTS=1`, as `.ci/run` sets): a real
/// Slurm cluster, Podman, headless Chromium, emulated CPUs, the slowest examples and the
/// fuzzer at full scale. Off, the calling test is skipped, saying so (under `CI=true`, a
/// failure: CI runs them all).
pub fn heavy(test: &str) -> bool {
    if heavy_on() {
        return true;
    }
    skip(
        test,
        "a heavy test: TESSERA_HEAVY_TESTS=1 runs it (.ci/run does)",
    );
    false
}

/// `TESSERA_HEAVY_TESTS=1`, without a word when it is not.
pub fn heavy_on() -> bool {
    std::env::var("TESSERA_HEAVY_TESTS").as_deref() == Ok("1")
}

/// Runs `script` with `sh` in `dir`, in a private mount namespace where `dir/small` is a
/// filesystem of `kib` KiB, so that writing there fills the disk. `None` if this machine
/// cannot make one (no `unshare`, or user namespaces turned off).
pub fn in_a_small_filesystem(dir: &Path, kib: u32, script: &str) -> Option<Output> {
    std::fs::create_dir_all(dir.join("small")).unwrap();
    let mount = format!(
        "mount -t tmpfs -o size={kib}k none '{}/small'",
        dir.display()
    );
    let in_namespace = |script: &str| {
        Command::new("unshare")
            .args(["-rm", "sh", "-c", script])
            .current_dir(dir)
            .output()
    };
    if !in_namespace(&mount).is_ok_and(|o| o.status.success()) {
        return None;
    }
    Some(in_namespace(&format!("{mount} && {script}")).unwrap())
}

/// Flags this machine's Podman needs and a cluster does not: the runtime that works with
/// this kernel's cgroups, and limits within what the sandbox lets a container set.
pub const PODMAN_FLAGS: &[&str] = &[
    "--runtime",
    "runc",
    "--ulimit",
    "nofile=1024:1024",
    "--ulimit",
    "nproc=4096:4096",
];

/// The container image under test (`TESSERA_IMAGE`, which `.ci/run` builds with
/// deploy/container/build.sh), if Podman runs here and has it; otherwise why not.
pub fn container_image() -> Result<String, String> {
    let podman = |args: &[&str]| Command::new("podman").args(args).output();
    if let Err(e) = podman(&["--version"]) {
        return Err(format!(
            "podman cannot run ({e}): install Debian's podman and runc"
        ));
    }
    let image = std::env::var("TESSERA_IMAGE").map_err(|_| {
        "TESSERA_IMAGE is not set: build the image with deploy/container/build.sh (.ci/run does)"
            .to_owned()
    })?;
    match podman(&["image", "exists", &image]) {
        Ok(o) if o.status.success() => Ok(image),
        _ => Err(format!("TESSERA_IMAGE={image} is not an image Podman has")),
    }
}

/// A valid small scene (16×9, one red sphere), for tests to break one line at a time.
pub const GOOD: &str = r#"[image]
width = 16
height = 9
samples_per_pixel = 1
max_depth = 5

[materials.red]
type = "lambertian"
albedo = [0.9, 0.1, 0.1]

[[spheres]]
center = [0.0, 0.0, -1.0]
radius = 0.5
material = "red"
"#;

#[test]
fn the_files_of_ended_test_runs_are_removed_and_those_of_running_ones_kept() {
    let tmp = temp_dir("ended-runs");
    let mut ended = Command::new("true").spawn().unwrap();
    let ended_pid = ended.id();
    ended.wait().unwrap();
    let mut running = Command::new("sleep").arg("60").spawn().unwrap();
    let names = [
        format!("tessera-test-{ended_pid}-a"),
        format!("tessera-test-{ended_pid}-results.db"),
        format!("tessera-test-{}-b", std::process::id()),
        format!("tessera-test-{}-c", running.id()),
        format!("other-{ended_pid}-d"),
        "tessera-test-x-e".to_owned(),
    ];
    for (i, name) in names.iter().enumerate() {
        if name.ends_with(".db") {
            std::fs::write(tmp.join(name), "a database").unwrap();
        } else {
            std::fs::create_dir_all(tmp.join(name).join("inner")).unwrap();
            std::fs::write(tmp.join(name).join("inner/file"), i.to_string()).unwrap();
        }
    }
    remove_ended_runs_files(&tmp);
    let _ = running.kill();
    let _ = running.wait();
    let left: Vec<bool> = names.iter().map(|n| tmp.join(n).exists()).collect();
    assert_eq!(left, [false, false, true, true, true, true], "{names:?}");
}
