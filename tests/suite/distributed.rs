//! One render spread over processes: shards and sample ranges merged must equal a single
//! render byte for byte; a render killed at any moment and resumed must too; bad parts are
//! refused with their reason and nothing on disk is damaged. Every case runs real processes.

use crate::common::*;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

fn spawn(args: &[&str], dir: &Path) -> Child {
    tessera()
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn tessera")
}

/// A scene other than the cover, for parts and checkpoints that must not mix with it.
fn other_scene() -> String {
    scene_path("img-1.18-view-distant.toml")
        .to_string_lossy()
        .into_owned()
}

/// A small cover render's settings, as arguments.
const SMALL: [&str; 4] = ["--width", "120", "--spp", "12"];

/// `render SCENE -q MORE…` at the small size.
fn small<'a>(scene: &'a str, more: &[&'a str]) -> Vec<&'a str> {
    with(&with(&["render", scene, "-q"], more), &SMALL)
}

fn with<'a>(base: &[&'a str], more: &[&'a str]) -> Vec<&'a str> {
    base.iter().chain(more).copied().collect()
}

fn bytes(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn parallel_sample_shards_merge_to_the_single_render() {
    let dir = temp_dir("shards-samples");
    let scene = cover();
    ok(&small(&scene, &["-o", "single.png"]), &dir);
    ok(&small(&scene, &["-o", "single.exr"]), &dir);
    let names: Vec<String> = (0..4).map(|i| format!("part{i}.bin")).collect();
    let specs: Vec<String> = (0..4).map(|i| format!("{i}/4")).collect();
    let children: Vec<Child> = (0..4)
        .map(|i| {
            spawn(
                &small(&scene, &["--shard", &specs[i], "-o", &names[i]]),
                &dir,
            )
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let parts: Vec<&str> = names.iter().map(String::as_str).collect();
    ok(&with(&["merge", "-o", "merged.png"], &parts), &dir);
    assert_eq!(bytes(&dir, "merged.png"), bytes(&dir, "single.png"));
    // Any order, any output format.
    let reversed: Vec<&str> = parts.iter().rev().copied().collect();
    ok(&with(&["merge", "-o", "merged.exr"], &reversed), &dir);
    assert_eq!(bytes(&dir, "merged.exr"), bytes(&dir, "single.exr"));
}

#[test]
fn a_directory_of_parts_merges_as_its_part_files() {
    // As a Kubernetes merge job runs it: no shell to expand `*.part`, checkpoints and other
    // files beside the parts.
    let dir = temp_dir("shards-directory");
    let scene = cover();
    ok(&small(&scene, &["-o", "single.png"]), &dir);
    std::fs::create_dir_all(dir.join("parts")).unwrap();
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    for i in 0..3 {
        let spec = format!("{i}/3");
        let out = format!("parts/shard-{i}.part");
        let checkpoint = format!("parts/shard-{i}.ckpt");
        ok(
            &small(
                &scene,
                &["--shard", &spec, "--checkpoint", &checkpoint, "-o", &out],
            ),
            &dir,
        );
    }
    std::fs::write(dir.join("parts/notes.txt"), "not a part").unwrap();
    ok(&["merge", "parts", "-o", "merged.png"], &dir);
    assert_eq!(bytes(&dir, "merged.png"), bytes(&dir, "single.png"));
    let empty = run(&["merge", "empty", "-o", "out.png"], &dir);
    assert_eq!(empty.status.code(), Some(2));
    assert!(
        stderr(&empty).contains("empty: no .part files"),
        "{}",
        stderr(&empty)
    );
    // A part named twice (the directory and the file) overlaps, as any repeated part does.
    let twice = run(
        &["merge", "parts", "parts/shard-0.part", "-o", "out.png"],
        &dir,
    );
    assert!(stderr(&twice).contains("overlaps"), "{}", stderr(&twice));
}

#[test]
fn row_shards_and_sample_ranges_merge_to_the_single_render() {
    let dir = temp_dir("shards-rows");
    let scene = cover();
    ok(&small(&scene, &["-o", "single.ppm"]), &dir);
    for i in 0..3 {
        let spec = format!("{i}/3");
        let out = format!("rows{i}.part");
        ok(
            &small(&scene, &["--shard", &spec, "--split", "rows", "-o", &out]),
            &dir,
        );
    }
    ok(
        &[
            "merge",
            "rows0.part",
            "rows1.part",
            "rows2.part",
            "-o",
            "rows.ppm",
        ],
        &dir,
    );
    assert_eq!(bytes(&dir, "rows.ppm"), bytes(&dir, "single.ppm"));

    // Sample ranges, one of them split again into row shards.
    ok(&small(&scene, &["--samples", "0..5", "-o", "a.part"]), &dir);
    for (spec, out) in [("0/2", "b.part"), ("1/2", "c.part")] {
        let args = [
            "--samples",
            "5..12",
            "--shard",
            spec,
            "--split",
            "rows",
            "-o",
            out,
        ];
        ok(&small(&scene, &args), &dir);
    }
    ok(
        &["merge", "a.part", "b.part", "c.part", "-o", "ranges.ppm"],
        &dir,
    );
    assert_eq!(bytes(&dir, "ranges.ppm"), bytes(&dir, "single.ppm"));
}

#[test]
fn shard_index_from_slurm_and_kubernetes_environments() {
    let dir = temp_dir("shards-env");
    let scene = cover();
    ok(
        &small(&scene, &["--shard", "1/3", "-o", "explicit.part"]),
        &dir,
    );
    let slurm = [
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_COUNT", "3"),
    ];
    ok_in_env(
        &small(&scene, &["--shard", "env", "-o", "slurm.part"]),
        &slurm,
        &dir,
    );
    ok_in_env(
        &small(&scene, &["--shard", "env/3", "-o", "k8s.part"]),
        &[("JOB_COMPLETION_INDEX", "1")],
        &dir,
    );
    assert_eq!(bytes(&dir, "slurm.part"), bytes(&dir, "explicit.part"));
    assert_eq!(bytes(&dir, "k8s.part"), bytes(&dir, "explicit.part"));
}

/// Size and samples of a render long enough to be killed in the middle of.
const LONG: [&str; 4] = ["--width", "200", "--spp", "60"];

/// The arguments of that render, checkpointing after every tile into `checkpoint`.
fn long_render<'a>(scene: &'a str, out: &'a str, checkpoint: &'a str) -> Vec<&'a str> {
    let more = [
        "-o",
        out,
        "--checkpoint",
        checkpoint,
        "--checkpoint-every",
        "0",
        "--threads",
        "2",
    ];
    with(&with(&["render", scene, "-q"], &LONG), &more)
}

/// The same render straight through; returns its bytes.
fn straight_render(dir: &Path, scene: &str) -> Vec<u8> {
    ok(
        &with(&["render", scene, "-q", "-o", "straight.png"], &LONG),
        dir,
    );
    bytes(dir, "straight.png")
}

/// When a render is killed: a while after it starts, or as soon as it has saved a
/// checkpoint newer than the one it resumed from.
#[derive(Clone, Copy, Debug)]
enum Kill {
    After(u64),
    AtCheckpoint,
}

#[test]
fn killed_renders_resume_to_the_same_bytes() {
    let dir = temp_dir("sigkill");
    let scene = cover();
    let straight = straight_render(&dir, &scene);
    let mut caught_mid_render = 0;
    // Kill at several moments, and kill the resumed render again, then finish. The kills
    // at a checkpoint hit a render in progress however slow the machine is: kills at fixed
    // moments alone once all fell before the first checkpoint on a loaded machine.
    use Kill::*;
    let series = [
        &[After(20)][..],
        &[After(90)],
        &[After(200)],
        &[AtCheckpoint, AtCheckpoint, After(100)],
    ];
    for (n, kills) in series.iter().enumerate() {
        let (out, ck) = (format!("killed{n}.png"), format!("killed{n}.ckpt"));
        for &kill in kills.iter() {
            let before = std::fs::read(dir.join(&ck)).ok();
            let mut child = spawn(&long_render(&scene, &out, &ck), &dir);
            match kill {
                After(ms) => std::thread::sleep(Duration::from_millis(ms)),
                AtCheckpoint => {
                    while child.try_wait().unwrap().is_none()
                        && std::fs::read(dir.join(&ck)).ok() == before
                    {
                        std::thread::sleep(Duration::from_millis(1));
                    }
                }
            }
            child.kill().unwrap(); // SIGKILL
            child.wait().unwrap();
            // Killed before its first checkpoint, or between two: either way it resumes.
            if let Ok(part) = tessera::partial::Part::load(&dir.join(&ck))
                && !part.is_complete()
            {
                caught_mid_render += 1;
            }
        }
        ok(&long_render(&scene, &out, &ck), &dir);
        assert_eq!(bytes(&dir, &out), straight, "killed {kills:?}");
    }
    assert!(
        caught_mid_render >= 2,
        "only {caught_mid_render} kills hit a render in progress"
    );
}

#[test]
fn interrupted_render_saves_says_how_to_resume_and_resumes() {
    let dir = temp_dir("sigint");
    let scene = cover();
    let straight = straight_render(&dir, &scene);
    let mut args = long_render(&scene, "int.png", "int.ckpt");
    args.retain(|a| *a != "-q");
    let child = spawn(&args, &dir);
    std::thread::sleep(Duration::from_millis(150));
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    if o.status.code() == Some(130) {
        assert!(
            err.contains("Run the same command again to resume"),
            "{err}"
        );
        assert!(
            !dir.join("int.png").exists(),
            "an interrupted render wrote its image"
        );
    } else {
        // The machine finished before the signal arrived.
        assert!(o.status.success(), "{err}");
    }
    assert!(dir.join("int.ckpt").exists());
    ok(&args, &dir);
    assert_eq!(bytes(&dir, "int.png"), straight);
}

#[test]
fn progressive_render_continues_to_more_samples() {
    let dir = temp_dir("progressive");
    let scene = cover();
    let base = [
        "render",
        &scene,
        "-q",
        "--width",
        "100",
        "--checkpoint",
        "prog.ckpt",
    ];
    ok(&with(&base, &["--spp", "8", "-o", "p8.png"]), &dir);
    ok(&with(&base, &["--spp", "24", "-o", "p24.png"]), &dir);
    ok(
        &[
            "render", &scene, "-q", "--width", "100", "--spp", "24", "-o", "d24.png",
        ],
        &dir,
    );
    assert_eq!(bytes(&dir, "p24.png"), bytes(&dir, "d24.png"));
    // Asking for fewer samples than the checkpoint holds, or another seed, is refused.
    let fewer = run(&with(&base, &["--spp", "4", "-o", "p4.png"]), &dir);
    assert_eq!(fewer.status.code(), Some(2));
    let other = run(
        &with(&base, &["--spp", "24", "--seed", "9", "-o", "p9.png"]),
        &dir,
    );
    assert_eq!(other.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&other.stderr).contains("different seed"));
}

#[test]
fn checkpoint_of_another_scene_is_refused() {
    let dir = temp_dir("ckpt-scene");
    let scene = cover();
    let other = other_scene();
    // The same small checkpointed render of each scene, into one checkpoint file.
    let tiny = [
        "-q",
        "--width",
        "60",
        "--spp",
        "2",
        "--checkpoint",
        "c.ckpt",
        "-o",
    ];
    ok(&with(&with(&["render", &other], &tiny), &["o.png"]), &dir);
    let before = bytes(&dir, "c.ckpt");
    let o = run(&with(&with(&["render", &scene], &tiny), &["x.png"]), &dir);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("c.ckpt"));
    assert_eq!(
        bytes(&dir, "c.ckpt"),
        before,
        "a refused checkpoint was changed"
    );
}

