//! Building the hierarchy over the primitives' bounds: a binary tree by the surface area
//! heuristic (binned for large nodes; for small ones, a sweep that keeps packs full),
//! collapsed into wide nodes of up to `WIDTH` children, with leaves of one pack each; or,
//! for a small set of a kind that asks (`Leaf::CLUSTERED`), one node over packs grouped by
//! their boxes' areas.

use super::{
    BINS, Bvh, EMPTY, FLAT_GROUP, FLAT_MAX_PACKS, LEAF, Leaf, MAX_LEAF, PackBoxes, TRAVERSAL_COST,
    WIDTH, WideNode, index_of,
};
use crate::geometry::Aabb;
use crate::math::Vec3;
use crate::simd::{F32x8, F32x16};

/// Nodes of at most this many items (`WIDTH³`) are split by a sweep of their sorted
/// centroids at the positions `best_aligned_split` allows; larger ones by binned SAH. The
/// sweep sorts, so it is kept to the levels where full packs and nodes pay.
const EXACT_SPLIT_LIMIT: usize = WIDTH * WIDTH * WIDTH;

/// A node of the binary build tree: either two children (`count == 0`, at `first` and
/// `first + 1`) or a leaf of `count` primitives starting at `first` of the build order.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    first: u32,
    count: u32,
    /// Items in the subtree.
    size: u32,
}

struct BuildItem {
    bounds: Aabb,
    centroid: Vec3,
    id: u32,
}

/// Builds the hierarchy over `prims`: a binned-SAH binary tree, collapsed into wide nodes.
pub(super) fn build<P: Leaf>(prims: &[P::Item], layer_grid: bool) -> Bvh<P> {
    let all = prims.iter().fold(Aabb::EMPTY, |b, s| b.union(P::bounds(s)));
    let mut areas: Vec<f32> = prims.iter().map(|s| P::bounds(s).area()).collect();
    areas.sort_by(f32::total_cmp);
    let median = areas.get(areas.len() / 2).copied().unwrap_or(0.0);
    // A giant's box is a large share of the whole scene's and far above a typical one.
    let giant = |s: &P::Item| {
        let area = P::bounds(s).area();
        prims.len() > 8 && area > 0.25 * all.area() && area > 100.0 * median
    };
    // Build items carry the primitive's index within its kind (its id less `P::ID_BASE`).
    let mut items: Vec<BuildItem> = prims
        .iter()
        .enumerate()
        .filter(|(_, s)| !giant(s))
        .map(|(i, s)| {
            let bounds = P::bounds(s);
            BuildItem {
                bounds,
                centroid: bounds.centroid(),
                id: i as u32,
            }
        })
        .collect();
    let mut bvh = Bvh {
        giants: (prims.iter().enumerate())
            .filter(|(_, s)| giant(s))
            .map(|(i, s)| (s.clone(), P::ID_BASE + i as u32))
            .collect(),
        ..Bvh::default()
    };
    if items.is_empty() {
        return bvh;
    }
    if P::CLUSTERED
        && let Some(groups) = clusters(&items)
    {
        bvh.over_packs(prims, &items, &groups);
        return bvh;
    }
    let mut binary = vec![Node {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
        size: 0,
    }];
    let len = items.len();
    build_node(&mut binary, 0, &mut items, 0, len);
    let order: Vec<u32> = items.iter().map(|it| it.id).collect();
    let root_kids = if binary[0].count > 0 { vec![0] } else { vec![] };
    bvh.collapse(&binary, &order, prims, 0, root_kids, 0);
    if layer_grid {
        bvh.layer = super::LayerGrid::build(prims, &order);
    }
    if bvh.packs.len() <= FLAT_MAX_PACKS {
        bvh.flat = pack_boxes(&bvh.packs, prims);
    }
    bvh
}

/// A pack's box test relative to its primitives' test, for `clusters`: eight or sixteen
/// boxes are tested at once, so a pack more costs a fraction of a pack test.
const BOX_TEST_COST: f32 = 1.0 / 16.0;

