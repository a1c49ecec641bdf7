//! A bounding volume hierarchy over the primitives of one kind: built over their bounds as a
//! binary tree with the surface area heuristic, then collapsed into a flat array of
//! eight-wide nodes whose child boxes, and whose leaf primitives, are stored as
//! structure-of-arrays and tested eight at a time with SIMD (a `Leaf` pack per kind). A tree
//! of at most 64 packs also keeps their boxes sixteen to a group, for a flat walk on the
//! AVX-512 path.
//!
//! The public surface is this file: the `Leaf` a kind of primitive implements, build,
//! intersect (with optional hints), and per-tile candidate lists. `build` makes the tree,
//! `traverse` walks it, `pack` tests eight spheres at once (`quads`, `moving` and `media` the
//! other kinds), `candidates` picks the spheres a bundle of rays can reach, `layer` finds the
//! few packs a ray in or over a thin layer of spheres can meet without walking the tree.

mod batch;
mod build;
mod candidates;
mod layer;
mod media;
mod moving;
mod pack;
mod quads;
#[cfg(test)]
mod tests;
mod traverse;

pub use batch::{BATCH, QuadBatch, RayBatch, media_hit};
pub use candidates::Candidates;
pub use media::MediumPack;
pub use moving::MovingSpherePack;
pub use pack::SpherePack;
pub use quads::QuadPack;

use crate::geometry::{Aabb, PrimitiveId};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use crate::simd::{F32x8, F32x16, Ids, Isa, Lanes, Portable};
use layer::LayerGrid;
use std::fmt;
use traverse::Traversal;

/// The hierarchy of the book's spheres.
pub type SphereBvh = Bvh<SpherePack>;

/// What a ray carries besides its line that a primitive may need: the time it is taken at
/// (motion blur: where a moving sphere is) and the random number a medium turns into the
/// distance the ray travels through it before it scatters, drawn from the sample's own
/// generator for this segment so that no hit test draws one, whatever order a walk tests
/// primitives in.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moment {
    pub time: f32,
    pub medium_key: u32,
}

/// The ray a walk traces and its moment, for the kinds tested a lane at a time (the walk
/// keeps the ray in lanes for the rest).
#[derive(Clone, Copy)]
pub(crate) struct Query<'a> {
    ray: &'a Ray,
    moment: Moment,
}

/// A ray as the packs take it: origin, direction and `t_min` in lanes, the id to skip
/// (`RayHints::leaving`), and, for kinds tested a lane at a time, the ray itself with its
/// `t_min` and `Moment`.
#[derive(Clone, Copy)]
pub struct PackRay<'a, I: Isa> {
    pub o: &'a [Lanes<I>; 3],
    pub d: &'a [Lanes<I>; 3],
    pub t_min: Lanes<I>,
    pub skip: Ids<I>,
    pub ray: &'a Ray,
    pub t_min_scalar: f32,
    pub moment: Moment,
}

/// A kind of primitive as the hierarchy holds it: its bounds, and a pack of up to `WIDTH` of
/// them in structure-of-arrays form that a ray is tested against at once. The hierarchy
/// knows nothing else of a primitive.
pub trait Leaf: Clone + fmt::Debug + Send + Sync + Sized + 'static {
    /// The primitive, as the scene keeps it.
    type Item: Clone + fmt::Debug + Send + Sync;
    /// The id of this kind's first primitive: ids are `ID_BASE + index`, so every kind's
    /// ids differ and a hit's id says its kind (`PrimitiveId::kind`).
    const ID_BASE: u32;

    /// A box holding the primitive wherever it is (a moving one over its whole path), no
    /// tighter than its own test: a ray the test finds meets the box.
    fn bounds(item: &Self::Item) -> Aabb;

    /// A pack of `items[i]` for the indices `indices` (at most `WIDTH`).
    fn pack(items: &[Self::Item], indices: &[u32]) -> Self;

    /// The ids of the primitives the pack holds.
    fn ids(&self) -> impl Iterator<Item = u32> + '_;

    /// Takes a hit among the pack's primitives that beats `(closest, found)`, the best so far:
    /// the nearest within `(t_min, closest]`, ties going to the lower id (see `beats`).
    fn intersect<I: Isa>(&self, ray: &PackRay<'_, I>, closest: &mut f32, found: &mut u32);

    /// The nearest hit of one primitive within `interval`, the same as its pack's test (for
    /// the giants, tested on their own).
    fn intersect_one(
        item: &Self::Item,
        id: u32,
        ray: &Ray,
        moment: Moment,
        interval: Interval,
    ) -> Option<f32>;

    /// True when the packs of one node (or of a flat tree) are best tested each against the
    /// closest hit from before them, not against the one a pack before found: their tests
    /// then overlap, where a cheap pack test (a sphere's, which leaves early on a miss) is
    /// better waited on for the bound it gives. The answer is the same either way.
    const OVERLAP: bool = false;

    /// True when a small set of this kind's primitives (at most `WIDTH` packs' worth) is
    /// better grouped into packs by their boxes' areas than by the tree's axis splits
    /// (`build::clusters`): primitives that enclose one another, as a room's walls do its
    /// furniture, cannot be split apart along an axis, so every pack would span the room
    /// and every ray test them all. The spheres keep the axis splits the cover was tuned
    /// with.
    const CLUSTERED: bool = false;

    /// The primitive as a still sphere (centre, radius), for what is shaped for spheres
    /// (the layer grid, the camera's ray bundles); `None` for other kinds.
    fn as_sphere(_item: &Self::Item) -> Option<(Vec3, f32)> {
        None
    }
}

