//! Scenes: loading a TOML scene file, validating it, and the runtime scene the renderer reads.

mod accel;
mod build;
mod check;
mod cover;
pub mod desc;
mod draws;
mod fingerprint;
mod hits;
mod settings;
mod shapes;
mod syntax;
mod textures;
mod values;

pub use build::{MAX_PIXELS, Overrides};
pub use check::{MAX_LENGTH, MIN_RADIUS};
pub use cover::MAX_KEEP_CLEAR;
pub use textures::{
    MAX_TEXTURE_BYTES, MAX_TEXTURE_PIXELS, TextureSource, is_plain_name, open_texture, read_texture,
};

/// The longest scene file tessera reads: the cover's is 3 KiB, 20,000 spheres written out
/// about 2 MiB.
pub const MAX_SCENE_BYTES: u64 = 64 << 20;
pub use settings::{Background, RenderSettings, Shading, SurfaceOffset};

use crate::camera::{Camera, CameraSettings};
use crate::error::{Error, Location, Result};
use crate::geometry::{Hit, Sphere};
use crate::material::Material;
use crate::texture::{Texture, TextureId};
use accel::Accelerator;
pub use accel::{AcceleratorChoice, Primitives};
use std::path::Path;
use syntax::{key_path, name_the_table, plain_types, too_deep};

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
        Self::describe(text, path)?.build(overrides, source)
    }

    /// Scene text parsed, within the bounds on its values and tokens, into its description,
    /// from which its settings are read and the scene is built without parsing the text
    /// again; `path` names the source in errors.
    pub fn describe<'a>(text: &'a str, path: &Path) -> Result<Described<'a>> {
        Ok(Described {
            desc: describe(text, path)?,
            text,
            path: path.to_owned(),
        })
    }
}

/// Scene text parsed once (`Scene::describe`): what a recipe's settings are checked against
/// where its textures may not be at hand (`tessera info`), and then what its scene is built
/// from. A scene file of 2^20 values takes some seconds and 500 MB to parse: it is parsed
/// once however many times it is looked at.
pub struct Described<'a> {
    desc: desc::SceneDesc,
    text: &'a str,
    path: std::path::PathBuf,
}

impl Described<'_> {
    /// The settings the text gives with `overrides` (size, crop, sampling, depth, seed,
    /// gamma), checked as `Scene::parse` checks them, with nothing else built and no texture
    /// file read.
    pub fn settings(&self, overrides: &Overrides) -> Result<RenderSettings> {
        build::settings(&self.desc, self.text, &self.path, overrides)
    }

    /// The scene, built and checked as `Scene::parse` builds it, with image textures read
    /// from `source`; its settings are `settings`' with the same `overrides`.
    pub fn build(&self, overrides: &Overrides, source: &TextureSource) -> Result<Scene> {
        build::build(&self.desc, self.text, &self.path, overrides, source)
    }
}

