//! The random numbers that build a scene (its generators' spheres and boxes, its noise
//! textures' tables): tessera's seeded PCG, or the C libraries' `rand()` the books' figures
//! were made with (glibc's, Microsoft's), in the order a compiler evaluates the books'
//! expressions. All of it is tessera's own integer arithmetic: the same numbers on every
//! machine.

use super::check::Checker;
use super::desc::{DrawOrder, SphereGenerator};
use crate::error::Result;
use crate::sampling::Sampler;
use std::ops::Range;
use toml::Spanned;

/// A generator's validated settings: which source, its seed, how many draws to skip first,
/// and the order of multi-draw expressions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DrawSettings {
    pub generator: SphereGenerator,
    pub seed: u64,
    pub skip: u64,
    pub order: DrawOrder,
}

/// The most draws a scene's generators may skip, each and in all. Skipping is one draw at a
/// time (glibc's generator cannot jump ahead), about 2 ns each: the limit keeps a scene's
/// skipping under about 40 ms, however many generators it holds. The books' scenes skip a
/// few thousand.
pub const MAX_SKIPPED: u64 = 1 << 24;

impl DrawSettings {
    /// Checks a generator's `seed` (default `default_seed`), `skip` and `draw_order` (default:
    /// the generator's compiler's).
    pub(super) fn check(
        ck: &Checker,
        table: &str,
        generator: SphereGenerator,
        seed: Option<&Spanned<u64>>,
        skip: Option<&Spanned<i64>>,
        order: Option<DrawOrder>,
        default_seed: u64,
    ) -> Result<Self> {
        let value = seed.map_or(default_seed, |s| *s.get_ref());
        let span = |s: Option<&Spanned<u64>>| s.map_or(0..0, Spanned::span);
        if generator != SphereGenerator::Pcg && value > u64::from(u32::MAX) {
            return Err(ck.error(
                span(seed),
                &format!("{table}.seed"),
                format!(
                    "srand takes an unsigned int: at most {}, got {value}",
                    u32::MAX
                ),
            ));
        }
        let skip = match skip {
            None => 0,
            Some(s) => {
                let n = *s.get_ref();
                let field = format!("{table}.skip");
                let Some(n) = u64::try_from(n).ok().filter(|&n| n <= MAX_SKIPPED) else {
                    return Err(ck.error(
                        s.span(),
                        &field,
                        format!("must be between 0 and {MAX_SKIPPED}, got {n}"),
                    ));
                };
                let total = ck.skipped.get() + n;
                if total > MAX_SKIPPED {
                    return Err(ck.error(
                        s.span(),
                        &field,
                        format!(
                            "the scene's generators would skip {total} draws in all, \
                             at most {MAX_SKIPPED}"
                        ),
                    ));
                }
                ck.skipped.set(total);
                n
            }
        };
        let order = order.unwrap_or(match generator {
            // tessera's own generator draws in the order the expressions read.
            SphereGenerator::Pcg => DrawOrder::LeftToRight,
            // GCC and MSVC evaluate function arguments last first.
            SphereGenerator::Glibc | SphereGenerator::Msvc => DrawOrder::RightToLeft,
        });
        Ok(Self {
            generator,
            seed: value,
            skip,
            order,
        })
    }

    /// The generator, its skipped draws behind it.
    pub fn draws(&self) -> Draws {
        let mut source = match self.generator {
            SphereGenerator::Pcg => Source::Pcg(Sampler::from_seed(self.seed)),
            // The seed is checked to fit an unsigned int.
            SphereGenerator::Glibc => Source::Glibc(GlibcRand::new(self.seed as u32)),
            SphereGenerator::Msvc => Source::Msvc(MsvcRand::new(self.seed as u32)),
        };
        for _ in 0..self.skip {
            source.next();
        }
        Draws {
            source,
            order: self.order,
        }
    }
}

enum Source {
    Pcg(Sampler),
    Glibc(GlibcRand),
    Msvc(MsvcRand),
}

impl Source {
    fn next(&mut self) -> f64 {
        match self {
            Source::Pcg(rng) => rng.uniform_f64(),
            Source::Glibc(rng) => rng.uniform(),
            Source::Msvc(rng) => rng.uniform(),
        }
    }
}

/// A scene generator's stream of random numbers: the book's `random_double()`.
pub struct Draws {
    source: Source,
    order: DrawOrder,
}

impl Draws {
    /// The book's `random_double()`, in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        self.source.next()
    }

    /// The book's `random_double(min, max)`.
    pub fn range(&mut self, r: Range<f64>) -> f64 {
        r.start + (r.end - r.start) * self.uniform()
    }

    /// The book's `random_int(0, max)`: `static_cast<int>(random_double(0, max + 1))`.
    pub fn int_to(&mut self, max: u32) -> u32 {
        ((f64::from(max) + 1.0) * self.uniform()) as u32
    }

    /// Three draws as the arguments of one call (`vec3::random()`): in `[x, y, z]` order
    /// whichever order the compiler draws them in.
    pub fn three(&mut self, r: Range<f64>) -> [f64; 3] {
        let (p, q, s) = (self.range(r.clone()), self.range(r.clone()), self.range(r));
        match self.order {
            DrawOrder::LeftToRight => [p, q, s],
            DrawOrder::RightToLeft => [s, q, p],
        }
    }

    /// Two draws as the arguments of one call: `(first, second)` in argument order.
    pub fn two(&mut self) -> (f64, f64) {
        let (p, q) = (self.uniform(), self.uniform());
        match self.order {
            DrawOrder::LeftToRight => (p, q),
            DrawOrder::RightToLeft => (q, p),
        }
    }
}

