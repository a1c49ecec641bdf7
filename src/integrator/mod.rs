//! What a pixel's samples bring back. `pixel` makes each camera sample (film position, lens,
//! time, ray) and shades it by the scene's shading mode, the book's early stages or path
//! tracing; this file traces a path: the books' `ray_color`, as a bounce loop carrying
//! throughput. The first book's scenes (still spheres, no light but the sky, no texture)
//! take its loop as it was; everything else *The Next Week*'s, which adds what the hit
//! emits, textures, the ray's time and the media's random numbers. No threads, no I/O.

mod batch;
mod pixel;

pub use batch::trace_tile;
pub use pixel::{PixelEvaluator, tile_candidates};

/// The rays traced between two looks at a stop flag, at most (and one sample's more): some
/// milliseconds' work on one thread, so that a stop is seen within a tenth of a second
/// whatever the paths' lengths.
pub const STOP_RAYS: u64 = 1 << 16;

use crate::bvh::{Leaving, Moment, RayHints, TraversalStack};
use crate::geometry::Hit;
use crate::math::{Color, Interval, Vec3};
use crate::ray::Ray;
use crate::sampling::Sampler;
use crate::scene::{Scene, SurfaceOffset};
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
/// For the first book's scenes only (still spheres: `Scene::needs_full_paths` is false).
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
        let (next, interval, hints) = bounce::<false>(scene, &here, scatter.dir);
        hit = scene.hit_still_on(isa, &next, interval, stack, hints);
        ray = next;
        rays += 1;
    }
}

/// *The Next Week*'s `ray_color`, unrolled as `path_trace_from`: each hit adds what it emits
/// (times the throughput so far) before it scatters; textured materials take their colour
/// from the texture where hit. The path keeps the camera ray's time (`moment.time`); each
/// segment after the first draws the random number media scatter by when the scene has
/// media (`moment.medium_key`, the camera ray's drawn with its sample).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn path_trace_full<I: Isa>(
    isa: I,
    scene: &Scene,
    ray: Ray,
    moment: Moment,
    first: Option<Hit>,
    rng: &mut Sampler,
    stack: &mut TraversalStack,
) -> Radiance {
    let mut path = FullPath::start(ray, moment);
    let mut hit = first;
    loop {
        match path.advance(scene, hit, rng) {
            Some((next, interval, hints)) => {
                hit = scene.hit_at(isa, &next, path.moment, interval, stack, hints);
            }
            None => return path.radiance(),
        }
    }
}

/// A path of *The Next Week*'s `ray_color` (see `path_trace_full`), a segment at a time:
/// what it has gathered so far, and the ray it traced last. The caller traces each segment
/// the path asks for and hands its hit back, so that several paths can be traced side by
/// side (`batch`).
#[derive(Clone, Copy, Debug)]
pub struct FullPath {
    /// The ray traced last.
    ray: Ray,
    /// Its time, and the medium key of its segment.
    pub moment: Moment,
    radiance: Color,
    throughput: Color,
    rays: u32,
}

impl FullPath {
    /// A path whose first segment is the camera ray `ray`, taken at `moment`.
    #[inline(always)]
    pub fn start(ray: Ray, moment: Moment) -> Self {
        FullPath {
            ray,
            moment,
            radiance: Color::ZERO,
            throughput: Color::ONE,
            rays: 1,
        }
    }

    /// Takes the hit of the segment traced last (`None`: it escaped) and returns the next
    /// segment to trace (the ray, where along it hits count, and the tree's hints), or
    /// `None` when the path has ended and `radiance` is its value.
    #[inline(always)]
    pub fn advance(
        &mut self,
        scene: &Scene,
        hit: Option<Hit>,
        rng: &mut Sampler,
    ) -> Option<(Ray, Interval, RayHints)> {
        let raw = self.scatter(scene, hit.as_ref(), rng)?;
        // `scatter` goes on only from a hit.
        let here = hit?;
        Some(self.leave(scene, &here, raw))
    }

