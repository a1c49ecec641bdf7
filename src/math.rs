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

/// `tan(x)` for `|x| < π/2`, rounded to `f32`: the same bits on every machine. A platform's
/// `tanf` (its libm) may round differently, and the camera's field of view goes through this
/// once per render, so one last bit would move every camera ray. Computed in `f64` as
/// `sin / cos` by Taylor series with only `+`, `×` and `/` (IEEE-exact operations), to about
/// 10⁻¹⁵ relative: far under `f32`'s 6·10⁻⁸, so the result is the correctly rounded tangent
/// but where the exact value lies within 10⁻¹⁵ of a rounding boundary.
pub fn tan(x: f32) -> f32 {
    let x = f64::from(x);
    let x2 = x * x;
    // sin x = x Σ (-x²)ⁿ / (2n+1)!, cos x = Σ (-x²)ⁿ / (2n)!: 16 terms reach x³³/33!, under
    // 10⁻²⁹ for |x| < π/2.
    let (mut sin, mut cos) = (0.0f64, 0.0f64);
    for n in (0..16).rev() {
        let k = 2.0 * f64::from(n);
        sin = 1.0 - x2 * sin / ((k + 2.0) * (k + 3.0));
        cos = 1.0 - x2 * cos / ((k + 1.0) * (k + 2.0));
    }
    (x * sin / cos) as f32
}

/// `c^e` for `c ≥ 0` (negative `c` and NaN give 0), rounded to `f32`, the same bits on every
/// machine (see `tan`): `exp(e · ln c)` in `f64`, the logarithm by the `atanh` series on the
/// mantissa scaled into `[√½, √2)`, the exponential by its Taylor series after taking out
/// whole powers of two.
pub fn pow(c: f32, e: f32) -> f32 {
    if c.is_nan() || c <= 0.0 {
        return 0.0;
    }
    if c.is_infinite() {
        return if e > 0.0 { c } else { 0.0 };
    }
    let y = f64::from(e) * ln(f64::from(c));
    exp(y) as f32
}

/// `ln x` for finite `x > 0` in `f64`.
fn ln(x: f64) -> f64 {
    const LN_2: f64 = std::f64::consts::LN_2;
    // x = m · 2^k, m in [1, 2) (an f32's value is a normal f64), then into [√½, √2).
    let bits = x.to_bits();
    let mut k = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let mut m = f64::from_bits((bits & ((1 << 52) - 1)) | (1023 << 52));
    if m > std::f64::consts::SQRT_2 {
        m /= 2.0;
        k += 1;
    }
    // ln m = 2 atanh s = 2 (s + s³/3 + s⁵/5 + …), s = (m - 1)/(m + 1), |s| < 0.172: 20 terms.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let mut sum = 0.0f64;
    for n in (0..20).rev() {
        sum = 1.0 / f64::from(2 * n + 1) + s2 * sum;
    }
    k as f64 * LN_2 + 2.0 * s * sum
}

/// `ln x` for finite `x > 0` in `f32`, the same bits on every machine (see `tan`), within a
/// few units in the last place: the `atanh` series of `ln` in `f32` on the mantissa scaled
/// into `[√½, √2)`, to `s¹¹`.
pub fn ln_f32(x: f32) -> f32 {
    let bits = x.to_bits();
    let mut k = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & ((1 << 23) - 1)) | (127 << 23));
    if m > std::f32::consts::SQRT_2 {
        m *= 0.5;
        k += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series =
        1.0 + s2 * (1.0 / 3.0 + s2 * (1.0 / 5.0 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0 + s2 / 11.0))));
    k as f32 * std::f32::consts::LN_2 + 2.0 * s * series
}

