//! The book's positionable thin-lens camera: settings in, derived basis out, rays per pixel.

use crate::math::{Vec3, cross, tan, unit};
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
    /// When the shutter opens and closes (*The Next Week*'s `time0`, `time1`): each camera
    /// ray is taken at a uniform time between them, which blurs what moves. Equal times
    /// (the default, both 0) take every ray at that time and draw nothing.
    pub shutter: (f32, f32),
}

/// The derived camera (the book's `camera` class).
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    origin: Vec3,
    /// The focus plane's lower left corner, from `origin`: a ray's direction is computed
    /// without `origin`'s magnitude, whose rounding (1.2·10⁻⁴ at 1000) would otherwise move
    /// film points by pixels in a narrow view from afar.
    to_lower_left: Vec3,
    horizontal: Vec3,
    vertical: Vec3,
    u: Vec3,
    v: Vec3,
    /// Unit view direction, from `origin` towards the focus plane.
    forward: Vec3,
    focus_dist: f32,
    lens_radius: f32,
    shutter: (f32, f32),
}

/// A conservative bound of every ray the camera shoots through a rectangle of the film,
/// whatever the lens sample: spheres wholly outside it cannot be any of those rays' hit.
///
/// In camera coordinates (`x` along `u`, `y` along `v`, depth `z` along the view, the lens
/// at `z = 0` and the focus plane at `z = D`), a ray from lens point `a` (with `|a| ≤ R` per
/// axis) through film point `f` is at `x = a + (z/D)(f - a)` at depth `z`. Over all `a` and
/// `f ∈ [f0, f1]` that spans `[(z/D) f0 - R|1 - z/D|, (z/D) f1 + R|1 - z/D|]`: each side is
/// bounded by the outer of two planes meeting at the film rectangle's edge, one for the
/// stretch between lens and focus plane, one beyond. A shape is outside the bundle when it
/// lies wholly beyond both planes of any one side.
#[derive(Clone, Copy, Debug)]
pub struct RayBundle {
    origin: Vec3,
    /// x min, x max, y min, y max: two planes each.
    sides: [[BundlePlane; 2]; 4],
}

/// A plane through the bundle's side, in world space relative to the camera's origin: the
/// bundle lies where `normal · p - offset ≥ 0`.
#[derive(Clone, Copy, Debug)]
struct BundlePlane {
    normal: Vec3,
    offset: f32,
    /// The normal's length, which scales distances measured with it.
    norm: f32,
}

impl RayBundle {
    /// False only if no ray of the bundle can meet the sphere (margins cover rounding).
    pub fn may_hit(&self, center: Vec3, radius: f32) -> bool {
        let rel = center - self.origin;
        let r = radius.abs() + 1e-4 * (rel.length() + radius.abs()) + 1e-5;
        self.may_reach(rel, |p| r * p.norm)
    }

    /// False only if no ray of the bundle can meet the box from `min` to `max`.
    pub fn may_hit_box(&self, min: Vec3, max: Vec3) -> bool {
        let (center, half) = ((min + max) * 0.5, (max - min) * 0.5);
        let rel = center - self.origin;
        let margin = 1e-4 * (rel.length() + half.length()) + 1e-5;
        // The box reaches out along a normal by its half extents times the normal's
        // components.
        self.may_reach(rel, |p| p.normal.abs().dot(half) + margin * p.norm)
    }

    /// False when a shape centred at `rel` (from the camera's origin), reaching `reach(plane)`
    /// along each plane's normal, lies beyond both planes of some side.
    fn may_reach(&self, rel: Vec3, reach: impl Fn(&BundlePlane) -> f32) -> bool {
        let beyond = |p: &BundlePlane| p.normal.dot(rel) - p.offset + reach(p) < 0.0;
        !self.sides.iter().any(|side| side.iter().all(beyond))
    }
}

