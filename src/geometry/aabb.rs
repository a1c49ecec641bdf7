//! Axis-aligned bounding boxes and the slab test.

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

    /// Entry distance of a ray into the box if it meets the box within `(t_min, t_max)`.
    /// `inv_dir` is `1 / dir` per component (infinities are fine).
    #[inline]
    pub fn hit(&self, origin: Vec3, inv_dir: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        let near = t0.min(t1).max_element().max(t_min);
        let far = t0.max(t1).min_element().min(t_max);
        (near <= far).then_some(near)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_test_hits_and_misses() {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let o = Vec3::new(0.0, 0.0, -5.0);
        let d = Vec3::Z;
        assert_eq!(b.hit(o, d.recip(), 0.0, f32::INFINITY), Some(4.0));
        assert_eq!(b.hit(o, d.recip(), 0.0, 3.0), None);
        let o2 = Vec3::new(2.0, 0.0, -5.0);
        assert_eq!(b.hit(o2, d.recip(), 0.0, f32::INFINITY), None);
    }

    #[test]
    fn area_and_union() {
        let a = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(a.area(), 6.0);
        assert_eq!(Aabb::EMPTY.area(), 0.0);
        assert_eq!(Aabb::EMPTY.union(a), a);
    }
}
