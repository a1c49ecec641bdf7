//! Evaluating a pixel's samples, pbrt's `EvaluatePixelSample`: where each sample falls on the
//! film, its camera ray, and the radiance the scene's shading mode gives it. The one place a
//! sample is made, and the only code that knows shading modes.

use super::{ANY_DISTANCE, Radiance, path_trace_from, path_trace_full};
use crate::bvh::{Candidates, Moment, RayHints, TraversalStack};
use crate::geometry::Hit;
use crate::job::SampleRange;
use crate::material::Material;
use crate::math::{Color, PixelRect};
use crate::ray::Ray;
use crate::sampling::{PixelSeed, Sampler};
use crate::scene::{Scene, Shading};
use crate::simd::Isa;

/// One camera sample: where it falls on the film (the book's `u`, `v`), its camera ray, and
/// its generator after the draws that made them. (Its ray's `Moment` goes beside it, for
/// the scenes that have one.)
#[derive(Clone, Debug)]
pub(super) struct CameraSample {
    u: f32,
    v: f32,
    pub(super) ray: Ray,
    pub(super) rng: Sampler,
}

impl CameraSample {
    /// The sample of pixel `(x, y)` (top row `y = 0`) drawn from the sample's own generator
    /// `rng`: jitter within the pixel, then the lens, then (`FULL`, for *The Next Week*'s
    /// scenes) the time when the shutter is open a while and the medium key when the scene
    /// has media.
    #[inline(always)]
    pub(super) fn new<const FULL: bool>(
        scene: &Scene,
        x: u32,
        y: u32,
        mut rng: Sampler,
    ) -> (Self, Moment) {
        let s = &scene.settings;
        let (du, dv) = if s.jitter {
            (rng.uniform(), rng.uniform())
        } else {
            (0.0, 0.0)
        };
        // The book's mapping, v counted up from the bottom row.
        let j = s.height - 1 - y;
        let (u, v) = film_point(scene, x as f32 + du, j as f32 + dv);
        let ray = scene.camera.ray(u, v, &mut rng);
        let moment = if FULL {
            let time = scene.camera.time(&mut rng);
            let medium_key = if scene.has_media() { rng.word() } else { 0 };
            Moment { time, medium_key }
        } else {
            Moment::default()
        };
        (CameraSample { u, v, ray, rng }, moment)
    }
}

/// The book's film coordinates `(u, v)` of the point `i` pixels from the left and `j` rows up
/// from the bottom row: `u = i / (width - 1)`, `v = j / (height - 1)`.
#[inline]
fn film_point(scene: &Scene, i: f32, j: f32) -> (f32, f32) {
    let s = &scene.settings;
    // Multiplying by the reciprocal keeps the division (a constant of the scene) off each
    // sample's chain of dependent arithmetic.
    (
        i * (1.0 / (s.width.max(2) - 1) as f32),
        j * (1.0 / (s.height.max(2) - 1) as f32),
    )
}

/// The spheres, giants included, that any camera ray through the pixels `tile` might hit,
/// when they are few enough to test without the hierarchy: `Camera::bundle` bounds those rays,
/// the tree is walked skipping the boxes the bound misses.
pub fn tile_candidates(scene: &Scene, tile: &PixelRect) -> Option<Candidates> {
    // Jitter included, pixel (x, y) covers [x, x + 1) × [j, j + 1) of `film_point`, with
    // j = height - 1 - y counted from the bottom row.
    let height = scene.settings.height;
    let below = height.saturating_sub(tile.y0 + tile.height);
    let (u0, v0) = film_point(scene, tile.x0 as f32, below as f32);
    let (u1, v1) = film_point(
        scene,
        (tile.x0 + tile.width) as f32,
        (height - tile.y0) as f32,
    );
    let bundle = scene.camera.bundle((u0, u1), (v0, v1));
    scene.candidates(
        |min, max| bundle.may_hit_box(min, max),
        |sphere| bundle.may_hit(sphere.center, sphere.radius),
    )
}

/// How a shading mode turns a camera sample (with its first hit, when the mode traces camera
/// rays) into radiance, given scratch space.
trait Shade {
    fn shade(
        &self,
        s: CameraSample,
        moment: Moment,
        first: Option<Hit>,
        stack: &mut TraversalStack,
    ) -> Radiance;
}

/// A closure as a `Shade`, for the modes that run no SIMD code (see `PathTrace`).
struct Closure<F>(F);

