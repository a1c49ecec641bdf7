//! A bounding volume hierarchy over spheres: built as a binary tree with the surface area
//! heuristic, then collapsed into a flat array of eight-wide nodes whose child boxes, and
//! whose leaf spheres, are stored as structure-of-arrays and tested eight at a time with SIMD.
//! A tree of at most 64 packs also keeps their boxes sixteen to a group, for a flat walk on
//! the AVX-512 path.
//!
//! The public surface is this file: build, intersect (with optional hints), and per-tile
//! candidate lists. `build` makes the tree, `traverse` walks it, `pack` tests eight spheres
//! at once, `candidates` picks the spheres a bundle of rays can reach, `layer` finds the few
//! packs a ray in or over a thin layer of spheres can meet without walking the tree.

mod build;
mod candidates;
mod layer;
mod pack;
#[cfg(test)]
mod tests;
mod traverse;

pub use candidates::Candidates;

use crate::geometry::{PrimitiveId, Sphere};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use crate::simd::{F32x8, F32x16, Isa, Portable};
use layer::LayerGrid;
use pack::SpherePack;
use traverse::Traversal;

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
const NO_HIT: u32 = u32::MAX;
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

/// The hierarchy, ready to trace.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<WideNode>,
    packs: Vec<SpherePack>,
    /// For a tree of at most `FLAT_MAX_PACKS` packs, their boxes (see `FLAT_MAX_PACKS`);
    /// else empty.
    flat: Vec<PackBoxes>,
    /// Spheres so large (the book's ground) that any box holding them holds everything:
    /// tested on their own after the tree, which then stays tight around the rest.
    giants: Vec<(Sphere, u32)>,
    /// Deepest level of inner nodes below the root (the root is level 0).
    max_level: usize,
    /// For a thin layer of spheres (the book's cover), the packs a ray in or over it can
    /// meet, found without the walk (see `layer`).
    layer: Option<LayerGrid>,
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

    fn with_entries(need: usize) -> Self {
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

impl Bvh {
    /// Builds the hierarchy over `spheres`.
    pub fn build(spheres: &[Sphere]) -> Self {
        build::build(spheres)
    }

    /// A stack deep enough for this hierarchy: each inner level pushes at most `WIDTH - 1`
    /// siblings beyond the node it descends into.
    pub fn new_stack(&self) -> TraversalStack {
        TraversalStack::with_entries(self.stack_need())
    }

    fn stack_need(&self) -> usize {
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
        self.walk(isa, ray, interval, stack, hints, I::WIDE_SLABS)
    }

    /// `intersect_on`, walking the tree flat (see `FLAT_MAX_PACKS`) when `flat` and the
    /// tree is small enough. Either walk gives the same answer on any path.
    #[inline(always)]
    fn walk<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
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
        // Not `Option::and_then`: a closure may be left out of line, compiled for no SIMD path.
        let layer_packs = match &self.layer {
            Some(grid) => grid.packs_for(ray.origin, hints.heading.unwrap_or(ray.dir)),
            None => None,
        };
        if let Some(packs) = layer_packs {
            for pack in packs {
                walk.test_pack(pack);
            }
        } else if flat && !self.flat.is_empty() {
            walk.flat(self);
        } else if !self.nodes.is_empty() {
            let entries = stack.entries(need);
            while !walk.step(self, entries) {}
        }
        walk.test_giants(self, ray);
        walk.result()
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

/// The sphere a ray leaves (see `RayHints::leaving`), or none: an id with a value for none
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

    /// The id the packs' tests leave out (`NO_SPHERE`, no sphere's, for none).
    fn id(self) -> u32 {
        self.0
    }
}

impl Default for Leaving {
    fn default() -> Self {
        Self::NONE
    }
}
