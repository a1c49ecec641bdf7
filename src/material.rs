//! Materials of the books and how each scatters a ray: Lambertian (in the first book's three
//! diffuse variants), metal with fuzz, dielectric glass, and from *The Next Week* a diffuse
//! light, which emits and scatters nothing, and the isotropic phase function of media.
//!
//! A material's colour (albedo or emission) is a constant here; a textured material keeps
//! white and the integrator multiplies in its texture's value where the ray hits.

use crate::geometry::Hit;
use crate::math::{Color, Vec3, near_zero, reflect, reflectance, refract};
use crate::sampling::Sampler;
use serde::Deserialize;

/// How a diffuse surface picks its bounce direction: the book's three variants. Scene files
/// name them in snake case (`unit_sphere`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DiffuseModel {
    /// `normal + random_in_unit_sphere()`: the book's first, biased approximation (§8.2).
    UnitSphere,
    /// `normal + random_unit_vector()`: true Lambertian (§8.5).
    #[default]
    Lambertian,
    /// `random_in_hemisphere(normal)`: uniform over the hemisphere (§8.6).
    Hemisphere,
}

/// Which of the book's stages of glass a dielectric follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Refraction {
    /// Always refract, even past the critical angle (§10.2, image 14).
    Always,
    /// Refract, or reflect on total internal reflection (§10.3, image 15).
    Snell,
    /// Snell plus Schlick's reflectance chosen at random (§10.4 onwards).
    #[default]
    Schlick,
    /// The book's wrong first attempt (§10.1, image 13): the index ratio inverted, so rays
    /// bend the wrong way, and rays that cannot refract are absorbed (the black rings).
    Inverted,
}

/// A surface material. A closed set, dispatched with `match`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    Lambertian {
        albedo: Color,
    },
    Metal {
        albedo: Color,
        fuzz: f32,
    },
    Dielectric {
        ir: f32,
        refraction: Refraction,
    },
    /// An area light (the book's `diffuse_light`): emits `emit` from both faces.
    DiffuseLight {
        emit: Color,
    },
    /// A medium's phase function (the book's `isotropic`): scatters into any direction with
    /// equal probability.
    Isotropic {
        albedo: Color,
    },
}

/// The outcome of a scatter: the attenuation and the new (not necessarily unit) direction.
#[derive(Clone, Copy, Debug)]
pub struct Scatter {
    pub attenuation: Color,
    pub dir: Vec3,
}

impl Material {
    /// Scatters the unit direction `dir_in` at `hit`; `None` when the ray is absorbed.
    #[inline(always)]
    pub fn scatter(
        &self,
        dir_in: Vec3,
        hit: &Hit,
        diffuse: DiffuseModel,
        rng: &mut Sampler,
    ) -> Option<Scatter> {
        match *self {
            Material::Lambertian { albedo } => {
                let dir = match diffuse {
                    DiffuseModel::UnitSphere => hit.normal + rng.in_unit_sphere(),
                    DiffuseModel::Lambertian => hit.normal + rng.unit_vector(),
                    DiffuseModel::Hemisphere => rng.in_hemisphere(hit.normal),
                };
                // A direction that cancels the normal would be a zero vector (§9.3).
                let dir = if near_zero(dir) { hit.normal } else { dir };
                Some(Scatter {
                    attenuation: albedo,
                    dir,
                })
            }
            Material::Metal { albedo, fuzz } => {
                let reflected = reflect(dir_in, hit.normal);
                let dir = if fuzz > 0.0 {
                    reflected + fuzz * rng.in_unit_sphere()
                } else {
                    reflected
                };
                (dir.dot(hit.normal) > 0.0).then_some(Scatter {
                    attenuation: albedo,
                    dir,
                })
            }
            Material::Dielectric { ir, refraction } => {
                let ratio = if hit.front_face == (refraction == Refraction::Inverted) {
                    ir
                } else {
                    1.0 / ir
                };
                let cos_theta = (-dir_in).dot(hit.normal).min(1.0);
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                let cannot_refract = ratio * sin_theta > 1.0;
                let reflects = match refraction {
                    Refraction::Always => false,
                    Refraction::Inverted if cannot_refract => return None,
                    Refraction::Inverted => false,
                    Refraction::Snell => cannot_refract,
                    Refraction::Schlick => {
                        cannot_refract || reflectance(cos_theta, ratio) > rng.uniform()
                    }
                };
                let dir = if reflects {
                    reflect(dir_in, hit.normal)
                } else {
                    refract(dir_in, hit.normal, ratio)
                };
                Some(Scatter {
                    attenuation: Color::ONE,
                    dir,
                })
            }
            Material::DiffuseLight { .. } => None,
            // The book's `random_in_unit_sphere()`: its direction is uniform, which is all
            // the new ray keeps.
            Material::Isotropic { albedo } => Some(Scatter {
                attenuation: albedo,
                dir: rng.unit_vector(),
            }),
        }
    }

