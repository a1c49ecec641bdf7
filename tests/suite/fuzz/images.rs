//! Mutated images with recipes: their metadata read as a stranger's, refused by name and
//! never inflated, believed or allocated beyond its limits.

use super::harness::*;
use crate::common::GOOD;
use std::path::Path;
use tessera::film::Film;
use tessera::image_file::{Format, png_header_of};
use tessera::recipe::{KEY, Recipe, Source};
use tessera::scene::{Overrides, Scene};

/// A PNG of a blank 16x9 image with `recipe` in an iTXt chunk (compressed or not), CRC and
/// all correct, as another program might write it.
fn png_with(recipe: &str, compressed: bool) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 16, 9);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    let mut chunk = png::text_metadata::ITXtChunk::new(KEY, recipe);
    chunk.compressed = compressed;
    writer.write_text_chunk(&chunk).unwrap();
    writer.write_image_data(&[0; 16 * 9 * 3]).unwrap();
    writer.finish().unwrap();
    bytes
}

/// The recipe of a small render, and variants a reader must take apart (a newer schema,
/// nesting, a bomb, a huge scene).
fn seed_recipes() -> Vec<String> {
    let scene = Scene::parse(GOOD, Path::new("good.toml"), &Overrides::default()).unwrap();
    let film = Film::new(scene.settings.width, scene.settings.height, 1);
    let source = Source::new(Path::new("good.toml"), GOOD, Overrides::default());
    let json = Recipe::new(&source, &scene, &film).to_json();
    vec![
        json.replace("tessera-recipe/1", "tessera-recipe/9"),
        format!("{}{}", "[".repeat(5000), "]".repeat(5000)),
        format!("{json}{}", " ".repeat(4 << 20)),
        json.replace("width = 16", "width = 1000000000"),
        json,
    ]
}

/// The PNG tessera writes of that render, recipe and all.
fn written_png() -> Vec<u8> {
    let scene = Scene::parse(GOOD, Path::new("good.toml"), &Overrides::default()).unwrap();
    let film = Film::new(scene.settings.width, scene.settings.height, 1);
    let source = Source::new(Path::new("good.toml"), GOOD, Overrides::default());
    let mut written = Vec::new();
    film.write(
        Format::Png,
        2.0,
        Some(&Recipe::new(&source, &scene, &film)),
        &mut written,
    )
    .unwrap();
    written
}

/// One random change to a recipe's text: a byte, a cut, a value of another kind.
fn mutate_text(g: &mut Gen, text: &mut String) {
    let mut b = std::mem::take(text).into_bytes();
    match g.below(3) {
        0 if !b.is_empty() => {
            let i = g.below(b.len());
            b[i] = g.pick(b"0123456789-.e\"{}[],: azAZ\xff");
        }
        1 => b.truncate(g.below(b.len() + 1)),
        _ => {
            let at = g.below(b.len() + 1);
            let v = g.pick(&[
                "1e999",
                "-1",
                "4294967296",
                "null",
                "\"\\u0000\"",
                "[]",
                "{}",
                "\"tessera-recipe/2\"",
            ]);
            b.splice(at..at, v.bytes());
        }
    }
    *text = String::from_utf8_lossy(&b).into_owned();
}

/// One random change to a PNG's bytes: a bit, a cut, a length field, a run of junk.
fn mutate(g: &mut Gen, b: &mut Vec<u8>) {
    match g.below(4) {
        0 if !b.is_empty() => {
            let i = g.below(b.len());
            b[i] ^= 1 << g.below(8);
        }
        1 => b.truncate(g.below(b.len() + 1)),
        2 if b.len() > 40 => {
            // A chunk's length word, near the front where the recipe's chunk is.
            let at = 8 + g.below(b.len().min(84) - 12);
            let claims = [0u32, 1, 13, 1 << 20, (1 << 31) - 1, u32::MAX];
            let claim = g.pick(&claims);
            b.splice(at..at + 4, claim.to_be_bytes());
        }
        _ => {
            let at = g.below(b.len() + 1);
            let junk: Vec<u8> = (0..g.below(32)).map(|_| g.below(256) as u8).collect();
            b.splice(at..at, junk);
        }
    }
}

/// Reading the header, the recipe and the scene it describes never panics nor allocates
/// beyond the ceiling; every refusal is a message.
fn check(bytes: &[u8]) -> Result<Outcome, String> {
    let Ok(header) = png_header_of(bytes) else {
        return Ok(Outcome::Refused);
    };
    let Some(text) = header.recipe else {
        return Ok(Outcome::Refused);
    };
    if text.len() > tessera::recipe::MAX_BYTES {
        return Err(format!("accepted a recipe of {} bytes", text.len()));
    }
    let Ok(recipe) = Recipe::parse(&text, Path::new("fuzz.png")) else {
        return Ok(Outcome::Refused);
    };
    match recipe.scene(Path::new("fuzz.png"), &[]) {
        Ok(_) => Ok(Outcome::Accepted),
        Err(e) if e.to_string().starts_with("fuzz.png") => Ok(Outcome::Refused),
        Err(e) => Err(format!("a refusal that does not name the image: {e}")),
    }
}

#[test]
fn mutated_images_with_recipes_are_read_within_limits() {
    let recipes = seed_recipes();
    let written = written_png();
    run_family(
        "image",
        4_000,
        // A recipe is at most 1 MiB; its scene is parsed, not rendered.
        64 << 20,
        |g| {
            // Half the cases change the recipe and write a well-formed PNG of it, so the
            // checks behind the chunk's CRC are reached; half change the file's bytes.
            let bytes = if g.chance(50) {
                let mut text = recipes[g.below(recipes.len())].clone();
                for _ in 0..1 + g.below(3) {
                    mutate_text(g, &mut text);
                }
                png_with(&text, g.chance(50))
            } else {
                let mut bytes = written.clone();
                for _ in 0..1 + g.below(3) {
                    mutate(g, &mut bytes);
                }
                bytes
            };
            let shown = format!("{} bytes", bytes.len());
            (bytes, shown)
        },
        |bytes| check(bytes),
    );
}
