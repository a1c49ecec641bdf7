//! `tessera merge`: adds part files (shards, sample ranges, finished checkpoints) into the
//! image a single render writes, recipe included when the parts carry one that describes
//! them.

use super::output::note;
use super::writable::{check_output, same_file};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tessera::film::Film;
use tessera::image_file::Format;
use tessera::partial::RenderId;
use tessera::recipe::{Recipe, Source};
use tessera::text::{message_safe, path_safe};

/// `tessera merge` as typed.
#[derive(clap::Args)]
pub struct Args {
    /// Partial render files written by `render --shard` or `--samples`; a directory
    /// stands for every `.part` file in it.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output image (.png, .ppm or .exr).
    #[arg(short, long)]
    output: PathBuf,
    /// Leave the parts' recipe out of the image's metadata.
    #[arg(long)]
    no_provenance: bool,
    /// Look for the scene's texture files here first (then next to the first part, then in
    /// `scenes/`): the merged image's recipe is checked against its scene, textures
    /// included.
    #[arg(long, value_name = "DIR")]
    textures: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let Args {
        parts,
        output,
        no_provenance,
        textures,
    } = args;
    Format::from_path(&output)?;
    check_output("-o", &output)?;
    let paths = part_files(&parts)?;
    // The image replaces whatever file it is written to: a part it adds up would be lost.
    if let Some(part) = paths.iter().find(|p| same_file(&output, p)) {
        anyhow::bail!(
            "-o {} names the same file as the part {}: give the image a name of its own",
            output.display(),
            part.display()
        );
    }
    let (film, render) = tessera::partial::merge_files(&paths)?;
    let recipe = match render.recipe.as_ref().filter(|_| !no_provenance) {
        Some(source) => {
            let recipe = merged_recipe(source, &render, &film, &paths[0], textures.as_deref());
            // The reason quotes the parts' scene, a stranger's text: of bounded length.
            if let Err(why) = &recipe {
                note(format_args!(
                    "tessera: warning: {}; {} carries no recipe",
                    message_safe(why),
                    path_safe(&output)
                ));
            }
            recipe.ok()
        }
        None if no_provenance => None,
        None => {
            note(format_args!(
                "tessera: note: the parts carry no common recipe, so {} carries none",
                path_safe(&output)
            ));
            None
        }
    };
    film.save(&output, render.gamma, recipe.as_ref())?;
    note(format_args!(
        "{}: merged {}, {}x{}, {} spp",
        path_safe(&output),
        super::output::count(paths.len() as u64, "part"),
        film.width,
        film.height,
        film.samples_per_pixel
    ));
    Ok(ExitCode::SUCCESS)
}

/// The part files `paths` name: a directory stands for every `*.part` file in it (sorted),
/// as a shared volume holds a job's parts where no shell expands `*.part`.
fn part_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for path in paths {
        if !path.is_dir() {
            files.push(path.clone());
            continue;
        }
        let entries = std::fs::read_dir(path)
            .with_context(|| format!("{}: could not list the directory", path.display()))?;
        let mut parts = Vec::new();
        for entry in entries {
            let entry = entry
                .with_context(|| format!("{}: could not list the directory", path.display()))?;
            let file = entry.path();
            if file.extension().is_some_and(|e| e == "part") && file.is_file() {
                parts.push(file);
            }
        }
        if parts.is_empty() {
            anyhow::bail!("{}: no .part files in the directory", path.display());
        }
        parts.sort();
        files.extend(parts);
    }
    Ok(files)
}

/// The recipe of a merged `film` of `render`'s parts, which carry `source`, when `source`
/// describes them: the scene it gives has their fingerprint, window and sample count, and
/// the settings their header gives apart from the fingerprint (size, depth, seed and the
/// gamma the image is written with), which a crafted header may set otherwise.
/// `part` names the source in errors; its textures are looked for in `textures` first.
fn merged_recipe(
    source: &Source,
    render: &RenderId,
    film: &Film,
    part: &Path,
    textures: Option<&Path>,
) -> std::result::Result<Recipe, String> {
    // A recipe names the build that renders its image: parts of another build's (all of
    // one, or `check_set` refuses them) may hold other sums than this one renders.
    let this = tessera::recipe::Maker::this_build();
    if render.tessera != this {
        return Err(format!(
            "the parts were rendered by {}, not by this {this}, which may render other sums; \
             merge them with that build for a recipe",
            render.tessera
        ));
    }
    let dirs = tessera::recipe::texture_dirs(textures, part);
    let scene = source
        .parse(part, &dirs)
        .map_err(|e| format!("the parts' scene cannot be read again ({e})"))?;
    let describes = scene.settings.samples_per_pixel == render.target
        && RenderId::of(&scene, render.target)
            == RenderId {
                recipe: None,
                ..render.clone()
            };
    if describes {
        let recipe = Recipe::new(source, &scene, film);
        match recipe.why_not_carried() {
            Some(why) => Err(format!("of the parts' scene, {why}")),
            None => Ok(recipe),
        }
    } else {
        Err("the parts' recipe does not describe them".to_owned())
    }
}
