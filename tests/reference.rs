//! The fast path (f32, SIMD BVH, offset along the normal) against a plain f64 port of the
//! book (brute-force closest hit over every sphere, the textbook half-b quadratic, the book's
//! `t_min = 0.001`, recursion). Both render the cover at low resolution with independent
//! random numbers; their mean radiance must agree within a statistical bound and their rays
//! per sample within 1%. A careless f32 port fails this: rays trapped under the radius-1000
//! ground push rays/sample from ≈2.7 towards 3 and darken the image.

mod common;

use common::*;
use glam::DVec3;
use tessera::material::{DiffuseModel, Material, Refraction};
use tessera::sampling::Sampler;
use tessera::scene::{Background, Overrides, Scene};

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
        for (i, s) in self.scene.spheres.iter().enumerate() {
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
        let material = self.scene.materials[self.scene.spheres[i].material.0 as usize];
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
        };
        attenuation * self.ray_color(p, scattered, depth - 1, rng)
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
    let cam = &scene.camera_settings;
    let (lookfrom, lookat) = (d(cam.lookfrom), d(cam.lookat));
    let h = (f64::from(cam.vfov_deg).to_radians() / 2.0).tan();
    let (vh, vw) = (2.0 * h, f64::from(cam.aspect_ratio) * 2.0 * h);
    let w = (lookfrom - lookat).normalize();
    let u = d(cam.vup).cross(w).normalize();
    let v = w.cross(u);
    let focus = f64::from(cam.focus_dist);
    let (horizontal, vertical) = (focus * vw * u, focus * vh * v);
    let lower_left = lookfrom - horizontal / 2.0 - vertical / 2.0 - focus * w;
    let lens = f64::from(cam.aperture) / 2.0;
    let mut values = Vec::new();
    for y in 0..s.height {
        for x in 0..s.width {
            for k in 0..s.samples_per_pixel {
                let mut rng = Sampler::for_sample(s.seed ^ 0xdead_beef, x, y, k);
                let su = (f64::from(x) + rng.uniform_f64()) / f64::from(s.width - 1);
                let sv =
                    (f64::from(s.height - 1 - y) + rng.uniform_f64()) / f64::from(s.height - 1);
                let (dx, dy) = loop {
                    let (a, b) = (2.0 * rng.uniform_f64() - 1.0, 2.0 * rng.uniform_f64() - 1.0);
                    if a * a + b * b < 1.0 {
                        break (a, b);
                    }
                };
                let offset = lens * (dx * u + dy * v);
                let origin = lookfrom + offset;
                let dir = lower_left + su * horizontal + sv * vertical - origin;
                let c = reference.ray_color(origin, dir, s.max_depth, &mut rng);
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
