//! One ray's walk through the hierarchy: the giants first, then node by node, leaves as soon
//! as their parent is tested, inner children nearest first.

use super::pack::SpherePack;
use super::pack::{hit_of, lowest_lane, splat3};
use super::{Bvh, LEAF, NO_HIT, NO_SPHERE, RayHints};
use crate::geometry::PrimitiveId;
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use crate::simd::{Ids, Isa, Lanes};

impl Bvh {
    /// The nearest giant hit in `interval`: its parameter and id, else `(interval.max,
    /// NO_HIT)`.
    #[inline(always)]
    pub(super) fn nearest_giant(&self, ray: &Ray, interval: Interval) -> (f32, u32) {
        let mut closest = interval.max;
        let mut found = NO_HIT;
        for (sphere, id) in &self.giants {
            if let Some(t) = sphere.intersect(ray, Interval::new(interval.min, closest)) {
                closest = t;
                found = *id;
            }
        }
        (closest, found)
    }

    /// The pack of the leaf child reference `child`.
    #[inline(always)]
    pub(super) fn leaf_pack(&self, child: u32) -> &SpherePack {
        &self.packs[(child & !LEAF) as usize]
    }
}

/// One ray's walk through the hierarchy, advanced a node at a time by `step`.
pub(super) struct Traversal<I: Isa> {
    o: [Lanes<I>; 3],
    d: [Lanes<I>; 3],
    inv: [Lanes<I>; 3],
    t_min: Lanes<I>,
    /// The id of a sphere the ray cannot hit (`RayHints::leaving`), or `NO_SPHERE`.
    skip: Ids<I>,
    closest: f32,
    found: u32,
    /// The node to visit next.
    current: u32,
    /// Entries of the caller's stack in use.
    top: usize,
}

impl<I: Isa> Traversal<I> {
    /// Starts a walk: tests the giant spheres, and sets up the root as the first node.
    #[inline(always)]
    pub(super) fn new(isa: I, bvh: &Bvh, ray: &Ray, interval: Interval, hints: RayHints) -> Self {
        let (closest, found) = bvh.nearest_giant(ray, interval);
        // Clamped so a zero direction component gives a huge finite slope, never the
        // 0 · ∞ = NaN of a box face through the origin.
        let inv = hints.inv_dir.unwrap_or_else(|| Vec3::ONE / ray.dir);
        let inv = inv.clamp(Vec3::splat(-1e30), Vec3::splat(1e30));
        Traversal {
            o: splat3(isa, ray.origin),
            d: splat3(isa, ray.dir),
            inv: splat3(isa, inv),
            t_min: Lanes::splat(isa, interval.min),
            skip: Ids::splat(isa, hints.leaving.map_or(NO_SPHERE, |id| id.0)),
            closest,
            found,
            current: 0,
            top: 0,
        }
    }

    pub(super) fn result(&self) -> Option<(f32, PrimitiveId)> {
        hit_of(self.closest, self.found)
    }

    /// Visits the current node: tests its leaf children's spheres at once and picks the
    /// next inner node. True when the walk is over.
    #[inline(always)]
    pub(super) fn step(&mut self, bvh: &Bvh, stack: &mut [(u32, f32)]) -> bool {
        let (o, inv) = (&self.o, &self.inv);
        let node = &bvh.nodes[self.current as usize];
        let isa = self.t_min.isa();
        // The slab test: per axis, the ray's parameters at the min and max planes; the
        // nearer of each pair enters the slab, the farther leaves it.
        let p = &node.planes;
        let t0 = [
            (Lanes::load(isa, &p[0]) - o[0]) * inv[0],
            (Lanes::load(isa, &p[1]) - o[1]) * inv[1],
            (Lanes::load(isa, &p[2]) - o[2]) * inv[2],
        ];
        let t1 = [
            (Lanes::load(isa, &p[3]) - o[0]) * inv[0],
            (Lanes::load(isa, &p[4]) - o[1]) * inv[1],
            (Lanes::load(isa, &p[5]) - o[2]) * inv[2],
        ];
        let t_near = t0[0]
            .fast_min(t1[0])
            .fast_max(t0[1].fast_min(t1[1]))
            .fast_max(t0[2].fast_min(t1[2]).fast_max(self.t_min));
        let t_far = t0[0]
            .fast_max(t1[0])
            .fast_min(t0[1].fast_max(t1[1]))
            .fast_min(
                t0[2]
                    .fast_max(t1[2])
                    .fast_min(Lanes::splat(isa, self.closest)),
            );
        let mut hits = t_near.simd_le(t_far).to_bitmask();
        // Indexing a SIMD vector by a variable lane compiles to a jump table.
        let t_near = t_near.to_array();
        // Leaves first, as soon as their parent is tested: a pack test costs the same
        // whatever `closest` is, so their order does not matter, only that their boxes are
        // not already behind the closest hit.
        let mut leaves = hits & node.leaf_mask;
        while leaves != 0 {
            let lane = lowest_lane(leaves);
            leaves &= leaves - 1;
            if t_near[lane] <= self.closest {
                bvh.leaf_pack(node.child[lane]).intersect(
                    &self.o,
                    &self.d,
                    self.t_min,
                    self.skip,
                    &mut self.closest,
                    &mut self.found,
                );
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
