//! A layer grid: a shortcut through the tree for rays in or over a thin layer of spheres, such
//! as the book's cover (hundreds of small spheres on the ground under three tall ones).
//!
//! The tree's spheres are split at a height: the few whose tops rise above it are "tall", the
//! rest make the layer, between their lowest bottom and that height.
//!
//! - A ray that never enters the layer (above it heading up, below it heading down) can meet
//!   only the tall spheres: one pack of them.
//! - A ray from a point below the layer's top meets layer spheres only before it climbs
//!   above the top or falls below the bottom, so only within a horizontal distance of its
//!   origin that its direction gives (its reach). The ground plane (x, z) under the layer is
//!   cut into square cells; each cell keeps two packs, of the tall spheres and the layer
//!   spheres nearest the cell, and the distance beyond which every other layer sphere lies.
//!   A ray whose reach falls short of its cell's needs only those packs.
//!
//! Either way there is no box test and no walk; the giants are tested as ever. Rays beyond
//! their cell's reach, outside the grid, or from origins far outside the scene walk the tree.
//!
//! Every distance is kept short of the geometry by a margin far above `f32` rounding at the
//! scene's scale, so a sphere left out cannot be hit even by rounding: the hits are the
//! tree's, bit for bit (`bvh::tests` check them against brute force and against the tree).

use super::{Leaf, WIDTH};
use crate::math::Vec3;
use crate::simd::index_below;

/// At most this many tall spheres (they share every cell's pack with the nearest layer
/// spheres).
const MAX_TALL: usize = 3;
/// Fewer layer spheres than this: the tree alone is fast enough.
const MIN_LAYER: usize = 64;
/// At most this many cells, which bounds the grid's memory (two packs per cell), and this
/// many (layer sphere, cell) pairs, the build's work.
const MAX_CELLS: usize = 4096;
const MAX_PAIRS: usize = 1 << 22;
/// Cells per layer sphere, about: a cell about as wide as the spacing of the spheres.
const CELLS_PER_SPHERE: f32 = 1.0;

/// Packs per cell. One reached too few rays; three cost more to test than they saved
/// (`docs/performance.md`).
const CELL_PACKS: usize = 2;

/// A cell: its packs, and the squared horizontal distance from the cell within which no
/// layer sphere outside them lies.
#[derive(Clone, Debug)]
struct Cell<P: Leaf> {
    reach2: f32,
    packs: [P; CELL_PACKS],
}

/// The grid (see the module's notes), over primitives that are still spheres
/// (`Leaf::as_sphere`).
#[derive(Clone, Debug)]
pub(super) struct LayerGrid<P: Leaf> {
    /// The heights a ray must start between (the layer's bottom and top, widened by the
    /// margin).
    bottom: f32,
    top: f32,
    /// Origins farther than this from the scene's coordinate origin on any axis walk (see
    /// the margin in `build`).
    far: f32,
    /// The grid's corner (least x and z) and `1 / cell width`.
    x0: f32,
    z0: f32,
    inv_cell: f32,
    /// Cells along x and z, as integers and as `f32` (exact: at most `MAX_CELLS`), so the
    /// lookup converts no integer to a float.
    nx: usize,
    nx_f: f32,
    nz_f: f32,
    cells: Vec<Cell<P>>,
    /// The tall spheres alone, for rays that never enter the layer.
    tall: P,
}

/// A still sphere as the grid takes it.
struct Ball {
    center: Vec3,
    radius: f32,
}

impl Ball {
    fn bounds(&self) -> (Vec3, Vec3) {
        let r = Vec3::splat(self.radius.abs());
        (self.center - r, self.center + r)
    }
}

impl<P: Leaf> LayerGrid<P> {
    /// The grid over the tree's primitives `ids` (indices into `prims`), when they are all
    /// still spheres and make a layer worth one.
    pub(super) fn build(prims: &[P::Item], ids: &[u32]) -> Option<LayerGrid<P>> {
        if ids.len() < MIN_LAYER {
            return None;
        }
        // Indexed by the primitive's index, as `ids` are.
        let mut balls = Vec::with_capacity(prims.len());
        for item in prims {
            let (center, radius) = P::as_sphere(item)?;
            balls.push(Ball { center, radius });
        }
        let spheres = &balls;
        let top_of = |id: u32| {
            let s = &spheres[id as usize];
            s.center.y + s.radius.abs()
        };
        // The layer's top: the highest top but the `MAX_TALL` highest.
        let mut tops: Vec<f32> = ids.iter().map(|&id| top_of(id)).collect();
        tops.sort_by(|a, b| b.total_cmp(a));
        let layer_top = tops[MAX_TALL];
        let (tall, layer): (Vec<u32>, Vec<u32>) =
            ids.iter().partition(|&&id| top_of(id) > layer_top);
        // The margin. A ray passing a sphere at distance r + margin has |g| (the centre's
        // distance from the line) at least that, and the test computes g = f + b·d within a
        // few 2⁻²⁴·|f| of it, where |f| (the origin's distance from the centre) is below
        // 175·scale for the origins `packs_for` takes (within 100·scale on each axis):
        // under 10⁻⁴·scale, a tenth of the margin, so the discriminant stays negative.
        let scale = ids.iter().fold(1.0f32, |m, &id| {
            let s = &spheres[id as usize];
            m.max(s.center.abs().max_element() + s.radius.abs())
        });
        let margin = 1e-3 * scale;
        let (lo, hi) = layer.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &id| {
                let (min, max) = spheres[id as usize].bounds();
                (lo.min(min), hi.max(max))
            },
        );
        let (width, depth) = (hi.x - lo.x, hi.z - lo.z);
        if !(width > 0.0 && depth > 0.0 && layer_top.is_finite()) {
            return None;
        }

