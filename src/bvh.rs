//! A bounding volume hierarchy over spheres: a flat node array built with the binned surface
//! area heuristic, traversed front to back with a fixed-size stack.

use crate::geometry::{Aabb, PrimitiveId, Sphere};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;

/// Leaves hold at most this many primitives.
const MAX_LEAF: usize = 4;
/// Number of SAH bins per axis.
const BINS: usize = 12;
/// Traversal stack depth; a build over `u32` primitives cannot exceed it.
const STACK: usize = 64;

/// One node: its bounds, and either two children (`count == 0`, children at `first` and
/// `first + 1`) or a leaf of `count` primitives starting at `first` in `Bvh::order`.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    first: u32,
    count: u32,
    axis: u8,
}

/// The hierarchy. Primitives are referenced through `order`, a permutation of the scene's
/// primitive ids, so the scene keeps its own indexing.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
    spheres: Vec<Sphere>,
}

struct BuildItem {
    bounds: Aabb,
    centroid: Vec3,
    id: u32,
}

impl Bvh {
    /// Builds the hierarchy over `spheres`, keeping a copy in traversal order.
    pub fn build(spheres: &[Sphere]) -> Self {
        let mut items: Vec<BuildItem> = spheres
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let bounds = s.bounds();
                BuildItem {
                    bounds,
                    centroid: bounds.centroid(),
                    id: i as u32,
                }
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * spheres.len().max(1));
        if !items.is_empty() {
            nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: 0,
                count: 0,
                axis: 0,
            });
            let len = items.len();
            build_node(&mut nodes, 0, &mut items, 0, len);
        }
        let order: Vec<u32> = items.iter().map(|it| it.id).collect();
        let spheres = order.iter().map(|&i| spheres[i as usize]).collect();
        Self {
            nodes,
            order,
            spheres,
        }
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The closest hit in `interval`: its parameter and primitive id.
    #[inline]
    pub fn intersect(&self, ray: &Ray, interval: Interval) -> Option<(f32, PrimitiveId)> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv_dir = ray.dir.recip();
        let negative = [ray.dir.x < 0.0, ray.dir.y < 0.0, ray.dir.z < 0.0];
        let mut closest = interval.max;
        let mut found: Option<u32> = None;
        let mut stack = [0u32; STACK];
        let mut top = 0usize;
        let mut index = 0u32;
        loop {
            let node = &self.nodes[index as usize];
            if node
                .bounds
                .hit(ray.origin, inv_dir, interval.min, closest)
                .is_some()
            {
                if node.count > 0 {
                    let start = node.first as usize;
                    for slot in start..start + node.count as usize {
                        let range = Interval::new(interval.min, closest);
                        if let Some(t) = self.spheres[slot].intersect(ray, range) {
                            closest = t;
                            found = Some(slot as u32);
                        }
                    }
                } else {
                    // Visit the child on the ray's near side first; push the other.
                    let (near, far) = if negative[node.axis as usize] {
                        (node.first + 1, node.first)
                    } else {
                        (node.first, node.first + 1)
                    };
                    stack[top] = far;
                    top += 1;
                    index = near;
                    continue;
                }
            }
            if top == 0 {
                break;
            }
            top -= 1;
            index = stack[top];
        }
        found.map(|slot| (closest, PrimitiveId(self.order[slot as usize])))
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
        axis: 0,
    };
    if count <= 1 {
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
        push_children(
            nodes,
            at,
            items,
            start,
            start + count / 2,
            end,
            bounds,
            axis,
        );
        return;
    };
    let mut mid = partition(slice, |it| {
        bin_of(it.centroid[axis], &centroids, axis) < split
    });
    if mid == 0 || mid == count {
        mid = count / 2;
    }
    push_children(nodes, at, items, start, start + mid, end, bounds, axis);
}

#[allow(clippy::too_many_arguments)]
fn push_children(
    nodes: &mut Vec<Node>,
    at: usize,
    items: &mut [BuildItem],
    start: usize,
    mid: usize,
    end: usize,
    bounds: Aabb,
    axis: usize,
) {
    let left = nodes.len();
    let placeholder = Node {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
        axis: 0,
    };
    nodes.push(placeholder);
    nodes.push(placeholder);
    nodes[at] = Node {
        bounds,
        first: left as u32,
        count: 0,
        axis: axis as u8,
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
    let leaf_cost = items.len() as f32;
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
            let cost = 1.0
                + (acc.area() * n as f32 + right_area[split] * right_count[split] as f32)
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
            for _ in 0..4000 {
                let o = Vec3::new(
                    rng.range(-15.0, 15.0),
                    rng.range(0.0, 6.0),
                    rng.range(-15.0, 15.0),
                );
                let ray = Ray::new(o, rng.unit_vector());
                let iv = Interval::new(1e-4, f32::INFINITY);
                let a = bvh.intersect(&ray, iv);
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
    fn leaves_stay_small_even_for_coincident_spheres() {
        let spheres = vec![Sphere::new(Vec3::ZERO, 1.0, MaterialId(0)); 40];
        let bvh = Bvh::build(&spheres);
        assert!(bvh.nodes.iter().all(|n| n.count as usize <= MAX_LEAF));
        let ray = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
        assert_eq!(
            bvh.intersect(&ray, Interval::new(0.0, 100.0)).unwrap().0,
            4.0
        );
    }
}
