//! A few quads tested against sixteen rays at once, a lane per ray and no hierarchy: for scenes
//! as small as the Cornell box, whose paths are traced sixteen at a time
//! (`integrator::batch`). Sixteen independent rays keep the processor busy where one ray's
//! walk waits on its box tests, its division and its branches. The arithmetic is
//! `QuadPack`'s, lane by lane, with a quad's values in every lane instead of a ray's, so each
//! lane finds the same hit, bit for bit, as that ray's walk through the tree.

use super::NO_HIT;
use super::pack::beats;
use crate::geometry::{Medium, PrimitiveId, Quad};
use crate::math::Interval;
use crate::ray::Ray;
use crate::simd::{F32x8, Isa, Lanes};

/// Rays a batch holds: one per lane, in halves of eight (two independent computations per
/// quad, which the processor overlaps).
pub const BATCH: usize = 16;
const HALF: usize = 8;

/// One quad's values as the test takes them (see `Quad::plane_hit`).
#[derive(Clone, Copy, Debug)]
struct QuadRow {
    normal: [f32; 3],
    d: f32,
    corner: [f32; 3],
    along_u: [f32; 3],
    along_v: [f32; 3],
    /// The quad's index among the scene's quads, as a float.
    index: f32,
    /// Its id's bits as a float's, moved (never computed with) into the lanes that hit it.
    id_bits: f32,
}

/// The quads of a scene small enough to test every one against every ray.
#[derive(Clone, Debug, Default)]
pub struct QuadBatch {
    rows: Vec<QuadRow>,
}

/// Half a batch: eight rays as the test takes them, a lane each.
#[derive(Clone, Copy, Debug)]
struct RayHalf {
    origin: [F32x8; 3],
    dir: [F32x8; 3],
    /// Hits count beyond this; `+∞` in a lane without a ray.
    t_min: F32x8,
    /// And up to this.
    t_max: F32x8,
    /// The index among the quads of the one the lane's ray leaves and cannot meet again
    /// (`RayHints::leaving`), as a float; -1 for none.
    skip: F32x8,
}

/// `BATCH` rays as the batch test takes them, a lane each.
#[derive(Clone, Copy, Debug)]
pub struct RayBatch {
    halves: [RayHalf; 2],
}

impl Default for RayBatch {
    fn default() -> Self {
        let half = RayHalf {
            origin: [F32x8::ZERO; 3],
            dir: [F32x8([1.0; HALF]); 3],
            t_min: F32x8([f32::INFINITY; HALF]),
            t_max: F32x8([f32::INFINITY; HALF]),
            skip: F32x8([-1.0; HALF]),
        };
        RayBatch { halves: [half; 2] }
    }
}

impl RayBatch {
    /// Puts `ray` in `lane`, its hits counted within `interval`, leaving primitive `leaving`
    /// (an id; only a quad's is used).
    #[inline(always)]
    pub fn set(&mut self, lane: usize, ray: &Ray, interval: Interval, leaving: u32) {
        let (h, lane) = (&mut self.halves[lane / HALF % 2], lane % HALF);
        for axis in 0..3 {
            h.origin[axis].0[lane] = ray.origin[axis];
            h.dir[axis].0[lane] = ray.dir[axis];
        }
        h.t_min.0[lane] = interval.min;
        h.t_max.0[lane] = interval.max;
        let quad = PrimitiveId(leaving);
        h.skip.0[lane] = if (PrimitiveId::QUADS..PrimitiveId::MEDIA).contains(&quad.0) {
            quad.index() as f32
        } else {
            -1.0
        };
    }

    /// Leaves `lane` without a ray: nothing hits it.
    #[inline(always)]
    pub fn clear(&mut self, lane: usize) {
        self.halves[lane / HALF % 2].t_min.0[lane % HALF] = f32::INFINITY;
    }

    /// Hits in `lane` count beyond this.
    #[inline(always)]
    pub fn t_min(&self, lane: usize) -> f32 {
        self.halves[lane / HALF % 2].t_min.0[lane % HALF]
    }
}

/// A half's rays in lanes, and the closest hit so far of each.
struct HalfLanes<I: Isa> {
    o: [Lanes<I>; 3],
    dir: [Lanes<I>; 3],
    t_min: Lanes<I>,
    skip: Lanes<I>,
    closest: Lanes<I>,
    /// The id of the quad found, its bits as a float's (`QuadRow::id_bits`); `NO_HIT`'s
    /// for none.
    found: Lanes<I>,
}

impl<I: Isa> HalfLanes<I> {
    #[inline(always)]
    fn load(isa: I, h: &RayHalf) -> Self {
        let load3 = |v: &[F32x8; 3]| v.each_ref().map(|v| Lanes::load(isa, v));
        HalfLanes {
            o: load3(&h.origin),
            dir: load3(&h.dir),
            t_min: Lanes::load(isa, &h.t_min),
            skip: Lanes::load(isa, &h.skip),
            closest: Lanes::load(isa, &h.t_max),
            found: Lanes::splat(isa, f32::from_bits(NO_HIT)),
        }
    }

