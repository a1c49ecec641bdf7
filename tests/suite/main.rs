//! tessera's end-to-end tests, in one test binary so that they link once: closed forms and
//! furnace tests, determinism, shards and resumes, every figure, the f64 reference, the
//! command line and its errors, recipes, the benchmark and results database, the live
//! viewer, and hostile input in bulk.
//!
//! The heavy tests (a real Slurm cluster, the container image under Podman, headless
//! Chromium, emulated CPUs under qemu) run only with
//! `TESSERA_HEAVY_TESTS=1`, which `.ci/run` sets after installing what they need; without
//! it they are skipped, saying so.

mod common;

mod analytic;
mod bench;
#[cfg(all(feature = "results", feature = "preview"))]
mod browser;
mod cli;
mod container;
mod determinism;
mod distributed;
#[cfg(all(feature = "results", feature = "preview"))]
mod docs;
mod figures;
mod fuzz;
mod hostile;
mod layers;
mod next_week;
#[cfg(feature = "preview")]
mod preview;
mod provenance;
mod reference;
#[cfg(feature = "results")]
mod results;
mod scene_errors;
mod scenes;
mod simd_paths;
mod slurm;
