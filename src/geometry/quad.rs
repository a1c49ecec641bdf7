//! The quadrilateral: a parallelogram `corner + a·u + b·v` for `a, b` in `[0, 1]`. The book's
//! axis-aligned rectangles (*The Next Week* §7) are quads whose edges lie along two axes, and
//! its boxes six of them; a rotated or moved one is still a quad.

use super::{Aabb, MaterialId, OFFSET_PER_UNIT};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;

/// A parallelogram with its plane (unit `normal` along `u × v`, offset `d = normal · corner`)
/// and the two vectors that give a point's coordinates along the edges: with
/// `w = n / (n · n)` (`n = u × v`) and `h = p - corner`, `a = w · (h × v) = h · (v × w)` and
/// `b = w · (u × h) = h · (w × u)`, so `along_u = v × w` and `along_v = w × u`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quad {
    pub corner: Vec3,
    pub u: Vec3,
    pub v: Vec3,
    pub material: MaterialId,
    pub normal: Vec3,
    d: f32,
    along_u: Vec3,
    along_v: Vec3,
    /// The part of `escape_offset` that does not depend on the ray.
    offset_floor: f32,
}

impl Quad {
    /// The quad from `corner` along edges `u` and `v`, which must not be parallel (the
    /// scene's checks refuse that).
    pub fn new(corner: Vec3, u: Vec3, v: Vec3, material: MaterialId) -> Self {
        // In f64, so the edge vectors are as exact as f32 can hold them.
        let f = |v: Vec3| glam::DVec3::new(v.x.into(), v.y.into(), v.z.into());
        let (du, dv) = (f(u), f(v));
        let n = du.cross(dv);
        let w = n / n.length_squared();
        let g = |v: glam::DVec3| Vec3::new(v.x as f32, v.y as f32, v.z as f32);
        let normal = g(n / n.length());
        let magnitude = corner.abs().max_element() + u.abs().max_element() + v.abs().max_element();
        Self {
            corner,
            u,
            v,
            material,
            normal,
            d: dot(normal, corner),
            along_u: g(dv.cross(w)),
            along_v: g(w.cross(du)),
            offset_floor: OFFSET_PER_UNIT * magnitude,
        }
    }

    /// The quad's plane: its unit normal and `normal · p` for points on it.
    pub fn plane(&self) -> (Vec3, f32) {
        (self.normal, self.d)
    }

    /// The vectors whose dot products with `p - corner` are a point's coordinates along `u`
    /// and `v`.
    pub fn edge_duals(&self) -> (Vec3, Vec3) {
        (self.along_u, self.along_v)
    }

    /// See `Sphere::escape_offset`: the hit comes from the ray's origin (within `t` of the
    /// hit) and the quad's corner and edges.
    #[inline]
    pub fn escape_offset(&self, t: f32) -> f32 {
        self.offset_floor + OFFSET_PER_UNIT * t
    }