/// `sin x` in `f64` for `|x| < 2²⁰`, the same bits on every machine (see `tan`): `x` less
/// the nearest multiple of π/2 (in three parts, Cody and Waite's, so the reduction is exact
/// to about 10⁻²⁴ at 2²⁰), then the sine or cosine series of the rest, `|r| ≤ π/4`, to the
/// 23rd power. Beyond 2²⁰ (and for NaN) it returns 0: no texture or mapping of tessera's
/// looks that far.
pub fn sin(x: f64) -> f64 {
    const PIO2_1: f64 = 1.570_796_326_734_125_6; // the first 33 bits of π/2
    const PIO2_2: f64 = 6.077_100_506_506_192e-11; // the next 33
    const PIO2_3: f64 = 2.022_266_248_795_950_7e-21; // the rest
    if x.abs().partial_cmp(&1048576.0) != Some(std::cmp::Ordering::Less) {
        return 0.0;
    }
    let n = (x * std::f64::consts::FRAC_2_PI).round();
    let r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3;
    let r2 = r * r;
    let (mut sin, mut cos) = (0.0f64, 0.0f64);
    for k in (0..12).rev() {
        let k = 2.0 * f64::from(k);
        sin = 1.0 - r2 * sin / ((k + 2.0) * (k + 3.0));
        cos = 1.0 - r2 * cos / ((k + 1.0) * (k + 2.0));
    }
    let (sin, cos) = (r * sin, cos);
    match (n as i64).rem_euclid(4) {
        0 => sin,
        1 => cos,
        2 => -sin,
        _ => -cos,
    }
}

/// `atan2(y, x)` in `f64`, in `(-π, π]`, the same bits on every machine (see `tan`): the
/// angle of the smaller over the larger magnitude, halved twice (`atan t = 2 atan(t / (1 +
/// √(1 + t²)))`, square roots being exact operations) to below 0.2, then the series.
pub fn atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    if y.is_nan() || x.is_nan() {
        return 0.0;
    }
    let (ay, ax) = (y.abs(), x.abs());
    if ay == 0.0 && ax == 0.0 {
        return if x.is_sign_negative() {
            PI.copysign(y)
        } else {
            0.0f64.copysign(y)
        };
    }
    let swap = ay > ax;
    let t = if swap { ax / ay } else { ay / ax };
    let mut t = t;
    for _ in 0..2 {
        t /= 1.0 + (1.0 + t * t).sqrt();
    }
    let t2 = t * t;
    let mut sum = 0.0f64;
    for n in (0..18).rev() {
        sum = 1.0 / f64::from(2 * n + 1) - t2 * sum;
    }
    let mut a = 4.0 * t * sum;
    if swap {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    a.copysign(y)
}