#[test]
fn bad_parts_are_refused_and_nothing_is_damaged() {
    let dir = temp_dir("bad-parts");
    let scene = cover();
    for i in 0..3 {
        let (spec, out) = (format!("{i}/3"), format!("p{i}.part"));
        ok(&small(&scene, &["--shard", &spec, "-o", &out]), &dir);
    }
    ok(
        &small(
            &scene,
            &["--seed", "7", "--shard", "1/3", "-o", "seed7.part"],
        ),
        &dir,
    );
    let other = other_scene();
    ok(
        &small(&other, &["--shard", "1/3", "-o", "other.part"]),
        &dir,
    );
    ok(
        &small(&scene, &["--samples", "3..6", "-o", "overlap.part"]),
        &dir,
    );
    let good = bytes(&dir, "p1.part");
    std::fs::write(dir.join("truncated.part"), &good[..good.len() / 2]).unwrap();
    let mut flipped = good.clone();
    let middle = flipped.len() / 2;
    flipped[middle] ^= 0x01;
    std::fs::write(dir.join("flipped.part"), &flipped).unwrap();
    std::fs::write(dir.join("out.png"), b"precious").unwrap();

    for (middle, expected) in [
        ("truncated.part", "truncated"),
        ("flipped.part", "corrupt"),
        ("seed7.part", "different seed"),
        ("other.part", "another render"),
        ("../missing.part", "missing.part"),
        ("scene.toml", "not a tessera partial render"),
    ] {
        if middle == "scene.toml" {
            std::fs::copy(scene_path("cover.toml"), dir.join("scene.toml")).unwrap();
        }
        let o = run(
            &["merge", "p0.part", middle, "p2.part", "-o", "out.png"],
            &dir,
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{middle}: {err}");
        assert!(
            err.contains(expected),
            "{middle}: expected `{expected}` in {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(
            bytes(&dir, "out.png"),
            b"precious",
            "{middle} damaged the output"
        );
    }
    let missing = run(&["merge", "p0.part", "p2.part", "-o", "out.png"], &dir);
    let err = String::from_utf8_lossy(&missing.stderr);
    assert_eq!(missing.status.code(), Some(2));
    assert!(err.contains("gaps") && err.contains("missing"), "{err}");
    let overlap = run(
        &[
            "merge",
            "p0.part",
            "p1.part",
            "p2.part",
            "overlap.part",
            "-o",
            "out.png",
        ],
        &dir,
    );
    assert!(String::from_utf8_lossy(&overlap.stderr).contains("overlaps"));
    assert_eq!(bytes(&dir, "out.png"), b"precious");
    // The parts themselves are untouched by all this.
    assert_eq!(bytes(&dir, "p1.part"), good);
    ok(
        &["merge", "p0.part", "p1.part", "p2.part", "-o", "out.png"],
        &dir,
    );
    assert_ne!(bytes(&dir, "out.png"), b"precious");
}

/// `merge p0.png p1.png -o p0.png`, parts named as images (a part may have any name),
/// replaced part `p0.png` with the image (exit 0, "merged 2 parts"): a shard's render was
/// lost, and the merge could not be run again. An output naming one of the parts, however
/// spelt or by a link, is refused before anything is read, every part left as it was.
#[test]
fn an_image_named_as_one_of_its_parts_is_refused() {
    let dir = temp_dir("merge-onto-a-part");
    let scene = cover();
    for (spec, out) in [("0/2", "p0.png"), ("1/2", "p1.png")] {
        ok(&small(&scene, &["--shard", spec, "-o", out]), &dir);
    }
    std::os::unix::fs::symlink("p1.png", dir.join("link.png")).unwrap();
    let parts = [bytes(&dir, "p0.png"), bytes(&dir, "p1.png")];
    for out in ["p0.png", "./p1.png", "link.png"] {
        let o = run(&["merge", "p0.png", "p1.png", "-o", out], &dir);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{out}: {err}");
        assert!(
            err.contains("names the same file as the part"),
            "{out}: {err}"
        );
    }
    assert_eq!([bytes(&dir, "p0.png"), bytes(&dir, "p1.png")], parts);
    ok(&["merge", "p0.png", "p1.png", "-o", "out.png"], &dir);
}

#[test]
fn a_render_in_one_part_writes_a_part_that_merges() {
    let dir = temp_dir("one-part");
    let scene = cover();
    ok(&small(&scene, &["-o", "single.png"]), &dir);
    ok(
        &small(&scene, &["--shard", "0/1", "-o", "shard.part"]),
        &dir,
    );
    ok(
        &small(&scene, &["--samples", "0..12", "-o", "samples.part"]),
        &dir,
    );
    // A Slurm array of one task.
    ok_in_env(
        &small(&scene, &["--shard", "env", "-o", "array.part"]),
        &[
            ("SLURM_ARRAY_TASK_ID", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "1"),
        ],
        &dir,
    );
    for part in ["shard.part", "samples.part", "array.part"] {
        let out = format!("{part}.png");
        ok(&["merge", part, "-o", &out], &dir);
        assert_eq!(bytes(&dir, &out), bytes(&dir, "single.png"), "{part}");
    }
}

/// A 260-byte part whose header claims a 16384×16384 image, one tile per pixel.
fn crafted_part() -> Vec<u8> {
    let header = concat!(
        r#"{"version":1,"fingerprint":"0","seed":0,"width":16384,"height":16384,"#,
        r#""max_depth":1,"gamma":2.0,"window":[0,0,16384,16384],"#,
        r#""region":[0,0,16384,16384],"samples":[0,1],"target":1,"tile":1,"done":[]}"#
    );
    let mut bytes = b"TESSERA-PARTIAL\n".to_vec();
    bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.resize(260, 0);
    bytes
}

#[test]
fn a_part_claiming_a_huge_image_is_refused_before_anything_is_allocated() {
    let dir = temp_dir("crafted-part");
    std::fs::write(dir.join("huge.part"), crafted_part()).unwrap();
    std::fs::write(dir.join("out.png"), b"precious").unwrap();
    let tessera = env!("CARGO_BIN_EXE_tessera");
    // Under a 1 GiB address-space limit a reader that believed the header would abort.
    let limited = |args: &str| {
        Command::new("sh")
            .args(["-c", &format!("ulimit -v 1048576; exec {tessera} {args}")])
            .current_dir(&dir)
            .output()
            .unwrap()
    };
    let cover = cover();
    for args in [
        "merge huge.part -o out.png".to_owned(),
        format!("render {cover} -q --width 40 --spp 1 --checkpoint huge.part -o out.png"),
    ] {
        let o = limited(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args}: {err}");
        assert!(
            err.contains("huge.part") && !err.contains("panicked"),
            "{args}: {err}"
        );
    }
    assert_eq!(bytes(&dir, "out.png"), b"precious");
}

/// This build, as a part's header names it.
fn this_build() -> tessera::recipe::Maker {
    tessera::recipe::Maker::this_build()
}

/// `part` as if rendered by the build of `commit`: its header's commit replaced, its length
/// and checksum made right.
fn made_by(part: &[u8], commit: &str) -> Vec<u8> {
    with_part_header(part, |header| {
        let header = std::str::from_utf8(header).unwrap();
        let ours = format!("\"commit\":\"{}\"", this_build().commit);
        assert!(
            header.contains(&ours),
            "the header names no build: {header}"
        );
        header
            .replace(&ours, &format!("\"commit\":\"{commit}\""))
            .into_bytes()
    })
}

/// Builds of other commits may render other sums for one scene and settings, and parts
/// named no build: a shard of one build merged with a shard of another made an image that
/// neither renders, its recipe naming the build that merged, and a checkpoint of an older
/// build was resumed by a newer one. Parts of two builds are refused, naming both; parts all
/// of another build merge to an image without a recipe (this build's would not be its); a
/// checkpoint of another build is not resumed.
#[test]
fn parts_and_checkpoints_of_another_tessera_build_do_not_mix() {
    let dir = temp_dir("another-build");
    let scene = cover();
    let other = "0123456789abcdef0123456789abcdef01234567";
    for i in 0..2 {
        let (spec, name) = (format!("{i}/2"), format!("p{i}.part"));
        ok(&small(&scene, &["--shard", &spec, "-o", &name]), &dir);
        let theirs = made_by(&bytes(&dir, &name), other);
        std::fs::write(dir.join(format!("q{i}.part")), theirs).unwrap();
    }
    let o = run(&["merge", "p0.part", "q1.part", "-o", "mixed.png"], &dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("q1.part: belongs to another render than p0.part: different tessera build")
            && err.contains(other)
            && err.contains(&this_build().commit),
        "{err}"
    );
    assert!(!dir.join("mixed.png").exists());

    let o = run(&["merge", "q0.part", "q1.part", "-o", "theirs.png"], &dir);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(&format!(
            "the parts were rendered by tessera {}",
            this_build().version
        )) && err.contains(other)
            && err.contains("theirs.png carries no recipe"),
        "{err}"
    );
    let o = run(&["info", "theirs.png"], &dir);
    assert!(stderr(&o).contains("no recipe"), "{}", stderr(&o));

    let args = small(&scene, &["--checkpoint", "c.ckpt", "-o", "c.png"]);
    ok(&args, &dir);
    std::fs::write(dir.join("c.ckpt"), made_by(&bytes(&dir, "c.ckpt"), other)).unwrap();
    let o = run(&args, &dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("c.ckpt: was rendered with a different tessera build") && err.contains(other),
        "{err}"
    );
}

