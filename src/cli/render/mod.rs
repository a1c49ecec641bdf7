//! `tessera render`: its arguments, checked into a `RenderPlan` (`plan`), then run:
//! resumes or starts the job, renders it with a progress bar, saves checkpoints on the way
//! and on Ctrl-C or SIGTERM, then writes the image or part and a summary. `preview` watches
//! it.

mod plan;
mod preview;

use super::flags::{self, SimdArg};
use super::output::{self, note, progress_bar, render_summary};
use anyhow::{Context, Result};
use clap::ValueEnum;
use indicatif::ProgressBar;
use plan::{CheckpointSettings, Output, RenderPlan};
use preview::Session;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use tessera::atomic_file::write_result_atomically_with;
use tessera::film::Film;
use tessera::image_file::Format;
use tessera::job::{Job, JobState};
use tessera::partial::{self, Part, RenderId};
use tessera::preview::{About, RunState};
use tessera::recipe::Recipe;
use tessera::render::{self, Control, ProgressSaver, RenderOptions, RenderStats, Watch};
use tessera::scene::Scene;
use tessera::text::{message_safe, path_safe};

pub use plan::DEFAULT_SCENE;

/// `tessera render` as typed.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output image; its extension picks the format (default: the scene's name with .png).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Maximum ray segments per path.
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = flags::positive_u32)]
    pub depth: Option<u32>,
    /// Seed of every random number of the render.
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = flags::seed)]
    pub seed: Option<u64>,
    /// Tile edge in pixels (scheduling only; the image does not change).
    #[arg(long, value_name = "PX", default_value_t = render::DEFAULT_TILE, allow_negative_numbers = true, value_parser = flags::positive_u32)]
    pub tile: u32,
    /// Render only shard I of N (`I/N`, 0-based), or take I from a job system: `env`
    /// (Slurm array: SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT) or `env/N` (Kubernetes
    /// Indexed Job: JOB_COMPLETION_INDEX). Writes a partial file for `tessera merge`.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// How shards divide the render: `samples` (each renders every pixel over a slice of
    /// the samples; even work) or `rows` (each renders a band of rows).
    #[arg(long, value_enum, default_value = "samples")]
    pub split: SplitArg,
    /// Render only sample indices A..B of every pixel; writes a partial file.
    #[arg(long, value_name = "A..B")]
    pub samples: Option<String>,
    /// Save progress to this file now and then and on Ctrl-C / SIGTERM; running the same
    /// command again resumes from it, and a larger --spp continues a finished render.
    #[arg(long, value_name = "FILE")]
    pub checkpoint: Option<PathBuf>,
    /// Seconds between checkpoint saves (0: after every tile).
    #[arg(
        long,
        default_value_t = 10.0,
        value_name = "SECS",
        allow_negative_numbers = true
    )]
    pub checkpoint_every: f64,
    /// No progress bar and no summary line.
    #[arg(long, short)]
    pub quiet: bool,
    /// Leave the recipe (the scene's text, the settings, the build) out of the image's
    /// metadata and of partial files, for a scene that must not be published.
    #[arg(long)]
    pub no_provenance: bool,
    #[command(flatten)]
    pub preview: PreviewArgs,
}

/// The scene and what changes it or how fast it renders.
#[derive(clap::Args)]
pub struct SceneArgs {
    /// Scene file (TOML).
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    /// Image width in pixels; the height keeps the scene's aspect ratio.
    #[arg(long, value_name = "PX", allow_negative_numbers = true, value_parser = flags::positive_u32)]
    pub width: Option<u32>,
    /// Samples per pixel.
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = flags::positive_u32)]
    pub spp: Option<u32>,
    /// Worker threads (default: one per core); the image does not change.
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = flags::threads)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub simd: SimdArg,
}

/// How to watch a render.
#[derive(clap::Args)]
pub struct PreviewArgs {
    /// Watch the render in a web browser: serves a live viewer at ADDR:PORT (default
    /// 127.0.0.1 on a free port; `--preview=PORT` or `--preview=ADDR:PORT` to choose) and
    /// prints its address. The image is the same as without.
    #[arg(
        long,
        value_name = "ADDR:PORT",
        num_args = 0..=1,
        require_equals = true,
        default_missing_value = "127.0.0.1:0"
    )]
    pub preview: Option<String>,
    /// Keep serving the final image after the render ends, until Ctrl-C.
    #[arg(long, requires = "preview")]
    pub preview_hold: bool,
    /// Write the image so far to this PNG file every --preview-every seconds (atomically),
    /// for machines where nobody can open a port; any viewer that reloads files shows it.
    #[arg(long, value_name = "PNG")]
    pub preview_file: Option<PathBuf>,
    /// Seconds between writes of --preview-file [default: 2].
    #[arg(long, value_name = "SECS", allow_negative_numbers = true)]
    pub preview_every: Option<f64>,
}

