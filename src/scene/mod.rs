//! Scenes: loading a TOML scene file, validating it, and the runtime scene the renderer reads.

mod accel;
mod build;
mod check;
mod cover;
pub mod desc;
mod draws;
mod settings;
mod shapes;
mod textures;
mod values;

pub use build::{MAX_PIXELS, Overrides};
pub use check::{MAX_LENGTH, MIN_RADIUS};
pub use textures::{
    MAX_TEXTURE_BYTES, MAX_TEXTURE_PIXELS, TextureSource, find_texture, is_plain_name,
};

/// The longest scene file tessera reads: the cover's is 3 KiB, 20,000 spheres written out
/// about 2 MiB.
pub const MAX_SCENE_BYTES: u64 = 64 << 20;
pub use settings::{Background, RenderSettings, Shading, SurfaceOffset};

use crate::bvh::{BATCH, Candidates, Moment, RayBatch, RayHints, TraversalStack};
use crate::camera::{Camera, CameraSettings};
use crate::error::{Error, Location, Result};
use crate::geometry::{Hit, PrimitiveId, PrimitiveKind, Sphere};
use crate::material::Material;
use crate::math::{Color, Interval, Vec3, atan2};
use crate::ray::Ray;
use crate::simd::{Isa, Portable};
use crate::texture::{Texture, TextureId};
use accel::Accelerator;
pub use accel::{AcceleratorChoice, Primitives};
use std::path::Path;

/// A validated, ready-to-render scene.
#[derive(Clone, Debug)]
pub struct Scene {
    pub settings: RenderSettings,
    pub camera_settings: CameraSettings,
    pub camera: Camera,
    pub background: Background,
    pub materials: Vec<Material>,
    /// The texture each material's colour comes from (its albedo, or a light's emission),
    /// or `None` for the material's own constant colour.
    pub material_textures: Vec<Option<TextureId>>,
    pub textures: Vec<Texture>,
    pub primitives: Primitives,
    /// The image files the textures were read from, for the recipe.
    pub texture_files: Vec<TextureFile>,
    /// Some material takes its colour from a texture.
    textured: bool,
    accel: Accelerator,
}

/// An image file a texture was read from: its name as the scene file gives it, and the
/// XXH3-128 of its bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextureFile {
    pub name: String,
    pub hash: u128,
}

/// What a scene is made of besides its settings, camera and background.
#[derive(Clone, Debug, Default)]
pub struct SceneContents {
    pub materials: Vec<Material>,
    pub material_textures: Vec<Option<TextureId>>,
    pub textures: Vec<Texture>,
    pub primitives: Primitives,
    pub texture_files: Vec<TextureFile>,
}

impl Scene {
    /// Assembles a scene of still spheres from runtime parts (used by tests).
    pub fn new(
        settings: RenderSettings,
        camera_settings: CameraSettings,
        background: Background,
        materials: Vec<Material>,
        spheres: Vec<Sphere>,
    ) -> Self {
        let contents = SceneContents {
            material_textures: vec![None; materials.len()],
            materials,
            primitives: Primitives {
                spheres,
                ..Primitives::default()
            },
            ..SceneContents::default()
        };
        Self::assemble(settings, camera_settings, background, contents)
    }

    /// Assembles a scene from runtime parts, building its accelerator.
    pub fn assemble(
        settings: RenderSettings,
        camera_settings: CameraSettings,
        background: Background,
        contents: SceneContents,
    ) -> Self {
        let accel = Accelerator::build(&contents.primitives);
        let textured = contents.material_textures.iter().any(Option::is_some);
        Self {
            textured,
            settings,
            camera: Camera::new(&camera_settings),
            camera_settings,
            background,
            materials: contents.materials,
            material_textures: contents.material_textures,
            textures: contents.textures,
            primitives: contents.primitives,
            texture_files: contents.texture_files,
            accel,
        }
    }

