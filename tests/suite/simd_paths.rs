//! One binary for every CPU: each SIMD path this CPU runs gives the same bytes, and the
//! release binary runs on an emulated x86-64 without AVX (`qemu-x86_64 -cpu qemu64`, from
//! Debian's `qemu-user`), where it picks the portable path, with the same bytes again. So do
//! an aarch64 build under emulation and the static (musl) build of the container image.

use crate::common::*;
use std::path::{Path, PathBuf};
use tessera::simd;

/// The scenes of the byte checks: the cover (small), and every figure scene (narrow; *The
/// Next Week*'s, which ask for hundreds of samples, at 16).
fn scenes() -> Vec<(String, Vec<&'static str>)> {
    let mut all = vec![(cover(), vec!["--width", "200", "--spp", "4"])];
    let mut figures: Vec<PathBuf> = std::fs::read_dir(root().join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with("img-"))
        .collect();
    figures.sort();
    assert_eq!(figures.len(), 38);
    for f in figures {
        let name = f.to_string_lossy().into_owned();
        let mut flags = vec!["--width", "100"];
        if name.contains("img-2.") {
            flags.extend(["--spp", "16"]);
        }
        all.push((name, flags));
    }
    all
}

/// `scenes()` for an emulated CPU, where a sample costs tens of times more: every figure
/// at 8 samples per pixel (the same arithmetic on fewer paths), *The Next Week*'s at 2.
fn emulated_scenes() -> Vec<(String, Vec<&'static str>)> {
    let mut all = scenes();
    for (scene, flags) in all.iter_mut().skip(1) {
        assert!(scene.contains("img-"), "{scene}");
        if scene.contains("img-2.") {
            flags.truncate(2);
            flags.extend(["--spp", "2"]);
        } else {
            flags.extend(["--spp", "8"]);
        }
    }
    all
}

/// Renders `scene` with `extra` flags by `command` (a prefix such as an emulator, then the
/// binary) to `out`.
fn render(command: &[&str], scene: &str, extra: &[&str], out: &Path) {
    let o = std::process::Command::new(command[0])
        .args(&command[1..])
        .args(["render", scene, "-q", "-o"])
        .arg(out)
        .args(extra)
        .output()
        .expect("run tessera");
    assert!(o.status.success(), "{command:?} {scene}: {}", stderr(&o));
}

#[test]
fn every_simd_path_gives_the_same_bytes() {
    let dir = temp_dir("simd-paths");
    let bin = env!("CARGO_BIN_EXE_tessera");
    let paths = simd::Path::supported();
    if paths.len() < 2 {
        skip(
            "every_simd_path_gives_the_same_bytes",
            "this CPU runs only the portable path",
        );
        return;
    }
    for (i, (scene, flags)) in scenes().iter().enumerate() {
        let images: Vec<Vec<u8>> = paths
            .iter()
            .map(|path| {
                let out = dir.join(format!("{i}-{path}.png"));
                let mut extra = flags.clone();
                extra.extend(["--simd", path.name()]);
                render(&[bin], scene, &extra, &out);
                std::fs::read(&out).unwrap()
            })
            .collect();
        for (path, image) in paths.iter().zip(&images) {
            assert!(
                image == &images[0],
                "{scene}: {path} differs from {}",
                paths[0]
            );
        }
    }
}

#[test]
fn a_path_the_cpu_lacks_is_refused_and_unknown_names_too() {
    let dir = temp_dir("simd-refused");
    let o = run(&["render", &cover(), "--simd", "sse9", "-o", "x.png"], &dir);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unknown SIMD path `sse9`"),
        "{}",
        stderr(&o)
    );
    // Named in the environment, the name is said as far as a line holds it, and where it
    // came from: 100,000 characters of it were printed whole, after "--simd".
    let long = "x".repeat(100_000);
    let o = run_in_env(
        &["render", &cover(), "-o", "x.png"],
        &[("TESSERA_SIMD", &long)],
        &dir,
    );
    assert_eq!(o.status.code(), Some(2));
    let said = stderr(&o);
    assert!(
        said.contains("--simd (or TESSERA_SIMD): unknown SIMD path `xxx") && said.len() < 300,
        "{}",
        &said[..said.len().min(300)]
    );
    let o = run_in_env(
        &[
            "bench",
            &cover(),
            "--width",
            "40",
            "--spp",
            "1",
            "--no-scaling",
        ],
        &[("TESSERA_SIMD", "nonsense")],
        &dir,
    );
    assert_eq!(o.status.code(), Some(2));
    for path in simd::Path::ALL.into_iter().filter(|p| !p.is_supported()) {
        let o = run(
            &["render", &cover(), "--simd", path.name(), "-o", "x.png"],
            &dir,
        );
        assert_eq!(o.status.code(), Some(2));
        assert!(stderr(&o).contains("does not run"), "{}", stderr(&o));
    }
}

