//! What one camera ray brings back: the book's `ray_color`, as a bounce loop carrying
//! throughput, plus the simpler shading modes of the book's first chapters. No threads, no I/O.

use crate::bvh::{Candidates, TraversalStack};
use crate::material::Material;
use crate::math::{Color, Interval};
use crate::ray::Ray;
use crate::sampling::Sampler;
use crate::scene::{Scene, Shading};

/// Radiance along a camera ray and the number of ray segments traced to find it.
#[derive(Clone, Copy, Debug)]
pub struct Radiance {
    pub color: Color,
    pub rays: u32,
}

const ANY_DISTANCE: Interval = Interval::new(0.0, f32::INFINITY);

/// Radiance arriving along camera ray `ray` under the scene's shading mode. `Shading::Uv`
/// has no rays; the renderer handles it before calling here. `primary`, the spheres picked
/// for this camera ray, serves path tracing (see `path_trace`).
#[inline]
pub fn radiance(
    scene: &Scene,
    ray: Ray,
    rng: &mut Sampler,
    primary: Option<&Candidates>,
    stack: &mut TraversalStack,
) -> Radiance {
    match scene.settings.shading {
        Shading::Uv | Shading::Gradient => Radiance {
            color: scene.background.radiance(ray.dir),
            rays: u32::from(scene.settings.shading == Shading::Gradient),
        },
        Shading::Flat => Radiance {
            color: match scene.hit(&ray, ANY_DISTANCE, stack) {
                Some(hit) => match *scene.material(&hit) {
                    Material::Lambertian { albedo } | Material::Metal { albedo, .. } => albedo,
                    Material::Dielectric { .. } => Color::ONE,
                },
                None => scene.background.radiance(ray.dir),
            },
            rays: 1,
        },
        Shading::Normals => Radiance {
            color: match scene.hit(&ray, ANY_DISTANCE, stack) {
                Some(hit) => 0.5 * (hit.normal + Color::ONE),
                None => scene.background.radiance(ray.dir),
            },
            rays: 1,
        },
        Shading::Path => path_trace(scene, ray, rng, primary, stack),
    }
}

/// The book's recursive `ray_color` unrolled: at most `max_depth` segments, each hit
/// multiplying the throughput by the material's attenuation, escape rays picking up the
/// background. When `primary` is given, the first segment (a camera ray) is tested against
/// those spheres alone, the ones `Scene::camera_candidates` picked for it; the answer is
/// the same as the hierarchy's.
#[inline]
pub fn path_trace(
    scene: &Scene,
    mut ray: Ray,
    rng: &mut Sampler,
    primary: Option<&Candidates>,
    stack: &mut TraversalStack,
) -> Radiance {
    let settings = &scene.settings;
    let mut throughput = Color::ONE;
    let mut rays = 0;
    while rays < settings.max_depth {
        let hit = match primary {
            Some(candidates) if rays == 0 => scene.hit_candidates(candidates, &ray, ANY_DISTANCE),
            _ => scene.hit(&ray, ANY_DISTANCE, stack),
        };
        rays += 1;
        let Some(hit) = hit else {
            return Radiance {
                color: throughput * scene.background.radiance(ray.dir),
                rays,
            };
        };
        let Some(scatter) = scene
            .material(&hit)
            .scatter(ray.dir, &hit, settings.diffuse, rng)
        else {
            return Radiance {
                color: Color::ZERO,
                rays,
            };
        };
        throughput *= scatter.attenuation;
        let dir = scatter.dir.normalize();
        // Start the next segment off the surface on the side it leaves towards, which
        // avoids shadow acne (§8.4) without the book's t_min cut-off losing real hits.
        let side = if dir.dot(hit.normal) >= 0.0 {
            hit.normal
        } else {
            -hit.normal
        };
        ray = Ray::new(hit.p + settings.t_min * side, dir);
    }
    Radiance {
        color: Color::ZERO,
        rays,
    }
}
