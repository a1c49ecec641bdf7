//! The hierarchy against brute force, bit for bit: random rays, rays leaving a sphere,
//! every-hit-is-a-tie scenes, candidate lists, coincident spheres.

use super::*;
use crate::geometry::{MaterialId, Quad, Sphere};
use crate::sampling::Sampler;
use crate::simd::Portable;

/// The closest hit by testing every sphere: the reference the hierarchy is tested against.
fn intersect_brute_force(
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

/// The closest hit by each walk the hierarchy has, flat (where the tree is small enough for
/// one) and down the tree, each checked to agree with the other.
fn intersect_both_walks(
    bvh: &SphereBvh,
    ray: &Ray,
    interval: Interval,
    stack: &mut TraversalStack,
    hints: RayHints,
) -> Option<(f32, PrimitiveId)> {
    let flat = bvh.walk(
        Portable,
        ray,
        Moment::default(),
        interval,
        stack,
        hints,
        true,
    );
    let tree = bvh.walk(
        Portable,
        ray,
        Moment::default(),
        interval,
        stack,
        hints,
        false,
    );
    assert_eq!(flat, tree, "flat and tree walks differ for {ray:?}");
    tree
}

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
    for n in [0, 1, 2, 7, 64, 500, 1000] {
        let spheres = random_spheres(n, &mut rng);
        let bvh = SphereBvh::build(&spheres);
        // Up to 64 packs the tree also has a flat walk.
        assert_eq!(bvh.flat.is_empty(), bvh.packs.len() > FLAT_MAX_PACKS, "{n}");
        let mut stack = TraversalStack::default();
        for _ in 0..4000 {
            let o = Vec3::new(
                rng.range(-15.0, 15.0),
                rng.range(0.0, 6.0),
                rng.range(-15.0, 15.0),
            );
            let ray = Ray::new(o, rng.unit_vector());
            let iv = Interval::new(1e-4, f32::INFINITY);
            let a = intersect_both_walks(&bvh, &ray, iv, &mut stack, RayHints::default());
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
    let bvh = SphereBvh::build(&spheres);
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
            leaving: Leaving::sphere_if(true, PrimitiveId(id as u32)),
            inv_dir: Some(raw.length() * (Vec3::ONE / raw)),
            heading: Some(raw),
        };
        let fast = intersect_both_walks(&bvh, &ray, iv, &mut stack, hints);
        let full = intersect_both_walks(&bvh, &ray, iv, &mut stack, RayHints::default());
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
    let bvh = SphereBvh::build(&spheres);
    let mut stack = TraversalStack::default();
    let iv = Interval::new(1e-4, f32::INFINITY);
    let mut hits = 0;
    for _ in 0..2000 {
        let o = Vec3::new(rng.range(-15.0, 15.0), rng.range(0.0, 6.0), 15.0);
        let ray = Ray::new(o, rng.unit_vector());
        let a = intersect_both_walks(&bvh, &ray, iv, &mut stack, RayHints::default());
        let b = intersect_brute_force(&spheres, &ray, iv);
        assert_eq!(a, b, "for {ray:?}");
        if let Some((_, id)) = a {
            assert!((id.0 as usize) < base.len(), "tie lost to a later copy");
            hits += 1;
        }
    }
    assert!(hits > 200, "only {hits} hits");
}

#[test]
fn a_giant_and_a_tree_sphere_tied_go_to_the_lower_id() {
    // Along -z from the origin both the giant and the small sphere are met at t = 1
    // exactly (every step of the arithmetic is exact): whichever comes first in the list
    // must win, on both walks, wherever the giants are tested.
    let giant = Sphere::new(Vec3::new(0.0, 0.0, -1001.0), 1000.0, MaterialId(0));
    let tied = Sphere::new(Vec3::new(0.0, 0.0, -1.5), 0.5, MaterialId(1));
    let others =
        (0..9).map(|i| Sphere::new(Vec3::new(5.0 + i as f32, 0.0, -5.0), 0.3, MaterialId(2)));
    let ray = Ray::new(Vec3::ZERO, -Vec3::Z);
    let iv = Interval::new(1e-4, f32::INFINITY);
    for giant_first in [true, false] {
        let (first, last) = if giant_first {
            (giant, tied)
        } else {
            (tied, giant)
        };
        let spheres: Vec<Sphere> = std::iter::once(first)
            .chain(others.clone())
            .chain(std::iter::once(last))
            .collect();
        let bvh = SphereBvh::build(&spheres);
        assert_eq!(bvh.giants.len(), 1, "the radius-1000 sphere is a giant");
        let mut stack = TraversalStack::default();
        let hit = intersect_both_walks(&bvh, &ray, iv, &mut stack, RayHints::default());
        assert_eq!(
            hit,
            Some((1.0, PrimitiveId(0))),
            "giant first: {giant_first}"
        );
        assert_eq!(hit, intersect_brute_force(&spheres, &ray, iv));
    }
}

/// Picking candidates through the tree, skipping subtrees whose boxes the bundle misses,
/// must pick exactly the spheres a scan of every sphere picks.
#[test]
fn candidates_through_the_tree_equal_a_scan_of_every_sphere() {
    use crate::camera::{Camera, CameraSettings};
    let mut rng = Sampler::from_seed(21);
    let spheres = random_spheres(500, &mut rng);
    let bvh = SphereBvh::build(&spheres);
    let camera = Camera::new(&CameraSettings {
        lookfrom: Vec3::new(13.0, 2.0, 3.0),
        lookat: Vec3::ZERO,
        vup: Vec3::Y,
        vfov_deg: 20.0,
        aspect_ratio: 1.5,
        aperture: 0.3,
        focus_dist: 10.0,
        shutter: (0.0, 0.0),
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
    let bvh = SphereBvh::build(&spheres);
    // Coincident centroids leave the SAH nothing to split: the median split still cuts
    // them into packs, none empty, holding every sphere exactly once.
    let mut ids: Vec<u32> = bvh.packs.iter().flat_map(SpherePack::ids).collect();
    assert!(bvh.packs.iter().all(|p| p.ids().count() > 0));
    ids.sort_unstable();
    assert_eq!(ids, (0..40).collect::<Vec<u32>>());
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

#[test]
fn packs_come_out_full_and_small_scenes_need_two_levels_at_most() {
    let mut rng = Sampler::from_seed(13);
    for n in [9, 40, 64, 65, 200, 486, 512] {
        // Without the giant `random_spheres` adds, so every sphere is in the tree.
        let mut spheres = random_spheres(n, &mut rng);
        spheres.pop();
        let bvh = SphereBvh::build(&spheres);
        assert!(bvh.giants.is_empty());
        // As few packs as `n` spheres need, so at most one is not full.
        assert_eq!(bvh.packs.len(), n.div_ceil(WIDTH), "{n} spheres");
        // Up to 64 spheres: one node over packs; up to 512: a root over such nodes.
        let levels = if n <= WIDTH * WIDTH { 0 } else { 1 };
        assert_eq!(bvh.max_level, levels, "{n} spheres");
        let inner_of_root = bvh.nodes[0].inner_mask.count_ones() as usize;
        assert_eq!(bvh.nodes.len(), 1 + inner_of_root, "{n} spheres");
    }
    // The cover: 486 spheres in the tree, 61 packs under 8 nodes under the root.
    let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cover.toml"));
    let scene = crate::scene::Scene::load(path, &crate::scene::Overrides::default()).unwrap();
    let bvh = SphereBvh::build(scene.spheres());
    assert_eq!(
        (bvh.packs.len(), bvh.nodes.len(), bvh.max_level),
        (61, 9, 1)
    );
}

#[test]
fn stack_entries_share_no_cache_line_with_other_allocations() {
    let mut rng = Sampler::from_seed(9);
    let bvh = SphereBvh::build(&random_spheres(500, &mut rng));
    for mut stack in [TraversalStack::default(), bvh.new_stack()] {
        // A walk grows a stack too small for the tree before using it.
        let ray = Ray::new(Vec3::new(0.0, 1.0, -20.0), Vec3::Z);
        bvh.intersect(&ray, Interval::new(1e-4, f32::INFINITY), &mut stack);
        let need = bvh.stack_need();
        let whole = stack.0.as_ptr_range();
        let used = stack.entries(need).as_ptr_range();
        assert!(used.start as usize - whole.start as usize >= 64);
        assert!(whole.end as usize - used.end as usize >= 64);
    }
}

/// A layer of spheres like the book's cover: small spheres on a grid with random offsets
/// and radii `radius` (spacing `spacing`), three tall ones, and the radius-1000 ground.
fn layer_scene(rng: &mut Sampler, spacing: f32, radius: f32) -> Vec<Sphere> {
    let mut spheres = vec![Sphere::new(
        Vec3::new(0.0, -1000.0, 0.0),
        1000.0,
        MaterialId(0),
    )];
    for a in -11..11 {
        for b in -11..11 {
            let r = radius * rng.range(0.5, 1.0);
            let c = Vec3::new(
                spacing * (a as f32 + 0.9 * rng.uniform()),
                r,
                spacing * (b as f32 + 0.9 * rng.uniform()),
            );
            spheres.push(Sphere::new(c, r, MaterialId(1)));
        }
    }
    for x in [-4.0, 0.0, 4.0] {
        spheres.push(Sphere::new(Vec3::new(x, 1.0, 0.0), 1.0, MaterialId(2)));
    }
    // The book's hollow glass: a negative radius inside one of them.
    spheres.push(Sphere::new(Vec3::new(0.0, 1.0, 0.0), -0.9, MaterialId(2)));
    spheres
}

/// Rays of every kind the layer grid sorts: leaving a sphere's surface (hinted, as bounce
/// rays are), leaving the ground, inside the layer in any direction (near-level too), level,
/// from above and from below; each traced with the grid, without it, and by brute force.
#[test]
fn the_layer_grid_finds_what_brute_force_finds() {
    let mut rng = Sampler::from_seed(33);
    for (spacing, radius) in [(1.0, 0.2), (0.1, 0.02), (1.0, 0.45)] {
        let spheres = layer_scene(&mut rng, spacing, radius);
        let bvh = SphereBvh::build(&spheres);
        let grid = bvh.layer.as_ref().expect("a layer grid for a layer scene");
        let plain = Bvh {
            layer: None,
            ..bvh.clone()
        };
        let mut stack = TraversalStack::default();
        let iv = Interval::new(0.0, f32::INFINITY);
        let extent = 11.0 * spacing;
        let mut by_grid = 0;
        for i in 0..60_000 {
            let mut d = rng.unit_vector();
            let (o, hints) = match i % 6 {
                0 | 1 => {
                    let id = 1 + (rng.uniform() * (spheres.len() - 1) as f32) as usize;
                    let s = &spheres[id.min(spheres.len() - 1)];
                    let n = rng.unit_vector();
                    let out = if s.radius > 0.0 { n } else { -n };
                    if d.dot(out) < 0.0 {
                        d = -d;
                    }
                    // As the path tracer hints it: the direction before it is normalised,
                    // any length.
                    let hints = RayHints {
                        leaving: Leaving::sphere_if(i % 6 == 0, PrimitiveId(id as u32)),
                        inv_dir: None,
                        heading: Some(rng.range(0.2, 2.0) * d),
                    };
                    (s.center + s.radius * n + 1e-3 * out, hints)
                }
                2 => {
                    d.y = d.y.abs();
                    let (x, z) = (rng.range(-extent, extent), rng.range(-extent, extent));
                    (Vec3::new(x, 1e-3, z), RayHints::default())
                }
                3 => {
                    // Near level: the reach is long, or just within a cell's.
                    d.y *= 10f32.powf(-rng.range(0.0, 6.0));
                    d = d.normalize();
                    let y = rng.range(0.0, 2.0 * radius);
                    let (x, z) = (rng.range(-extent, extent), rng.range(-extent, extent));
                    (Vec3::new(x, y, z), RayHints::default())
                }
                4 => {
                    d.y = 0.0;
                    d = d.normalize();
                    let y = rng.range(-0.1, 2.5);
                    let (x, z) = (rng.range(-extent, extent), rng.range(-extent, extent));
                    (Vec3::new(x, y, z), RayHints::default())
                }
                _ => {
                    let y = rng.range(-1.0, 4.0);
                    let (x, z) = (rng.range(-15.0, 15.0), rng.range(-15.0, 15.0));
                    (Vec3::new(x, y, z), RayHints::default())
                }
            };
            let ray = Ray::new(o, d);
            by_grid += usize::from(grid.packs_for(ray.origin, ray.dir).is_some());
            let with_grid = intersect_both_walks(&bvh, &ray, iv, &mut stack, hints);
            let without = intersect_both_walks(&plain, &ray, iv, &mut stack, hints);
            let brute = intersect_brute_force(&spheres, &ray, iv);
            assert_eq!(with_grid, brute, "{ray:?} {hints:?}");
            assert_eq!(without, brute, "{ray:?} {hints:?}");
        }
        assert!(by_grid > 10_000, "only {by_grid} rays took the grid");
    }
}

/// The grid is built only where it pays: a layer, of enough spheres.
#[test]
fn a_layer_grid_is_built_only_for_a_layer_of_many_spheres() {
    let mut rng = Sampler::from_seed(34);
    let few: Vec<Sphere> = layer_scene(&mut rng, 1.0, 0.2)
        .into_iter()
        .take(40)
        .collect();
    assert!(SphereBvh::build(&few).layer.is_none());
    assert!(
        SphereBvh::build(&layer_scene(&mut rng, 1.0, 0.2))
            .layer
            .is_some()
    );
    assert!(SphereBvh::build(&[]).layer.is_none());
}

/// Rays from far outside the scene walk the tree: the grid's margins are sized for origins
/// within the scene's scale.
#[test]
fn the_layer_grid_leaves_far_origins_to_the_walk() {
    let mut rng = Sampler::from_seed(35);
    let bvh = SphereBvh::build(&layer_scene(&mut rng, 1.0, 0.2));
    let grid = bvh.layer.as_ref().expect("a layer grid");
    let up = |y: f32| grid.packs_for(Vec3::new(0.5, y, 0.5), Vec3::Y);
    assert!(up(5.0).is_some(), "over the layer, heading up");
    assert!(up(1e6).is_none(), "far above");
    let level = grid.packs_for(Vec3::new(-1e6, 0.41, 0.5), Vec3::X);
    assert!(level.is_none(), "far away");
    let nan = grid.packs_for(Vec3::new(f32::NAN, 0.1, 0.5), Vec3::Y);
    assert!(nan.is_none(), "not a number");
}

/// The book's Cornell box (*The Next Week* §8): five walls and the lamp, then its two blocks
/// rotated about y and moved, six quads each, in the scene file's order.
fn cornell_quads() -> Vec<Quad> {
    let path = std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/img-2.20-cornell-standard.toml"
    ));
    let scene = crate::scene::Scene::load(path, &crate::scene::Overrides::default()).unwrap();
    scene.primitives().quads.clone()
}

/// The closest hit by testing every quad, the nearest in `(min, max]`, ties going to the
/// lower id, as the packs take them.
fn quads_brute_force(quads: &[Quad], ray: &Ray, interval: Interval) -> Option<(f32, PrimitiveId)> {
    let mut best: Option<(f32, u32)> = None;
    for (i, q) in quads.iter().enumerate() {
        let Some((t, a, b)) = q.plane_hit(ray) else {
            continue;
        };
        let inside = (0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b);
        let id = PrimitiveId::QUADS + i as u32;
        if inside && interval.min < t && t <= interval.max && best.is_none_or(|b| (t, id) < b) {
            best = Some((t, id));
        }
    }
    best.map(|(t, id)| (t, PrimitiveId(id)))
}

/// Random quads, some of them boxes around others (as walls are around furniture).
fn random_quads(n: usize, rng: &mut Sampler) -> Vec<Quad> {
    (0..n)
        .map(|i| {
            let scale = if i % 5 == 0 { 40.0 } else { 4.0 };
            let corner = 20.0 * Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 10.0;
            let u = scale * rng.range(0.2, 1.0) * rng.unit_vector();
            let v = scale * rng.range(0.2, 1.0) * rng.unit_vector();
            Quad::new(corner, u, v, MaterialId(0))
        })
        .filter(|q| q.plane().0.is_finite())
        .collect()
}

#[test]
fn small_sets_of_quads_clustered_find_what_brute_force_finds() {
    let mut rng = Sampler::from_seed(31);
    let mut sets = vec![cornell_quads()];
    for n in [1, 2, 7, 9, 18, 40, 64, 65, 200] {
        sets.push(random_quads(n, &mut rng));
    }
    for quads in &sets {
        let bvh = Bvh::<QuadPack>::build(quads);
        let mut stack = bvh.new_stack();
        for _ in 0..4000 {
            let origin = Vec3::new(278.0, 278.0, 278.0)
                + 400.0 * Vec3::new(rng.uniform(), rng.uniform(), rng.uniform())
                - 200.0;
            let origin = if quads.len() == 18 {
                origin
            } else {
                origin / 20.0
            };
            let ray = Ray::new(origin, rng.unit_vector());
            let interval = Interval::new(rng.range(0.0, 0.01), f32::INFINITY);
            let expected = quads_brute_force(quads, &ray, interval);
            for flat in [true, false] {
                let got = bvh.walk(
                    Portable,
                    &ray,
                    Moment::default(),
                    interval,
                    &mut stack,
                    RayHints::default(),
                    flat,
                );
                let key = |h: Option<(f32, PrimitiveId)>| h.map(|(t, id)| (t.to_bits(), id));
                assert_eq!(key(got), key(expected), "{} quads, {ray:?}", quads.len());
            }
        }
    }
}

#[test]
fn the_cornell_box_s_walls_and_blocks_are_packed_apart() {
    // Axis splits put walls and block faces in the same packs, each spanning the room: a ray
    // from inside met 2.08 pack boxes. Clustered, it meets the box of the one wall it leaves
    // through and those of the blocks it passes: 1.12.
    let quads = cornell_quads();
    let bvh = Bvh::<QuadPack>::build(&quads);
    let boxes: Vec<Aabb> = (bvh.packs.iter())
        .map(|p| {
            p.ids().fold(Aabb::EMPTY, |b, id| {
                b.union(QuadPack::quad_of(&quads, id).bounds())
            })
        })
        .collect();
    let meets = |b: &Aabb, ray: &Ray| {
        let (mut lo, mut hi) = (0.0f32, f32::INFINITY);
        for axis in 0..3 {
            let inv = 1.0 / ray.dir[axis];
            let (a, c) = (
                (b.min[axis] - ray.origin[axis]) * inv,
                (b.max[axis] - ray.origin[axis]) * inv,
            );
            lo = lo.max(a.min(c));
            hi = hi.min(a.max(c));
        }
        lo <= hi
    };
    let mut rng = Sampler::from_seed(8);
    let rays = 20_000;
    let mut met = 0;
    for _ in 0..rays {
        let origin = Vec3::new(
            rng.range(1.0, 554.0),
            rng.range(1.0, 554.0),
            rng.range(1.0, 554.0),
        );
        let ray = Ray::new(origin, rng.unit_vector());
        met += boxes.iter().filter(|b| meets(b, &ray)).count();
    }
    let per_ray = met as f64 / f64::from(rays);
    assert!(bvh.packs.len() <= WIDTH, "{} packs", bvh.packs.len());
    assert!(per_ray < 1.5, "{per_ray} pack boxes a ray");
    // Every wall's pack holds no face of a block but the ones lying in that wall's plane.
    for pack in &bvh.packs {
        let ids: Vec<usize> = pack.ids().map(index_of::<QuadPack>).collect();
        if let Some(&wall) = ids.iter().find(|&&i| i < 6) {
            let (n, d) = quads[wall].plane();
            for &i in &ids {
                let (m, e) = quads[i].plane();
                assert!(
                    i < 6 || (n.dot(m).abs() > 0.999 && (d - e * n.dot(m)).abs() < 1.0),
                    "{ids:?}"
                );
            }
        }
    }
}

/// Batches of eight rays against a set of quads, tested on a SIMD path (see
/// `a_batch_of_rays_finds_what_each_ray_s_walk_finds`).
struct BatchHits<'a> {
    batch: &'a QuadBatch,
    rays: &'a [RayBatch],
}

impl crate::simd::Kernel for BatchHits<'_> {
    type Output = Vec<([f32; BATCH], [u32; BATCH])>;

    #[inline(always)]
    fn run<I: crate::simd::Isa>(self, isa: I) -> Self::Output {
        self.rays
            .iter()
            .map(|r| self.batch.intersect(isa, r))
            .collect()
    }
}

