//! The checks of single values in a scene file, each refusal pointing at the file, line,
//! column and field; and the limits that keep the scene inside what f32 arithmetic can do.

use super::desc::Vec3Desc;
use crate::error::{Error, Location, Result};
use crate::math::{Color, Vec3};
use std::cell::Cell;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// The largest magnitude of a coordinate, radius or distance. Ray-sphere tests square
/// differences of points and sum three of them: within ±10¹⁸ that stays far inside f32's
/// range (3.4·10³⁸); a sphere of radius 10²⁰ would square to infinity and vanish.
pub const MAX_LENGTH: f32 = 1e18;
/// The smallest magnitude of a sphere's radius, whose square stays a normal f32 number.
pub const MIN_RADIUS: f32 = 1e-18;

/// A number as a scene author would write it: `1e20` rather than a digit per power of ten.
fn plain(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e7).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        x.to_string()
    }
}

/// Three numbers as written, `[x, y, z]`.
fn plain3([x, y, z]: [f64; 3]) -> String {
    format!("[{}, {}, {}]", plain(x), plain(y), plain(z))
}

/// Where validation errors point: the source text and its path; and what the scene's checks
/// have granted so far, for limits on the whole scene.
pub(super) struct Checker<'a> {
    pub(super) text: &'a str,
    pub(super) path: &'a Path,
    /// Draws the scene's generators skip, in all (see `draws::MAX_SKIPPED`).
    pub(super) skipped: Cell<u64>,
}

impl<'a> Checker<'a> {
    pub(super) fn new(text: &'a str, path: &'a Path) -> Self {
        Self {
            text,
            path,
            skipped: Cell::new(0),
        }
    }

    pub(super) fn error(
        &self,
        span: Range<usize>,
        field: &str,
        message: impl Into<String>,
    ) -> Error {
        Error::SceneValue {
            path: self.path.to_owned(),
            at: Location::of_offset(self.text, span.start),
            field: field.to_owned(),
            message: message.into(),
        }
    }

    pub(super) fn positive_int(&self, v: &Spanned<i64>, field: &str) -> Result<u32> {
        let n = *v.get_ref();
        if n <= 0 {
            return Err(self.error(v.span(), field, format!("must be positive, got {n}")));
        }
        u32::try_from(n).map_err(|_| self.error(v.span(), field, format!("{n} is too large")))
    }

    pub(super) fn finite(&self, v: &Spanned<f64>, field: &str) -> Result<f32> {
        let x = *v.get_ref();
        if !x.is_finite() || !(x as f32).is_finite() {
            let x = plain(x);
            return Err(self.error(v.span(), field, format!("must be a finite number, got {x}")));
        }
        Ok(x as f32)
    }

    pub(super) fn in_range(
        &self,
        v: &Spanned<f64>,
        field: &str,
        ok: impl Fn(f64) -> bool,
        what: &str,
    ) -> Result<f32> {
        let x = self.finite(v, field)?;
        if !ok(f64::from(x)) {
            let written = plain(*v.get_ref());
            return Err(self.error(v.span(), field, format!("must be {what}, got {written}")));
        }
        Ok(x)
    }

    pub(super) fn vec3(&self, v: &Vec3Desc, field: &str) -> Result<Vec3> {
        let [x, y, z] = v.get_ref().0;
        if ![x, y, z]
            .iter()
            .all(|c| c.is_finite() && (*c as f32).is_finite())
        {
            let written = plain3(v.get_ref().0);
            return Err(self.error(
                v.span(),
                field,
                format!("must have three finite numbers, got {written}"),
            ));
        }
        Ok(Vec3::new(x as f32, y as f32, z as f32))
    }

