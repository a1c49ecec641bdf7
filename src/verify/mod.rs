//! Checking an image against its recipe, for `tessera reproduce` and the Python package: the
//! recipe read from an image a stranger may have made, the work it asks for judged before
//! anything is rendered, and the verdict on a render of it, bit for bit: the exact sums, the
//! pixels as stored, the size, and anything else in the file that changes how it is shown.

use crate::error::{Error, Result};
use crate::film::Film;
use crate::image_diff::{self, RgbImage};
use crate::image_file::{self, ImageHeader, Pixels};
use crate::recipe::{self, Recipe};
use crate::text::{path_safe, significant, terminal_safe};
use std::path::Path;

mod cost;
pub use cost::{
    BUDGET_VARIABLE, COVER_RAYS, COVER_SAMPLES, Judged, Measured, NotStarted, UNASKED_COVERS,
    UNASKED_PIXELS, Work, render_judged,
};

/// The recipe of the image at `path`, read and checked, with the image's header.
pub fn read_recipe(path: &Path) -> Result<(ImageHeader, Recipe)> {
    let header = image_file::read_header(path)?;
    let Some(text) = &header.recipe else {
        return Err(Error::Image {
            path: path.to_owned(),
            message: "no recipe (the image was written with --no-provenance, of a scene \
                      too large for a recipe, by another program, or its metadata was \
                      stripped)"
                .into(),
        });
    };
    let recipe = Recipe::parse(text, path)?;
    Ok((header, recipe))
}

/// How an image differs from what its recipe makes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Differs {
    /// What differs, in a line.
    pub summary: String,
    /// Each difference.
    pub details: Vec<String>,
}

/// What is known of an image against its recipe before anything is rendered.
pub enum Unrendered<'a> {
    /// It is not what its recipe makes, whatever a render gives: `differs`.
    Differs(Differs),
    /// Its recipe checked and its scene parsed: a render decides.
    Render(Box<recipe::Checked<'a>>),
}

/// The checks of an image against its recipe that need no render, in the one order that
/// `tessera info`, `tessera reproduce` and the Python package's `reproduce` take, so that
/// none says `differs` where another refuses: the recipe's scene parsed and its settings
/// checked against the recipe's (an error where they are not its scene's: the recipe is not
/// to be trusted, whatever the image), then the image against the recipe (another size, or
/// what changes how it is shown: `differs`). Its textures are looked for only to render
/// (`recipe::Checked::scene`).
pub fn unrendered<'a>(
    image: &Path,
    header: &ImageHeader,
    recipe: &'a Recipe,
) -> Result<Unrendered<'a>> {
    let checked = recipe.checked(image)?;
    Ok(match differs_unrendered(image, header, recipe) {
        Some(differs) => Unrendered::Differs(differs),
        None => Unrendered::Render(Box::new(checked)),
    })
}

/// How an image differs from what its recipe makes, seen before anything is rendered:
/// another size, or what tessera does not write and what changes how a viewer shows it.
/// None, and the render decides.
fn differs_unrendered(image: &Path, header: &ImageHeader, recipe: &Recipe) -> Option<Differs> {
    let window = recipe.window();
    if (header.width, header.height) != (window.width, window.height) {
        return Some(Differs {
            summary: format!(
                "{} is {}x{}, its recipe makes {}x{}",
                path_safe(image),
                header.width,
                header.height,
                window.width,
                window.height
            ),
            details: Vec::new(),
        });
    }
    (!header.display_changes.is_empty()).then(|| Differs {
        summary: format!(
            "{} holds what tessera does not write and what changes how it is shown",
            path_safe(image)
        ),
        details: header.display_changes.clone(),
    })
}

/// How the image differs from `film`, the render of its recipe (tone-mapped with `gamma`):
/// the sums the recipe claims, then the pixels as stored, each a line of `details`. None
/// when it is bit for bit what the recipe makes.
pub fn differs_rendered(
    image: &Path,
    header: &ImageHeader,
    recipe: &Recipe,
    film: &Film,
    gamma: f32,
) -> Result<Option<Differs>> {
    let rendered = recipe::sums_hash(film);
    let pixels = image_file::read_pixels(image, header)?;
    let mut lines = Vec::new();
    let same_sums = rendered == recipe.sums;
    if !same_sums {
        lines.push(format!(
            "sums: the recipe says {}, the render gives {rendered}",
            terminal_safe(&recipe.sums, 64)
        ));
    }
    match check_pixels(film, gamma, &pixels) {
        Ok(()) if !same_sums => lines.push("pixels: the same as the render's".into()),
        Ok(()) => {}
        Err(why) => lines.push(format!("pixels: {why}")),
    }
    Ok((!lines.is_empty()).then(|| Differs {
        summary: format!("{} is not what its recipe makes", path_safe(image)),
        details: lines,
    }))
}

/// Whether `pixels` are exactly what `film` writes: where and how much they differ if not.
fn check_pixels(film: &Film, gamma: f32, pixels: &Pixels) -> Result<(), String> {
    let (w, h) = (film.width, film.height);
    let expected = film.to_rgb8(gamma);
    // Both sides as 8-bit values for the difference's figures; equality is checked exactly.
    let (differing, first, actual) = match pixels {
        Pixels::Other(layout) => {
            return Err(format!(
                "stored as {layout}, not as tessera writes them (re-saved by another program)"
            ));
        }
        Pixels::Rgb8(bytes) => {
            same_count(bytes.len(), expected.len())?;
            let wrong = pixel_mismatches(bytes.len(), |i| bytes[i] != expected[i]);
            (wrong.0, wrong.1, RgbImage::from_rgb8(w, h, bytes))
        }
        Pixels::Linear(values) => {
            let linear = film.linear();
            same_count(values.len(), linear.len())?;
            let wrong =
                pixel_mismatches(values.len(), |i| values[i].to_bits() != linear[i].to_bits());
            let shown: Vec<u8> = values
                .iter()
                .map(|&c| crate::tonemap::encode_8bit(c, gamma))
                .collect();
            (wrong.0, wrong.1, RgbImage::from_rgb8(w, h, &shown))
        }
    };
    let Some((x, y)) = first.map(|i| (i as u32 % w, i as u32 / w)) else {
        return Ok(());
    };
    let figures = image_diff::difference(&RgbImage::from_rgb8(w, h, &expected), &actual)
        .map(|d| {
            format!(
                "RMSE {}, PSNR {:.2} dB, mean abs error {}",
                significant(d.rmse, 4),
                d.psnr_db,
                significant(d.mean_abs, 4)
            )
        })
        .unwrap_or_default();
    Err(format!(
        "{differing} of {} pixels differ, the first at ({x}, {y}); {figures}",
        u64::from(w) * u64::from(h)
    ))
}

/// Refuses pixels of another count than the render's (the size was checked: only a
/// decoder's surprise could make them so).
fn same_count(values: usize, expected: usize) -> Result<(), String> {
    if values == expected {
        Ok(())
    } else {
        Err(format!(
            "{values} values decoded, the render has {expected}"
        ))
    }
}

/// The number of pixels among `len` values (3 each) whose values differ, and the first
/// one's index.
fn pixel_mismatches(len: usize, differs: impl Fn(usize) -> bool) -> (u64, Option<usize>) {
    let mut count = 0;
    let mut first = None;
    for p in 0..len / 3 {
        if (3 * p..3 * p + 3).any(&differs) {
            count += 1;
            first.get_or_insert(p);
        }
    }
    (count, first)
}
