//! What a scene sets besides its geometry: image size and sampling, the integrator's knobs
//! and shading mode, and the background. Plain data, read by the integrator and the renderer.

use crate::material::DiffuseModel;
use crate::math::{Color, PixelRect, Vec3};

/// What each camera sample computes: the book's stages before path tracing, then the path
/// tracer. Scene files name them in snake case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shading {
    /// Pixel coordinates as red and green (image 1); no rays.
    Uv,
    /// The background seen through the camera, ignoring objects (image 2).
    Gradient,
    /// The surface's albedo where a ray hits, the background elsewhere (image 3).
    Flat,
    /// `(n + 1) / 2` of the front-facing normal (images 4–6).
    Normals,
    /// Full path tracing with materials (images 7 onwards).
    #[default]
    Path,
}

/// The colour of rays that escape the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    Gradient { bottom: Color, top: Color },
    Uniform(Color),
}

impl Background {
    #[inline]
    pub fn radiance(&self, unit_dir: Vec3) -> Color {
        match *self {
            Background::Gradient { bottom, top } => {
                let t = 0.5 * (unit_dir.y + 1.0);
                (1.0 - t) * bottom + t * top
            }
            Background::Uniform(c) => c,
        }
    }
}

/// How a scattered ray keeps clear of the surface it leaves: the book's shadow-acne guard
/// (§8.4, its `t_min`), against meeting that surface again at once because the hit point
/// was rounded to the wrong side of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SurfaceOffset {
    /// The ray starts at the hit point and ignores hits until it is past a bound on the
    /// hit's rounding (`Sphere::escape_offset`, 16 units in the last place of the largest
    /// magnitude that went into it): about 10⁻⁵ on the book's small spheres, 0.002 on the
    /// radius-1000 ground. Rays nearly along the surface start that far off along the
    /// normal (`integrator::bounce`).
    Auto,
    /// A fixed start off the surface along the normal (scene files' `t_min = 0.001`); zero
    /// reproduces the book's acne. On curved glass a start moved sideways bends rays.
    Fixed(f32),
}

/// Image size, sampling and the integrator's knobs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// The pixels to render and write (the whole image unless the scene crops it).
    pub window: PixelRect,
    pub samples_per_pixel: u32,
    pub max_depth: u32,
    pub seed: u64,
    pub shading: Shading,
    pub diffuse: DiffuseModel,
    /// Display gamma of 8-bit outputs (the book: 1 until §8.3, then 2).
    pub gamma: f32,
    /// How far off the surface scattered rays start (the shadow-acne guard, §8.4).
    pub surface_offset: SurfaceOffset,
    /// Jitter samples within the pixel (anti-aliasing, §7); off for the first figures.
    pub jitter: bool,
}
