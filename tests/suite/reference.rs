//! The fast path (f32, SIMD BVH, offset along the normal) against a plain f64 port of the
//! book (brute-force closest hit over every sphere, the textbook half-b quadratic, the book's
//! `t_min = 0.001`, recursion). Both render the cover at low resolution with independent
//! random numbers; their mean radiance must agree within a statistical bound and their rays
//! per sample within 1%. A careless f32 port fails this: rays trapped under the radius-1000
//! ground push rays/sample from ≈2.7 towards 3 and darken the image.

use crate::common::*;
use glam::DVec3;
use tessera::material::{DiffuseModel, Material, Refraction};
use tessera::math::PixelRect;
use tessera::sampling::Sampler;
use tessera::scene::{Background, Overrides, Scene, SurfaceOffset};

struct Reference<'a> {
    scene: &'a Scene,
    rays: u64,
}

fn d(v: glam::Vec3A) -> DVec3 {
    DVec3::new(v.x.into(), v.y.into(), v.z.into())
}

impl Reference<'_> {
    /// The book's `hittable_list::hit`: every sphere, closest root in `(0.001, ∞)`.
    fn hit(&self, o: DVec3, dir: DVec3) -> Option<(f64, DVec3, DVec3, bool, usize)> {
        let mut closest = f64::INFINITY;
        let mut found = None;
        for (i, s) in self.scene.spheres().iter().enumerate() {
            let (c, r) = (d(s.center), f64::from(s.radius));
            let oc = o - c;
            let a = dir.length_squared();
            let half_b = oc.dot(dir);
            let cc = oc.length_squared() - r * r;
            let disc = half_b * half_b - a * cc;
            if disc < 0.0 {
                continue;
            }
            let sq = disc.sqrt();
            let mut root = (-half_b - sq) / a;
            if root < 0.001 || root > closest {
                root = (-half_b + sq) / a;
                if root < 0.001 || root > closest {
                    continue;
                }
            }
            closest = root;
            let p = o + root * dir;
            let outward = (p - c) / r;
            let front = dir.dot(outward) < 0.0;
            found = Some((root, p, if front { outward } else { -outward }, front, i));
        }
        found
    }

    fn ray_color(&mut self, o: DVec3, dir: DVec3, depth: u32, rng: &mut Sampler) -> DVec3 {
        if depth == 0 {
            return DVec3::ZERO;
        }
        self.rays += 1;
        let Some((_, p, n, front, i)) = self.hit(o, dir) else {
            let unit = dir.normalize();
            return match self.scene.background {
                Background::Gradient { bottom, top } => {
                    let t = 0.5 * (unit.y + 1.0);
                    (1.0 - t) * d(bottom) + t * d(top)
                }
                Background::Uniform(c) => d(c),
            };
        };
        let material = self.scene.materials[self.scene.spheres()[i].material.0 as usize];
        let in_sphere = |rng: &mut Sampler| loop {
            let v = DVec3::new(rng.uniform_f64(), rng.uniform_f64(), rng.uniform_f64()) * 2.0
                - DVec3::ONE;
            if v.length_squared() < 1.0 {
                return v;
            }
        };
        let (attenuation, scattered) = match material {
            Material::Lambertian { albedo } => {
                assert_eq!(self.scene.settings.diffuse, DiffuseModel::Lambertian);
                let mut s = n + in_sphere(rng).normalize();
                if s.abs().max_element() < 1e-8 {
                    s = n;
                }
                (d(albedo), s)
            }
            Material::Metal { albedo, fuzz } => {
                let u = dir.normalize();
                let reflected = u - 2.0 * u.dot(n) * n;
                let s = reflected + f64::from(fuzz) * in_sphere(rng);
                if s.dot(n) <= 0.0 {
                    return DVec3::ZERO;
                }
                (d(albedo), s)
            }
            Material::Dielectric { ir, refraction } => {
                assert_eq!(refraction, Refraction::Schlick);
                let ir = f64::from(ir);
                let ratio = if front { 1.0 / ir } else { ir };
                let u = dir.normalize();
                let cos = (-u).dot(n).min(1.0);
                let sin = (1.0 - cos * cos).sqrt();
                let r0 = ((1.0 - ratio) / (1.0 + ratio)).powi(2);
                let schlick = r0 + (1.0 - r0) * (1.0 - cos).powi(5);
                let s = if ratio * sin > 1.0 || schlick > rng.uniform_f64() {
                    u - 2.0 * u.dot(n) * n
                } else {
                    let perp = ratio * (u + cos * n);
                    let parallel = -(1.0 - perp.length_squared()).abs().sqrt() * n;
                    perp + parallel
                };
                (DVec3::ONE, s)
            }
            Material::DiffuseLight { .. } | Material::Isotropic { .. } => {
                unreachable!("the first book's scenes have neither lights nor media")
            }
        };
        attenuation * self.ray_color(p, scattered, depth - 1, rng)
    }
}