    /// A point of the scene's geometry: three numbers within `±MAX_LENGTH`.
    pub(super) fn point(&self, v: &Vec3Desc, field: &str) -> Result<Vec3> {
        let p = self.vec3(v, field)?;
        if p.abs().max_element() > MAX_LENGTH {
            return Err(self.error(
                v.span(),
                field,
                format!(
                    "coordinates must lie within ±{MAX_LENGTH:e} (beyond, f32 arithmetic \
                     overflows), got {}",
                    plain3(v.get_ref().0)
                ),
            ));
        }
        Ok(p)
    }

    /// A length or distance: `ok` (described by `what`), and at most `MAX_LENGTH`.
    pub(super) fn length(
        &self,
        v: &Spanned<f64>,
        field: &str,
        ok: impl Fn(f64) -> bool,
        what: &str,
    ) -> Result<f32> {
        let limited = |x: f64| ok(x) && x.abs() <= f64::from(MAX_LENGTH);
        self.in_range(
            v,
            field,
            limited,
            &format!("{what}, at most {MAX_LENGTH:e}"),
        )
    }

    /// A sphere radius: `positive_only` or either sign, of magnitude within
    /// `[MIN_RADIUS, MAX_LENGTH]`.
    pub(super) fn radius(&self, v: &Spanned<f64>, field: &str, positive_only: bool) -> Result<f32> {
        let sign_ok = |r: f64| if positive_only { r > 0.0 } else { r != 0.0 };
        let ok = |r: f64| sign_ok(r) && r.abs() >= f64::from(MIN_RADIUS);
        let what = if positive_only {
            "positive"
        } else {
            "non-zero"
        };
        self.length(
            v,
            field,
            ok,
            &format!("{what} and at least {MIN_RADIUS:e} in size"),
        )
    }

    /// A direction, scaled to unit length in f64 so any non-zero length works: `vup` means
    /// the same at `[0, 1e-18, 0]` and `[0, 1e20, 0]`.
    pub(super) fn direction(&self, v: &Vec3Desc, field: &str) -> Result<Vec3> {
        let [x, y, z] = v.get_ref().0;
        let largest = x.abs().max(y.abs()).max(z.abs());
        if !largest.is_finite() || largest == 0.0 {
            return Err(self.error(
                v.span(),
                field,
                format!(
                    "must be a non-zero direction of finite numbers, got {}",
                    plain3(v.get_ref().0)
                ),
            ));
        }
        // Dividing by the largest component first keeps the squares finite.
        let (x, y, z) = (x / largest, y / largest, z / largest);
        let len = (x * x + y * y + z * z).sqrt();
        Ok(Vec3::new(
            (x / len) as f32,
            (y / len) as f32,
            (z / len) as f32,
        ))
    }

    /// A range `[low, high]` of finite numbers within `±MAX_LENGTH`, `low ≤ high`.
    pub(super) fn range(
        &self,
        v: &Spanned<super::desc::Exactly<f64, 2>>,
        field: &str,
    ) -> Result<(f64, f64)> {
        let [a, b] = v.get_ref().0;
        // Rounded to f32 as a point's coordinates and a length are: the bound as the message
        // writes it, 1e18, is within it (as f64 it lies above `MAX_LENGTH`, 1e18 rounded to
        // f32, and was refused with a message saying it must be within ±1e18).
        let ok = |x: f64| x.is_finite() && (x as f32).abs() <= MAX_LENGTH;
        if !(ok(a) && ok(b) && a <= b) {
            return Err(self.error(
                v.span(),
                field,
                format!(
                    "must be a range [low, high] of finite numbers within ±{MAX_LENGTH:e}, low at \
                     most high, got [{}, {}]",
                    plain(a),
                    plain(b)
                ),
            ));
        }
        Ok((a, b))
    }

    pub(super) fn color(&self, v: &Vec3Desc, field: &str) -> Result<Color> {
        let c = self.vec3(v, field)?;
        if c.min_element() < 0.0 {
            return Err(self.error(v.span(), field, format!("must not be negative, got {c}")));
        }
        Ok(c)
    }
}
