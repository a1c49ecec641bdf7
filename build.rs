//! Build facts for `tessera --version`, bench results and image recipes: the git commit the
//! binary was built from (with `-dirty` when the working tree differed from it), the rustc
//! that built it, the target and the cargo profile, as compile-time environment variables
//! (`unknown` where not found, e.g. a build from a source archive without git).

use std::path::Path;
use std::process::Command;

fn output(program: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(program).args(args).output().ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    out.status.success().then(|| text.trim().to_owned())
}

/// What goes into the binary: a change to any of these (or a new file among them that git
/// does not ignore) makes the build `-dirty`.
const COMPILED_IN: [&str; 6] = [
    "src",
    "benches",
    "scenes",
    "Cargo.toml",
    "Cargo.lock",
    "build.rs",
];

/// The commit of HEAD, with `-dirty` when what is compiled in differs from it.
fn commit() -> String {
    let Some(head) = output("git", &["rev-parse", "HEAD"]).filter(|h| !h.is_empty()) else {
        return "unknown".into();
    };
    // Without optional locks git does not refresh its index, whose change would make cargo
    // run this script, and compile tessera, again.
    let mut status = vec!["--no-optional-locks", "status", "--porcelain", "--"];
    status.extend(COMPILED_IN);
    match output("git", &status) {
        Some(changes) if changes.is_empty() => head,
        _ => format!("{head}-dirty"),
    }
}

/// The cargo profile, from the directory cargo builds into (`target/[TRIPLE/]PROFILE/build/
/// tessera-…/out`): `PROFILE` says only `debug` or `release`, also for a custom profile such
/// as `container` that inherits from one.
fn profile() -> String {
    let from_dir = std::env::var("OUT_DIR").ok().and_then(|out| {
        let dir = Path::new(&out)
            .ancestors()
            .nth(3)?
            .file_name()?
            .to_str()?
            .to_owned();
        // A profile's name, not a directory of another layout.
        let plausible = !dir.is_empty()
            && !["build", "deps", "target", "out"].contains(&dir.as_str())
            && (dir.bytes()).all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
        plausible.then_some(dir)
    });
    from_dir
        .or_else(|| std::env::var("PROFILE").ok())
        .unwrap_or_else(|| "unknown".into())
}

fn main() {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let version = output(&rustc, &["--version"])
        .filter(|v| !v.is_empty())
        .unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=TESSERA_GIT_COMMIT={}", commit());
    println!("cargo:rustc-env=TESSERA_RUSTC_VERSION={version}");
    println!(
        "cargo:rustc-env=TESSERA_TARGET={}",
        std::env::var("TARGET").unwrap_or_default()
    );
    println!("cargo:rustc-env=TESSERA_PROFILE={}", profile());
    // A new commit or checkout changes HEAD or the branch it points to; an edit or a new
    // file among what is compiled in changes whether the build is dirty. Not the index: any
    // git command may rewrite it without changing what is compiled in.
    let git = [".git/HEAD", ".git/refs/heads", ".git/packed-refs"];
    for path in git.into_iter().chain(COMPILED_IN) {
        if Path::new(path).exists() {
            println!("cargo:rerun-if-changed={path}");
        }
    }
}