/// The book's camera (§12), in f64.
struct BookCamera {
    origin: DVec3,
    lower_left: DVec3,
    horizontal: DVec3,
    vertical: DVec3,
    u: DVec3,
    v: DVec3,
    lens_radius: f64,
}

impl BookCamera {
    fn of(scene: &Scene) -> Self {
        let cam = &scene.camera_settings;
        let (lookfrom, lookat) = (d(cam.lookfrom), d(cam.lookat));
        let h = (f64::from(cam.vfov_deg).to_radians() / 2.0).tan();
        let (vh, vw) = (2.0 * h, f64::from(cam.aspect_ratio) * 2.0 * h);
        let w = (lookfrom - lookat).normalize();
        let u = d(cam.vup).cross(w).normalize();
        let v = w.cross(u);
        let focus = f64::from(cam.focus_dist);
        let (horizontal, vertical) = (focus * vw * u, focus * vh * v);
        BookCamera {
            origin: lookfrom,
            lower_left: lookfrom - horizontal / 2.0 - vertical / 2.0 - focus * w,
            horizontal,
            vertical,
            u,
            v,
            lens_radius: f64::from(cam.aperture) / 2.0,
        }
    }
}

impl Reference<'_> {
    /// Sample `k` of pixel `(x, y)` (top row 0), with random numbers of its own from `seed`.
    fn sample(&mut self, camera: &BookCamera, seed: u64, x: u32, y: u32, k: u32) -> DVec3 {
        let s = self.scene.settings;
        let mut rng = Sampler::for_sample(seed, x, y, k);
        let su = (f64::from(x) + rng.uniform_f64()) / f64::from(s.width - 1);
        let sv = (f64::from(s.height - 1 - y) + rng.uniform_f64()) / f64::from(s.height - 1);
        let (dx, dy) = loop {
            let (a, b) = (2.0 * rng.uniform_f64() - 1.0, 2.0 * rng.uniform_f64() - 1.0);
            if a * a + b * b < 1.0 {
                break (a, b);
            }
        };
        let offset = camera.lens_radius * (dx * camera.u + dy * camera.v);
        let origin = camera.origin + offset;
        let dir = camera.lower_left + su * camera.horizontal + sv * camera.vertical - origin;
        self.ray_color(origin, dir, s.max_depth, &mut rng)
    }
}

#[test]
fn fast_path_agrees_with_an_f64_brute_force_port_of_the_book() {
    let scene = load(
        &scene_path("cover.toml"),
        Overrides {
            width: Some(120),
            samples_per_pixel: Some(8),
            ..Overrides::default()
        },
    );
    let s = scene.settings;

    // The reference: f64, brute force, its own random numbers (another seed).
    let mut reference = Reference {
        scene: &scene,
        rays: 0,
    };
    let camera = BookCamera::of(&scene);
    let mut values = Vec::new();
    for y in 0..s.height {
        for x in 0..s.width {
            for k in 0..s.samples_per_pixel {
                let c = reference.sample(&camera, s.seed ^ 0xdead_beef, x, y, k);
                values.push((c.x + c.y + c.z) / 3.0);
            }
        }
    }
    let n = values.len() as f64;
    let ref_mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|x| (x - ref_mean).powi(2)).sum::<f64>() / (n - 1.0);
    let ref_rays_per_sample = reference.rays as f64 / n;

    // The fast path, as `tessera render` runs it.
    let (film, stats) = render_with(&scene, 2, 16);
    let fast_mean = film.mean_radiance();
    let fast_rays_per_sample = stats.rays_per_sample();

    // Both means are averages of n independent samples of about the same variance: their
    // difference has standard error √(2 var / n). Allow 4 of them.
    let bound = 4.0 * (2.0 * var / n).sqrt();
    println!(
        "mean radiance: fast {fast_mean:.5}, reference {ref_mean:.5} (bound ±{bound:.5}); \
         rays/sample: fast {fast_rays_per_sample:.4}, reference {ref_rays_per_sample:.4}"
    );
    assert!(
        (fast_mean - ref_mean).abs() < bound,
        "mean radiance {fast_mean} vs reference {ref_mean}, bound {bound}"
    );
    let rel = (fast_rays_per_sample - ref_rays_per_sample).abs() / ref_rays_per_sample;
    assert!(
        rel < 0.01,
        "rays/sample {fast_rays_per_sample} vs reference {ref_rays_per_sample}"
    );
    assert!(
        (2.55..2.85).contains(&fast_rays_per_sample),
        "the cover traces ≈2.7 rays per sample, got {fast_rays_per_sample}"
    );
}

