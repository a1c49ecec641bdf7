//! The Slurm scripts in `deploy/slurm/` against a real Slurm cluster: an array of shards and
//! its merge give the bytes of a single render, also when a task is requeued mid-render,
//! when the array has one task, and when tessera runs from the container image.
//!
//! The cluster is whatever `sinfo` reaches (`SLURM_CONF`); `deploy/slurm/local-cluster.sh
//! start` makes a single-node one, as `.ci/run` does. Without one the tests are skipped, saying
//! why, except under `CI=true`, where a missing cluster fails them.

use crate::common::*;
use std::path::PathBuf;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// How long a submitted render and its merge may take before the test gives up.
const PATIENCE: Duration = Duration::from_secs(240);

fn command(program: &str, args: &[&str]) -> std::io::Result<Output> {
    Command::new(program).args(args).output()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// True when a Slurm cluster answers; otherwise says why the test is skipped (or, under
/// `CI=true`, fails it).
fn cluster_answers() -> bool {
    if !heavy("the Slurm test") {
        return false;
    }
    let why = match command("sinfo", &["-h", "-o", "%t"]) {
        Ok(o) if o.status.success() && !o.stdout.is_empty() => return true,
        Ok(o) => format!("`sinfo` finds no cluster: {}", text(&o.stderr).trim()),
        Err(e) => format!("`sinfo` cannot run ({e}): Slurm is not installed"),
    };
    let start = "start one with `eval \"$(deploy/slurm/local-cluster.sh start)\"` (as root)";
    skip(
        "the Slurm test",
        &format!("no Slurm cluster: {why}; {start}"),
    );
    false
}

/// The daemons of a cluster `local-cluster.sh` made listen on the loopback address alone,
/// not on every address of the machine (Slurm's default, which put slurmctld and slurmd on
/// 0.0.0.0: open to the network, guarded by munge alone).
#[test]
fn the_local_cluster_s_daemons_listen_on_loopback_only() {
    if !cluster_answers() {
        return;
    }
    let conf = std::env::var("SLURM_CONF").unwrap_or_default();
    let text = std::fs::read_to_string(&conf).unwrap_or_default();
    if !text.starts_with("# Written by deploy/slurm/local-cluster.sh") {
        skip(
            "the local cluster's listening test",
            &format!("SLURM_CONF ({conf}) is not a cluster local-cluster.sh made"),
        );
        return;
    }
    let setting = |name: &str| -> u16 {
        text.lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix('='))
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("{conf} gives no {name}"))
    };
    for port in [setting("SlurmctldPort"), setting("SlurmdPort")] {
        // /proc/net/tcp{,6}: "sl local_address rem_address st …", addresses in hex with
        // the port after a colon; state 0A is LISTEN.
        let mut addresses = Vec::new();
        for table in ["/proc/net/tcp", "/proc/net/tcp6"] {
            for line in std::fs::read_to_string(table).unwrap().lines().skip(1) {
                let fields: Vec<&str> = line.split_whitespace().collect();
                let Some((address, at)) = fields[1].rsplit_once(':') else {
                    continue;
                };
                if fields[3] == "0A" && u16::from_str_radix(at, 16) == Ok(port) {
                    addresses.push(address.to_owned());
                }
            }
        }
        assert!(!addresses.is_empty(), "nothing listens on port {port}");
        // 127.0.0.1, as the kernel prints it: four bytes in the machine's order.
        let loopback = format!("{:08X}", u32::from_ne_bytes([127, 0, 0, 1]));
        assert!(
            addresses.iter().all(|a| *a == loopback),
            "port {port} listens on {addresses:?}, not 127.0.0.1 ({loopback}) alone"
        );
    }
}

/// The jobs one test submitted; cancelled when the test ends, however it ends.
struct Jobs(Vec<String>);

impl Drop for Jobs {
    fn drop(&mut self) {
        if !self.0.is_empty() {
            let _ = Command::new("scancel").args(&self.0).output();
        }
    }
}

/// A render of the cover through `deploy/slurm/submit.sh` in its own directory.
struct SlurmRender {
    dir: PathBuf,
    extra: String,
    /// More variables for submit.sh (CONTAINER, …).
    env: Vec<(String, String)>,
}

impl SlurmRender {
    fn new(name: &str, extra: &str) -> Self {
        Self {
            dir: temp_dir(&format!("slurm-{name}")),
            extra: extra.to_owned(),
            env: Vec::new(),
        }
    }

    /// Submits `tasks` array tasks and the merge; returns (render array id, merge id).
    fn submit(&self, tasks: u32, jobs: &mut Jobs) -> (String, String) {
        let o = Command::new(root().join("deploy/slurm/submit.sh"))
            .arg(tasks.to_string())
            .current_dir(&self.dir)
            .env("SCENE", scene_path("cover.toml"))
            .env("EXTRA", &self.extra)
            .env("OUTDIR", self.dir.join("parts"))
            .env("IMAGE", self.dir.join("merged.png"))
            .env("TESSERA", env!("CARGO_BIN_EXE_tessera"))
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .output()
            .expect("run submit.sh");
        assert!(o.status.success(), "submit.sh: {}", text(&o.stderr));
        let out = text(&o.stdout);
        let id = |what: &str| {
            out.lines()
                .find_map(|l| l.strip_prefix(what))
                .unwrap_or_else(|| panic!("no `{what}` line in: {out}"))
                .trim()
                .to_owned()
        };
        let ids = (id("render "), id("merge "));
        jobs.0.extend([ids.0.clone(), ids.1.clone()]);
        ids
    }

    /// The same render straight through, on this machine.
    fn single(&self) -> Vec<u8> {
        let o = tessera()
            .arg("render")
            .arg(scene_path("cover.toml"))
            .args(["-q", "-o", "single.png"])
            .args(self.extra.split_whitespace())
            .current_dir(&self.dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", text(&o.stderr));
        std::fs::read(self.dir.join("single.png")).unwrap()
    }

    /// Checks that the merged image has the single render's bytes.
    fn assert_merged_equals_single(&self) {
        assert!(self.merged() == self.single(), "merged != single render");
    }

    fn merged(&self) -> Vec<u8> {
        std::fs::read(self.dir.join("merged.png")).unwrap_or_else(|e| {
            panic!("no merged image ({e}); logs:\n{}", self.logs());
        })
    }

    fn logs(&self) -> String {
        let mut all = String::new();
        for entry in std::fs::read_dir(&self.dir).unwrap().flatten() {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "log") {
                let body = std::fs::read_to_string(&path).unwrap_or_default();
                all.push_str(&format!("--- {}\n{body}", path.display()));
            }
        }
        all
    }
}

