//! The book's `random_scene()` (§13.1): a grid of small random spheres, driven by a seeded
//! PCG generator so the same seed always gives the same cover, or by glibc's `rand()` as the
//! book's own program draws them on Linux, sphere for sphere.

use super::check::Checker;
use super::desc::{RandomSpheresDesc, SphereGenerator};
use crate::error::Result;
use crate::geometry::{MaterialId, Sphere};
use crate::material::{Material, Refraction};
use crate::math::{Color, Vec3};
use crate::sampling::Sampler;

/// Validated parameters of the generator.
#[derive(Clone, Debug, PartialEq)]
pub struct RandomSpheres {
    pub grid: i32,
    pub radius: f32,
    pub keep_clear: Vec<Vec3>,
    pub clearance: f32,
    pub p_diffuse: f64,
    pub p_metal: f64,
    pub glass_ir: f32,
    pub generator: SphereGenerator,
    pub seed: u64,
}

impl RandomSpheres {
    /// The generator `d` describes; its seed defaults to `image_seed`.
    pub(super) fn from_desc(d: &RandomSpheresDesc, image_seed: u64, ck: &Checker) -> Result<Self> {
        let seed = d.seed.as_ref().map_or(image_seed, |s| *s.get_ref());
        if d.generator == SphereGenerator::Glibc && seed > u64::from(u32::MAX) {
            let span = d.seed.as_ref().map_or(0..0, |s| s.span());
            return Err(ck.error(
                span,
                "random_spheres.seed",
                format!(
                    "glibc's srand takes an unsigned int: at most {}, got {seed}",
                    u32::MAX
                ),
            ));
        }
        let grid = *d.grid.get_ref();
        if !(0..=1000).contains(&grid) {
            return Err(ck.error(
                d.grid.span(),
                "random_spheres.grid",
                format!("must be between 0 and 1000, got {grid}"),
            ));
        }
        let probability = |v, f: &str| {
            ck.in_range(
                v,
                f,
                |p| (0.0..=1.0).contains(&p),
                "a probability in [0, 1]",
            )
        };
        let p_diffuse = probability(&d.p_diffuse, "random_spheres.p_diffuse")?;
        let p_metal = probability(&d.p_metal, "random_spheres.p_metal")?;
        if p_diffuse + p_metal > 1.0 + 1e-6 {
            return Err(ck.error(
                d.p_metal.span(),
                "random_spheres.p_metal",
                format!(
                    "p_diffuse + p_metal must not exceed 1, got {}",
                    p_diffuse + p_metal
                ),
            ));
        }
        let keep_clear = d
            .keep_clear
            .iter()
            .map(|p| ck.point(p, "random_spheres.keep_clear"))
            .collect::<Result<_>>()?;
        Ok(Self {
            grid: grid as i32,
            radius: ck.radius(&d.radius, "random_spheres.radius", true)?,
            keep_clear,
            clearance: ck.length(
                &d.clearance,
                "random_spheres.clearance",
                |c| c >= 0.0,
                "zero or positive",
            )?,
            p_diffuse: f64::from(p_diffuse),
            p_metal: f64::from(p_metal),
            glass_ir: ck.in_range(
                &d.glass_ir,
                "random_spheres.glass_ir",
                |i| i > 0.0,
                "positive",
            )?,
            generator: d.generator,
            seed,
        })
    }

    /// The spheres, in the book's order, appending their materials to `materials`.
    pub fn generate(&self, materials: &mut Vec<Material>) -> Vec<Sphere> {
        match self.generator {
            SphereGenerator::Pcg => {
                let mut rng = Sampler::from_seed(self.seed);
                self.generate_with(materials, move || rng.uniform_f64(), false)
            }
            SphereGenerator::Glibc => {
                // The seed is checked to fit an unsigned int.
                let mut rng = GlibcRand::new(self.seed as u32);
                self.generate_with(materials, move || rng.uniform(), true)
            }
        }
    }

    /// The book's loop, drawing from `rnd`. `right_to_left`: the arguments of each
    /// constructor and operator call are drawn last first, as GCC evaluates them (the book's
    /// `point3 center(a + 0.9*random_double(), 0.2, b + 0.9*random_double())` draws z, then x).
    fn generate_with(
        &self,
        materials: &mut Vec<Material>,
        mut rnd: impl FnMut() -> f64,
        right_to_left: bool,
    ) -> Vec<Sphere> {
        // Three draws in argument order.
        let three = |rnd: &mut dyn FnMut() -> f64| {
            let (p, q, r) = (rnd(), rnd(), rnd());
            if right_to_left { [r, q, p] } else { [p, q, r] }
        };
        let mut spheres = Vec::new();
        let y = f64::from(self.radius);
        for a in -self.grid..self.grid {
            for b in -self.grid..self.grid {
                let choose_mat = rnd();
                let (cx, cz) = if right_to_left {
                    let cz = f64::from(b) + 0.9 * rnd();
                    (f64::from(a) + 0.9 * rnd(), cz)
                } else {
                    let cx = f64::from(a) + 0.9 * rnd();
                    (cx, f64::from(b) + 0.9 * rnd())
                };
                let center = Vec3::new(cx as f32, y as f32, cz as f32);
                if self
                    .keep_clear
                    .iter()
                    .any(|&p| (center - p).length() <= self.clearance)
                {
                    continue;
                }
                let material = if choose_mat < self.p_diffuse {
                    // `color::random() * color::random()`: which factor is drawn first
                    // does not matter, as the product commutes.
                    let c1 = three(&mut rnd);
                    let c2 = three(&mut rnd);
                    Material::Lambertian {
                        albedo: color(|i| c1[i] * c2[i]),
                    }
                } else if choose_mat < self.p_diffuse + self.p_metal {
                    let c = three(&mut rnd);
                    let albedo = color(|i| 0.5 + 0.5 * c[i]);
                    Material::Metal {
                        albedo,
                        fuzz: (0.5 * rnd()) as f32,
                    }
                } else {
                    Material::Dielectric {
                        ir: self.glass_ir,
                        refraction: Refraction::Schlick,
                    }
                };
                let id = MaterialId(materials.len() as u32);
                materials.push(material);
                spheres.push(Sphere::new(center, self.radius, id));
            }
        }
        spheres
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

fn color(f: impl Fn(usize) -> f64) -> Color {
    Color::new(f(0) as f32, f(1) as f32, f(2) as f32)
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
}
