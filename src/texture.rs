//! Textures of *The Next Week* (§4–6): what colour a material has where a ray hits it, from
//! the hit's texture coordinates `(u, v)` and point `p`. Solid colours, the book's 3D
//! checker, Perlin noise in each of the book's stages (hashed, trilinear, smoothed, random
//! vectors, turbulence, marble), and images.
//!
//! Every value is computed with `+`, `×`, `/`, `floor` and tessera's own `sin`, and every
//! random table is drawn by tessera's own generator from a seed the scene sets, so a texture
//! gives the same bits on every machine.

use crate::math::{Color, Vec3, sin};
use std::sync::Arc;

/// The random numbers a noise texture's tables are drawn from: the book's `random_double()`,
/// `vec3::random(-1, 1)` (three draws in the compiler's argument order, given back in
/// `[x, y, z]` order) and `random_int(0, max)`.
pub trait TableDraws {
    fn uniform(&mut self) -> f64;
    fn three(&mut self, range: std::ops::Range<f64>) -> [f64; 3];
    fn int_to(&mut self, max: u32) -> u32;
}

/// Index of a texture in the scene's texture table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TextureId(pub u32);

/// A texture. A closed set, dispatched with `match`; a checker's squares are other textures
/// of the table (the scene's checks keep them free of cycles).
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    Solid(Color),
    /// The book's `checker_texture`: `odd` where `sin(f·x) sin(f·y) sin(f·z) < 0`, else
    /// `even`, `f` the frequency (the book's 10).
    Checker {
        even: TextureId,
        odd: TextureId,
        frequency: f32,
    },
    Noise(Noise),
    Image(ImageTexture),
}

impl Texture {
    /// The colour of texture `id` of `table` at texture coordinates `(u, v)` and point `p`.
    pub fn value(table: &[Texture], id: TextureId, u: f32, v: f32, p: Vec3) -> Color {
        let mut id = id;
        // A checker picks one of its squares' textures; the chain ends at a texture of
        // another kind (the checks refuse cycles, and the loop is bounded all the same).
        for _ in 0..table.len() {
            match &table[id.0 as usize] {
                Texture::Solid(c) => return *c,
                Texture::Checker {
                    even,
                    odd,
                    frequency,
                } => {
                    let f = f64::from(*frequency);
                    let sines =
                        sin(f * f64::from(p.x)) * sin(f * f64::from(p.y)) * sin(f * f64::from(p.z));
                    id = if sines < 0.0 { *odd } else { *even };
                }
                Texture::Noise(noise) => return noise.value(p),
                Texture::Image(image) => return image.value(u, v),
            }
        }
        Color::ZERO
    }
}

/// Which of the book's stages of Perlin noise a noise texture shows (images 7–13).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseKind {
    /// Random floats hashed by lattice cell, four cells per unit (image 7).
    Hash,
    /// Random floats at the lattice points, trilinearly interpolated (image 8).
    Trilinear,
    /// The same with Hermite smoothing of the fractions (images 9 and 10).
    Smooth,
    /// Random unit vectors at the lattice points (Perlin's gradients), `0.5 (1 + noise)`
    /// (image 11).
    Perlin,
    /// Seven octaves of it, `|Σ noise(2ⁱ p) / 2ⁱ|` (image 12).
    Turbulence,
    /// Marble: `0.5 (1 + sin(scale · z + 10 · turbulence(p)))` (image 13 and the final scene).
    Marble,
}

/// Lattice points of the noise tables.
const POINTS: usize = 256;

/// A noise texture: its kind, the scale of the point it is taken at, and its random tables
/// (shared by clones of the scene).
#[derive(Clone, Debug, PartialEq)]
pub struct Noise {
    pub kind: NoiseKind,
    pub scale: f32,
    tables: Arc<PerlinTables>,
}

/// The book's `perlin` class: random floats and unit vectors at 256 lattice points and three
/// permutations that hash a cell to one of them.
#[derive(Debug, PartialEq)]
struct PerlinTables {
    floats: [f32; POINTS],
    vectors: [[f32; 3]; POINTS],
    perm: [[u8; POINTS]; 3],
}