/// Scene text parsed into its description, within the bounds on its values and tokens;
/// `path` names the source in errors.
fn describe(text: &str, path: &Path) -> Result<desc::SceneDesc> {
    let syntax = |e: &toml::de::Error, field: Option<String>| {
        let start = e.span().map_or(0, |s| s.start);
        // The parser's refusal of what nests too deep names no place (for a key) and no
        // field: they are found in the text.
        let (start, field, message) = match too_deep(text, start, e.message().trim()) {
            Some((at, deep_field, message)) => (at, deep_field.or(field), message),
            None => (
                start,
                field,
                name_the_table(text, start, &plain_types(e.message().trim())),
            ),
        };
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
    Ok(desc)
}

impl Scene {
    pub fn material(&self, hit: &Hit) -> &Material {
        &self.materials[hit.material.0 as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A medium's density at the bounds the docs give (10^-30 and 10^30) is taken; past
    /// them, refused. 1e30 was refused as "must be positive, between 1e-30 and 1e30, got
    /// 1e30": the check compared f32's 1e30 (1.0000000150e30) with f64's.
    #[test]
    fn a_medium_s_density_at_its_documented_bounds_is_taken() {
        let scene = |density: &str| {
            let text = format!(
                "[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 2\n\
                 [materials.smoke]\ntype = \"isotropic\"\nalbedo = [1.0, 1.0, 1.0]\n\
                 [[media]]\ndensity = {density}\nmaterial = \"smoke\"\n\
                 sphere = {{ center = [0.0, 0.0, -1.0], radius = 0.5 }}\n"
            );
            Scene::parse(&text, Path::new("s.toml"), &Overrides::default())
        };
        for within in ["1e30", "1e-30", "1.0"] {
            assert!(scene(within).is_ok(), "{within}: {:?}", scene(within).err());
        }
        for past in ["1.1e30", "9e-31"] {
            let e = scene(past).err().unwrap().to_string();
            assert!(
                e.contains("must be positive, between 1e-30 and 1e30"),
                "{e}"
            );
        }
    }

    /// An integer past its field's type is said as out of range, with the field, its line
    /// and the range: it was "invalid type: integer `…` as i128, expected an integer".
    #[test]
    fn an_integer_past_its_field_s_type_is_said_out_of_range() {
        let error = |from: &str, to: &str| {
            let text = "[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 2\n\
                        seed = 1\n[materials.m]\ntype = \"lambertian\"\nalbedo = [1.0, 1.0, 1.0]\n\
                        [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"m\"\n";
            assert!(text.contains(from));
            Scene::parse(
                &text.replace(from, to),
                Path::new("s.toml"),
                &Overrides::default(),
            )
            .err()
            .unwrap()
            .to_string()
        };
        let signed = format!("an integer from {} to {}", i64::MIN, i64::MAX);
        for big in [
            "99999999999999999999999",
            "9999999999999999999",
            "-99999999999999999999",
        ] {
            assert_eq!(
                error("width = 4", &format!("width = {big}")),
                format!(
                    "s.toml:2:9: field `image.width`: integer `{big}` is out of range: this \
                     field is {signed}"
                )
            );
        }
        for seed in ["99999999999999999999", "-1"] {
            assert_eq!(
                error("seed = 1", &format!("seed = {seed}")),
                format!(
                    "s.toml:6:8: field `image.seed`: integer `{seed}` is out of range: this \
                     field is an integer from 0 to {}",
                    u64::MAX
                )
            );
        }
        let radius = error("radius = 0.5", "radius = 99999999999999999999999");
        assert!(
            radius.starts_with(
                "s.toml:12:10: field `spheres[0].radius`: integer `99999999999999999999999` \
                 is out of range"
            ) && radius.contains("(`1e23`)"),
            "{radius}"
        );
    }

    /// A key or value nested deeper than the TOML parser goes is refused at its line, with
    /// its field: a dotted key of 81 parts was "s.toml:1:1: recursion limit" wherever it
    /// stood, and arrays nested 81 deep "cannot recurse further; max recursion depth met",
    /// with no field.
    #[test]
    fn what_nests_past_the_parser_s_depth_is_refused_at_its_line_and_field() {
        let good = "[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 2\n\
                    [materials.m]\ntype = \"lambertian\"\nalbedo = [1.0, 1.0, 1.0]\n";
        let error = |text: &str| {
            Scene::parse(text, Path::new("s.toml"), &Overrides::default())
                .err()
                .unwrap()
                .to_string()
        };
        let n = syntax::PARSER_NESTING;
        let key = vec!["k"; n + 1].join(".");
        // # a comment. with. dots. and a "quoted.key" stay out of the count.
        let quiet = format!("# {}\n", ".".repeat(n + 5));
        for (place, text) in [
            ("a key", format!("{good}{quiet}  {key} = 1\n")),
            ("a header", format!("{good}{quiet}  [{key}]\n")),
            (
                "an inline table",
                format!("{good}{quiet}x = {{ {key} = 1 }}\n"),
            ),
        ] {
            let e = error(&text);
            assert!(
                e.starts_with(&format!(
                    "s.toml:10:{}: a dotted key of more than {} parts",
                    if place == "an inline table" {
                        7
                    } else {
                        3 + usize::from(place == "a header")
                    },
                    n
                )),
                "{place}: {e}"
            );
        }
        // One part fewer is a key the parser takes (and the scene does not know).
        let within = vec!["k"; n].join(".");
        assert!(!error(&format!("{good}{within} = 1\n")).contains("more than"));
        let deep = format!(
            "{good}[random_spheres]\nclearance = 0.5 # [[\nkeep_clear = [\n  \"[\", {}{}]\n",
            "[".repeat(n),
            "]".repeat(n)
        );
        let e = error(&deep);
        assert_eq!(
            e,
            format!(
                "s.toml:12:{}: field `random_spheres.keep_clear`: arrays and inline tables \
                 nested more than {n} deep, more than the TOML parser takes; a scene's values \
                 nest a few deep",
                7 + n
            )
        );
    }

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
}
