//! The scene file as written: serde types mirroring the TOML, with source spans kept for the
//! values that are validated later. Nothing here is used by the renderer directly.

use serde::Deserialize;
use serde::de::{self, Deserializer, IgnoredAny, SeqAccess, Visitor};
use std::collections::BTreeMap;
use std::fmt;
use std::marker::PhantomData;
use toml::Spanned;

use super::settings::Shading;
use crate::material::{DiffuseModel, Refraction};

pub type Vec3Desc = Spanned<Exactly<f64, 3>>;

/// An array of exactly `N` values. Serde's own `[T; N]` stops reading after `N` elements
/// and ignores the rest, so `center = [0, 0, -1, "junk"]` would pass for a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exactly<T, const N: usize>(pub [T; N]);

impl<'de, T: Deserialize<'de> + Copy + Default, const N: usize> Deserialize<'de> for Exactly<T, N> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Elements<T, const N: usize>(PhantomData<T>);

        impl<'de, T: Deserialize<'de> + Copy + Default, const N: usize> Visitor<'de> for Elements<T, N> {
            type Value = Exactly<T, N>;

            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of {N} numbers")
            }

            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
                let mut out = [T::default(); N];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                let mut len = N;
                while seq.next_element::<IgnoredAny>()?.is_some() {
                    len += 1;
                }
                if len != N {
                    return Err(de::Error::invalid_length(len, &self));
                }
                Ok(Exactly(out))
            }
        }

        deserializer.deserialize_seq(Elements::<T, N>(PhantomData))
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    pub image: ImageDesc,
    #[serde(default)]
    pub render: RenderDesc,
    /// Defaults to the book's first camera: at the origin, looking down -z, 90° vertical fov.
    #[serde(default)]
    pub camera: Option<Spanned<CameraDesc>>,
    #[serde(default)]
    pub background: Option<Spanned<BackgroundDesc>>,
    #[serde(default)]
    pub materials: BTreeMap<String, Spanned<MaterialDesc>>,
    #[serde(default)]
    pub spheres: Vec<SphereDesc>,
    #[serde(default)]
    pub random_spheres: Option<Spanned<RandomSpheresDesc>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageDesc {
    pub width: Spanned<i64>,
    pub height: Spanned<i64>,
    pub samples_per_pixel: Spanned<i64>,
    pub max_depth: Spanned<i64>,
    #[serde(default)]
    pub seed: u64,
    /// Render and write only `[x, y, width, height]` of the image (pixels, top row 0).
    #[serde(default)]
    pub crop: Option<Spanned<Exactly<i64, 4>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    #[serde(default)]
    pub shading: Shading,
    #[serde(default)]
    pub diffuse: DiffuseModel,
    #[serde(default = "default_gamma")]
    pub gamma: Spanned<f64>,
    #[serde(default = "default_t_min")]
    pub t_min: Spanned<OffsetDesc>,
    #[serde(default = "default_true")]
    pub jitter: bool,
}

impl Default for RenderDesc {
    fn default() -> Self {
        Self {
            shading: Shading::default(),
            diffuse: DiffuseModel::default(),
            gamma: default_gamma(),
            t_min: default_t_min(),
            jitter: true,
        }
    }
}

fn default_gamma() -> Spanned<f64> {
    Spanned::new(0..0, 2.0)
}

fn default_t_min() -> Spanned<OffsetDesc> {
    Spanned::new(0..0, OffsetDesc::Auto)
}

/// `render.t_min`: `"auto"` or a distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OffsetDesc {
    Auto,
    Distance(f64),
}

impl<'de> Deserialize<'de> for OffsetDesc {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Offset;

        impl Visitor<'_> for Offset {
            type Value = OffsetDesc;

            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "\"auto\" or a distance")
            }

            fn visit_str<E: de::Error>(self, v: &str) -> Result<OffsetDesc, E> {
                match v {
                    "auto" => Ok(OffsetDesc::Auto),
                    _ => Err(E::invalid_value(de::Unexpected::Str(v), &self)),
                }
            }

            fn visit_f64<E: de::Error>(self, v: f64) -> Result<OffsetDesc, E> {
                Ok(OffsetDesc::Distance(v))
            }

            fn visit_i64<E: de::Error>(self, v: i64) -> Result<OffsetDesc, E> {
                Ok(OffsetDesc::Distance(v as f64))
            }
        }

        deserializer.deserialize_any(Offset)
    }
}