/// The index within its kind of the primitive `id` of kind `P`.
#[inline(always)]
fn index_of<P: Leaf>(id: u32) -> usize {
    (id - P::ID_BASE) as usize
}

/// Children per node and spheres per pack: one SIMD lane each (AVX where the build has it,
/// two SSE halves otherwise).
const WIDTH: usize = 8;

/// Leaves hold at most this many primitives: one SIMD pack.
const MAX_LEAF: usize = WIDTH;
const _: () = assert!(MAX_LEAF <= WIDTH, "a leaf must fit in one pack");
/// Cost of visiting a node relative to testing one pack, for the SAH.
const TRAVERSAL_COST: f32 = 1.0;
/// Number of SAH bins per axis.
const BINS: usize = 12;
/// Child reference flags: a leaf (its pack's index in the low bits), or no child at all.
const LEAF: u32 = 1 << 31;
const EMPTY: u32 = u32::MAX;
/// The primitive id of no hit, during traversal.
pub const NO_HIT: u32 = u32::MAX;
/// The id in an unused lane of a sphere pack.
const NO_SPHERE: u32 = u32::MAX;

/// A wide node: the boxes of up to `WIDTH` children, one SIMD lane each. `planes` holds
/// min x, y, z then max x, y, z.
#[derive(Clone, Copy, Debug)]
struct WideNode {
    planes: [F32x8; 6],
    child: [u32; WIDTH],
    /// Bit `i` is set when child `i` is a leaf.
    leaf_mask: u32,
    /// Bit `i` is set when child `i` is an inner node.
    inner_mask: u32,
}

/// Trees of at most this many packs (two levels: a root over nodes of packs) are walked flat
/// on a path with sixteen-lane box tests (`Isa::WIDE_SLABS`): every pack's box is tested,
/// sixteen at a time, then the packs whose boxes the ray meets. The four tests are
/// independent of one another, so they overlap, where the tree's two levels wait on each
/// other and branch between them. With eight-lane tests (twice the instructions) the flat
/// walk measured slower than the tree.
const FLAT_MAX_PACKS: usize = WIDTH * WIDTH;
/// Pack boxes per group of a flat tree.
const FLAT_GROUP: usize = 16;
/// Groups of pack boxes in a flat tree, at most.
const FLAT_MAX_GROUPS: usize = FLAT_MAX_PACKS / FLAT_GROUP;

/// The boxes of packs `FLAT_GROUP · g ..` (for group `g`), one lane each; `mask` has a bit
/// for each lane that holds a pack.
#[derive(Clone, Copy, Debug)]
struct PackBoxes {
    planes: [F32x16; 6],
    mask: u32,
}

/// The hierarchy of one kind of primitive, ready to trace.
#[derive(Clone, Debug)]
pub struct Bvh<P: Leaf> {
    nodes: Vec<WideNode>,
    packs: Vec<P>,
    /// For a tree of at most `FLAT_MAX_PACKS` packs, their boxes (see `FLAT_MAX_PACKS`);
    /// else empty.
    flat: Vec<PackBoxes>,
    /// Primitives so large (the book's ground) that any box holding them holds everything:
    /// tested on their own after the tree, which then stays tight around the rest.
    giants: Vec<(P::Item, u32)>,
    /// Deepest level of inner nodes below the root (the root is level 0).
    max_level: usize,
    /// For a thin layer of spheres (the book's cover), the packs a ray in or over it can
    /// meet, found without the walk (see `layer`).
    layer: Option<LayerGrid<P>>,
}

