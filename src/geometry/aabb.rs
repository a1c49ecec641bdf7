//! Axis-aligned bounding boxes: union, centroid and surface area for the BVH build.

use crate::math::Vec3;

/// An axis-aligned box; `EMPTY` is the identity of `union`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    pub fn union(self, other: Aabb) -> Aabb {
        Aabb::new(self.min.min(other.min), self.max.max(other.max))
    }

    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb::new(self.min.min(p), self.max.max(p))
    }

    pub fn centroid(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Surface area, the cost measure of the SAH; zero for an empty box.
    pub fn area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.max - self.min;
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_and_union() {
        let a = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(a.area(), 6.0);
        assert_eq!(Aabb::EMPTY.area(), 0.0);
        assert_eq!(Aabb::EMPTY.union(a), a);
    }
}
