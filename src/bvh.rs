//! A bounding volume hierarchy over spheres: built as a binary tree with the binned surface
//! area heuristic, then collapsed into a flat array of eight-wide nodes whose child boxes, and
//! whose leaf spheres, are stored as structure-of-arrays and tested eight at a time with SIMD.

use crate::geometry::{Aabb, PrimitiveId, Sphere};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use wide::{f32x8, u32x8};

/// Children per node and spheres per pack: one SIMD lane each (AVX where the build has it,
/// two SSE halves otherwise).
const WIDTH: usize = 8;
type Lanes = f32x8;

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

/// A node of the binary build tree: either two children (`count == 0`, at `first` and
/// `first + 1`) or a leaf of `count` primitives starting at `first` of the build order.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    first: u32,
    count: u32,
}

/// A wide node: the boxes of up to `WIDTH` children, one SIMD lane each. `planes` holds
/// min x, y, z then max x, y, z.
#[derive(Clone, Copy, Debug)]
struct WideNode {
    planes: [Lanes; 6],
    child: [u32; WIDTH],
    /// Bit `i` is set when child `i` is a leaf.
    leaf_mask: u32,
    /// Bit `i` is set when child `i` is an inner node.
    inner_mask: u32,
}

/// Up to `WIDTH` spheres in structure-of-arrays form; unused lanes have `r2 = -1`, which no
/// ray can hit.
#[derive(Clone, Copy, Debug)]
struct SpherePack {
    center: [Lanes; 3],
    r2: Lanes,
    id: [u32; WIDTH],
}

impl SpherePack {
    fn new(spheres: &[Sphere], ids: &[u32]) -> Self {
        let mut center = [[0.0; WIDTH]; 3];
        let mut r2 = [-1.0; WIDTH];
        let mut id = [NO_SPHERE; WIDTH];
        for (lane, &i) in ids.iter().enumerate() {
            let s = &spheres[i as usize];
            for (axis, lanes) in center.iter_mut().enumerate() {
                lanes[lane] = s.center[axis];
            }
            r2[lane] = s.radius * s.radius;
            id[lane] = i;
        }
        SpherePack {
            center: center.map(Lanes::from),
            r2: Lanes::from(r2),
            id,
        }
    }

    /// The ids of the spheres the pack holds, leaving out its unused lanes.
    fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.id.iter().copied().filter(|&id| id != NO_SPHERE)
    }

    /// Takes a hit among the spheres that beats `(closest, found)`, the best so far: the
    /// nearest within `(t_min, closest]`, ties going to the lower primitive id wherever
    /// they are met, so every traversal order finds the same hit. The same arithmetic, lane
    /// by lane, as `Sphere::intersect`.
    #[inline(always)]
    fn intersect(
        &self,
        o: &[Lanes; 3],
        d: &[Lanes; 3],
        t_min: Lanes,
        skip: u32x8,
        closest: &mut f32,
        found: &mut u32,
    ) {
        let zero = Lanes::ZERO;
        let fx = o[0] - self.center[0];
        let fy = o[1] - self.center[1];
        let fz = o[2] - self.center[2];
        let b = -(fx * d[0] + fy * d[1] + fz * d[2]);
        let (gx, gy, gz) = (fx + b * d[0], fy + b * d[1], fz + b * d[2]);
        let disc = self.r2 - (gx * gx + gy * gy + gz * gz);
        // Lanes whose line meets the sphere, less the sphere the ray is known to leave.
        let valid =
            disc.simd_ge(zero).to_bitmask() & !u32x8::from(self.id).simd_eq(skip).to_bitmask();
        // Most packs a ray reaches it misses outright: leave before the square root.
        if valid == 0 {
            return;
        }
        let sq = disc.fast_max(zero).sqrt();
        let q = b.simd_ge(zero).select(b + sq, b - sq);
        let c = (fx * fx + fy * fy + fz * fz) - self.r2;
        let q_zero = q.simd_eq(zero);
        let t0 = q_zero.select(zero, c / q);
        let t1 = q_zero.select(zero, q);
        let (near, far) = (t0.fast_min(t1), t0.fast_max(t1));
        let hi = Lanes::splat(*closest);
        let inside = |t: Lanes| t_min.simd_lt(t) & t.simd_le(hi);
        let inf = Lanes::splat(f32::INFINITY);
        let t = inside(near).select(near, inside(far).select(far, inf));
        let hits = t.simd_lt(inf).to_bitmask() & valid;
        if hits == 0 {
            return;
        }
        let t = t.to_array();
        let mut lane = lowest_lane(hits);
        // Rarely does a ray meet two spheres of one pack: then the nearer.
        let mut rest = hits & (hits - 1);
        while rest != 0 {
            let other = lowest_lane(rest);
            rest &= rest - 1;
            if (t[other], self.id[other]) < (t[lane], self.id[lane]) {
                lane = other;
            }
        }
        let (t, id) = (t[lane], self.id[lane]);
        // A tie with the best so far counts only against a real hit, not the interval's end.
        if t < *closest || (*found != NO_HIT && id < *found) {
            *closest = t;
            *found = id;
        }
    }
}