impl<F: Fn(CameraSample, Moment, Option<Hit>) -> Radiance> Shade for Closure<F> {
    #[inline(always)]
    fn shade(
        &self,
        s: CameraSample,
        m: Moment,
        first: Option<Hit>,
        _: &mut TraversalStack,
    ) -> Radiance {
        (self.0)(s, m, first)
    }
}

fn closure<F: Fn(CameraSample, Moment, Option<Hit>) -> Radiance>(f: F) -> Closure<F> {
    Closure(f)
}

/// Path tracing, as a type rather than a closure: it runs the SIMD path's code, which must
/// be inlined into the function `simd::dispatch` compiled for that path, and only a function
/// (not a closure) can be marked to be inlined.
struct PathTrace<'a, I: Isa> {
    isa: I,
    scene: &'a Scene,
}

impl<I: Isa> Shade for PathTrace<'_, I> {
    #[inline(always)]
    fn shade(
        &self,
        s: CameraSample,
        _: Moment,
        first: Option<Hit>,
        stack: &mut TraversalStack,
    ) -> Radiance {
        let mut rng = s.rng;
        path_trace_from(self.isa, self.scene, s.ray, first, &mut rng, stack)
    }
}

/// *The Next Week*'s path tracing (see `PathTrace`).
struct FullPathTrace<'a, I: Isa> {
    isa: I,
    scene: &'a Scene,
}

impl<I: Isa> Shade for FullPathTrace<'_, I> {
    #[inline(always)]
    fn shade(
        &self,
        s: CameraSample,
        moment: Moment,
        first: Option<Hit>,
        stack: &mut TraversalStack,
    ) -> Radiance {
        let mut rng = s.rng;
        path_trace_full(self.isa, self.scene, s.ray, moment, first, &mut rng, stack)
    }
}

/// Evaluates the samples of pixels: one per worker and tile, reused from pixel to pixel, so
/// nothing is allocated per sample.
pub struct PixelEvaluator<'a, I: Isa> {
    /// The SIMD path of every ray test.
    isa: I,
    scene: &'a Scene,
    /// The spheres every camera ray may hit (see `tile_candidates`); `None`: the tree.
    candidates: Option<Candidates>,
    stack: TraversalStack,
    /// The scene needs *The Next Week*'s paths (`Scene::needs_full_paths`).
    full: bool,
}

impl<'a, I: Isa> PixelEvaluator<'a, I> {
    /// For the pixels of `tile`: camera rays are tested against the tile's candidates when
    /// the shading mode traces them and the candidates are few.
    pub fn for_tile(isa: I, scene: &'a Scene, tile: &PixelRect) -> Self {
        let traces = match scene.settings.shading {
            Shading::Uv | Shading::Gradient => false,
            Shading::Flat | Shading::Normals => true,
            Shading::Path => scene.settings.max_depth > 0,
        };
        let candidates = traces.then(|| tile_candidates(scene, tile)).flatten();
        Self::with_candidates(isa, scene, candidates)
    }

    /// With camera rays tested against `candidates`, which must hold every sphere they can
    /// hit; `None` traces them through the tree. Either gives the same hits.
    pub fn with_candidates(isa: I, scene: &'a Scene, candidates: Option<Candidates>) -> Self {
        Self {
            isa,
            scene,
            candidates,
            stack: scene.new_stack(),
            full: scene.needs_full_paths(),
        }
    }

    /// Evaluates samples `range` of pixel `(x, y)`, handing each one's radiance and the ray
    /// segments it traced to `add`, in sample order.
    #[inline(always)]
    pub fn evaluate(&mut self, x: u32, y: u32, range: SampleRange, add: impl FnMut(Color, u32)) {
        if self.full {
            self.evaluate_as::<true>(x, y, range, add);
        } else {
            self.evaluate_as::<false>(x, y, range, add);
        }
    }

