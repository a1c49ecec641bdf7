//! The sphere, with an intersection that stays accurate in `f32` for the radius-1000 ground.

use super::{Aabb, MaterialId, OFFSET_PER_UNIT};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;

/// A sphere; a negative radius flips its normals inward (the book's hollow glass trick).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
    pub material: MaterialId,
    /// `1 / radius`, so a hit's normal costs a multiplication instead of a division on the
    /// path's chain of dependent arithmetic.
    inv_radius: f32,
    /// The part of `escape_offset` that does not depend on the ray.
    offset_floor: f32,
}

impl Sphere {
    pub fn new(center: Vec3, radius: f32, material: MaterialId) -> Self {
        Self {
            center,
            radius,
            material,
            inv_radius: 1.0 / radius,
            offset_floor: OFFSET_PER_UNIT * (center.abs().max_element() + radius.abs()),
        }
    }

    /// How far off the surface, along the normal, a ray leaving a hit `t` along its ray must
    /// start to be on the side it leaves towards whatever the hit's rounding: a bound on that
    /// rounding. The hit comes from the ray's origin, the centre and the radius; the origin
    /// is within `t + |radius|` of the centre, so `|centre| + |radius| + t` bounds every
    /// magnitude in the arithmetic, and the errors are a few units in its last place.
    #[inline]
    pub fn escape_offset(&self, t: f32) -> f32 {
        self.offset_floor + OFFSET_PER_UNIT * t
    }

    pub fn bounds(&self) -> Aabb {
        let r = Vec3::splat(self.radius.abs());
        Aabb::new(self.center - r, self.center + r)
    }

    /// The nearest ray parameter in `interval` where `ray` (with a unit direction) meets the
    /// sphere.
    ///
    /// This is the book's half-b quadratic, rearranged for `f32` (Haines et al., *Ray Tracing
    /// Gems* ch. 7): the discriminant is `r² - |f + b d|²`, the squared distance of the
    /// chord's half, instead of `b² - c`, which cancels catastrophically when `|f|` and `r`
    /// are both near 1000; and the far root comes from `q = b + sign(b)·√disc`, the near one
    /// from `c / q`, so neither root is a difference of nearly equal numbers.
    #[inline]
    pub fn intersect(&self, ray: &Ray, interval: Interval) -> Option<f32> {
        hit_ball(self.center, self.radius * self.radius, ray, interval)
    }

    /// Both parameters where the line of `ray` meets the sphere, nearer first.
    pub fn line_hits(&self, ray: &Ray) -> Option<(f32, f32)> {
        line_hits_ball(self.center, self.radius * self.radius, ray)
    }

    /// Outward geometric normal at a surface point (inward for a negative radius).
    #[inline]
    pub fn normal_at(&self, p: Vec3) -> Vec3 {
        (p - self.center) * self.inv_radius
    }
}

/// The nearest ray parameter in `interval` where `ray` (with a unit direction) meets the ball
/// of centre `center` and squared radius `r2`: `Sphere::intersect`'s arithmetic, shared with
/// the moving sphere (at its centre for the ray's time).
#[inline(always)]
pub(crate) fn hit_ball(center: Vec3, r2: f32, ray: &Ray, interval: Interval) -> Option<f32> {
    // Written out per component, in the same order as the SIMD pack test of
    // `bvh::SpherePack`, so both give bit-identical answers.
    let (o, d, c) = (ray.origin, ray.dir, center);
    let (fx, fy, fz) = (o.x - c.x, o.y - c.y, o.z - c.z);
    let b = -(fx * d.x + fy * d.y + fz * d.z);
    let c = (fx * fx + fy * fy + fz * fz) - r2;
    // From outside and moving away both roots are negative: every ray leaving the
    // ground skips the rest. (The full test below says no in this case too.)
    if c > 0.0 && b < 0.0 && interval.min >= 0.0 {
        return None;
    }
    let (near, far) = roots(fx, fy, fz, b, c, r2, d)?;
    if interval.surrounds(near) {
        Some(near)
    } else if interval.surrounds(far) {
        Some(far)
    } else {
        None
    }
}

