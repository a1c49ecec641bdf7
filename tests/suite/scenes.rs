//! Every scene file in `scenes/` parses, validates and renders at a tiny size.

use crate::common::*;
use tessera::scene::Overrides;

#[test]
fn every_scene_file_renders_small() {
    let mut count = 0;
    for entry in std::fs::read_dir(root().join("scenes")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let scene = load(
            &path,
            Overrides {
                width: Some(24),
                samples_per_pixel: Some(2),
                ..Overrides::default()
            },
        );
        assert_eq!(scene.settings.width, 24, "{}", path.display());
        let film = render(&scene);
        assert_eq!(film.sums.len() as u64, scene.settings.window.area());
        let mean = film.mean_radiance();
        assert!(
            mean.is_finite() && mean > 0.0,
            "{}: mean {mean}",
            path.display()
        );
        count += 1;
    }
    assert!(
        count >= 21,
        "expected the 20 figure scenes and the cover, found {count}"
    );
}

#[test]
fn cover_has_the_books_settings_and_random_spheres() {
    let scene = load(&scene_path("cover.toml"), Overrides::default());
    let s = &scene.settings;
    assert_eq!(
        (s.width, s.height, s.samples_per_pixel, s.max_depth),
        (1200, 800, 500, 50)
    );
    let c = &scene.camera_settings;
    assert_eq!(c.lookfrom, tessera::math::Vec3::new(13.0, 2.0, 3.0));
    assert_eq!(c.lookat, tessera::math::Vec3::ZERO);
    assert_eq!((c.vfov_deg, c.aperture, c.focus_dist), (20.0, 0.1, 10.0));
    // Ground + 3 big spheres + the grid: 22×22 cells minus the few near (4, 0.2, 0).
    let small = scene.spheres().len() - 4;
    assert!((470..=484).contains(&small), "{small} small spheres");
    let count = |f: fn(&tessera::material::Material) -> bool| {
        scene
            .spheres()
            .iter()
            .filter(|s| s.radius == 0.2 && f(&scene.materials[s.material.0 as usize]))
            .count() as f64
    };
    use tessera::material::Material::*;
    let diffuse = count(|m| matches!(m, Lambertian { .. })) / small as f64;
    let metal = count(|m| matches!(m, Metal { .. })) / small as f64;
    let glass = count(|m| matches!(m, Dielectric { .. })) / small as f64;
    // Binomial proportions of ~480 draws: 3 standard deviations ≈ 0.055, 0.05, 0.03.
    assert!((diffuse - 0.80).abs() < 0.055, "diffuse share {diffuse}");
    assert!((metal - 0.15).abs() < 0.05, "metal share {metal}");
    assert!((glass - 0.05).abs() < 0.03, "glass share {glass}");
}

#[test]
fn cover_generator_is_seeded() {
    let a = load(&scene_path("cover.toml"), Overrides::default());
    let b = load(&scene_path("cover.toml"), Overrides::default());
    assert_eq!(a.spheres(), b.spheres());
    let c = load(
        &scene_path("cover.toml"),
        Overrides {
            seed: Some(2),
            ..Overrides::default()
        },
    );
    assert_ne!(a.spheres(), c.spheres(), "the grid follows the seed");
}

/// `scenes/cover-book.toml` places the book's own spheres: those the book's `random_scene()`
/// makes with glibc's `rand()` when built by GCC on Linux (values printed by that program,
/// compiled from the book's listings with g++ 12, printed with `%.17g`, digits kept as printed).
#[test]
#[allow(clippy::excessive_precision)]
fn the_book_cover_scene_has_the_books_spheres_in_the_books_order() {
    use tessera::material::Material;
    use tessera::math::Color;
    let scene = load(&scene_path("cover-book.toml"), Overrides::default());
    assert_eq!(scene.spheres().len(), 487);
    let s = &scene.spheres();
    let at = |i: usize| (s[i].center.x, s[i].center.y, s[i].center.z, s[i].radius);
    // The ground first, the three big spheres last.
    assert_eq!(at(0), (0.0, -1000.0, 0.0, 1000.0));
    assert_eq!(at(484), (0.0, 1.0, 0.0, 1.0));
    assert_eq!(at(485), (-4.0, 1.0, 0.0, 1.0));
    assert_eq!(at(486), (4.0, 1.0, 0.0, 1.0));
    // Small spheres: centre x and z, and material, as the C++ program printed them.
    let small = |i: usize, x: f64, z: f64, material: Material| {
        assert_eq!(at(i), (x as f32, 0.2, z as f32, 0.2), "sphere {i}");
        assert_eq!(
            scene.materials[s[i].material.0 as usize], material,
            "sphere {i}"
        );
    };
    let color = |c: [f64; 3]| Color::from_array(c.map(|x| x as f32));
    small(
        1,
        -10.295210698945448,
        -10.6450553660281,
        Material::Metal {
            albedo: color([
                0.59877568460069597,
                0.95582367875613272,
                0.89922001655213535,
            ]),
            fuzz: 0.16761137777939439_f64 as f32,
        },
    );
    small(
        2,
        -10.501427040016278,
        -9.7500027603935457,
        Material::Lambertian {
            albedo: color([
                0.33421373454495618,
                0.59882958729871127,
                0.24509608072247305,
            ]),
        },
    );
    // The last small one.
    small(
        483,
        10.547971142642201,
        10.416230813739821,
        Material::Lambertian {
            albedo: color([
                0.0019927751580631802,
                0.38925773163881977,
                0.17954751492354906,
            ]),
        },
    );
    // The PCG cover is another layout of the same kind.
    let pcg = load(&scene_path("cover.toml"), Overrides::default());
    assert_eq!(pcg.spheres().len(), 485);
}
