//! Criterion benchmarks: a tile of the cover scene (samples/s), the BVH build, and
//! closest-hit queries against the cover (rays/s): camera rays through the tree, camera rays
//! of one tile against that tile's candidate spheres, and diffuse bounces off the ground.
//! Fixed seeds and sizes. The tile runs on the SIMD path `auto` picks; the ray queries call
//! the library's public, portable-path functions (the render's own path is `tessera bench`'s).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::Path;
use tessera::bvh::{SphereBvh, TraversalStack};
use tessera::integrator::tile_candidates;
use tessera::job::SampleRange;
use tessera::math::{Interval, PixelRect};
use tessera::ray::Ray;
use tessera::render::render_tile;
use tessera::sampling::Sampler;
use tessera::scene::{Overrides, Scene};
use tessera::simd;

fn cover(spp: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cover.toml");
    Scene::load(
        &path,
        &Overrides {
            samples_per_pixel: Some(spp),
            ..Overrides::default()
        },
    )
    .expect("cover scene")
}

fn tile(c: &mut Criterion) {
    let scene = cover(4);
    // A 32x32 tile across the three big spheres and the ground, one thread.
    let tile = PixelRect {
        x0: 560,
        y0: 360,
        width: 32,
        height: 32,
    };
    let mut g = c.benchmark_group("cover");
    g.throughput(Throughput::Elements(tile.area() * 4));
    g.bench_function("tile_32x32_4spp", |b| {
        let all = SampleRange { start: 0, end: 4 };
        b.iter(|| render_tile(black_box(&scene), &tile, all, simd::Path::best()))
    });
    g.finish();
}

fn bvh(c: &mut Criterion) {
    let scene = cover(1);
    let mut g = c.benchmark_group("bvh");
    g.throughput(Throughput::Elements(scene.spheres().len() as u64));
    g.bench_function("build_cover", |b| {
        b.iter(|| SphereBvh::build(black_box(scene.spheres())))
    });
    g.finish();

    let mut rng = Sampler::from_seed(1);
    let rays: Vec<Ray> = (0..4096)
        .map(|_| {
            let origin = scene.camera_settings.lookfrom;
            let target = tessera::math::Vec3::new(
                rng.range(-8.0, 8.0),
                rng.range(0.0, 2.0),
                rng.range(-4.0, 4.0),
            );
            Ray::new(origin, (target - origin).normalize())
        })
        .collect();
    let mut g = c.benchmark_group("intersect");
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("cover_closest_hit", |b| {
        let mut stack = scene.new_stack();
        b.iter(|| count_tree_hits(&scene, &rays, &mut stack))
    });

    // Most rays are bounces: from the ground, up in a cosine lobe.
    let bounces: Vec<Ray> = (0..4096)
        .map(|_| {
            let origin =
                tessera::math::Vec3::new(rng.range(-11.0, 11.0), 1e-3, rng.range(-11.0, 11.0));
            let dir = (tessera::math::Vec3::Y + rng.unit_vector()).normalize();
            Ray::new(origin, dir)
        })
        .collect();
    g.throughput(Throughput::Elements(bounces.len() as u64));
    g.bench_function("cover_ground_bounce", |b| {
        let mut stack = scene.new_stack();
        b.iter(|| count_tree_hits(&scene, &bounces, &mut stack))
    });

    // Camera rays of one 16x16 tile, against the spheres picked for the tile.
    let tile = PixelRect {
        x0: 600,
        y0: 400,
        width: 16,
        height: 16,
    };
    let (w, h) = (
        scene.settings.width as f32 - 1.0,
        scene.settings.height as f32 - 1.0,
    );
    let camera_rays: Vec<Ray> = (0..4096)
        .map(|i| {
            let x = (tile.x0 + i % 16) as f32 + rng.uniform();
            let y = (tile.y0 + (i / 16) % 16) as f32 + rng.uniform();
            scene.camera.ray(x / w, (h - y) / h, &mut rng)
        })
        .collect();
    let candidates = tile_candidates(&scene, &tile).expect("a short list");
    g.throughput(Throughput::Elements(camera_rays.len() as u64));
    g.bench_function("tile_camera_rays_candidates", |b| {
        b.iter(|| {
            camera_rays
                .iter()
                .filter(|r| {
                    scene
                        .hit_candidates(
                            simd::Portable,
                            &candidates,
                            r,
                            Interval::new(0.0, f32::INFINITY),
                        )
                        .is_some()
                })
                .count()
        })
    });
    g.bench_function("tile_camera_rays_tree", |b| {
        let mut stack = scene.new_stack();
        b.iter(|| count_tree_hits(&scene, &camera_rays, &mut stack))
    });
    g.finish();
}

/// How many of `rays` hit something, found through the tree.
fn count_tree_hits(scene: &Scene, rays: &[Ray], stack: &mut TraversalStack) -> usize {
    let all = Interval::new(0.0, f32::INFINITY);
    rays.iter()
        .filter(|r| scene.hit(r, all, stack).is_some())
        .count()
}

criterion_group!(benches, tile, bvh);
criterion_main!(benches);
