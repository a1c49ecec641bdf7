//! Renders whose answer is known in closed form: the book's first figures, furnace tests,
//! invisible glass, perfect mirrors and the camera's field of view.

use crate::common::*;
use glam::DVec3;
use tessera::camera::Camera;
use tessera::math::Vec3;
use tessera::sampling::Sampler;
use tessera::scene::{Overrides, Scene};
use tessera::tonemap::encode_8bit;

/// The book's sky for a unit direction, in f64.
fn sky(d: DVec3) -> DVec3 {
    let t = 0.5 * (d.y + 1.0);
    (1.0 - t) * DVec3::ONE + t * DVec3::new(0.5, 0.7, 1.0)
}

/// The unit direction of the book's first camera (origin, looking down -z, vfov 90) through
/// pixel `(x, y)` without jitter, in f64.
fn first_camera_dir(x: u32, y: u32, w: u32, h: u32) -> DVec3 {
    let aspect = f64::from(w) / f64::from(h);
    let (vw, vh) = (2.0 * aspect, 2.0);
    let u = f64::from(x) / f64::from(w - 1);
    let v = f64::from(h - 1 - y) / f64::from(h - 1);
    DVec3::new(-vw / 2.0 + u * vw, -vh / 2.0 + v * vh, -1.0).normalize()
}

const CENTRE: DVec3 = DVec3::new(0.0, 0.0, -1.0);

/// Where the unit direction `d` from the origin meets the radius-0.5 sphere at `CENTRE`, in
/// f64: `Some(Some(point))` on a hit, `Some(None)` on a miss, `None` within `margin` of the
/// silhouette, where f32 and f64 may disagree on hit or miss.
fn centre_sphere(d: DVec3, margin: f64) -> Option<Option<DVec3>> {
    let b = d.dot(CENTRE);
    let disc = b * b - (CENTRE.length_squared() - 0.25);
    if disc.abs() < margin {
        None
    } else if disc > 0.0 {
        Some(Some((b - disc.sqrt()) * d))
    } else {
        Some(None)
    }
}

/// Mean linear radiance of pixel `(x, y)` of `lin`, a film's `linear()` values `width` wide.
fn pixel_of(lin: &[f32], width: u32, x: u32, y: u32) -> DVec3 {
    let i = 3 * (y * width + x) as usize;
    DVec3::new(lin[i].into(), lin[i + 1].into(), lin[i + 2].into())
}

fn pixel(film: &tessera::film::Film, x: u32, y: u32) -> DVec3 {
    pixel_of(&film.linear(), film.width, x, y)
}

#[test]
fn first_ppm_image_is_its_formula() {
    let scene = load(
        &scene_path("img-1.01-first-ppm-image.toml"),
        Overrides::default(),
    );
    let film = render(&scene);
    let bytes = film.to_rgb8(scene.settings.gamma);
    let (w, h) = (film.width, film.height);
    let quantise = |c: f64| (256.0 * c.clamp(0.0, 0.999)) as u8;
    for y in 0..h {
        for x in 0..w {
            let i = 3 * (y * w + x) as usize;
            let want = [
                quantise(f64::from(x) / f64::from(w - 1)),
                quantise(f64::from(h - 1 - y) / f64::from(h - 1)),
                quantise(0.25),
            ];
            assert_eq!(bytes[i..i + 3], want, "pixel ({x}, {y})");
        }
    }
}

