//! A pack of up to `WIDTH` quads in structure-of-arrays form, tested against one ray at once
//! with the same arithmetic, lane by lane, as `Quad::plane_hit`.

use super::pack::{take_nearest, within};
use super::{Leaf, Moment, NO_SPHERE, PackRay, WIDTH, index_of};
use crate::geometry::{Aabb, PrimitiveId, Quad};
use crate::math::Interval;
use crate::ray::Ray;
use crate::simd::{F32x8, Ids, Isa, Lanes, U32x8};

/// Up to `WIDTH` quads; unused lanes have a zero normal, which no ray's test passes.
#[derive(Clone, Copy, Debug)]
pub struct QuadPack {
    corner: [F32x8; 3],
    along_u: [F32x8; 3],
    along_v: [F32x8; 3],
    normal: [F32x8; 3],
    d: F32x8,
    id: U32x8,
}

impl Leaf for QuadPack {
    type Item = Quad;
    const ID_BASE: u32 = PrimitiveId::QUADS;
    // A quad's test waits on a division before it can miss.
    const OVERLAP: bool = true;
    // The book's Cornell box: five walls and a lamp around two blocks.
    const CLUSTERED: bool = true;

    fn bounds(item: &Quad) -> Aabb {
        item.bounds()
    }

    fn pack(items: &[Quad], indices: &[u32]) -> Self {
        let mut lanes = [[[0.0f32; WIDTH]; 3]; 4];
        let mut d = [0.0; WIDTH];
        let mut id = [NO_SPHERE; WIDTH];
        for (lane, &i) in indices.iter().enumerate() {
            let q = &items[i as usize];
            let (normal, offset) = q.plane();
            let (along_u, along_v) = q.edge_duals();
            for (field, value) in [q.corner, along_u, along_v, normal].iter().enumerate() {
                for axis in 0..3 {
                    lanes[field][axis][lane] = value[axis];
                }
            }
            d[lane] = offset;
            id[lane] = Self::ID_BASE + i;
        }
        let [corner, along_u, along_v, normal] = lanes.map(|field| field.map(F32x8));
        QuadPack {
            corner,
            along_u,
            along_v,
            normal,
            d: F32x8(d),
            id: U32x8(id),
        }
    }

    fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.id.0.iter().copied().filter(|&id| id != NO_SPHERE)
    }

    #[inline(always)]
    fn intersect<I: Isa>(&self, ray: &PackRay<'_, I>, closest: &mut f32, found: &mut u32) {
        let isa = ray.t_min.isa();
        let load3 = |v: &[F32x8; 3]| {
            [
                Lanes::load(isa, &v[0]),
                Lanes::load(isa, &v[1]),
                Lanes::load(isa, &v[2]),
            ]
        };
        let (o, dir) = (ray.o, ray.d);
        let n = load3(&self.normal);
        let denom = n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2];
        let t = (Lanes::load(isa, &self.d) - (n[0] * o[0] + n[1] * o[1] + n[2] * o[2])) / denom;
        // Beside the division: the edge coordinates' parts that do not wait on it.
        let c = load3(&self.corner);
        let (fx, fy, fz) = (o[0] - c[0], o[1] - c[1], o[2] - c[2]);
        let (au, av) = (load3(&self.along_u), load3(&self.along_v));
        let a0 = fx * au[0] + fy * au[1] + fz * au[2];
        let da = dir[0] * au[0] + dir[1] * au[1] + dir[2] * au[2];
        let b0 = fx * av[0] + fy * av[1] + fz * av[2];
        let db = dir[0] * av[0] + dir[1] * av[1] + dir[2] * av[2];
        let facing = denom
            .fast_max(-denom)
            .simd_ge(Lanes::splat(isa, 1e-8))
            .to_bitmask()
            & !Ids::load(isa, &self.id).eq_bitmask(ray.skip);
        let (a, b) = (a0 + t * da, b0 + t * db);
        let (zero, one) = (Lanes::splat(isa, 0.0), Lanes::splat(isa, 1.0));
        let hi = Lanes::splat(isa, *closest);
        let inside = within(t, ray.t_min, hi)
            & a.simd_ge(zero)
            & a.simd_le(one)
            & b.simd_ge(zero)
            & b.simd_le(one);
        let hits = inside.to_bitmask() & facing;
        if hits == 0 {
            return;
        }
        take_nearest(hits, &t.to_array(), &self.id, closest, found);
    }

    #[inline(always)]
    fn intersect_one(item: &Quad, _: u32, ray: &Ray, _: Moment, interval: Interval) -> Option<f32> {
        item.intersect(ray, interval)
    }
}

impl QuadPack {
    /// The quad of `id` among `quads`.
    pub fn quad_of(quads: &[Quad], id: u32) -> &Quad {
        &quads[index_of::<Self>(id)]
    }
}