/// A part of the image `width`×`height` holding one finished pixel at (`x`, `y`), sample 0
/// of 1: its header passes every check of its own.
fn one_pixel_part(width: u32, height: u32, x: u32, y: u32) -> Vec<u8> {
    let header = format!(
        concat!(
            r#"{{"version":4,"render":{{"fingerprint":"00","seed":1,"width":{w},"height":{h},"#,
            r#""max_depth":5,"gamma":2.0,"window":{{"x0":0,"y0":0,"width":{w},"height":{h}}},"#,
            r#""target":1,"tessera":{{"version":"{v}","commit":"{c}"}}}},"state":{{"job":{{"region":{{"x0":{x},"y0":{y},"width":1,"#,
            r#""height":1}},"samples":{{"start":0,"end":1}}}},"tile":1,"done":[1]}}}}"#
        ),
        w = width,
        h = height,
        x = x,
        y = y,
        v = this_build().version,
        c = this_build().commit,
    );
    let mut bytes = b"TESSERA-PARTIAL\n".to_vec();
    bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.resize(bytes.len() + 24 + 8, 0);
    bytes
}

/// Two one-pixel parts of a 16384×16384 image leave a gap, seen from their headers before
/// anything the size of the image is allocated: the search for overlaps once came first,
/// four bytes a pixel (1 GiB), and under a 1 GiB address-space limit the merge aborted
/// ("memory allocation of 1073741824 bytes failed", exit 134).
#[test]
fn parts_that_leave_a_gap_in_a_huge_image_are_refused_before_it_is_allocated() {
    let dir = temp_dir("gap-in-a-huge-image");
    std::fs::write(dir.join("a.part"), one_pixel_part(16384, 16384, 0, 0)).unwrap();
    std::fs::write(dir.join("b.part"), one_pixel_part(16384, 16384, 5, 5)).unwrap();
    std::fs::write(dir.join("out.png"), b"precious").unwrap();
    let tessera = env!("CARGO_BIN_EXE_tessera");
    let o = Command::new("sh")
        .args([
            "-c",
            &format!("ulimit -v 1048576; exec {tessera} merge a.part b.part -o out.png"),
        ])
        .current_dir(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("the parts leave gaps") && !err.contains("allocation"),
        "{err}"
    );
    assert_eq!(bytes(&dir, "out.png"), b"precious");
}

