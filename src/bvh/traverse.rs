//! One ray's walk through the hierarchy: node by node, leaves as soon as their parent is
//! tested, inner children nearest first; or, for a small tree on a path with sixteen-lane box
//! tests, every pack's box at once, then the packs hit. The giants come last either way.

use super::pack::{beats, hit_of, lowest_lane, lowest_of, splat3};
use super::{
    Bvh, FLAT_GROUP, FLAT_MAX_GROUPS, LEAF, Leaf, Moment, NO_HIT, PackRay, Query, RayHints,
};
use crate::geometry::PrimitiveId;
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use crate::simd::{Ids, Isa, Lanes, SlabLanes, SlabRay, slab8};

impl<P: Leaf> Bvh<P> {
    /// The pack of the leaf child reference `child`.
    #[inline(always)]
    pub(super) fn leaf_pack(&self, child: u32) -> &P {
        &self.packs[(child & !LEAF) as usize]
    }
}

/// One ray's walk through the hierarchy, advanced a node at a time by `step`, or over every
/// pack of a small tree at once by `flat`.
pub(super) struct Traversal<I: Isa> {
    /// The ray as the box tests take it, over the whole interval: the tree walk bounds
    /// each test by the closest hit so far, the flat walk checks that after its tests.
    slab: SlabRay,
    /// Its origin, `1 / direction` and `t_min` in lanes, for the eight-lane box tests (and
    /// the origin and `t_min` for the sphere tests).
    lanes: SlabLanes<I>,
    d: [Lanes<I>; 3],
    /// The id of a primitive the ray cannot hit (`RayHints::leaving`), or `NO_SPHERE`: in
    /// lanes for the packs, and as it is for the giants.
    skip: Ids<I>,
    skip_id: u32,
    closest: f32,
    found: u32,
    /// The node to visit next.
    current: u32,
    /// Entries of the caller's stack in use.
    top: usize,
}

impl<I: Isa> Traversal<I> {
    /// Starts a walk, with no hit yet and the root as the first node.
    #[inline(always)]
    pub(super) fn new(isa: I, ray: &Ray, interval: Interval, hints: RayHints) -> Self {
        // Clamped so a zero direction component gives a huge finite slope, never the
        // 0 · ∞ = NaN of a box face through the origin.
        let inv = hints.inv_dir.unwrap_or_else(|| Vec3::ONE / ray.dir);
        let inv = inv.clamp(Vec3::splat(-1e30), Vec3::splat(1e30));
        let slab = SlabRay {
            origin: ray.origin.to_array(),
            inv_dir: inv.to_array(),
            t_min: interval.min,
            t_max: interval.max,
        };
        Traversal {
            slab,
            lanes: slab.lanes(isa),
            d: splat3(isa, ray.dir),
            skip: Ids::splat(isa, hints.leaving.id()),
            skip_id: hints.leaving.id(),
            closest: interval.max,
            found: NO_HIT,
            current: 0,
            top: 0,
        }
    }

    /// Readies the walk for another hierarchy, keeping the closest hit so far.
    #[inline(always)]
    pub(super) fn restart(&mut self) {
        self.current = 0;
        self.top = 0;
    }

    /// Tests the giants, after the rest: keeps a giant's hit when it `beats` the closest so
    /// far, as the packs do. Last, so the walk's first box tests wait on no
    /// square root and division of theirs, and the ground's early exits stay off the walk's
    /// chain. The ground never hides a box in the book's scenes (their boxes stand on it),
    /// so testing it first pruned nothing there.
    #[inline(always)]
    pub(super) fn test_giants<P: Leaf>(&mut self, bvh: &Bvh<P>, ray: &Ray, moment: Moment) {
        let interval = Interval::new(self.slab.t_min, self.slab.t_max);
        for (item, id) in &bvh.giants {
            // A bounce ray leaving the ground starts on it: its test would not end at the
            // first check (which needs the start outside) and cost a square root.
            if *id == self.skip_id {
                continue;
            }
            if let Some(t) = P::intersect_one(item, *id, ray, moment, interval)
                && beats(t, *id, self.closest, self.found)
            {
                self.closest = t;
                self.found = *id;
            }
        }
    }

    pub(super) fn result(&self) -> Option<(f32, PrimitiveId)> {
        hit_of(self.closest, self.found)
    }

    /// Tests the primitives of `pack`, keeping a hit that beats the closest so far.
    #[inline(always)]
    pub(super) fn test_pack<P: Leaf>(&mut self, pack: &P, at: Query<'_>) {
        let ray = PackRay {
            o: &self.lanes.origin,
            d: &self.d,
            t_min: self.lanes.t_min,
            skip: self.skip,
            ray: at.ray,
            t_min_scalar: self.slab.t_min,
            moment: at.moment,
        };
        pack.intersect(&ray, &mut self.closest, &mut self.found);
    }

