//! tessera: a deterministic, tiled, multicore path tracer of *Ray Tracing in One Weekend*.
//!
//! How a render flows through the modules, each importing only those below it:
//!
//! - [`scene`] reads a TOML file ([`scene::desc`]), checks every value with its file, line
//!   and column, and builds the runtime [`scene::Scene`]: settings, the [`camera`], the
//!   [`material`]s and spheres ([`geometry`]) in a [`bvh`].
//! - [`job`] says what one process renders, the scene's window over a range of sample
//!   indices ([`shard`] cuts a render into such jobs), and keeps its state tile by tile.
//! - [`render`] spreads the job's unfinished tiles over a rayon pool and folds finished ones
//!   into the state; it is the only module that knows threads.
//! - [`integrator`] evaluates a tile's pixels: each sample's film position, camera ray and
//!   random numbers come from the sample's own seeded [`sampling::Sampler`], and its radiance
//!   from the scene's shading mode (the book's early stages, or a path).
//! - [`film`] holds the exact fixed-point sums; [`tonemap`] turns a sum into a pixel's value
//!   and [`image_file`] a film into PNG, PPM or EXR; [`partial`] stores a job's state as a
//!   part file (shards, checkpoints) and merges parts; [`atomic_file`] writes every file
//!   whole or not at all. [`recipe`] is what an image carries to be made again: the scene's
//!   text, the settings and the hash of its sums, written into the image's metadata.
//! - Reading what a stranger made: [`input_file`] opens only regular files, [`exr_header`]
//!   reads an EXR header within limits before any EXR library sees it, and [`png_header`] a
//!   PNG's chunks the same way (for image files and image textures alike), [`pnm_header`] a
//!   PNM's header, [`jpeg_end`] whether a JPEG ends; [`metadata`] says where an image
//!   carries its recipe.
//!
//! - [`preview`] watches a running job from the folding thread (a picture kept tile by
//!   tile, published about once a second) and serves it to a browser.
//!
//! The same scene, settings and seed give the same bytes whatever the thread count, tile
//! size, shard split or interruption. [`math`], [`ray`], [`error`] and [`text`] serve them all;
//! [`image_diff`] measures the difference of two images.
//!
//! [`verify`] checks an image against its recipe (`tessera reproduce`), bit for bit.
//!
//! [`record`] is what a benchmark records: its result and schema, the build and host it ran
//! on (what confines the process, from [`confinement`]), the workloads, and, with the
//! `results` feature, the database that keeps the results.
//!
//! [`simd`] picks the instruction set of the hot code when a tile is rendered (portable,
//! AVX2 or AVX-512, the same bytes on each) and holds the crate's only `unsafe` code; the
//! rest of the crate denies it.

#![deny(unsafe_code)]

pub mod atomic_file;
pub mod bvh;
pub mod camera;
pub mod confinement;
pub mod error;
pub mod exr_header;
pub mod film;
pub mod geometry;
pub mod image_diff;
pub mod image_file;
pub mod input_file;
pub mod integrator;
pub mod job;
pub mod jpeg_end;
pub mod material;
pub mod math;
pub mod metadata;
pub mod owner;
pub mod partial;
pub mod png_header;
pub mod pnm_header;
pub mod preview;
pub mod ray;
pub mod recipe;
pub mod record;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod shard;
pub mod simd;
pub mod text;
pub mod texture;
pub mod tonemap;
pub mod verify;

pub use error::{Error, Result};