fn default_true() -> bool {
    true
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    pub lookfrom: Vec3Desc,
    pub lookat: Vec3Desc,
    #[serde(default)]
    pub vup: Option<Vec3Desc>,
    pub vfov_deg: Spanned<f64>,
    #[serde(default)]
    pub aperture: Option<Spanned<f64>>,
    #[serde(default)]
    pub focus_dist: Option<Spanned<f64>>,
}

/// The colour of escaping rays. `type = "gradient"` is the book's sky, `(1-t)·bottom + t·top`
/// with `t = (dir.y + 1) / 2`; `type = "uniform"` is one `color`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackgroundDesc {
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    pub bottom: Option<Vec3Desc>,
    pub top: Option<Vec3Desc>,
    pub color: Option<Vec3Desc>,
}

/// A material. Which fields apply depends on `type` (lambertian: albedo; metal: albedo,
/// fuzz; dielectric: ir, refraction); the builder rejects the others. A flat struct rather
/// than a tagged enum keeps every value's position in the file for error messages.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    pub albedo: Option<Vec3Desc>,
    pub fuzz: Option<Spanned<f64>>,
    pub ir: Option<Spanned<f64>>,
    pub refraction: Option<Spanned<Refraction>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    pub center: Vec3Desc,
    pub radius: Spanned<f64>,
    pub material: Spanned<String>,
}

/// The book's `random_scene()` grid of small spheres.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomSpheresDesc {
    /// Which random numbers place the spheres.
    #[serde(default)]
    pub generator: SphereGenerator,
    /// Seed of the generator; defaults to the image seed.
    #[serde(default)]
    pub seed: Option<Spanned<u64>>,
    /// The random spheres go after this many of the listed `[[spheres]]` (default: after
    /// all of them). The book adds them after the ground and before the three big ones.
    #[serde(default)]
    pub after_spheres: Option<Spanned<i64>>,
    /// Grid cells run over `a, b in -grid..grid`.
    #[serde(default = "default_grid")]
    pub grid: Spanned<i64>,
    #[serde(default = "default_radius")]
    pub radius: Spanned<f64>,
    /// Cells whose sphere lands within `clearance` of any of these points stay empty.
    #[serde(default = "default_keep_clear")]
    pub keep_clear: Vec<Vec3Desc>,
    #[serde(default = "default_clearance")]
    pub clearance: Spanned<f64>,
    #[serde(default = "default_p_diffuse")]
    pub p_diffuse: Spanned<f64>,
    #[serde(default = "default_p_metal")]
    pub p_metal: Spanned<f64>,
    #[serde(default = "default_glass_ir")]
    pub glass_ir: Spanned<f64>,
}

/// The generator of `[random_spheres]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SphereGenerator {
    /// tessera's seeded PCG, drawing in the book's source order.
    #[default]
    Pcg,
    /// The book's program as built on Linux: glibc's `rand()` (seeded by `srand(seed)`,
    /// 1 by default in C), `rand() / (RAND_MAX + 1.0)`, drawn in the order GCC evaluates
    /// the book's expressions (function arguments right to left). Gives the book's 487
    /// spheres, sphere for sphere.
    Glibc,
}

fn default_grid() -> Spanned<i64> {
    Spanned::new(0..0, 11)
}
fn default_radius() -> Spanned<f64> {
    Spanned::new(0..0, 0.2)
}
fn default_keep_clear() -> Vec<Vec3Desc> {
    vec![Spanned::new(0..0, Exactly([4.0, 0.2, 0.0]))]
}
fn default_clearance() -> Spanned<f64> {
    Spanned::new(0..0, 0.9)
}
fn default_p_diffuse() -> Spanned<f64> {
    Spanned::new(0..0, 0.8)
}
fn default_p_metal() -> Spanned<f64> {
    Spanned::new(0..0, 0.15)
}
fn default_glass_ir() -> Spanned<f64> {
    Spanned::new(0..0, 1.5)
}
