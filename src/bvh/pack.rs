//! A pack of up to `WIDTH` spheres in structure-of-arrays form, tested against one ray at
//! once with the same arithmetic, lane by lane, as `Sphere::intersect`.

use super::{Lanes, NO_HIT, NO_SPHERE, WIDTH};
use crate::geometry::{PrimitiveId, Sphere};
use crate::math::Vec3;
use wide::u32x8;

/// Up to `WIDTH` spheres in structure-of-arrays form; unused lanes have `r2 = -1`, which no
/// ray can hit.
#[derive(Clone, Copy, Debug)]
pub(super) struct SpherePack {
    center: [Lanes; 3],
    r2: Lanes,
    id: [u32; WIDTH],
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
            center: center.map(Lanes::from),
            r2: Lanes::from(r2),
            id,
        }
    }

    /// The ids of the spheres the pack holds, leaving out its unused lanes.
    pub(super) fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.id.iter().copied().filter(|&id| id != NO_SPHERE)
    }

    /// Takes a hit among the spheres that beats `(closest, found)`, the best so far: the
    /// nearest within `(t_min, closest]`, ties going to the lower primitive id wherever
    /// they are met, so every traversal order finds the same hit. The same arithmetic, lane
    /// by lane, as `Sphere::intersect`.
    #[inline(always)]
    pub(super) fn intersect(
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

/// The lowest set lane of a non-empty lane mask. (Masked to `WIDTH`, which changes nothing
/// but lets the compiler drop the bounds checks of indexing by it.)
#[inline(always)]
pub(super) fn lowest_lane(mask: u32) -> usize {
    mask.trailing_zeros() as usize & (WIDTH - 1)
}

#[inline(always)]
pub(super) fn splat3(v: Vec3) -> [Lanes; 3] {
    [Lanes::splat(v.x), Lanes::splat(v.y), Lanes::splat(v.z)]
}

pub(super) fn hit_of(closest: f32, found: u32) -> Option<(f32, PrimitiveId)> {
    (found != NO_HIT).then_some((closest, PrimitiveId(found)))
}
