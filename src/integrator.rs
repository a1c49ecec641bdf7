//! What one camera ray brings back: the book's `ray_color`, as a bounce loop carrying
//! throughput, plus the simpler shading modes of the book's first chapters. No threads, no I/O.

use crate::bvh::{Candidates, TraversalStack};
use crate::geometry::Hit;
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
/// has no rays; the renderer handles it before calling here.
#[inline]
pub fn radiance(
    scene: &Scene,
    ray: Ray,
    rng: &mut Sampler,
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
        Shading::Path => path_trace(scene, ray, rng, stack),
    }
}

/// The book's recursive `ray_color` unrolled: at most `max_depth` segments, each hit
/// multiplying the throughput by the material's attenuation, escape rays picking up the
/// background.
#[inline]
pub fn path_trace(
    scene: &Scene,
    ray: Ray,
    rng: &mut Sampler,
    stack: &mut TraversalStack,
) -> Radiance {
    if scene.settings.max_depth == 0 {
        return Radiance {
            color: Color::ZERO,
            rays: 0,
        };
    }
    let hit = scene.hit(&ray, ANY_DISTANCE, stack);
    path_trace_from(scene, ray, hit, rng, stack)
}

/// What camera ray `ray` hits first: among `primary` when given (the spheres
/// `Scene::camera_candidates` picked for its tile, which give the same answer as the tree),
/// else through the tree.
#[inline(always)]
pub fn camera_hit(
    scene: &Scene,
    ray: &Ray,
    primary: Option<&Candidates>,
    stack: &mut TraversalStack,
) -> Option<Hit> {
    match primary {
        Some(candidates) => scene.hit_candidates(candidates, ray, ANY_DISTANCE),
        None => scene.hit(ray, ANY_DISTANCE, stack),
    }
}

/// `path_trace` after its first segment: camera ray `ray` has been traced and met `first`
/// (`None`: it escaped). The caller checks that `max_depth` allows one segment.
#[inline(always)]
pub fn path_trace_from(
    scene: &Scene,
    mut ray: Ray,
    first: Option<Hit>,
    rng: &mut Sampler,
    stack: &mut TraversalStack,
) -> Radiance {
    let settings = &scene.settings;
    let mut throughput = Color::ONE;
    let mut hit = first;
    let mut rays = 1;
    loop {
        let Some(here) = hit else {
            return Radiance {
                color: throughput * scene.background.radiance(ray.dir),
                rays,
            };
        };
        let Some(scatter) = scene
            .material(&here)
            .scatter(ray.dir, &here, settings.diffuse, rng)
        else {
            return Radiance {
                color: Color::ZERO,
                rays,
            };
        };
        if rays >= settings.max_depth {
            return Radiance {
                color: Color::ZERO,
                rays,
            };
        }
        throughput *= scatter.attenuation;
        let dir = scatter.dir.normalize();
        // Start the next segment off the surface on the side it leaves towards, which
        // avoids shadow acne (§8.4) without the book's t_min cut-off losing real hits.
        let along_normal = dir.dot(here.normal) >= 0.0;
        let side = if along_normal {
            here.normal
        } else {
            -here.normal
        };
        ray = Ray::new(here.p + settings.t_min * side, dir);
        // A ray that leaves a sphere from outside cannot meet it again: the tree skips it.
        let leaving = (settings.t_min > 0.0 && scene.leaves_outside(&here, along_normal))
            .then_some(here.primitive);
        hit = scene.hit_leaving(&ray, ANY_DISTANCE, stack, leaving);
        rays += 1;
    }
}
