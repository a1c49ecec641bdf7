//! A pack of up to `WIDTH` spheres in structure-of-arrays form, tested against one ray at
//! once with the same arithmetic, lane by lane, as `Sphere::intersect`; and what every
//! kind's pack shares (the tie rule, lane helpers).

use super::{Leaf, Moment, NO_HIT, NO_SPHERE, PackRay, WIDTH};
use crate::geometry::{Aabb, PrimitiveId, Sphere};
use crate::math::{Interval, Vec3};
use crate::ray::Ray;
use crate::simd::{F32x8, Ids, Isa, Lanes, Mask, U32x8};

/// Up to `WIDTH` spheres in structure-of-arrays form; unused lanes have `r2 = -1`, which no
/// ray can hit.
#[derive(Clone, Copy, Debug)]
pub struct SpherePack {
    center: [F32x8; 3],
    r2: F32x8,
    id: U32x8,
}

impl Leaf for SpherePack {
    type Item = Sphere;
    const ID_BASE: u32 = PrimitiveId::SPHERES;

    fn bounds(item: &Sphere) -> Aabb {
        item.bounds()
    }

    fn pack(items: &[Sphere], indices: &[u32]) -> Self {
        Self::new(items, indices)
    }

    fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        SpherePack::ids(self)
    }

    #[inline(always)]
    fn intersect<I: Isa>(&self, ray: &PackRay<'_, I>, closest: &mut f32, found: &mut u32) {
        SpherePack::intersect(self, ray.o, ray.d, ray.t_min, ray.skip, closest, found);
    }

    #[inline(always)]
    fn intersect_one(
        item: &Sphere,
        _: u32,
        ray: &Ray,
        _: Moment,
        interval: Interval,
    ) -> Option<f32> {
        item.intersect(ray, interval)
    }

    fn as_sphere(item: &Sphere) -> Option<(Vec3, f32)> {
        Some((item.center, item.radius))
    }
}

impl SpherePack {
    pub(super) fn new(spheres: &[Sphere], ids: &[u32]) -> Self {
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
            center: center.map(F32x8),
            r2: F32x8(r2),
            id: U32x8(id),
        }
    }

    /// The ids of the spheres the pack holds, leaving out its unused lanes.
    pub fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.id.0.iter().copied().filter(|&id| id != NO_SPHERE)
    }

    /// Takes a hit among the spheres that beats `(closest, found)`, the best so far: the
    /// nearest within `(t_min, closest]`, ties going to the lower primitive id wherever
    /// they are met, so every traversal order finds the same hit. The same arithmetic, lane
    /// by lane, as `Sphere::intersect`.
    #[inline(always)]
    pub(super) fn intersect<I: Isa>(
        &self,
        o: &[Lanes<I>; 3],
        d: &[Lanes<I>; 3],
        t_min: Lanes<I>,
        skip: Ids<I>,
        closest: &mut f32,
        found: &mut u32,
    ) {
        let isa = t_min.isa();
        let center = [
            Lanes::load(isa, &self.center[0]),
            Lanes::load(isa, &self.center[1]),
            Lanes::load(isa, &self.center[2]),
        ];
        let r2 = Lanes::load(isa, &self.r2);
        hit_balls(center, r2, &self.id, o, d, t_min, skip, closest, found);
    }
}

