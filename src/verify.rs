//! Checking an image against its recipe, for `tessera reproduce` and the Python package: the
//! recipe read from an image a stranger may have made, the work it asks for judged before
//! anything is rendered, and the verdict on a render of it, bit for bit: the exact sums, the
//! pixels as stored, the size, and anything else in the file that changes how it is shown.

use crate::error::{Error, Result};
use crate::film::Film;
use crate::image_diff::{self, RgbImage};
use crate::image_file::{self, ImageHeader, Pixels};
use crate::job::SampleRange;
use crate::math::PixelRect;
use crate::recipe::{self, Effective, Recipe};
use crate::render::render_tile;
use crate::scene::Scene;
use crate::simd;
use crate::text::{count, significant, terminal_safe};
use std::path::Path;
use std::time::{Duration, Instant};

/// The book cover's work: 1200x800 pixels at 500 samples per pixel, up to 50 bounces.
pub const COVER_RAYS: f64 = 1200.0 * 800.0 * 500.0 * 50.0;
/// The most work a recipe gets rendered unasked, in book covers (a few minutes on two cores).
pub const UNASKED_COVERS: f64 = 4.0;
/// The book cover's samples: 1200x800 pixels at 500 per pixel.
pub const COVER_SAMPLES: f64 = 1200.0 * 800.0 * 500.0;
/// The most pixels a recipe gets rendered unasked, whatever its samples: 8192x4096, whose
/// film alone (three 64-bit sums a pixel) is 800 MB. A recipe may claim 2^28 pixels, a
/// 6.4 GB film, at one sample each: little work, but more memory than many machines have.
pub const UNASKED_PIXELS: u64 = 1 << 25;

/// The recipe of the image at `path`, read and checked, with the image's header.
pub fn read_recipe(path: &Path) -> Result<(ImageHeader, Recipe)> {
    let header = image_file::read_header(path)?;
    let Some(text) = &header.recipe else {
        return Err(Error::Image {
            path: path.to_owned(),
            message: "no recipe (the image was written with --no-provenance, by another \
                      program, or its metadata was stripped)"
                .into(),
        });
    };
    let recipe = Recipe::parse(text, path)?;
    Ok((header, recipe))
}

/// The most work a recipe can ask for, from what it claims before its scene is parsed: every
/// path its longest.
pub struct Work {
    pub claimed: Effective,
    /// In book covers' rays, every path its longest, each ray costing what one of the
    /// cover's does.
    pub covers: f64,
    /// The pixels it renders (its window's).
    pub pixels: u64,
    /// Once its scene is built and a few of its paths traced (`measured`): one path's cost
    /// as a multiple of one of the cover's, and the work in book covers that makes.
    pub measured: Option<(f64, f64)>,
}

impl Work {
    pub fn of(recipe: &Recipe) -> Self {
        let claimed = recipe.image;
        let pixels = u64::from(claimed.window[2]) * u64::from(claimed.window[3]);
        let samples = pixels * u64::from(claimed.samples_per_pixel);
        Work {
            claimed,
            covers: samples as f64 * f64::from(claimed.max_depth) / COVER_RAYS,
            pixels,
            measured: None,
        }
    }

    /// The work, its paths' cost measured on `scene` (the recipe's, built) against the book
    /// cover's scene `cover` (at any size): what the claim alone cannot tell, such as a ray
    /// that meets a million overlapping spheres.
    pub fn measured(mut self, scene: &Scene, cover: &Scene) -> Self {
        let cost = path_cost(scene, cover);
        let samples = self.pixels as f64 * f64::from(self.claimed.samples_per_pixel);
        self.measured = Some((cost, samples * cost / COVER_SAMPLES));
        self
    }

