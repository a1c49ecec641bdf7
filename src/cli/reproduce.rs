//! `tessera info` and `tessera reproduce`: the recipe an image carries, printed, and the image
//! rendered again from it alone and checked bit for bit against the image.

use super::flags::{self, SimdArg};
use super::output::{self, count, note, out, progress_bar, significant};
use super::writable::check_output;
use anyhow::{Result, bail};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;
use tessera::film::Film;
use tessera::image_diff::{self, RgbImage};
use tessera::image_file::{self, ImageHeader, Pixels};
use tessera::recipe::{self, Recipe, describe};
use tessera::render::{self, RenderOptions};
use tessera::text::{terminal_safe, terminal_safe_lines};

/// `tessera info` as typed.
#[derive(clap::Args)]
pub struct InfoArgs {
    /// A PNG or EXR image tessera wrote.
    image: PathBuf,
    /// The recipe as tessera wrote it (JSON).
    #[arg(long)]
    json: bool,
}

/// `tessera reproduce` as typed.
#[derive(clap::Args)]
pub struct Args {
    /// A PNG or EXR image tessera wrote.
    image: PathBuf,
    /// Also write the re-rendered image here (with its recipe).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write the recipe's scene file here and stop.
    #[arg(long, value_name = "FILE")]
    extract_scene: Option<PathBuf>,
    /// Worker threads (default: one per core); the image does not change.
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = flags::threads)]
    threads: Option<usize>,
    #[command(flatten)]
    simd: SimdArg,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Render however much work the recipe asks for; without it, a recipe asking for more
    /// than four book covers' worth is refused before anything is rendered.
    #[arg(long)]
    any_cost: bool,
    /// Look for the scene's texture files here first (then next to the image, then in
    /// `scenes/`).
    #[arg(long, value_name = "DIR")]
    textures: Option<PathBuf>,
}