/// `--preview 8080` or `--preview ADDR:PORT` with a space: clap leaves the flag without a
/// value and takes the address for the scene file (or an extra argument). Says what was
/// meant, for a value that is an address and not a file.
pub fn preview_without_equals(args: &[std::ffi::OsString]) -> Option<String> {
    let after = args.windows(2).find(|w| w[0] == "--preview")?[1].to_str()?;
    if after.starts_with('-') || Path::new(after).exists() || plan::preview_address(after).is_err()
    {
        return None;
    }
    Some(format!(
        "--preview {after}: the viewer's address follows an `=`: write --preview={after} \
         (after a space, `{after}` is read as the scene file)"
    ))
}

#[derive(Clone, Copy, ValueEnum)]
pub enum SplitArg {
    Samples,
    Rows,
}

/// A render's checkpoint file: saved now and then, and at the end. A save that fails (a full
/// disk) is reported once, then counted: the render goes on, and its image is still written if
/// the image's own disk has room.
struct Checkpoint<'a> {
    settings: &'a CheckpointSettings,
    render: &'a RenderId,
    failed: u32,
}

impl Checkpoint<'_> {
    /// Saves `state` during the render; a failure is reported once, above the bar.
    fn save_while_rendering(&mut self, state: &JobState, bar: &ProgressBar) {
        if let Err(e) = partial::save(&self.settings.path, self.render, state) {
            if self.failed == 0 {
                bar.suspend(|| {
                    note(format_args!(
                        "tessera: warning: could not save the checkpoint: {}; rendering goes on",
                        message_safe(&e.to_string())
                    ))
                });
            }
            self.failed += 1;
        }
    }

    /// Saves `state` at the end of the render. An unfinished render whose progress cannot
    /// be saved is an error; a finished one only warns, and its image is written.
    fn save_at_end(&self, state: &JobState) -> Result<()> {
        if self.failed > 1 {
            note(format_args!(
                "tessera: warning: {} checkpoint saves failed in all",
                self.failed
            ));
        }
        let saved = partial::save(&self.settings.path, self.render, state);
        if !state.is_complete() {
            return saved.context(format!(
                "interrupted at {:.1}%, and the progress could not be saved",
                state.percent_done()
            ));
        }
        if let Err(e) = saved {
            note(format_args!(
                "tessera: warning: could not save the finished checkpoint ({}); writing the image",
                message_safe(&e.to_string())
            ));
        }
        Ok(())
    }
}

