//! `tessera info` and `tessera reproduce`: the recipe an image carries, printed, and the image
//! rendered again from it alone and compared bit for bit; and the recipe a merge writes.

use super::args::ReproduceArgs;
use super::settings::render_options;
use super::{note, progress_bar};
use anyhow::{Result, bail};
use std::path::Path;
use std::time::Instant;
use tessera::compare::{self, RgbImage};
use tessera::film::Film;
use tessera::image_file::{self, ImageHeader, Pixels};
use tessera::partial::RenderId;
use tessera::recipe::{self, Recipe, Source, describe};
use tessera::render;
use tessera::text::{terminal_safe, terminal_safe_lines};

/// The recipe of the image at `path`, read and checked, with the image's header.
fn recipe_of(path: &Path) -> Result<(ImageHeader, Recipe)> {
    let header = image_file::read_header(path)?;
    let Some(text) = &header.recipe else {
        bail!(
            "{}: no recipe (the image was written with --no-provenance, by another program, \
             or its metadata was stripped)",
            path.display()
        );
    };
    let recipe = Recipe::parse(text, path)?;
    Ok((header, recipe))
}

/// `tessera info IMAGE`: the recipe, readably, or as JSON.
pub fn info(path: &Path, json: bool) -> Result<()> {
    let (header, recipe) = recipe_of(path)?;
    if json {
        println!("{}", recipe.to_json());
        return Ok(());
    }
    let o = &recipe.overrides;
    let flags: Vec<String> = [
        o.width.map(|w| format!("--width {w}")),
        o.samples_per_pixel.map(|s| format!("--spp {s}")),
        o.max_depth.map(|d| format!("--depth {d}")),
        o.seed.map(|s| format!("--seed {s}")),
    ]
    .into_iter()
    .flatten()
    .collect();
    let text = &recipe.scene.text;
    println!(
        "{}: {} {}x{}, with a recipe ({})",
        path.display(),
        format!("{:?}", header.format).to_uppercase(),
        header.width,
        header.height,
        recipe.schema
    );
    println!(
        "  made by    tessera {}, commit {}",
        terminal_safe(&recipe.tessera.version, 40),
        terminal_safe(&recipe.tessera.commit, 64)
    );
    println!(
        "  scene      {} ({} bytes, {} lines)",
        terminal_safe(&recipe.scene.name, 80),
        text.len(),
        text.lines().count()
    );
    println!("  settings   {}", describe(&recipe.image));
    println!(
        "  overrides  {}",
        if flags.is_empty() {
            "none (the scene file's own settings)".to_owned()
        } else {
            flags.join(" ")
        }
    );
    println!("  sums       {}", terminal_safe(&recipe.sums, 64));
    println!("  check      tessera reproduce {}", path.display());
    println!("--- {} ---", terminal_safe(&recipe.scene.name, 80));
    print!("{}", terminal_safe_lines(text));
    if !text.ends_with('\n') {
        println!();
    }
    Ok(())
}

/// `tessera reproduce IMAGE`: exit 0 when identical; differences print and exit 1.
pub fn run(args: ReproduceArgs) -> Result<()> {
    let image = &args.image;
    let (header, recipe) = recipe_of(image)?;
    if let Some(out) = &args.extract_scene {
        tessera::atomic_file::write_atomically_with(out, &mut |w| {
            w.write_all(recipe.scene.text.as_bytes())
        })?;
        note(format_args!(
            "{}: the scene of {}'s recipe ({} bytes)",
            out.display(),
            image.display(),
            recipe.scene.text.len()
        ));
        return Ok(());
    }
    let options = render_options(args.threads, render::DEFAULT_TILE, args.simd.path()?)?;
    let scene = recipe.scene(image)?;
    let window = recipe.window();
    if (header.width, header.height) != (window.width, window.height) {
        println!(
            "differs: {} is {}x{}, its recipe makes {}x{}",
            image.display(),
            header.width,
            header.height,
            window.width,
            window.height
        );
        std::process::exit(1);
    }
    let s = &scene.settings;
    let total = u64::from(window.width) * u64::from(window.height) * u64::from(s.samples_per_pixel);
    let bar = progress_bar(total, args.quiet);
    let start = Instant::now();
    let (film, stats) = render::render(&scene, &options, &|n| bar.inc(n))?;
    bar.finish_and_clear();
    if let Some(out) = &args.output {
        let again = Recipe::new(&recipe.source(), &scene, &film);
        film.save(out, s.gamma, Some(&again))?;
    }
    let rendered = recipe::sums_hash(&film);
    let pixels = image_file::read_pixels(image, &header)?;
    let verdict = compare_pixels(&film, s.gamma, &pixels);
    let how = format!(
        "{} in {:.1} s on {} threads, SIMD path {}",
        describe(&recipe.image),
        start.elapsed().as_secs_f64(),
        stats.threads,
        options.simd.name()
    );
    match (rendered == recipe.sums, verdict) {
        (true, Ok(())) => {
            println!(
                "identical: {} is bit for bit what its recipe makes ({rendered}; {how})",
                image.display()
            );
            Ok(())
        }
        (same_sums, verdict) => {
            println!(
                "differs: {} is not what its recipe makes ({how})",
                image.display()
            );
            if !same_sums {
                println!(
                    "  sums: the recipe says {}, the render gives {rendered}",
                    terminal_safe(&recipe.sums, 64)
                );
            }
            match verdict {
                Ok(()) => println!("  pixels: the same as the render's"),
                Err(why) => println!("  pixels: {why}"),
            }
            std::process::exit(1);
        }
    }
}

/// Whether `pixels` are exactly what `film` writes: where and how much they differ if not.
fn compare_pixels(film: &Film, gamma: f32, pixels: &Pixels) -> Result<(), String> {
    let (w, h) = (film.width, film.height);
    let expected = film.to_rgb8(gamma);
    // Both sides as 8-bit values for `compare`'s figures; equality is checked exactly.
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
                .map(|&c| tessera::tonemap::encode_8bit(c, gamma))
                .collect();
            (wrong.0, wrong.1, RgbImage::from_rgb8(w, h, &shown))
        }
    };
    let Some((x, y)) = first.map(|i| (i as u32 % w, i as u32 / w)) else {
        return Ok(());
    };
    let figures = compare::difference(&RgbImage::from_rgb8(w, h, &expected), &actual)
        .map(|d| {
            format!(
                "RMSE {:.6}, PSNR {:.2} dB, mean abs error {:.6}",
                d.rmse, d.psnr_db, d.mean_abs
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

/// The recipe of a merged `film` of `render`'s parts, which carry `source`, when `source`
/// describes them: the scene it gives has their fingerprint, window and sample count.
/// `part` names the source in errors.
pub fn merged_recipe(
    source: &Source,
    render: &RenderId,
    film: &Film,
    part: &Path,
) -> Option<Recipe> {
    let scene = source.parse(part).ok()?;
    let s = &scene.settings;
    (format!("{:016x}", scene.fingerprint()) == render.fingerprint
        && s.window == render.window
        && s.samples_per_pixel == render.target)
        .then(|| Recipe::new(source, &scene, film))
}
