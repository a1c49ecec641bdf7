//! Geometric primitives and what a ray learns when it hits one; knows nothing of materials
//! beyond the id a primitive carries.

mod aabb;
mod sphere;

pub use aabb::Aabb;
pub use sphere::Sphere;

use crate::math::Vec3;

/// Index of a material in the scene's material table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MaterialId(pub u32);

/// Index of a primitive in the scene's primitive table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PrimitiveId(pub u32);

/// The surface record at a ray's closest hit (the book's `hit_record`).
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// The hit point.
    pub p: Vec3,
    /// Unit normal facing against the incoming ray.
    pub normal: Vec3,
    /// True when the ray arrived from the side the geometric normal points to.
    pub front_face: bool,
    /// True when `normal` points out of the primitive's solid (for a sphere, where
    /// `p - centre` points, whatever the radius' sign).
    pub normal_points_out: bool,
    pub material: MaterialId,
    pub primitive: PrimitiveId,
}

impl Hit {
    /// True when a ray leaving this hit off the side of its normal (`side_is_normal`) or of
    /// the opposite starts outside the solid it hit and heads away from it: it cannot meet
    /// that (convex) solid again.
    #[inline]
    pub fn leaves_outside(&self, side_is_normal: bool) -> bool {
        self.normal_points_out == side_is_normal
    }
}