    /// The still spheres (the only primitives of the first book's scenes).
    pub fn spheres(&self) -> &[Sphere] {
        &self.primitives.spheres
    }

    /// Every primitive, by kind.
    pub fn primitives(&self) -> &Primitives {
        &self.primitives
    }

    /// How the scene's accelerator is shaped (see `AcceleratorChoice`).
    pub fn accelerator(&self) -> AcceleratorChoice {
        self.accel.choice()
    }

    /// True when a path needs more than the first book's integrator: something emits, is
    /// textured, moves, or scatters inside a medium, or the camera's shutter stays open.
    pub fn needs_full_paths(&self) -> bool {
        self.accel.choice() != AcceleratorChoice::StillSpheres
            || self.camera.has_shutter()
            || self.textured
            || self.materials.iter().any(|m| {
                matches!(
                    m,
                    Material::DiffuseLight { .. } | Material::Isotropic { .. }
                )
            })
    }

    /// True when the scene holds a medium: each ray segment then draws the random number a
    /// medium turns into its scattering distance (`Moment::medium_key`).
    pub fn has_media(&self) -> bool {
        !self.primitives.media.is_empty()
    }

    /// Reads, parses and validates a scene file, applying command-line overrides. Image
    /// textures are read from the scene file's directory.
    pub fn load(path: &Path, overrides: &Overrides) -> Result<Scene> {
        Self::parse(&Self::read_text(path)?, path, overrides)
    }
    /// The text of the scene file at `path`, which must be UTF-8 and at most
    /// `MAX_SCENE_BYTES` long. (A pipe is read too: `tessera render <(generate)`.)
    pub fn read_text(path: &Path) -> Result<String> {
        use std::io::Read;
        let io = |cause| Error::Io {
            path: path.to_owned(),
            cause,
        };
        let mut bytes = Vec::new();
        // Only a regular file: a FIFO or a device would block or never end.
        crate::input_file::open_regular(path)
            .and_then(|f| f.take(MAX_SCENE_BYTES + 1).read_to_end(&mut bytes))
            .map_err(io)?;
        if bytes.len() as u64 > MAX_SCENE_BYTES {
            return Err(io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!(
                    "is larger than {} MiB, more than a scene file may be",
                    MAX_SCENE_BYTES >> 20
                ),
            )));
        }
        let text = String::from_utf8(bytes).map_err(|e| {
            let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
            // The valid prefix is text: its end is where the bad byte sits.
            let prefix = std::str::from_utf8(valid).unwrap_or_default();
            Error::SceneSyntax {
                path: path.to_owned(),
                at: Location::of_offset(prefix, prefix.len()),
                message: format!(
                    "invalid UTF-8 (byte 0x{:02x}); a scene file is UTF-8 text",
                    e.as_bytes()[valid.len()]
                ),
            }
        })?;
        Ok(text)
    }

    /// Parses and validates scene text; `path` names the source in errors, and image textures
    /// are read from its directory.
    pub fn parse(text: &str, path: &Path, overrides: &Overrides) -> Result<Scene> {
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::parse_with(text, path, overrides, &TextureSource::Dirs(vec![dir]))
    }

    /// `parse`, reading image textures from `source`.
    pub fn parse_with(
        text: &str,
        path: &Path,
        overrides: &Overrides,
        source: &TextureSource,
    ) -> Result<Scene> {
        let syntax = |e: &toml::de::Error, field: Option<String>| {
            let start = e.span().map_or(0, |s| s.start);
            let message = name_the_table(text, start, &plain_types(e.message().trim()));
            let at = Location::of_offset(text, start);
            match field {
                Some(field) => Error::SceneValue {
                    path: path.to_owned(),
                    at,
                    field,
                    message,
                },
                None => Error::SceneSyntax {
                    path: path.to_owned(),
                    at,
                    message,
                },
            }
        };
        if let Some((offset, bound)) = values::past_the_bound(text) {
            let message = match bound {
                values::Bound::Values => format!(
                    "more than {} values, tables and arrays (commas, equals signs, dots, \
                     brackets and braces) in one scene file; a scene of more spheres draws \
                     them with a generator",
                    values::MAX_SCENE_VALUES
                ),
                values::Bound::Tokens => format!(
                    "more than {} words, strings, comments, line ends, runs of blanks and \
                     closing brackets in one scene file",
                    values::MAX_SCENE_TOKENS
                ),
            };
            return Err(Error::SceneSyntax {
                path: path.to_owned(),
                at: Location::of_offset(text, offset),
                message,
            });
        }
        let document = toml::Deserializer::parse(text).map_err(|e| syntax(&e, None))?;
        // The path of keys to a value of the wrong shape names its field, as a value out
        // of range does; a missing key names its table instead (`name_the_table`).
        let desc: desc::SceneDesc = serde_path_to_error::deserialize(document).map_err(|e| {
            let field = key_path(e.path());
            let missing = e.inner().message().starts_with("missing field");
            let field = (!field.is_empty() && !missing).then_some(field);
            syntax(e.inner(), field)
        })?;
        build::build(&desc, text, path, overrides, source)
    }

    /// The closest hit along `ray` within `interval`, using `stack` as scratch space.
    #[inline]
    pub fn hit(&self, ray: &Ray, interval: Interval, stack: &mut TraversalStack) -> Option<Hit> {
        self.hit_with(ray, interval, stack, RayHints::default())
    }

    /// `hit` helped by what the caller knows of the ray (see `RayHints`); the same answer.
    #[inline]
    pub fn hit_with(
        &self,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        self.hit_on(Portable, ray, interval, stack, hints)
    }

    /// `hit_with` on the SIMD path of `isa`: the same answer on every path. Rays are taken
    /// at time 0 and media scatter by the key 0 (`hit_at` gives both).
    #[inline(always)]
    pub fn hit_on<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        if self.accel.choice() == AcceleratorChoice::StillSpheres {
            self.accel
                .hit_spheres(isa, ray, interval, stack, hints)
                .map(|(t, id)| self.sphere_surface(ray, t, id))
        } else {
            self.hit_at(isa, ray, Moment::default(), interval, stack, hints)
        }
    }

    /// `hit_on` for a scene of still spheres only (`AcceleratorChoice::StillSpheres`: the
    /// first book's path takes it, so as not to ask at each hit).
    #[inline(always)]
    pub fn hit_still_on<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        self.accel
            .hit_spheres(isa, ray, interval, stack, hints)
            .map(|(t, id)| self.sphere_surface(ray, t, id))
    }

    /// The closest hit along `ray` taken at `moment` (its time, and its segment's random
    /// number for media), on the SIMD path of `isa`.
    #[inline(always)]
    pub fn hit_at<I: Isa>(
        &self,
        isa: I,
        ray: &Ray,
        moment: Moment,
        interval: Interval,
        stack: &mut TraversalStack,
        hints: RayHints,
    ) -> Option<Hit> {
        self.accel
            .hit_all(isa, ray, moment, interval, stack, hints)
            .map(|(t, id)| self.surface(ray, moment, t, id))
    }

    /// True when paths are traced sixteen at a time, each segment's rays tested together
    /// (`AcceleratorChoice::FewQuads`): see `hit_batch`.
    pub fn batches_paths(&self) -> bool {
        self.accel.choice() == AcceleratorChoice::FewQuads
    }

    /// For a scene that `batches_paths`: the closest hit of each ray of `rays` (in the lanes
    /// of `active`; `alone`, the same rays one by one, taken at `moments`), as `hit_at` finds
    /// it for that ray alone: its parameter and primitive id (`bvh::NO_HIT` for none). Its
    /// hit record is `surface_of`'s.
    #[inline(always)]
    pub fn hit_batch<I: Isa>(
        &self,
        isa: I,
        rays: &RayBatch,
        alone: &[Ray; BATCH],
        moments: &[Moment; BATCH],
        active: u32,
    ) -> ([f32; BATCH], [u32; BATCH]) {
        (self.accel).hit_batch(isa, rays, alone, moments, active, &self.primitives.media)
    }

    /// The hit record of primitive `id` (`bvh::NO_HIT`: none) at `t` along `ray` taken at
    /// `moment`.
    #[inline(always)]
    pub fn surface_of(&self, ray: &Ray, moment: Moment, t: f32, id: u32) -> Option<Hit> {
        (id != crate::bvh::NO_HIT).then(|| self.surface(ray, moment, t, PrimitiveId(id)))
    }

    /// The spheres, giants included, that `keep` accepts, when they are few enough to test
    /// without the hierarchy (see `Bvh::candidates`; `keep_box` must accept every box
    /// holding a sphere `keep` would). Only scenes of still spheres have them.
    pub fn candidates(
        &self,
        keep_box: impl Fn(Vec3, Vec3) -> bool,
        keep: impl Fn(&Sphere) -> bool,
    ) -> Option<Candidates> {
        self.accel
            .candidates(&self.primitives.spheres, keep_box, keep)
    }

    /// The closest hit along a camera ray among the `candidates` picked for it: the same as
    /// `hit` (on the SIMD path of `isa`).
    #[inline(always)]
    pub fn hit_candidates<I: Isa>(
        &self,
        isa: I,
        candidates: &Candidates,
        ray: &Ray,
        interval: Interval,
    ) -> Option<Hit> {
        self.accel
            .hit_candidates(isa, candidates, ray, interval)
            .map(|(t, id)| self.sphere_surface(ray, t, id))
    }

    /// Scratch space for `hit`, sized for this scene.
    pub fn new_stack(&self) -> TraversalStack {
        self.accel.new_stack()
    }

    /// The hit record of still sphere `id` at `t` along `ray`.
    #[inline(always)]
    fn sphere_surface(&self, ray: &Ray, t: f32, id: PrimitiveId) -> Hit {
        // A still sphere's id is its index (`PrimitiveId::SPHERES` is 0).
        let sphere = &self.primitives.spheres[id.0 as usize];
        let p = ray.at(t);
        let outward = sphere.normal_at(p);
        let front_face = ray.dir.dot(outward) < 0.0;
        Hit {
            t,
            p,
            normal: if front_face { outward } else { -outward },
            front_face,
            // `outward` is (p - c)/r: out of the ball when r > 0; flipped on a back face.
            normal_points_out: (sphere.radius > 0.0) == front_face,
            material: sphere.material,
            primitive: id,
        }
    }

    /// The hit record of primitive `id` at `t` along `ray` taken at `moment`.
    #[inline(always)]
    fn surface(&self, ray: &Ray, moment: Moment, t: f32, id: PrimitiveId) -> Hit {
        let p = ray.at(t);
        let (outward, radius_sign, material) = match id.kind() {
            PrimitiveKind::Sphere => return self.sphere_surface(ray, t, id),
            PrimitiveKind::MovingSphere => {
                let s = &self.primitives.moving_spheres[id.index()];
                (s.normal_at(p, moment.time), s.radius > 0.0, s.material)
            }
            PrimitiveKind::Quad => {
                let q = &self.primitives.quads[id.index()];
                (q.normal, true, q.material)
            }
            PrimitiveKind::Medium => {
                // A scattering point inside a medium: no surface; the book's record.
                let m = &self.primitives.media[id.index()];
                return Hit {
                    t,
                    p,
                    normal: crate::geometry::SCATTER_NORMAL,
                    front_face: true,
                    normal_points_out: true,
                    material: m.material,
                    primitive: id,
                };
            }
        };
        let front_face = ray.dir.dot(outward) < 0.0;
        Hit {
            t,
            p,
            normal: if front_face { outward } else { -outward },
            front_face,
            normal_points_out: radius_sign == front_face,
            material,
            primitive: id,
        }
    }

    /// `escape_offset` of a hit on a still sphere (all a scene of still spheres has).
    #[inline(always)]
    pub fn still_sphere_offset(&self, hit: &Hit) -> f32 {
        self.primitives.spheres[hit.primitive.0 as usize].escape_offset(hit.t)
    }

    /// How far off the surface a ray leaving `hit` must start to clear the rounding of the
    /// hit (see `Sphere::escape_offset`); 0 inside a medium, where there is no surface.
    #[inline(always)]
    pub fn escape_offset(&self, hit: &Hit) -> f32 {
        let i = hit.primitive.index();
        match hit.primitive.kind() {
            PrimitiveKind::Sphere => self.primitives.spheres[i].escape_offset(hit.t),
            PrimitiveKind::MovingSphere => self.primitives.moving_spheres[i].escape_offset(hit.t),
            PrimitiveKind::Quad => self.primitives.quads[i].escape_offset(hit.t),
            PrimitiveKind::Medium => 0.0,
        }
    }

    /// True when no ray leaving `hit` to the side `side_is_normal` can meet the primitive
    /// hit again: off a sphere's outside (convex), and off a quad either way (flat).
    #[inline(always)]
    pub fn leaves_for_good(&self, hit: &Hit, side_is_normal: bool) -> bool {
        self.leaving(hit, side_is_normal).1
    }

    /// `escape_offset` and `leaves_for_good` at once, with one look at the hit's kind.
    #[inline(always)]
    pub fn leaving(&self, hit: &Hit, side_is_normal: bool) -> (f32, bool) {
        let i = hit.primitive.index();
        let outside = hit.leaves_outside(side_is_normal);
        match hit.primitive.kind() {
            PrimitiveKind::Sphere => (self.primitives.spheres[i].escape_offset(hit.t), outside),
            PrimitiveKind::MovingSphere => (
                self.primitives.moving_spheres[i].escape_offset(hit.t),
                outside,
            ),
            PrimitiveKind::Quad => (self.primitives.quads[i].escape_offset(hit.t), true),
            PrimitiveKind::Medium => (0.0, false),
        }
    }

    /// The texture coordinates of `hit` (the book's `get_sphere_uv` on spheres, the edge
    /// coordinates on quads; 0 in media), at `time` for a moving sphere.
    pub fn uv(&self, hit: &Hit, time: f32) -> (f32, f32) {
        let i = hit.primitive.index();
        let on_ball = |n: Vec3| {
            // theta from -y up, phi around y from -x: u = phi / 2π, v = theta / π.
            use std::f64::consts::PI;
            let (x, y, z) = (f64::from(n.x), f64::from(n.y), f64::from(n.z));
            let theta = atan2((1.0 - y * y).max(0.0).sqrt(), -y);
            let phi = atan2(-z, x) + PI;
            ((phi / (2.0 * PI)) as f32, (theta / PI) as f32)
        };
        match hit.primitive.kind() {
            PrimitiveKind::Sphere => {
                let s = &self.primitives.spheres[i];
                on_ball(((hit.p - s.center) / s.radius.abs()).clamp(-Vec3::ONE, Vec3::ONE))
            }
            PrimitiveKind::MovingSphere => {
                let s = &self.primitives.moving_spheres[i];
                let n = (hit.p - s.center(time)) / s.radius.abs();
                on_ball(n.clamp(-Vec3::ONE, Vec3::ONE))
            }
            PrimitiveKind::Quad => self.primitives.quads[i].uv(hit.p),
            PrimitiveKind::Medium => (0.0, 0.0),
        }
    }

    /// The value at `hit` of the texture that colours its material, if it has one.
    #[inline(always)]
    pub fn texture_at(&self, hit: &Hit, time: f32) -> Option<Color> {
        if !self.textured {
            return None;
        }
        self.texture_value(hit, time)
    }

    /// `texture_at` for a scene with textures.
    #[inline(never)]
    fn texture_value(&self, hit: &Hit, time: f32) -> Option<Color> {
        let id = self.material_textures[hit.material.0 as usize]?;
        let (u, v) = match self.textures[id.0 as usize] {
            // Only image textures read the coordinates.
            Texture::Image(_) | Texture::Checker { .. } => self.uv(hit, time),
            _ => (0.0, 0.0),
        };
        Some(Texture::value(&self.textures, id, u, v, hit.p))
    }

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
                    let hash = xxhash_rust::xxh3::xxh3_64(image.pixels());
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

    pub fn material(&self, hit: &Hit) -> &Material {
        &self.materials[hit.material.0 as usize]
    }
}

