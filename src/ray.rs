//! The ray: an origin and a unit direction.

use crate::math::Vec3;

/// A ray `origin + t * dir`. The tracer keeps `dir` normalised so that `t` is a distance,
/// which keeps the sphere discriminant well conditioned in `f32`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

impl Ray {
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self { origin, dir }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }
}