/// `-o /dev/stdin < in.txt` (a part) or `-o in.png` with `in.png` a link to `/dev/stdin`
/// (an image, named by its extension): standard input is open only for reading, so the
/// output is refused before the render, and the file the shell opened is left as it was;
/// written through, the image (a 12-byte file grew to 3,393 bytes) or the part (26,847) was
/// appended to it, exit 0.
#[test]
fn an_output_named_as_standard_input_is_refused_and_the_input_untouched() {
    let dir = temp_dir("output-to-stdin");
    let input = dir.join("in.txt");
    std::os::unix::fs::symlink("/dev/stdin", dir.join("in.png")).unwrap();
    for (output, more) in [("in.png", &[][..]), ("/dev/stdin", &["--shard", "0/1"][..])] {
        std::fs::write(&input, b"hello input\n").unwrap();
        let o = tessera()
            .args(with(&small(&cover(), &["-o", output]), more))
            .current_dir(&dir)
            .stdin(std::fs::File::open(&input).unwrap())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{output}: {err}");
        let said = format!("{output}: leads to standard input (file descriptor 0)");
        assert!(
            err.contains(&said) && err.contains("only for reading"),
            "{err}"
        );
        assert_eq!(bytes(&dir, "in.txt"), b"hello input\n", "{output}");
    }
}