/// The emulator, when this machine has it (Debian's `qemu-user`).
fn qemu() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join("qemu-x86_64"))
        .find(|p| p.is_file())
}

#[cfg(target_arch = "x86_64")]
#[test]
fn a_cpu_without_avx_renders_the_same_bytes() {
    if !heavy("a_cpu_without_avx_renders_the_same_bytes") {
        return;
    }
    let Some(qemu) = qemu() else {
        skip(
            "a_cpu_without_avx_renders_the_same_bytes",
            "qemu-x86_64 is not installed (apt-get install qemu-user)",
        );
        return;
    };
    let dir = temp_dir("qemu64");
    let bin = env!("CARGO_BIN_EXE_tessera");
    let emulated = [qemu.to_str().unwrap(), "-cpu", "qemu64", bin];
    // The emulated CPU runs only the portable path: auto picks it, AVX2 is refused.
    let o = std::process::Command::new(emulated[0])
        .args(&emulated[1..])
        .args(["render", &cover(), "--simd", "avx2", "-o"])
        .arg(dir.join("refused.png"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("does not run the avx2 SIMD path"),
        "{}",
        stderr(&o)
    );
    let scenes = scenes();
    // The cover and three figure scenes of different shading modes (normals, diffuse, glass).
    for (scene, flags) in [&scenes[0], &scenes[4], &scenes[9], &scenes[16]] {
        let native = dir.join("native.png");
        let old_cpu = dir.join("qemu64.png");
        render(&[bin], scene, flags, &native);
        render(&emulated, scene, flags, &old_cpu);
        assert!(
            std::fs::read(&native).unwrap() == std::fs::read(&old_cpu).unwrap(),
            "{scene}: qemu64 differs from native"
        );
    }
}

/// An aarch64 build of tessera (`TESSERA_AARCH64_BIN`, which `.ci/run` cross-builds) run
/// under `qemu-aarch64` gives the x86-64 bytes on the cover and every figure scene.
#[cfg(target_arch = "x86_64")]
#[test]
fn an_aarch64_build_renders_the_same_bytes() {
    let name = "an_aarch64_build_renders_the_same_bytes";
    if !heavy(name) {
        return;
    }
    let Some(arm) = std::env::var_os("TESSERA_AARCH64_BIN").map(PathBuf::from) else {
        skip(
            name,
            "TESSERA_AARCH64_BIN is not set (.ci/run cross-builds one as root)",
        );
        return;
    };
    let Some(qemu) = qemu().map(|q| q.with_file_name("qemu-aarch64")) else {
        skip(name, "qemu-user is not installed");
        return;
    };
    assert!(
        arm.is_file(),
        "TESSERA_AARCH64_BIN={} is not a file",
        arm.display()
    );
    let dir = temp_dir("aarch64");
    let bin = env!("CARGO_BIN_EXE_tessera");
    for (scene, flags) in emulated_scenes() {
        let native = dir.join("native.png");
        let emulated = dir.join("aarch64.png");
        render(&[bin], &scene, &flags, &native);
        let o = std::process::Command::new(&qemu)
            .env("QEMU_LD_PREFIX", "/usr/aarch64-linux-gnu")
            .arg(&arm)
            .args(["render", &scene, "-q", "-o"])
            .arg(&emulated)
            .args(&flags)
            .output()
            .expect("run qemu-aarch64");
        assert!(o.status.success(), "{scene}: {}", stderr(&o));
        assert!(
            std::fs::read(&native).unwrap() == std::fs::read(&emulated).unwrap(),
            "{scene}: aarch64 differs from x86-64"
        );
    }
}

/// The static (musl) build the container image holds (`TESSERA_STATIC_BIN`, which `.ci/run`
/// builds with deploy/container/build.sh) gives this build's bytes on the cover and every
/// figure scene.
#[test]
fn the_static_build_renders_the_same_bytes() {
    let name = "the_static_build_renders_the_same_bytes";
    if !heavy(name) {
        return;
    }
    let Some(static_bin) = std::env::var_os("TESSERA_STATIC_BIN").map(PathBuf::from) else {
        skip(
            name,
            "TESSERA_STATIC_BIN is not set (.ci/run builds one with deploy/container/build.sh)",
        );
        return;
    };
    assert!(
        static_bin.is_file(),
        "TESSERA_STATIC_BIN={} is not a file",
        static_bin.display()
    );
    let static_bin = static_bin.to_str().unwrap();
    let dir = temp_dir("static");
    let bin = env!("CARGO_BIN_EXE_tessera");
    for (scene, flags) in scenes() {
        let (ours, theirs) = (dir.join("this.png"), dir.join("static.png"));
        render(&[bin], &scene, &flags, &ours);
        render(&[static_bin], &scene, &flags, &theirs);
        assert!(
            std::fs::read(&ours).unwrap() == std::fs::read(&theirs).unwrap(),
            "{scene}: the static build differs"
        );
    }
}
