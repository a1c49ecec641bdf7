//! What a pixel's samples bring back. `pixel` makes each camera sample (film position, lens,
//! ray) and shades it by the scene's shading mode, the book's early stages or path tracing;
//! this file traces a path: the book's `ray_color`, as a bounce loop carrying throughput.
//! No threads, no I/O.

mod pixel;

pub use pixel::{PixelEvaluator, tile_candidates};

use crate::bvh::{Leaving, RayHints, TraversalStack};
use crate::geometry::Hit;
use crate::math::{Color, Interval, Vec3};
use crate::ray::Ray;
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::simd::Isa;

/// Radiance along a camera ray and the number of ray segments traced to find it.
#[derive(Clone, Copy, Debug)]
pub struct Radiance {
    pub color: Color,
    pub rays: u32,
}

const ANY_DISTANCE: Interval = Interval::new(0.0, f32::INFINITY);

/// The radiance a path brings back, the book's recursive `ray_color` unrolled: at most
/// `max_depth` segments, each hit multiplying the throughput by the material's attenuation,
/// escape rays picking up the background. Its first segment, camera ray `ray`, has been traced
/// and met `first` (`None`: it escaped); the caller checks that `max_depth` allows one segment.
#[inline(always)]
pub fn path_trace_from<I: Isa>(
    isa: I,
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
        hit = scene.hit_on(isa, &next, ANY_DISTANCE, stack, hints);
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
        leaving: Leaving::sphere_if(
            (t_min > 0.0) & here.leaves_outside(along_normal),
            here.primitive,
        ),
        // From the raw direction, a division sooner than `1 / dir`.
        inv_dir: Some(len * (Vec3::ONE / raw)),
        heading: Some(raw),
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