#[test]
fn a_batch_of_rays_finds_what_each_ray_s_walk_finds() {
    // The Cornell box and random sets up to the batch's most, one with every quad twice (each
    // hit a tie, which the lower id wins); each lane with its own interval, some leaving a
    // quad (`RayHints::leaving`), some empty; on every SIMD path, bit for bit.
    let mut rng = Sampler::from_seed(47);
    let mut sets = vec![cornell_quads()];
    for n in [1, 3, 8, 17, QuadBatch::MAX] {
        sets.push(random_quads(n, &mut rng));
    }
    let twice = random_quads(QuadBatch::MAX / 2, &mut rng);
    sets.push(twice.iter().chain(&twice).copied().collect());
    for quads in &sets {
        let batch = QuadBatch::new(quads);
        let bvh = Bvh::<QuadPack>::build(quads);
        let mut stack = bvh.new_stack();
        let mut batches = Vec::new();
        let mut expected = Vec::new();
        for _ in 0..600 {
            let mut rays = RayBatch::default();
            let mut want = [(f32::INFINITY, NO_HIT); BATCH];
            for (lane, want) in want.iter_mut().enumerate() {
                if rng.uniform() < 0.1 {
                    rays.clear(lane);
                    continue;
                }
                let centre = if quads.len() == 18 {
                    Vec3::splat(278.0)
                } else {
                    Vec3::ZERO
                };
                let spread = if quads.len() == 18 { 400.0 } else { 20.0 };
                let origin = centre + spread * (rng.uniform() - 0.5) * rng.unit_vector();
                let ray = Ray::new(origin, rng.unit_vector());
                let interval = if rng.uniform() < 0.3 {
                    Interval::new(0.0, f32::INFINITY)
                } else {
                    Interval::new(rng.range(0.0, 1.0), rng.range(1.0, 900.0))
                };
                // Leaving the quad it hits from behind, or one at random, or none.
                let hit = bvh.intersect_with(&ray, interval, &mut stack, RayHints::default());
                let leaving = match (rng.uniform() < 0.5, hit) {
                    (true, Some((_, id))) => Leaving(id.0),
                    (false, _) if rng.uniform() < 0.5 => Leaving(
                        PrimitiveId::QUADS
                            + (rng.uniform() * quads.len() as f32) as u32 % quads.len() as u32,
                    ),
                    _ => Leaving::NONE,
                };
                let hints = RayHints {
                    leaving,
                    ..RayHints::default()
                };
                rays.set(lane, &ray, interval, leaving.id());
                let got = bvh.intersect_with(&ray, interval, &mut stack, hints);
                if let Some((t, id)) = got {
                    *want = (t, id.0);
                }
            }
            batches.push(rays);
            expected.push(want);
        }
        for path in crate::simd::Path::supported() {
            let got = crate::simd::dispatch(
                path,
                BatchHits {
                    batch: &batch,
                    rays: &batches,
                },
            );
            for (b, (t, ids)) in got.iter().enumerate() {
                for lane in 0..BATCH {
                    if batches[b].t_min(lane) == f32::INFINITY {
                        assert_eq!(ids[lane], NO_HIT);
                        continue;
                    }
                    let (want_t, want_id) = expected[b][lane];
                    assert_eq!(
                        ids[lane],
                        want_id,
                        "{path}, {} quads, batch {b} lane {lane}",
                        quads.len()
                    );
                    if want_id != NO_HIT {
                        assert_eq!(
                            t[lane].to_bits(),
                            want_t.to_bits(),
                            "{path}, batch {b} lane {lane}"
                        );
                    }
                }
            }
        }
    }
}
