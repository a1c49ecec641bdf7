//! The `tessera` binary end to end: outputs in every format, the same bytes across thread
//! counts, `compare` and `bench`, `--version`, bad command lines (exit 2, no damage on disk), and output
//! that cannot be written (a full disk, a closed pipe). Bad scene files: `scene_errors.rs`.

use crate::common::*;
use std::path::Path;
use std::process::{Command, Output, Stdio};

#[test]
fn thread_counts_give_identical_files_in_every_format() {
    let dir = temp_dir("threads");
    for ext in ["png", "ppm", "exr"] {
        let mut files: Vec<Vec<u8>> = Vec::new();
        for threads in ["1", "2", "3"] {
            let out = format!("t{threads}.{ext}");
            let o = run(
                &[
                    "render",
                    &cover(),
                    "--width",
                    "60",
                    "--spp",
                    "3",
                    "--threads",
                    threads,
                    "-o",
                    &out,
                    "--quiet",
                ],
                &dir,
            );
            assert!(o.status.success(), "{}", stderr(&o));
            files.push(std::fs::read(dir.join(&out)).unwrap());
        }
        assert!(
            files.windows(2).all(|w| w[0] == w[1]),
            "{ext} differs across threads"
        );
    }
    let ppm = String::from_utf8(std::fs::read(dir.join("t1.ppm")).unwrap()).unwrap();
    assert!(ppm.starts_with("P3\n60 40\n255\n"), "{}", &ppm[..20]);
    assert_eq!(ppm.lines().count(), 3 + 60 * 40);
}