    /// `advance`'s first half: takes the hit, adds what it emits and scatters there; the
    /// (not necessarily unit) direction the path goes on in, or `None` when it has ended.
    /// Every random number a segment needs is drawn here.
    #[inline(always)]
    pub fn scatter(&mut self, scene: &Scene, hit: Option<&Hit>, rng: &mut Sampler) -> Option<Vec3> {
        let Some(here) = hit else {
            self.radiance += self.throughput * scene.background.radiance(self.ray.dir);
            return None;
        };
        let material = scene.material(here);
        let texture = scene.texture_at(here, self.moment.time);
        let tint = |c: Color| texture.map_or(c, |t| c * t);
        self.radiance += self.throughput * tint(material.emitted());
        let settings = &scene.settings;
        let scatter = material.scatter(self.ray.dir, here, settings.diffuse, rng)?;
        if self.rays >= settings.max_depth {
            return None;
        }
        self.throughput *= tint(scatter.attenuation);
        if scene.has_media() {
            self.moment.medium_key = rng.word();
        }
        Some(scatter.dir)
    }

    /// `advance`'s second half: the segment leaving `here` along `raw` (what `scatter`
    /// returned), which becomes the ray traced last.
    #[inline(always)]
    pub fn leave(&mut self, scene: &Scene, here: &Hit, raw: Vec3) -> (Ray, Interval, RayHints) {
        let (next, interval, hints) = bounce::<true>(scene, here, raw);
        self.ray = next;
        self.rays += 1;
        (next, interval, hints)
    }

    /// What the path has brought back so far: all of it once `advance` says it has ended.
    #[inline(always)]
    pub fn radiance(&self) -> Radiance {
        Radiance {
            color: self.radiance,
            rays: self.rays,
        }
    }
}

/// The furthest a bounce ray's first hit may be ignored, in units of the clearance it needs
/// (see `bounce`): rays that would need more (within 3.6° of the surface) start off the
/// surface along the normal instead.
const MAX_SKIP: f32 = 16.0;

