//! The random number generator, its seeding from (seed, pixel, sample), and the book's
//! sampling routines (unit sphere, unit vector, hemisphere, unit disk).
//!
//! Every random number a camera sample consumes comes from one PCG32 stream whose state is a
//! strong hash of `(scene seed, pixel x, pixel y, sample index)`. Nothing depends on which
//! thread or tile renders the sample, so images are reproducible byte for byte.

use crate::math::Vec3;
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

    /// A uniform `f32` in `[min, max)`.
    #[inline]
    pub fn range(&mut self, min: f32, max: f32) -> f32 {
        min + (max - min) * self.uniform()
    }

    /// A uniform point inside the unit ball, by rejection (the book's `random_in_unit_sphere`).
    #[inline]
    pub fn in_unit_sphere(&mut self) -> Vec3 {
        loop {
            let p = Vec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            if p.length_squared() < 1.0 {
                return p;
            }
        }
    }

    /// A uniform direction on the unit sphere (the book's `random_unit_vector`), by
    /// Marsaglia's method: a point `(u, v)` of the unit disk (by rejection, 1.27 tries on
    /// average) lifts to `(2u√(1-s), 2v√(1-s), 1-2s)` with `s = u² + v²`. Same distribution
    /// as normalising a point of the ball, with fewer random numbers and no trigonometry.
    #[inline]
    pub fn unit_vector(&mut self) -> Vec3 {
        let (u, v) = self.in_unit_disk();
        let s = u * u + v * v;
        let r = 2.0 * (1.0 - s).max(0.0).sqrt();
        Vec3::new(u * r, v * r, 1.0 - 2.0 * s)
    }

    /// A point of the unit ball flipped into the hemisphere around `normal`
    /// (the book's `random_in_hemisphere`).
    #[inline]
    pub fn in_hemisphere(&mut self, normal: Vec3) -> Vec3 {
        let p = self.in_unit_sphere();
        if p.dot(normal) > 0.0 { p } else { -p }
    }

    /// A uniform point of the unit disk in the xy plane, by rejection.
    #[inline]
    pub fn in_unit_disk(&mut self) -> (f32, f32) {
        loop {
            let x = self.range(-1.0, 1.0);
            let y = self.range(-1.0, 1.0);
            if x * x + y * y < 1.0 {
                return (x, y);
            }
        }
    }
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
    fn neighbouring_samples_differ() {
        let first = |s: Sampler| s.clone().uniform();
        let base = first(Sampler::for_sample(1, 10, 10, 0));
        for other in [
            Sampler::for_sample(2, 10, 10, 0),
            Sampler::for_sample(1, 11, 10, 0),
            Sampler::for_sample(1, 10, 11, 0),
            Sampler::for_sample(1, 10, 10, 1),
        ] {
            assert_ne!(base, first(other));
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