        let cell = (width * depth / (CELLS_PER_SPHERE * layer.len() as f32)).sqrt();
        let nx = ((width / cell).ceil() as usize).max(1);
        let nz = ((depth / cell).ceil() as usize).max(1);
        let count = nx.checked_mul(nz).filter(|&n| n <= MAX_CELLS)?;
        if count * layer.len() > MAX_PAIRS {
            return None;
        }
        let slots = CELL_PACKS * WIDTH - tall.len();
        let mut cells = Vec::with_capacity(count);
        let mut nearest: Vec<(f32, u32)> = Vec::with_capacity(layer.len());
        for iz in 0..nz {
            for ix in 0..nx {
                let (x0, z0) = (lo.x + ix as f32 * cell, lo.z + iz as f32 * cell);
                // How far each layer sphere's disk (seen from above) lies from the cell.
                nearest.clear();
                nearest.extend(layer.iter().map(|&id| {
                    let s = &spheres[id as usize];
                    let dx = (x0 - s.center.x).max(s.center.x - (x0 + cell)).max(0.0);
                    let dz = (z0 - s.center.z).max(s.center.z - (z0 + cell)).max(0.0);
                    ((dx * dx + dz * dz).sqrt() - s.radius.abs(), id)
                }));
                let by_distance = |a: &(f32, u32), b: &(f32, u32)| a.0.total_cmp(&b.0);
                let kept = slots.min(nearest.len());
                if kept < nearest.len() {
                    // The `kept` nearest, then the nearest of the rest (which sets the reach).
                    nearest.select_nth_unstable_by(kept, by_distance);
                    nearest[..kept].sort_unstable_by(by_distance);
                }
                let reach = nearest
                    .get(kept)
                    .map_or(f32::INFINITY, |&(d, _)| d - margin);
                let mut pack_ids = tall.clone();
                pack_ids.extend(nearest[..kept].iter().map(|&(_, id)| id));
                let mut chunks = pack_ids.chunks(WIDTH);
                let packs = std::array::from_fn(|_| P::pack(prims, chunks.next().unwrap_or(&[])));
                cells.push(Cell {
                    reach2: if reach > 0.0 { reach * reach } else { 0.0 },
                    packs,
                });
            }
        }
        let bottom = layer.iter().fold(f32::INFINITY, |b, &id| {
            let s = &spheres[id as usize];
            b.min(s.center.y - s.radius.abs())
        });
        Some(LayerGrid {
            bottom: bottom - margin,
            top: layer_top + margin,
            far: 100.0 * scale,
            x0: lo.x,
            z0: lo.z,
            inv_cell: 1.0 / cell,
            nx,
            nx_f: nx as f32,
            nz_f: nz as f32,
            cells,
            tall: P::pack(prims, &tall),
        })
    }

    /// The packs that hold every sphere of the tree a ray from `o` along `d` can hit: the
    /// tall spheres when the ray never enters the layer, its cell's packs when it leaves the
    /// layer (up or down) within the cell's reach; else `None`. `d` need not be unit, nor
    /// exactly the ray's direction: only its signs and ratios count, and a few units of
    /// rounding in them move the reach far less than the margin.
    #[inline(always)]
    pub(super) fn packs_for(&self, o: Vec3, d: Vec3) -> Option<&[P]> {
        // Written so that NaN fails every test.
        let within = o.abs().max_element() < self.far;
        if !within {
            return None;
        }
        if (o.y >= self.top && d.y >= 0.0) || (o.y <= self.bottom && d.y <= 0.0) {
            return Some(std::slice::from_ref(&self.tall));
        }
        let fx = (o.x - self.x0) * self.inv_cell;
        let fz = (o.z - self.z0) * self.inv_cell;
        // A ray from below heading up meets no layer sphere before it reaches the layer, so
        // its reach is taken from its origin's cell as well. (Rays falling into the layer
        // from above rarely fell within reach: looking them up measured slower.)
        let (in_x, ix) = index_below(fx, self.nx_f);
        let (in_z, iz) = index_below(fz, self.nz_f);
        // `&`, not `&&`: one branch, not three.
        if !((o.y < self.top) & in_x & in_z) {
            return None;
        }
        let index = iz * self.nx + ix;
        let cell = self.cells.get(index)?;
        // How far the ray climbs or falls to leave the layer, from its origin.
        let exit = if d.y > 0.0 {
            self.top - o.y
        } else {
            o.y - self.bottom
        };
        // The reach, (exit / |d.y|)·|d.xz|, below the cell's, without a division (a level
        // ray, d.y = 0, never is).
        let across = d.x * d.x + d.z * d.z;
        (exit * exit * across < cell.reach2 * (d.y * d.y)).then_some(&cell.packs)
    }
}