    /// The light the material emits (the book's `emitted`): black but for a diffuse light.
    #[inline(always)]
    pub fn emitted(&self) -> Color {
        match *self {
            Material::DiffuseLight { emit } => emit,
            _ => Color::ZERO,
        }
    }

    /// The colour a texture replaces (albedo, or a light's emission); `None` for glass,
    /// which has none.
    pub fn has_color(&self) -> bool {
        !matches!(self, Material::Dielectric { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{MaterialId, PrimitiveId};

    fn hit_with(normal: Vec3, front_face: bool) -> Hit {
        Hit {
            t: 1.0,
            p: Vec3::ZERO,
            normal,
            front_face,
            normal_points_out: front_face,
            material: MaterialId(0),
            primitive: PrimitiveId(0),
        }
    }

    #[test]
    fn diffuse_variants_scatter_above_the_surface() {
        let hit = hit_with(Vec3::Y, true);
        let m = Material::Lambertian {
            albedo: Color::splat(0.5),
        };
        let mut rng = Sampler::from_seed(1);
        for model in [
            DiffuseModel::UnitSphere,
            DiffuseModel::Lambertian,
            DiffuseModel::Hemisphere,
        ] {
            for _ in 0..1000 {
                let s = m.scatter(-Vec3::Y, &hit, model, &mut rng).unwrap();
                assert!(s.dir.dot(Vec3::Y) >= 0.0, "{model:?} {}", s.dir);
                assert_eq!(s.attenuation, Color::splat(0.5));
            }
        }
    }

    #[test]
    fn lambertian_mean_cosine_is_two_thirds() {
        // For a cosine-distributed direction, E[cos θ] = 2/3; uniform hemisphere gives 1/2.
        let hit = hit_with(Vec3::Y, true);
        let m = Material::Lambertian { albedo: Color::ONE };
        let mut rng = Sampler::from_seed(2);
        let mean_cos = |model, rng: &mut Sampler| {
            let n = 40_000;
            (0..n)
                .map(|_| {
                    m.scatter(-Vec3::Y, &hit, model, rng)
                        .unwrap()
                        .dir
                        .normalize()
                        .y
                })
                .sum::<f32>()
                / n as f32
        };
        assert!((mean_cos(DiffuseModel::Lambertian, &mut rng) - 2.0 / 3.0).abs() < 0.01);
        assert!((mean_cos(DiffuseModel::Hemisphere, &mut rng) - 0.5).abs() < 0.01);
    }

    #[test]
    fn smooth_metal_mirrors() {
        let hit = hit_with(Vec3::Y, true);
        let m = Material::Metal {
            albedo: Color::ONE,
            fuzz: 0.0,
        };
        let d = Vec3::new(1.0, -1.0, 0.0).normalize();
        let s = m.scatter(
            d,
            &hit,
            DiffuseModel::Lambertian,
            &mut Sampler::from_seed(0),
        );
        assert!((s.unwrap().dir - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-6);
    }

    #[test]
    fn glass_reflects_totally_past_the_critical_angle() {
        // Inside glass (back face), at 60° incidence: 1.5 · sin 60° > 1.
        let hit = hit_with(Vec3::Y, false);
        let d = Vec3::new(60f32.to_radians().sin(), -60f32.to_radians().cos(), 0.0);
        let mut rng = Sampler::from_seed(0);
        for refraction in [Refraction::Snell, Refraction::Schlick] {
            let m = Material::Dielectric {
                ir: 1.5,
                refraction,
            };
            let s = m
                .scatter(d, &hit, DiffuseModel::Lambertian, &mut rng)
                .unwrap();
            assert!(s.dir.y > 0.0, "{refraction:?} should reflect");
        }
        let always = Material::Dielectric {
            ir: 1.5,
            refraction: Refraction::Always,
        };
        let s = always.scatter(d, &hit, DiffuseModel::Lambertian, &mut rng);
        assert!(
            s.unwrap().dir.y < 0.0,
            "always-refract glass must not reflect"
        );
    }
}
