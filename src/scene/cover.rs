//! The book's `random_scene()` (§13.1): a grid of small random spheres, driven by a seeded
//! PCG generator so the same seed always gives the same cover, or by a C library's `rand()`
//! as the book's own program draws them, sphere for sphere (`draws`). *The Next Week* bounces
//! its diffuse spheres: each moves up between times 0 and 1.

use super::check::{Checker, MAX_LENGTH};
use super::desc::RandomSpheresDesc;
use super::draws::{DrawSettings, Draws};
use crate::error::Result;
use crate::geometry::{MaterialId, MovingSphere, Sphere};
use crate::material::{Material, Refraction};
use crate::math::{Color, Vec3};

/// The most points a grid keeps clear (`keep_clear`). Each of the grid's spheres is tested
/// against every point before it is drawn, and a grid may hold 2^20 spheres: 10,000 points
/// (a 129 KB file) took 27 s before the first pixel, and the most a file's values allow
/// (about 260,000) some ten minutes. 256 keep the tests to about half a second; the books'
/// scenes keep one point clear.
pub const MAX_KEEP_CLEAR: usize = 256;

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
    /// How far up a diffuse sphere may move between times 0 and 1 (`None`: it stands still).
    pub diffuse_bounce: Option<(f64, f64)>,
    pub draws: DrawSettings,
}

/// The generator's spheres, still and moving, in the book's order within each kind.
#[derive(Debug, Default)]
pub struct GeneratedSpheres {
    pub still: Vec<Sphere>,
    pub moving: Vec<MovingSphere>,
}

impl RandomSpheres {
    /// The generator `d` describes, for rays taken within `shutter`; its seed defaults to
    /// `image_seed`.
    pub(super) fn from_desc(
        d: &RandomSpheresDesc,
        image_seed: u64,
        shutter: (f32, f32),
        ck: &Checker,
    ) -> Result<Self> {
        let draws = DrawSettings::check(
            ck,
            "random_spheres",
            d.generator,
            d.seed.as_ref(),
            d.skip.as_ref(),
            d.draw_order,
            image_seed,
        )?;
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
        if let Some(past) = d.keep_clear.get(MAX_KEEP_CLEAR) {
            return Err(ck.error(
                past.span(),
                "random_spheres.keep_clear",
                format!(
                    "holds {} points, more than the {MAX_KEEP_CLEAR} a grid may keep clear \
                     (every sphere of the grid is tested against each)",
                    d.keep_clear.len()
                ),
            ));
        }
        let keep_clear = d
            .keep_clear
            .iter()
            .map(|p| ck.point(p, "random_spheres.keep_clear"))
            .collect::<Result<_>>()?;
        let radius = ck.radius(&d.radius, "random_spheres.radius", true)?;
        let diffuse_bounce = match &d.diffuse_bounce {
            None => None,
            Some(b) => {
                let (low, high) = ck.range(b, "random_spheres.diffuse_bounce")?;
                // A sphere rises `rise` from time 0 to 1, and keeps moving so outside: where
                // the shutter opens and closes its centre must lie within `MAX_LENGTH`, or its
                // squares overflow and it silently vanishes.
                let reach = [shutter.0, shutter.1]
                    .iter()
                    .flat_map(|&t| [low, high].map(|rise| f64::from(radius) + f64::from(t) * rise))
                    .fold(0.0, |m: f64, y| m.max(y.abs()));
                if reach > f64::from(MAX_LENGTH) {
                    return Err(ck.error(
                        b.span(),
                        "random_spheres.diffuse_bounce",
                        format!(
                            "moves a sphere's centre to {reach:e} from the ground within the \
                             shutter [{}, {}]: coordinates must lie within ±{MAX_LENGTH:e} \
                             (beyond, f32 arithmetic overflows and the sphere would vanish)",
                            shutter.0, shutter.1
                        ),
                    ));
                }
                Some((low, high))
            }
        };
        Ok(Self {
            grid: grid as i32,
            radius,
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
            diffuse_bounce,
            draws,
        })
    }

    /// The spheres, in the book's order, appending their materials to `materials`; moving
    /// ones are seen by rays taken within `shutter`.
    pub fn generate(&self, materials: &mut Vec<Material>, shutter: (f32, f32)) -> GeneratedSpheres {
        let mut draws = self.draws.draws();
        self.generate_with(materials, &mut draws, shutter)
    }

    /// The book's loop, drawing from `draws` (whose argument order decides which of the
    /// book's `point3 center(a + 0.9*random_double(), 0.2, b + 0.9*random_double())` draws
    /// comes first: GCC draws z, then x).
    fn generate_with(
        &self,
        materials: &mut Vec<Material>,
        draws: &mut Draws,
        shutter: (f32, f32),
    ) -> GeneratedSpheres {
        let mut out = GeneratedSpheres::default();
        let y = f64::from(self.radius);
        for a in -self.grid..self.grid {
            for b in -self.grid..self.grid {
                let choose_mat = draws.uniform();
                let (dx, dz) = draws.two();
                let (cx, cz) = (f64::from(a) + 0.9 * dx, f64::from(b) + 0.9 * dz);
                let center = Vec3::new(cx as f32, y as f32, cz as f32);
                if self
                    .keep_clear
                    .iter()
                    .any(|&p| (center - p).length() <= self.clearance)
                {
                    continue;
                }
                let mut rise = None;
                let material = if choose_mat < self.p_diffuse {
                    // `color::random() * color::random()`: which factor is drawn first
                    // does not matter, as the product commutes.
                    let c1 = draws.three(0.0..1.0);
                    let c2 = draws.three(0.0..1.0);
                    if let Some((low, high)) = self.diffuse_bounce {
                        rise = Some(draws.range(low..high));
                    }
                    Material::Lambertian {
                        albedo: color(|i| c1[i] * c2[i]),
                    }
                } else if choose_mat < self.p_diffuse + self.p_metal {
                    let albedo = draws.three(0.5..1.0);
                    Material::Metal {
                        albedo: color(|i| albedo[i]),
                        fuzz: draws.range(0.0..0.5) as f32,
                    }
                } else {
                    Material::Dielectric {
                        ir: self.glass_ir,
                        refraction: Refraction::Schlick,
                    }
                };
                let id = MaterialId(materials.len() as u32);
                materials.push(material);
                match rise {
                    None => out.still.push(Sphere::new(center, self.radius, id)),
                    Some(rise) => {
                        let up = Vec3::new(cx as f32, (y + rise) as f32, cz as f32);
                        out.moving.push(MovingSphere::new(
                            (center, 0.0),
                            (up, 1.0),
                            self.radius,
                            id,
                            shutter,
                        ));
                    }
                }
            }
        }
        out
    }
}

fn color(f: impl Fn(usize) -> f64) -> Color {
    Color::new(f(0) as f32, f(1) as f32, f(2) as f32)
}