impl crate::texture::TableDraws for Draws {
    fn uniform(&mut self) -> f64 {
        Draws::uniform(self)
    }
    fn three(&mut self, range: Range<f64>) -> [f64; 3] {
        Draws::three(self, range)
    }
    fn int_to(&mut self, max: u32) -> u32 {
        Draws::int_to(self, max)
    }
}

/// glibc's `rand()` (its default `TYPE_3` additive feedback generator), as `srand(seed)`
/// leaves it: `r[i] = r[i-31] + r[i-3]` over 34 words seeded by the Park–Miller generator,
/// the first 310 outputs discarded, each output `r >> 1`.
#[derive(Clone, Debug)]
pub struct GlibcRand {
    r: [u32; 34],
    /// Where the next word goes: the ring holds the last 34 words.
    i: usize,
}

impl GlibcRand {
    pub fn new(seed: u32) -> Self {
        let mut r = [0u32; 34];
        // `srand(0)` seeds as `srand(1)`.
        r[0] = seed.max(1);
        for i in 1..31 {
            // 16807 · r mod (2³¹ − 1), on the word as glibc's `int32_t` sees it.
            let prev = i64::from(r[i - 1] as i32);
            let mut word = (16807 * prev) % 2_147_483_647;
            if word < 0 {
                word += 2_147_483_647;
            }
            r[i] = word as u32;
        }
        for i in 31..34 {
            r[i] = r[i - 31];
        }
        let mut rng = Self { r, i: 0 };
        for _ in 34..344 {
            rng.next_word();
        }
        rng
    }

    fn next_word(&mut self) -> u32 {
        // Words 31 and 3 back from the new one.
        let word = self.r[(self.i + 3) % 34].wrapping_add(self.r[(self.i + 31) % 34]);
        self.r[self.i] = word;
        self.i = (self.i + 1) % 34;
        word
    }

    /// The next `rand()`: 0 to `RAND_MAX` (2³¹ − 1).
    pub fn next(&mut self) -> u32 {
        self.next_word() >> 1
    }

    /// The book's `random_double()`: `rand() / (RAND_MAX + 1.0)`.
    pub fn uniform(&mut self) -> f64 {
        f64::from(self.next()) / 2_147_483_648.0
    }
}

/// Microsoft's C runtime `rand()`: `s = 214013 s + 2531011 (mod 2³²)`, each output the 15
/// bits `s >> 16`, `RAND_MAX` 32767; `srand(seed)` sets `s`, 1 by default.
#[derive(Clone, Debug)]
pub struct MsvcRand {
    state: u32,
}

impl MsvcRand {
    pub fn new(seed: u32) -> Self {
        Self { state: seed }
    }

    pub fn next(&mut self) -> u32 {
        self.state = self.state.wrapping_mul(214_013).wrapping_add(2_531_011);
        (self.state >> 16) & 0x7fff
    }

    /// `rand() / (RAND_MAX + 1.0)`.
    pub fn uniform(&mut self) -> f64 {
        f64::from(self.next()) / 32768.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// glibc's documented first outputs of `rand()` without `srand` (seed 1), and with
    /// `srand(0)`, which seeds as 1.
    #[test]
    fn glibc_rand_matches_its_known_first_outputs() {
        let want = [
            1804289383, 846930886, 1681692777, 1714636915, 1957747793, 424238335,
        ];
        for seed in [1, 0] {
            let mut rng = GlibcRand::new(seed);
            let got: Vec<u32> = (0..6).map(|_| rng.next()).collect();
            assert_eq!(got, want);
        }
        // srand(42): its first output, as glibc gives it.
        assert_eq!(GlibcRand::new(42).next(), 71876166);
        let mut rng = GlibcRand::new(7);
        let later = (0..1001).map(|_| rng.next()).last();
        assert_eq!(later, Some(363912548));
    }

    /// Microsoft's first outputs without `srand`.
    #[test]
    fn msvc_rand_matches_its_known_first_outputs() {
        let mut rng = MsvcRand::new(1);
        let got: Vec<u32> = (0..4).map(|_| rng.next()).collect();
        assert_eq!(got, [41, 18467, 6334, 26500]);
    }

    #[test]
    fn skipped_draws_and_argument_order() {
        let settings = |order, skip| DrawSettings {
            generator: SphereGenerator::Glibc,
            seed: 1,
            skip,
            order,
        };
        let mut plain = settings(DrawOrder::LeftToRight, 0).draws();
        let first: Vec<f64> = (0..6).map(|_| plain.uniform()).collect();
        let mut skipped = settings(DrawOrder::LeftToRight, 3).draws();
        assert_eq!(skipped.three(0.0..1.0), [first[3], first[4], first[5]]);
        let mut gcc = settings(DrawOrder::RightToLeft, 0).draws();
        assert_eq!(gcc.three(0.0..1.0), [first[2], first[1], first[0]]);
        assert_eq!(gcc.two(), (first[4], first[3]));
    }
}
