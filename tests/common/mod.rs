//! Helpers shared by the end-to-end tests: paths, loading scenes, rendering quietly.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use tessera::film::Film;
use tessera::render::{self, RenderOptions, RenderStats};
use tessera::scene::{Overrides, Scene};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn scene_path(name: &str) -> PathBuf {
    root().join("scenes").join(name)
}

/// The book's figures (CC0, like the book), kept with the tests.
pub fn figures_dir() -> PathBuf {
    root().join("tests").join("data").join("book-figures")
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
    };
    render::render(scene, &opts, &|_| {}).expect("thread pool")
}

pub fn render(scene: &Scene) -> Film {
    render_with(scene, 2, 16).0
}

/// A fresh, empty temporary directory for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tessera-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
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