/// The book cover's work: 1200x800 pixels at 500 samples per pixel, up to 50 bounces.
const COVER_RAYS: f64 = 1200.0 * 800.0 * 500.0 * 50.0;
/// The most work `reproduce` does unasked, in book covers (a few minutes on two cores).
const UNASKED_COVERS: f64 = 4.0;

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
pub fn info(args: InfoArgs) -> Result<ExitCode> {
    let path = &args.image;
    let (header, recipe) = recipe_of(path)?;
    if args.json {
        out(&format!("{}\n", recipe.to_json()))?;
        return Ok(ExitCode::SUCCESS);
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
    let mut t = format!(
        "{}: {} {}x{}, with a recipe ({})\n",
        path.display(),
        format!("{:?}", header.format).to_uppercase(),
        header.width,
        header.height,
        recipe.schema
    );
    t.push_str(&format!(
        "  made by    tessera {}, commit {}\n",
        terminal_safe(&recipe.tessera.version, 40),
        terminal_safe(&recipe.tessera.commit, 64)
    ));
    t.push_str(&format!(
        "  scene      {} ({} bytes, {} lines)\n",
        terminal_safe(&recipe.scene.name, 80),
        text.len(),
        text.lines().count()
    ));
    t.push_str(&format!("  settings   {}\n", describe(&recipe.image)));
    t.push_str(&format!(
        "  overrides  {}\n",
        if flags.is_empty() {
            "none (the scene file's own settings)".to_owned()
        } else {
            flags.join(" ")
        }
    ));
    t.push_str(&format!(
        "  sums       {}\n",
        terminal_safe(&recipe.sums, 64)
    ));
    for texture in &recipe.textures {
        t.push_str(&format!(
            "  texture    {} ({})\n",
            terminal_safe(&texture.name, 80),
            terminal_safe(&texture.hash, 64)
        ));
    }
    t.push_str(&format!(
        "  check      tessera reproduce {}\n",
        path.display()
    ));
    t.push_str(&format!(
        "--- {} ---\n",
        terminal_safe(&recipe.scene.name, 80)
    ));
    t.push_str(&terminal_safe_lines(text));
    if !text.ends_with('\n') {
        t.push('\n');
    }
    out(&t)?;
    Ok(ExitCode::SUCCESS)
}

/// `tessera reproduce IMAGE`: exit 0 when identical; differences print and exit 1.
pub fn run(args: Args) -> Result<ExitCode> {
    let image = &args.image;
    let (header, recipe) = recipe_of(image)?;
    if let Some(file) = &args.extract_scene {
        check_output(file)?;
        tessera::atomic_file::write_atomically_with(file, &mut |w| {
            w.write_all(recipe.scene.text.as_bytes())
        })?;
        note(format_args!(
            "{}: the scene of {}'s recipe ({} bytes)",
            file.display(),
            image.display(),
            recipe.scene.text.len()
        ));
        return Ok(ExitCode::SUCCESS);
    }
    if let Some(file) = &args.output {
        check_output(file)?;
    }
    let options = RenderOptions {
        threads: args.threads,
        tile: render::DEFAULT_TILE,
        simd: args.simd.path()?,
    };
    // The most rays the recipe can ask for, every path its longest, judged from what it
    // claims before its scene is even parsed.
    let claimed = &recipe.image;
    let samples = u64::from(claimed.window[2])
        * u64::from(claimed.window[3])
        * u64::from(claimed.samples_per_pixel);
    let covers = samples as f64 * f64::from(claimed.max_depth) / COVER_RAYS;
    let work = format!(
        "{}x{} pixels at {} per pixel, paths of up to {}: at most {} book covers' work",
        claimed.window[2],
        claimed.window[3],
        count(claimed.samples_per_pixel, "sample"),
        count(claimed.max_depth, "bounce"),
        significant(covers, 2)
    );
    if covers > UNASKED_COVERS && !args.any_cost {
        bail!(
            "{}: its recipe asks for {work}, more than the {UNASKED_COVERS} that reproduce \
             renders unasked; pass --any-cost to render it anyway",
            image.display()
        );
    }
    let dirs = recipe::texture_dirs(args.textures.as_deref(), image);
    let scene = recipe.scene(image, &dirs)?;
    let window = recipe.window();
    let differs = ExitCode::from(output::NEGATIVE);
    if (header.width, header.height) != (window.width, window.height) {
        out(&format!(
            "differs: {} is {}x{}, its recipe makes {}x{}\n",
            image.display(),
            header.width,
            header.height,
            window.width,
            window.height
        ))?;
        return Ok(differs);
    }
    if !header.display_changes.is_empty() {
        let mut t = format!(
            "differs: {} holds what tessera does not write and what changes how it is shown:\n",
            image.display()
        );
        for change in &header.display_changes {
            t.push_str(&format!("  {change}\n"));
        }
        out(&t)?;
        return Ok(differs);
    }
    let s = &scene.settings;
    let total = u64::from(window.width) * u64::from(window.height) * u64::from(s.samples_per_pixel);
    if !args.quiet {
        note(format_args!("reproduce: rendering {work}"));
    }
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
    let verdict = check_pixels(&film, s.gamma, &pixels);
    let how = format!(
        "{} in {:.1} s on {}, SIMD path {}",
        describe(&recipe.image),
        start.elapsed().as_secs_f64(),
        count(stats.threads as u64, "thread"),
        options.simd.name()
    );
    match (rendered == recipe.sums, verdict) {
        (true, Ok(())) => {
            out(&format!(
                "identical: {} is bit for bit what its recipe makes ({rendered}; {how})\n",
                image.display()
            ))?;
            Ok(ExitCode::SUCCESS)
        }
        (same_sums, verdict) => {
            let mut t = format!(
                "differs: {} is not what its recipe makes ({how})\n",
                image.display()
            );
            if !same_sums {
                t.push_str(&format!(
                    "  sums: the recipe says {}, the render gives {rendered}\n",
                    terminal_safe(&recipe.sums, 64)
                ));
            }
            match verdict {
                Ok(()) => t.push_str("  pixels: the same as the render's\n"),
                Err(why) => t.push_str(&format!("  pixels: {why}\n")),
            }
            out(&t)?;
            Ok(differs)
        }
    }
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
                .map(|&c| tessera::tonemap::encode_8bit(c, gamma))
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