impl PerlinTables {
    /// Tables drawn in the book's order: its random floats (the first stages' tables) or its
    /// random vectors (Perlin's, from the stage of image 11 on), then the three permutations
    /// by Fisher–Yates (the book's `permute`). The other table stays zero.
    fn new(gradients: bool, draws: &mut dyn TableDraws) -> Self {
        let mut floats = [0.0; POINTS];
        let mut vectors = [[0.0; 3]; POINTS];
        if gradients {
            for v in &mut vectors {
                // `unit_vector(vec3::random(-1, 1))`: a point of the cube, scaled to unit
                // length (as the book does: not uniform over directions).
                let [x, y, z] = draws.three(-1.0..1.0);
                let len = (x * x + y * y + z * z).sqrt();
                *v = if len > 0.0 {
                    [(x / len) as f32, (y / len) as f32, (z / len) as f32]
                } else {
                    [1.0, 0.0, 0.0]
                };
            }
        } else {
            for f in &mut floats {
                *f = draws.uniform() as f32;
            }
        }
        let perm = std::array::from_fn(|_| {
            let mut p: [u8; POINTS] = std::array::from_fn(|i| i as u8);
            for i in (1..POINTS).rev() {
                let target = (draws.int_to(i as u32) as usize).min(i);
                p.swap(i, target);
            }
            p
        });
        PerlinTables {
            floats,
            vectors,
            perm,
        }
    }

    /// The lattice point that cell `(i, j, k)` hashes to.
    #[inline]
    fn point(&self, i: i32, j: i32, k: i32) -> usize {
        let [px, py, pz] = &self.perm;
        (px[(i & 255) as usize] ^ py[(j & 255) as usize] ^ pz[(k & 255) as usize]) as usize
    }

    /// The book's first noise: the hashed random float of the cell of `4p`, cells counted by
    /// truncation toward zero (`static_cast<int>`).
    fn hash(&self, p: Vec3) -> f32 {
        let cell = |x: f32| (4.0 * x) as i32;
        self.floats[self.point(cell(p.x), cell(p.y), cell(p.z))]
    }

    /// Random floats interpolated trilinearly over the unit cell, the fractions Hermite
    /// smoothed when `smooth`.
    fn interpolated(&self, p: Vec3, smooth: bool) -> f32 {
        let (u, v, w, i, j, k) = cell_of(p);
        let hermite = |t: f32| if smooth { t * t * (3.0 - 2.0 * t) } else { t };
        let (u, v, w) = (hermite(u), hermite(v), hermite(w));
        let mut accum = 0.0f32;
        for di in 0..2 {
            for dj in 0..2 {
                for dk in 0..2 {
                    let c = self.floats[self.point(i + di, j + dj, k + dk)];
                    accum += weight(di, u) * weight(dj, v) * weight(dk, w) * c;
                }
            }
        }
        accum
    }

    /// Perlin's gradient noise (the book's `noise` with `perlin_interp`), in about [-1, 1].
    fn gradient(&self, p: Vec3) -> f32 {
        let (u, v, w, i, j, k) = cell_of(p);
        let hermite = |t: f32| t * t * (3.0 - 2.0 * t);
        let (uu, vv, ww) = (hermite(u), hermite(v), hermite(w));
        let mut accum = 0.0f32;
        for di in 0..2 {
            for dj in 0..2 {
                for dk in 0..2 {
                    let c = self.vectors[self.point(i + di, j + dj, k + dk)];
                    let (x, y, z) = (u - di as f32, v - dj as f32, w - dk as f32);
                    let dot = c[0] * x + c[1] * y + c[2] * z;
                    accum += weight(di, uu) * weight(dj, vv) * weight(dk, ww) * dot;
                }
            }
        }
        accum
    }

    /// The book's `turb`: seven octaves of gradient noise, each twice the frequency and half
    /// the weight of the last, absolute.
    fn turbulence(&self, p: Vec3) -> f32 {
        let (mut accum, mut weight, mut p) = (0.0f32, 1.0f32, p);
        for _ in 0..7 {
            accum += weight * self.gradient(p);
            weight *= 0.5;
            p *= 2.0;
        }
        accum.abs()
    }
}

/// A point's fractions within its unit lattice cell and the cell's corner.
#[inline]
fn cell_of(p: Vec3) -> (f32, f32, f32, i32, i32, i32) {
    let (fx, fy, fz) = (p.x.floor(), p.y.floor(), p.z.floor());
    (
        p.x - fx,
        p.y - fy,
        p.z - fz,
        fx as i32,
        fy as i32,
        fz as i32,
    )
}

