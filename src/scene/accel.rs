//! The scene's primitives by kind, and the accelerator that finds a ray's closest hit among
//! them: a hierarchy per kind (`bvh::Bvh` over each kind's bounds, with that kind's SIMD
//! pack in its leaves), chosen by what the scene holds.

use crate::bvh::{
    BATCH, Bvh, Candidates, MediumPack, Moment, MovingSpherePack, MultiWalk, QuadBatch, QuadPack,
    RayBatch, RayHints, SphereBvh, TraversalStack, media_hit,
};
use crate::geometry::{Medium, MovingSphere, PrimitiveId, Quad, Sphere};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use crate::simd::Isa;

/// The scene's primitives, each kind in the order the scene lists it: a primitive's id is
/// its kind's first id plus its index here (`PrimitiveId`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Primitives {
    pub spheres: Vec<Sphere>,
    pub moving_spheres: Vec<MovingSphere>,
    pub quads: Vec<Quad>,
    pub media: Vec<Medium>,
}

impl Primitives {
    pub fn len(&self) -> usize {
        self.spheres.len() + self.moving_spheres.len() + self.quads.len() + self.media.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// True when every primitive is a still sphere (the first book's scenes).
    pub fn only_still_spheres(&self) -> bool {
        self.moving_spheres.is_empty() && self.quads.is_empty() && self.media.is_empty()
    }
}

/// How the accelerator is shaped, picked by what the scene holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcceleratorChoice {
    /// Still spheres only, the first book's scenes: one tree of sphere packs, whose giant
    /// spheres (the ground) are tested on their own and which, when the spheres lie in a
    /// thin layer (the cover), has the layer grid's shortcut; camera rays are tested against
    /// each tile's few candidate spheres where there are few. Its constants (pack and grid
    /// sizes) were tuned on the cover's 486 spheres.
    StillSpheres,
    /// Any primitives: one tree per kind present (still spheres, moving spheres, quads,
    /// media), each walked in turn with the closest hit so far as its bound, without the
    /// layer grid.
    PerKind,
    /// A few quads (at most `QuadBatch::MAX`) and any media, nothing else (the Cornell
    /// box): the trees of `PerKind` for a ray alone, and paths traced sixteen at a time, each
    /// segment's sixteen rays tested against every quad at once (`QuadBatch`), then against
    /// each medium.
    FewQuads,
}

/// Bits of `Accelerator::present`: which kinds the scene holds.
const QUADS: u8 = 1;
const SPHERES: u8 = 2;
const MOVING: u8 = 4;
const MEDIA: u8 = 8;

/// The trees of every kind.
#[derive(Clone, Debug)]
pub(super) struct Accelerator {
    choice: AcceleratorChoice,
    /// The kinds present, one bit each: a ray skips the others without looking at them.
    present: u8,
    spheres: SphereBvh,
    moving: Bvh<MovingSpherePack>,
    quads: Bvh<QuadPack>,
    media: Bvh<MediumPack>,
    /// For `FewQuads`, the quads as a batch of rays tests them.
    quad_batch: QuadBatch,
}

impl Accelerator {
    pub(super) fn build(prims: &Primitives) -> Self {
        let bit = |has: bool, b: u8| if has { b } else { 0 };
        let few_quads = prims.spheres.is_empty()
            && prims.moving_spheres.is_empty()
            && (1..=QuadBatch::MAX).contains(&prims.quads.len());
        let choice = if prims.only_still_spheres() {
            AcceleratorChoice::StillSpheres
        } else if few_quads {
            AcceleratorChoice::FewQuads
        } else {
            AcceleratorChoice::PerKind
        };
        Self {
            choice,
            present: bit(!prims.quads.is_empty(), QUADS)
                | bit(!prims.spheres.is_empty(), SPHERES)
                | bit(!prims.moving_spheres.is_empty(), MOVING)
                | bit(!prims.media.is_empty(), MEDIA),
            // The layer grid is the cover's shape: a scene of still spheres only.
            spheres: match choice {
                AcceleratorChoice::StillSpheres => SphereBvh::build(&prims.spheres),
                _ => SphereBvh::build_plain(&prims.spheres),
            },
            moving: Bvh::build_plain(&prims.moving_spheres),
            quads: Bvh::build_plain(&prims.quads),
            media: Bvh::build_plain(&prims.media),
            quad_batch: match choice {
                AcceleratorChoice::FewQuads => QuadBatch::new(&prims.quads),
                _ => QuadBatch::default(),
            },
        }
    }