/// Checks `args` and renders.
pub fn run(args: Args) -> Result<ExitCode> {
    let RenderPlan {
        scene,
        options,
        job,
        render,
        output,
        checkpoint,
        preview,
        job_label,
        scene_file,
        quiet,
    } = RenderPlan::new(args)?;
    let mut state = match &checkpoint {
        Some(c) if c.path.exists() => resume(&scene, &c.path, job, quiet)?,
        // Reserved, not assumed: a scene of 16384x16384 pixels claims 6 GiB of sums, and a
        // failed allocation aborted tessera ("memory allocation of … bytes failed").
        _ => JobState::try_new(job, options.tile).map_err(|why| anyhow::anyhow!("{why}"))?,
    };
    let stop = Arc::new(AtomicBool::new(false));
    if checkpoint.is_some() || preview.is_on() {
        // The first Ctrl-C or SIGTERM stops the render, which saves its checkpoint and tells
        // its viewer and preview file it was interrupted (unwatched and without a checkpoint,
        // the signal's default ends it at once, as nothing is left to tell); a second ends
        // the process at once (exit 130), where the first finds it waiting on what no
        // signal interrupts (an output that is this user's pipe with no reader: once deaf to
        // every signal but SIGKILL). Registered first, the exit looks at the flag before the
        // first signal sets it.
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            signal_hook::flag::register_conditional_shutdown(signal, 130, Arc::clone(&stop))
                .and_then(|_| signal_hook::flag::register(signal, Arc::clone(&stop)))
                .context("could not install the signal handler")?;
        }
    }
    let bar = progress_bar(state.remaining_samples(), quiet);
    let mut preview = if preview.is_on() {
        let held = preview.hold;
        let about = about(
            &scene_file,
            &scene,
            &options,
            &state,
            job_label,
            &output,
            held,
        );
        Some(Session::start(
            preview,
            about,
            &state,
            scene.settings.gamma,
            &bar,
        )?)
    } else {
        None
    };
    let mut saver = checkpoint.as_ref().map(|settings| Checkpoint {
        settings,
        render: &render,
        failed: 0,
    });
    let mut save = |state: &JobState| {
        if let Some(saver) = saver.as_mut() {
            saver.save_while_rendering(state, &bar);
        }
    };
    let control = Control {
        stop: &stop,
        on_samples: &|n| bar.inc(n),
        on_progress: checkpoint
            .as_ref()
            .map(|c| (&mut save as ProgressSaver, c.every)),
        progressive: preview.is_some(),
        watch: preview.as_mut().map(|p| &mut p.previewer as &mut dyn Watch),
    };
    let stats = render::render_job(&scene, &options, &mut state, control)
        .context("could not start the thread pool")?;
    bar.finish_and_clear();
    // An interrupted render's progress is saved before the viewer is closed: closing waits
    // up to 5 s for its clients (a hostile one holds it that long), which would eat into the
    // few seconds a container is given between SIGTERM and SIGKILL.
    let saved = saver.as_ref().map(|saver| saver.save_at_end(&state));
    // Interrupted, its progress saved; or failed, where the checkpoint could not be written
    // and the progress is lost (the terminal says why).
    if let Some(preview) = preview.take_if(|_| !state.is_complete()) {
        let run = match &saved {
            Some(Err(_)) => RunState::Failed,
            _ => RunState::Interrupted,
        };
        preview.end(&state, run).close();
    }
    if let Some(saver) = &saver {
        failed_if(saved.transpose(), &mut preview, &state)?;
        if !state.is_complete() {
            note(format_args!(
                "tessera: interrupted at {:.1}%; progress is saved in {}. Run the same command again to resume.",
                state.percent_done(),
                path_safe(&saver.settings.path)
            ));
            return Ok(ExitCode::from(output::INTERRUPTED));
        }
    }
    // A watched render stopped by a signal with no checkpoint to keep its progress: its
    // viewer was told above; no image is written (an output is whole or absent).
    if !state.is_complete() {
        note(format_args!(
            "tessera: interrupted at {:.1}%; nothing is saved (with --checkpoint FILE, the same \
             command resumes)",
            state.percent_done()
        ));
        return Ok(ExitCode::from(output::INTERRUPTED));
    }
    let what = describe(&scene, &state, &output);
    // The output first, so that a viewer told the render has finished finds it written, and
    // one told it has failed when it could not be written.
    let preview = match (&output, preview) {
        (Output::Part(path), mut preview) => {
            let saved = partial::save_result(path, &render, &state).map_err(Into::into);
            failed_if(saved, &mut preview, &state)?;
            preview.map(|p| p.end(&state, RunState::Finished))
        }
        // The viewer's final frame comes from the state: the image gets a copy.
        (Output::Image(path), Some(session)) => {
            let film = state.clone().into_film();
            let as_png = session.has_viewer();
            let mut preview = Some(session);
            let written = write_image(path, &film, &scene, &render, quiet, as_png);
            let png = failed_if(written, &mut preview, &state)?;
            preview.map(|mut p| {
                if let Some(png) = png {
                    p.previewer.offer_download(download_name(path), png);
                }
                p.end(&state, RunState::Finished)
            })
        }
        (Output::Image(path), None) => {
            write_image(path, &state.into_film(), &scene, &render, quiet, false)?;
            None
        }
    };
    if !quiet {
        report(&scene, &output, &what, &stats);
    }
    if let Some(preview) = preview {
        preview.close();
    }
    Ok(ExitCode::SUCCESS)
}

/// Gives `result` back; where it is an error, first tells a watched render's viewer and
/// preview file that the render failed (the error itself goes to the terminal, as ever), so
/// that a page left showing 100% "rendering" does not wait for an image that never comes.
fn failed_if<T>(result: Result<T>, preview: &mut Option<Session>, state: &JobState) -> Result<T> {
    if result.is_err()
        && let Some(session) = preview.take()
    {
        session.end(state, RunState::Failed).close();
    }
    result
}