/// The trilinear weight of corner `d` (0 or 1) for fraction `t`: `d t + (1 - d)(1 - t)`.
#[inline]
fn weight(d: i32, t: f32) -> f32 {
    if d == 1 { t } else { 1.0 - t }
}

impl Noise {
    /// A noise texture whose tables are drawn from `draws`.
    pub fn new(kind: NoiseKind, scale: f32, draws: &mut dyn TableDraws) -> Self {
        let gradients = matches!(
            kind,
            NoiseKind::Perlin | NoiseKind::Turbulence | NoiseKind::Marble
        );
        Noise {
            kind,
            scale,
            tables: Arc::new(PerlinTables::new(gradients, draws)),
        }
    }

    /// A 64-bit digest of the tables, for the scene's fingerprint.
    pub fn tables_digest(&self) -> u64 {
        let t = &self.tables;
        let mut words: Vec<u64> = t.floats.iter().map(|f| u64::from(f.to_bits())).collect();
        words.extend(t.vectors.iter().flatten().map(|f| u64::from(f.to_bits())));
        words.extend(t.perm.iter().flatten().map(|&b| u64::from(b)));
        crate::sampling::hash_words(0x09e7_11e5, &words)
    }

    /// The grey level at `p`, as the book's `noise_texture::value` at each stage.
    pub fn value(&self, p: Vec3) -> Color {
        let t = &self.tables;
        let q = self.scale * p;
        let grey = match self.kind {
            NoiseKind::Hash => t.hash(q),
            NoiseKind::Trilinear => t.interpolated(q, false),
            NoiseKind::Smooth => t.interpolated(q, true),
            NoiseKind::Perlin => 0.5 * (1.0 + t.gradient(q)),
            NoiseKind::Turbulence => t.turbulence(q),
            // The book's marble scales only the stripes' z: its turbulence is of `p` itself.
            NoiseKind::Marble => {
                let phase = f64::from(q.z) + 10.0 * f64::from(t.turbulence(p));
                0.5 * (1.0 + sin(phase) as f32)
            }
        };
        Color::splat(grey)
    }
}

/// An image texture: 8-bit RGB pixels, top row first, read as the book's `image_texture`
/// does (each byte over 255, no gamma decoding).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageTexture {
    pub width: u32,
    pub height: u32,
    rgb: Arc<Vec<u8>>,
    /// `pixel_digest` of `rgb`, taken once as the image is made: clones share the pixels,
    /// and a scene's fingerprint reads this for each texture that names the image.
    digest: u64,
}

impl ImageTexture {
    /// An image of `width × height` pixels from `rgb` (3 bytes a pixel, rows top first);
    /// `None` when the sizes disagree or the image is empty.
    pub fn new(width: u32, height: u32, rgb: Vec<u8>) -> Option<Self> {
        let expected = u64::from(width) * u64::from(height) * 3;
        (expected > 0 && rgb.len() as u64 == expected).then(|| ImageTexture {
            width,
            height,
            digest: pixel_digest(&rgb),
            rgb: Arc::new(rgb),
        })
    }

    /// The XXH3-64 of the pixels, for the scene's fingerprint.
    pub fn digest(&self) -> u64 {
        self.digest
    }

    /// The colour at texture coordinates `(u, v)`, clamped to `[0, 1]`, `v` counted up from
    /// the bottom row.
    pub fn value(&self, u: f32, v: f32) -> Color {
        // NaN coordinates clamp to 0.
        let u = if u > 0.0 { u.min(1.0) } else { 0.0 };
        let v = 1.0 - if v > 0.0 { v.min(1.0) } else { 0.0 };
        let i = ((u * self.width as f32) as u32).min(self.width - 1);
        let j = ((v * self.height as f32) as u32).min(self.height - 1);
        let at = 3 * (j as usize * self.width as usize + i as usize);
        let scale = 1.0 / 255.0;
        Color::new(
            scale * f32::from(self.rgb[at]),
            scale * f32::from(self.rgb[at + 1]),
            scale * f32::from(self.rgb[at + 2]),
        )
    }
}

/// The XXH3-64 of an image's pixels.
fn pixel_digest(rgb: &[u8]) -> u64 {
    #[cfg(test)]
    PIXEL_BYTES_HASHED.with(|n| n.set(n.get() + rgb.len() as u64));
    xxhash_rust::xxh3::xxh3_64(rgb)
}