#[test]
fn gradient_figure_is_its_formula() {
    let scene = load(
        &scene_path("img-1.02-blue-to-white.toml"),
        Overrides::default(),
    );
    let film = render(&scene);
    let bytes = film.to_rgb8(scene.settings.gamma);
    let (w, h) = (film.width, film.height);
    let mut max_err = 0.0f64;
    let lin = film.linear();
    for y in 0..h {
        for x in 0..w {
            let want = sky(first_camera_dir(x, y, w, h));
            max_err = max_err.max((pixel_of(&lin, w, x, y) - want).abs().max_element());
            let i = 3 * (y * w + x) as usize;
            for c in 0..3 {
                let exact = want[c];
                let byte = bytes[i + c];
                // The byte is the book's truncation of the exact value, except where the exact
                // value sits within f32 rounding of a quantisation step.
                let near_step = ((256.0 * exact).fract()).min(1.0 - (256.0 * exact).fract()) < 1e-4;
                if !near_step {
                    assert_eq!(
                        byte,
                        encode_8bit(exact as f32, 1.0),
                        "pixel ({x}, {y}) channel {c}"
                    );
                }
            }
        }
    }
    assert!(
        max_err < 2e-6,
        "largest deviation from the formula: {max_err}"
    );
}

#[test]
fn normals_figure_is_its_formula() {
    let scene = load(
        &scene_path("img-1.04-normals-sphere.toml"),
        Overrides::default(),
    );
    let film = render(&scene);
    let (w, h) = (film.width, film.height);
    let (mut hits, mut checked) = (0, 0);
    let lin = film.linear();
    for y in 0..h {
        for x in 0..w {
            let d = first_camera_dir(x, y, w, h);
            let want = match centre_sphere(d, 1e-4) {
                None => continue,
                Some(Some(p)) => {
                    hits += 1;
                    0.5 * ((p - CENTRE) / 0.5 + DVec3::ONE)
                }
                Some(None) => sky(d),
            };
            let got = pixel_of(&lin, w, x, y);
            assert!(
                (got - want).abs().max_element() < 1e-4,
                "pixel ({x}, {y}): {got} vs {want}"
            );
            checked += 1;
        }
    }
    assert!(hits > 5000 && checked > 80_000, "{hits} hits of {checked}");
}

fn furnace_scene(diffuse: &str, albedo: f32, with_ground: bool) -> Scene {
    let ground = if with_ground {
        "[[spheres]]\ncenter = [0.0, -100.5, -1.0]\nradius = 100.0\nmaterial = \"m\"\n"
    } else {
        ""
    };
    load_text(&format!(
        r#"
[image]
width = 48
height = 27
samples_per_pixel = 16
max_depth = 50
seed = 3
[render]
diffuse = "{diffuse}"
[background]
type = "uniform"
color = [1.0, 1.0, 1.0]
[materials.m]
type = "lambertian"
albedo = [{albedo}, {albedo}, {albedo}]
[[spheres]]
center = [0.0, 0.0, -1.0]
radius = 0.5
material = "m"
{ground}"#
    ))
}

#[test]
fn furnace_white_diffuse_under_white_sky_renders_one() {
    for diffuse in ["unit_sphere", "lambertian", "hemisphere"] {
        let film = render(&furnace_scene(diffuse, 1.0, true));
        // Every path that escapes carries exactly 1; only paths cut off at max_depth lose
        // energy, and between a sphere and the ground those are very rare.
        let mean = film.mean_radiance();
        assert!(mean > 0.999 && mean <= 1.0 + 1e-6, "{diffuse}: mean {mean}");
        for c in film.linear() {
            assert!(
                (0.9..=1.0 + 1e-6).contains(&c),
                "{diffuse}: pixel value {c}"
            );
        }
    }
}

#[test]
fn furnace_half_albedo_sphere_renders_its_albedo() {
    // A lone convex sphere: every ray that hits it scatters once and escapes, so it shows
    // exactly its albedo, and the sky shows exactly 1.
    for diffuse in ["unit_sphere", "lambertian", "hemisphere"] {
        let film = render(&furnace_scene(diffuse, 0.5, false));
        let centre = pixel(&film, film.width / 2, film.height / 2);
        let corner = pixel(&film, 0, 0);
        assert!(
            (centre - DVec3::splat(0.5)).abs().max_element() < 1e-6,
            "{diffuse}: {centre}"
        );
        assert!(
            (corner - DVec3::ONE).abs().max_element() < 1e-6,
            "{diffuse}: {corner}"
        );
    }
}