    /// The box of the four corners, widened by a margin far above the rounding of the hit
    /// test, so a ray the test finds always meets the box (a rectangle's box is flat).
    pub fn bounds(&self) -> Aabb {
        let corners = [
            self.corner,
            self.corner + self.u,
            self.corner + self.v,
            self.corner + self.u + self.v,
        ];
        let b = corners.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p));
        let pad = Vec3::splat(64.0 * self.offset_floor + f32::MIN_POSITIVE);
        Aabb::new(b.min - pad, b.max + pad)
    }

    /// The nearest ray parameter in `interval` where `ray` meets the quad. Written out per
    /// component, in the same order as `bvh::QuadPack`, so both give the same bits.
    #[inline]
    pub fn intersect(&self, ray: &Ray, interval: Interval) -> Option<f32> {
        let (t, a, b) = self.plane_hit(ray)?;
        let inside = (0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b);
        (inside && interval.surrounds(t)).then_some(t)
    }

    /// The ray parameter where `ray` meets the quad's plane and the hit's coordinates along
    /// `u` and `v`; `None` for a ray parallel to the plane. With `f = o - corner`, the
    /// coordinates are `f · A + t (d · A)` (`A = along_u`, and so for `v`): their dot
    /// products wait on no division, only their last step on `t`'s.
    #[inline(always)]
    pub fn plane_hit(&self, ray: &Ray) -> Option<(f32, f32, f32)> {
        let (o, dir, n) = (ray.origin, ray.dir, self.normal);
        let denom = n.x * dir.x + n.y * dir.y + n.z * dir.z;
        if denom.abs() < 1e-8 {
            return None;
        }
        let t = (self.d - (n.x * o.x + n.y * o.y + n.z * o.z)) / denom;
        let (fx, fy, fz) = (
            o.x - self.corner.x,
            o.y - self.corner.y,
            o.z - self.corner.z,
        );
        let (au, av) = (self.along_u, self.along_v);
        let a0 = fx * au.x + fy * au.y + fz * au.z;
        let da = dir.x * au.x + dir.y * au.y + dir.z * au.z;
        let b0 = fx * av.x + fy * av.y + fz * av.z;
        let db = dir.x * av.x + dir.y * av.y + dir.z * av.z;
        Some((t, a0 + t * da, b0 + t * db))
    }

    /// The texture coordinates of a point on the quad: its coordinates along `u` and `v`.
    pub fn uv(&self, p: Vec3) -> (f32, f32) {
        let h = p - self.corner;
        (dot(h, self.along_u), dot(h, self.along_v))
    }
}

#[inline(always)]
fn dot(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: Interval = Interval::new(0.0, f32::INFINITY);

    #[test]
    fn a_rectangle_is_hit_inside_and_missed_outside() {
        // The book's xy_rect(3, 5, 1, 3, -2): corner (3, 1, -2), edges along x and y.
        let q = Quad::new(
            Vec3::new(3.0, 1.0, -2.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            MaterialId(0),
        );
        assert_eq!(q.normal, Vec3::Z);
        let toward = |x: f32, y: f32| Ray::new(Vec3::new(x, y, 5.0), -Vec3::Z);
        assert_eq!(q.intersect(&toward(4.0, 2.0), ALL), Some(7.0));
        assert_eq!(q.intersect(&toward(5.5, 2.0), ALL), None);
        assert_eq!(q.intersect(&toward(4.0, 0.5), ALL), None);
        // Parallel to the plane, and behind the ray.
        assert_eq!(
            q.intersect(&Ray::new(Vec3::new(4.0, 2.0, 5.0), Vec3::X), ALL),
            None
        );
        assert_eq!(
            q.intersect(&Ray::new(Vec3::new(4.0, 2.0, 5.0), Vec3::Z), ALL),
            None
        );
        let (a, b) = q.uv(Vec3::new(4.5, 1.5, -2.0));
        assert!(
            (a - 0.75).abs() < 1e-6 && (b - 0.25).abs() < 1e-6,
            "{a} {b}"
        );
    }

    #[test]
    fn every_hit_lies_in_the_box_and_on_the_plane() {
        let mut rng = crate::sampling::Sampler::from_seed(4);
        for _ in 0..200 {
            let corner = 300.0 * Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
            let u = 200.0 * (rng.unit_vector() * rng.range(0.1, 1.0));
            let v = 200.0 * (rng.unit_vector() * rng.range(0.1, 1.0));
            if crate::math::cross(u, v).length() < 1.0 {
                continue;
            }
            let q = Quad::new(corner, u, v, MaterialId(0));
            let b = q.bounds();
            for _ in 0..200 {
                let target = corner + rng.uniform() * u + rng.uniform() * v;
                let origin = target + 500.0 * rng.unit_vector();
                let ray = Ray::new(origin, (target - origin).normalize());
                let Some(t) = q.intersect(&ray, ALL) else {
                    continue;
                };
                let p = ray.at(t);
                assert!(p.cmpge(b.min).all() && p.cmple(b.max).all(), "{p} {b:?}");
                let (n, d) = q.plane();
                assert!((n.dot(p) - d).abs() < 1e-3, "{}", n.dot(p) - d);
            }
        }
    }
}