#[cfg(test)]
thread_local! {
    /// The pixel bytes `pixel_digest` has hashed on this thread, for tests that bound it.
    pub static PIXEL_BYTES_HASHED: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Sampler;

    struct Pcg(Sampler);

    impl TableDraws for Pcg {
        fn uniform(&mut self) -> f64 {
            self.0.uniform_f64()
        }
        fn three(&mut self, r: std::ops::Range<f64>) -> [f64; 3] {
            std::array::from_fn(|_| r.start + (r.end - r.start) * self.uniform())
        }
        fn int_to(&mut self, max: u32) -> u32 {
            ((f64::from(max) + 1.0) * self.uniform()) as u32
        }
    }

    fn noise(kind: NoiseKind, scale: f32, seed: u64) -> Noise {
        Noise::new(kind, scale, &mut Pcg(Sampler::from_seed(seed)))
    }

    #[test]
    fn the_checker_alternates_with_the_sign_of_its_sines() {
        let table = [
            Texture::Solid(Color::new(0.2, 0.3, 0.1)),
            Texture::Solid(Color::splat(0.9)),
            Texture::Checker {
                even: TextureId(0),
                odd: TextureId(1),
                frequency: 10.0,
            },
        ];
        let at = |x: f32| Texture::value(&table, TextureId(2), 0.0, 0.0, Vec3::new(x, 0.05, 0.05));
        // sin(10·0.05) > 0 twice; the sign of sin(10 x) picks the square.
        assert_eq!(at(0.05), Color::new(0.2, 0.3, 0.1));
        assert_eq!(at(0.4), Color::splat(0.9));
    }

    #[test]
    fn noise_stays_in_range_and_is_the_same_for_the_same_seed() {
        let mut rng = Sampler::from_seed(1);
        for kind in [
            NoiseKind::Hash,
            NoiseKind::Trilinear,
            NoiseKind::Smooth,
            NoiseKind::Perlin,
            NoiseKind::Turbulence,
            NoiseKind::Marble,
        ] {
            let a = noise(kind, 4.0, 7);
            let b = noise(kind, 4.0, 7);
            let c = noise(kind, 4.0, 8);
            assert_eq!(a, b);
            assert_ne!(a.tables_digest(), c.tables_digest());
            for _ in 0..2000 {
                let p = Vec3::new(
                    rng.range(-50.0, 50.0),
                    rng.range(-50.0, 50.0),
                    rng.range(-50.0, 50.0),
                );
                let g = a.value(p).x;
                let limit = if kind == NoiseKind::Turbulence {
                    2.5
                } else {
                    1.0 + 1e-5
                };
                assert!((0.0..=limit).contains(&g), "{kind:?} {g} at {p}");
            }
        }
    }

    #[test]
    fn interpolated_noise_is_continuous_and_equals_the_table_at_lattice_points() {
        let smooth = noise(NoiseKind::Smooth, 1.0, 3);
        let t = &smooth.tables;
        let perlin = noise(NoiseKind::Perlin, 1.0, 3);
        let g = &perlin.tables;
        for (i, j, k) in [(0, 0, 0), (3, -2, 7), (-1, -1, -1)] {
            let p = Vec3::new(i as f32, j as f32, k as f32);
            assert_eq!(t.interpolated(p, true), t.floats[t.point(i, j, k)]);
        }
        let p = Vec3::new(2.0, 0.5, 0.25);
        let below = g.gradient(p - Vec3::X * 1e-4);
        let above = g.gradient(p + Vec3::X * 1e-4);
        assert!((below - above).abs() < 1e-3);
    }

    #[test]
    fn image_coordinates_clamp_and_flip_as_the_book_does() {
        // Two by two: top row red, green; bottom row blue, white.
        let rgb = vec![255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255];
        let image = ImageTexture::new(2, 2, rgb).unwrap();
        assert_eq!(image.value(0.0, 1.0), Color::new(1.0, 0.0, 0.0));
        assert_eq!(image.value(1.0, 1.0), Color::new(0.0, 1.0, 0.0));
        assert_eq!(image.value(0.0, 0.0), Color::new(0.0, 0.0, 1.0));
        assert_eq!(image.value(2.0, -1.0), Color::ONE);
        assert_eq!(image.value(f32::NAN, f32::NAN), Color::new(0.0, 0.0, 1.0));
        assert!(ImageTexture::new(2, 2, vec![0; 11]).is_none());
        assert!(ImageTexture::new(0, 2, vec![]).is_none());
    }
}
