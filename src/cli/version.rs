//! `tessera --version`: which build this is (version, commit, `-dirty` when built from a
//! changed tree, target, cargo profile, compiler, features) and what this CPU runs, so that
//! a binary or an image found in a cluster can be identified.

use tessera::simd;

/// The commit the binary was built from, `-dirty` when the tree had changes.
pub const COMMIT: &str = env!("TESSERA_GIT_COMMIT");
/// The cargo profile it was built with (`release`, `container`, `debug`, …).
pub const PROFILE: &str = env!("TESSERA_PROFILE");

/// The optional parts compiled in (cargo features).
pub fn features() -> Vec<&'static str> {
    let mut features = Vec::new();
    if cfg!(feature = "results") {
        features.push("results");
    }
    if cfg!(feature = "preview") {
        features.push("preview");
    }
    features
}

/// `0.1.0 (abcdef012345)`, or `0.1.0 (abcdef012345-dirty)`.
pub fn short() -> String {
    let (hash, dirty) = match COMMIT.strip_suffix("-dirty") {
        Some(hash) => (hash, "-dirty"),
        None => (COMMIT, ""),
    };
    format!(
        "{} ({}{dirty})",
        env!("CARGO_PKG_VERSION"),
        hash.get(..12).unwrap_or(hash)
    )
}

/// The version, the commit, the build and the SIMD paths, one fact a line.
pub fn long() -> String {
    let paths: Vec<&str> = (simd::Path::supported().iter().rev())
        .map(|p| p.name())
        .collect();
    let features = features();
    format!(
        "{}\ncommit {COMMIT}\ntarget {} ({PROFILE} build, {})\nfeatures {}\n\
         SIMD paths this CPU runs: {} (auto takes {})\n  because {} ({})",
        env!("CARGO_PKG_VERSION"),
        env!("TESSERA_TARGET"),
        env!("TESSERA_RUSTC_VERSION"),
        if features.is_empty() {
            "none (render only)".to_owned()
        } else {
            features.join(", ")
        },
        paths.join(", "),
        simd::Path::best().name(),
        simd::Path::auto().1,
        simd::cpu_identity().unwrap_or_else(|| std::env::consts::ARCH.into()),
    )
}