impl<P: Leaf> Default for Bvh<P> {
    fn default() -> Self {
        Self {
            nodes: Vec::new(),
            packs: Vec::new(),
            flat: Vec::new(),
            giants: Vec::new(),
            max_level: 0,
            layer: None,
        }
    }
}

/// Scratch space for traversal, reused from ray to ray so no ray pays to clear or allocate
/// it. One per thread of work (e.g. per tile).
///
/// The entries in use have a cache line of padding on each side, so no other allocation
/// shares a cache line with them: the stack is written on every ray, and a neighbour written
/// by another thread (another worker's data, or the allocator's bookkeeping as the folding
/// thread frees a finished tile) would make that line bounce between cores. Unpadded, two
/// threads rendered 6% slower (`docs/performance.md`).
#[derive(Clone, Debug, Default)]
pub struct TraversalStack(Vec<(u32, f32)>);

impl TraversalStack {
    /// Entries of padding on each side: a cache line's worth.
    const PAD: usize = 64 / std::mem::size_of::<(u32, f32)>();

    pub(crate) fn with_entries(need: usize) -> Self {
        TraversalStack(vec![(0, 0.0); need + 2 * Self::PAD])
    }

    /// The `need` entries in use, away from both ends.
    #[inline(always)]
    fn entries(&mut self, need: usize) -> &mut [(u32, f32)] {
        &mut self.0[Self::PAD..Self::PAD + need]
    }

    fn holds(&self, need: usize) -> bool {
        self.0.len() >= need + 2 * Self::PAD
    }
}

impl<P: Leaf> Bvh<P> {
    /// Builds the hierarchy over `items`, whose ids are `P::ID_BASE` onwards, with the layer
    /// grid where they make a layer (see `layer`).
    pub fn build(items: &[P::Item]) -> Self {
        build::build(items, true)
    }

    /// `build` without the layer grid.
    pub fn build_plain(items: &[P::Item]) -> Self {
        build::build(items, false)
    }

    /// True when the hierarchy holds no primitive.
    pub fn is_empty(&self) -> bool {
        self.packs.is_empty() && self.giants.is_empty()
    }

    /// A stack deep enough for this hierarchy: each inner level pushes at most `WIDTH - 1`
    /// siblings beyond the node it descends into.
    pub fn new_stack(&self) -> TraversalStack {
        TraversalStack::with_entries(self.stack_need())
    }

    pub(crate) fn stack_need(&self) -> usize {
        (WIDTH - 1) * (self.max_level + 1) + 1
    }

    /// The closest hit in `interval`: its parameter and primitive id (on the portable SIMD
    /// path; `intersect_on` takes any).
    pub fn intersect(
        &self,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
    ) -> Option<(f32, PrimitiveId)> {
        self.intersect_with(ray, interval, stack, RayHints::default())
    }

    /// `intersect` helped by what the caller knows of the ray (see `RayHints`).
    pub fn intersect_with(
        &self,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<(f32, PrimitiveId)> {
        self.intersect_on(Portable, ray, interval, stack, hints)
    }

    /// `intersect_with` on the SIMD path of `isa`: the same answer on every path.
    #[inline(always)]
    pub fn intersect_on<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<(f32, PrimitiveId)> {
        self.walk(
            isa,
            ray,
            Moment::default(),
            interval,
            stack,
            hints,
            I::WIDE_SLABS,
        )
    }

    /// `intersect_on`, walking the tree flat (see `FLAT_MAX_PACKS`) when `flat` and the
    /// tree is small enough. Either walk gives the same answer on any path.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn walk<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        moment: Moment,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
        flat: bool,
    ) -> Option<(f32, PrimitiveId)> {
        // Before the walk starts, even a flat one: so placed, the tree walk measured 2% faster.
        let need = self.stack_need();
        if !stack.holds(need) {
            *stack = self.new_stack();
        }
        let mut walk = Traversal::new(isa, ray, interval, hints);
        self.run(&mut walk, Query { ray, moment }, stack, need, hints, flat);
        walk.result()
    }

