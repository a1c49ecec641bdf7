//! A ray's closest hit in the scene and what it learns there: the accelerator asked for one
//! ray (every kind, or the still spheres alone) or for a batch of rays, the hit record of
//! each kind of primitive, the clearance a ray leaving a hit needs, and the value there of
//! the texture that colours its material.

use super::{AcceleratorChoice, Scene};
use crate::bvh::{BATCH, Candidates, Moment, RayBatch, RayHints, TraversalStack};
use crate::geometry::{Hit, PrimitiveId, PrimitiveKind, Sphere};
use crate::math::{Color, Interval, Vec3, atan2};
use crate::ray::Ray;
use crate::simd::{Isa, Portable};
use crate::texture::Texture;

impl Scene {
    /// The closest hit along `ray` within `interval`, using `stack` as scratch space.
    #[inline]
    pub fn hit(&self, ray: &Ray, interval: Interval, stack: &mut TraversalStack) -> Option<Hit> {
        self.hit_with(ray, interval, stack, RayHints::default())
    }

    /// `hit` helped by what the caller knows of the ray (see `RayHints`); the same answer.
    #[inline]
    pub fn hit_with(
        &self,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        self.hit_on(Portable, ray, interval, stack, hints)
    }

    /// `hit_with` on the SIMD path of `isa`: the same answer on every path. Rays are taken
    /// at time 0 and media scatter by the key 0 (`hit_at` gives both).
    #[inline(always)]
    pub fn hit_on<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        if self.accel.choice() == AcceleratorChoice::StillSpheres {
            self.hit_still_on(isa, ray, interval, stack, hints)
        } else {
            self.hit_at(isa, ray, Moment::default(), interval, stack, hints)
        }
    }

    /// `hit_on` for a scene of still spheres only (`AcceleratorChoice::StillSpheres`: the
    /// first book's path takes it, so as not to ask at each hit).
    #[inline(always)]
    pub fn hit_still_on<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        self.accel
            .hit_spheres(isa, ray, interval, stack, hints)
            .map(|(t, id)| self.sphere_surface(ray, t, id))
    }

    /// The closest hit along `ray` taken at `moment` (its time, and its segment's random
    /// number for media), on the SIMD path of `isa`.
    #[inline(always)]
    pub fn hit_at<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        moment: Moment,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        self.accel
            .hit_all(isa, ray, moment, interval, stack, hints)
            .map(|(t, id)| self.surface(ray, moment, t, id))
    }

    /// True when paths are traced sixteen at a time, each segment's rays tested together
    /// (`AcceleratorChoice::FewQuads`): see `hit_batch`.
    pub fn batches_paths(&self) -> bool {
        self.accel.choice() == AcceleratorChoice::FewQuads
    }

    /// For a scene that `batches_paths`: the closest hit of each ray of `rays` (in the lanes
    /// of `active`; `alone`, the same rays one by one, taken at `moments`), as `hit_at` finds
    /// it for that ray alone: its parameter and primitive id (`bvh::NO_HIT` for none). Its
    /// hit record is `surface_of`'s.
    #[inline(always)]
    pub fn hit_batch<I: Isa>(
        &self,
        isa: I,
        rays: &RayBatch,
        alone: &[Ray; BATCH],
        moments: &[Moment; BATCH],
        active: u32,
    ) -> ([f32; BATCH], [u32; BATCH]) {
        (self.accel).hit_batch(isa, rays, alone, moments, active, &self.primitives.media)
    }

    /// The hit record of primitive `id` (`bvh::NO_HIT`: none) at `t` along `ray` taken at
    /// `moment`.
    #[inline(always)]
    pub fn surface_of(&self, ray: &Ray, moment: Moment, t: f32, id: u32) -> Option<Hit> {
        (id != crate::bvh::NO_HIT).then(|| self.surface(ray, moment, t, PrimitiveId(id)))
    }

    /// The spheres, giants included, that `keep` accepts, when they are few enough to test
    /// without the hierarchy (see `Bvh::candidates`; `keep_box` must accept every box
    /// holding a sphere `keep` would). Only scenes of still spheres have them.
    pub fn candidates(
        &self,
        keep_box: impl Fn(Vec3, Vec3) -> bool,
        keep: impl Fn(&Sphere) -> bool,
    ) -> Option<Candidates> {
        self.accel
            .candidates(&self.primitives.spheres, keep_box, keep)
    }

    /// The closest hit along a camera ray among the `candidates` picked for it: the same as
    /// `hit` (on the SIMD path of `isa`).
    #[inline(always)]
    pub fn hit_candidates<I: Isa>(
        &self,
        isa: I,
        candidates: &Candidates,
        ray: &Ray,
        interval: Interval,
    ) -> Option<Hit> {
        self.accel
            .hit_candidates(isa, candidates, ray, interval)
            .map(|(t, id)| self.sphere_surface(ray, t, id))
    }

    /// Scratch space for `hit`, sized for this scene.
    pub fn new_stack(&self) -> TraversalStack {
        self.accel.new_stack()
    }

    /// The hit record of still sphere `id` at `t` along `ray`.
    #[inline(always)]
    fn sphere_surface(&self, ray: &Ray, t: f32, id: PrimitiveId) -> Hit {
        // A still sphere's id is its index (`PrimitiveId::SPHERES` is 0).
        let sphere = &self.primitives.spheres[id.0 as usize];
        let p = ray.at(t);
        let outward = sphere.normal_at(p);
        let front_face = ray.dir.dot(outward) < 0.0;
        Hit {
            t,
            p,
            normal: if front_face { outward } else { -outward },
            front_face,
            // `outward` is (p - c)/r: out of the ball when r > 0; flipped on a back face.
            normal_points_out: (sphere.radius > 0.0) == front_face,
            material: sphere.material,
            primitive: id,
        }
    }

    /// The hit record of primitive `id` at `t` along `ray` taken at `moment`.
    #[inline(always)]
    fn surface(&self, ray: &Ray, moment: Moment, t: f32, id: PrimitiveId) -> Hit {
        let p = ray.at(t);
        let (outward, radius_sign, material) = match id.kind() {
            PrimitiveKind::Sphere => return self.sphere_surface(ray, t, id),
            PrimitiveKind::MovingSphere => {
                let s = &self.primitives.moving_spheres[id.index()];
                (s.normal_at(p, moment.time), s.radius > 0.0, s.material)
            }
            PrimitiveKind::Quad => {
                let q = &self.primitives.quads[id.index()];
                (q.normal, true, q.material)
            }
            PrimitiveKind::Medium => {
                // A scattering point inside a medium: no surface; the book's record.
                let m = &self.primitives.media[id.index()];
                return Hit {
                    t,
                    p,
                    normal: crate::geometry::SCATTER_NORMAL,
                    front_face: true,
                    normal_points_out: true,
                    material: m.material,
                    primitive: id,
                };
            }
        };
        let front_face = ray.dir.dot(outward) < 0.0;
        Hit {
            t,
            p,
            normal: if front_face { outward } else { -outward },
            front_face,
            normal_points_out: radius_sign == front_face,
            material,
            primitive: id,
        }
    }

    /// `escape_offset` of a hit on a still sphere (all a scene of still spheres has).
    #[inline(always)]
    pub fn still_sphere_offset(&self, hit: &Hit) -> f32 {
        self.primitives.spheres[hit.primitive.0 as usize].escape_offset(hit.t)
    }

    /// How far off the surface a ray leaving `hit` must start to clear the rounding of the
    /// hit (see `Sphere::escape_offset`); 0 inside a medium, where there is no surface.
    #[inline(always)]
    pub fn escape_offset(&self, hit: &Hit) -> f32 {
        let i = hit.primitive.index();
        match hit.primitive.kind() {
            PrimitiveKind::Sphere => self.primitives.spheres[i].escape_offset(hit.t),
            PrimitiveKind::MovingSphere => self.primitives.moving_spheres[i].escape_offset(hit.t),
            PrimitiveKind::Quad => self.primitives.quads[i].escape_offset(hit.t),
            PrimitiveKind::Medium => 0.0,
        }
    }

    /// True when no ray leaving `hit` to the side `side_is_normal` can meet the primitive
    /// hit again: off a sphere's outside (convex), and off a quad either way (flat).
    #[inline(always)]
    pub fn leaves_for_good(&self, hit: &Hit, side_is_normal: bool) -> bool {
        self.leaving(hit, side_is_normal).1
    }

    /// `escape_offset` and `leaves_for_good` at once, with one look at the hit's kind.
    #[inline(always)]
    pub fn leaving(&self, hit: &Hit, side_is_normal: bool) -> (f32, bool) {
        let i = hit.primitive.index();
        let outside = hit.leaves_outside(side_is_normal);
        match hit.primitive.kind() {
            PrimitiveKind::Sphere => (self.primitives.spheres[i].escape_offset(hit.t), outside),
            PrimitiveKind::MovingSphere => (
                self.primitives.moving_spheres[i].escape_offset(hit.t),
                outside,
            ),
            PrimitiveKind::Quad => (self.primitives.quads[i].escape_offset(hit.t), true),
            PrimitiveKind::Medium => (0.0, false),
        }
    }

    /// The texture coordinates of `hit` (the book's `get_sphere_uv` on spheres, the edge
    /// coordinates on quads; 0 in media), at `time` for a moving sphere.
    pub fn uv(&self, hit: &Hit, time: f32) -> (f32, f32) {
        let i = hit.primitive.index();
        let on_ball = |n: Vec3| {
            // theta from -y up, phi around y from -x: u = phi / 2π, v = theta / π.
            use std::f64::consts::PI;
            let (x, y, z) = (f64::from(n.x), f64::from(n.y), f64::from(n.z));
            let theta = atan2((1.0 - y * y).max(0.0).sqrt(), -y);
            let phi = atan2(-z, x) + PI;
            ((phi / (2.0 * PI)) as f32, (theta / PI) as f32)
        };
        match hit.primitive.kind() {
            PrimitiveKind::Sphere => {
                let s = &self.primitives.spheres[i];
                on_ball(((hit.p - s.center) / s.radius.abs()).clamp(-Vec3::ONE, Vec3::ONE))
            }
            PrimitiveKind::MovingSphere => {
                let s = &self.primitives.moving_spheres[i];
                let n = (hit.p - s.center(time)) / s.radius.abs();
                on_ball(n.clamp(-Vec3::ONE, Vec3::ONE))
            }
            PrimitiveKind::Quad => self.primitives.quads[i].uv(hit.p),
            PrimitiveKind::Medium => (0.0, 0.0),
        }
    }

    /// The value at `hit` of the texture that colours its material, if it has one.
    #[inline(always)]
    pub fn texture_at(&self, hit: &Hit, time: f32) -> Option<Color> {
        if !self.textured {
            return None;
        }
        self.texture_value(hit, time)
    }

    /// `texture_at` for a scene with textures.
    #[inline(never)]
    fn texture_value(&self, hit: &Hit, time: f32) -> Option<Color> {
        let id = self.material_textures[hit.material.0 as usize]?;
        let (u, v) = match self.textures[id.0 as usize] {
            // Only image textures read the coordinates.
            Texture::Image(_) | Texture::Checker { .. } => self.uv(hit, time),
            _ => (0.0, 0.0),
        };
        Some(Texture::value(&self.textures, id, u, v, hit.p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Sampler;
    use crate::scene::Overrides;
    use std::path::Path;

    #[test]
    fn leaving_outside_means_heading_away_from_the_centre_for_either_radius_sign() {
        // Figure 16's scene: solid spheres and a hollow one (negative radius) inside glass.
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/img-1.16-glass-hollow.toml"
        ));
        let scene = Scene::load(path, &Overrides::default()).unwrap();
        let mut rng = Sampler::from_seed(3);
        let mut stack = scene.new_stack();
        let mut seen = [[0usize; 2]; 2];
        let glass = Vec3::new(-1.0, 0.0, -1.0);
        for k in 0..20_000 {
            // Rays from the camera's side, and rays from within the glass shell and the
            // hollow, which meet the hollow sphere from both sides.
            let ray = if k % 2 == 0 {
                let origin = Vec3::new(rng.range(-2.0, 2.0), rng.range(-0.3, 1.0), 1.0);
                let target = Vec3::new(rng.range(-1.5, 1.5), rng.range(-0.5, 0.5), -1.0);
                Ray::new(origin, (target - origin).normalize())
            } else {
                let origin = glass + rng.range(0.0, 0.49) * rng.unit_vector();
                Ray::new(origin, rng.unit_vector())
            };
            let Some(hit) = scene.hit(&ray, Interval::new(1e-3, f32::INFINITY), &mut stack) else {
                continue;
            };
            let sphere = &scene.spheres()[hit.primitive.index()];
            for side_is_normal in [true, false] {
                let side = if side_is_normal {
                    hit.normal
                } else {
                    -hit.normal
                };
                let outside = side.dot(hit.p - sphere.center) > 0.0;
                assert_eq!(hit.leaves_outside(side_is_normal), outside, "{hit:?}");
                seen[usize::from(sphere.radius < 0.0)][usize::from(outside)] += 1;
            }
        }
        // Both radius signs met, each leaving both ways.
        assert!(seen.iter().flatten().all(|&n| n > 0), "{seen:?}");
    }
}
