//! `tessera info` and `tessera reproduce`: the recipe an image carries, printed, and the image
//! rendered again from it alone and checked bit for bit against the image.

use super::flags::{self, SimdArg};
use super::output::{self, count, note, out, progress_bar};
use super::writable::{check_output, same_file};
use anyhow::{Result, bail};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use tessera::image_file::ImageHeader;
use tessera::recipe::{self, Recipe, describe};
use tessera::record::workload::Workload;
use tessera::render::{self, RenderOptions};
use tessera::text::{ascii_json, path_safe, terminal_safe, terminal_safe_lines};
use tessera::verify::{self, Differs, Unrendered};

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

/// The recipe of the image at `path`, read and checked, with the image's header.
fn recipe_of(path: &Path) -> Result<(ImageHeader, Recipe)> {
    Ok(verify::read_recipe(path)?)
}

/// `tessera info IMAGE`: the recipe, readably, or as JSON.
pub fn info(args: InfoArgs) -> Result<ExitCode> {
    let path = &args.image;
    let (header, recipe) = recipe_of(path)?;
    // What `reproduce` refuses before rendering, `info` does not print as true: a recipe
    // whose settings are not what its own scene gives (exit 2, as reproduce), whatever the
    // form. And where `reproduce` says `differs` without rendering (another size, what
    // changes how the image is shown), `info` says so too, from the same check. Its
    // textures are not looked for: the image may be shown where they are not.
    let differs = match verify::unrendered(path, &header, &recipe)? {
        Unrendered::Differs(differs) => Some(differs),
        Unrendered::Render(_) => None,
    };
    if args.json {
        // The recipe as tessera wrote it, its fields in order; where the image is not what
        // it makes, with a field `differs` (its summary and details), which no recipe has.
        #[derive(serde::Serialize)]
        struct Shown<'a> {
            #[serde(flatten)]
            recipe: &'a Recipe,
            #[serde(skip_serializing_if = "Option::is_none")]
            differs: Option<&'a Differs>,
        }
        let shown = Shown {
            recipe: &recipe,
            differs: differs.as_ref(),
        };
        let json = serde_json::to_string(&shown)?;
        out(&format!("{}\n", ascii_json(&json)))?;
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
        path_safe(path),
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
    match &differs {
        // What `reproduce` says of it without rendering.
        Some(d) => {
            t.push_str(&format!("  differs    {}\n", d.summary));
            for line in &d.details {
                t.push_str(&format!("             {line}\n"));
            }
        }
        None => t.push_str(&format!(
            "  check      tessera reproduce {}\n",
            path_safe(path)
        )),
    }
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
    let same = |a: &Path, b: &Path| matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b);
    let dirs = recipe::texture_dirs(args.textures.as_deref(), image);
    if let Some(file) = &args.extract_scene {
        if same(file, image) {
            bail!(
                "--extract-scene {} names the image being checked: write the scene to another \
                 file",
                file.display()
            );
        }
        refuse_texture("--extract-scene", file, &recipe, &dirs)?;
        check_output("--extract-scene", file)?;
        tessera::atomic_file::write_atomically_with(file, &mut |w| {
            w.write_all(recipe.scene.text.as_bytes())
        })?;
        note(format_args!(
            "{}: the scene of {}'s recipe ({} bytes)",
            path_safe(file),
            path_safe(image),
            recipe.scene.text.len()
        ));
        return Ok(ExitCode::SUCCESS);
    }
    if let Some(file) = &args.output {
        if same(file, image) {
            bail!(
                "-o {} names the image being checked: write the render to another file",
                file.display()
            );
        }
        refuse_texture("-o", file, &recipe, &dirs)?;
        check_output("-o", file)?;
    }
    let options = RenderOptions {
        threads: args.threads,
        tile: render::DEFAULT_TILE,
        simd: args.simd.path()?,
    };
    let work = verify::Work::of(&recipe);
    if let Some(refusal) = work.refusal(image, "--any-cost")
        && !args.any_cost
    {
        bail!("{refusal}");
    }
    let differs = ExitCode::from(output::NEGATIVE);
    // The recipe's scene and settings, then the image against the recipe, as `info` and the
    // Python package check them: one function, one order.
    let checked = match verify::unrendered(image, &header, &recipe)? {
        Unrendered::Differs(d) => {
            out(&differs_text(&d.summary, &d.details))?;
            return Ok(differs);
        }
        Unrendered::Render(checked) => checked,
    };
    let mut scene = checked.scene(&dirs)?;
    let window = recipe.window();
    let s = &scene.settings;
    let total = u64::from(window.width) * u64::from(window.height) * u64::from(s.samples_per_pixel);
    let stop = AtomicBool::new(false);
    let yardstick = Workload::named("quick")?;
    let judged = verify::render_judged(
        work,
        &mut scene,
        &yardstick.scene,
        image,
        "--any-cost",
        args.any_cost,
        options.threads,
        &stop,
        |work| {
            if !args.quiet {
                note(format_args!("reproduce: rendering {work}"));
            }
        },
        |scene| {
            let bar = progress_bar(total, args.quiet);
            let done = render::render_unless(scene, &options, &|n| bar.inc(n), &stop);
            bar.finish_and_clear();
            done
        },
    );
    let judged = match judged {
        Ok(judged) => judged,
        Err(verify::NotStarted::Refused(refusal)) => bail!("{refusal}"),
        Err(verify::NotStarted::Setting(e)) => return Err(e.into()),
    };
    let Some((film, stats)) = judged.done? else {
        if let Some(over) = judged.over_budget {
            bail!("{over}");
        }
        bail!("{}: the render was stopped", image.display());
    };
    let s = &scene.settings;
    // The image is read before the render is written: `-o` may name the image itself.
    let verdict = verify::differs_rendered(image, &header, &recipe, &film, s.gamma)?;
    if let Some(out) = &args.output {
        let again = Recipe::new(&recipe.source(), &scene, &film);
        film.save(out, s.gamma, Some(&again))?;
    }
    let how = format!(
        "{} in {:.1} s on {}, SIMD path {}",
        describe(&recipe.image),
        judged.elapsed.as_secs_f64(),
        count(stats.threads as u64, "thread"),
        options.simd.name()
    );
    match verdict {
        None => {
            out(&format!(
                "identical: {} is bit for bit what its recipe makes ({}; {how})\n",
                path_safe(image),
                recipe.sums
            ))?;
            Ok(ExitCode::SUCCESS)
        }
        Some(d) => {
            out(&differs_text(&format!("{} ({how})", d.summary), &d.details))?;
            Ok(differs)
        }
    }
}