/// The hierarchy, ready to trace.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<WideNode>,
    packs: Vec<SpherePack>,
    /// Spheres so large (the book's ground) that any box holding them holds everything:
    /// tested on their own before the tree, which then stays tight around the rest.
    giants: Vec<(Sphere, u32)>,
    /// Deepest level of inner nodes below the root (the root is level 0).
    max_level: usize,
}

/// Scratch space for traversal, reused from ray to ray so no ray pays to clear or allocate
/// it. One per thread of work (e.g. per tile).
#[derive(Clone, Debug, Default)]
pub struct TraversalStack(Vec<(u32, f32)>);

struct BuildItem {
    bounds: Aabb,
    centroid: Vec3,
    id: u32,
}

impl Bvh {
    /// Builds the hierarchy over `spheres`.
    pub fn build(spheres: &[Sphere]) -> Self {
        let all = spheres.iter().fold(Aabb::EMPTY, |b, s| b.union(s.bounds()));
        let mut areas: Vec<f32> = spheres.iter().map(|s| s.bounds().area()).collect();
        areas.sort_by(f32::total_cmp);
        let median = areas.get(areas.len() / 2).copied().unwrap_or(0.0);
        // A giant's box is a large share of the whole scene's and far above a typical one.
        let giant = |s: &Sphere| {
            let area = s.bounds().area();
            spheres.len() > 8 && area > 0.25 * all.area() && area > 100.0 * median
        };
        let mut items: Vec<BuildItem> = spheres
            .iter()
            .enumerate()
            .filter(|(_, s)| !giant(s))
            .map(|(i, s)| {
                let bounds = s.bounds();
                BuildItem {
                    bounds,
                    centroid: bounds.centroid(),
                    id: i as u32,
                }
            })
            .collect();
        let mut bvh = Bvh {
            giants: (spheres.iter().enumerate())
                .filter(|(_, s)| giant(s))
                .map(|(i, s)| (*s, i as u32))
                .collect(),
            ..Bvh::default()
        };
        if items.is_empty() {
            return bvh;
        }
        let mut binary = vec![Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: 0,
        }];
        let len = items.len();
        build_node(&mut binary, 0, &mut items, 0, len);
        let order: Vec<u32> = items.iter().map(|it| it.id).collect();
        let root_kids = if binary[0].count > 0 { vec![0] } else { vec![] };
        bvh.collapse(&binary, &order, spheres, 0, root_kids, 0);
        bvh
    }

    /// A stack deep enough for this hierarchy: each inner level pushes at most `WIDTH - 1`
    /// siblings beyond the node it descends into.
    pub fn new_stack(&self) -> TraversalStack {
        TraversalStack(vec![(0, 0.0); self.stack_need()])
    }

    fn stack_need(&self) -> usize {
        (WIDTH - 1) * (self.max_level + 1) + 1
    }

    /// Appends the wide node for binary node `at` (or, for a leaf root, for `kids`), and
    /// returns its index.
    fn collapse(
        &mut self,
        binary: &[Node],
        order: &[u32],
        spheres: &[Sphere],
        at: usize,
        mut kids: Vec<usize>,
        level: usize,
    ) -> u32 {
        self.max_level = self.max_level.max(level);
        if kids.is_empty() {
            let first = binary[at].first as usize;
            kids = vec![first, first + 1];
        }
        // Open the largest inner child until the node is full.
        while kids.len() < WIDTH {
            let widest = kids
                .iter()
                .enumerate()
                .filter(|(_, k)| binary[**k].count == 0)
                .max_by(|a, b| {
                    binary[*a.1]
                        .bounds
                        .area()
                        .total_cmp(&binary[*b.1].bounds.area())
                });
            let Some((slot, &k)) = widest else { break };
            let first = binary[k].first as usize;
            kids[slot] = first;
            kids.push(first + 1);
        }
        let index = self.nodes.len();
        // Empty lanes keep an inverted box; the masks leave them out anyway.
        let mut planes = [[f32::INFINITY; WIDTH]; 6];
        planes[3..].fill([f32::NEG_INFINITY; WIDTH]);
        let mut node_out = WideNode {
            planes: [Lanes::ZERO; 6],
            child: [EMPTY; WIDTH],
            leaf_mask: 0,
            inner_mask: 0,
        };
        // Reserve the slot so the node comes before its children.
        self.nodes.push(node_out);
        for (lane, &k) in kids.iter().enumerate() {
            let node = binary[k];
            let child = if node.count > 0 {
                let first = node.first as usize;
                let ids = &order[first..first + node.count as usize];
                self.packs.push(SpherePack::new(spheres, ids));
                LEAF | (self.packs.len() - 1) as u32
            } else {
                self.collapse(binary, order, spheres, k, Vec::new(), level + 1)
            };
            for axis in 0..3 {
                planes[axis][lane] = node.bounds.min[axis];
                planes[axis + 3][lane] = node.bounds.max[axis];
            }
            node_out.child[lane] = child;
            if child & LEAF != 0 {
                node_out.leaf_mask |= 1 << lane;
            } else {
                node_out.inner_mask |= 1 << lane;
            }
        }
        for (out, plane) in node_out.planes.iter_mut().zip(planes) {
            *out = Lanes::from(plane);
        }
        self.nodes[index] = node_out;
        index as u32
    }

    /// The pack of the leaf child reference `child`.
    #[inline(always)]
    fn leaf_pack(&self, child: u32) -> &SpherePack {
        &self.packs[(child & !LEAF) as usize]
    }

    /// The closest hit in `interval`: its parameter and primitive id.
    #[inline(always)]
    pub fn intersect(
        &self,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
    ) -> Option<(f32, PrimitiveId)> {
        self.intersect_with(ray, interval, stack, RayHints::default())
    }

    /// `intersect` helped by what the caller knows of the ray (see `RayHints`).
    #[inline(always)]
    pub fn intersect_with(
        &self,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<(f32, PrimitiveId)> {
        let need = self.stack_need();
        if stack.0.len() < need {
            *stack = self.new_stack();
        }
        let mut walk = Traversal::new(self, ray, interval, hints);
        if !self.nodes.is_empty() {
            while !walk.step(self, &mut stack.0[..need]) {}
        }
        walk.result()
    }
}

