//! Constant-density media (*The Next Week* §9): smoke or fog filling a convex boundary (a
//! sphere, a moving sphere or a box), which a ray crossing it may scatter in at a distance
//! drawn from the exponential law of its density.

use super::{Aabb, MaterialId, MovingSphere, Quad, Sphere};
use crate::math::{Interval, Vec3, ln_f32};
use crate::ray::Ray;
use crate::sampling::mix64;

/// The convex shape a medium fills.
#[derive(Clone, Debug, PartialEq)]
pub enum Boundary {
    Sphere(Sphere),
    MovingSphere(MovingSphere),
    /// A box (or any convex solid) as the quads of its faces.
    Quads(Vec<Quad>),
}

impl Boundary {
    pub fn bounds(&self) -> Aabb {
        match self {
            Boundary::Sphere(s) => s.bounds(),
            Boundary::MovingSphere(s) => s.bounds(),
            Boundary::Quads(quads) => quads.iter().fold(Aabb::EMPTY, |b, q| b.union(q.bounds())),
        }
    }

    /// Where the line of `ray` (at `time`) enters and leaves the boundary: the nearest and
    /// farthest of its hits anywhere along the line. A line meets a convex solid's surface
    /// at two points at most, so no cut-off like the book's `rec1.t + 0.0001` is needed to
    /// find the second.
    fn line_hits(&self, ray: &Ray, time: f32) -> Option<(f32, f32)> {
        match self {
            Boundary::Sphere(s) => s.line_hits(ray),
            Boundary::MovingSphere(s) => s.line_hits(ray, time),
            Boundary::Quads(quads) => {
                let all = Interval::new(f32::NEG_INFINITY, f32::INFINITY);
                let mut span: Option<(f32, f32)> = None;
                for t in quads.iter().filter_map(|q| q.intersect(ray, all)) {
                    span = Some(span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
                }
                span
            }
        }
    }
}

/// A medium of constant density: its boundary, `-1 / density` and its phase function's
/// material (the book's isotropic).
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    pub boundary: Boundary,
    pub density: f32,
    pub material: MaterialId,
    neg_inv_density: f32,
}

impl Medium {
    pub fn new(boundary: Boundary, density: f32, material: MaterialId) -> Self {
        Self {
            boundary,
            density,
            material,
            neg_inv_density: -1.0 / density,
        }
    }

    pub fn bounds(&self) -> Aabb {
        self.boundary.bounds()
    }

    /// Where in `interval` a ray crossing the medium scatters, if it does: the book's
    /// `constant_medium::hit`. The distance inside is exponential in the density, drawn from
    /// `key` (the segment's random number, `Moment::medium_key`) and `id` (the medium's), so
    /// that the answer does not depend on the order or the number of times the medium is
    /// tested.
    pub fn intersect(
        &self,
        ray: &Ray,
        time: f32,
        key: u32,
        id: u32,
        interval: Interval,
    ) -> Option<f32> {
        let (enter, leave) = self.boundary.line_hits(ray, time)?;
        let enter = enter.max(interval.min).max(0.0);
        let leave = leave.min(interval.max);
        if enter.partial_cmp(&leave) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        // The ray's direction is a unit vector: parameters are distances.
        let distance = self.neg_inv_density * ln_f32(uniform_open(key, id));
        let t = enter + distance;
        (distance <= leave - enter && interval.surrounds(t)).then_some(t)
    }
}

/// A uniform number in `(0, 1]` from a segment's key and a medium's id.
#[inline]
fn uniform_open(key: u32, id: u32) -> f32 {
    let bits = mix64((u64::from(key) << 32) | u64::from(id)) >> 40;
    (bits + 1) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The hit record's normal of a scattering point: any unit vector does (the book's
/// `(1, 0, 0)`); the phase function does not look at it.
pub const SCATTER_NORMAL: Vec3 = Vec3::X;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_free_path_is_one_over_the_density() {
        // A slab of fog 1000 thick: the distance to the first scattering is exponential
        // with mean 1/density, whatever the keys.
        let boundary = Boundary::Sphere(Sphere::new(Vec3::ZERO, 1000.0, MaterialId(0)));
        let density = 0.05;
        let fog = Medium::new(boundary, density, MaterialId(0));
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        let all = Interval::new(0.0, f32::INFINITY);
        let n = 50_000;
        let mean = (0..n)
            .map(|key| f64::from(fog.intersect(&ray, 0.0, key, 7, all).unwrap()))
            .sum::<f64>()
            / f64::from(n);
        assert!((mean * f64::from(density) - 1.0).abs() < 0.02, "{mean}");
        // From outside, the ray enters first; and a closer hit elsewhere cuts it short.
        let outside = Ray::new(Vec3::new(-2000.0, 0.0, 0.0), Vec3::X);
        let t = fog.intersect(&outside, 0.0, 3, 7, all).unwrap();
        assert!(t >= 1000.0, "{t}");
        let near = Interval::new(0.0, 999.0);
        assert_eq!(fog.intersect(&outside, 0.0, 3, 7, near), None);
    }

    #[test]
    fn a_box_boundary_is_entered_and_left_once() {
        let corner = Vec3::ZERO;
        let faces = |size: f32| {
            let (x, y, z) = (size * Vec3::X, size * Vec3::Y, size * Vec3::Z);
            vec![
                Quad::new(corner, x, y, MaterialId(0)),
                Quad::new(corner + z, x, y, MaterialId(0)),
                Quad::new(corner, y, z, MaterialId(0)),
                Quad::new(corner + x, y, z, MaterialId(0)),
                Quad::new(corner, z, x, MaterialId(0)),
                Quad::new(corner + y, z, x, MaterialId(0)),
            ]
        };
        let b = Boundary::Quads(faces(10.0));
        let ray = Ray::new(Vec3::new(5.0, 5.0, -20.0), Vec3::Z);
        assert_eq!(b.line_hits(&ray, 0.0), Some((20.0, 30.0)));
        let inside = Ray::new(Vec3::new(5.0, 5.0, 5.0), Vec3::Z);
        assert_eq!(b.line_hits(&inside, 0.0), Some((-5.0, 5.0)));
    }
}