fn one_sphere_in_the_sky(material: &str) -> String {
    format!(
        r#"
[image]
width = 160
height = 90
samples_per_pixel = 1
max_depth = 50
[render]
jitter = false
{material}
"#
    )
}

#[test]
fn glass_of_index_one_is_invisible() {
    let glass = one_sphere_in_the_sky(
        "[materials.g]\ntype = \"dielectric\"\nir = 1.0\nrefraction = \"snell\"\n\
         [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"g\"",
    );
    let empty = one_sphere_in_the_sky("");
    let (with, without) = (render(&load_text(&glass)), render(&load_text(&empty)));
    let (a, b) = (with.linear(), without.linear());
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert!(worst < 1e-4, "largest difference {worst}");
    // The sphere really is in the way: the same sphere in opaque grey is not invisible.
    let grey = one_sphere_in_the_sky(
        "[materials.g]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"g\"",
    );
    assert!(render(&load_text(&grey)) != without);
}

#[test]
fn smooth_metal_reflects_the_sky_exactly() {
    let scene = load_text(&one_sphere_in_the_sky(
        "[materials.m]\ntype = \"metal\"\nalbedo = [1.0, 1.0, 1.0]\nfuzz = 0.0\n\
         [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"m\"",
    ));
    let film = render(&scene);
    let (w, h) = (film.width, film.height);
    let mut mirrored = 0;
    let lin = film.linear();
    for y in 0..h {
        for x in 0..w {
            let d = first_camera_dir(x, y, w, h);
            let want = match centre_sphere(d, 1e-3) {
                None => continue,
                Some(Some(p)) => {
                    mirrored += 1;
                    let n = (p - CENTRE) / 0.5;
                    sky(d - 2.0 * d.dot(n) * n)
                }
                Some(None) => sky(d),
            };
            let got = pixel_of(&lin, w, x, y);
            assert!(
                (got - want).abs().max_element() < 1e-4,
                "pixel ({x}, {y}): {got} vs {want}"
            );
        }
    }
    assert!(mirrored > 1000);
}

#[test]
fn camera_corner_rays_follow_vfov_and_lookat() {
    let scene = load(&scene_path("cover.toml"), Overrides::default());
    let s = scene.camera_settings;
    let camera = Camera::new(&s);
    let mut rng = Sampler::from_seed(0);
    let pinhole = Camera::new(&tessera::camera::CameraSettings { aperture: 0.0, ..s });
    let axis = (s.lookat - s.lookfrom).normalize();
    let w = -axis;
    let u = s.vup.cross(w).normalize();
    let v = w.cross(u);
    let half_h = (f64::from(s.vfov_deg).to_radians() / 2.0).tan();
    let half_w = f64::from(s.aspect_ratio) * half_h;
    for (sx, sy) in [(0.0f32, 0.0f32), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        let d = pinhole.ray(sx, sy, &mut rng).dir;
        // Angle off the view axis: tan θ = √(half_w² + half_h²).
        let cos = f64::from(d.dot(axis));
        let tan = (1.0 - cos * cos).sqrt() / cos;
        assert!(
            (tan - half_w.hypot(half_h)).abs() < 1e-5,
            "corner ({sx}, {sy}): tan {tan}"
        );
        // Left/right and down/up on the side the corner names.
        assert_eq!(
            d.dot(u) > 0.0,
            sx > 0.5,
            "corner ({sx}, {sy}) horizontal side"
        );
        assert_eq!(
            d.dot(v) > 0.0,
            sy > 0.5,
            "corner ({sx}, {sy}) vertical side"
        );
    }
    // The centre ray of the lens camera, averaged over the lens, points at lookat.
    let mut mean = Vec3::ZERO;
    for _ in 0..4000 {
        let r = camera.ray(0.5, 0.5, &mut rng);
        let p = r.at((s.focus_dist) / r.dir.dot(axis));
        mean += p;
    }
    let focus_point = s.lookfrom + s.focus_dist * axis;
    assert!((mean / 4000.0 - focus_point).length() < 1e-3);
}
