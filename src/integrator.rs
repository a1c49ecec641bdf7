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

/// Radiance arriving along `ray` under the scene's shading mode. `Shading::Uv` has no rays;
/// the renderer handles it before calling here.
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
    let mut path = Path::new((), ray, rng.clone());
    let color = loop {
        if let Some(color) = path.finished(scene) {
            break color;
        }
        let hit = scene.hit(&path.ray, ANY_DISTANCE, stack);
        if let Some(color) = path.advance(scene, hit) {
            break color;
        }
    };
    *rng = path.rng;
    Radiance {
        color,
        rays: path.rays,
    }
}

/// Traces the path of every camera sample `samples` yields (a key, its camera ray and its
/// generator), two at a time with their hierarchy walks interleaved (`Bvh::intersect_pair`),
/// and hands each radiance to `done` with its key as the path ends. Camera rays are tested
/// against `primary` alone when given: the spheres picked for all of them
/// (`Scene::camera_candidates`). Each path's numbers are exactly those `path_trace` gives it;
/// only the order in which paths end differs.
pub fn trace_paths<K>(
    scene: &Scene,
    mut samples: impl Iterator<Item = (K, Ray, Sampler)>,
    primary: Option<&Candidates>,
    stack: &mut TraversalStack,
    mut done: impl FnMut(K, Radiance),
) {
    // The next path with a segment left to trace; paths that end sooner (zero depth, or
    // at their camera ray's hit) are handed over at once.
    let mut next = |done: &mut dyn FnMut(K, Radiance)| {
        for (key, ray, rng) in samples.by_ref() {
            let mut path = Path::new(key, ray, rng);
            let mut end = path.finished(scene);
            if end.is_none()
                && let Some(candidates) = primary
            {
                let hit = scene.hit_candidates(candidates, &path.ray, ANY_DISTANCE);
                end = path.advance(scene, hit);
            }
            match end {
                Some(color) => done(
                    path.key,
                    Radiance {
                        color,
                        rays: path.rays,
                    },
                ),
                None => return Some(path),
            }
        }
        None
    };
    let mut slots = [next(&mut done), next(&mut done)];
    loop {
        let hits = match &slots {
            [Some(a), Some(b)] => {
                let [ha, hb] = scene.hit_pair([&a.ray, &b.ray], ANY_DISTANCE, stack);
                [Some(ha), Some(hb)]
            }
            [Some(a), None] => [Some(scene.hit(&a.ray, ANY_DISTANCE, stack)), None],
            [None, Some(b)] => [None, Some(scene.hit(&b.ray, ANY_DISTANCE, stack))],
            [None, None] => return,
        };
        for (slot, hit) in slots.iter_mut().zip(hits) {
            let (Some(path), Some(hit)) = (slot.as_mut(), hit) else {
                continue;
            };
            if let Some(color) = path.advance(scene, hit) {
                let rays = path.rays;
                if let Some(path) = slot.take() {
                    done(path.key, Radiance { color, rays });
                }
                *slot = next(&mut done);
            }
        }
    }
}

/// A path under way: the segment to trace next and what the segments so far carry.
struct Path<K> {
    key: K,
    ray: Ray,
    rng: Sampler,
    throughput: Color,
    rays: u32,
}

impl<K> Path<K> {
    fn new(key: K, ray: Ray, rng: Sampler) -> Self {
        Path {
            key,
            ray,
            rng,
            throughput: Color::ONE,
            rays: 0,
        }
    }

    /// The radiance of a path that has used up its segments: none.
    #[inline(always)]
    fn finished(&self, scene: &Scene) -> Option<Color> {
        (self.rays >= scene.settings.max_depth).then_some(Color::ZERO)
    }

    /// Takes the traced segment's closest hit: the path's radiance if that ends it
    /// (escape, absorption, or the depth limit), else `None` with the next segment set up.
    #[inline(always)]
    fn advance(&mut self, scene: &Scene, hit: Option<Hit>) -> Option<Color> {
        self.rays += 1;
        let Some(hit) = hit else {
            return Some(self.throughput * scene.background.radiance(self.ray.dir));
        };
        let Some(scatter) =
            scene
                .material(&hit)
                .scatter(self.ray.dir, &hit, scene.settings.diffuse, &mut self.rng)
        else {
            return Some(Color::ZERO);
        };
        self.throughput *= scatter.attenuation;
        let dir = scatter.dir.normalize();
        // Start the next segment off the surface on the side it leaves towards, which
        // avoids shadow acne (§8.4) without the book's t_min cut-off losing real hits.
        let side = if dir.dot(hit.normal) >= 0.0 {
            hit.normal
        } else {
            -hit.normal
        };
        self.ray = Ray::new(hit.p + scene.settings.t_min * side, dir);
        self.finished(scene)
    }
}
