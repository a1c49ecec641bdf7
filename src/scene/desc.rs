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
    pub textures: BTreeMap<String, Spanned<TextureDesc>>,
    #[serde(default)]
    pub materials: BTreeMap<String, Spanned<MaterialDesc>>,
    #[serde(default)]
    pub spheres: Vec<Spanned<SphereDesc>>,
    #[serde(default)]
    pub quads: Vec<Spanned<QuadDesc>>,
    #[serde(default)]
    pub rects: Vec<Spanned<RectDesc>>,
    #[serde(default)]
    pub boxes: Vec<Spanned<BoxDesc>>,
    #[serde(default)]
    pub media: Vec<Spanned<MediumDesc>>,
    #[serde(default)]
    pub random_spheres: Option<Spanned<RandomSpheresDesc>>,
    #[serde(default)]
    pub random_boxes: Vec<Spanned<RandomBoxesDesc>>,
    #[serde(default)]
    pub random_sphere_clouds: Vec<Spanned<SphereCloudDesc>>,
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
    /// `[time0, time1]`: when the shutter opens and closes (motion blur).
    #[serde(default)]
    pub shutter: Option<Spanned<Exactly<f64, 2>>>,
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
/// fuzz; dielectric: ir, refraction; diffuse_light: emit; isotropic: albedo); the builder
/// rejects the others. A flat struct rather than a tagged enum keeps every value's position
/// in the file for error messages.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    pub albedo: Option<Spanned<ColorDesc>>,
    pub emit: Option<Spanned<ColorDesc>>,
    pub fuzz: Option<Spanned<f64>>,
    pub ir: Option<Spanned<f64>>,
    pub refraction: Option<Spanned<Refraction>>,
}

/// A colour as a scene file gives it: three numbers, or the name of a texture.
#[derive(Clone, Debug, PartialEq)]
pub enum ColorDesc {
    Rgb([f64; 3]),
    Texture(String),
}

impl<'de> Deserialize<'de> for ColorDesc {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ColorOrName;

        impl<'de> Visitor<'de> for ColorOrName {
            type Value = ColorDesc;

            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of 3 numbers (a colour) or a texture's name")
            }

            fn visit_str<E: de::Error>(self, v: &str) -> Result<ColorDesc, E> {
                Ok(ColorDesc::Texture(v.to_owned()))
            }

            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<ColorDesc, A::Error> {
                let Exactly(rgb) =
                    Exactly::<f64, 3>::deserialize(de::value::SeqAccessDeserializer::new(seq))?;
                Ok(ColorDesc::Rgb(rgb))
            }
        }

        deserializer.deserialize_any(ColorOrName)
    }
}

/// A texture. Which fields apply depends on `type` (solid: color; checker: even, odd,
/// frequency; noise: noise, scale, seed; image: file).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextureDesc {
    #[serde(rename = "type")]
    pub kind: Spanned<String>,
    pub color: Option<Vec3Desc>,
    pub even: Option<Spanned<ColorDesc>>,
    pub odd: Option<Spanned<ColorDesc>>,
    pub frequency: Option<Spanned<f64>>,
    pub noise: Option<Spanned<crate::texture::NoiseKind>>,
    pub scale: Option<Spanned<f64>>,
    pub generator: Option<Spanned<SphereGenerator>>,
    pub seed: Option<Spanned<u64>>,
    pub skip: Option<Spanned<i64>>,
    pub draw_order: Option<Spanned<DrawOrder>>,
    pub file: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    pub center: Vec3Desc,
    pub radius: Spanned<f64>,
    pub material: Spanned<String>,
    /// A moving sphere's centre at the end of its move (*The Next Week*'s `center1`).
    #[serde(default)]
    pub center2: Option<Vec3Desc>,
    /// `[time0, time1]`: when a moving sphere is at `center` and at `center2`.
    #[serde(default)]
    pub move_times: Option<Spanned<Exactly<f64, 2>>>,
    #[serde(default)]
    pub rotate_y_deg: Option<Spanned<f64>>,
    #[serde(default)]
    pub translate: Option<Vec3Desc>,
}

/// A parallelogram `corner + a u + b v`, `a, b` in `[0, 1]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QuadDesc {
    pub corner: Vec3Desc,
    pub u: Vec3Desc,
    pub v: Vec3Desc,
    pub material: Spanned<String>,
    #[serde(default)]
    pub rotate_y_deg: Option<Spanned<f64>>,
    #[serde(default)]
    pub translate: Option<Vec3Desc>,
}

/// One axis of the book's axis-aligned rectangle: a range `[a, b]` it spans, or the
/// coordinate `k` of its plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AxisDesc {
    Range([f64; 2]),
    Plane(f64),
}

impl<'de> Deserialize<'de> for AxisDesc {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct RangeOrNumber;

        impl<'de> Visitor<'de> for RangeOrNumber {
            type Value = AxisDesc;

            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(
                    f,
                    "a number (the plane's coordinate) or an array of 2 numbers (a range)"
                )
            }

            fn visit_f64<E: de::Error>(self, v: f64) -> Result<AxisDesc, E> {
                Ok(AxisDesc::Plane(v))
            }

            fn visit_i64<E: de::Error>(self, v: i64) -> Result<AxisDesc, E> {
                Ok(AxisDesc::Plane(v as f64))
            }

            fn visit_u64<E: de::Error>(self, v: u64) -> Result<AxisDesc, E> {
                Ok(AxisDesc::Plane(v as f64))
            }

            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<AxisDesc, A::Error> {
                let Exactly(range) =
                    Exactly::<f64, 2>::deserialize(de::value::SeqAccessDeserializer::new(seq))?;
                Ok(AxisDesc::Range(range))
            }
        }

        deserializer.deserialize_any(RangeOrNumber)
    }
}