    /// `evaluate` for the first book's scenes (`FULL` false) or any (true, which a scene
    /// that `needs_full_paths` must take).
    #[inline(always)]
    pub fn evaluate_as<const FULL: bool>(
        &mut self,
        x: u32,
        y: u32,
        range: SampleRange,
        add: impl FnMut(Color, u32),
    ) {
        let (isa, scene) = (self.isa, self.scene);
        let background = |ray: &Ray| scene.background.radiance(ray.dir);
        match scene.settings.shading {
            // Pixel coordinates as red and green (image 1); no rays.
            Shading::Uv => self.each_sample::<FULL>(
                x,
                y,
                range,
                false,
                add,
                closure(|s, _, _| Radiance {
                    color: Color::new(s.u, s.v, 0.25),
                    rays: 0,
                }),
            ),
            // The background seen through the camera (image 2).
            Shading::Gradient => self.each_sample::<FULL>(
                x,
                y,
                range,
                false,
                add,
                closure(|s, _, _| Radiance {
                    color: background(&s.ray),
                    rays: 1,
                }),
            ),
            // The surface's albedo where a ray hits (image 3).
            Shading::Flat => self.each_sample::<FULL>(
                x,
                y,
                range,
                true,
                add,
                closure(|s, moment, first| {
                    let color = match first {
                        Some(hit) => {
                            let own = match *scene.material(&hit) {
                                Material::Lambertian { albedo }
                                | Material::Metal { albedo, .. }
                                | Material::Isotropic { albedo } => albedo,
                                Material::DiffuseLight { emit } => emit,
                                Material::Dielectric { .. } => Color::ONE,
                            };
                            scene.texture_at(&hit, moment.time).map_or(own, |t| own * t)
                        }
                        None => background(&s.ray),
                    };
                    Radiance { color, rays: 1 }
                }),
            ),
            // `(n + 1) / 2` of the front-facing normal (images 4–6).
            Shading::Normals => self.each_sample::<FULL>(
                x,
                y,
                range,
                true,
                add,
                closure(|s, _, first| {
                    let color = match first {
                        Some(hit) => 0.5 * (hit.normal + Color::ONE),
                        None => background(&s.ray),
                    };
                    Radiance { color, rays: 1 }
                }),
            ),
            Shading::Path if scene.settings.max_depth == 0 => self.each_sample::<FULL>(
                x,
                y,
                range,
                false,
                add,
                closure(|_, _, _| Radiance {
                    color: Color::ZERO,
                    rays: 0,
                }),
            ),
            Shading::Path if FULL => {
                self.each_sample::<FULL>(x, y, range, true, add, FullPathTrace { isa, scene })
            }
            Shading::Path => {
                self.each_sample::<FULL>(x, y, range, true, add, PathTrace { isa, scene })
            }
        }
    }

    /// The one sample loop, for each shading mode `shade` (given the sample, its camera ray's
    /// first hit when `traces`, and scratch space).
    ///
    /// Software pipelining: the next sample's camera sample is made after this sample's first
    /// hit and before this sample is shaded. It depends on nothing the shading computes and has
    /// no branch of its own, so the processor works it out while a path waits on its long
    /// chains of arithmetic, and no mispredicted branch of the path can undo it.
    #[inline(always)]
    fn each_sample<const FULL: bool>(
        &mut self,
        x: u32,
        y: u32,
        range: SampleRange,
        traces: bool,
        mut add: impl FnMut(Color, u32),
        shade: impl Shade,
    ) {
        if range.is_empty() {
            return;
        }
        let scene = self.scene;
        let seed = PixelSeed::new(scene.settings.seed, x, y);
        let mut next = CameraSample::new::<FULL>(scene, x, y, seed.sample(range.start));
        for sample in range.start..range.end {
            let (current, moment) = next.clone();
            let first = if traces {
                self.camera_hit::<FULL>(&current.ray, moment)
            } else {
                None
            };
            if sample + 1 < range.end {
                next = CameraSample::new::<FULL>(scene, x, y, seed.sample(sample + 1));
            }
            let r = shade.shade(current, moment, first, &mut self.stack);
            add(r.color, r.rays);
        }
    }

    /// What camera ray `ray` hits first: among the candidates when there are some (the same
    /// answer as the tree), else through the tree.
    #[inline(always)]
    fn camera_hit<const FULL: bool>(&mut self, ray: &Ray, moment: Moment) -> Option<Hit> {
        if FULL {
            let hints = RayHints::default();
            return (self.scene).hit_at(
                self.isa,
                ray,
                moment,
                ANY_DISTANCE,
                &mut self.stack,
                hints,
            );
        }
        match &self.candidates {
            Some(candidates) => {
                (self.scene).hit_candidates(self.isa, candidates, ray, ANY_DISTANCE)
            }
            None => (self.scene).hit_still_on(
                self.isa,
                ray,
                ANY_DISTANCE,
                &mut self.stack,
                RayHints::default(),
            ),
        }
    }
}