/// The pack test of balls of centres `center` and squared radii `r2` (the lanes of a pack
/// with ids `ids`): `SpherePack::intersect`, shared with the moving spheres' pack.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn hit_balls<I: Isa>(
    center: [Lanes<I>; 3],
    r2: Lanes<I>,
    ids: &U32x8,
    o: &[Lanes<I>; 3],
    d: &[Lanes<I>; 3],
    t_min: Lanes<I>,
    skip: Ids<I>,
    closest: &mut f32,
    found: &mut u32,
) {
    let isa = t_min.isa();
    let zero = Lanes::splat(isa, 0.0);
    let fx = o[0] - center[0];
    let fy = o[1] - center[1];
    let fz = o[2] - center[2];
    let b = -(fx * d[0] + fy * d[1] + fz * d[2]);
    let (gx, gy, gz) = (fx + b * d[0], fy + b * d[1], fz + b * d[2]);
    let disc = r2 - (gx * gx + gy * gy + gz * gz);
    // Lanes whose line meets the sphere, less the sphere the ray is known to leave.
    let valid = disc.simd_ge(zero).to_bitmask() & !Ids::load(isa, ids).eq_bitmask(skip);
    // Most packs a ray reaches it misses outright: leave before the square root.
    if valid == 0 {
        return;
    }
    let sq = disc.fast_max(zero).sqrt();
    let q = b.simd_ge(zero).select(b + sq, b - sq);
    let c = (fx * fx + fy * fy + fz * fz) - r2;
    let q_zero = q.simd_eq(zero);
    let t0 = q_zero.select(zero, c / q);
    let t1 = q_zero.select(zero, q);
    let (near, far) = (t0.fast_min(t1), t0.fast_max(t1));
    let hi = Lanes::splat(isa, *closest);
    let inf = Lanes::splat(isa, f32::INFINITY);
    let t = within(near, t_min, hi).select(near, within(far, t_min, hi).select(far, inf));
    let hits = t.simd_lt(inf).to_bitmask() & valid;
    if hits == 0 {
        return;
    }
    take_nearest(hits, &t.to_array(), ids, closest, found);
}

/// The lanes of `t` in `(t_min, hi]`. (Not a closure: only a function can be marked to be
/// inlined into the dispatched code.)
#[inline(always)]
pub(super) fn within<I: Isa>(t: Lanes<I>, t_min: Lanes<I>, hi: Lanes<I>) -> Mask<I> {
    t_min.simd_lt(t) & t.simd_le(hi)
}

/// Of the lanes `hits` (not empty) with parameters `t` and ids `ids`, takes the nearest (the
/// lower id on a tie) when it `beats` `(closest, found)`.
#[inline(always)]
pub(super) fn take_nearest(
    hits: u32,
    t: &[f32; WIDTH],
    ids: &U32x8,
    closest: &mut f32,
    found: &mut u32,
) {
    let mut lane = lowest_lane(hits);
    // Rarely does a ray meet two primitives of one pack: then the nearer.
    let mut rest = hits & (hits - 1);
    while rest != 0 {
        let other = lowest_lane(rest);
        rest &= rest - 1;
        if (t[other], ids.0[other]) < (t[lane], ids.0[lane]) {
            lane = other;
        }
    }
    let (t, id) = (t[lane], ids.0[lane]);
    if beats(t, id, *closest, *found) {
        *closest = t;
        *found = id;
    }
}

/// Whether a hit `(t, id)` beats `(closest, found)`, the best so far: nearer, or as near with
/// a lower id, so every order of tests finds the same hit. A tie with the best so far counts
/// only against a real hit, not the interval's end.
#[inline(always)]
pub(super) fn beats(t: f32, id: u32, closest: f32, found: u32) -> bool {
    t < closest || (t == closest && found != NO_HIT && id < found)
}

/// The lowest set lane of a non-empty mask of `WIDTH` lanes.
#[inline(always)]
pub(super) fn lowest_lane(mask: u32) -> usize {
    lowest_of::<WIDTH>(mask)
}

/// The lowest set lane of a non-empty mask of `N` lanes (a power of two). (Masked to `N`,
/// which changes nothing but lets the compiler drop the bounds checks of indexing by it.)
#[inline(always)]
pub(super) fn lowest_of<const N: usize>(mask: u32) -> usize {
    mask.trailing_zeros() as usize & (N - 1)
}

#[inline(always)]
pub(super) fn splat3<I: Isa>(isa: I, v: Vec3) -> [Lanes<I>; 3] {
    [
        Lanes::splat(isa, v.x),
        Lanes::splat(isa, v.y),
        Lanes::splat(isa, v.z),
    ]
}

pub(super) fn hit_of(closest: f32, found: u32) -> Option<(f32, PrimitiveId)> {
    (found != NO_HIT).then_some((closest, PrimitiveId(found)))
}