    /// Walks the hierarchy with `walk` (grid, flat or tree), then tests the giants.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn run<I: Isa>(
        &self,
        walk: &mut Traversal<I>,
        at: Query<'_>,
        stack: &mut TraversalStack,
        need: usize,
        hints: RayHints,
        flat: bool,
    ) {
        let ray = at.ray;
        // Not `Option::and_then`: a closure may be left out of line, compiled for no SIMD path.
        let layer_packs = match &self.layer {
            Some(grid) => grid.packs_for(ray.origin, hints.heading.unwrap_or(ray.dir)),
            None => None,
        };
        if let Some(packs) = layer_packs {
            for pack in packs {
                walk.test_pack(pack, at);
            }
        } else if flat && !self.flat.is_empty() {
            walk.flat(self, at);
        } else if !self.nodes.is_empty() {
            let entries = stack.entries(need);
            while !walk.step(self, entries, at) {}
        }
        walk.test_giants(self, ray, at.moment);
    }
}

/// One ray's walk through several hierarchies in turn (one per kind of primitive), set up
/// once, the closest hit so far carried from each to the next (which bounds its walk). Ties
/// go to the lower id, so the order of the hierarchies does not change the answer.
pub struct MultiWalk<'a, I: Isa> {
    walk: Traversal<I>,
    at: Query<'a>,
    hints: RayHints,
}

impl<'a, I: Isa> MultiWalk<'a, I> {
    #[inline(always)]
    pub fn new(isa: I, ray: &'a Ray, moment: Moment, interval: Interval, hints: RayHints) -> Self {
        MultiWalk {
            walk: Traversal::new(isa, ray, interval, hints),
            at: Query { ray, moment },
            hints,
        }
    }

    /// Walks `bvh`, keeping a hit that beats the closest so far.
    #[inline(always)]
    pub fn through<P: Leaf>(&mut self, bvh: &Bvh<P>, stack: &mut TraversalStack) {
        let need = bvh.stack_need();
        if !stack.holds(need) {
            *stack = bvh.new_stack();
        }
        bvh.run(
            &mut self.walk,
            self.at,
            stack,
            need,
            self.hints,
            I::WIDE_SLABS,
        );
        self.walk.restart();
    }

    /// The closest hit of every hierarchy walked.
    #[inline(always)]
    pub fn result(&self) -> Option<(f32, PrimitiveId)> {
        self.walk.result()
    }
}

/// What a caller may know of a ray that lets `Bvh::intersect_with` do less or start sooner.
/// The default knows nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayHints {
    /// A sphere the ray leaves from outside (starting on or just off its surface) and heads
    /// away from, so cannot meet again (convex): its test is left out, a giant's too. Most
    /// bounce rays leave the sphere they bounced off this way, and its pack would otherwise
    /// pass the cheap first check for every one of them.
    pub leaving: Leaving,
    /// `1 / dir` (up to rounding), for a caller that has it before `dir` itself: a bounce
    /// ray's `len × (1 / raw)` is ready a division sooner than `1 / (raw / len)`, and the
    /// first box test waits for it.
    pub inv_dir: Option<Vec3>,
    /// A positive multiple of the direction (up to rounding), for a caller that has it
    /// before the direction itself: a bounce ray's raw direction, ready a square root and a
    /// division sooner. The layer grid's choice depends only on the direction's signs and
    /// ratios, so it can be made while the direction is still being normalised.
    pub heading: Option<Vec3>,
}

/// The primitive a ray leaves (see `RayHints::leaving`), or none: an id with a value for none
/// rather than an `Option`, so a bounce ray's hint is made by a select, not a branch (glass
/// makes it unpredictable which rays have one). The default is none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Leaving(u32);

impl Leaving {
    pub const NONE: Leaving = Leaving(NO_SPHERE);

    /// `sphere` where `leaves`, else none.
    #[inline(always)]
    pub fn sphere_if(leaves: bool, sphere: PrimitiveId) -> Self {
        Leaving(if leaves { sphere.0 } else { NO_SPHERE })
    }

    pub fn is_some(self) -> bool {
        self != Self::NONE
    }

    /// The id the packs' tests leave out (`NO_SPHERE`, no primitive's, for none).
    pub(crate) fn id(self) -> u32 {
        self.0
    }
}

impl Default for Leaving {
    fn default() -> Self {
        Self::NONE
    }
}
