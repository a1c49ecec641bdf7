//! The recipe an image carries: the scene file's text, the command-line settings that change
//! the image, the build that made it and the hash of its exact sums. `image_file` writes it
//! into the image's own metadata and reads it back; this module makes it, checks one read
//! from a file a stranger may have crafted, and rebuilds the scene it describes.

use crate::error::{Error, Result};
use crate::film::Film;
use crate::math::PixelRect;
use crate::scene::{Overrides, RenderSettings, Scene, TextureSource};
use crate::text::terminal_safe;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The recipe's format, and the one this tessera reads.
pub const SCHEMA: &str = "tessera-recipe/1";
const SCHEMA_PREFIX: &str = "tessera-recipe/";
pub use crate::metadata::{KEY, MAX_BYTES};
/// The longest scene file name a recipe may give.
const MAX_NAME: usize = 255;
/// The most texture files a recipe may list.
const MAX_TEXTURES: usize = 256;

/// The part of a recipe a partial render carries, so that a merge of parts can write it:
/// the scene file and the command line's settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Source {
    pub scene: SceneText,
    pub overrides: RecipeOverrides,
}

impl Source {
    /// The source of a render of the file `scene_file`, whose text is `text`, with
    /// `overrides`.
    pub fn new(scene_file: &Path, text: &str, overrides: Overrides) -> Self {
        let name = scene_file
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        Source {
            scene: SceneText {
                name,
                text: text.to_owned(),
            },
            overrides: overrides.into(),
        }
    }

    /// The scene it describes, parsed as a scene file is; `origin` names it in errors, and
    /// image textures are looked for in `dirs`.
    pub fn parse(&self, origin: &Path, dirs: &[PathBuf]) -> Result<Scene> {
        let source = TextureSource::Dirs(dirs.to_vec());
        Scene::parse_with(&self.scene.text, origin, &self.overrides.into(), &source)
    }
}

/// Where the image textures of a scene made again are looked for: `first` (an explicit
/// directory, if any), next to the file that carried the recipe (`carrier`), then in
/// `scenes/` of the working directory, where the repository keeps its scenes' textures.
pub fn texture_dirs(first: Option<&Path>, carrier: &Path) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = first.map(Path::to_path_buf).into_iter().collect();
    let beside = carrier
        .parent()
        .map_or_else(PathBuf::new, Path::to_path_buf);
    dirs.push(if beside.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        beside
    });
    dirs.push(PathBuf::from("scenes"));
    dirs
}

/// What made an image, and how to make it again.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Recipe {
    pub schema: String,
    pub tessera: Maker,
    pub scene: SceneText,
    /// The command line's settings that replaced the scene file's.
    pub overrides: RecipeOverrides,
    /// The settings in effect: what the scene and the overrides give.
    pub image: Effective,
    /// XXH3-128 of the exact sums (`Film::content_hash`), as `xxh3-128:` and 32 hex digits.
    pub sums: String,
    /// The image files the scene's textures were read from, each with the hash of its bytes
    /// (none for most scenes, and then left out of the JSON).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub textures: Vec<RecipeTexture>,
}

/// A texture file as a recipe records it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecipeTexture {
    /// Its name as the scene file gives it.
    pub name: String,
    /// XXH3-128 of its bytes, as `xxh3-128:` and 32 hex digits.
    pub hash: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Maker {
    pub version: String,
    pub commit: String,
}

impl Maker {
    /// This build of tessera: its version and the commit it was built from (`-dirty` where
    /// the tree had changes).
    pub fn this_build() -> Self {
        Maker {
            version: env!("CARGO_PKG_VERSION").to_owned(),
            commit: env!("TESSERA_GIT_COMMIT").to_owned(),
        }
    }
}

