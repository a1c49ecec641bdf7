//! The book's `random_scene()` (§13.1): a grid of small random spheres, driven by a seeded
//! PCG generator so the same seed always gives the same cover.

use super::check::Checker;
use super::desc::RandomSpheresDesc;
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
}

impl RandomSpheres {
    pub(super) fn from_desc(d: &RandomSpheresDesc, ck: &Checker) -> Result<Self> {
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
        })
    }

    /// Appends the spheres and their materials, drawing random numbers in the book's order.
    pub fn generate(&self, seed: u64, materials: &mut Vec<Material>, spheres: &mut Vec<Sphere>) {
        let mut rng = Sampler::from_seed(seed);
        let mut rnd = move || rng.uniform_f64();
        let y = f64::from(self.radius);
        for a in -self.grid..self.grid {
            for b in -self.grid..self.grid {
                let choose_mat = rnd();
                let cx = f64::from(a) + 0.9 * rnd();
                let cz = f64::from(b) + 0.9 * rnd();
                let center = Vec3::new(cx as f32, y as f32, cz as f32);
                if self
                    .keep_clear
                    .iter()
                    .any(|&p| (center - p).length() <= self.clearance)
                {
                    continue;
                }
                let material = if choose_mat < self.p_diffuse {
                    let c1 = [rnd(), rnd(), rnd()];
                    let c2 = [rnd(), rnd(), rnd()];
                    Material::Lambertian {
                        albedo: color(|i| c1[i] * c2[i]),
                    }
                } else if choose_mat < self.p_diffuse + self.p_metal {
                    let c = [rnd(), rnd(), rnd()];
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
    }
}

fn color(f: impl Fn(usize) -> f64) -> Color {
    Color::new(f(0) as f32, f(1) as f32, f(2) as f32)
}