#[test]
fn default_output_is_named_after_the_scene_and_summary_is_printed() {
    let dir = temp_dir("default-out");
    let o = run(&["render", &cover(), "--width", "30", "--spp", "1"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("cover.png").exists());
    let err = stderr(&o);
    for word in ["samples/s", "Mrays/s", "rays/sample", "wall"] {
        assert!(err.contains(word), "summary lacks {word}: {err}");
    }
    let quiet = run(
        &["render", &cover(), "--width", "30", "--spp", "1", "-q"],
        &dir,
    );
    assert!(
        quiet.status.success() && quiet.stderr.is_empty(),
        "{}",
        stderr(&quiet)
    );
}

#[test]
fn compare_reports_rmse_and_psnr() {
    let dir = temp_dir("compare");
    for (name, spp) in [("a.png", "2"), ("b.png", "2"), ("c.png", "8")] {
        let o = run(
            &[
                "render",
                &cover(),
                "--width",
                "40",
                "--spp",
                spp,
                "-o",
                name,
                "-q",
            ],
            &dir,
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let same = run(&["compare", "a.png", "b.png"], &dir);
    let same = String::from_utf8_lossy(&same.stdout).into_owned();
    assert!(
        same.contains("RMSE 0 ") && same.contains("inf dB (identical)"),
        "{same}"
    );
    let differ = run(&["compare", "a.png", "c.png"], &dir);
    let differ = String::from_utf8_lossy(&differ.stdout).into_owned();
    assert!(
        differ.contains("PSNR") && !differ.contains("inf"),
        "{differ}"
    );
    let o = run(
        &[
            "render",
            &cover(),
            "--width",
            "20",
            "-o",
            "d.png",
            "-q",
            "--spp",
            "1",
        ],
        &dir,
    );
    assert!(o.status.success());
    let mismatch = run(&["compare", "a.png", "d.png"], &dir);
    assert_eq!(mismatch.status.code(), Some(2));
    assert!(
        stderr(&mismatch).contains("differ in size"),
        "{}",
        stderr(&mismatch)
    );
}

/// `compare` reads JPEG too (the book's final figure is one): a render against its own
/// JPEG encoding is close but not exact.
#[test]
fn compare_reads_jpeg() {
    let dir = temp_dir("compare-jpeg");
    ok(
        &[
            "render",
            &cover(),
            "--width",
            "60",
            "--spp",
            "4",
            "-o",
            "a.png",
            "-q",
        ],
        &dir,
    );
    let png = image::open(dir.join("a.png")).unwrap().to_rgb8();
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
        .encode_image(&png)
        .unwrap();
    std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
    let o = run(&["compare", "a.png", "a.jpg"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let psnr: f64 = text
        .split("PSNR ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{text}"));
    assert!((30.0..80.0).contains(&psnr), "{text}");
}

#[test]
fn bench_prints_json() {
    let dir = temp_dir("bench");
    let o = run(
        &[
            "bench",
            &cover(),
            "--width",
            "40",
            "--spp",
            "2",
            "--threads",
            "2",
            "--json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let r = &v["result"];
    for key in ["samples_per_sec", "mrays_per_sec", "wall_s"] {
        assert!(
            r[key]["median"].as_f64().is_some(),
            "missing result.{key} in {v}"
        );
    }
    assert_eq!(v["workload"]["width"], 40);
    assert_eq!(v["workload"]["height"], 26);
    assert_eq!(v["workload"]["spp"], 2);
    assert_eq!(r["threads"], 2);
    let rps = r["rays_per_sample"].as_f64().unwrap();
    assert!((2.0..3.5).contains(&rps), "rays per sample {rps}");
}

#[test]
fn version_names_the_build_and_the_simd_paths_this_cpu_runs() {
    let dir = temp_dir("version");
    let o = run(&["--version"], &dir);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], format!("tessera {}", env!("CARGO_PKG_VERSION")));
    let commit = lines[1].strip_prefix("commit ").expect("a commit line");
    let (hash, dirty) = match commit.strip_suffix("-dirty") {
        Some(hash) => (hash, true),
        None => (commit, false),
    };
    assert!(
        commit == "unknown" || (hash.len() == 40 && hash.chars().all(|c| c.is_ascii_hexdigit())),
        "{commit}"
    );
    // A build of a tree whose compiled-in files differ from the commit says so.
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .current_dir(root())
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
    };
    if git(&["rev-parse", "HEAD"]).as_deref() == Some(hash) {
        let changes = git(&[
            "status",
            "--porcelain",
            "--",
            "src",
            "benches",
            "scenes",
            "Cargo.toml",
            "Cargo.lock",
            "build.rs",
        ]);
        assert_eq!(
            dirty,
            changes.is_some_and(|c| !c.is_empty()),
            "--version says {commit}"
        );
    }
    assert!(
        lines[2].starts_with("target ") && lines[2].contains("(release build, rustc "),
        "{text}"
    );
    assert!(
        lines[3] == "features results, preview" || lines[3].starts_with("features "),
        "{text}"
    );
    let simd = lines[4]
        .strip_prefix("SIMD paths this CPU runs: ")
        .expect("a SIMD line");
    for path in tessera::simd::Path::supported() {
        assert!(simd.contains(path.name()), "{path} missing from {simd}");
    }
    let auto = tessera::simd::Path::best();
    assert!(simd.ends_with(&format!("(auto takes {auto})")), "{simd}");
    // -V is one line: the version and the commit's first 12 digits.
    let short = run(&["-V"], &dir);
    let short = String::from_utf8_lossy(&short.stdout).into_owned();
    let twelve = hash.get(..12).unwrap_or(hash);
    let mark = if dirty { "-dirty" } else { "" };
    assert_eq!(
        short.trim(),
        format!("tessera {} ({twelve}{mark})", env!("CARGO_PKG_VERSION"))
    );
}

#[test]
fn bad_command_lines_exit_2_without_touching_output() {
    let dir = dir_with_scene("bad-args", GOOD);
    std::fs::write(dir.join("out.png"), b"precious").unwrap();
    for (args, expect) in [
        (
            vec!["render", "missing.toml", "-o", "out.png"],
            "missing.toml: no such scene file",
        ),
        (
            vec!["render", "scen.toml", "-o", "out.png"],
            "did you mean scene.toml?",
        ),
        (
            vec!["render", "scene.toml", "-o", "out.jpg"],
            "unsupported output extension",
        ),
        (
            vec!["render", "scene.toml", "-o", "out.png", "--threads", "0"],
            "--threads",
        ),
        (
            vec!["render", "scene.toml", "-o", "out.png", "--width", "0"],
            "width",
        ),
        (
            vec![
                "render",
                "scene.toml",
                "-o",
                "out.png",
                "--width",
                "9000000",
            ],
            "pixels an image may have",
        ),
        (
            vec!["render", "scene.toml", "-o", "out.png", "--spp", "-3"],
            "invalid value '-3' for '--spp <N>': must be a whole number from 1 to 4294967295",
        ),
        (
            vec!["render", "scene.toml", "-o", "out.png", "--seed", "-1"],
            "for '--seed <N>': must be a whole number from 0 to 18446744073709551615",
        ),
        (
            vec!["render", "scene.toml", "-o", "out.png", "--threads", "-2"],
            "for '--threads <N>': must be a whole number from 1 to 4096",
        ),
        (
            vec!["render", "scene.toml", "-o", "out.png", "--width", "-640"],
            "for '--width <PX>': must be a whole number from 1",
        ),
        (
            vec!["bench", "--repeat", "-1", "--no-save"],
            "for '--repeat <N>': must be a whole number from 1",
        ),
        (
            vec!["render", "scene.toml", "-o", "no/such/dir/out.png"],
            "the directory no/such/dir does not exist; create it first (mkdir -p no/such/dir)",
        ),
        (vec!["compare", "out.png", "scene.toml"], "out.png"),
    ] {
        let o = run(&args, &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(expect) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
        // A negative number is a number out of range, not a flag to escape with `--`.
        assert!(!err.contains("tip: to pass"), "{args:?}: {err}");
        assert_eq!(
            std::fs::read(dir.join("out.png")).unwrap(),
            b"precious",
            "{args:?}"
        );
    }
}

#[test]
fn checkpoint_interval_beyond_any_duration_means_never() {
    let dir = dir_with_scene("ckpt-every", GOOD);
    for every in ["2e19", "1e308"] {
        let o = run(
            &[
                "render",
                "scene.toml",
                "-o",
                "out.png",
                "-q",
                "--checkpoint",
                "c.ckpt",
                "--checkpoint-every",
                every,
            ],
            &dir,
        );
        assert!(o.status.success(), "{every}: {}", stderr(&o));
        assert!(dir.join("c.ckpt").exists());
        std::fs::remove_file(dir.join("c.ckpt")).unwrap();
    }
}

/// Runs tessera with standard output and error sent to `stdout` and `stderr`.
fn run_to(args: &[&str], cwd: &Path, stdout: Stdio, stderr: Stdio) -> Output {
    tessera()
        .args(args)
        .current_dir(cwd)
        .stdout(stdout)
        .stderr(stderr)
        .output()
        .expect("run tessera")
}

fn dev_full() -> Stdio {
    Stdio::from(std::fs::File::create("/dev/full").expect("/dev/full"))
}

#[test]
fn output_that_cannot_be_written_is_an_error_not_a_crash() {
    let dir = dir_with_scene("dev-full", GOOD);
    let o = run(&["render", "scene.toml", "-o", "a.png", "-q"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    // Standard output on a full disk: exit 2 with a message.
    let tiny_bench = [
        "bench",
        "scene.toml",
        "--json",
        "--no-scaling",
        "--repeat",
        "1",
    ];
    for args in [&["compare", "a.png", "a.png"][..], &tiny_bench, &["--help"]] {
        let o = run_to(args, &dir, dev_full(), Stdio::piped());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("No space left on device"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    // Standard error on a full disk: the exit status still tells.
    let refused = run_to(
        &["compare", "a.png", "missing.png"],
        &dir,
        Stdio::piped(),
        dev_full(),
    );
    assert_eq!(refused.status.code(), Some(2));
    let rendered = run_to(
        &["render", "scene.toml", "-o", "b.png"],
        &dir,
        Stdio::piped(),
        dev_full(),
    );
    assert_eq!(rendered.status.code(), Some(0));
    assert_eq!(
        std::fs::read(dir.join("b.png")).unwrap(),
        std::fs::read(dir.join("a.png")).unwrap()
    );
}

/// A write past the file size limit (`ulimit -f`) is an error said as a full disk's is, the
/// old file at the output left as it was: the kernel's SIGXFSZ once ended tessera there with
/// no word of its own ("File size limit exceeded", exit 153 in the shell).
#[test]
fn an_output_past_the_file_size_limit_is_an_error_not_a_killed_process() {
    let dir = dir_with_scene("file-size-limit", GOOD);
    ok(&["render", "scene.toml", "-o", "a.png", "-q"], &dir);
    let old = std::fs::read(dir.join("a.png")).unwrap();
    for args in [
        &["render", "scene.toml", "-o", "a.png", "-q"][..],
        &[
            "render",
            "scene.toml",
            "--shard",
            "0/1",
            "-o",
            "a.part",
            "-q",
        ],
    ] {
        let o = Command::new("sh")
            .args(["-c", "ulimit -f 0 && exec \"$0\" \"$@\""])
            .arg(env!("CARGO_BIN_EXE_tessera"))
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}: {o:?}");
        assert!(
            stderr(&o).contains("File too large"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    assert_eq!(std::fs::read(dir.join("a.png")).unwrap(), old);
    assert!(!dir.join("a.part").exists());
}

/// An output in the current directory, where it cannot be written, is refused naming that
/// directory in words and in full: a bare "." before the message's full stop read as the
/// parent directory.
#[test]
fn an_output_the_current_directory_cannot_take_names_that_directory() {
    let test = "an_output_the_current_directory_cannot_take_names_that_directory";
    let dir = dir_with_scene("read-only-cwd", GOOD);
    let tessera = env!("CARGO_BIN_EXE_tessera");
    let script = format!(
        "mount -o remount,ro small && cd small && {tessera} render ../scene.toml -o a.png -q; \
         echo \"status=$?\""
    );
    let Some(o) = in_a_small_filesystem(&dir, 16, &script) else {
        return skip(
            test,
            "this machine cannot make a private filesystem (unshare -rm)",
        );
    };
    let (out, err) = (String::from_utf8_lossy(&o.stdout), stderr(&o));
    assert!(out.contains("status=2"), "{out}{err}");
    let full = dir.canonicalize().unwrap().join("small");
    assert!(
        err.contains(&format!(
            "a.png: the current directory ({}) is on a read-only file system; choose another \
             directory with -o",
            full.display()
        )),
        "{err}"
    );
}

/// A checkpoint or preview file that cannot be written is refused with advice naming the
/// flag that gave it: the advice once said "choose another directory with -o" for a
/// `--checkpoint` or `--preview-file` path, where `-o` would change nothing.
#[test]
fn an_unwritable_checkpoint_or_preview_names_its_own_flag() {
    let test = "an_unwritable_checkpoint_or_preview_names_its_own_flag";
    let dir = dir_with_scene("read-only-side-files", GOOD);
    let tessera = env!("CARGO_BIN_EXE_tessera");
    for (flag, file) in [("--checkpoint", "c.ckpt"), ("--preview-file", "p.png")] {
        let script = format!(
            "mount -o remount,ro small && {tessera} render scene.toml -o a.png -q \
             {flag} small/{file}; echo \"status=$?\""
        );
        let Some(o) = in_a_small_filesystem(&dir, 16, &script) else {
            return skip(
                test,
                "this machine cannot make a private filesystem (unshare -rm)",
            );
        };
        let (out, err) = (String::from_utf8_lossy(&o.stdout), stderr(&o));
        assert!(out.contains("status=2"), "{flag}: {out}{err}");
        assert!(
            err.contains(&format!(
                "small/{file}: small is on a read-only file system; choose another \
                 directory with {flag}"
            )),
            "{flag}: {err}"
        );
        assert!(!dir.join("a.png").exists(), "{flag}: rendered anyway");
    }
}

#[test]
fn a_closed_pipe_ends_quietly() {
    let dir = dir_with_scene("closed-pipe", GOOD);
    let o = run(&["render", "scene.toml", "-o", "a.png", "-q"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    for args in [&["compare", "a.png", "a.png"][..], &["--help"]] {
        // The reader is gone before tessera writes a byte.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = run_to(args, &dir, Stdio::from(writer), Stdio::piped());
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert!(o.stderr.is_empty(), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn a_checkpoint_naming_the_image_or_the_preview_is_refused_before_rendering() {
    let dir = dir_with_scene("ckpt-same-file", GOOD);
    std::fs::write(dir.join("out.png"), b"an earlier image").unwrap();
    std::fs::write(dir.join("c.ckpt"), b"an earlier checkpoint").unwrap();
    std::os::unix::fs::symlink("c.ckpt", dir.join("link.ckpt")).unwrap();
    std::os::unix::fs::symlink("c.ckpt", dir.join("link.png")).unwrap();
    let cases: [(&[&str], &str); 4] = [
        (
            &["-o", "out.png", "--checkpoint", "./out.png"],
            "--checkpoint ./out.png names the same file as -o",
        ),
        (
            &[
                "-o",
                "a.png",
                "--preview-file",
                "p.png",
                "--checkpoint",
                "p.png",
            ],
            "--checkpoint p.png names the same file as --preview-file",
        ),
        // One file by two names: the link to the checkpoint as the preview.
        (
            &[
                "-o",
                "a.png",
                "--preview-file",
                "link.ckpt",
                "--checkpoint",
                "c.ckpt",
            ],
            "--checkpoint c.ckpt names the same file as --preview-file",
        ),
        (
            &["-o", "link.png", "--checkpoint", "c.ckpt"],
            "--checkpoint c.ckpt names the same file as -o",
        ),
    ];
    for (flags, said) in cases {
        let mut args = vec!["render", "scene.toml", "--checkpoint-every", "0"];
        args.extend_from_slice(flags);
        let o = run(&args, &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{flags:?}: {err}");
        assert!(err.contains(said), "{flags:?}: {err}");
        assert!(!dir.join("a.png").exists() && !dir.join("p.png").exists());
        assert_eq!(
            std::fs::read(dir.join("out.png")).unwrap(),
            b"an earlier image"
        );
        assert_eq!(
            std::fs::read(dir.join("c.ckpt")).unwrap(),
            b"an earlier checkpoint"
        );
    }
}

/// A part is written whatever -o's extension: `render scene.toml --shard 0/2 -o scene.toml`
/// replaced the scene file with the part (exit 0), the scene lost. Each of the render's
/// outputs naming the scene file, by its name or a link, is refused before rendering.
#[test]
fn an_output_naming_the_scene_file_is_refused_before_rendering() {
    let dir = dir_with_scene("output-is-scene", GOOD);
    std::os::unix::fs::symlink("scene.toml", dir.join("link.png")).unwrap();
    let cases: [&[&str]; 4] = [
        &["--shard", "0/2", "-o", "scene.toml"],
        &["--samples", "0..1", "-o", "./scene.toml"],
        &["-o", "link.png"],
        &["-o", "a.png", "--checkpoint", "scene.toml"],
    ];
    for flags in cases {
        refused_before_rendering(&dir, flags, "names the scene file being rendered");
        assert_eq!(
            std::fs::read(dir.join("scene.toml")).unwrap(),
            GOOD.as_bytes()
        );
    }
}

/// Renders `scene.toml` in `dir` with `flags`, which must be refused for `why` (exit 2)
/// before an image is written.
fn refused_before_rendering(dir: &Path, flags: &[&str], why: &str) {
    let mut args = vec!["render", "scene.toml", "--width", "8", "--spp", "2"];
    args.extend_from_slice(flags);
    let o = run(&args, dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{flags:?}: {err}");
    assert!(err.contains(why), "{flags:?}: {err}");
    assert!(!dir.join("a.png").exists());
}

/// `render scene.toml -o earth.png` where the scene reads earth.png as a texture replaced the
/// texture with the render (and `reproduce` of it then read its own image as the texture).
/// Refused before rendering, however the name is spelt.
#[test]
fn an_output_naming_a_texture_the_scene_reads_is_refused_before_rendering() {
    let scene = "[image]\nwidth = 16\nheight = 9\nsamples_per_pixel = 1\nmax_depth = 5\n\
                 [textures.t]\ntype = \"image\"\nfile = \"tex.ppm\"\n\
                 [materials.m]\ntype = \"lambertian\"\nalbedo = \"t\"\n\
                 [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"m\"\n";
    let dir = dir_with_scene("output-is-texture", scene);
    let texture = b"P3\n1 1\n255\n10 20 30\n";
    std::fs::write(dir.join("tex.ppm"), texture).unwrap();
    for flags in [
        &["-o", "tex.ppm"][..],
        &["-o", "./tex.ppm"],
        &["--shard", "0/2", "-o", "tex.ppm"],
        &["-o", "a.png", "--preview-file", "tex.ppm"],
    ] {
        let why = "names the texture file `tex.ppm` the scene reads";
        refused_before_rendering(&dir, flags, why);
        assert_eq!(std::fs::read(dir.join("tex.ppm")).unwrap(), texture);
    }
}

#[test]
fn an_unwritable_checkpoint_is_refused_before_rendering() {
    let dir = dir_with_scene("ckpt-missing-dir", GOOD);
    let o = run(
        &[
            "render",
            "scene.toml",
            "-o",
            "out.png",
            "--checkpoint",
            "no/such/dir/c.ckpt",
            "--checkpoint-every",
            "0",
        ],
        &dir,
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("no/such/dir/c.ckpt"), "{err}");
    // Refused at the start: no save was tried, no summary of a finished render printed.
    assert!(
        !err.contains("warning") && !err.contains("samples/s"),
        "{err}"
    );
    assert!(!dir.join("out.png").exists());
}
