//! A pack of up to `WIDTH` moving spheres: each lane's centre at the ray's time, then the
//! still spheres' test (`pack::hit_balls`), with the same arithmetic, lane by lane, as
//! `MovingSphere::intersect`.

use super::pack::hit_balls;
use super::{Leaf, Moment, NO_SPHERE, PackRay, WIDTH};
use crate::geometry::{Aabb, MovingSphere, PrimitiveId};
use crate::math::Interval;
use crate::ray::Ray;
use crate::simd::{F32x8, Isa, Lanes, U32x8};

/// Up to `WIDTH` moving spheres; unused lanes have `r2 = -1`, which no ray can hit.
#[derive(Clone, Copy, Debug)]
pub struct MovingSpherePack {
    center0: [F32x8; 3],
    delta: [F32x8; 3],
    time0: F32x8,
    inv_duration: F32x8,
    r2: F32x8,
    id: U32x8,
}

impl Leaf for MovingSpherePack {
    type Item = MovingSphere;
    const ID_BASE: u32 = PrimitiveId::MOVING_SPHERES;

    fn bounds(item: &MovingSphere) -> Aabb {
        item.bounds()
    }

    fn pack(items: &[MovingSphere], indices: &[u32]) -> Self {
        let mut center0 = [[0.0; WIDTH]; 3];
        let mut delta = [[0.0; WIDTH]; 3];
        let mut time0 = [0.0; WIDTH];
        let mut inv_duration = [0.0; WIDTH];
        let mut r2 = [-1.0; WIDTH];
        let mut id = [NO_SPHERE; WIDTH];
        for (lane, &i) in indices.iter().enumerate() {
            let s = &items[i as usize];
            let d = s.center1 - s.center0;
            for axis in 0..3 {
                center0[axis][lane] = s.center0[axis];
                delta[axis][lane] = d[axis];
            }
            time0[lane] = s.time0;
            inv_duration[lane] = s.inv_duration;
            r2[lane] = s.radius * s.radius;
            id[lane] = Self::ID_BASE + i;
        }
        MovingSpherePack {
            center0: center0.map(F32x8),
            delta: delta.map(F32x8),
            time0: F32x8(time0),
            inv_duration: F32x8(inv_duration),
            r2: F32x8(r2),
            id: U32x8(id),
        }
    }

    fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.id.0.iter().copied().filter(|&id| id != NO_SPHERE)
    }

    #[inline(always)]
    fn intersect<I: Isa>(&self, ray: &PackRay<'_, I>, closest: &mut f32, found: &mut u32) {
        let isa = ray.t_min.isa();
        let time = Lanes::splat(isa, ray.moment.time);
        let s = (time - Lanes::load(isa, &self.time0)) * Lanes::load(isa, &self.inv_duration);
        let at = |axis: usize| {
            Lanes::load(isa, &self.center0[axis]) + s * Lanes::load(isa, &self.delta[axis])
        };
        let center = [at(0), at(1), at(2)];
        let r2 = Lanes::load(isa, &self.r2);
        hit_balls(
            center, r2, &self.id, ray.o, ray.d, ray.t_min, ray.skip, closest, found,
        );
    }

    #[inline(always)]
    fn intersect_one(
        item: &MovingSphere,
        _: u32,
        ray: &Ray,
        moment: Moment,
        interval: Interval,
    ) -> Option<f32> {
        item.intersect(ray, moment.time, interval)
    }
}