/// One row of a band of columns: the mean radiance of the fast path and of the f64 port
/// there, and how many standard errors of their difference apart they are.
#[derive(Debug)]
struct RowAgreement {
    row: u32,
    columns: (u32, u32),
    fast: f64,
    reference: f64,
    z: f64,
}

/// Renders rows `rows` of `scene` with the fast path and with the f64 port (its own random
/// numbers) and compares them row by row over each band of `columns`: a whole image's PSNR
/// or mean hides a line one pixel high, a row's mean over a band does not.
fn compare_rows(
    scene: &Scene,
    rows: (u32, u32),
    columns: &[(u32, u32)],
    surface_offset: SurfaceOffset,
) -> Vec<RowAgreement> {
    let mut scene = scene.clone();
    let s = &mut scene.settings;
    s.surface_offset = surface_offset;
    s.window = PixelRect {
        x0: 0,
        y0: rows.0,
        width: s.width,
        height: rows.1 - rows.0,
    };
    let (film, _) = render_with(&scene, 2, 16);
    let s = scene.settings;
    let spp = f64::from(s.samples_per_pixel);
    let one = (1u64 << tessera::film::FRAC_BITS) as f64 * spp;
    let mut reference = Reference {
        scene: &scene,
        rays: 0,
    };
    let camera = BookCamera::of(&scene);
    let mut out = Vec::new();
    for y in rows.0..rows.1 {
        for &(x0, x1) in columns {
            let (mut fast, mut sum, mut squares) = (0.0, 0.0, 0.0);
            for x in x0..x1 {
                let p = film.sums[((y - rows.0) * s.width + x) as usize];
                fast += (p[0] + p[1] + p[2]) as f64 / 3.0 / one;
                for k in 0..s.samples_per_pixel {
                    let c = reference.sample(&camera, s.seed ^ 0xdead_beef, x, y, k);
                    let v = (c.x + c.y + c.z) / 3.0;
                    sum += v;
                    squares += v * v;
                }
            }
            let pixels = f64::from(x1 - x0);
            let n = pixels * spp;
            let (fast, reference) = (fast / pixels, sum / n);
            // Both are means of n samples of about the same variance (the reference's).
            let var = ((squares - sum * sum / n) / (n - 1.0)).max(1e-12);
            let z = (fast - reference) / (2.0 * var / n).sqrt();
            out.push(RowAgreement {
                row: y,
                columns: (x0, x1),
                fast,
                reference,
                z,
            });
        }
    }
    out
}

fn worst(rows: &[RowAgreement]) -> &RowAgreement {
    rows.iter()
        .max_by(|a, b| a.z.abs().total_cmp(&b.z.abs()))
        .expect("rows compared")
}

fn print_rows(what: &str, rows: &[RowAgreement]) {
    println!("{what}:");
    for r in rows {
        println!(
            "  row {:3} columns {:3}..{:3}: fast {:.4} reference {:.4} diff {:+.4} z {:+.1}",
            r.row,
            r.columns.0,
            r.columns.1,
            r.fast,
            r.reference,
            r.fast - r.reference,
            r.z
        );
    }
}

/// Rows 80..104 of the hollow glass scene hold the horizon, seen directly (row 90, left and
/// right of the sphere) and through the glass (row 95, columns 260..340).
const HORIZON_ROWS: (u32, u32) = (80, 104);
const HORIZON_COLUMNS: [(u32, u32); 3] = [(100, 200), (260, 340), (400, 500)];

fn hollow_glass_horizon() -> Scene {
    load(
        &root().join("tests/data/scenes/hollow-glass-horizon.toml"),
        Overrides::default(),
    )
}

#[test]
fn the_horizon_through_hollow_glass_matches_the_f64_port_row_by_row() {
    let scene = hollow_glass_horizon();
    assert_eq!(scene.settings.surface_offset, SurfaceOffset::Auto);
    let rows = compare_rows(&scene, HORIZON_ROWS, &HORIZON_COLUMNS, SurfaceOffset::Auto);
    print_rows("surface offset auto", &rows);
    assert_agree("the horizon through glass", &rows);
}