/// The segment that leaves `here` along the scattered direction `raw` (not necessarily
/// unit): the ray, the distances along it where hits count, and what the tree may use to
/// trace it sooner (`RayHints`). `ANY_KIND`: `here` may be any primitive (else it is a still
/// sphere, as all a first book's scene holds).
#[inline(always)]
pub fn bounce<const ANY_KIND: bool>(
    scene: &Scene,
    here: &Hit,
    raw: Vec3,
) -> (Ray, Interval, RayHints) {
    // `raw / len` is what `normalize` computes; the side and the hints come from `raw` (a
    // positive scale of `dir`), so they are ready before `dir` is.
    let len = raw.length();
    let dir = raw / len;
    let raw_normal = raw.dot(here.normal);
    let along_normal = raw_normal >= 0.0;
    let side = if along_normal {
        here.normal
    } else {
        -here.normal
    };
    // Shadow acne (§8.4): the hit point is rounded, perhaps to the far side of the surface,
    // where the new ray would meet it again at once.
    let (clearance, origin, interval) = match scene.settings.surface_offset {
        SurfaceOffset::Auto => {
            // The book's cure, sized to the rounding: the ray starts at the hit point, on
            // its own line, and ignores hits until it is a bound on that rounding off the
            // surface. (Starting off the surface along the normal instead moves the ray
            // sideways, which bends it at the next curved surface: through glass by up to a
            // pixel for 0.001 on a sphere of radius 0.5.) A ray nearly along the surface
            // would ignore too much of its way: it starts that bound off along the normal.
            let clearance = if ANY_KIND {
                scene.leaving(here, along_normal).0
            } else {
                scene.still_sphere_offset(here)
            };
            let across = raw_normal.abs();
            // |cos θ| ≥ 1 / MAX_SKIP, without a square root.
            if across * across * (MAX_SKIP * MAX_SKIP) >= raw.length_squared() {
                // clearance / |cos θ|, the division beside the square root of `len`.
                let skip = (clearance / across) * len;
                (clearance, here.p, Interval::new(skip, f32::INFINITY))
            } else {
                (clearance, here.p + clearance * side, ANY_DISTANCE)
            }
        }
        // A start off the surface along the normal (without the book's t_min cut-off,
        // which loses real hits).
        SurfaceOffset::Fixed(d) => (d, here.p + d * side, ANY_DISTANCE),
    };
    let leaves = if ANY_KIND {
        scene.leaving(here, along_normal).1
    } else {
        here.leaves_outside(along_normal)
    };
    let hints = RayHints {
        // A ray that leaves a sphere from outside (or a quad either way) cannot meet it
        // again.
        leaving: Leaving::sphere_if((clearance > 0.0) & leaves, here.primitive),
        // From the raw direction, a division sooner than `1 / dir`.
        inv_dir: Some(len * (Vec3::ONE / raw)),
        heading: Some(raw),
    };
    (Ray::new(origin, dir), interval, hints)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::SampleRange;
    use crate::math::PixelRect;
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
            let (next, interval, hints) = bounce::<false>(&scene, &here, raw);
            let plain = scene.hit(&next, interval, &mut stack);
            let hinted = scene.hit_with(&next, interval, &mut stack, hints);
            let key = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.primitive));
            assert_eq!(key(hinted), key(plain), "{next:?} {hints:?}");
            bounces += 1;
            skipped += usize::from(hints.leaving.is_some());
        }
        assert!(bounces > 15_000 && skipped > 5_000, "{bounces} {skipped}");
    }

    /// Sixteen paths of 65,536 bounces each (a box of white fog, the camera inside) hand out
    /// no sample for 65,536 rounds: the batch looks at its stop flag every `STOP_RAYS` rays
    /// all the same. It once looked only when a lane took a new sample, every 4,096 of
    /// them: a minute of such paths between looks.
    #[test]
    fn a_batch_of_endless_paths_looks_at_its_stop_flag_every_stop_rays() {
        let text = "[image]\nwidth = 1\nheight = 1\nsamples_per_pixel = 16\nmax_depth = 65536\n\
                    [camera]\nlookfrom = [278.0, 278.0, 200.0]\nlookat = [278.0, 278.0, 555.0]\n\
                    vfov_deg = 40.0\n\
                    [materials.w]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n\
                    [materials.fog]\ntype = \"isotropic\"\nalbedo = [1.0, 1.0, 1.0]\n\
                    [[quads]]\ncorner = [0.0, 0.0, 555.0]\nu = [555.0, 0.0, 0.0]\n\
                    v = [0.0, 555.0, 0.0]\nmaterial = \"w\"\n\
                    [[media]]\ndensity = 1000.0\nmaterial = \"fog\"\n\
                    box = { min = [0.0, 0.0, 0.0], max = [555.0, 555.0, 555.0] }\n";
        let scene = Scene::parse(text, Path::new("fog.toml"), &Overrides::default()).unwrap();
        assert!(scene.batches_paths());
        let looks = std::cell::Cell::new(0u64);
        let mut rays = 0u64;
        let tile = PixelRect::full(1, 1);
        let range = SampleRange { start: 0, end: 16 };
        let stopped = || {
            looks.set(looks.get() + 1);
            false
        };
        let done = trace_tile(
            crate::simd::Portable,
            &scene,
            &tile,
            range,
            stopped,
            16,
            |_, _, r| rays += u64::from(r),
        );
        assert!(done);
        assert_eq!(rays, 16 * 65_536, "every path is max_depth long");
        assert!(
            looks.get() >= rays / STOP_RAYS,
            "{} looks for {rays} rays",
            looks.get()
        );
    }

    /// A scene of one glass sphere with the default surface offset.
    fn one_sphere(center: Vec3, radius: f32) -> Scene {
        let text = format!(
            "[image]\nwidth = 10\nheight = 10\nsamples_per_pixel = 1\nmax_depth = 5\n\
             [materials.glass]\ntype = \"dielectric\"\nir = 1.5\n\
             [[spheres]]\ncenter = [{}, {}, {}]\nradius = {radius}\nmaterial = \"glass\"\n",
            center.x, center.y, center.z
        );
        Scene::parse(&text, Path::new("one.toml"), &Overrides::default()).unwrap()
    }

    /// Whether the ray that `bounce` makes for `raw` at `here` starts on the side it leaves
    /// towards: one leaving the (convex) sphere's solid never meets it again; one going into
    /// it meets it from inside, and not right where it started.
    fn starts_on_its_side(
        scene: &Scene,
        here: &Hit,
        raw: Vec3,
        stack: &mut TraversalStack,
    ) -> (bool, Option<Hit>) {
        let (next, interval, _) = bounce::<false>(scene, here, raw);
        let inside = !here.leaves_outside(raw.dot(here.normal) >= 0.0);
        let radius = scene.spheres()[0].radius.abs();
        let again = scene.hit(&next, interval, stack);
        let ok = match again {
            None => !inside,
            Some(h) => inside && !h.normal_points_out && h.t > 1e-3 * radius,
        };
        (ok, again)
    }

    #[test]
    fn bounce_rays_start_on_the_side_they_leave_towards() {
        // The surface offset is a bound on the hit's rounding (`Sphere::escape_offset`): at
        // a quarter of it 4 of these bounces started on the wrong side, at an eighth one in
        // a hundred. Spheres small and large, near and far from the origin, hit from up to
        // 50 radii away, grazing included; bounces both ways, and once more from inside.
        let mut rng = Sampler::from_seed(5);
        for (center, radius) in [
            (Vec3::ZERO, 0.5),
            (Vec3::new(3.0, -4.0, 1.5), 0.5),
            (Vec3::new(3.0, -4.0, 1.5), -0.45),
            (Vec3::new(30.0, -40.0, 15.0), 0.2),
            (Vec3::new(0.0, -1000.0, 0.0), 1000.0),
            (Vec3::new(60.0, -80.0, 30.0), 100.0),
            (Vec3::new(600.0, -800.0, 300.0), 0.5),
            (Vec3::ZERO, 0.01),
            (Vec3::new(0.6, -0.8, 0.3), 1e-3),
            (Vec3::new(1800.0, -2400.0, 900.0), 2.0),
        ] {
            let scene = one_sphere(center, radius);
            let s = scene.spheres()[0];
            let mut stack = scene.new_stack();
            let (mut bounces, mut wrong) = (0, 0);
            for _ in 0..20_000 {
                let from = s.center + s.radius.abs() * rng.range(1.01, 50.0) * rng.unit_vector();
                let aim = s.center + s.radius.abs() * rng.uniform() * rng.unit_vector();
                let ray = Ray::new(from, (aim - from).normalize());
                let Some(here) = scene.hit(&ray, ANY_DISTANCE, &mut stack) else {
                    continue;
                };
                for _ in 0..4 {
                    let raw = rng.range(0.2, 2.0) * rng.unit_vector();
                    let (ok, again) = starts_on_its_side(&scene, &here, raw, &mut stack);
                    bounces += 1;
                    wrong += usize::from(!ok);
                    if let (true, Some(inner)) = (ok, again) {
                        let raw = rng.unit_vector();
                        let (ok, _) = starts_on_its_side(&scene, &inner, raw, &mut stack);
                        bounces += 1;
                        wrong += usize::from(!ok);
                    }
                }
            }
            assert!(bounces > 80_000, "{bounces}");
            assert_eq!(
                wrong, 0,
                "sphere {center} radius {radius}: {wrong} of {bounces} bounces"
            );
        }
    }

    #[test]
    fn bounce_rays_start_on_their_own_line_unless_nearly_along_the_surface() {
        // A start moved sideways bends a ray at the next curved surface; `Auto` starts it at
        // the hit point and ignores hits until it is the clearance off the surface, except
        // within 3.6° of the surface (cos < 1 / MAX_SKIP), where it starts off the surface.
        let scene = one_sphere(Vec3::new(5.0, 1.5, 1.2), 0.6);
        let mut rng = Sampler::from_seed(9);
        let mut stack = scene.new_stack();
        let (mut along, mut grazing) = (0, 0);
        for _ in 0..20_000 {
            let from = Vec3::new(13.0, 2.0, 3.0);
            let aim = Vec3::new(5.0, 1.5, 1.2) + 0.6 * rng.uniform() * rng.unit_vector();
            let ray = Ray::new(from, (aim - from).normalize());
            let Some(here) = scene.hit(&ray, ANY_DISTANCE, &mut stack) else {
                continue;
            };
            let raw = rng.range(0.2, 2.0) * rng.unit_vector();
            let (next, interval, _) = bounce::<false>(&scene, &here, raw);
            let clearance = scene.spheres()[0].escape_offset(here.t);
            let cos = next.dir.dot(here.normal).abs();
            if cos * MAX_SKIP >= 1.0 {
                assert_eq!(next.origin, here.p);
                // Hits count from where the ray is the clearance off the surface.
                let off = interval.min * cos;
                assert!(
                    (off - clearance).abs() <= 1e-5 * clearance,
                    "{off} {clearance}"
                );
                along += 1;
            } else {
                assert_eq!(interval.min, 0.0);
                let moved = next.origin - here.p;
                // Up to the rounding of `here.p + clearance · side` (8% of it here).
                assert!(moved.dot(here.normal).abs() >= 0.9 * clearance, "{moved}");
                grazing += 1;
            }
        }
        assert!(along > 10_000 && grazing > 0, "{along} {grazing}");
    }
}