/// Writes `film` of `scene` to `path` with the recipe of `render`, if it keeps one. With
/// `as_png`, also gives the image as a PNG file's bytes, recipe included: for a PNG output
/// the very bytes written.
fn write_image(
    path: &Path,
    film: &Film,
    scene: &Scene,
    render: &RenderId,
    quiet: bool,
    as_png: bool,
) -> Result<Option<Vec<u8>>> {
    let recipe = render
        .recipe
        .as_ref()
        .map(|source| Recipe::new(source, scene, film));
    let format = Format::from_path(path)?;
    if recipe.is_some() && !quiet && format == Format::Ppm {
        note(format_args!(
            "tessera: note: PPM has no metadata, so {} carries no recipe (PNG and EXR do)",
            path_safe(path)
        ));
    }
    let gamma = scene.settings.gamma;
    if !as_png {
        film.save(path, gamma, recipe.as_ref())?;
        return Ok(None);
    }
    let mut png = Vec::new();
    film.write(Format::Png, gamma, recipe.as_ref(), &mut png)
        .context("could not encode the PNG")?;
    if format == Format::Png {
        write_result_atomically_with(path, &mut |out| out.write_all(&png))?;
    } else {
        film.save(path, gamma, recipe.as_ref())?;
    }
    Ok(Some(png))
}

/// The name the viewer offers the image under: the output's, as a PNG.
fn download_name(output: &Path) -> String {
    let stem = output
        .file_stem()
        .map_or("render".into(), |s| s.to_string_lossy().into_owned());
    format!("{stem}.png")
}

/// What the viewer says the render is.
fn about(
    scene_file: &Path,
    scene: &Scene,
    options: &RenderOptions,
    state: &JobState,
    job: String,
    output: &Output,
    held: bool,
) -> About {
    let s = &scene.settings;
    let r = state.job.region;
    About {
        scene: (scene_file.file_stem())
            .map_or("scene".into(), |n| n.to_string_lossy().into_owned()),
        scene_file: scene_file.display().to_string(),
        width: s.width,
        height: s.height,
        spp: s.samples_per_pixel,
        max_depth: s.max_depth,
        seed: s.seed,
        shading: format!("{:?}", s.shading).to_lowercase(),
        threads: options.threads.unwrap_or_else(rayon::current_num_threads),
        tile: state.tile,
        simd: options.simd.name().to_owned(),
        region: [r.x0, r.y0, r.width, r.height],
        samples: [state.job.samples.start, state.job.samples.end],
        job,
        output: output.path().display().to_string(),
        held,
    }
}

/// The state saved in checkpoint `path` (a file of this user's), checked against this render
/// and extended to `job`.
fn resume(scene: &Scene, path: &Path, job: Job, quiet: bool) -> Result<JobState> {
    let state = Part::load_checkpoint(path, scene, job)?;
    if !quiet {
        note(format_args!(
            "tessera: resuming from {} ({:.1}% done)",
            path_safe(path),
            state.percent_done()
        ));
    }
    Ok(state)
}

/// What was rendered, for the summary line.
fn describe(scene: &Scene, state: &JobState, output: &Output) -> String {
    let s = &scene.settings;
    let r = state.job.region;
    match output {
        Output::Part(_) => format!(
            "partial render of pixels {}x{} at ({}, {}), samples {}..{} (combine parts with `tessera merge`)",
            r.width, r.height, r.x0, r.y0, state.job.samples.start, state.job.samples.end
        ),
        Output::Image(_) if (r.width, r.height) != (s.width, s.height) => format!(
            "{}x{} cropped to {}x{} at ({}, {}), {} spp",
            s.width, s.height, r.width, r.height, r.x0, r.y0, s.samples_per_pixel
        ),
        Output::Image(_) => format!("{}x{}, {} spp", s.width, s.height, s.samples_per_pixel),
    }
}

fn report(scene: &Scene, output: &Output, what: &str, stats: &RenderStats) {
    let s = &scene.settings;
    note(format_args!(
        "{}: {what}, depth {}, seed {} | {}",
        path_safe(output.path()),
        s.max_depth,
        s.seed,
        render_summary(stats)
    ));
}