/// The items grouped into at most `WIDTH` packs (`Leaf::CLUSTERED`), each a list of item
/// indices, or `None` where they need more. A pack is tested by every ray that meets its
/// box, so the groups are chosen to make the sum of their boxes' areas small, each box
/// test counted too: from one item a group, the two groups whose merging lowers that cost
/// the most are merged while any does. Merging two parallel walls of a room makes a box of
/// the whole room, so the walls stay apart (a ray crosses the flat box of the one wall it
/// meets), and the blocks inside become packs of their own: a ray tests a wall and the
/// blocks it passes, where axis splits put walls and blocks together in packs that every
/// ray tests. Deterministic: ties go to the first pair in order.
fn clusters(items: &[BuildItem]) -> Option<Vec<Vec<usize>>> {
    if items.len() > WIDTH * MAX_LEAF {
        return None;
    }
    let whole = items.iter().fold(Aabb::EMPTY, |b, it| b.union(it.bounds));
    let box_cost = BOX_TEST_COST * whole.area();
    let mut groups: Vec<(Aabb, Vec<usize>)> = (items.iter().enumerate())
        .map(|(i, it)| (it.bounds, vec![i]))
        .collect();
    loop {
        let mut best: Option<(f32, usize, usize)> = None;
        for a in 0..groups.len() {
            for b in a + 1..groups.len() {
                let ((box_a, in_a), (box_b, in_b)) = (&groups[a], &groups[b]);
                if in_a.len() + in_b.len() > MAX_LEAF {
                    continue;
                }
                let gain = box_a.area() + box_b.area() + box_cost - box_a.union(*box_b).area();
                if gain > 0.0 && best.is_none_or(|(g, _, _)| gain > g) {
                    best = Some((gain, a, b));
                }
            }
        }
        let Some((_, a, b)) = best else { break };
        let (box_b, in_b) = groups.remove(b);
        groups[a].0 = groups[a].0.union(box_b);
        groups[a].1.extend(in_b);
    }
    (groups.len() <= WIDTH).then(|| groups.into_iter().map(|(_, g)| g).collect())
}

/// The boxes of `packs` (the same as the tree's leaf boxes: unions of the primitives'
/// boxes), `FLAT_GROUP` to a group.
fn pack_boxes<P: Leaf>(packs: &[P], prims: &[P::Item]) -> Vec<PackBoxes> {
    packs
        .chunks(FLAT_GROUP)
        .map(|group| {
            let bounds = group.iter().map(|pack| {
                (pack.ids()).fold(Aabb::EMPTY, |b, id| {
                    b.union(P::bounds(&prims[index_of::<P>(id)]))
                })
            });
            let halves = |p: [f32; FLAT_GROUP]| {
                let (lo, hi) = p.split_at(WIDTH);
                F32x16([lo, hi].map(|h| F32x8(h.try_into().expect("WIDTH lanes"))))
            };
            PackBoxes {
                planes: box_planes::<FLAT_GROUP>(bounds).map(halves),
                mask: (1 << group.len()) - 1,
            }
        })
        .collect()
}

impl<P: Leaf> Bvh<P> {
    /// Makes the hierarchy one node over a pack for each of `groups` (indices into `items`,
    /// at most `WIDTH` groups), walked flat where the path allows.
    fn over_packs(&mut self, prims: &[P::Item], items: &[BuildItem], groups: &[Vec<usize>]) {
        let mut root = WideNode {
            planes: [F32x8::ZERO; 6],
            child: [EMPTY; WIDTH],
            leaf_mask: 0,
            inner_mask: 0,
        };
        let mut boxes = Vec::with_capacity(groups.len());
        for (lane, group) in groups.iter().enumerate() {
            let ids: Vec<u32> = group.iter().map(|&i| items[i].id).collect();
            boxes.push(
                group
                    .iter()
                    .fold(Aabb::EMPTY, |b, &i| b.union(items[i].bounds)),
            );
            self.packs.push(P::pack(prims, &ids));
            root.child[lane] = LEAF | lane as u32;
            root.leaf_mask |= 1 << lane;
        }
        root.planes = box_planes::<WIDTH>(boxes).map(F32x8);
        self.nodes = vec![root];
        self.max_level = 0;
        self.flat = pack_boxes(&self.packs, prims);
    }

    /// Appends the wide node for binary node `at` (or, for a leaf root, for `kids`), and
    /// returns its index.
    fn collapse(
        &mut self,
        binary: &[Node],
        order: &[u32],
        prims: &[P::Item],
        at: usize,
        mut kids: Vec<usize>,
        level: usize,
    ) -> u32 {
        self.max_level = self.max_level.max(level);
        if kids.is_empty() {
            let first = binary[at].first as usize;
            kids = vec![first, first + 1];
        }
        // Open inner children until the node is full: first those bigger than this node's
        // groups (see `granularity`), then the largest.
        let g = granularity(binary[at].size as usize);
        while kids.len() < WIDTH {
            let key = |k: usize| (binary[k].size as usize > g, binary[k].bounds.area());
            let widest = kids
                .iter()
                .enumerate()
                .filter(|(_, k)| binary[**k].count == 0)
                .max_by(|a, b| {
                    let (ka, kb) = (key(*a.1), key(*b.1));
                    ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
                });
            let Some((slot, &k)) = widest else { break };
            let first = binary[k].first as usize;
            kids[slot] = first;
            kids.push(first + 1);
        }
        let index = self.nodes.len();
        let mut node_out = WideNode {
            planes: [F32x8::ZERO; 6],
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
                self.packs.push(P::pack(prims, ids));
                LEAF | (self.packs.len() - 1) as u32
            } else {
                self.collapse(binary, order, prims, k, Vec::new(), level + 1)
            };
            node_out.child[lane] = child;
            if child & LEAF != 0 {
                node_out.leaf_mask |= 1 << lane;
            } else {
                node_out.inner_mask |= 1 << lane;
            }
        }
        node_out.planes = box_planes::<WIDTH>(kids.iter().map(|&k| binary[k].bounds)).map(F32x8);
        self.nodes[index] = node_out;
        index as u32
    }
}

