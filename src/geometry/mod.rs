//! Geometric primitives and what a ray learns when it hits one; knows nothing of materials
//! beyond the id a primitive carries. The kinds: still spheres, moving spheres (motion
//! blur), quadrilaterals (the book's rectangles and boxes), and constant-density media
//! bounded by one of the others.

mod aabb;
mod medium;
mod moving;
mod quad;
mod sphere;

pub use aabb::Aabb;
pub use medium::{Boundary, Medium, SCATTER_NORMAL};
pub use moving::MovingSphere;
pub use quad::Quad;
pub use sphere::Sphere;

/// A hit's rounding error bound per unit of the magnitudes that went into it: 16 units in the
/// last place (2⁻²⁴ each). `integrator::tests` bounce off spheres of radius 10⁻³ to 10³ up to
/// 3000 from the origin: at 8 no bounce started on the wrong side of the surface over
/// millions (at 4, a few in 10⁵); this is twice that.
pub(crate) const OFFSET_PER_UNIT: f32 = 16.0 * f32::EPSILON / 2.0;

use crate::math::Vec3;

/// Index of a material in the scene's material table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MaterialId(pub u32);

/// A primitive: its kind in the top two bits, its index among the scene's primitives of that
/// kind below them. Ties between hits at the same distance go to the lower id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PrimitiveId(pub u32);

/// The kinds of primitive, as `PrimitiveId::kind` tells them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimitiveKind {
    Sphere,
    MovingSphere,
    Quad,
    Medium,
}

impl PrimitiveId {
    /// The first id of each kind.
    pub const SPHERES: u32 = 0;
    pub const MOVING_SPHERES: u32 = 1 << 30;
    pub const QUADS: u32 = 2 << 30;
    pub const MEDIA: u32 = 3 << 30;
    /// The most primitives of one kind: the last id of all means no hit.
    pub const MAX_PER_KIND: usize = (1 << 30) - 1;

    #[inline(always)]
    pub fn kind(self) -> PrimitiveKind {
        match self.0 >> 30 {
            0 => PrimitiveKind::Sphere,
            1 => PrimitiveKind::MovingSphere,
            2 => PrimitiveKind::Quad,
            _ => PrimitiveKind::Medium,
        }
    }

    /// The index among the scene's primitives of its kind.
    #[inline(always)]
    pub fn index(self) -> usize {
        (self.0 & ((1 << 30) - 1)) as usize
    }
}

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
