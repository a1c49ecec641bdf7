//! Vector aliases over glam and the optics helpers of the book: reflect, refract, Schlick.

/// A point or direction in world space. `Vec3A` is 16-byte aligned so glam uses SIMD lanes.
pub type Vec3 = glam::Vec3A;
/// Linear RGB radiance or reflectance.
pub type Color = glam::Vec3A;

/// The cross product `a × b`, each component a difference of two rounded products. Not
/// glam's `cross`: on aarch64 that fuses one multiply into the subtraction (`vfmsq_f32`),
/// which rounds differently and moved every camera ray there by a last bit.
#[inline]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

/// `v` scaled to unit length, by dividing by its length. Not glam's `normalize`: on aarch64
/// that multiplies by the reciprocal of the length, which rounds differently from the
/// division its x86-64 code does.
#[inline]
pub fn unit(v: Vec3) -> Vec3 {
    v / v.length()
}

/// An open interval of ray parameters `(min, max)` that a hit must fall in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    pub min: f32,
    pub max: f32,
}

impl Interval {
    pub const fn new(min: f32, max: f32) -> Self {
        Self { min, max }
    }

    /// True when `t` lies strictly inside the interval.
    #[inline]
    pub fn surrounds(&self, t: f32) -> bool {
        self.min < t && t < self.max
    }
}

/// A rectangle of pixels: `x0..x0 + width` by `y0..y0 + height`, top row `y = 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PixelRect {
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

impl PixelRect {
    /// The whole of a `width × height` image.
    pub const fn full(width: u32, height: u32) -> Self {
        Self {
            x0: 0,
            y0: 0,
            width,
            height,
        }
    }

    pub fn area(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// True when `other` lies wholly inside `self`.
    pub fn contains(&self, other: &PixelRect) -> bool {
        other.x0 >= self.x0
            && other.y0 >= self.y0
            && u64::from(other.x0) + u64::from(other.width)
                <= u64::from(self.x0) + u64::from(self.width)
            && u64::from(other.y0) + u64::from(other.height)
                <= u64::from(self.y0) + u64::from(self.height)
    }

    /// How many tiles `tiles(edge)` makes, counted without making them.
    pub fn tile_count(&self, edge: u32) -> u64 {
        let edge = edge.max(1);
        u64::from(self.width.div_ceil(edge)) * u64::from(self.height.div_ceil(edge))
    }

    /// Tiles of at most `edge × edge` pixels covering the rectangle, row-major.
    pub fn tiles(&self, edge: u32) -> Vec<PixelRect> {
        let edge = edge.max(1);
        let (x1, y1) = (self.x0 + self.width, self.y0 + self.height);
        let mut out = Vec::new();
        for y0 in (self.y0..y1).step_by(edge as usize) {
            for x0 in (self.x0..x1).step_by(edge as usize) {
                out.push(PixelRect {
                    x0,
                    y0,
                    width: edge.min(x1 - x0),
                    height: edge.min(y1 - y0),
                });
            }
        }
        out
    }
}

/// Mirror reflection of `v` about the normal `n` (the book's `reflect`).
#[inline]
pub fn reflect(v: Vec3, n: Vec3) -> Vec3 {
    v - 2.0 * v.dot(n) * n
}

/// Snell refraction of the unit vector `uv` through a surface with unit normal `n` facing
/// against `uv`, with `etai_over_etat` the ratio of indices (the book's `refract`).
#[inline]
pub fn refract(uv: Vec3, n: Vec3, etai_over_etat: f32) -> Vec3 {
    let cos_theta = (-uv).dot(n).min(1.0);
    let r_out_perp = etai_over_etat * (uv + cos_theta * n);
    let r_out_parallel = -(1.0 - r_out_perp.length_squared()).abs().sqrt() * n;
    r_out_perp + r_out_parallel
}

/// Schlick's approximation of the Fresnel reflectance.
#[inline]
pub fn reflectance(cosine: f32, ref_idx: f32) -> f32 {
    let r0 = (1.0 - ref_idx) / (1.0 + ref_idx);
    let r0 = r0 * r0;
    r0 + (1.0 - r0) * (1.0 - cosine).powi(5)
}

/// True when every component is within `1e-8` of zero (the book's `near_zero`).
#[inline]
pub fn near_zero(v: Vec3) -> bool {
    v.abs().max_element() < 1e-8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_rectangle_once() {
        for (x0, y0, w, h, e) in [
            (0, 0, 10, 7, 4),
            (3, 2, 16, 16, 16),
            (5, 5, 1, 1, 8),
            (0, 1, 33, 5, 32),
        ] {
            let rect = PixelRect {
                x0,
                y0,
                width: w,
                height: h,
            };
            let mut hits = vec![0u8; (w * h) as usize];
            assert_eq!(rect.tile_count(e), rect.tiles(e).len() as u64);
            for t in rect.tiles(e) {
                assert!(rect.contains(&t));
                for y in t.y0..t.y0 + t.height {
                    for x in t.x0..t.x0 + t.width {
                        hits[((y - y0) * w + (x - x0)) as usize] += 1;
                    }
                }
            }
            assert!(hits.iter().all(|&n| n == 1), "{rect:?}/{e}");
        }
    }

    #[test]
    fn reflect_flips_normal_component() {
        let r = reflect(Vec3::new(1.0, -1.0, 0.0), Vec3::Y);
        assert_eq!(r, Vec3::new(1.0, 1.0, 0.0));
    }

    #[test]
    fn refract_with_index_one_passes_straight_through() {
        let d = Vec3::new(0.3, -0.8, 0.2).normalize();
        let n = Vec3::Y;
        let r = refract(d, n, 1.0);
        assert!((r - d).length() < 1e-6, "{r} vs {d}");
    }

    #[test]
    fn refract_obeys_snell() {
        let d = Vec3::new(0.6, -0.8, 0.0);
        let r = refract(d, Vec3::Y, 1.0 / 1.5);
        // sin(theta_t) = sin(theta_i) / 1.5
        assert!((r.x - 0.6 / 1.5).abs() < 1e-6);
        assert!((r.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn schlick_limits() {
        assert!((reflectance(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((reflectance(0.0, 1.5) - 1.0).abs() < 1e-6);
    }
}
