//! The random number generator, its seeding from (seed, pixel, sample), and the book's
//! sampling routines (unit sphere, unit vector, hemisphere, unit disk).
//!
//! Every random number a camera sample consumes comes from one PCG32 stream whose state is a
//! strong hash of `(scene seed, pixel x, pixel y, sample index)`. Nothing depends on which
//! thread or tile renders the sample, so images are reproducible byte for byte.

use crate::math::Vec3;
use glam::Vec4;
use rand_core::Rng as _;
use rand_pcg::Pcg32;

/// The increment PCG32 uses by default; every stream shares it and differs by state.
const PCG_STREAM: u64 = 0x0a02_bdbf_7bb3_c0a7;

/// 2^64 / φ, the odd constant words are spread by before mixing.
const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// Finaliser of SplitMix64 / Stafford's Mix13: a bijective, well-avalanching 64-bit hash.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hash of a seed and a sequence of words, each folded in through `mix64`.
#[inline]
pub fn hash_words(seed: u64, words: &[u64]) -> u64 {
    let mut h = mix64(seed ^ GOLDEN);
    for &w in words {
        h = mix64(h ^ w.wrapping_mul(GOLDEN));
    }
    h
}

/// The hash of (seed, pixel) that all of a pixel's sample generators start from, so a
/// pixel's many samples each hash only their own index.
#[derive(Clone, Copy, Debug)]
pub struct PixelSeed(u64);

impl PixelSeed {
    #[inline]
    pub fn new(seed: u64, x: u32, y: u32) -> Self {
        let pixel = (u64::from(y) << 32) | u64::from(x);
        PixelSeed(hash_words(seed, &[pixel]))
    }

    /// The generator of sample `sample`: the same as `hash_words(seed, &[pixel, sample])`
    /// would seed.
    #[inline]
    pub fn sample(self, sample: u32) -> Sampler {
        let state = mix64(self.0 ^ u64::from(sample).wrapping_mul(GOLDEN));
        Sampler {
            pcg: Pcg32::new(state, PCG_STREAM),
        }
    }
}

/// A seeded random source: the only kind of randomness the renderer uses.
#[derive(Clone, Debug)]
pub struct Sampler {
    pcg: Pcg32,
}

impl Sampler {
    /// A generator seeded directly from a 64-bit value (used by scene generators).
    pub fn from_seed(seed: u64) -> Self {
        Self {
            pcg: Pcg32::new(mix64(seed), PCG_STREAM),
        }
    }

    /// The generator for one camera sample: a pure function of its four coordinates.
    #[inline]
    pub fn for_sample(seed: u64, x: u32, y: u32, sample: u32) -> Self {
        PixelSeed::new(seed, x, y).sample(sample)
    }