    pub(super) fn choice(&self) -> AcceleratorChoice {
        self.choice
    }

    /// Scratch space deep enough for every tree.
    pub(super) fn new_stack(&self) -> TraversalStack {
        let needs = [
            self.spheres.stack_need(),
            self.moving.stack_need(),
            self.quads.stack_need(),
            self.media.stack_need(),
        ];
        TraversalStack::with_entries(needs.into_iter().max().unwrap_or(1))
    }

    /// The still spheres' closest hit (the whole answer for `StillSpheres`).
    #[inline(always)]
    pub(super) fn hit_spheres<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<(f32, PrimitiveId)> {
        self.spheres.intersect_on(isa, ray, interval, stack, hints)
    }

    /// The closest hit of every kind at `moment`: each tree in turn, bounded by the best so
    /// far (the answer does not depend on the order: ties go to the lower id).
    #[inline(always)]
    pub(super) fn hit_all<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        moment: Moment,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<(f32, PrimitiveId)> {
        let present = self.present;
        let mut walk = MultiWalk::new(isa, ray, moment, interval, hints);
        if present & QUADS != 0 {
            walk.through(&self.quads, stack);
        }
        if present & SPHERES != 0 {
            walk.through(&self.spheres, stack);
        }
        if present & MOVING != 0 {
            walk.through(&self.moving, stack);
        }
        if present & MEDIA != 0 {
            walk.through(&self.media, stack);
        }
        walk.result()
    }

    /// See `Scene::candidates`: only for still spheres.
    pub(super) fn candidates(
        &self,
        spheres: &[Sphere],
        keep_box: impl Fn(Vec3, Vec3) -> bool,
        keep: impl Fn(&Sphere) -> bool,
    ) -> Option<Candidates> {
        match self.choice {
            AcceleratorChoice::StillSpheres => self.spheres.candidates(spheres, keep_box, keep),
            AcceleratorChoice::PerKind | AcceleratorChoice::FewQuads => None,
        }
    }

    #[inline(always)]
    pub(super) fn hit_candidates<I: Isa>(
        &self,
        isa: I,
        candidates: &Candidates,
        ray: &Ray,
        interval: Interval,
    ) -> Option<(f32, PrimitiveId)> {
        self.spheres
            .intersect_candidates(isa, candidates, ray, interval)
    }
}

impl Accelerator {
    /// For `FewQuads`: each lane's closest hit of `rays` (`rays_alone` the same rays, and
    /// `moments` their moments; lanes of `active` only), as `hit_all` finds it for each
    /// ray: its parameter and id, or `NO_HIT`.
    #[inline(always)]
    pub(super) fn hit_batch<I: Isa>(
        &self,
        isa: I,
        rays: &RayBatch,
        rays_alone: &[Ray; BATCH],
        moments: &[Moment; BATCH],
        active: u32,
        media: &[Medium],
    ) -> ([f32; BATCH], [u32; BATCH]) {
        let (mut closest, mut found) = self.quad_batch.intersect(isa, rays);
        if !media.is_empty() {
            let mut lanes = active;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize & (BATCH - 1);
                lanes &= lanes - 1;
                let m = moments[lane];
                media_hit(
                    media,
                    &rays_alone[lane],
                    m.time,
                    m.medium_key,
                    rays.t_min(lane),
                    &mut closest[lane],
                    &mut found[lane],
                );
            }
        }
        (closest, found)
    }
}