/// What a caller may know of a ray that lets `Bvh::intersect_with` do less or start sooner.
/// The default knows nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayHints {
    /// A sphere the ray starts just outside of (off its surface) and heads away from, so
    /// cannot meet again (convex): its test is left out. Most bounce rays leave the sphere
    /// they bounced off this way, and its pack would otherwise pass the cheap first check
    /// for every one of them.
    pub leaving: Option<PrimitiveId>,
    /// `1 / dir` (up to rounding), for a caller that has it before `dir` itself: a bounce
    /// ray's `len × (1 / raw)` is ready a division sooner than `1 / (raw / len)`, and the
    /// first box test waits for it.
    pub inv_dir: Option<Vec3>,
}

/// A few spheres picked out for a bundle of rays (the camera rays of one tile), giants
/// included, tested together in SIMD packs without walking the tree.
#[derive(Clone, Debug)]
pub struct Candidates {
    packs: Vec<SpherePack>,
}

impl Candidates {
    /// At most this many spheres are worth a list: beyond it the tree is faster.
    pub const MAX: usize = 2 * WIDTH;
}

impl Bvh {
    /// The spheres `keep` accepts, giants and the tree's, or `None` when there are more
    /// than `Candidates::MAX`. Subtrees whose box `keep_box` (given min and max corners) rejects
    /// are skipped whole, so `keep_box` must accept every box holding a sphere `keep` would.
    pub fn candidates(
        &self,
        spheres: &[Sphere],
        keep_box: impl Fn(Vec3, Vec3) -> bool,
        keep: impl Fn(&Sphere) -> bool,
    ) -> Option<Candidates> {
        let mut ids: Vec<u32> = (self.giants.iter())
            .filter(|(sphere, _)| keep(sphere))
            .map(|(_, id)| *id)
            .collect();
        let mut todo = if self.nodes.is_empty() {
            vec![]
        } else {
            vec![0]
        };
        while let Some(index) = todo.pop() {
            let node = &self.nodes[index as usize];
            let planes = node.planes.map(Lanes::to_array);
            for (lane, &child) in node.child.iter().enumerate() {
                let corner = |first: usize| {
                    Vec3::new(
                        planes[first][lane],
                        planes[first + 1][lane],
                        planes[first + 2][lane],
                    )
                };
                if child == EMPTY || !keep_box(corner(0), corner(3)) {
                    continue;
                }
                if child & LEAF == 0 {
                    todo.push(child);
                    continue;
                }
                for id in self.leaf_pack(child).ids() {
                    if keep(&spheres[id as usize]) {
                        if ids.len() == Candidates::MAX {
                            return None;
                        }
                        ids.push(id);
                    }
                }
            }
        }
        ids.sort_unstable();
        let packs = ids
            .chunks(WIDTH)
            .map(|chunk| SpherePack::new(spheres, chunk))
            .collect();
        Some(Candidates { packs })
    }

