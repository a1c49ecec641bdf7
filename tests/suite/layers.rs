//! The library's modules import only modules below them, in the order `src/lib.rs` describes:
//! no module reaches up, so there is no cycle. Read from the sources' `crate::` paths (test
//! code aside).

use crate::common::root;
use std::path::Path;

/// The top-level modules, lowest first.
const LAYERS: &[&str] = &[
    "math",
    "simd",
    "error",
    "text",
    "owner",
    "atomic_file",
    "input_file",
    "metadata",
    "png_header",
    "exr_header",
    "pnm_header",
    "jpeg_end",
    "confinement",
    "ray",
    "sampling",
    "texture",
    "geometry",
    "material",
    "camera",
    "bvh",
    "film",
    "tonemap",
    "scene",
    "recipe",
    "image_file",
    "image_diff",
    "job",
    "shard",
    "integrator",
    "render",
    "partial",
    "verify",
    "preview",
    "record",
];

/// The library source files under `dir`, with the top-level module each belongs to.
fn sources(dir: &Path, module: Option<&str>, out: &mut Vec<(String, String)>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let top = module.map_or(name.clone(), str::to_owned);
        if path.is_dir() {
            sources(&path, Some(&top), out);
        } else if path.extension().is_some_and(|e| e == "rs") && name != "tests" {
            out.push((top, std::fs::read_to_string(&path).unwrap()));
        }
    }
}

#[test]
fn modules_import_only_modules_below_them() {
    let mut files = Vec::new();
    sources(&root().join("src"), None, &mut files);
    let rank = |m: &str| LAYERS.iter().position(|&l| l == m);
    let mut checked = 0;
    let mut upward = Vec::new();
    for (module, text) in &files {
        // The binary (main, cli) sits above everything; lib.rs declares the modules.
        let Some(own) = rank(module) else {
            assert!(
                ["main", "cli", "lib"].contains(&module.as_str()),
                "module `{module}` is not in LAYERS: place it there"
            );
            continue;
        };
        let code = text.split("#[cfg(test)]").next().unwrap_or_default();
        for (i, _) in code.match_indices("crate::") {
            let name: String = code[i + 7..]
                .chars()
                .take_while(|c| c.is_ascii_lowercase() || *c == '_')
                .collect();
            let Some(other) = rank(&name) else {
                continue; // crate::Error and such, re-exported at the root
            };
            checked += 1;
            if other > own {
                upward.push(format!("{module} imports {name}"));
            }
        }
    }
    assert!(
        checked > 40,
        "only {checked} imports read: is the parse broken?"
    );
    upward.sort();
    upward.dedup();
    assert!(upward.is_empty(), "imports upward: {upward:?}");
}

/// `unsafe` lives in one module, `simd` (run-time dispatch and the AVX intrinsics), which
/// alone may allow it; the crate root denies it everywhere else.
#[test]
fn unsafe_code_lives_only_in_the_simd_module() {
    let mut files = Vec::new();
    sources(&root().join("src"), None, &mut files);
    let lib = std::fs::read_to_string(root().join("src/lib.rs")).unwrap();
    assert!(lib.contains("#![deny(unsafe_code)]"));
    let main = std::fs::read_to_string(root().join("src/main.rs")).unwrap();
    assert!(main.contains("#![forbid(unsafe_code)]"));
    let mut found = Vec::new();
    for (module, text) in &files {
        let uses = text.contains("unsafe {") || text.contains("allow(unsafe_code)");
        if uses && module != "simd" {
            found.push(module.clone());
        }
    }
    assert!(found.is_empty(), "unsafe outside simd: {found:?}");
}
