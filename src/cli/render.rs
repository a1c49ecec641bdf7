//! `tessera render`: resumes or starts the job, renders it with a progress bar, saves
//! checkpoints on the way and on Ctrl-C or SIGTERM, then writes the image or part and a summary.

use super::preview::Session;
use super::settings::{CheckpointSettings, Output, RenderSettings};
use super::{note, progress_bar, summary};
use anyhow::{Context, Result};
use indicatif::ProgressBar;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use tessera::film::Film;
use tessera::image_file::Format;
use tessera::job::{Job, JobState};
use tessera::partial::{self, Part, RenderId};
use tessera::preview::{About, RunState};
use tessera::recipe::Recipe;
use tessera::render::{self, Control, RenderOptions, RenderStats, Snapshot, Watch};
use tessera::scene::Scene;

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
                        "tessera: warning: could not save the checkpoint: {e}; rendering goes on"
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
                "tessera: warning: could not save the finished checkpoint ({e}); writing the image"
            ));
        }
        Ok(())
    }
}

pub fn run(settings: RenderSettings) -> Result<()> {
    let RenderSettings {
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
    } = settings;
    let mut state = match &checkpoint {
        Some(c) if c.path.exists() => resume(&scene, &c.path, job, quiet)?,
        _ => JobState::new(job, options.tile),
    };
    let stop = Arc::new(AtomicBool::new(false));
    if checkpoint.is_some() {
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            signal_hook::flag::register(signal, Arc::clone(&stop))
                .context("could not install the signal handler")?;
        }
    }
    let bar = progress_bar(state.remaining_samples(), quiet);
    let mut preview = if preview.is_on() {
        let about = about(&scene_file, &scene, &options, &state, job_label, &output);
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
        on_snapshot: checkpoint
            .as_ref()
            .map(|c| (&mut save as Snapshot, c.every)),
        progressive: preview.is_some(),
        watch: preview.as_mut().map(|p| &mut p.previewer as &mut dyn Watch),
    };
    let stats = render::render_job(&scene, &options, &mut state, control)
        .context("could not start the thread pool")?;
    bar.finish_and_clear();
    if let Some(preview) = preview.take_if(|_| !state.is_complete()) {
        preview.end(&state, RunState::Interrupted).close();
    }
    if let Some(saver) = &saver {
        saver.save_at_end(&state)?;
        if !state.is_complete() {
            note(format_args!(
                "tessera: interrupted at {:.1}%; progress is saved in {}. Run the same command again to resume.",
                state.percent_done(),
                saver.settings.path.display()
            ));
            std::process::exit(130);
        }
    }
    let what = describe(&scene, &state, &output);
    // The output first, so that a viewer told the render has finished finds it written.
    let preview = match (&output, preview) {
        (Output::Part(path), preview) => {
            partial::save(path, &render, &state)?;
            preview.map(|p| p.end(&state, RunState::Finished))
        }
        // The viewer's final frame comes from the state: the image gets a copy.
        (Output::Image(path), Some(p)) => {
            write_image(path, state.clone().into_film(), &scene, &render, quiet)?;
            Some(p.end(&state, RunState::Finished))
        }
        (Output::Image(path), None) => {
            write_image(path, state.into_film(), &scene, &render, quiet)?;
            None
        }
    };
    if !quiet {
        report(&scene, &output, &what, &stats);
    }
    if let Some(preview) = preview {
        preview.close();
    }
    Ok(())
}

/// Writes `film` of `scene` to `path` with the recipe of `render`, if it keeps one.
fn write_image(
    path: &Path,
    film: Film,
    scene: &Scene,
    render: &RenderId,
    quiet: bool,
) -> Result<()> {
    let recipe = render
        .recipe
        .as_ref()
        .map(|source| Recipe::new(source, scene, &film));
    if recipe.is_some() && !quiet && Format::from_path(path)? == Format::Ppm {
        note(format_args!(
            "tessera: note: PPM has no metadata, so {} carries no recipe (PNG and EXR do)",
            path.display()
        ));
    }
    film.save(path, scene.settings.gamma, recipe.as_ref())?;
    Ok(())
}

/// What the viewer says the render is.
fn about(
    scene_file: &Path,
    scene: &Scene,
    options: &RenderOptions,
    state: &JobState,
    job: String,
    output: &Output,
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
    }
}

/// The state saved in checkpoint `path`, checked against this render and extended to `job`.
fn resume(scene: &Scene, path: &Path, job: Job, quiet: bool) -> Result<JobState> {
    let state = Part::load(path)?.resume(scene, job, path)?;
    if !quiet {
        note(format_args!(
            "tessera: resuming from {} ({:.1}% done)",
            path.display(),
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
        output.path().display(),
        s.max_depth,
        s.seed,
        summary(stats)
    ));
}