    /// The closest hit among `candidates`: what `intersect` gives for any ray the
    /// candidates were picked for.
    #[inline]
    pub fn intersect_candidates(
        &self,
        candidates: &Candidates,
        ray: &Ray,
        interval: Interval,
    ) -> Option<(f32, PrimitiveId)> {
        let (mut closest, mut found) = (interval.max, NO_HIT);
        let (o, d) = (splat3(ray.origin), splat3(ray.dir));
        let t_min = Lanes::splat(interval.min);
        let skip = u32x8::splat(NO_SPHERE);
        for pack in &candidates.packs {
            pack.intersect(&o, &d, t_min, skip, &mut closest, &mut found);
        }
        hit_of(closest, found)
    }

    /// The nearest giant hit in `interval`: its parameter and id, else `(interval.max,
    /// NO_HIT)`.
    #[inline(always)]
    fn nearest_giant(&self, ray: &Ray, interval: Interval) -> (f32, u32) {
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
}

/// The lowest set lane of a non-empty lane mask. (Masked to `WIDTH`, which changes nothing
/// but lets the compiler drop the bounds checks of indexing by it.)
#[inline(always)]
fn lowest_lane(mask: u32) -> usize {
    mask.trailing_zeros() as usize & (WIDTH - 1)
}

#[inline(always)]
fn splat3(v: Vec3) -> [Lanes; 3] {
    [Lanes::splat(v.x), Lanes::splat(v.y), Lanes::splat(v.z)]
}

fn hit_of(closest: f32, found: u32) -> Option<(f32, PrimitiveId)> {
    (found != NO_HIT).then_some((closest, PrimitiveId(found)))
}

/// One ray's walk through the hierarchy, advanced a node at a time by `step`.
struct Traversal {
    o: [Lanes; 3],
    d: [Lanes; 3],
    inv: [Lanes; 3],
    t_min: Lanes,
    /// The id of a sphere the ray cannot hit (`RayHints::leaving`), or `NO_SPHERE`.
    skip: u32x8,
    closest: f32,
    found: u32,
    /// The node to visit next.
    current: u32,
    /// Entries of the caller's stack in use.
    top: usize,
}

impl Traversal {
    /// Starts a walk: tests the giant spheres, and sets up the root as the first node.
    #[inline(always)]
    fn new(bvh: &Bvh, ray: &Ray, interval: Interval, hints: RayHints) -> Self {
        let (closest, found) = bvh.nearest_giant(ray, interval);
        // Clamped so a zero direction component gives a huge finite slope, never the
        // 0 · ∞ = NaN of a box face through the origin.
        let inv = hints.inv_dir.unwrap_or_else(|| Vec3::ONE / ray.dir);
        let inv = inv.clamp(Vec3::splat(-1e30), Vec3::splat(1e30));
        Traversal {
            o: splat3(ray.origin),
            d: splat3(ray.dir),
            inv: splat3(inv),
            t_min: Lanes::splat(interval.min),
            skip: u32x8::splat(hints.leaving.map_or(NO_SPHERE, |id| id.0)),
            closest,
            found,
            current: 0,
            top: 0,
        }
    }