/// The keys to a value as a scene file names them (`spheres[2].center`), without the
/// wrappers that keep each value's place in the file.
fn key_path(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut named = String::new();
    for segment in path.iter() {
        match segment {
            Segment::Seq { index } => named.push_str(&format!("[{index}]")),
            Segment::Map { key } | Segment::Enum { variant: key } => {
                if key.starts_with("$__serde_spanned") {
                    continue;
                }
                if !named.is_empty() {
                    named.push('.');
                }
                named.push_str(key);
            }
            Segment::Unknown => {}
        }
    }
    named
}

/// The tables a scene file holds at its top level (`desc::SceneDesc`'s fields).
const TOP_LEVEL: [&str; 14] = [
    "image",
    "render",
    "camera",
    "background",
    "textures",
    "materials",
    "spheres",
    "quads",
    "rects",
    "boxes",
    "media",
    "random_spheres",
    "random_boxes",
    "random_sphere_clouds",
];

/// A missing key's message with the table it is missing from: for a whole table, the
/// file's top level; else the table whose header starts the line at `start` (where the
/// parser points), `[[spheres]]` counted (`#2`), or the key of an inline table on it.
fn name_the_table(text: &str, start: usize, message: &str) -> String {
    let Some(key) = message
        .strip_prefix("missing field `")
        .and_then(|m| m.strip_suffix('`'))
    else {
        return message.to_owned();
    };
    if TOP_LEVEL.contains(&key) {
        return format!(
            "missing table [{key}] at the top level of the file; docs/scene-format.md lists \
             every key"
        );
    }
    let line_start = text
        .get(..start)
        .map_or(0, |t| t.rfind('\n').map_or(0, |i| i + 1));
    let line = text
        .get(line_start..)
        .unwrap_or("")
        .lines()
        .next()
        .unwrap_or("");
    let header = line.split('#').next().unwrap_or("").trim();
    let inline = header
        .split_once('=')
        .filter(|(_, value)| value.trim_start().starts_with(['{', '[']))
        .map(|(name, _)| name.trim());
    if let Some(name) = inline {
        return format!("`{name}`: missing key `{key}`; docs/scene-format.md lists every key");
    }
    let Some(name) = header
        .strip_prefix('[')
        .and_then(|h| h.strip_suffix(']'))
        .map(|h| h.trim_matches(['[', ']']).trim())
    else {
        return format!("missing key `{key}`; docs/scene-format.md lists every key");
    };
    let table = if header.starts_with("[[") {
        // Which of the array's tables: count the headers of the same name up to here.
        let nth = text[..line_start]
            .lines()
            .filter(|l| l.split('#').next().unwrap_or("").trim() == header)
            .count()
            + 1;
        format!("{header} #{nth}")
    } else {
        header.to_owned()
    };
    let hint = match (name, key) {
        ("image", "max_depth") => " (the most ray segments per path: the book uses 50)",
        ("image", "samples_per_pixel") => " (samples per pixel: the book uses 100)",
        ("image", "width" | "height") => " (the image's size in pixels)",
        _ => "",
    };
    format!("{table}: missing key `{key}`{hint}; docs/scene-format.md lists every key")
}