    /// A uniform `f32` in `[0, 1)` with 24 random bits.
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        (self.pcg.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// A uniform `f64` in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn uniform_f64(&mut self) -> f64 {
        let hi = u64::from(self.pcg.next_u32());
        let lo = u64::from(self.pcg.next_u32());
        (((hi << 32) | lo) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform integer in `[0, n)` for `n > 0` (the top bits of a product: off from
    /// uniform by at most `n / 2³²`).
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        ((u64::from(self.pcg.next_u32()) * u64::from(n)) >> 32) as u32
    }

    /// A uniform 32-bit word.
    #[inline]
    pub fn word(&mut self) -> u32 {
        self.pcg.next_u32()
    }

    /// A uniform `f32` in `[min, max)`.
    #[inline]
    pub fn range(&mut self, min: f32, max: f32) -> f32 {
        min + (max - min) * self.uniform()
    }

    /// A uniform point inside the unit ball (the book's `random_in_unit_sphere`): a uniform
    /// direction scaled by the largest of three uniforms, whose distribution `P(r < x) = x³`
    /// is the ball's radial one. No rejection loop, so no unpredictable branch.
    #[inline]
    pub fn in_unit_sphere(&mut self) -> Vec3 {
        let dir = self.unit_vector();
        let r = self.uniform().max(self.uniform()).max(self.uniform());
        r * dir
    }

    /// A uniform direction on the unit sphere (the book's `random_unit_vector`), by
    /// Archimedes' hat-box theorem: the height `z = 1 - 2u` is uniform, the azimuth too, and
    /// the radius of that height's circle is `√(1 - z²) = 2√(u(1 - u))`.
    #[inline]
    pub fn unit_vector(&mut self) -> Vec3 {
        let u = self.uniform();
        let r = 2.0 * (u * (1.0 - u)).sqrt();
        let (x, y) = self.on_unit_circle();
        Vec3::new(r * x, r * y, 1.0 - 2.0 * u)
    }

    /// A point of the unit ball flipped into the hemisphere around `normal`
    /// (the book's `random_in_hemisphere`).
    #[inline]
    pub fn in_hemisphere(&mut self, normal: Vec3) -> Vec3 {
        let p = self.in_unit_sphere();
        if p.dot(normal) > 0.0 { p } else { -p }
    }

    /// A uniform point of the unit disk in the xy plane: radius `√u`, uniform azimuth.
    #[inline]
    pub fn in_unit_disk(&mut self) -> (f32, f32) {
        let r = self.uniform().sqrt();
        let (x, y) = self.on_unit_circle();
        (r * x, r * y)
    }

    /// A uniform point of the unit circle from one 32-bit draw: the top 24 bits give an
    /// angle in `[0, π/4)`, and three low bits reflect it into any of the eight octants
    /// (swap x and y, then each sign), each with probability 1/8. Only `+`, `*` and table
    /// lookups, so every machine gives the same bits, and no data-dependent branch.
    ///
    /// The sine and cosine series of `sin_cos_octant` run side by side in two lanes of one
    /// vector, already in (x, y) order: the swap picks which lane gets which coefficients,
    /// and the signs multiply in at the end (exact). The same bits as `sin_cos_octant` and
    /// the reflections done one by one (`tests` check them against each other).
    #[inline]
    pub fn on_unit_circle(&mut self) -> (f32, f32) {
        circle_point(self.pcg.next_u32())
    }
}

/// The point of the unit circle that `Sampler::on_unit_circle` makes of the draw `bits`.
#[inline]
fn circle_point(bits: u32) -> (f32, f32) {
    let angle = (bits >> 8) as f32 * (std::f32::consts::FRAC_PI_4 / (1u32 << 24) as f32);
    let swap = &OCTANT_SERIES[(bits & 1) as usize];
    let sign = OCTANT_SIGNS[((bits >> 1) & 3) as usize];
    let a2 = Vec4::splat(angle * angle);
    let k = &swap.steps;
    let p = k[4] + a2 * (k[3] + a2 * (k[2] + a2 * (k[1] + a2 * k[0])));
    // Lane by lane `1 + a2·p` (cosine) or `a + (a·a2)·p` (sine).
    let start = swap.one + swap.angle * angle;
    let xy = (start + (a2 * start) * p) * sign;
    (xy.x, xy.y)
}

/// The octant sampler's series in (x, y) lane order, for one value of the swap bit.
struct OctantSeries {
    /// The Horner steps, highest power first: each lane's coefficient (cosine's or sine's;
    /// sine's series has one step fewer, so its first is 0, which the next step's
    /// `k + a2 · 0` turns into its own first coefficient exactly).
    steps: [Vec4; 5],
    /// `one + angle · a` gives each lane's constant term: 1 for the cosine, `a` for the sine.
    one: Vec4,
    angle: Vec4,
}

impl OctantSeries {
    /// x takes the sine where `swap`, else the cosine; y the other.
    const fn new(swap: bool) -> Self {
        const fn pair(swap: bool, cos: f32, sin: f32) -> Vec4 {
            if swap {
                Vec4::new(sin, cos, 0.0, 0.0)
            } else {
                Vec4::new(cos, sin, 0.0, 0.0)
            }
        }
        OctantSeries {
            steps: [
                pair(swap, SERIES_COS[4], 0.0),
                pair(swap, SERIES_COS[3], SERIES_SIN[3]),
                pair(swap, SERIES_COS[2], SERIES_SIN[2]),
                pair(swap, SERIES_COS[1], SERIES_SIN[1]),
                pair(swap, SERIES_COS[0], SERIES_SIN[0]),
            ],
            one: pair(swap, 1.0, 0.0),
            angle: pair(swap, 0.0, 1.0),
        }
    }
}

/// By the swap bit (bit 0 of the draw).
const OCTANT_SERIES: [OctantSeries; 2] = [OctantSeries::new(false), OctantSeries::new(true)];

/// By bits 1 (x's sign) and 2 (y's sign) of the draw.
const OCTANT_SIGNS: [Vec4; 4] = [
    Vec4::new(1.0, 1.0, 0.0, 0.0),
    Vec4::new(-1.0, 1.0, 0.0, 0.0),
    Vec4::new(1.0, -1.0, 0.0, 0.0),
    Vec4::new(-1.0, -1.0, 0.0, 0.0),
];

/// Taylor coefficients of `sin a / a` and `cos a` in powers of `a²`, past the constant term.
const SERIES_SIN: [f32; 4] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0];
const SERIES_COS: [f32; 5] = [
    -1.0 / 2.0,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
];

/// Sine and cosine of `a` in `[0, π/4]` by their Taylor series to `a⁹` and `a¹⁰`, whose
/// truncation errors there stay below 10⁻⁹, far under `f32`'s rounding.
#[inline]
pub fn sin_cos_octant(a: f32) -> (f32, f32) {
    const S: [f32; 4] = SERIES_SIN;
    const C: [f32; 5] = SERIES_COS;
    let a2 = a * a;
    let sin = a + a * a2 * (S[0] + a2 * (S[1] + a2 * (S[2] + a2 * S[3])));
    let cos = 1.0 + a2 * (C[0] + a2 * (C[1] + a2 * (C[2] + a2 * (C[3] + a2 * C[4]))));
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_seeds_give_the_streams_hashing_all_four_coordinates_gives() {
        let pixel = (4u64 << 32) | 3;
        let mut a = PixelSeed::new(7, 3, 4).sample(5);
        let mut b = Sampler {
            pcg: Pcg32::new(hash_words(7, &[pixel, 5]), PCG_STREAM),
        };
        for _ in 0..16 {
            assert_eq!(a.uniform().to_bits(), b.uniform().to_bits());
        }
    }

    #[test]
    fn sample_streams_are_pure_functions_of_their_coordinates() {
        let mut a = Sampler::for_sample(7, 3, 4, 5);
        let mut b = Sampler::for_sample(7, 3, 4, 5);
        for _ in 0..16 {
            assert_eq!(a.uniform().to_bits(), b.uniform().to_bits());
        }
    }

    #[test]
    fn neighbouring_samples_draw_unrelated_streams() {
        // Streams one coordinate apart: each must differ from the others draw by draw, and
        // not be another's stream shifted by a few draws (overlapping PCG sequences).
        let draws = |mut s: Sampler| (0..32).map(|_| s.uniform().to_bits()).collect::<Vec<_>>();
        let streams = [
            draws(Sampler::for_sample(1, 10, 10, 0)),
            draws(Sampler::for_sample(2, 10, 10, 0)),
            draws(Sampler::for_sample(1, 11, 10, 0)),
            draws(Sampler::for_sample(1, 10, 11, 0)),
            draws(Sampler::for_sample(1, 10, 10, 1)),
        ];
        for (i, a) in streams.iter().enumerate() {
            for b in &streams[i + 1..] {
                for shift in 0..8 {
                    let same = (a[shift..].iter().zip(b)).filter(|(x, y)| x == y).count();
                    let same_back = (b[shift..].iter().zip(a)).filter(|(x, y)| x == y).count();
                    assert!(
                        same <= 1 && same_back <= 1,
                        "streams {i} overlap at shift {shift}"
                    );
                }
            }
        }
    }

    #[test]
    fn uniform_stays_in_unit_interval_with_mean_one_half() {
        let mut s = Sampler::from_seed(3);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let u = s.uniform();
            assert!((0.0..1.0).contains(&u));
            sum += f64::from(u);
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.005);
    }