impl Camera {
    pub fn new(s: &CameraSettings) -> Self {
        let h = tan(s.vfov_deg.to_radians() / 2.0);
        let viewport_height = 2.0 * h;
        let viewport_width = s.aspect_ratio * viewport_height;
        let w = unit(s.lookfrom - s.lookat);
        let u = unit(cross(s.vup, w));
        let v = cross(w, u);
        let horizontal = s.focus_dist * viewport_width * u;
        let vertical = s.focus_dist * viewport_height * v;
        Self {
            forward: -w,
            focus_dist: s.focus_dist,
            origin: s.lookfrom,
            to_lower_left: -horizontal / 2.0 - vertical / 2.0 - s.focus_dist * w,
            horizontal,
            vertical,
            u,
            v,
            lens_radius: s.aperture / 2.0,
            shutter: s.shutter,
        }
    }

    /// True when the shutter stays open for a while: rays then have times of their own.
    pub fn has_shutter(&self) -> bool {
        self.shutter.0 != self.shutter.1
    }

    /// The time of a camera ray: uniform over the shutter's opening, drawn from `rng` (after
    /// the lens, as the book's `get_ray` draws it) only when it is open for a while.
    #[inline]
    pub fn time(&self, rng: &mut Sampler) -> f32 {
        let (open, close) = self.shutter;
        if open == close {
            open
        } else {
            rng.range(open, close)
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
        let target = self.to_lower_left + s * self.horizontal + t * self.vertical;
        Ray::new(self.origin + offset, unit(target - offset))
    }

    /// True when every ray the camera shoots has a sound unit direction: the view's
    /// arithmetic (focus distance times the viewport, plus the lens) neither overflows nor
    /// underflows f32.
    pub fn rays_are_finite(&self) -> bool {
        let basis = [
            self.origin,
            self.to_lower_left,
            self.horizontal,
            self.vertical,
            self.u,
            self.v,
            self.forward,
        ];
        let lens = self.lens_radius * std::f32::consts::SQRT_2;
        // A ray's direction before normalising is at most a corner's reach plus the lens,
        // and at least the focus distance (the lens lies across the view).
        let longest_fits =
            [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .iter()
                .all(|&(s, t)| {
                    let corner = self.to_lower_left + s * self.horizontal + t * self.vertical;
                    let reach = corner.length() + lens;
                    (reach * reach).is_finite()
                });
        basis.iter().all(|v| v.is_finite())
            && lens.is_finite()
            && longest_fits
            && self.focus_dist * self.focus_dist >= f32::MIN_POSITIVE
    }

    /// Bounds every ray `ray(s, t, _)` with `s` in `s_range` and `t` in `t_range`.
    pub fn bundle(&self, s_range: (f32, f32), t_range: (f32, f32)) -> RayBundle {
        let (d, r) = (self.focus_dist, self.lens_radius.abs());
        // Film rectangle edges, in camera coordinates on the focus plane.
        let (width, height) = (self.horizontal.length(), self.vertical.length());
        let x = (width * (s_range.0 - 0.5), width * (s_range.1 - 0.5));
        let y = (height * (t_range.0 - 0.5), height * (t_range.1 - 0.5));
        // In camera coordinates a plane `sign · (c - slope · z - offset) = 0` for coordinate
        // `c` along `axis`; in world space its normal is `sign · (axis - slope · forward)`.
        let plane = |axis: Vec3, sign: f32, slope: f32, offset: f32| BundlePlane {
            normal: sign * (axis - slope * self.forward),
            offset: sign * offset,
            norm: (1.0 + slope * slope).sqrt(),
        };
        // Lower edge f0: c ≥ (z/D)(f0 + R) - R up to the focus plane, (z/D)(f0 - R) + R beyond.
        let low = |axis, f0: f32| {
            [
                plane(axis, 1.0, (f0 + r) / d, -r),
                plane(axis, 1.0, (f0 - r) / d, r),
            ]
        };
        // Upper edge f1: c ≤ (z/D)(f1 - R) + R, then (z/D)(f1 + R) - R.
        let high = |axis, f1: f32| {
            [
                plane(axis, -1.0, (f1 - r) / d, r),
                plane(axis, -1.0, (f1 + r) / d, -r),
            ]
        };
        RayBundle {
            origin: self.origin,
            sides: [
                low(self.u, x.0),
                high(self.u, x.1),
                low(self.v, y.0),
                high(self.v, y.1),
            ],
        }
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
            shutter: (0.0, 0.0),
        }
    }

    /// Spheres placed on camera rays through a film rectangle: the bundle must keep every
    /// one, and must drop spheres well off to the side.
    #[test]
    fn ray_bundles_keep_every_sphere_a_ray_can_hit() {
        let mut rng = Sampler::from_seed(11);
        for aperture in [0.0, 0.1, 2.0] {
            let mut s = settings();
            s.lookfrom = Vec3::new(13.0, 2.0, 3.0);
            s.lookat = Vec3::ZERO;
            s.vfov_deg = 20.0;
            s.aperture = aperture;
            s.focus_dist = 10.0;
            let cam = Camera::new(&s);
            for _ in 0..200 {
                let s0 = rng.uniform() * 0.9;
                let t0 = rng.uniform() * 0.9;
                let (s1, t1) = (s0 + 0.02, t0 + 0.03);
                let bundle = cam.bundle((s0, s1), (t0, t1));
                for _ in 0..20 {
                    let ray = cam.ray(
                        s0 + (s1 - s0) * rng.uniform(),
                        t0 + (t1 - t0) * rng.uniform(),
                        &mut rng,
                    );
                    let radius = rng.range(0.01, 1.0);
                    // The sphere's surface just touches the ray at a random distance.
                    let along = ray.at(rng.range(0.1, 40.0));
                    let side = ray.dir.any_orthonormal_vector();
                    let center = along + side * radius * 0.999;
                    assert!(bundle.may_hit(center, radius), "{ray:?} {center} {radius}");
                }
                // Far off to one side of the rectangle, at the rectangle's own depth.
                let mid = cam.ray((s0 + s1) / 2.0, (t0 + t1) / 2.0, &mut rng);
                let away = mid.at(10.0) + cam.u * 5.0;
                assert!(!bundle.may_hit(away, 0.5));
            }
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

    #[test]
    fn a_camera_far_from_the_origin_resolves_every_pixel() {
        // The cover's view from 150 times as far (1200 from the origin) through a 150 times
        // narrower field, 600 pixels wide: neighbouring pixels are 5.8·10⁻⁶ rad apart, and
        // a point on the focus plane near 1200 is rounded to 1.2·10⁻⁴, two pixels there.
        // Every step across the film must turn the ray by its angle, as in f64, to within
        // a hundredth of a pixel (a unit direction's own rounding is a hundredth).
        let lookat = Vec3::new(5.2, 1.5, 1.2);
        let s = CameraSettings {
            lookfrom: lookat + 150.0 * (Vec3::new(13.0, 2.0, 3.0) - lookat),
            lookat,
            vup: Vec3::Y,
            vfov_deg: 20.0 / 150.0,
            aspect_ratio: 1.5,
            aperture: 0.0,
            focus_dist: 10.0,
            shutter: (0.0, 0.0),
        };
        let cam = Camera::new(&s);
        let mut rng = Sampler::from_seed(1);
        let fov = f64::from(s.vfov_deg).to_radians();
        let (across, up) = (1.5 * fov / 599.0, fov / 399.0);
        let mut worst: f64 = 0.0;
        for _ in 0..2000 {
            let (i, j) = (rng.range(0.0, 598.0), rng.range(0.0, 398.0));
            let mut ray = |i: f32, j: f32| {
                let d = cam.ray(i / 599.0, j / 399.0, &mut rng).dir.as_dvec3();
                d / d.length()
            };
            let here = ray(i, j);
            for (di, dj) in [(1.0, 0.0), (0.0, 1.0), (0.25, 0.0), (0.0, 0.25)] {
                let turn = here.angle_between(ray(i + di, j + dj));
                let expected = across * f64::from(di) + up * f64::from(dj);
                worst = worst.max((turn - expected).abs() / up);
            }
        }
        println!("worst error {worst} pixel");
        assert!(
            worst < 0.01,
            "a step across the film is off by {worst} pixel"
        );
    }
}
