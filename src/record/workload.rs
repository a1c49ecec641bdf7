//! What `tessera bench` renders: the standard workloads of `benches/workloads.toml` (scenes
//! compiled into the binary, fixed settings, the hash of the image each must produce), or a
//! custom scene; each identified by a hash of its scene text and settings.

use crate::scene::{Overrides, Scene, TextureSource};
use anyhow::{Context, Result, bail};
use serde::Deserialize;
use std::path::Path;

/// The standard workloads and their expected image hashes, as kept in the repository.
const WORKLOADS: &str = include_str!("../../benches/workloads.toml");

/// The scenes a standard workload may name, compiled in so `bench` runs from anywhere.
const SCENES: &[(&str, &str)] = &[
    ("cover.toml", include_str!("../../scenes/cover.toml")),
    (
        "img-2.20-cornell-standard.toml",
        include_str!("../../scenes/img-2.20-cornell-standard.toml"),
    ),
    (
        "img-2.22-book2-final.toml",
        include_str!("../../scenes/img-2.22-book2-final.toml"),
    ),
];

/// The image textures those scenes read, compiled in with them.
const TEXTURES: &[(&str, &[u8])] = &[("earthmap.jpg", include_bytes!("../../scenes/earthmap.jpg"))];

/// One standard workload as `benches/workloads.toml` lists it.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Standard {
    pub name: String,
    pub about: String,
    pub scene: String,
    pub width: u32,
    pub spp: u32,
    /// `xxh3-128:` and the hex of `Film::content_hash` of the image it must produce.
    pub image: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    workload: Vec<Standard>,
}

/// The standard workloads, in the file's order (the first is the default).
pub fn standard() -> Vec<Standard> {
    // Checked by the tests: the file compiled in is always valid.
    toml::from_str::<File>(WORKLOADS).map_or_else(|_| Vec::new(), |f| f.workload)
}

/// The standard workload `name`, or an error listing them all.
pub fn standard_named(name: &str) -> Result<Standard> {
    let all = standard();
    let Some(w) = all.iter().find(|w| w.name == name) else {
        let names: Vec<_> = all.iter().map(|w| w.name.as_str()).collect();
        bail!(
            "unknown workload `{name}` (the workloads are: {})",
            names.join(", ")
        );
    };
    Ok(w.clone())
}

/// The text of the compiled-in scene file `name`.
fn compiled_scene(name: &str) -> Option<&'static str> {
    SCENES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, text)| text)
}

/// A workload ready to render.
pub struct Workload {
    /// The standard workload's name, or `custom`.
    pub name: String,
    /// The scene file it renders (for a standard one, as named in `scenes/`).
    pub scene_name: String,
    pub scene: Scene,
    /// The hash of the scene text and the settings: equal ids, equal work.
    pub id: String,
    /// The image hash it must produce, for a standard workload.
    pub expected: Option<String>,
}

/// `xxh3-128:` and 32 hex digits.
pub fn hash_text(hash: u128) -> String {
    format!("xxh3-128:{hash:032x}")
}

/// The id of rendering `text` at the loaded scene's settings.
fn workload_id(text: &str, scene: &Scene) -> String {
    let s = &scene.settings;
    let settings = format!(
        "width={} height={} spp={} window={:?}",
        s.width, s.height, s.samples_per_pixel, s.window
    );
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    for part in ["tessera-workload-1", text, &settings] {
        hasher.update(&(part.len() as u64).to_le_bytes());
        hasher.update(part.as_bytes());
    }
    hash_text(hasher.digest128())
}

impl Workload {
    /// The standard workload `name`.
    pub fn named(name: &str) -> Result<Self> {
        Self::from_standard(&standard_named(name)?)
    }

    pub fn from_standard(w: &Standard) -> Result<Self> {
        let Some(text) = compiled_scene(&w.scene) else {
            bail!(
                "workload `{}` names scene {}, which is not compiled in",
                w.name,
                w.scene
            );
        };
        let overrides = Overrides {
            width: Some(w.width),
            samples_per_pixel: Some(w.spp),
            ..Overrides::default()
        };
        let path = Path::new("scenes").join(&w.scene);
        let scene = Scene::parse_with(text, &path, &overrides, &TextureSource::Embedded(TEXTURES))?;
        Ok(Self {
            name: w.name.clone(),
            scene_name: w.scene.clone(),
            id: workload_id(text, &scene),
            scene,
            expected: Some(w.image.clone()),
        })
    }

    /// A scene file with the given overrides. When it is a standard workload's very scene
    /// and settings (the same id), it is that workload, and validated.
    pub fn custom(path: &Path, overrides: &Overrides) -> Result<Self> {
        // As `render` reads it: a regular file, within the size a scene file may have.
        let text = Scene::read_text(path)?;
        let scene = Scene::parse(&text, path, overrides)?;
        let id = workload_id(&text, &scene);
        // The id hashes the scene's text, so only a workload of this very text can match:
        // no other standard scene is built.
        for w in standard() {
            if compiled_scene(&w.scene) == Some(text.as_str())
                && let Ok(known) = Self::from_standard(&w)
                && known.id == id
            {
                return Ok(known);
            }
        }
        Ok(Self {
            name: "custom".into(),
            scene_name: path.display().to_string(),
            scene,
            id,
            expected: None,
        })
    }
}

/// `benches/workloads.toml` with each workload's image hash replaced by `hash(workload)`, for
/// regenerating the file after a deliberate change of the image.
pub fn with_new_hashes(hash: &mut dyn FnMut(&Standard) -> Result<String>) -> Result<String> {
    let all = standard();
    let mut text = String::new();
    let mut name = None;
    for line in WORKLOADS.lines() {
        if let Some(v) = line.strip_prefix("name = ") {
            name = Some(v.trim_matches('"').to_owned());
        }
        if line.starts_with("image = ") {
            let w = all
                .iter()
                .find(|w| Some(&w.name) == name.as_ref())
                .context("benches/workloads.toml: `image` before `name`")?;
            text.push_str(&format!("image = \"{}\"\n", hash(w)?));
        } else {
            text.push_str(line);
            text.push('\n');
        }
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workloads_file_compiled_in_is_whole() {
        let all = standard();
        let names: Vec<_> = all.iter().map(|w| w.name.as_str()).collect();
        assert_eq!(names, ["quick", "cover", "cornell", "next-week"]);
        for w in &all {
            let loaded = Workload::from_standard(w).unwrap();
            assert!(loaded.id.starts_with("xxh3-128:") && loaded.id.len() == 41);
            assert!(w.image.starts_with("xxh3-128:"), "{}", w.image);
        }
        // The file rewritten with its own hashes is itself.
        let same = with_new_hashes(&mut |w| Ok(w.image.clone())).unwrap();
        assert_eq!(same, include_str!("../../benches/workloads.toml"));
    }
}