    #[test]
    fn unit_vectors_are_unit_and_centred() {
        let mut s = Sampler::from_seed(9);
        let mut mean = Vec3::ZERO;
        let n = 50_000;
        for _ in 0..n {
            let v = s.unit_vector();
            assert!((v.length() - 1.0).abs() < 1e-5);
            mean += v;
        }
        assert!((mean / n as f32).length() < 0.02);
    }

    #[test]
    fn octant_sine_and_cosine_match_f64_to_rounding() {
        for k in 0..=10_000 {
            let a = k as f32 * (std::f32::consts::FRAC_PI_4 / 10_000.0);
            let (sin, cos) = sin_cos_octant(a);
            let exact = f64::from(a);
            assert!((f64::from(sin) - exact.sin()).abs() < 1.2e-7, "sin {a}");
            assert!((f64::from(cos) - exact.cos()).abs() < 1.2e-7, "cos {a}");
        }
    }

    /// The octant sampler done one step at a time: `sin_cos_octant`, then the swap and the
    /// signs as bit operations.
    fn circle_point_reference(bits: u32) -> (f32, f32) {
        let angle = (bits >> 8) as f32 * (std::f32::consts::FRAC_PI_4 / (1u32 << 24) as f32);
        let (sin, cos) = sin_cos_octant(angle);
        let swap = 0u32.wrapping_sub(bits & 1);
        let x = (cos.to_bits() & !swap) | (sin.to_bits() & swap);
        let y = (sin.to_bits() & !swap) | (cos.to_bits() & swap);
        (
            f32::from_bits(x ^ ((bits & 2) << 30)),
            f32::from_bits(y ^ ((bits & 4) << 29)),
        )
    }