/// `--checkpoint /dev/stdin < own.ckpt`, or a link to `/dev/stdin` as the checkpoint: the
/// checkpoint is read to resume and saved over as the render goes, and standard input is
/// open only for reading, so it is refused before the render as `-o /dev/stdin` is. It was
/// resumed, each save refused with a warning, and the render went on with no checkpoint
/// saved, exit 0. The checkpoint the shell opened is left as it was.
#[test]
fn a_checkpoint_named_as_standard_input_is_refused_before_the_render() {
    let dir = temp_dir("checkpoint-to-stdin");
    let scene = cover();
    ok(
        &small(&scene, &["--checkpoint", "own.ckpt", "-o", "own.png"]),
        &dir,
    );
    let own = bytes(&dir, "own.ckpt");
    std::os::unix::fs::symlink("/dev/stdin", dir.join("ck")).unwrap();
    for checkpoint in ["/dev/stdin", "ck"] {
        let o = tessera()
            .args(small(
                &scene,
                &["--checkpoint", checkpoint, "-o", "out.png"],
            ))
            .current_dir(&dir)
            .stdin(std::fs::File::open(dir.join("own.ckpt")).unwrap())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{checkpoint}: {err}");
        let said = format!("{checkpoint}: leads to standard input (file descriptor 0)");
        assert!(
            err.contains(&said) && err.contains("only for reading"),
            "{err}"
        );
        assert!(
            !err.contains("resuming") && !err.contains("warning"),
            "{err}"
        );
        assert!(!dir.join("out.png").exists(), "{checkpoint}");
        assert_eq!(bytes(&dir, "own.ckpt"), own, "{checkpoint}");
    }
}