    /// Why the recipe of `image` is not rendered unasked, if it is more than that: the
    /// message, ending with `allow`, what renders it anyway (`--any-cost` on the command
    /// line).
    pub fn refusal(&self, image: &Path, allow: &str) -> Option<String> {
        let measured_beyond = self
            .measured
            .is_some_and(|(_, covers)| covers > UNASKED_COVERS);
        let beyond = if self.covers > UNASKED_COVERS || measured_beyond {
            format!("more than the {UNASKED_COVERS} book covers' work")
        } else if self.pixels > UNASKED_PIXELS {
            format!("more than the {UNASKED_PIXELS} pixels")
        } else {
            return None;
        };
        Some(format!(
            "{}: its recipe asks for {self}, {beyond} that reproduce renders unasked; pass \
             {allow} to render it anyway",
            image.display()
        ))
    }
}

impl std::fmt::Display for Work {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = &self.claimed;
        write!(
            f,
            "{}x{} pixels at {} per pixel, paths of up to {}: ",
            c.window[2],
            c.window[3],
            count(c.samples_per_pixel, "sample"),
            count(c.max_depth, "bounce"),
        )?;
        match self.measured {
            Some((cost, covers)) => write!(
                f,
                "about {} book covers' work (its paths, traced, cost {} times the cover's)",
                significant(covers, 2),
                significant(cost, 2)
            ),
            None => write!(
                f,
                "at most {} book covers' work",
                significant(self.covers, 2)
            ),
        }
    }
}

/// Paths traced for a measure of their cost: one sample at each pixel of a grid of small
/// tiles spread over the window (8x8 tiles of 4x4 pixels).
const PROBE_GRID: u32 = 8;
const PROBE_TILE: u32 = 4;
/// How long the paths of a scene are traced at most for the measure (at least one tile's).
const PROBE_TIME: Duration = Duration::from_millis(300);

/// What one path of `scene` costs as a multiple of one path of the book's cover, `cover`:
/// the same pattern of pixels traced in both, one sample each, on this machine's best SIMD
/// path. A measure in time, so only about right: the order of magnitude is what matters.
pub fn path_cost(scene: &Scene, cover: &Scene) -> f64 {
    // The cover twice: the first warms the caches and the clock.
    probe(cover, Duration::MAX);
    let per_cover_path = probe(cover, Duration::MAX);
    let per_path = probe(scene, PROBE_TIME);
    per_path / per_cover_path.max(1e-9)
}

/// The time one path of `scene` takes on the probe's pixels, in seconds, tracing for no
/// longer than about `limit`.
fn probe(scene: &Scene, limit: Duration) -> f64 {
    let window = scene.settings.window;
    let simd = simd::Path::best();
    // The k-th of PROBE_GRID places along a side, centred in its share of it.
    let place = |origin: u32, size: u32, k: u32| {
        let span = u64::from(size.saturating_sub(PROBE_TILE));
        origin + (span * u64::from(2 * k + 1) / u64::from(2 * PROBE_GRID)) as u32
    };
    let start = Instant::now();
    let mut paths = 0u64;
    'grid: for j in 0..PROBE_GRID {
        for i in 0..PROBE_GRID {
            let tile = PixelRect {
                x0: place(window.x0, window.width, i),
                y0: place(window.y0, window.height, j),
                width: PROBE_TILE.min(window.width),
                height: PROBE_TILE.min(window.height),
            };
            render_tile(scene, &tile, SampleRange { start: 0, end: 1 }, simd);
            paths += tile.area();
            if start.elapsed() > limit {
                break 'grid;
            }
        }
    }
    start.elapsed().as_secs_f64() / paths.max(1) as f64
}

/// How an image differs from what its recipe makes.
#[derive(Clone, Debug, PartialEq)]
pub struct Differs {
    /// What differs, in a line.
    pub summary: String,
    /// Each difference.
    pub details: Vec<String>,
}

/// How an image differs from what its recipe makes, seen before anything is rendered:
/// another size, or what tessera does not write and what changes how a viewer shows it.
/// None, and the render decides.
pub fn differs_unrendered(image: &Path, header: &ImageHeader, recipe: &Recipe) -> Option<Differs> {
    let window = recipe.window();
    if (header.width, header.height) != (window.width, window.height) {
        return Some(Differs {
            summary: format!(
                "{} is {}x{}, its recipe makes {}x{}",
                image.display(),
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
            image.display()
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
        summary: format!("{} is not what its recipe makes", image.display()),
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