    #[test]
    fn circle_points_equal_the_one_step_at_a_time_reference_bit_for_bit() {
        let mut s = Sampler::from_seed(21);
        // Every octant at the angle's ends (0, the least step, the largest) and random draws.
        let ends = [0u32, 1, 2, 0xffff_ff00, 0x0000_0100, 0x8000_0000];
        let edges = ends.iter().flat_map(|&e| (0..8).map(move |o| (e & !7) | o));
        let random = (0..200_000).map(|_| s.pcg.next_u32());
        for bits in edges.chain(random) {
            let (x, y) = circle_point(bits);
            let (rx, ry) = circle_point_reference(bits);
            assert_eq!(
                (x.to_bits(), y.to_bits()),
                (rx.to_bits(), ry.to_bits()),
                "{bits:#x}"
            );
        }
    }

    /// Fraction of `n` points falling in each of `bins` equal sectors of azimuth.
    fn azimuth_shares(points: impl Iterator<Item = (f32, f32)>, bins: usize) -> Vec<f64> {
        let mut counts = vec![0usize; bins];
        let mut n = 0;
        for (x, y) in points {
            let turn = f64::from(y).atan2(f64::from(x)) / std::f64::consts::TAU + 0.5;
            counts[((turn * bins as f64) as usize).min(bins - 1)] += 1;
            n += 1;
        }
        counts.iter().map(|&c| c as f64 / n as f64).collect()
    }

    #[test]
    fn circle_points_are_unit_and_spread_evenly_over_every_octant() {
        let mut s = Sampler::from_seed(5);
        let points: Vec<(f32, f32)> = (0..200_000).map(|_| s.on_unit_circle()).collect();
        for &(x, y) in &points {
            assert!((x * x + y * y - 1.0).abs() < 1e-6);
        }
        // 48 sectors: six per octant, so a missing reflection or a bent angle shows.
        for share in azimuth_shares(points.into_iter(), 48) {
            assert!((share - 1.0 / 48.0).abs() < 0.002, "{share}");
        }
    }

    #[test]
    fn disk_ball_and_sphere_samples_have_the_right_radial_law() {
        let mut s = Sampler::from_seed(13);
        let n = 200_000;
        let share = |f: &mut dyn FnMut() -> bool| (0..n).filter(|_| f()).count() as f64 / n as f64;
        // Uniform in area: a quarter of the disk lies within radius 1/2.
        let inner_disk = share(&mut || {
            let (x, y) = s.in_unit_disk();
            x * x + y * y < 0.25
        });
        assert!((inner_disk - 0.25).abs() < 0.005, "{inner_disk}");
        // Uniform in volume: an eighth of the ball lies within radius 1/2.
        let inner_ball = share(&mut || s.in_unit_sphere().length_squared() < 0.25);
        assert!((inner_ball - 0.125).abs() < 0.004, "{inner_ball}");
        // Uniform on the sphere: each axis is uniform in [-1, 1] (Archimedes), so a
        // quarter of the directions have |z| < 1/4, and likewise for x.
        let equator_z = share(&mut || s.unit_vector().z.abs() < 0.25);
        let equator_x = share(&mut || s.unit_vector().x.abs() < 0.25);
        for band in [equator_z, equator_x] {
            assert!((band - 0.25).abs() < 0.005, "{band}");
        }
        let disk_points = (0..n).map(|_| s.in_unit_disk());
        for sector in azimuth_shares(disk_points, 16) {
            assert!((sector - 1.0 / 16.0).abs() < 0.003, "{sector}");
        }
    }

    #[test]
    fn ball_disk_and_hemisphere_samples_stay_in_their_sets() {
        let mut s = Sampler::from_seed(11);
        let n = Vec3::new(0.0, 0.0, 1.0);
        for _ in 0..10_000 {
            assert!(s.in_unit_sphere().length_squared() < 1.0);
            let (x, y) = s.in_unit_disk();
            assert!(x * x + y * y < 1.0);
            assert!(s.in_hemisphere(n).dot(n) >= 0.0);
        }
    }
}
