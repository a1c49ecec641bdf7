//! tessera: a deterministic, tiled, multicore path tracer of *Ray Tracing in One Weekend*.
//!
//! The pipeline runs downward through the modules: a [`scene`] file is parsed and validated
//! into a runtime [`scene::Scene`]; [`render`] cuts the image into tiles and spreads them over
//! a rayon pool; each camera sample asks the [`integrator`] for radiance with its own seeded
//! [`sampling::Sampler`]; the [`film`] accumulates exact fixed-point sums and writes images.
//! The same scene, settings and seed give the same bytes whatever the thread count or tile
//! size.

#![forbid(unsafe_code)]

pub mod bvh;
pub mod camera;
pub mod compare;
pub mod error;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod job;
pub mod material;
pub mod math;
pub mod partial;
pub mod ray;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod shard;

pub use error::{Error, Result};
