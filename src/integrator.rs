//! What one camera ray brings back: the book's `ray_color`, as a bounce loop carrying
//! throughput, plus the simpler shading modes of the book's first chapters. No threads, no I/O.

use crate::bvh::{Candidates, RayHints, TraversalStack};
use crate::geometry::Hit;
use crate::material::Material;
use crate::math::{Color, Interval, Vec3};
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
        let (next, hints) = bounce(scene, &here, scatter.dir);
        hit = scene.hit_with(&next, ANY_DISTANCE, stack, hints);
        ray = next;
        rays += 1;
    }
}

/// The segment that leaves `here` along the scattered direction `raw` (not necessarily
/// unit), and what the tree may use to trace it sooner (`RayHints`).
#[inline(always)]
pub fn bounce(scene: &Scene, here: &Hit, raw: Vec3) -> (Ray, RayHints) {
    let t_min = scene.settings.t_min;
    // `raw / len` is what `normalize` computes; the side and the hints come from `raw` (a
    // positive scale of `dir`), so they are ready before `dir` is.
    let len = raw.length();
    let dir = raw / len;
    // Start off the surface on the side the ray leaves towards, which avoids shadow acne
    // (§8.4) without the book's t_min cut-off losing real hits.
    let along_normal = raw.dot(here.normal) >= 0.0;
    let side = if along_normal {
        here.normal
    } else {
        -here.normal
    };
    let hints = RayHints {
        // A ray that leaves a sphere from outside cannot meet it again.
        leaving: (t_min > 0.0 && here.leaves_outside(along_normal)).then_some(here.primitive),
        // From the raw direction, a division sooner than `1 / dir`.
        inv_dir: Some(len * (Vec3::ONE / raw)),
    };
    (Ray::new(here.p + t_min * side, dir), hints)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Overrides;
    use std::path::Path;

    #[test]
    fn hinted_bounce_rays_find_what_plain_tracing_finds() {
        let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cover.toml"));
        let scene = Scene::load(path, &Overrides::default()).unwrap();
        let mut rng = Sampler::from_seed(17);
        let mut stack = scene.new_stack();
        let (mut bounces, mut skipped) = (0, 0);
        for _ in 0..20_000 {
            let (u, v) = (rng.uniform(), rng.uniform());
            let ray = scene.camera.ray(u, v, &mut rng);
            let Some(here) = scene.hit(&ray, ANY_DISTANCE, &mut stack) else {
                continue;
            };
            // Any direction, outwards and inwards, unit or not (as materials give them).
            let raw = rng.range(0.2, 2.0) * rng.unit_vector();
            let (next, hints) = bounce(&scene, &here, raw);
            let plain = scene.hit(&next, ANY_DISTANCE, &mut stack);
            let hinted = scene.hit_with(&next, ANY_DISTANCE, &mut stack, hints);
            let key = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.primitive));
            assert_eq!(key(hinted), key(plain), "{next:?} {hints:?}");
            bounces += 1;
            skipped += usize::from(hints.leaving.is_some());
        }
        assert!(bounces > 15_000 && skipped > 5_000, "{bounces} {skipped}");
    }
}