/// `scontrol show job`'s fields of `job`, one map per job (an array job has one per task);
/// empty once Slurm has forgotten the job.
fn job_fields(job: &str) -> Vec<Vec<(String, String)>> {
    let Ok(o) = command("scontrol", &["show", "job", "-o", job]) else {
        return Vec::new();
    };
    text(&o.stdout)
        .lines()
        .map(|line| {
            line.split_whitespace()
                .filter_map(|kv| kv.split_once('='))
                .map(|(k, v)| (k.to_owned(), v.to_owned()))
                .collect()
        })
        .collect()
}

fn field<'a>(job: &'a [(String, String)], name: &str) -> &'a str {
    job.iter()
        .find(|(k, _)| k == name)
        .map_or("", |(_, v)| v.as_str())
}

/// Waits until job `id` has finished; panics, with the logs, if it failed or takes too long.
fn wait_for(render: &SlurmRender, id: &str) {
    let start = Instant::now();
    loop {
        let jobs = job_fields(id);
        let states: Vec<&str> = jobs.iter().map(|j| field(j, "JobState")).collect();
        if !states.is_empty() && states.iter().all(|&s| s == "COMPLETED") {
            return;
        }
        if let Some(bad) = states.iter().find(|&&s| {
            [
                "FAILED",
                "CANCELLED",
                "TIMEOUT",
                "NODE_FAIL",
                "OUT_OF_MEMORY",
            ]
            .contains(&s)
        }) {
            panic!("job {id} ended {bad}; logs:\n{}", render.logs());
        }
        assert!(
            start.elapsed() < PATIENCE,
            "job {id} still {states:?} after {PATIENCE:?}; logs:\n{}",
            render.logs()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn an_array_of_shards_merges_to_the_single_render() {
    if !cluster_answers() {
        return;
    }
    let mut jobs = Jobs(Vec::new());
    let render = SlurmRender::new("four", "--width 120 --spp 16");
    let (_, merge) = render.submit(4, &mut jobs);
    wait_for(&render, &merge);
    render.assert_merged_equals_single();
    let parts = render.dir.join("parts");
    for task in 0..4 {
        assert!(parts.join(format!("shard-{task}.part")).exists());
    }
    assert!(
        !parts.join("checkpoints").exists(),
        "checkpoints were left beside the parts"
    );
}

#[test]
fn an_array_of_one_task_works() {
    if !cluster_answers() {
        return;
    }
    let mut jobs = Jobs(Vec::new());
    let render = SlurmRender::new("one", "--width 90 --spp 6");
    let (_, merge) = render.submit(1, &mut jobs);
    wait_for(&render, &merge);
    render.assert_merged_equals_single();
}

#[test]
fn an_array_can_run_tessera_from_the_container_image() {
    if !cluster_answers() {
        return;
    }
    let image = match container_image() {
        Ok(image) => image,
        Err(why) => return skip("an_array_can_run_tessera_from_the_container_image", &why),
    };
    let mut jobs = Jobs(Vec::new());
    let mut render = SlurmRender::new("container", "--width 120 --spp 16");
    render.env = vec![
        ("CONTAINER".into(), image),
        ("PODMAN_FLAGS".into(), PODMAN_FLAGS.join(" ")),
        // No binary to fall back on: the image must do the work.
        ("TESSERA".into(), "/nonexistent/tessera".into()),
    ];
    let (_, merge) = render.submit(2, &mut jobs);
    wait_for(&render, &merge);
    render.assert_merged_equals_single();
}

/// Waits until job `job` is `what`, as `test` tells from its fields.
fn wait_until(
    render: &SlurmRender,
    job: &str,
    what: &str,
    test: impl Fn(&[(String, String)]) -> bool,
) {
    let start = Instant::now();
    while !job_fields(job).first().is_some_and(|j| test(j)) {
        assert!(
            start.elapsed() < PATIENCE,
            "job {job} never {what}; logs:\n{}",
            render.logs()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn scontrol(args: &[&str]) {
    let o = command("scontrol", args).expect("run scontrol");
    assert!(o.status.success(), "scontrol {args:?}: {}", text(&o.stderr));
}

#[test]
fn a_task_requeued_while_running_still_gives_the_same_bytes() {
    if !cluster_answers() {
        return;
    }
    let mut jobs = Jobs(Vec::new());
    // Long enough per task (a few seconds) to be caught in the middle.
    let render = SlurmRender::new("requeue", "--width 240 --spp 1200 --checkpoint-every 0.1");
    let (array, merge) = render.submit(4, &mut jobs);
    let task = format!("{array}_0");
    let checkpoint = render.dir.join("parts/checkpoints/shard-0.ckpt");
    wait_until(&render, &task, "ran with a checkpoint saved", |j| {
        field(j, "JobState") == "RUNNING" && checkpoint.exists()
    });
    scontrol(&["requeue", &task]);
    // Once its render has stopped, Slurm holds the requeued task back for two minutes; let
    // it start again at once.
    wait_until(&render, &task, "pending again after the requeue", |j| {
        field(j, "JobState") == "PENDING"
    });
    // It stopped mid-render, its progress saved (SIGTERM), to be resumed.
    let saved = tessera::partial::Part::load(&checkpoint)
        .unwrap_or_else(|e| panic!("no checkpoint after the requeue: {e}"));
    assert!(
        !saved.is_complete(),
        "task 0 had finished before the requeue"
    );
    scontrol(&["update", &format!("JobId={task}"), "StartTime=now"]);
    wait_for(&render, &merge);
    let restarts = job_fields(&task)
        .first()
        .map(|j| field(j, "Restarts").to_owned());
    assert_eq!(restarts.as_deref(), Some("1"), "task 0 was not requeued");
    render.assert_merged_equals_single();
}

/// `submit.sh 010` queued an array of 8 tasks (bash read 010 as octal), `submit.sh 08` failed
/// with bash's "value too great for base" (exit 1), and `00` passed as a number of tasks.
/// N is read as decimal. No cluster needed: a stand-in `sbatch` records what it is given.
#[test]
fn the_number_of_tasks_is_read_as_decimal() {
    use std::os::unix::fs::PermissionsExt;
    let dir = temp_dir("slurm-submit-decimal");
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let sbatch = bin.join("sbatch");
    std::fs::write(
        &sbatch,
        "#!/bin/sh\necho \"$*\" >> \"$SBATCH_LOG\"\necho 7\n",
    )
    .unwrap();
    std::fs::set_permissions(&sbatch, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let submit = |n: &str, log: &std::path::Path| {
        Command::new(root().join("deploy/slurm/submit.sh"))
            .arg(n)
            .env("PATH", &path)
            .env("CPUS_PER_TASK", "2")
            .env("SBATCH_LOG", log)
            .current_dir(&dir)
            .output()
            .expect("run submit.sh")
    };
    for (n, array) in [
        ("8", "--array=0-7 "),
        ("010", "--array=0-9 "),
        ("08", "--array=0-7 "),
    ] {
        let log = dir.join(format!("sbatch-{n}.log"));
        let o = submit(n, &log);
        assert!(o.status.success(), "{n}: {}", text(&o.stderr));
        let queued = std::fs::read_to_string(&log).unwrap();
        assert!(queued.contains(array), "{n}: {queued}");
    }
    for n in [
        "0",
        "00",
        "x",
        "-1",
        "99999999999999999999",
        "18446744073709551617",
    ] {
        let log = dir.join("refused.log");
        let o = submit(n, &log);
        assert_eq!(o.status.code(), Some(2), "{n}: {}", text(&o.stderr));
        assert!(
            text(&o.stderr).contains("N must be a positive number of tasks"),
            "{n}: {}",
            text(&o.stderr)
        );
        assert!(!log.exists(), "{n}: queued");
    }
}

/// What `deploy/slurm/podman-tessera ARGS`, run in `work`, hands Podman: a stand-in `podman`
/// (in `dir/bin`) prints its arguments, one a line. No Podman needed.
fn podman_tessera_hands_podman(
    dir: &std::path::Path,
    work: &std::path::Path,
    args: &[&str],
) -> Vec<String> {
    use std::os::unix::fs::PermissionsExt;
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let podman = bin.join("podman");
    std::fs::write(&podman, "#!/bin/sh\nprintf '%s\\n' \"$@\"\n").unwrap();
    std::fs::set_permissions(&podman, std::fs::Permissions::from_mode(0o755)).unwrap();
    let o = Command::new(root().join("deploy/slurm/podman-tessera"))
        .args(args)
        .env(
            "PATH",
            format!("{}:{}", bin.display(), std::env::var("PATH").unwrap()),
        )
        .env("CONTAINER", "tessera:test")
        .current_dir(work)
        .output()
        .expect("run podman-tessera");
    assert!(o.status.success(), "{}", text(&o.stderr));
    text(&o.stdout).lines().map(str::to_owned).collect()
}

/// The `--mount` values among Podman's arguments.
fn mounts(args: &[String]) -> Vec<&str> {
    (args.windows(2))
        .filter(|w| w[0] == "--mount")
        .map(|w| w[1].as_str())
        .collect()
}

/// The mount of `path` at its own path: a CSV value whose fields are quoted, a quote
/// doubled, so that it is one path whatever it holds.
fn bind_mount(path: &std::path::Path) -> String {
    let field = path.display().to_string().replace('"', "\"\"");
    format!("type=bind,\"src={field}\",\"dst={field}\"")
}

/// podman-tessera mounted each directory with `--volume DIR:DIR`, which Podman splits at `:`
/// and `,`: a working directory named `a:b,c` broke every task; and it mounted only the
/// directories of absolute paths, so `../scenes/a.toml` or `--checkpoint=/scratch/c.ckpt`
/// named a file the container did not have.
#[test]
fn podman_tessera_mounts_the_directory_of_every_path_it_is_given() {
    let dir = temp_dir("slurm-podman-mounts");
    let work = dir.join("run: a,\"b\"");
    let out_dir = dir.join("out dir");
    for d in [&work, &dir.join("scenes"), &out_dir] {
        std::fs::create_dir_all(d).unwrap();
    }
    let checkpoint = format!("--checkpoint={}/c.ckpt", out_dir.display());
    let given = [
        "render",
        "../scenes/a.toml",
        "--shard",
        "0/4",
        "-o",
        "x/y.png",
        &checkpoint,
    ];
    let args = podman_tessera_hands_podman(&dir, &work, &given);
    let expected = [
        bind_mount(&work),
        bind_mount(&dir.join("scenes")),
        bind_mount(&out_dir),
    ];
    assert_eq!(mounts(&args), expected, "{args:?}");
    assert!(!args.iter().any(|a| a == "--volume"), "{args:?}");
    // The arguments reach tessera as they were given.
    let image = args.iter().position(|a| *a == "tessera:test").unwrap();
    assert_eq!(args[image + 1..], given);
}

/// A link in the working directory to a directory outside it (`out -> /scratch/out`, as a
/// cluster's home links to its scratch space) named a file the container did not have:
/// `-o out/a.png` failed with "the directory out does not exist in this podman container"
/// and a linked scene with "no such scene file". The directory a path's links lead to is
/// mounted too.
#[test]
fn podman_tessera_mounts_the_directory_a_path_s_links_lead_to() {
    let dir = temp_dir("slurm-podman-links");
    let work = dir.join("work");
    let scratch = dir.join("scratch");
    let shared = dir.join("shared");
    for d in [&work, &scratch, &shared] {
        std::fs::create_dir_all(d).unwrap();
    }
    std::os::unix::fs::symlink(&scratch, work.join("out")).unwrap();
    std::os::unix::fs::symlink(shared.join("a.toml"), work.join("a.toml")).unwrap();
    let args = podman_tessera_hands_podman(&dir, &work, &["render", "./a.toml", "-o", "out/a.png"]);
    let expected = [bind_mount(&work), bind_mount(&shared), bind_mount(&scratch)];
    assert_eq!(mounts(&args), expected, "{args:?}");
}

/// local-cluster.sh lives in /tmp by default and trusted whatever was there: another user's
/// directory of that name, its pid files naming any process, made root's `start` say
/// "already running" and point Slurm's commands at that user's slurm.conf (whose plugins they
/// load), and `stop` kill the processes named. A directory another user owns, one others may
/// write, or a link is refused by every command, and nothing is stopped. No Slurm needed.
#[test]
fn local_cluster_refuses_a_directory_another_user_made() {
    let dir = temp_dir("slurm-planted");
    let planted = dir.join("cluster");
    std::fs::create_dir(&planted).unwrap();
    // A process of ours the planted pid files name: it must outlive `stop`.
    let mut victim = Command::new("sleep").arg("600").spawn().unwrap();
    for name in ["slurmctld.pid", "slurmd.pid"] {
        std::fs::write(planted.join(name), victim.id().to_string()).unwrap();
    }
    std::fs::write(planted.join("slurm.conf"), "PluginDir=/nonexistent\n").unwrap();
    if std::os::unix::fs::chown(&planted, Some(65534), Some(65534)).is_err() {
        let _ = victim.kill();
        let _ = victim.wait();
        return skip(
            "local_cluster_refuses_a_directory_another_user_made",
            "changing a file's owner needs root",
        );
    }
    let run = |command: &str| local_cluster(command, &planted, None);
    let refused = |command: &str, why: &str| {
        let o = run(command);
        assert!(!o.status.success(), "{command}: {}", text(&o.stderr));
        assert!(o.stdout.is_empty(), "{command}: {}", text(&o.stdout));
        assert!(
            text(&o.stderr).contains(why),
            "{command}: {}",
            text(&o.stderr)
        );
    };
    for command in ["status", "stop", "start"] {
        refused(command, "belongs to another user (uid 65534)");
    }
    std::fs::set_permissions(
        &planted,
        std::os::unix::fs::PermissionsExt::from_mode(0o777),
    )
    .unwrap();
    std::os::unix::fs::chown(&planted, Some(0), Some(0)).unwrap();
    refused("stop", "may be written by other users (mode 777)");
    let link = dir.join("link");
    std::os::unix::fs::symlink(&planted, &link).unwrap();
    let o = local_cluster("stop", &link, None);
    assert!(
        text(&o.stderr).contains("is not a directory (a link"),
        "{}",
        text(&o.stderr)
    );
    assert!(
        victim.try_wait().unwrap().is_none(),
        "stop killed a process another user named"
    );
    let _ = victim.kill();
    let _ = victim.wait();
}

/// local-cluster.sh checked its directory but not the directories above it: with
/// `TESSERA_SLURM_DIR=/tmp/work/slurm` in a `/tmp/work` another user made, root's `start` ran
/// the cluster there, and that user then renamed root's directory away and put their own in
/// its place, whose slurm.conf (`PluginDir=` their own) root's next `sinfo` read, running
/// their code as root. Every directory above the cluster's must be root's or this user's and
/// not writable by others unless sticky (as /tmp is); nothing is started otherwise. No Slurm
/// needed.
#[test]
fn local_cluster_refuses_a_directory_whose_parent_another_user_controls() {
    use std::os::unix::fs::PermissionsExt;
    let dir = temp_dir("slurm-parent");
    let theirs = dir.join("theirs");
    std::fs::create_dir(&theirs).unwrap();
    if std::os::unix::fs::chown(&theirs, Some(65534), Some(65534)).is_err() {
        return skip(
            "local_cluster_refuses_a_directory_whose_parent_another_user_controls",
            "changing a file's owner needs root",
        );
    }
    // Root's own directories below another user's, and one others may write.
    let below = theirs.join("ours");
    std::fs::create_dir(&below).unwrap();
    std::os::unix::fs::chown(&below, Some(0), Some(0)).unwrap();
    let open = dir.join("open");
    std::fs::create_dir(&open).unwrap();
    std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o777)).unwrap();
    let run = |cluster: &std::path::Path, command: &str| local_cluster(command, cluster, None);
    for (cluster, above, why) in [
        (
            theirs.join("slurm"),
            &theirs,
            "belongs to another user (uid 65534)",
        ),
        (
            below.join("slurm"),
            &theirs,
            "belongs to another user (uid 65534)",
        ),
        (
            open.join("slurm"),
            &open,
            "may be written by other users (mode 777)",
        ),
    ] {
        for command in ["status", "stop", "start"] {
            let o = run(&cluster, command);
            let said = text(&o.stderr);
            assert!(
                !o.status.success(),
                "{command} {}: {said}",
                cluster.display()
            );
            assert!(o.stdout.is_empty(), "{command}: {}", text(&o.stdout));
            assert!(
                said.contains(&format!("{}, above", above.display())) && said.contains(why),
                "{command} {}: {said}",
                cluster.display()
            );
            assert!(!cluster.exists(), "{command} made {}", cluster.display());
        }
    }
    // A sticky directory others may write, as /tmp, is a parent like any other.
    let sticky = dir.join("sticky");
    std::fs::create_dir(&sticky).unwrap();
    std::fs::set_permissions(&sticky, std::fs::Permissions::from_mode(0o1777)).unwrap();
    let o = run(&sticky.join("slurm"), "status");
    assert!(
        text(&o.stderr).contains("not running"),
        "{}",
        text(&o.stderr)
    );
}

/// A link of another user's among the directories TESSERA_SLURM_DIR names is theirs to point
/// elsewhere at any time: with `/tmp/theirs` a link of mallory's to a directory of root's,
/// every directory on the physical path was root's, so `TESSERA_SLURM_DIR=/tmp/theirs/slurm`
/// was taken, and root's `start` removed whatever `slurm` directory she pointed it at. Such a
/// link is refused, as is a directory of another user's among those named, though the
/// physical path avoids it (`theirs/../ours`). No Slurm needed.
#[test]
fn local_cluster_refuses_a_path_through_another_user_s_link() {
    let test = "local_cluster_refuses_a_path_through_another_user_s_link";
    let dir = temp_dir("slurm-link");
    let (ours, link, theirs) = (dir.join("ours"), dir.join("link"), dir.join("theirs"));
    std::fs::create_dir_all(ours.join("slurm")).unwrap();
    std::fs::write(ours.join("slurm/precious"), "root's").unwrap();
    std::fs::create_dir(&theirs).unwrap();
    std::os::unix::fs::symlink(&ours, &link).unwrap();
    if std::os::unix::fs::lchown(&link, Some(65534), Some(65534)).is_err()
        || std::os::unix::fs::chown(&theirs, Some(65534), Some(65534)).is_err()
    {
        return skip(test, "changing a file's owner needs root");
    }
    for (cluster, said) in [
        (
            link.join("slurm"),
            format!(
                "{}, above {}, is a link of another user's (uid 65534)",
                link.display(),
                link.join("slurm").display()
            ),
        ),
        (
            theirs.join("../ours/slurm"),
            format!("{}, above", theirs.display()),
        ),
    ] {
        for command in ["status", "stop", "start"] {
            let o = local_cluster(command, &cluster, None);
            let err = text(&o.stderr);
            assert!(
                !o.status.success() && err.contains(&said),
                "{command}: {err}"
            );
            assert!(o.stdout.is_empty(), "{command}: {}", text(&o.stdout));
            assert_eq!(
                std::fs::read_to_string(ours.join("slurm/precious"))
                    .ok()
                    .as_deref(),
                Some("root's"),
                "{command} removed root's directory"
            );
        }
    }
}

/// local-cluster.sh took any directory of root's as its own: `TESSERA_SLURM_DIR=/var/lib
/// start` removed it whole, and `TESSERA_SLURM_DIR=/run stop` ended the processes named by
/// the pid files there (Debian's own munged and slurmd keep theirs in /run). Only a directory
/// the script made (its mark inside) or an empty one is removed or stopped; a port that is
/// not one is refused before anything starts. No Slurm needed: stand-ins play the daemons.
#[test]
fn local_cluster_removes_and_stops_only_a_directory_it_made() {
    use std::os::unix::fs::MetadataExt;
    let dir = temp_dir("slurm-not-ours");
    let bin = dir.join("bin");
    stand_in_cluster_programs(&bin);
    let keep = dir.join("keep");
    std::fs::create_dir(&keep).unwrap();
    std::fs::write(keep.join("precious"), "root's").unwrap();
    // A process of ours a pid file there names: it must outlive `stop`.
    let mut victim = Command::new("sleep").arg("600").spawn().unwrap();
    std::fs::write(keep.join("slurmd.pid"), victim.id().to_string()).unwrap();
    let as_root = std::fs::metadata("/proc/self").map(|m| m.uid()).ok() == Some(0);
    let commands: &[&str] = if as_root {
        &["status", "stop", "start"]
    } else {
        &["status", "stop"]
    };
    for command in commands {
        let o = local_cluster(command, &keep, Some(&with_stand_ins(&bin)));
        let said = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{command}: {said}");
        assert!(
            said.contains("is not a cluster this script made"),
            "{command}: {said}"
        );
        assert!(o.stdout.is_empty(), "{command}: {}", text(&o.stdout));
    }
    let alive = victim.try_wait().unwrap().is_none();
    let _ = victim.kill();
    let _ = victim.wait();
    assert!(alive, "stop killed the process a pid file named");
    assert_eq!(
        std::fs::read_to_string(keep.join("precious"))
            .ok()
            .as_deref(),
        Some("root's")
    );
    if !as_root {
        return skip(
            "local_cluster_removes_and_stops_only_a_directory_it_made",
            "local-cluster.sh start needs root",
        );
    }
    // An empty directory is taken, and marked as the cluster's from its start (which the
    // stand-in slurmd then fails).
    let empty = dir.join("empty");
    std::fs::create_dir(&empty).unwrap();
    start_takes_and_marks(&empty, &bin);
    for port in ["x", "0", "65535", "a[$(id)]", "1234567"] {
        let fresh = dir.join("fresh");
        let o = Command::new(root().join("deploy/slurm/local-cluster.sh"))
            .arg("start")
            .env("TESSERA_SLURM_DIR", &fresh)
            .env("TESSERA_SLURM_PORT", port)
            .env("PATH", with_stand_ins(&bin))
            .output()
            .unwrap();
        let said = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{port}: {said}");
        assert!(
            said.contains(&format!("TESSERA_SLURM_PORT={port} is not a port")),
            "{port}: {said}"
        );
        assert!(!fresh.exists(), "{port}: made {}", fresh.display());
    }
}

/// A cluster directory made before the mark (`.tessera-local-cluster`) was written is still
/// the script's own, known by its slurm.conf's first line: CI's `start` refused one left in
/// /tmp by an earlier version, and every Slurm test failed. A slurm.conf that only resembles
/// it, or a link to one, is not taken. No Slurm needed: stand-ins play the daemons.
#[test]
fn local_cluster_takes_a_directory_an_earlier_version_made() {
    use std::os::unix::fs::MetadataExt;
    let dir = temp_dir("slurm-earlier");
    let bin = dir.join("bin");
    stand_in_cluster_programs(&bin);
    let header = "# Written by deploy/slurm/local-cluster.sh: a single-node cluster for tests.\n";
    let earlier = dir.join("earlier");
    std::fs::create_dir_all(earlier.join("log")).unwrap();
    std::fs::write(
        earlier.join("slurm.conf"),
        format!("{header}ClusterName=tessera-local\n"),
    )
    .unwrap();
    let o = local_cluster("status", &earlier, Some(&with_stand_ins(&bin)));
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("not running"),
        "{}",
        text(&o.stderr)
    );
    let o = local_cluster("stop", &earlier, Some(&with_stand_ins(&bin)));
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("stopped"), "{}", text(&o.stderr));

    let like = dir.join("like");
    std::fs::create_dir(&like).unwrap();
    std::fs::write(like.join("slurm.conf"), format!("\n{header}")).unwrap();
    let linked = dir.join("linked");
    std::fs::create_dir(&linked).unwrap();
    std::os::unix::fs::symlink(earlier.join("slurm.conf"), linked.join("slurm.conf")).unwrap();
    for other in [&like, &linked] {
        for command in ["status", "stop"] {
            let o = local_cluster(command, other, Some(&with_stand_ins(&bin)));
            assert_eq!(o.status.code(), Some(1), "{command}: {}", text(&o.stderr));
            assert!(
                text(&o.stderr).contains("is not a cluster this script made"),
                "{command} {}: {}",
                other.display(),
                text(&o.stderr)
            );
        }
    }
    if std::fs::metadata("/proc/self").map(|m| m.uid()).ok() != Some(0) {
        return skip(
            "local_cluster_takes_a_directory_an_earlier_version_made",
            "local-cluster.sh start needs root",
        );
    }
    // `start` takes it afresh, with the mark (the stand-in slurmd then fails).
    start_takes_and_marks(&earlier, &bin);
}

/// `start` (as root) takes `cluster` as its own, marked from its start, before the stand-in
/// slurmd in `bin` fails it; `stop` then ends what it started.
fn start_takes_and_marks(cluster: &std::path::Path, bin: &std::path::Path) {
    let o = local_cluster("start", cluster, Some(&with_stand_ins(bin)));
    assert!(
        text(&o.stderr).contains("slurmd did not start"),
        "{}",
        text(&o.stderr)
    );
    assert!(cluster.join(".tessera-local-cluster").is_file());
    let o = local_cluster("stop", cluster, Some(&with_stand_ins(bin)));
    assert!(o.status.success(), "{}", text(&o.stderr));
}

/// `deploy/slurm/local-cluster.sh COMMAND` on the cluster directory `cluster`, with `path`
/// as its PATH where given (stand-ins for Slurm's programs), on a port free now whose next
/// one is free too (the stand-in slurmctld listens on it, beside other tests' stand-ins).
fn local_cluster(
    command: &str,
    cluster: &std::path::Path,
    path: Option<&std::ffi::OsStr>,
) -> Output {
    let mut script = Command::new(root().join("deploy/slurm/local-cluster.sh"));
    script
        .arg(command)
        .env("TESSERA_SLURM_DIR", cluster)
        .env("TESSERA_SLURM_PORT", free_ports().1.to_string());
    if let Some(path) = path {
        script.env("PATH", path);
    }
    script.output().expect("run local-cluster.sh")
}

/// This process's PATH with `bin` (`stand_in_cluster_programs`) first.
fn with_stand_ins(bin: &std::path::Path) -> std::ffi::OsString {
    let mut path = bin.as_os_str().to_owned();
    path.push(":");
    path.push(std::env::var_os("PATH").unwrap_or_default());
    path
}

/// A port free now whose next one is free too, and a listener holding it.
fn free_ports() -> (std::net::TcpListener, u16) {
    loop {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = l.local_addr().unwrap().port();
        if port < 65535 && std::net::TcpListener::bind(("127.0.0.1", port + 1)).is_ok() {
            return (l, port);
        }
    }
}

/// A stand-in for each Slurm and munge program `local-cluster.sh start` runs, in `bin`:
/// `munged` leaves a `sleep` running under its pid file, as the daemon does, and
/// `slurmctld` a Python that listens on slurm.conf's port (`start` waits for that before it
/// starts slurmd); `slurmd -C` prints a node line and `slurmd` itself fails, as when its
/// port is taken. Each bears its daemon's name (`/proc/PID/comm`), as local-cluster.sh asks
/// of a process its pid files name.
fn stand_in_cluster_programs(bin: &std::path::Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::create_dir_all(bin).unwrap();
    let daemon = |pid_file: &str| {
        format!(
            "#!/bin/sh\n\"$(dirname \"$0\")/daemons/$(basename \"$0\")\" 600 </dev/null >/dev/null 2>&1 &\n\
             echo $! >\"{pid_file}\"\necho $! >>\"$(dirname \"$0\")/started\"\n"
        )
    };
    let on_path = |program: &str| {
        std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())
            .map(|d| d.join(program))
            .find(|p| p.is_file())
            .unwrap_or_else(|| panic!("{program} on the PATH"))
    };
    let sleep = on_path("sleep");
    std::fs::create_dir_all(bin.join("daemons/listening")).unwrap();
    for name in ["munged", "slurmctld", "slurmd"] {
        let _ = std::fs::remove_file(bin.join("daemons").join(name));
        std::os::unix::fs::symlink(&sleep, bin.join("daemons").join(name)).unwrap();
    }
    let listening = bin.join("daemons/listening/slurmctld");
    let _ = std::fs::remove_file(&listening);
    // Python itself, not a launcher on the PATH (pyenv's shim), which would run the program
    // the link is named after.
    let python = Command::new("python3")
        .args(["-c", "import sys; print(sys.executable)"])
        .output()
        .expect("python3 on the PATH");
    let python = text(&python.stdout).trim().to_owned();
    std::os::unix::fs::symlink(python, &listening).unwrap();
    // It writes its pid file once it listens, as slurmctld does once it has started.
    let listen = "import os, socket, sys, time\n\
                  s = socket.socket()\n\
                  s.bind(('127.0.0.1', int(sys.argv[1])))\n\
                  s.listen()\n\
                  for f, mode in ((sys.argv[2], 'w'), (sys.argv[3], 'a')):\n    \
                  open(f, mode).write(f'{os.getpid()}\\n')\n\
                  time.sleep(600)";
    for (name, script) in [
        (
            "munged",
            daemon("$(printf '%s\\n' \"$@\" | sed -n 's/^--pid-file=//p')"),
        ),
        (
            "slurmctld",
            format!(
                "#!/bin/sh\nport=$(sed -n 's/^SlurmctldPort=//p' \"$2\")\n\
                 \"$(dirname \"$0\")/daemons/listening/slurmctld\" -c \"{listen}\" \"$port\" \
                 \"$(dirname \"$2\")/slurmctld.pid\" \"$(dirname \"$0\")/started\" \
                 </dev/null >/dev/null 2>&1 &\n"
            ),
        ),
        (
            "slurmd",
            "#!/bin/sh\n[ \"$1\" = -C ] && echo 'NodeName=n CPUs=1' && exit 0\nexit 1\n".into(),
        ),
        ("sbatch", "#!/bin/sh\nexit 1\n".into()),
        ("sinfo", "#!/bin/sh\nexit 1\n".into()),
    ] {
        std::fs::write(bin.join(name), script).unwrap();
        std::fs::set_permissions(bin.join(name), std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// `local-cluster.sh start` that failed half-way ("slurmd did not start", or SIGTERM while
/// waiting for the node) exited leaving munged and slurmctld running as root, with nothing
/// to say so. It stops what it started. No Slurm needed: stand-ins play the daemons.
#[test]
fn local_cluster_start_that_fails_half_way_stops_what_it_started() {
    use std::os::unix::fs::MetadataExt;
    // /proc/self belongs to the process's effective user.
    if std::fs::metadata("/proc/self").map(|m| m.uid()).ok() != Some(0) {
        return skip(
            "local_cluster_start_that_fails_half_way_stops_what_it_started",
            "local-cluster.sh start needs root",
        );
    }
    let dir = temp_dir("slurm-half-way");
    let bin = dir.join("bin");
    stand_in_cluster_programs(&bin);
    let cluster = dir.join("cluster");
    let o = local_cluster("start", &cluster, Some(&with_stand_ins(&bin)));
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("slurmd did not start"),
        "{}",
        text(&o.stderr)
    );
    // Every stand-in still running is ended before the test says which: `stop` removes the
    // pid files, so the stand-ins' own list (`bin/started`) names them.
    let started = std::fs::read_to_string(bin.join("started")).unwrap();
    assert_eq!(
        started.lines().count(),
        2,
        "munged and slurmctld: {started}"
    );
    let mut running = Vec::new();
    for pid in started.lines() {
        if Command::new("kill")
            .args(["-0", pid])
            .status()
            .unwrap()
            .success()
        {
            let _ = Command::new("kill").arg(pid).status();
            running.push(pid.to_owned());
        }
    }
    assert!(running.is_empty(), "still running: {running:?}");
}

/// slurm.conf and munged take local-cluster.sh's paths unquoted: `start` in a directory named
/// with a space (or `#`, `%`, `,`) started munged, then failed at slurmctld's parse of
/// slurm.conf ("Parse error ... line 10"). Such a name is refused before anything starts.
/// No Slurm needed: stand-ins play the daemons.
#[test]
fn local_cluster_refuses_a_directory_name_slurm_conf_cannot_hold() {
    let dir = temp_dir("slurm-names");
    let bin = dir.join("bin");
    stand_in_cluster_programs(&bin);
    for name in ["a b", "a#b", "a%n", "a,b", "a$(id)"] {
        let cluster = dir.join(name).join("cluster");
        let o = local_cluster("start", &cluster, Some(&with_stand_ins(&bin)));
        let said = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {said}");
        if said.contains("needs root") {
            return skip(
                "local_cluster_refuses_a_directory_name_slurm_conf_cannot_hold",
                "local-cluster.sh start needs root",
            );
        }
        assert!(
            said.contains("holds a character slurm.conf cannot take"),
            "{name}: {said}"
        );
        assert!(o.stdout.is_empty(), "{name}: {}", text(&o.stdout));
        assert!(!cluster.exists(), "{name}: made {}", cluster.display());
    }
}

/// local-cluster.sh checked no directory above its own where the parent did not exist yet
/// (`TESSERA_SLURM_DIR=/tmp/work/c/slurm`, no `/tmp/work`), and `start` then removed that
/// path with `rm -rf`: another user who made `/tmp/work` while apt-get installed Slurm, with
/// `c` a link to any directory of root's, had root remove the `slurm` in it, and the cluster
/// ran there. A path whose parent did not exist is not removed (nor read by `status` or
/// `stop`), and missing parents are checked from the nearest directory above that exists.
/// No Slurm needed: stand-ins play the daemons, and apt-get plays the other user.
#[test]
fn local_cluster_start_removes_nothing_through_a_parent_made_after_its_check() {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    if std::fs::metadata("/proc/self").map(|m| m.uid()).ok() != Some(0) {
        return skip(
            "local_cluster_start_removes_nothing_through_a_parent_made_after_its_check",
            "local-cluster.sh start needs root",
        );
    }
    let dir = temp_dir("slurm-late-parent");
    let bin = dir.join("bin");
    stand_in_cluster_programs(&bin);
    // No sbatch on the way, so that start installs Slurm: the tools the script and the
    // stand-ins use are all its PATH holds.
    std::fs::remove_file(bin.join("sbatch")).unwrap();
    let path = std::env::var_os("PATH").unwrap();
    for tool in [
        "bash", "sh", "dirname", "basename", "realpath", "stat", "id", "rm", "mkdir", "ln",
        "chown", "cat", "head", "chmod", "sleep", "seq", "tail", "grep", "sed", "sort", "xargs",
        "hostname",
    ] {
        if let Some(found) = std::env::split_paths(&path)
            .map(|d| d.join(tool))
            .find(|p| p.is_file())
        {
            std::os::unix::fs::symlink(found, bin.join(tool)).unwrap();
        }
    }
    // Root's directory with a `slurm` of its own, and a sticky one others may write, as /tmp.
    let keep = dir.join("keep");
    std::fs::create_dir_all(keep.join("slurm")).unwrap();
    std::fs::write(keep.join("slurm/precious"), "root's").unwrap();
    let sticky = dir.join("sticky");
    std::fs::create_dir(&sticky).unwrap();
    std::fs::set_permissions(&sticky, std::fs::Permissions::from_mode(0o1777)).unwrap();
    let work = sticky.join("work");
    // While apt-get runs, the other user makes the missing parent, `c` a link to root's.
    std::fs::write(
        bin.join("apt-get"),
        format!(
            "#!/bin/sh\n[ \"$1\" = update ] || exit 0\nmkdir {work} && ln -s {keep} {work}/c && \
             chown -h 65534:65534 {work} {work}/c\n",
            work = work.display(),
            keep = keep.display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(bin.join("apt-get"), std::fs::Permissions::from_mode(0o755)).unwrap();
    let run = |command: &str| local_cluster(command, &work.join("c/slurm"), Some(bin.as_os_str()));
    let o = run("start");
    let said = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(said.contains("installing slurm-wlm"), "{said}");
    assert_eq!(
        std::fs::read_to_string(keep.join("slurm/precious"))
            .ok()
            .as_deref(),
        Some("root's"),
        "start removed what the other user's link led to: {said}"
    );
    // Their directory above a parent not made yet, there before the command: refused.
    std::fs::remove_file(work.join("c")).unwrap();
    let o = run("stop");
    let said = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(
        said.contains(&format!("{}, above", work.display()))
            && said.contains("belongs to another user (uid 65534)"),
        "{said}"
    );
}

/// slurmctld and slurmd take their ports once in the background, and one that finds its port
/// taken ends there: with another user's listener on slurmctld's port, root's `start` did not
/// notice, and ran sinfo against that listener (root's credentials, and the node's
/// registrations, sent to it) for minutes before saying "the node did not become idle within
/// 30 s"; a listener that answered "idle" had `start` say the cluster ran. A port taken before
/// anything starts is refused, and one taken after that check, before slurmctld binds it, is
/// found before any of Slurm's commands asks it, and before slurmd starts (which registered
/// with that listener when it was started beside slurmctld). No Slurm needed: stand-ins play
/// the daemons, whose `sinfo` answers "idle" and notes that it was asked, and this test
/// holds the port.
#[test]
fn local_cluster_start_refuses_a_port_another_process_holds() {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let test = "local_cluster_start_refuses_a_port_another_process_holds";
    if std::fs::metadata("/proc/self").map(|m| m.uid()).ok() != Some(0) {
        return skip(test, "local-cluster.sh start needs root");
    }
    let dir = temp_dir("slurm-port-taken");
    let bin = dir.join("bin");
    stand_in_cluster_programs(&bin);
    // slurmd starts, as slurmctld does; slurmctld waits, where the test says so, until the
    // port has been taken; sinfo says "idle"; squeue lists no job.
    let daemon = |pid_file: &str, then: &str| {
        format!(
            "#!/bin/sh\n[ \"$1\" = -C ] && echo 'NodeName=n CPUs=1' && exit 0\n\
             \"$(dirname \"$0\")/daemons/$(basename \"$0\")\" 600 </dev/null >/dev/null 2>&1 &\n\
             echo $! >\"{pid_file}\"\n{then}"
        )
    };
    let wait = "d=$(dirname \"$2\")\n[ -e \"$d/../wait\" ] || exit 0\ntouch \"$d/../started\"\n\
                for i in $(seq 1 100); do [ -e \"$d/../taken\" ] && exit 0; sleep 0.1; done\n";
    for (name, script) in [
        ("slurmctld", daemon("$(dirname \"$2\")/slurmctld.pid", wait)),
        (
            "slurmd",
            daemon(
                "$(dirname \"$2\")/slurmd.pid",
                "touch \"$(dirname \"$2\")/../slurmd-ran\"\n",
            ),
        ),
        (
            "sinfo",
            "#!/bin/sh\necho asked >>\"$(dirname \"$SLURM_CONF\")/../asked\"\necho idle\n".into(),
        ),
        ("squeue", "#!/bin/sh\nexit 0\n".into()),
    ] {
        std::fs::write(bin.join(name), script).unwrap();
        std::fs::set_permissions(bin.join(name), std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    // A port whose next one is free too, held as another user's daemon would hold it.
    let (listener, port) = free_ports();
    let cluster = dir.join("cluster");
    let start = || {
        Command::new(root().join("deploy/slurm/local-cluster.sh"))
            .arg("start")
            .env("TESSERA_SLURM_DIR", &cluster)
            .env("TESSERA_SLURM_PORT", port.to_string())
            .env("PATH", with_stand_ins(&bin))
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    // Ends every stand-in still running, saying which.
    let still_running = || {
        let mut running = Vec::new();
        for pid_file in ["munge/munged.pid", "slurmctld.pid", "slurmd.pid"] {
            let Ok(pid) = std::fs::read_to_string(cluster.join(pid_file)) else {
                continue;
            };
            let pid = pid.trim().to_owned();
            if Command::new("kill").arg(&pid).status().unwrap().success() {
                running.push(pid_file);
            }
        }
        running
    };
    let o = start().wait_with_output().unwrap();
    let said = text(&o.stderr);
    let running = still_running();
    assert_eq!(o.status.code(), Some(1), "taken before: {said}");
    assert!(
        said.contains(&format!("port {port} is already taken")),
        "taken before: {said}"
    );
    assert!(o.stdout.is_empty(), "taken before: {}", text(&o.stdout));
    assert!(!dir.join("asked").exists(), "sinfo asked the port's holder");
    assert!(!cluster.join("munge/munged.pid").exists(), "munged started");
    assert!(running.is_empty(), "still running: {running:?}");
    // Taken after that check, while slurmctld starts.
    drop(listener);
    std::fs::write(dir.join("wait"), "").unwrap();
    let child = start();
    let begun = Instant::now();
    while !dir.join("started").exists() && begun.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let listener = std::net::TcpListener::bind(("127.0.0.1", port));
    std::fs::write(dir.join("taken"), "").unwrap();
    let o = child.wait_with_output().unwrap();
    drop(listener);
    let said = text(&o.stderr);
    let running = still_running();
    assert_eq!(o.status.code(), Some(1), "taken after: {said}");
    assert!(
        said.contains(&format!("port {port} is held by another process")),
        "taken after: {said}"
    );
    // slurmd starts only once slurmctld holds its port: started beside a squatter, it
    // registered with it, sending root's credentials.
    assert!(
        !dir.join("slurmd-ran").exists(),
        "slurmd started while another process held slurmctld's port"
    );
    assert!(o.stdout.is_empty(), "taken after: {}", text(&o.stdout));
    assert!(!dir.join("asked").exists(), "sinfo asked the port's holder");
    assert!(running.is_empty(), "still running: {running:?}");
}

/// A daemon that ends without `stop` (slurmctld finding its port taken, a crash) leaves its
/// pid file, and its pid is soon another process's: root's `stop` then sent TERM and KILL to
/// whatever process had it (another user's `sleep`, in a cluster whose start had failed), and
/// `status` took two such processes for a running cluster. Only root's process bearing the
/// daemon's name is taken for it, and `stop` removes the pid files it is done with. No Slurm
/// needed: stand-ins play the daemons, and a `sleep` of this test's plays the pid's new owner.
#[test]
fn local_cluster_stop_ends_only_the_daemons_its_pid_files_name() {
    use std::os::unix::fs::MetadataExt;
    let test = "local_cluster_stop_ends_only_the_daemons_its_pid_files_name";
    if std::fs::metadata("/proc/self").map(|m| m.uid()).ok() != Some(0) {
        return skip(test, "local-cluster.sh start needs root");
    }
    let dir = temp_dir("slurm-stale-pid");
    let bin = dir.join("bin");
    stand_in_cluster_programs(&bin);
    let cluster = dir.join("cluster");
    // A start that fails half-way leaves a cluster directory of the script's.
    let o = local_cluster("start", &cluster, Some(&with_stand_ins(&bin)));
    assert!(
        text(&o.stderr).contains("slurmd did not start"),
        "{}",
        text(&o.stderr)
    );
    // Its daemons' pids, now another process's.
    let mut victim = Command::new("sleep").arg("600").spawn().unwrap();
    for pid_file in ["slurmctld.pid", "slurmd.pid", "munge/munged.pid"] {
        std::fs::write(cluster.join(pid_file), format!("{}\n", victim.id())).unwrap();
    }
    let status = local_cluster("status", &cluster, Some(&with_stand_ins(&bin)));
    let stop = local_cluster("stop", &cluster, Some(&with_stand_ins(&bin)));
    let alive = victim.try_wait().unwrap().is_none();
    let _ = victim.kill();
    let _ = victim.wait();
    assert!(alive, "stop killed the process a stale pid file named");
    assert_eq!(status.status.code(), Some(1), "{}", text(&status.stderr));
    assert!(
        text(&status.stderr).contains("not running"),
        "{}",
        text(&status.stderr)
    );
    assert!(stop.status.success(), "{}", text(&stop.stderr));
    for pid_file in ["slurmctld.pid", "slurmd.pid", "munge/munged.pid"] {
        assert!(!cluster.join(pid_file).exists(), "{pid_file} is left");
    }
}

/// render.sbatch splits EXTRA into words and once also expanded each as a pattern in the
/// job's directory: `--preview-file p[1].png` wrote the preview over a file `p1.png` lying
/// there. EXTRA's words are taken as they are. No Slurm needed: the script runs as the one
/// task of an array would.
#[test]
fn render_sbatch_takes_extra_s_words_as_they_are() {
    let dir = dir_with_scene("sbatch-extra", GOOD);
    std::fs::write(dir.join("p1.png"), "someone's file").unwrap();
    let o = Command::new(root().join("deploy/slurm/render.sbatch"))
        .current_dir(&dir)
        .env("SCENE", "scene.toml")
        .env("EXTRA", "--spp 1 --preview-file p[1].png")
        .env("TESSERA", env!("CARGO_BIN_EXE_tessera"))
        .env("SLURM_ARRAY_TASK_ID", "0")
        .env("SLURM_ARRAY_TASK_MIN", "0")
        .env("SLURM_ARRAY_TASK_COUNT", "1")
        .env("SLURM_CPUS_PER_TASK", "1")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert_eq!(
        std::fs::read_to_string(dir.join("p1.png")).unwrap(),
        "someone's file"
    );
    assert!(dir.join("p[1].png").is_file());
    assert!(dir.join("parts/shard-0.part").is_file());
}