/// Refuses `file`, named by `flag` to be written, where it is a texture file the recipe's
/// scene reads: the first of `dirs` that holds a file of the texture's name, as the scene's
/// build looks (`recipe::texture_dirs`, next to the image as a rule: a file that came with
/// it, not tessera's output). Written over, it would be lost, and the image would no longer
/// reproduce; `render -o` refuses the same.
fn refuse_texture(flag: &str, file: &Path, recipe: &Recipe, dirs: &[PathBuf]) -> Result<()> {
    // A name that is not plain is refused when the scene is built, and is not looked for.
    let plain = (recipe.textures.iter()).filter(|t| tessera::scene::is_plain_name(&t.name));
    for texture in plain {
        let read = (dirs.iter().map(|dir| dir.join(&texture.name))).find(|path| path.exists());
        if read.is_some_and(|read| same_file(file, &read)) {
            bail!(
                "{flag} {} names the texture file `{}` the recipe's scene reads: give the \
                 output a name of its own",
                file.display(),
                terminal_safe(&texture.name, 80)
            );
        }
    }
    Ok(())
}

/// The verdict `differs`: its summary, then each difference indented.
fn differs_text(summary: &str, details: &[String]) -> String {
    let mut t = format!("differs: {summary}");
    t.push_str(if details.is_empty() { "\n" } else { ":\n" });
    for line in details {
        t.push_str(&format!("  {line}\n"));
    }
    t
}