/// Serde names Rust types in its messages; a scene author knows TOML's.
fn plain_types(message: &str) -> String {
    message
        .replace("expected i64", "expected an integer")
        .replace("expected u64", "expected a non-negative integer")
        .replace("expected f64", "expected a number")
        .replace("a spanned value", "a value")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Sampler;

    #[test]
    fn a_missing_key_names_its_table_at_the_tables_line() {
        let error = |text: &str| {
            Scene::parse(text, Path::new("s.toml"), &Overrides::default())
                .err()
                .unwrap()
                .to_string()
        };
        let no_depth = "# small\n\n[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\n";
        assert_eq!(
            error(no_depth),
            "s.toml:3:1: [image]: missing key `max_depth` (the most ray segments per path: \
             the book uses 50); docs/scene-format.md lists every key"
        );
        let spheres = "[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 2\n\
                       [materials.m]\ntype = \"lambertian\"\nalbedo = [1.0, 1.0, 1.0]\n\
                       [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 1.0\nmaterial = \"m\"\n\
                       [[spheres]] # the second\ncenter = [0.0, 0.0, -1.0]\nmaterial = \"m\"\n";
        assert_eq!(
            error(spheres),
            "s.toml:13:1: [[spheres]] #2: missing key `radius`; docs/scene-format.md lists \
             every key"
        );
        let top = "missing table [image] at the top level";
        assert!(error("# nothing\n").contains(top));
        // A file that starts with another table still lacks its [image] at the top level.
        let render_first = "[render]\ngamma = 2.0\n";
        assert!(
            error(render_first).starts_with("s.toml:1:1: missing table [image]"),
            "{}",
            error(render_first)
        );
        // A key missing from an inline table names that table.
        let inline = "spheres = [{ center = [0.0, 0.0, -1.0], material = \"m\" }]\n\
                      [image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 2\n\
                      [materials.m]\ntype = \"lambertian\"\nalbedo = [1.0, 1.0, 1.0]\n";
        assert!(
            error(inline).contains(":1:")
                && error(inline).contains("`spheres`: missing key `radius`"),
            "{}",
            error(inline)
        );
    }

    #[test]
    fn leaving_outside_means_heading_away_from_the_centre_for_either_radius_sign() {
        // Figure 16's scene: solid spheres and a hollow one (negative radius) inside glass.
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/img-1.16-glass-hollow.toml"
        ));
        let scene = Scene::load(path, &Overrides::default()).unwrap();
        let mut rng = Sampler::from_seed(3);
        let mut stack = scene.new_stack();
        let mut seen = [[0usize; 2]; 2];
        let glass = Vec3::new(-1.0, 0.0, -1.0);
        for k in 0..20_000 {
            // Rays from the camera's side, and rays from within the glass shell and the
            // hollow, which meet the hollow sphere from both sides.
            let ray = if k % 2 == 0 {
                let origin = Vec3::new(rng.range(-2.0, 2.0), rng.range(-0.3, 1.0), 1.0);
                let target = Vec3::new(rng.range(-1.5, 1.5), rng.range(-0.5, 0.5), -1.0);
                Ray::new(origin, (target - origin).normalize())
            } else {
                let origin = glass + rng.range(0.0, 0.49) * rng.unit_vector();
                Ray::new(origin, rng.unit_vector())
            };
            let Some(hit) = scene.hit(&ray, Interval::new(1e-3, f32::INFINITY), &mut stack) else {
                continue;
            };
            let sphere = &scene.spheres()[hit.primitive.index()];
            for side_is_normal in [true, false] {
                let side = if side_is_normal {
                    hit.normal
                } else {
                    -hit.normal
                };
                let outside = side.dot(hit.p - sphere.center) > 0.0;
                assert_eq!(hit.leaves_outside(side_is_normal), outside, "{hit:?}");
                seen[usize::from(sphere.radius < 0.0)][usize::from(outside)] += 1;
            }
        }
        // Both radius signs met, each leaving both ways.
        assert!(seen.iter().flatten().all(|&n| n > 0), "{seen:?}");
    }
}