    /// The walk of a flat tree (see `FLAT_MAX_PACKS`): every group of pack boxes tested
    /// first (independent tests, which overlap), then the packs whose boxes the ray meets,
    /// in order, each unless the closest hit so far is nearer than its box.
    ///
    /// The box tests take the whole interval, not the closest hit so far, so they wait on
    /// no sphere test and start as soon as the ray is known.
    #[inline(always)]
    pub(super) fn flat<P: Leaf>(&mut self, bvh: &Bvh<P>, at: Query<'_>) {
        let isa = self.lanes.t_min.isa();
        let groups = &bvh.flat[..bvh.flat.len().min(FLAT_MAX_GROUPS)];
        let slab = self.slab;
        let mut hits = [0u32; FLAT_MAX_GROUPS];
        let mut t_near = [[0.0f32; FLAT_GROUP]; FLAT_MAX_GROUPS];
        for (g, boxes) in groups.iter().enumerate() {
            let (meets, near) = isa.slab16(&boxes.planes, &slab);
            hits[g] = meets & boxes.mask;
            t_near[g] = near;
        }
        if P::OVERLAP {
            let (start, found) = (self.closest, self.found);
            let mut best = (start, found);
            for g in 0..groups.len() {
                let mut packs = hits[g];
                while packs != 0 {
                    let lane = lowest_of::<FLAT_GROUP>(packs);
                    packs &= packs - 1;
                    if t_near[g][lane] <= start {
                        let hit =
                            self.pack_hit(&bvh.packs[g * FLAT_GROUP + lane], at, start, found);
                        if beats(hit.0, hit.1, best.0, best.1) {
                            best = hit;
                        }
                    }
                }
            }
            (self.closest, self.found) = best;
            return;
        }
        for g in 0..groups.len() {
            let mut packs = hits[g];
            while packs != 0 {
                let lane = lowest_of::<FLAT_GROUP>(packs);
                packs &= packs - 1;
                if t_near[g][lane] <= self.closest {
                    self.test_pack(&bvh.packs[g * FLAT_GROUP + lane], at);
                }
            }
        }
    }

    /// The best hit of `pack` against `(closest, found)` alone, not the walk's.
    #[inline(always)]
    fn pack_hit<P: Leaf>(&self, pack: &P, at: Query<'_>, closest: f32, found: u32) -> (f32, u32) {
        let ray = PackRay {
            o: &self.lanes.origin,
            d: &self.d,
            t_min: self.lanes.t_min,
            skip: self.skip,
            ray: at.ray,
            t_min_scalar: self.slab.t_min,
            moment: at.moment,
        };
        let (mut c, mut f) = (closest, found);
        pack.intersect(&ray, &mut c, &mut f);
        (c, f)
    }

    /// Visits the current node: tests its leaf children's spheres at once and picks the
    /// next inner node. True when the walk is over.
    #[inline(always)]
    pub(super) fn step<P: Leaf>(
        &mut self,
        bvh: &Bvh<P>,
        stack: &mut [(u32, f32)],
        at: Query<'_>,
    ) -> bool {
        let node = &bvh.nodes[self.current as usize];
        let (mut hits, t_near) = slab8(node.planes.each_ref(), &self.lanes, self.closest);
        // Leaves first, as soon as their parent is tested: a pack test costs the same
        // whatever `closest` is, so their order does not matter, only that their boxes are
        // not already behind the closest hit.
        let mut leaves = hits & node.leaf_mask;
        if P::OVERLAP {
            let (start, found) = (self.closest, self.found);
            let mut best = (start, found);
            while leaves != 0 {
                let lane = lowest_lane(leaves);
                leaves &= leaves - 1;
                if t_near[lane] <= start {
                    let hit = self.pack_hit(bvh.leaf_pack(node.child[lane]), at, start, found);
                    if beats(hit.0, hit.1, best.0, best.1) {
                        best = hit;
                    }
                }
            }
            (self.closest, self.found) = best;
        }
        while leaves != 0 {
            let lane = lowest_lane(leaves);
            leaves &= leaves - 1;
            if t_near[lane] <= self.closest {
                self.test_pack(bvh.leaf_pack(node.child[lane]), at);
            }
        }
        hits &= node.inner_mask;
        // One inner child (the common case): descend without touching the stack.
        if hits != 0 && hits & (hits - 1) == 0 {
            let lane = lowest_lane(hits);
            if t_near[lane] <= self.closest {
                self.current = node.child[lane];
                return false;
            }
            hits = 0;
        }
        // Several: onto the stack, sorted so the nearest is on top. Only inner nodes go on
        // the stack.
        let base = self.top;
        while hits != 0 {
            let lane = lowest_lane(hits);
            hits &= hits - 1;
            let entry = (node.child[lane], t_near[lane]);
            let mut i = self.top;
            while i > base && stack[i - 1].1 < entry.1 {
                stack[i] = stack[i - 1];
                i -= 1;
            }
            stack[i] = entry;
            self.top += 1;
        }
        // Next: the nearest stacked node the closest hit has not ruled out.
        while self.top > 0 {
            self.top -= 1;
            let (child, t_enter) = stack[self.top];
            if t_enter <= self.closest {
                self.current = child;
                return false;
            }
        }
        true
    }
}
