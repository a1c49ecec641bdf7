//! The moving sphere of motion blur (*The Next Week* §2): a centre that moves on a line at
//! constant speed, at `center0` at `time0` and `center1` at `time1`.

use super::sphere::hit_ball;
use super::{Aabb, MaterialId, OFFSET_PER_UNIT};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;

/// A sphere whose centre moves linearly with time (extrapolated outside `time0..time1`, as
/// the book's `moving_sphere::center` does).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MovingSphere {
    pub center0: Vec3,
    pub center1: Vec3,
    pub time0: f32,
    /// `1 / (time1 - time0)`, 0 when the two times are one (the sphere then stands still).
    pub inv_duration: f32,
    pub radius: f32,
    pub material: MaterialId,
    /// The times every ray's lies within (the camera's shutter): the sphere's box holds it
    /// over them.
    shutter: (f32, f32),
    inv_radius: f32,
    offset_floor: f32,
}

impl MovingSphere {
    /// A sphere at `center0` at `time0` and `center1` at `time1`, seen by rays whose times
    /// lie in `shutter`.
    pub fn new(
        (center0, time0): (Vec3, f32),
        (center1, time1): (Vec3, f32),
        radius: f32,
        material: MaterialId,
        shutter: (f32, f32),
    ) -> Self {
        let duration = time1 - time0;
        let inv_duration = if duration != 0.0 { 1.0 / duration } else { 0.0 };
        let mut moving = Self {
            center0,
            center1,
            time0,
            inv_duration,
            radius,
            material,
            shutter,
            inv_radius: 1.0 / radius,
            offset_floor: 0.0,
        };
        // The largest centre any ray meets it at bounds the magnitudes of its arithmetic.
        let reach = moving
            .center(shutter.0)
            .abs()
            .max(moving.center(shutter.1).abs())
            .max_element();
        moving.offset_floor = OFFSET_PER_UNIT * (reach + radius.abs());
        moving
    }

    /// The centre at `time`: `center0 + ((time - time0) / (time1 - time0)) (center1 - center0)`.
    #[inline(always)]
    pub fn center(&self, time: f32) -> Vec3 {
        let s = (time - self.time0) * self.inv_duration;
        let delta = self.center1 - self.center0;
        Vec3::new(
            self.center0.x + s * delta.x,
            self.center0.y + s * delta.y,
            self.center0.z + s * delta.z,
        )
    }

    /// See `Sphere::escape_offset`.
    #[inline]
    pub fn escape_offset(&self, t: f32) -> f32 {
        self.offset_floor + OFFSET_PER_UNIT * t
    }

    /// The box of the sphere over the shutter: its motion is a line, so the boxes at the two
    /// ends hold it in between.
    pub fn bounds(&self) -> Aabb {
        let r = Vec3::splat(self.radius.abs());
        let (a, b) = (self.center(self.shutter.0), self.center(self.shutter.1));
        Aabb::new(a.min(b) - r, a.max(b) + r)
    }

    /// The nearest hit in `interval` of `ray` taken at `time`: `Sphere::intersect` at the
    /// centre of that time.
    #[inline]
    pub fn intersect(&self, ray: &Ray, time: f32, interval: Interval) -> Option<f32> {
        hit_ball(self.center(time), self.radius * self.radius, ray, interval)
    }

    /// Both parameters where the line of `ray` at `time` meets the sphere, nearer first.
    pub fn line_hits(&self, ray: &Ray, time: f32) -> Option<(f32, f32)> {
        super::sphere::line_hits_ball(self.center(time), self.radius * self.radius, ray)
    }

    /// Outward geometric normal at a surface point at `time` (inward for a negative radius).
    #[inline]
    pub fn normal_at(&self, p: Vec3, time: f32) -> Vec3 {
        (p - self.center(time)) * self.inv_radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_moves_on_its_line_and_the_box_holds_it_over_the_shutter() {
        let s = MovingSphere::new(
            (Vec3::new(1.0, 0.2, 0.0), 0.0),
            (Vec3::new(1.0, 0.7, 0.0), 1.0),
            0.2,
            MaterialId(0),
            (0.0, 1.0),
        );
        assert_eq!(s.center(0.0), Vec3::new(1.0, 0.2, 0.0));
        assert_eq!(s.center(1.0), Vec3::new(1.0, 0.7, 0.0));
        assert!((s.center(0.5).y - 0.45).abs() < 1e-6);
        let b = s.bounds();
        assert_eq!((b.min.y, b.max.y), (0.0, 0.9));
        // A ray along y through the axis meets the bottom of the sphere where it is at that
        // time.
        let ray = Ray::new(Vec3::new(1.0, -5.0, 0.0), Vec3::Y);
        let all = Interval::new(0.0, f32::INFINITY);
        for time in [0.0, 0.25, 0.5, 1.0] {
            let t = s.intersect(&ray, time, all).unwrap();
            let bottom = s.center(time).y - 0.2;
            assert!((ray.at(t).y - bottom).abs() < 1e-5, "{time}");
        }
    }

    #[test]
    fn equal_times_stand_still() {
        let c = Vec3::new(0.0, 1.0, 0.0);
        let s = MovingSphere::new((c, 0.5), (c + Vec3::X, 0.5), 1.0, MaterialId(0), (0.0, 1.0));
        assert_eq!(s.center(0.0), c);
        assert_eq!(s.center(1.0), c);
    }
}