/// `--preview-file` leading to standard input (a link `p.png` to `/dev/stdin`: the flag
/// takes only a `.png` name) is refused before the render, as `-o` is.
#[test]
fn a_preview_file_named_as_standard_input_is_refused_before_the_render() {
    let dir = temp_dir("preview-to-stdin");
    let input = dir.join("in.txt");
    std::fs::write(&input, b"hello input\n").unwrap();
    std::os::unix::fs::symlink("/dev/stdin", dir.join("p.png")).unwrap();
    let o = tessera()
        .args(small(
            &cover(),
            &["--preview-file", "p.png", "-o", "out.png"],
        ))
        .current_dir(&dir)
        .stdin(std::fs::File::open(&input).unwrap())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("p.png: leads to standard input (file descriptor 0)"),
        "{err}"
    );
    assert!(!dir.join("out.png").exists());
    assert_eq!(bytes(&dir, "in.txt"), b"hello input\n");
}

/// An output's name is one line in the notes that name it, as in errors: `-o
/// "r\nfake: line.png"` printed its summary on two lines, the second one starting with what
/// the name chose (`render`, with or without `--shard`, and `merge`).
#[test]
fn an_output_s_name_is_one_line_in_the_notes() {
    let dir = temp_dir("newline-in-output");
    let scene = cover();
    let notes = |args: &[&str]| {
        let o = run(args, &dir);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let base = ["render", scene.as_str(), "--width", "40", "--spp", "2"];
    for (output, more) in [
        ("r\nfake: line.png", &[][..]),
        ("p0\nfake: line.part", &["--shard", "0/2"][..]),
    ] {
        let said = notes(&with(&with(&base, &["-o", output]), more));
        assert!(said.lines().all(|l| !l.starts_with("fake")), "{said}");
        assert!(said.contains(&output.replace('\n', "\\u{a}")), "{said}");
    }
    ok(&with(&base, &["--shard", "1/2", "-o", "p1.part"]), &dir);
    let said = notes(&[
        "merge",
        "p0\nfake: line.part",
        "p1.part",
        "-o",
        "m\nfake: x.png",
    ]);
    assert!(said.lines().all(|l| !l.starts_with("fake")), "{said}");
    assert!(
        said.contains("m\\u{a}fake: x.png: merged 2 parts"),
        "{said}"
    );
}

#[test]
fn a_checkpoint_on_a_full_disk_warns_once_and_the_image_is_still_written() {
    let dir = temp_dir("full-disk");
    let tessera = env!("CARGO_BIN_EXE_tessera");
    let cover = cover();
    let straight = straight_render(&dir, &cover);
    let render = format!(
        "{tessera} render {cover} -q --width 200 --spp 60 --checkpoint small/c.ckpt \
         --checkpoint-every 0 -o full.png"
    );
    let Some(o) = in_a_small_filesystem(&dir, 16, &render) else {
        skip(
            "the full-disk test",
            "`unshare -rm` cannot mount a small filesystem on this machine",
        );
        return;
    };
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(
        err.matches("could not save the checkpoint").count(),
        1,
        "{err}"
    );
    assert!(err.contains("checkpoint saves failed in all"), "{err}");
    assert_eq!(bytes(&dir, "full.png"), straight);
}

/// A render with a checkpoint whose output is the user's own pipe (FIFO) with no reader
/// waits for one in `open`, where a Ctrl-C only sets the stop flag: it waited through every
/// SIGINT and SIGTERM, ended only by SIGKILL. A second Ctrl-C ends it (exit 130), the pipe
/// left a pipe.
#[test]
fn a_second_ctrl_c_ends_a_render_waiting_on_its_output() {
    let dir = temp_dir("second-ctrl-c");
    let made = Command::new("mkfifo").arg(dir.join("out.ppm")).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo");
    let cover = cover();
    let args = [
        "render",
        &cover,
        "-q",
        "--width",
        "16",
        "--spp",
        "1",
        "--checkpoint",
        "c.ckpt",
        "-o",
        "out.ppm",
    ];
    let mut child = spawn(&args, &dir);
    let pid = child.id().to_string();
    let start = std::time::Instant::now();
    // The finished checkpoint is saved just before the output is opened: from then on the
    // render is over, and a Ctrl-C has nothing to stop.
    while !dir.join("c.ckpt").exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "it ended before its output"
        );
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no checkpoint saved"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // Ctrl-C every 100 ms until it ends: signals sent close together may arrive as one, so
    // the count sent says nothing; that it ends does.
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("the render did not end on Ctrl-C");
        }
        let _ = Command::new("kill").args(["-INT", &pid]).status();
        std::thread::sleep(Duration::from_millis(100));
    };
    assert_eq!(status.code(), Some(130), "{status}");
    let fifo = std::fs::symlink_metadata(dir.join("out.ppm")).unwrap();
    assert!(std::os::unix::fs::FileTypeExt::is_fifo(&fifo.file_type()));
}