    fn result(&self) -> Option<(f32, PrimitiveId)> {
        hit_of(self.closest, self.found)
    }

    /// Visits the current node: tests its leaf children's spheres at once and picks the
    /// next inner node. True when the walk is over.
    #[inline(always)]
    fn step(&mut self, bvh: &Bvh, stack: &mut [(u32, f32)]) -> bool {
        let (o, inv) = (&self.o, &self.inv);
        let node = &bvh.nodes[self.current as usize];
        let p = &node.planes;
        // The slab test: per axis, the ray's parameters at the min and max planes; the
        // nearer of each pair enters the slab, the farther leaves it.
        let t0 = [0, 1, 2].map(|axis| (p[axis] - o[axis]) * inv[axis]);
        let t1 = [0, 1, 2].map(|axis| (p[axis + 3] - o[axis]) * inv[axis]);
        let t_near = t0[0]
            .fast_min(t1[0])
            .fast_max(t0[1].fast_min(t1[1]))
            .fast_max(t0[2].fast_min(t1[2]).fast_max(self.t_min));
        let t_far = t0[0]
            .fast_max(t1[0])
            .fast_min(t0[1].fast_max(t1[1]))
            .fast_min(t0[2].fast_max(t1[2]).fast_min(Lanes::splat(self.closest)));
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

fn build_node(nodes: &mut Vec<Node>, at: usize, items: &mut [BuildItem], start: usize, end: usize) {
    let slice = &mut items[start..end];
    let bounds = slice.iter().fold(Aabb::EMPTY, |b, it| b.union(it.bounds));
    let centroids = slice.iter().fold(Aabb::EMPTY, |b, it| b.grow(it.centroid));
    let count = slice.len();
    let leaf = Node {
        bounds,
        first: start as u32,
        count: count as u32,
    };
    // A pack tests `WIDTH` spheres for the price of one, so never split what fits in one.
    if count <= MAX_LEAF {
        nodes[at] = leaf;
        return;
    }
    let Some((axis, split)) = best_split(slice, &centroids, bounds) else {
        if count <= MAX_LEAF {
            nodes[at] = leaf;
            return;
        }
        // No useful SAH split (e.g. coincident centroids): split at the median of the
        // widest axis so the leaf size bound still holds.
        let axis = widest_axis(&centroids);
        slice.sort_by(|a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
        push_children(nodes, at, items, start, start + count / 2, end, bounds);
        return;
    };
    let mut mid = partition(slice, |it| {
        bin_of(it.centroid[axis], &centroids, axis) < split
    });
    if mid == 0 || mid == count {
        mid = count / 2;
    }
    push_children(nodes, at, items, start, start + mid, end, bounds);
}

fn push_children(
    nodes: &mut Vec<Node>,
    at: usize,
    items: &mut [BuildItem],
    start: usize,
    mid: usize,
    end: usize,
    bounds: Aabb,
) {
    let left = nodes.len();
    let placeholder = Node {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
    };
    nodes.push(placeholder);
    nodes.push(placeholder);
    nodes[at] = Node {
        bounds,
        first: left as u32,
        count: 0,
    };
    build_node(nodes, left, items, start, mid);
    build_node(nodes, left + 1, items, mid, end);
}

fn widest_axis(b: &Aabb) -> usize {
    let e = b.max - b.min;
    if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    }
}

fn bin_of(c: f32, centroids: &Aabb, axis: usize) -> usize {
    let lo = centroids.min[axis];
    let extent = centroids.max[axis] - lo;
    let b = ((c - lo) / extent * BINS as f32) as usize;
    b.min(BINS - 1)
}

/// The SAH's best (axis, first bin of the right side), if splitting beats a leaf.
fn best_split(items: &[BuildItem], centroids: &Aabb, bounds: Aabb) -> Option<(usize, usize)> {
    let leaf_cost = items.len().div_ceil(WIDTH) as f32;
    let parent_area = bounds.area();
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if centroids.max[axis] - centroids.min[axis] <= 0.0 {
            continue;
        }
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        for it in items {
            let b = bin_of(it.centroid[axis], centroids, axis);
            bin_bounds[b] = bin_bounds[b].union(it.bounds);
            bin_counts[b] += 1;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(bin_bounds[b]);
            n += bin_counts[b];
            right_area[b] = acc.area();
            right_count[b] = n;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for split in 1..BINS {
            acc = acc.union(bin_bounds[split - 1]);
            n += bin_counts[split - 1];
            if n == 0 || right_count[split] == 0 {
                continue;
            }
            // Traversal cost 1 relative to one primitive test per unit probability.
            // Spheres are tested a pack at a time, so a side costs its packs.
            let packs = |n: usize| n.div_ceil(WIDTH) as f32;
            let cost = TRAVERSAL_COST
                + (acc.area() * packs(n) + right_area[split] * packs(right_count[split]))
                    / parent_area.max(f32::MIN_POSITIVE);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    match best {
        Some((cost, axis, split)) if cost < leaf_cost || items.len() > MAX_LEAF => {
            Some((axis, split))
        }
        _ => None,
    }
}

/// Moves the items satisfying `pred` to the front; returns how many there are.
fn partition(items: &mut [BuildItem], pred: impl Fn(&BuildItem) -> bool) -> usize {
    let mut mid = 0;
    for i in 0..items.len() {
        if pred(&items[i]) {
            items.swap(i, mid);
            mid += 1;
        }
    }
    mid
}

/// The closest hit by testing every sphere: the reference the hierarchy is tested against.
pub fn intersect_brute_force(
    spheres: &[Sphere],
    ray: &Ray,
    interval: Interval,
) -> Option<(f32, PrimitiveId)> {
    let mut closest = interval.max;
    let mut found = None;
    for (i, s) in spheres.iter().enumerate() {
        if let Some(t) = s.intersect(ray, Interval::new(interval.min, closest)) {
            closest = t;
            found = Some((t, PrimitiveId(i as u32)));
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::MaterialId;
    use crate::sampling::Sampler;

    fn random_spheres(n: usize, rng: &mut Sampler) -> Vec<Sphere> {
        let mut v: Vec<Sphere> = (0..n)
            .map(|i| {
                let c = Vec3::new(
                    rng.range(-10.0, 10.0),
                    rng.range(-2.0, 2.0),
                    rng.range(-10.0, 10.0),
                );
                Sphere::new(c, rng.range(0.05, 1.0), MaterialId(i as u32))
            })
            .collect();
        v.push(Sphere::new(
            Vec3::new(0.0, -1000.0, 0.0),
            1000.0,
            MaterialId(0),
        ));
        v
    }

    #[test]
    fn matches_brute_force_on_random_rays() {
        let mut rng = Sampler::from_seed(5);
        for n in [0, 1, 2, 7, 64, 500] {
            let spheres = random_spheres(n, &mut rng);
            let bvh = Bvh::build(&spheres);
            let mut stack = TraversalStack::default();
            for _ in 0..4000 {
                let o = Vec3::new(
                    rng.range(-15.0, 15.0),
                    rng.range(0.0, 6.0),
                    rng.range(-15.0, 15.0),
                );
                let ray = Ray::new(o, rng.unit_vector());
                let iv = Interval::new(1e-4, f32::INFINITY);
                let a = bvh.intersect(&ray, iv, &mut stack);
                let b = intersect_brute_force(&spheres, &ray, iv);
                match (a, b) {
                    (None, None) => {}
                    (Some((ta, ia)), Some((tb, ib))) => {
                        assert_eq!(ta.to_bits(), tb.to_bits(), "t for {ray:?}");
                        assert_eq!(ia, ib, "primitive for {ray:?}");
                    }
                    other => panic!("bvh and brute force disagree: {other:?} for {ray:?}"),
                }
            }
        }
    }

    #[test]
    fn rays_leaving_a_sphere_find_what_brute_force_finds_without_testing_it() {
        // Crowded spheres, so a bounce ray often meets a neighbour of its own pack.
        let mut rng = Sampler::from_seed(21);
        let spheres: Vec<Sphere> = (0..300)
            .map(|i| {
                let c = Vec3::new(
                    rng.range(-4.0, 4.0),
                    rng.range(0.0, 1.0),
                    rng.range(-4.0, 4.0),
                );
                Sphere::new(c, rng.range(0.1, 0.5), MaterialId(i))
            })
            .collect();
        let bvh = Bvh::build(&spheres);
        let mut stack = TraversalStack::default();
        let iv = Interval::new(0.0, f32::INFINITY);
        let mut neighbours = 0;
        for _ in 0..20_000 {
            let id = (rng.uniform() * spheres.len() as f32) as usize % spheres.len();
            let s = &spheres[id];
            // Off the surface by the renderer's default t_min, heading outwards.
            let n = rng.unit_vector();
            let mut d = rng.unit_vector();
            if d.dot(n) < 0.0 {
                d = -d;
            }
            let ray = Ray::new(s.center + s.radius * n + 1e-3 * n, d);
            // As the path tracer hints it: the sphere left, and 1/dir from the raw direction.
            let raw = 3.0 * d;
            let hints = RayHints {
                leaving: Some(PrimitiveId(id as u32)),
                inv_dir: Some(raw.length() * (Vec3::ONE / raw)),
            };
            let fast = bvh.intersect_with(&ray, iv, &mut stack, hints);
            let full = bvh.intersect(&ray, iv, &mut stack);
            let brute = intersect_brute_force(&spheres, &ray, iv);
            assert_eq!(fast, brute, "{ray:?} leaving {id}");
            assert_eq!(full, brute, "{ray:?} leaving {id}");
            neighbours += usize::from(brute.is_some());
        }
        assert!(
            neighbours > 5_000,
            "too few rays meet another sphere: {neighbours}"
        );
    }

    #[test]
    fn ties_go_to_the_lower_id_whatever_the_traversal_order() {
        // Every sphere twelve times over, more than a leaf holds: each hit is a tie between
        // spheres of different leaves and packs.
        let mut rng = Sampler::from_seed(9);
        let base = random_spheres(20, &mut rng);
        let spheres: Vec<Sphere> = (0..12).flat_map(|_| base.iter().copied()).collect();
        let bvh = Bvh::build(&spheres);
        let mut stack = TraversalStack::default();
        let iv = Interval::new(1e-4, f32::INFINITY);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(rng.range(-15.0, 15.0), rng.range(0.0, 6.0), 15.0);
            let ray = Ray::new(o, rng.unit_vector());
            let a = bvh.intersect(&ray, iv, &mut stack);
            let b = intersect_brute_force(&spheres, &ray, iv);
            assert_eq!(a, b, "for {ray:?}");
            if let Some((_, id)) = a {
                assert!((id.0 as usize) < base.len(), "tie lost to a later copy");
                hits += 1;
            }
        }
        assert!(hits > 200, "only {hits} hits");
    }

    /// Picking candidates through the tree, skipping subtrees whose boxes the bundle misses,
    /// must pick exactly the spheres a scan of every sphere picks.
    #[test]
    fn candidates_through_the_tree_equal_a_scan_of_every_sphere() {
        use crate::camera::{Camera, CameraSettings};
        let mut rng = Sampler::from_seed(21);
        let spheres = random_spheres(500, &mut rng);
        let bvh = Bvh::build(&spheres);
        let camera = Camera::new(&CameraSettings {
            lookfrom: Vec3::new(13.0, 2.0, 3.0),
            lookat: Vec3::ZERO,
            vup: Vec3::Y,
            vfov_deg: 20.0,
            aspect_ratio: 1.5,
            aperture: 0.3,
            focus_dist: 10.0,
        });
        let (mut listed, mut refused) = (0, 0);
        for _ in 0..300 {
            let (s0, t0) = (rng.uniform(), rng.uniform());
            let size = rng.range(0.002, 0.3);
            let bundle = camera.bundle((s0, s0 + size), (t0, t0 + size));
            let keep = |s: &Sphere| bundle.may_hit(s.center, s.radius);
            // Every sphere is a giant or in the tree.
            let scan: Vec<u32> = (0..spheres.len() as u32)
                .filter(|&id| keep(&spheres[id as usize]))
                .collect();
            let picked = bvh.candidates(&spheres, |lo, hi| bundle.may_hit_box(lo, hi), keep);
            match picked {
                Some(c) => {
                    let ids: Vec<u32> = c.packs.iter().flat_map(SpherePack::ids).collect();
                    assert_eq!(ids, scan);
                    listed += 1;
                }
                None => {
                    assert!(scan.len() > Candidates::MAX);
                    refused += 1;
                }
            }
        }
        assert!(
            listed > 30 && refused > 30,
            "{listed} listed, {refused} refused"
        );
    }

    #[test]
    fn leaves_stay_small_even_for_coincident_spheres() {
        let spheres = vec![Sphere::new(Vec3::ZERO, 1.0, MaterialId(0)); 40];
        let bvh = Bvh::build(&spheres);
        assert!(bvh.packs.len() >= 40 / MAX_LEAF);
        assert_eq!(bvh.packs.iter().flat_map(SpherePack::ids).count(), 40);
        let ray = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        assert_eq!(
            bvh.intersect(
                &ray,
                Interval::new(0.0, 100.0),
                &mut TraversalStack::default()
            )
            .unwrap()
            .0,
            4.0
        );
    }
}
