//! Candidate lists: the few spheres a bundle of rays (one tile's camera rays) can reach,
//! picked by walking the tree and tested together without it.

use super::pack::{SpherePack, hit_of, splat3};
use super::{Bvh, EMPTY, LEAF, NO_HIT, NO_SPHERE, WIDTH};
use crate::geometry::{PrimitiveId, Sphere};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use crate::simd::{Ids, Isa, Lanes};

/// A few spheres picked out for a bundle of rays (the camera rays of one tile), giants
/// included, tested together in SIMD packs without walking the tree.
#[derive(Clone, Debug)]
pub struct Candidates {
    pub(super) packs: Vec<SpherePack>,
}

impl Candidates {
    /// At most this many spheres are worth a list: beyond it the tree is faster.
    pub const MAX: usize = 2 * WIDTH;
}

impl Bvh<SpherePack> {
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
            let planes = node.planes.map(|plane| plane.0);
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
    #[inline(always)]
    pub fn intersect_candidates<I: Isa>(
        &self,
        isa: I,
        candidates: &Candidates,
        ray: &Ray,
        interval: Interval,
    ) -> Option<(f32, PrimitiveId)> {
        let (mut closest, mut found) = (interval.max, NO_HIT);
        let (o, d) = (splat3(isa, ray.origin), splat3(isa, ray.dir));
        let t_min = Lanes::splat(isa, interval.min);
        let skip = Ids::splat(isa, NO_SPHERE);
        for pack in &candidates.packs {
            pack.intersect(&o, &d, t_min, skip, &mut closest, &mut found);
        }
        hit_of(closest, found)
    }
}