impl std::fmt::Display for Maker {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "tessera {} (commit {})", self.version, self.commit)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneText {
    /// The scene file's name, without its directory.
    pub name: String,
    /// The scene file's text, whole.
    pub text: String,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecipeOverrides {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples_per_pixel: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_depth: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

impl From<Overrides> for RecipeOverrides {
    fn from(o: Overrides) -> Self {
        RecipeOverrides {
            width: o.width,
            samples_per_pixel: o.samples_per_pixel,
            max_depth: o.max_depth,
            seed: o.seed,
        }
    }
}

impl From<RecipeOverrides> for Overrides {
    fn from(o: RecipeOverrides) -> Self {
        Overrides {
            width: o.width,
            samples_per_pixel: o.samples_per_pixel,
            max_depth: o.max_depth,
            seed: o.seed,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effective {
    pub width: u32,
    pub height: u32,
    /// The pixels written, `[x, y, width, height]`: the whole image unless the scene crops.
    pub window: [u32; 4],
    pub samples_per_pixel: u32,
    pub max_depth: u32,
    pub seed: u64,
    pub gamma: f32,
}

impl Effective {
    fn of(scene: &Scene) -> Self {
        Self::of_settings(&scene.settings)
    }

    fn of_settings(s: &RenderSettings) -> Self {
        let w = s.window;
        Effective {
            width: s.width,
            height: s.height,
            window: [w.x0, w.y0, w.width, w.height],
            samples_per_pixel: s.samples_per_pixel,
            max_depth: s.max_depth,
            seed: s.seed,
            gamma: s.gamma,
        }
    }
}

/// The hash of a film's exact sums, as recipes and benchmark results write it.
pub fn sums_hash(film: &Film) -> String {
    format!("xxh3-128:{:032x}", film.content_hash())
}

impl Recipe {
    /// The recipe of `film`, rendered from `scene`, which `source` describes.
    pub fn new(source: &Source, scene: &Scene, film: &Film) -> Self {
        Self::with_sums(source, scene, sums_hash(film))
    }

    /// The recipe a render of `scene` from `source` will have, but for its sums' hash (a
    /// hash of none, of the same length): known before the render, to be checked as the
    /// image's will be (`why_not_carried`).
    pub fn unrendered(source: &Source, scene: &Scene) -> Self {
        Self::with_sums(source, scene, sums_hash(&Film::new(0, 0, 0)))
    }

    fn with_sums(source: &Source, scene: &Scene, sums: String) -> Self {
        Recipe {
            schema: SCHEMA.to_owned(),
            tessera: Maker::this_build(),
            scene: source.scene.clone(),
            overrides: source.overrides,
            image: Effective::of(scene),
            sums,
            textures: textures_of(scene),
        }
    }

    /// Why an image cannot carry this recipe, if it cannot: its readers, tessera's own
    /// first, refuse a recipe over `MAX_BYTES` or one that fails their other checks (more
    /// than `MAX_TEXTURES` texture files, a name over `MAX_NAME` bytes), so such a recipe is
    /// left out, not written. The same checks as `parse`'s, on what this build writes.
    pub fn why_not_carried(&self) -> Option<String> {
        self.carried_json().err()
    }

    /// The recipe's JSON (`to_json`), made once, where an image can carry it; else why not
    /// (`why_not_carried`). A scene text over `MAX_BYTES` is too long without writing its
    /// JSON, which is no shorter: a scene file may have 64 MiB, whose JSON took 0.5 s.
    pub fn carried_json(&self) -> std::result::Result<String, String> {
        let too_long = |len: usize, over: &str| {
            format!(
                "its recipe would be {over}{len} bytes, more than the {MAX_BYTES} an image may carry"
            )
        };
        if self.scene.text.len() > MAX_BYTES {
            return Err(too_long(self.scene.text.len(), "over "));
        }
        let json = self.to_json();
        if json.len() > MAX_BYTES {
            return Err(too_long(json.len(), ""));
        }
        self.check().map_err(|why| format!("its recipe {why}"))?;
        Ok(json)
    }

    /// The recipe as JSON, every character beyond ASCII escaped (`\uXXXX`), so that formats
    /// whose text is Latin-1 or bytes (EXR attributes) carry it unchanged.
    pub fn to_json(&self) -> String {
        crate::text::ascii_json(&serde_json::to_string(self).expect("a recipe serialises"))
    }

    /// Reads a recipe from the text found in `image`, refusing what this tessera cannot
    /// trust: too long, not JSON, another schema (naming the one needed when a newer tessera
    /// wrote it), fields it does not know, values out of range.
    pub fn parse(text: &str, image: &Path) -> Result<Recipe> {
        let fail = |message: String| Error::Image {
            path: image.to_owned(),
            message: format!("its recipe {message}"),
        };
        if text.len() > MAX_BYTES {
            return Err(fail(format!(
                "is {} bytes, more than the {MAX_BYTES} a recipe may have",
                text.len()
            )));
        }
        // The schema first, so a newer recipe is named as such rather than misread.
        #[derive(Deserialize)]
        struct Versioned {
            schema: Option<String>,
            tessera: Option<Maker>,
        }
        let versioned: Versioned = serde_json::from_str(text).map_err(|e| {
            fail(format!(
                "is not a tessera recipe (not JSON of its shape: {e})"
            ))
        })?;
        let made_by = versioned.tessera.as_ref().map_or_else(String::new, |m| {
            format!(" (made by tessera {})", terminal_safe(&m.version, 40))
        });
        match versioned.schema.as_deref() {
            Some(SCHEMA) => {}
            Some(s) if s.starts_with(SCHEMA_PREFIX) => {
                let newer = s[SCHEMA_PREFIX.len()..].parse::<u32>().is_ok_and(|n| n > 1);
                return Err(fail(if newer {
                    format!(
                        "needs {}{made_by}; this tessera reads {SCHEMA}: use a newer tessera",
                        terminal_safe(s, 60)
                    )
                } else {
                    format!("has an unknown schema `{}`", terminal_safe(s, 60))
                }));
            }
            Some(s) => {
                return Err(fail(format!(
                    "has an unknown schema `{}`",
                    terminal_safe(s, 60)
                )));
            }
            None => return Err(fail("has no schema".to_owned())),
        }
        let recipe: Recipe = serde_json::from_str(text).map_err(|e| {
            fail(if e.to_string().contains("unknown field") {
                format!("has a field this tessera does not know{made_by}: {e}")
            } else {
                format!("is malformed: {e}")
            })
        })?;
        recipe.check().map_err(fail)?;
        Ok(recipe)
    }

    fn check(&self) -> std::result::Result<(), String> {
        if self.scene.name.len() > MAX_NAME {
            return Err(format!(
                "names a scene file of {} bytes",
                self.scene.name.len()
            ));
        }
        let well_formed = |hash: &str| {
            let hex = hash.strip_prefix("xxh3-128:").unwrap_or("");
            hex.len() == 32 && hex.bytes().all(|b| b.is_ascii_hexdigit())
        };
        if !well_formed(&self.sums) {
            return Err(format!(
                "has a malformed sums hash `{}`",
                terminal_safe(&self.sums, 60)
            ));
        }
        if self.textures.len() > MAX_TEXTURES {
            return Err(format!(
                "lists {} texture files, more than the {MAX_TEXTURES} a recipe may",
                self.textures.len()
            ));
        }
        for t in &self.textures {
            if t.name.len() > MAX_NAME || !well_formed(&t.hash) {
                return Err(format!(
                    "has a malformed texture entry `{}`",
                    terminal_safe(&t.name, 80)
                ));
            }
        }
        Ok(())
    }

    /// The scene the recipe describes, parsed and checked as a scene file is (errors name
    /// `image` and the recipe's scene), with its settings checked against the recipe's, and
    /// its image textures looked for in `dirs` and checked against the recipe's hashes:
    /// `checked`, then `Checked::scene`.
    pub fn scene(&self, image: &Path, dirs: &[PathBuf]) -> Result<Scene> {
        self.checked(image)?.scene(dirs)
    }

    /// The recipe's scene text parsed, once, as a scene file is, and the settings it gives
    /// with the recipe's overrides checked against the recipe's (`image`), with nothing else
    /// built and no texture file read: a recipe whose scene is not a scene, or gives other
    /// settings than it claims, is refused, naming each setting that differs. `info` and
    /// `reproduce` both check it (`verify::unrendered`), so `info` shows no claim that
    /// `reproduce` would refuse; the scene is then built from the same parse.
    pub fn checked(&self, image: &Path) -> Result<Checked<'_>> {
        let origin = self.origin(image);
        let described =
            Scene::describe(&self.scene.text, &origin).map_err(|e| overrides_fault(image, e))?;
        let settings = described
            .settings(&self.overrides.into())
            .map_err(|e| overrides_fault(image, e))?;
        self.agrees(image, Effective::of_settings(&settings))?;
        Ok(Checked {
            recipe: self,
            described,
            image: image.to_owned(),
        })
    }

    /// Refuses the recipe where `given`, the settings its scene and overrides give, are not
    /// the ones it claims: naming each that differs, then both in full.
    fn agrees(&self, image: &Path, given: Effective) -> Result<()> {
        if given == self.image {
            return Ok(());
        }
        let (r, g) = (&self.image, &given);
        let differing: Vec<String> = [
            ("width", r.width.to_string(), g.width.to_string()),
            ("height", r.height.to_string(), g.height.to_string()),
            (
                "window",
                format!("{:?}", r.window),
                format!("{:?}", g.window),
            ),
            (
                "samples_per_pixel",
                r.samples_per_pixel.to_string(),
                g.samples_per_pixel.to_string(),
            ),
            (
                "max_depth",
                r.max_depth.to_string(),
                g.max_depth.to_string(),
            ),
            ("seed", r.seed.to_string(), g.seed.to_string()),
            ("gamma", r.gamma.to_string(), g.gamma.to_string()),
        ]
        .into_iter()
        .filter(|(_, claimed, gives)| claimed != gives)
        .map(|(field, claimed, gives)| format!("{field} {claimed}, the scene gives {gives}"))
        .collect();
        Err(Error::Image {
            path: image.to_owned(),
            message: format!(
                "its recipe's settings ({}) are not what its scene and overrides give ({}): {}",
                describe(&self.image),
                describe(&given),
                differing.join("; ")
            ),
        })
    }

    /// The name a recipe's scene goes by in errors: the image, and the scene file's name.
    fn origin(&self, image: &Path) -> PathBuf {
        PathBuf::from(format!(
            "{} (recipe scene {})",
            image.display(),
            terminal_safe(&self.scene.name, 80)
        ))
    }

    /// The scene file and overrides it was made from.
    pub fn source(&self) -> Source {
        Source {
            scene: self.scene.clone(),
            overrides: self.overrides,
        }
    }

    /// The window the image holds.
    pub fn window(&self) -> PixelRect {
        let [x0, y0, width, height] = self.image.window;
        PixelRect {
            x0,
            y0,
            width,
            height,
        }
    }
}

/// A recipe whose scene text is parsed and gives the settings it claims (`Recipe::checked`):
/// what its scene is built from, textures found, without parsing the text again.
pub struct Checked<'a> {
    recipe: &'a Recipe,
    described: crate::scene::Described<'a>,
    image: PathBuf,
}

impl Checked<'_> {
    /// The scene, built from the parse its settings were checked on, with its image
    /// textures looked for in `dirs`, each the very file the recipe's hash names. Its
    /// settings are those checked: one parse and one function give both.
    pub fn scene(&self, dirs: &[PathBuf]) -> Result<Scene> {
        let (recipe, image) = (self.recipe, self.image.as_path());
        let looked: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
        // The textures the recipe names must be found, each the very file it was made with.
        // A file named again, however spelt (`a.png`, `./a.png`), is read and hashed once:
        // 256 names of one 48 MB file once read 12 GB.
        let mut hashed: BTreeMap<PathBuf, String> = BTreeMap::new();
        for t in &recipe.textures {
            let name = terminal_safe(&t.name, 80);
            let refuse = |message: String| Error::Image {
                path: image.to_owned(),
                message,
            };
            // As a scene names a texture: nothing but what lies in `dirs` is read.
            if !crate::scene::is_plain_name(&t.name) {
                return Err(refuse(format!(
                    "its recipe names the texture file `{name}`, which is not a relative \
                     name without `..`: refused"
                )));
            }
            let found = crate::scene::open_texture(dirs, Path::new(&t.name))
                .map_err(|why| refuse(format!("its scene's {}", terminal_safe(&why, 400))))?;
            let Some((file, found)) = found else {
                return Err(Error::Image {
                    path: image.to_owned(),
                    message: format!(
                        "its scene's texture file `{name}` is not found (looked in {}); put it \
                         next to the image or pass --textures DIR",
                        looked.join(", ")
                    ),
                });
            };
            let io = |cause| Error::Io {
                path: found.clone(),
                cause,
            };
            let key = found.canonicalize().map_err(io)?;
            let hash = match hashed.get(&key) {
                Some(hash) => hash.clone(),
                None => {
                    let bytes = crate::scene::read_texture(file, &found).map_err(|why| {
                        refuse(format!("its scene's {}", terminal_safe(&why, 400)))
                    })?;
                    let hash = format!("xxh3-128:{:032x}", xxhash_rust::xxh3::xxh3_128(&bytes));
                    hashed.insert(key, hash.clone());
                    hash
                }
            };
            if hash != t.hash {
                return Err(Error::Image {
                    path: image.to_owned(),
                    message: format!(
                        "its scene's texture `{name}` found at {} is not the file the image \
                         was made with (its hash is {hash}, the recipe's {})",
                        found.display(),
                        terminal_safe(&t.hash, 60)
                    ),
                });
            }
        }
        let source = TextureSource::Dirs(dirs.to_vec());
        let scene = (self.described.build(&recipe.overrides.into(), &source))
            .map_err(|e| overrides_fault(image, e))?;
        if textures_of(&scene) != recipe.textures {
            return Err(Error::Image {
                path: image.to_owned(),
                message: "its recipe's texture files are not those its scene reads".to_owned(),
            });
        }
        Ok(scene)
    }
}
/// An error of the recipe's scene, where an override out of range is the recipe's fault,
/// named as such.
fn overrides_fault(image: &Path, e: Error) -> Error {
    match e {
        Error::Setting { field, message } => Error::Image {
            path: image.to_owned(),
            message: format!("its recipe's override `{field}` is refused: {message}"),
        },
        e => e,
    }
}

/// The texture files of `scene`, as a recipe records them.
fn textures_of(scene: &Scene) -> Vec<RecipeTexture> {
    scene
        .texture_files
        .iter()
        .map(|t| RecipeTexture {
            name: t.name.clone(),
            hash: format!("xxh3-128:{:032x}", t.hash),
        })
        .collect()
}

/// The settings in a few words.
pub fn describe(e: &Effective) -> String {
    let [x, y, w, h] = e.window;
    let crop = if (x, y, w, h) == (0, 0, e.width, e.height) {
        String::new()
    } else {
        format!(", crop {w}x{h} at ({x}, {y})")
    };
    format!(
        "{}x{}{crop}, {} spp, depth {}, seed {}, gamma {}",
        e.width, e.height, e.samples_per_pixel, e.max_depth, e.seed, e.gamma
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn recipe() -> Recipe {
        let text = "[image]\nwidth = 8\nheight = 4\nsamples_per_pixel = 2\nmax_depth = 3\n# § ²\n";
        let scene = Scene::parse(text, Path::new("s.toml"), &Overrides::default()).unwrap();
        let film = Film::new(8, 4, 2);
        let source = Source::new(Path::new("dir/s.toml"), text, Overrides::default());
        Recipe::new(&source, &scene, &film)
    }

    #[test]
    fn round_trips_through_ascii_json() {
        let r = recipe();
        let json = r.to_json();
        assert!(json.is_ascii(), "{json}");
        assert!(json.contains("\\u00a7"), "{json}");
        assert_eq!(Recipe::parse(&json, Path::new("x.png")).unwrap(), r);
        assert_eq!(r.scene.name, "s.toml");
    }

    #[test]
    fn newer_and_unknown_recipes_are_refused_by_name() {
        let json = recipe().to_json();
        let newer = json.replace(SCHEMA, "tessera-recipe/7");
        let e = Recipe::parse(&newer, Path::new("x.png"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("needs tessera-recipe/7") && e.contains("newer tessera"),
            "{e}"
        );
        let extra = json.replacen('{', "{\"lens\":1,", 1);
        let e = Recipe::parse(&extra, Path::new("x.png"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not know") && e.contains("lens"), "{e}");
        for bad in ["", "[]", "{\"schema\":\"other\"}", "{}", "1e999"] {
            assert!(Recipe::parse(bad, Path::new("x.png")).is_err(), "{bad}");
        }
        let deep = format!("{}{}", "[".repeat(200_000), "]".repeat(200_000));
        assert!(Recipe::parse(&deep, Path::new("x.png")).is_err());
        let hash = json.replace("xxh3-128:", "md5:");
        assert!(Recipe::parse(&hash, Path::new("x.png")).is_err());
    }

    /// `Recipe::scene` parsed the scene text twice, once to check the settings and again to
    /// build, and checked the built scene's settings again (a check that could no longer
    /// fail). It builds from the parse its settings were checked on; every refusal is still
    /// made: settings it does not give, an override out of range, a scene that does not
    /// build, texture files that are not its scene's.
    #[test]
    fn the_scene_is_built_from_one_parse_with_every_refusal() {
        let dirs = texture_dirs(None, Path::new("x.png"));
        let refused = |r: &Recipe| r.scene(Path::new("x.png"), &dirs).unwrap_err().to_string();
        let checked = recipe();
        let c = checked.checked(Path::new("x.png")).unwrap();
        assert_eq!(c.scene(&dirs).unwrap().settings.seed, checked.image.seed);

        let mut r = recipe();
        r.image.samples_per_pixel = 5;
        let e = refused(&r);
        assert!(e.contains("samples_per_pixel 5, the scene gives 2"), "{e}");

        let mut r = recipe();
        r.overrides.samples_per_pixel = Some(0);
        let e = refused(&r);
        assert!(e.contains("its recipe's override `spp` is refused"), "{e}");

        let mut r = recipe();
        r.scene
            .text
            .push_str("[[spheres]]\ncenter = [0, 0, -1]\nradius = 0.5\nmaterial = \"none\"\n");
        let e = refused(&r);
        assert!(e.contains("none"), "{e}");

        let mut r = recipe();
        r.textures.push(RecipeTexture {
            name: "a.png".to_owned(),
            hash: format!("xxh3-128:{:032x}", xxhash_rust::xxh3::xxh3_128(b"")),
        });
        let dir = std::env::temp_dir().join(format!("tessera-recipe-tex-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.png"), b"").unwrap();
        let e = r
            .scene(Path::new("x.png"), std::slice::from_ref(&dir))
            .unwrap_err()
            .to_string();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            e.contains("texture files are not those its scene reads"),
            "{e}"
        );
    }

    #[test]
    fn the_scene_must_give_the_recipes_settings() {
        let mut r = recipe();
        let dirs = texture_dirs(None, Path::new("x.png"));
        assert!(r.scene(Path::new("x.png"), &dirs).is_ok());
        r.image.seed = 9;
        let e = r.scene(Path::new("x.png"), &dirs).unwrap_err().to_string();
        assert!(e.contains("not what its scene"), "{e}");
    }
}
