//! The book's positionable thin-lens camera: settings in, derived basis out, rays per pixel.

use crate::math::Vec3;
use crate::ray::Ray;
use crate::sampling::Sampler;

/// What the user states about the camera (the book's constructor arguments).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSettings {
    pub lookfrom: Vec3,
    pub lookat: Vec3,
    pub vup: Vec3,
    pub vfov_deg: f32,
    /// Width over height of the viewport.
    pub aspect_ratio: f32,
    /// Lens diameter; 0 is a pinhole.
    pub aperture: f32,
    /// Distance from `lookfrom` to the plane in perfect focus.
    pub focus_dist: f32,
}

/// The derived camera (the book's `camera` class).
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    origin: Vec3,
    lower_left_corner: Vec3,
    horizontal: Vec3,
    vertical: Vec3,
    u: Vec3,
    v: Vec3,
    lens_radius: f32,
}

impl Camera {
    pub fn new(s: &CameraSettings) -> Self {
        let h = (s.vfov_deg.to_radians() / 2.0).tan();
        let viewport_height = 2.0 * h;
        let viewport_width = s.aspect_ratio * viewport_height;
        let w = (s.lookfrom - s.lookat).normalize();
        let u = s.vup.cross(w).normalize();
        let v = w.cross(u);
        let horizontal = s.focus_dist * viewport_width * u;
        let vertical = s.focus_dist * viewport_height * v;
        Self {
            origin: s.lookfrom,
            lower_left_corner: s.lookfrom - horizontal / 2.0 - vertical / 2.0 - s.focus_dist * w,
            horizontal,
            vertical,
            u,
            v,
            lens_radius: s.aperture / 2.0,
        }
    }

    /// The ray through viewport coordinates `(s, t)` in `[0,1]²`, `(0,0)` the lower left
    /// corner, with a unit direction. Draws a lens sample from `rng` only when the lens has
    /// an aperture.
    #[inline]
    pub fn ray(&self, s: f32, t: f32, rng: &mut Sampler) -> Ray {
        let offset = if self.lens_radius > 0.0 {
            let (x, y) = rng.in_unit_disk();
            self.lens_radius * (x * self.u + y * self.v)
        } else {
            Vec3::ZERO
        };
        let target = self.lower_left_corner + s * self.horizontal + t * self.vertical;
        let origin = self.origin + offset;
        Ray::new(origin, (target - origin).normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> CameraSettings {
        CameraSettings {
            lookfrom: Vec3::new(-2.0, 2.0, 1.0),
            lookat: Vec3::new(0.0, 0.0, -1.0),
            vup: Vec3::Y,
            vfov_deg: 90.0,
            aspect_ratio: 2.0,
            aperture: 0.0,
            focus_dist: 1.0,
        }
    }

    #[test]
    fn centre_ray_points_at_lookat() {
        let s = settings();
        let cam = Camera::new(&s);
        let r = cam.ray(0.5, 0.5, &mut Sampler::from_seed(0));
        let expect = (s.lookat - s.lookfrom).normalize();
        assert!((r.dir - expect).length() < 1e-6);
        assert_eq!(r.origin, s.lookfrom);
    }

    #[test]
    fn corner_rays_span_the_vertical_field_of_view() {
        let s = settings();
        let cam = Camera::new(&s);
        let mut rng = Sampler::from_seed(0);
        let top = cam.ray(0.5, 1.0, &mut rng).dir;
        let bottom = cam.ray(0.5, 0.0, &mut rng).dir;
        let angle = top.dot(bottom).acos().to_degrees();
        assert!((angle - 90.0).abs() < 1e-3, "{angle}");
        // With vup = +y the top edge ray points higher than the bottom one.
        assert!(top.y > bottom.y);
    }

    #[test]
    fn defocused_rays_converge_on_the_focus_plane() {
        let mut s = settings();
        s.aperture = 0.5;
        s.focus_dist = (s.lookat - s.lookfrom).length();
        let cam = Camera::new(&s);
        let mut rng = Sampler::from_seed(3);
        for _ in 0..100 {
            let r = cam.ray(0.5, 0.5, &mut rng);
            assert!((r.origin - s.lookfrom).length() <= 0.25 + 1e-6);
            let p = r.at((s.lookat - r.origin).length());
            assert!((p - s.lookat).length() < 1e-4, "{p}");
        }
    }
}