/// Both parameters where the line of `ray` meets the ball, nearer first.
pub(crate) fn line_hits_ball(center: Vec3, r2: f32, ray: &Ray) -> Option<(f32, f32)> {
    let (o, d, c) = (ray.origin, ray.dir, center);
    let (fx, fy, fz) = (o.x - c.x, o.y - c.y, o.z - c.z);
    let b = -(fx * d.x + fy * d.y + fz * d.z);
    let c = (fx * fx + fy * fy + fz * fz) - r2;
    roots(fx, fy, fz, b, c, r2, d)
}

/// The roots of the half-b quadratic of a ray from `f = o - centre` along `d`, nearer first.
#[inline(always)]
fn roots(fx: f32, fy: f32, fz: f32, b: f32, c: f32, r2: f32, d: Vec3) -> Option<(f32, f32)> {
    let (gx, gy, gz) = (fx + b * d.x, fy + b * d.y, fz + b * d.z);
    let disc = r2 - (gx * gx + gy * gy + gz * gz);
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    let q = if b >= 0.0 { b + sq } else { b - sq };
    let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
    Some((t0.min(t1), t0.max(t1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: Interval = Interval::new(0.0, f32::INFINITY);

    #[test]
    fn hits_front_of_unit_sphere() {
        let s = Sphere::new(Vec3::new(0.0, 0.0, -3.0), 1.0, MaterialId(0));
        let r = Ray::new(Vec3::ZERO, -Vec3::Z);
        assert_eq!(s.intersect(&r, ALL), Some(2.0));
        let p = r.at(2.0);
        assert_eq!(s.normal_at(p), Vec3::Z);
    }

    #[test]
    fn from_inside_finds_far_root() {
        let s = Sphere::new(Vec3::ZERO, 2.0, MaterialId(0));
        let r = Ray::new(Vec3::ZERO, Vec3::X);
        assert_eq!(s.intersect(&r, ALL), Some(2.0));
    }

    #[test]
    fn misses_and_behind() {
        let s = Sphere::new(Vec3::new(0.0, 0.0, -3.0), 1.0, MaterialId(0));
        assert_eq!(s.intersect(&Ray::new(Vec3::ZERO, Vec3::Y), ALL), None);
        assert_eq!(s.intersect(&Ray::new(Vec3::ZERO, Vec3::Z), ALL), None);
    }

    #[test]
    fn negative_radius_points_normals_inward() {
        let s = Sphere::new(Vec3::ZERO, -1.0, MaterialId(0));
        assert_eq!(s.normal_at(Vec3::X), -Vec3::X);
    }

    #[test]
    fn ground_sphere_hit_is_accurate_in_f32() {
        // The cover's ground: radius 1000 centred 1000 below the origin. A ray from the
        // camera down to the plane y = 0 must land on it to within a few micrometres, where
        // the textbook b² - c form is off by centimetres.
        let s = Sphere::new(Vec3::new(0.0, -1000.0, 0.0), 1000.0, MaterialId(0));
        let origin = Vec3::new(13.0, 2.0, 3.0);
        let target = Vec3::new(1.0, 0.0, 0.5);
        let dir = (target - origin).normalize();
        let t = s.intersect(&Ray::new(origin, dir), ALL).unwrap();
        let p = origin + t * dir;
        let exact = {
            let (o, d, c) = (
                origin.as_dvec3(),
                dir.as_dvec3(),
                glam::DVec3::new(0.0, -1000.0, 0.0),
            );
            let f = o - c;
            let b = f.dot(d);
            let cc = f.dot(f) - 1.0e6;
            -b - (b * b - cc).sqrt()
        };
        assert!((f64::from(t) - exact).abs() < 1e-4, "t {t} vs {exact}");
        assert!(p.y.abs() < 1e-3, "{p}");
    }

    #[test]
    fn ray_leaving_ground_does_not_hit_it_again() {
        let s = Sphere::new(Vec3::new(0.0, -1000.0, 0.0), 1000.0, MaterialId(0));
        let origin = Vec3::new(5.3, 1e-3, -7.1);
        for d in [
            Vec3::new(1.0, 0.01, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-0.7, 0.001, 0.7),
        ] {
            let r = Ray::new(origin, d.normalize());
            assert_eq!(s.intersect(&r, ALL), None, "{d}");
        }
    }
}
