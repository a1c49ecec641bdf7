//! The scene's fingerprint: a hash of everything that decides a sample's value, which
//! partial renders and checkpoints carry so that parts of different scenes never mix.

use super::{Background, Scene, SurfaceOffset};
use crate::material::Material;
use crate::math::Vec3;
use crate::texture::Texture;

impl Scene {
    /// A 64-bit hash of everything that decides a sample's value: image size, depth, seed,
    /// shading, camera, background, materials and spheres. The sample count and the crop
    /// window are left out: they choose which samples and pixels to render, not their values.
    /// Partial renders and checkpoints carry it so parts of different scenes never mix.
    pub fn fingerprint(&self) -> u64 {
        let s = &self.settings;
        let f = |x: f32| u64::from(x.to_bits());
        let v = |v: Vec3| [f(v.x), f(v.y), f(v.z)];
        let mut words = vec![
            u64::from(s.width),
            u64::from(s.height),
            u64::from(s.max_depth),
            s.seed,
            s.shading as u64,
            s.diffuse as u64,
            f(s.gamma),
            match s.surface_offset {
                // Not the bits of any finite offset.
                SurfaceOffset::Auto => u64::MAX,
                SurfaceOffset::Fixed(d) => f(d),
            },
            u64::from(s.jitter),
        ];
        let c = &self.camera_settings;
        for x in [c.lookfrom, c.lookat, c.vup] {
            words.extend(v(x));
        }
        words.extend([c.vfov_deg, c.aspect_ratio, c.aperture, c.focus_dist].map(f));
        match self.background {
            Background::Gradient { bottom, top } => {
                words.push(1);
                words.extend(v(bottom));
                words.extend(v(top));
            }
            Background::Uniform(color) => {
                words.push(2);
                words.extend(v(color));
            }
        }
        for m in &self.materials {
            match *m {
                Material::Lambertian { albedo } => {
                    words.push(10);
                    words.extend(v(albedo));
                }
                Material::Metal { albedo, fuzz } => {
                    words.push(11);
                    words.extend(v(albedo));
                    words.push(f(fuzz));
                }
                Material::Dielectric { ir, refraction } => {
                    words.extend([12, f(ir), refraction as u64]);
                }
                Material::DiffuseLight { emit } => {
                    words.push(13);
                    words.extend(v(emit));
                }
                Material::Isotropic { albedo } => {
                    words.push(14);
                    words.extend(v(albedo));
                }
            }
        }
        for sphere in &self.primitives.spheres {
            words.extend(v(sphere.center));
            words.extend([f(sphere.radius), u64::from(sphere.material.0)]);
        }
        // What the first book's scenes lack adds words only where a scene has it, so their
        // fingerprints (and the parts that carry them) stay as they were.
        if c.shutter != (0.0, 0.0) {
            words.extend([20, f(c.shutter.0), f(c.shutter.1)]);
        }
        for (i, texture) in self.material_textures.iter().enumerate() {
            if let Some(t) = texture {
                words.extend([21, i as u64, u64::from(t.0)]);
            }
        }
        for texture in &self.textures {
            match texture {
                Texture::Solid(c) => {
                    words.push(22);
                    words.extend(v(*c));
                }
                Texture::Checker {
                    even,
                    odd,
                    frequency,
                } => words.extend([23, u64::from(even.0), u64::from(odd.0), f(*frequency)]),
                Texture::Noise(n) => {
                    words.extend([24, n.kind as u64, f(n.scale), n.tables_digest()]);
                }
                Texture::Image(image) => {
                    // The digest taken as the image was decoded: an image named by many
                    // textures is one image, not hashed again for each.
                    let hash = image.digest();
                    words.extend([25, u64::from(image.width), u64::from(image.height), hash]);
                }
            }
        }
        for s in &self.primitives.moving_spheres {
            words.push(30);
            words.extend(v(s.center0));
            words.extend(v(s.center1));
            words.extend([
                f(s.time0),
                f(s.inv_duration),
                f(s.radius),
                u64::from(s.material.0),
            ]);
        }
        let quad_words = |words: &mut Vec<u64>, q: &crate::geometry::Quad| {
            words.extend(v(q.corner));
            words.extend(v(q.u));
            words.extend(v(q.v));
            words.push(u64::from(q.material.0));
        };
        for q in &self.primitives.quads {
            words.push(31);
            quad_words(&mut words, q);
        }
        for m in &self.primitives.media {
            words.extend([32, f(m.density), u64::from(m.material.0)]);
            match &m.boundary {
                crate::geometry::Boundary::Sphere(s) => {
                    words.push(33);
                    words.extend(v(s.center));
                    words.push(f(s.radius));
                }
                crate::geometry::Boundary::MovingSphere(s) => {
                    words.push(34);
                    words.extend(v(s.center0));
                    words.extend(v(s.center1));
                    words.extend([f(s.time0), f(s.inv_duration), f(s.radius)]);
                }
                crate::geometry::Boundary::Quads(quads) => {
                    words.push(35);
                    for q in quads {
                        quad_words(&mut words, q);
                    }
                }
            }
        }
        crate::sampling::hash_words(0x7e55_e4a0, &words)
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::{Overrides, Scene, TextureSource};
    use crate::texture::PIXEL_BYTES_HASHED;
    use std::path::Path;

    /// An image's pixels are hashed once, when it is decoded, however many textures name its
    /// file: the fingerprint hashed them again for each texture, so 1,000 textures naming
    /// one PNG of 2^25 pixels (98 KB) took 18 s before a 32×32 render, and the 150,000 a
    /// 6 MB scene holds some 40 minutes.
    #[test]
    fn an_image_named_by_many_textures_is_hashed_once() {
        const EARTH: &[(&str, &[u8])] =
            &[("earthmap.jpg", include_bytes!("../../scenes/earthmap.jpg"))];
        let mut text =
            String::from("[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 2\n");
        for i in 0..64 {
            text += &format!("[textures.t{i}]\ntype = \"image\"\nfile = \"earthmap.jpg\"\n");
        }
        let hashed = || PIXEL_BYTES_HASHED.with(|n| n.get());
        let before = hashed();
        let source = TextureSource::Embedded(EARTH);
        let scene =
            Scene::parse_with(&text, Path::new("s.toml"), &Overrides::default(), &source).unwrap();
        let fingerprint = scene.fingerprint();
        assert_eq!(scene.fingerprint(), fingerprint);
        // One image of 1024 × 512 RGB pixels, once.
        assert_eq!(hashed() - before, 1024 * 512 * 3);
    }
}