    /// Tests quad `q`, keeping each lane's hit when it is nearer than the closest so far
    /// (quads come in the order of their ids, so a tie keeps the lower id found before).
    #[inline(always)]
    fn test(&mut self, q: &QuadRow) {
        let isa = self.t_min.isa();
        let s = |x: f32| Lanes::splat(isa, x);
        let (o, dir) = (&self.o, &self.dir);
        let n = q.normal.map(s);
        // `QuadPack::intersect`'s expressions, operand for operand.
        let denom = n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2];
        let t = (s(q.d) - (n[0] * o[0] + n[1] * o[1] + n[2] * o[2])) / denom;
        let c = q.corner.map(s);
        let (fx, fy, fz) = (o[0] - c[0], o[1] - c[1], o[2] - c[2]);
        let (au, av) = (q.along_u.map(s), q.along_v.map(s));
        let a0 = fx * au[0] + fy * au[1] + fz * au[2];
        let da = dir[0] * au[0] + dir[1] * au[1] + dir[2] * au[2];
        let b0 = fx * av[0] + fy * av[1] + fz * av[2];
        let db = dir[0] * av[0] + dir[1] * av[1] + dir[2] * av[2];
        let facing = denom.fast_max(-denom).simd_ge(s(1e-8));
        let index = s(q.index);
        let apart = self.skip - index;
        let not_left = apart.fast_max(-apart).simd_ge(s(0.5));
        let (a, b) = (a0 + t * da, b0 + t * db);
        // Both edge coordinates in [0, 1] as the least at least 0 and the greatest at most
        // 1: the same lanes, as `a` or `b` is NaN only where `t` is infinite, which the
        // interval refuses anyway.
        let inside = a.fast_min(b).simd_ge(s(0.0)) & a.fast_max(b).simd_le(s(1.0));
        let hit = self.t_min.simd_lt(t) & t.simd_lt(self.closest) & inside & facing & not_left;
        self.closest = hit.select(t, self.closest);
        self.found = hit.select(s(q.id_bits), self.found);
    }
}

impl QuadBatch {
    /// The most quads a batch tests: beyond, the tree's walk tests fewer.
    pub const MAX: usize = 32;

    /// The batch of `quads` (at most `MAX`; their ids are their indices from
    /// `PrimitiveId::QUADS`).
    pub fn new(quads: &[Quad]) -> Self {
        let rows = (quads.iter().enumerate())
            .map(|(index, q)| {
                let (normal, d) = q.plane();
                let (along_u, along_v) = q.edge_duals();
                QuadRow {
                    normal: normal.to_array(),
                    d,
                    corner: q.corner.to_array(),
                    along_u: along_u.to_array(),
                    along_v: along_v.to_array(),
                    index: index as f32,
                    id_bits: f32::from_bits(PrimitiveId::QUADS + index as u32),
                }
            })
            .collect();
        QuadBatch { rows }
    }

    /// Each lane's closest hit among the quads: its parameter and id (`NO_HIT` for none),
    /// the nearest within `(t_min, t_max)`, a tie going to the lower id.
    #[inline(always)]
    pub fn intersect<I: Isa>(&self, isa: I, rays: &RayBatch) -> ([f32; BATCH], [u32; BATCH]) {
        let mut low = HalfLanes::load(isa, &rays.halves[0]);
        let mut high = HalfLanes::load(isa, &rays.halves[1]);
        for q in &self.rows {
            low.test(q);
            high.test(q);
        }
        let mut t = [0.0; BATCH];
        let mut ids = [NO_HIT; BATCH];
        for (i, h) in [low, high].iter().enumerate() {
            t[i * HALF..][..HALF].copy_from_slice(&h.closest.to_array());
            ids[i * HALF..][..HALF].copy_from_slice(&h.found.to_array().map(f32::to_bits));
        }
        (t, ids)
    }
}

/// Takes a hit among `media` (ids from `PrimitiveId::MEDIA`) that beats `(closest, found)`,
/// for one ray at `time` with the segment's medium key `key` (`MediumPack`'s test).
#[inline(always)]
pub fn media_hit(
    media: &[Medium],
    ray: &Ray,
    time: f32,
    key: u32,
    t_min: f32,
    closest: &mut f32,
    found: &mut u32,
) {
    for (i, medium) in media.iter().enumerate() {
        let id = PrimitiveId::MEDIA + i as u32;
        let interval = Interval::new(t_min, f32::INFINITY);
        if let Some(t) = medium.intersect(ray, time, key, id, interval)
            && beats(t, id, *closest, *found)
        {
            *closest = t;
            *found = id;
        }
    }
}