/// *The Next Week*'s final scene (every new kind of primitive, texture, motion blur and
/// media at once) obeys the same contract: sample shards, row shards and a render killed and
/// resumed all give the single render's bytes.
#[test]
fn the_next_weeks_final_scene_shards_and_resumes_to_the_same_bytes() {
    let dir = temp_dir("next-week-shards");
    let scene = scene_path("img-2.22-book2-final.toml")
        .to_string_lossy()
        .into_owned();
    ok(&small(&scene, &["-o", "single.png"]), &dir);
    for (i, spec) in ["0/3", "1/3", "2/3"].iter().enumerate() {
        let out = format!("samples{i}.part");
        ok(&small(&scene, &["--shard", spec, "-o", &out]), &dir);
        let out = format!("rows{i}.part");
        ok(
            &small(&scene, &["--shard", spec, "--split", "rows", "-o", &out]),
            &dir,
        );
    }
    // The merged image's recipe needs the scene's texture, which is not next to the parts.
    let textures = root().join("scenes").to_string_lossy().into_owned();
    let samples = ["samples0.part", "samples1.part", "samples2.part"];
    let merge = ["merge", "--textures", &textures, "-o", "samples.png"];
    ok(&with(&merge, &samples), &dir);
    assert_eq!(bytes(&dir, "samples.png"), bytes(&dir, "single.png"));
    // Without it, the merge says why its image carries no recipe.
    let o = run(&with(&["merge", "-o", "bare.png"], &samples), &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("earthmap.jpg") && stderr(&o).contains("carries no recipe"),
        "{}",
        stderr(&o)
    );
    ok(
        &[
            "merge",
            "--textures",
            &textures,
            "rows2.part",
            "rows0.part",
            "rows1.part",
            "-o",
            "rows.png",
        ],
        &dir,
    );
    assert_eq!(bytes(&dir, "rows.png"), bytes(&dir, "single.png"));
    // Killed mid-render (or before its first checkpoint), then resumed.
    let resumed = [
        "-o",
        "resumed.png",
        "--checkpoint",
        "r.ckpt",
        "--checkpoint-every",
        "0",
    ];
    let mut child = spawn(&small(&scene, &resumed), &dir);
    std::thread::sleep(Duration::from_millis(150));
    child.kill().unwrap();
    child.wait().unwrap();
    ok(&small(&scene, &resumed), &dir);
    assert_eq!(bytes(&dir, "resumed.png"), bytes(&dir, "single.png"));
}