/// `e^y` in `f64`: 0 below the smallest and infinity above the largest `f32` it can round to.
fn exp(y: f64) -> f64 {
    const LN_2: f64 = std::f64::consts::LN_2;
    if y < -110.0 {
        return 0.0;
    }
    if y > 90.0 {
        return f64::INFINITY;
    }
    // y = k ln 2 + r with |r| ≤ ln 2 / 2, e^r by Taylor to r²⁰/20!, then times 2^k exactly.
    let k = (y / LN_2).round();
    let r = y - k * LN_2;
    let mut sum = 0.0f64;
    for n in (1..=20).rev() {
        sum = 1.0 + r * sum / f64::from(n);
    }
    sum * f64::from_bits(((k as i64 + 1023) as u64) << 52)
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

    /// Tile `index` of `tiles(edge)`, made without making the others.
    pub fn tile(&self, edge: u32, index: usize) -> Option<PixelRect> {
        let edge = edge.max(1);
        let across = self.width.div_ceil(edge) as usize;
        if index as u64 >= self.tile_count(edge) || across == 0 {
            return None;
        }
        let (x0, y0) = (
            self.x0 + (index % across) as u32 * edge,
            self.y0 + (index / across) as u32 * edge,
        );
        Some(PixelRect {
            x0,
            y0,
            width: edge.min(self.x0 + self.width - x0),
            height: edge.min(self.y0 + self.height - y0),
        })
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

    /// True when `got` is `exact` rounded to `f32` (to the nearer neighbour, with a hair of
    /// slack for `exact`'s own error).
    fn correctly_rounded(got: f32, exact: f64) -> bool {
        let g = f64::from(got);
        let spacing = f64::from(got.abs().next_up() - got.abs());
        (g - exact).abs() <= 0.5 * spacing * (1.0 + 1e-6)
    }

    #[test]
    fn sin_and_atan2_agree_with_the_platform_to_its_last_bits() {
        let mut rng = crate::sampling::Sampler::from_seed(8);
        for _ in 0..100_000 {
            let x = rng.range(-20_000.0, 20_000.0) as f64;
            assert!((sin(x) - x.sin()).abs() < 1e-12, "sin {x}");
            let small = rng.range(-7.0, 7.0) as f64;
            assert!((sin(small) - small.sin()).abs() < 1e-15, "sin {small}");
            let (y, x) = (rng.range(-3.0, 3.0) as f64, rng.range(-3.0, 3.0) as f64);
            assert!((atan2(y, x) - y.atan2(x)).abs() < 1e-14, "atan2 {y} {x}");
        }
        for (y, x) in [
            (0.0, 1.0),
            (0.0, -1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, 1.0),
            (0.0, 0.0),
        ] {
            assert!((atan2(y, x) - f64::atan2(y, x)).abs() < 1e-15, "{y} {x}");
        }
        assert_eq!(sin(f64::NAN), 0.0);
    }

    #[test]
    fn ln_f32_is_within_a_few_units_in_the_last_place() {
        let mut x = 1e-7f32;
        while x < 1e7 {
            let exact = f64::from(x).ln();
            let got = f64::from(ln_f32(x));
            let ulp = (exact.abs() * f64::from(f32::EPSILON)).max(f64::from(f32::EPSILON));
            assert!((got - exact).abs() <= 4.0 * ulp, "ln {x}: {got} vs {exact}");
            x *= 1.0137;
        }
        assert_eq!(ln_f32(1.0), 0.0);
    }

    #[test]
    fn tan_is_correctly_rounded_over_the_whole_field_of_view() {
        let mut x = 1e-6f32;
        let mut checked = 0;
        while x < std::f32::consts::FRAC_PI_2 {
            for v in [x, -x] {
                let exact = f64::from(v).tan();
                assert!(
                    correctly_rounded(tan(v), exact),
                    "tan({v}) = {} not {exact}",
                    tan(v)
                );
            }
            checked += 1;
            x = x * 1.0001 + 1e-7;
        }
        assert!(checked > 70_000, "{checked}");
        // Every field of view the scenes use, and the extremes a scene may ask for.
        for deg in [20.0f32, 40.0, 90.0, 0.001, 179.999] {
            let half = deg.to_radians() / 2.0;
            assert!(correctly_rounded(tan(half), f64::from(half).tan()), "{deg}");
        }
        assert_eq!(tan(0.0), 0.0);
    }

    #[test]
    fn pow_is_correctly_rounded_over_radiance_values_and_gammas() {
        let mut c = 1e-30f32;
        let mut checked = 0;
        while c < 1e12 {
            for e in [1.0 / 2.2, 1.0 / 1.8, 0.5, 1.0, 2.5, 1.0 / 3.0, 7.0] {
                let exact = f64::from(c).powf(f64::from(e));
                let got = pow(c, e);
                if exact < f64::from(f32::MAX) && exact > 1e-37 {
                    assert!(correctly_rounded(got, exact), "{c}^{e} = {got} not {exact}");
                }
            }
            checked += 1;
            c = c * 1.003 + 1e-38;
        }
        assert!(checked > 25_000, "{checked}");
        assert_eq!(pow(1.0, 1.0 / 2.2), 1.0);
        assert_eq!(pow(0.0, 0.5), 0.0);
        assert_eq!(pow(-1.0, 0.5), 0.0);
        assert_eq!(pow(f32::NAN, 0.5), 0.0);
        assert_eq!(pow(f32::INFINITY, 0.5), f32::INFINITY);
        assert_eq!(pow(1e30, 7.0), f32::INFINITY);
        assert_eq!(pow(1e-30, 7.0), 0.0);
    }

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
            for (i, t) in rect.tiles(e).into_iter().enumerate() {
                assert_eq!(rect.tile(e, i), Some(t));
                assert!(rect.contains(&t));
                for y in t.y0..t.y0 + t.height {
                    for x in t.x0..t.x0 + t.width {
                        hits[((y - y0) * w + (x - x0)) as usize] += 1;
                    }
                }
            }
            assert!(hits.iter().all(|&n| n == 1), "{rect:?}/{e}");
            assert_eq!(rect.tile(e, rect.tile_count(e) as usize), None);
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