/// The book's axis-aligned rectangle (`xy_rect`, `xz_rect`, `yz_rect`): two axes are
/// ranges, the third the plane's coordinate (`x = [213, 343]`, `z = [227, 332]`, `y = 554`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RectDesc {
    pub x: Option<Spanned<AxisDesc>>,
    pub y: Option<Spanned<AxisDesc>>,
    pub z: Option<Spanned<AxisDesc>>,
    pub material: Spanned<String>,
    #[serde(default)]
    pub rotate_y_deg: Option<Spanned<f64>>,
    #[serde(default)]
    pub translate: Option<Vec3Desc>,
}

/// The book's `box`: six rectangles from `min` to `max`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxDesc {
    pub min: Vec3Desc,
    pub max: Vec3Desc,
    pub material: Spanned<String>,
    #[serde(default)]
    pub rotate_y_deg: Option<Spanned<f64>>,
    #[serde(default)]
    pub translate: Option<Vec3Desc>,
}

/// A constant-density medium (the book's `constant_medium`): `density`, an isotropic
/// `material`, and its boundary, one `sphere` or one `box`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumDesc {
    pub density: Spanned<f64>,
    pub material: Spanned<String>,
    #[serde(default)]
    pub sphere: Option<Spanned<BoundarySphereDesc>>,
    #[serde(rename = "box", default)]
    pub cuboid: Option<Spanned<BoundaryBoxDesc>>,
}

/// A sphere as a medium's boundary: a sphere's keys but its material.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySphereDesc {
    pub center: Vec3Desc,
    pub radius: Spanned<f64>,
    #[serde(default)]
    pub center2: Option<Vec3Desc>,
    #[serde(default)]
    pub move_times: Option<Spanned<Exactly<f64, 2>>>,
    #[serde(default)]
    pub rotate_y_deg: Option<Spanned<f64>>,
    #[serde(default)]
    pub translate: Option<Vec3Desc>,
}

/// A box as a medium's boundary: a box's keys but its material.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundaryBoxDesc {
    pub min: Vec3Desc,
    pub max: Vec3Desc,
    #[serde(default)]
    pub rotate_y_deg: Option<Spanned<f64>>,
    #[serde(default)]
    pub translate: Option<Vec3Desc>,
}

/// The final scene's ground of *The Next Week*: a grid of boxes of random heights.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomBoxesDesc {
    /// The least corner of the first box.
    pub corner: Vec3Desc,
    /// Boxes along x and along z.
    pub count: Spanned<Exactly<i64, 2>>,
    /// Each box's width along x and z.
    pub size: Spanned<f64>,
    /// `[low, high]`: each box's top (its `y`) is drawn uniformly from it.
    pub top: Spanned<Exactly<f64, 2>>,
    pub material: Spanned<String>,
    #[serde(default)]
    pub generator: SphereGenerator,
    #[serde(default)]
    pub seed: Option<Spanned<u64>>,
    /// Draws of the generator to skip first (the book's program draws for other objects
    /// between its generators from one `rand()`).
    #[serde(default)]
    pub skip: Option<Spanned<i64>>,
    #[serde(default)]
    pub draw_order: Option<DrawOrder>,
}

/// The final scene's cloud of *The Next Week*: spheres at random points of a box.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereCloudDesc {
    pub count: Spanned<i64>,
    /// The box the centres are drawn in, uniformly per axis.
    pub min: Vec3Desc,
    pub max: Vec3Desc,
    pub radius: Spanned<f64>,
    pub material: Spanned<String>,
    #[serde(default)]
    pub rotate_y_deg: Option<Spanned<f64>>,
    #[serde(default)]
    pub translate: Option<Vec3Desc>,
    #[serde(default)]
    pub generator: SphereGenerator,
    #[serde(default)]
    pub seed: Option<Spanned<u64>>,
    /// See `RandomBoxesDesc::skip`.
    #[serde(default)]
    pub skip: Option<Spanned<i64>>,
    #[serde(default)]
    pub draw_order: Option<DrawOrder>,
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
    /// `[low, high]`: each diffuse sphere moves up by a height drawn from it between times 0
    /// and 1 (*The Next Week*'s bouncing spheres); absent, every sphere stands still.
    #[serde(default)]
    pub diffuse_bounce: Option<Spanned<Exactly<f64, 2>>>,
    /// Draws of the generator to skip first.
    #[serde(default)]
    pub skip: Option<Spanned<i64>>,
    #[serde(default)]
    pub draw_order: Option<DrawOrder>,
}

/// The random numbers of a scene generator (`[random_spheres]`, `[[random_boxes]]`,
/// `[[random_sphere_clouds]]`, noise textures' tables).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SphereGenerator {
    /// tessera's seeded PCG, drawing in the book's source order.
    #[default]
    Pcg,
    /// The books' program as built on Linux: glibc's `rand()` (seeded by `srand(seed)`,
    /// 1 by default in C), `rand() / (RAND_MAX + 1.0)`, drawn by default in the order GCC
    /// evaluates the book's expressions (function arguments right to left). Gives the first
    /// book's 487 cover spheres, sphere for sphere.
    Glibc,
    /// Microsoft's C runtime `rand()` (15 bits, `RAND_MAX` 32767), with which some figures
    /// of *The Next Week* were made; arguments right to left by default, as MSVC does.
    Msvc,
}

/// The order a compiler evaluates a call's arguments in, which decides which coordinate of
/// `vec3::random()` takes which draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DrawOrder {
    /// First argument first (Clang).
    LeftToRight,
    /// Last argument first (GCC and MSVC on x86-64).
    RightToLeft,
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