/// The planes (min x, y, z, then max x, y, z) of up to `N` boxes, one lane each; lanes past
/// them keep an inverted box (the masks leave them out anyway).
fn box_planes<const N: usize>(boxes: impl IntoIterator<Item = Aabb>) -> [[f32; N]; 6] {
    let mut planes = [[f32::INFINITY; N]; 6];
    planes[3..].fill([f32::NEG_INFINITY; N]);
    for (lane, b) in boxes.into_iter().take(N).enumerate() {
        for axis in 0..3 {
            planes[axis][lane] = b.min[axis];
            planes[axis + 3][lane] = b.max[axis];
        }
    }
    planes
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
        size: count as u32,
    };
    // A pack tests `WIDTH` spheres for the price of one, so never split what fits in one.
    if count <= MAX_LEAF {
        nodes[at] = leaf;
        return;
    }
    let binned = best_split(slice, &centroids, bounds);
    if count <= EXACT_SPLIT_LIMIT {
        let axis = binned.map_or_else(|| widest_axis(&centroids), |(axis, _)| axis);
        let mid = best_aligned_split(slice, bounds, axis);
        push_children(nodes, at, items, start, start + mid, end, bounds);
        return;
    }
    let Some((axis, split)) = binned else {
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

/// The size of the groups a node of `count` items is cut into so its subtree needs as few
/// wide levels as possible: a node of up to `WIDTH²` items is one wide node over packs of
/// `WIDTH`, one of up to `WIDTH³` is one over such nodes, and so on.
fn granularity(count: usize) -> usize {
    let mut g = MAX_LEAF;
    while g.saturating_mul(WIDTH) < count {
        g = g.saturating_mul(WIDTH);
    }
    g
}

/// Sorts `items` along `axis` (the binned SAH's choice) and returns where to split them: the
/// cheapest split by the SAH, over every position that keeps the items in as few groups of
/// `granularity` as the whole needs. So packs come out full, and a node of up to `WIDTH²`
/// spheres becomes one wide node whose children are all packs, with no half-empty level
/// below it (the cover's 486 spheres: 61 packs under 8 nodes under the root, where binned
/// splits gave 67 packs and five nodes of two or three packs on a third level).
fn best_aligned_split(items: &mut [BuildItem], bounds: Aabb, axis: usize) -> usize {
    let count = items.len();
    let g = granularity(count);
    let groups = |n: usize| n.div_ceil(g);
    let packs = |n: usize| n.div_ceil(WIDTH) as f32;
    let parent_area = bounds.area().max(f32::MIN_POSITIVE);
    sort_on_axis(items, axis);
    let mut right_area = vec![0.0f32; count + 1];
    let mut acc = Aabb::EMPTY;
    for i in (1..count).rev() {
        acc = acc.union(items[i].bounds);
        right_area[i] = acc.area();
    }
    // A multiple of `g` below `count` always qualifies, so there is a best.
    let mut best: Option<(f32, usize)> = None;
    let mut left = Aabb::EMPTY;
    for mid in 1..count {
        left = left.union(items[mid - 1].bounds);
        if groups(mid) + groups(count - mid) != groups(count) {
            continue;
        }
        let cost = TRAVERSAL_COST
            + (left.area() * packs(mid) + right_area[mid] * packs(count - mid)) / parent_area;
        if best.is_none_or(|(c, _)| cost < c) {
            best = Some((cost, mid));
        }
    }
    best.map_or(g, |(_, mid)| mid)
}

/// Sorts by centroid along `axis`, ties by id: a total order, so the tree is the same on
/// every run.
fn sort_on_axis(items: &mut [BuildItem], axis: usize) {
    items.sort_unstable_by_key(|it| {
        // `f32::total_cmp`'s order, as an unsigned integer, then the id.
        let bits = it.centroid[axis].to_bits() as i32;
        let ordered = (bits ^ (((bits >> 31) as u32) >> 1) as i32) as u32 ^ (1 << 31);
        (u64::from(ordered) << 32) | u64::from(it.id)
    });
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
        size: 0,
    };
    nodes.push(placeholder);
    nodes.push(placeholder);
    nodes[at] = Node {
        bounds,
        first: left as u32,
        count: 0,
        size: (end - start) as u32,
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

/// The SAH's cheapest (axis, first bin of the right side), for items too many for one leaf;
/// `None` when no bin boundary separates their centroids.
fn best_split(items: &[BuildItem], centroids: &Aabb, bounds: Aabb) -> Option<(usize, usize)> {
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
    best.map(|(_, axis, split)| (axis, split))
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