#[test]
fn a_fixed_offset_of_a_thousandth_draws_a_line_through_hollow_glass() {
    // What the comparison above guards against, and proof it can tell: tessera's offset
    // before "auto", 0.001 along the normal, displaces each ray crossing the shell sideways
    // by up to 0.001, which bends it on the next curved surface; the horizon seen through
    // the glass moves up by a fraction of a pixel and its row comes out darker.
    let rows = compare_rows(
        &hollow_glass_horizon(),
        HORIZON_ROWS,
        &HORIZON_COLUMNS,
        SurfaceOffset::Fixed(0.001),
    );
    print_rows("surface offset 0.001", &rows);
    let w = worst(&rows);
    assert!(
        w.z < -8.0 && w.columns == HORIZON_COLUMNS[1] && w.row == 95,
        "expected the horizon row seen through the glass darker: {w:?}"
    );
}

/// The hollow glass sphere of `hollow-glass-horizon.toml` in the middle of the view, `distance`
/// from the cover's camera along its line of sight to the horizon (level with the camera when
/// beyond the horizon, where the ground would hide it), seen from `camera_scale` times as
/// far at the same size, everything moved by `shift` along x and z.
fn glass_at_scale(camera_scale: f64, distance: f64, shift: f64) -> Scene {
    let eye = DVec3::new(13.0, 2.0, 3.0);
    let level = DVec3::new(-13.0, 0.0, -3.0).normalize();
    let dip = -(1000.0f64 / 1002.0).acos();
    let glass = if distance > 100.0 {
        eye + distance * level
    } else {
        eye + distance * (level * dip.cos() + DVec3::Y * dip.sin())
    };
    let lookfrom = glass + camera_scale * (eye - glass);
    let vfov = 20.0 * 8.0 / (camera_scale * distance);
    let moved = |p: DVec3| {
        let p = p + DVec3::new(shift, 0.0, shift);
        format!("[{}, {}, {}]", p.x, p.y, p.z)
    };
    load_text(&format!(
        r#"
[image]
width = 600
height = 400
samples_per_pixel = 64
max_depth = 50
seed = 1
[camera]
lookfrom = {}
lookat = {}
vfov_deg = {vfov}
aperture = 0.0
focus_dist = 10.0
[materials.ground]
type = "lambertian"
albedo = [0.5, 0.5, 0.5]
[materials.glass]
type = "dielectric"
ir = 1.5
[[spheres]]
center = {}
radius = 1000.0
material = "ground"
[[spheres]]
center = {}
radius = 0.6
material = "glass"
[[spheres]]
center = {}
radius = -0.55
material = "glass"
"#,
        moved(lookfrom),
        moved(glass),
        moved(DVec3::new(0.0, -1000.0, 0.0)),
        moved(glass),
        moved(glass),
    ))
}

/// The rows through the middle of `glass_at_scale`'s sphere (rows 157..243), its centre and
/// the ground beside it, agree with the f64 port.
fn assert_glass_agrees(what: &str, scene: &Scene) {
    let rows = compare_rows(
        scene,
        (150, 250),
        &[(270, 330), (100, 200)],
        SurfaceOffset::Auto,
    );
    assert_agree(what, &rows);
}

/// Every row within 5 standard errors of the f64 port.
fn assert_agree(what: &str, rows: &[RowAgreement]) {
    let w = worst(rows);
    println!("{what}: worst {w:?}");
    assert!(
        w.z.abs() < 5.0,
        "{what}: row {} differs from the f64 port: {w:?}",
        w.row
    );
}

#[test]
fn glass_seen_by_a_camera_far_from_the_origin_matches_the_f64_port() {
    // The camera 1200 from the origin: its rays meet the glass 1200 along, where a hit is
    // rounded to 10⁻⁴ and the surface offset grows to 10⁻³. (At 0.001 along the normal this
    // scene's rows disagree by z = -17.)
    let scene = glass_at_scale(150.0, 8.0, 0.0);
    assert!(scene.camera_settings.lookfrom.length() > 1000.0);
    assert_glass_agrees("camera 1200 away", &scene);
}

#[test]
fn a_small_glass_sphere_far_away_matches_the_f64_port() {
    // Radius 0.6 at 1000 from the camera and the origin, seen through a 0.16° field of view.
    assert_glass_agrees("sphere 1000 away", &glass_at_scale(1.0, 1000.0, 0.0));
}

#[test]
fn glass_and_ground_far_from_the_origin_match_the_f64_port() {
    // The whole of the near scene moved 3000 along x and z: every coordinate is rounded to
    // 2·10⁻⁴, and the offset off the glass is 3·10⁻³. (At 0.001 along the normal the row
    // of the horizon seen through the glass is darker by z = -6.)
    assert_glass_agrees("scene 3000 away", &glass_at_scale(1.0, 8.0, 3000.0));
}
