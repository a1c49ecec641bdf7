//! The `tessera` command line: parses arguments, loads the scene, renders, saves and reports.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;
use tessera::film::Format;
use tessera::partial::Part;
use tessera::render::{self, Control, Job, Progress, RenderOptions, RenderStats, Snapshot};
use tessera::scene::{Overrides, Scene};
use tessera::shard::{self, Shard, Split, parse_samples};

const DEFAULT_SCENE: &str = "scenes/cover.toml";

#[derive(Parser)]
#[command(
    name = "tessera",
    version,
    about = "A deterministic multicore path tracer of Ray Tracing in One Weekend"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file to an image (.png, .ppm or .exr).
    Render(RenderArgs),
    /// Measure rendering speed: samples/s, Mrays/s and rays per sample.
    Bench(BenchArgs),
    /// Combine partial renders (shards, sample ranges) into one image, byte-identical to a
    /// single render of the same scene and settings.
    Merge {
        /// Partial render files written by `render --shard` or `--samples`.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        /// Output image (.png, .ppm or .exr).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Print the RMSE and PSNR between two images of equal size.
    Compare { a: PathBuf, b: PathBuf },
}

#[derive(Args)]
struct SceneArgs {
    /// Scene file (TOML).
    #[arg(default_value = DEFAULT_SCENE)]
    scene: PathBuf,
    /// Image width in pixels; the height keeps the scene's aspect ratio.
    #[arg(long)]
    width: Option<u32>,
    /// Samples per pixel.
    #[arg(long)]
    spp: Option<u32>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output image; its extension picks the format (default: the scene's name with .png).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Maximum ray segments per path.
    #[arg(long)]
    depth: Option<u32>,
    /// Seed of every random number of the render.
    #[arg(long)]
    seed: Option<u64>,
    /// Tile edge in pixels (scheduling only; the image does not change).
    #[arg(long, default_value_t = render::DEFAULT_TILE)]
    tile: u32,
    /// Render only shard I of N (`I/N`, 0-based), or take I from a job system: `env`
    /// (Slurm array: SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT) or `env/N` (Kubernetes
    /// Indexed Job: JOB_COMPLETION_INDEX). Writes a partial file for `tessera merge`.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// How shards divide the render: `samples` (each renders every pixel over a slice of
    /// the samples; even work) or `rows` (each renders a band of rows).
    #[arg(long, value_enum, default_value = "samples")]
    split: SplitArg,
    /// Render only sample indices A..B of every pixel; writes a partial file.
    #[arg(long, value_name = "A..B")]
    samples: Option<String>,
    /// Save progress to this file now and then and on Ctrl-C / SIGTERM; running the same
    /// command again resumes from it, and a larger --spp continues a finished render.
    #[arg(long, value_name = "FILE")]
    checkpoint: Option<PathBuf>,
    /// Seconds between checkpoint saves (0: after every tile).
    #[arg(long, default_value_t = 10.0, value_name = "SECS")]
    checkpoint_every: f64,
    /// No progress bar and no summary line.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum SplitArg {
    Samples,
    Rows,
}

#[derive(Args)]
struct BenchArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Renders per measurement; the median is reported.
    #[arg(long, default_value_t = 3)]
    repeat: u32,
    /// Skip the thread-scaling table.
    #[arg(long)]
    no_scaling: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

fn main() {
    require_build_features();
    let cli = Cli::try_parse().unwrap_or_else(|e| {
        // Help and usage errors, written without the panic `Cli::parse` risks on a full disk.
        match e.print() {
            Ok(()) => std::process::exit(e.exit_code()),
            Err(io) if io.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(0),
            Err(io) => {
                note(format_args!(
                    "tessera: error: could not write the message: {io}"
                ));
                std::process::exit(2);
            }
        }
    });
    let result = match cli.command {
        Command::Render(args) => cmd_render(args),
        Command::Bench(args) => cmd_bench(args),
        Command::Merge { parts, output } => cmd_merge(&parts, &output),
        Command::Compare { a, b } => cmd_compare(&a, &b),
    };
    if let Err(e) = result {
        // A reader that went away (`tessera bench | head -1`) ends the program quietly, as
        // it does any Unix tool.
        if is_broken_pipe(&e) {
            std::process::exit(0);
        }
        note(format_args!("tessera: error: {e:#}"));
        std::process::exit(2);
    }
}

/// True when `e` comes from writing to a pipe whose reader has gone.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Writes `text` to standard output. Unlike `print!`, which panics, a failure (a full disk, a
/// closed pipe) is an error for the caller to report.
fn print_out(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .context("could not write to standard output")
}

/// Writes a line to standard error. Unlike `eprintln!`, which panics, a failure is ignored:
/// when standard error cannot be written there is nobody left to tell.
fn note(line: std::fmt::Arguments) {
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(line).and_then(|()| err.write_all(b"\n"));
}

/// A build made for AVX2 (see `.cargo/config.toml`) would die of an illegal instruction on a
/// CPU without it; say so instead, before anything runs.
fn require_build_features() {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    if !std::is_x86_feature_detected!("avx2") {
        note(format_args!(
            "tessera: error: this build needs a CPU with AVX2; build a portable one with \
             RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release"
        ));
        std::process::exit(2);
    }
}

fn load(args: &SceneArgs, depth: Option<u32>, seed: Option<u64>) -> Result<Scene> {
    let overrides = Overrides {
        width: args.width,
        samples_per_pixel: args.spp,
        max_depth: depth,
        seed,
    };
    Ok(Scene::load(&args.scene, &overrides)?)
}

fn options(threads: Option<usize>, tile: u32) -> Result<RenderOptions> {
    if threads == Some(0) {
        bail!("--threads must be at least 1");
    }
    if tile == 0 {
        bail!("--tile must be at least 1 pixel");
    }
    Ok(RenderOptions { threads, tile })
}

fn cmd_render(args: RenderArgs) -> Result<()> {
    let output = match &args.output {
        Some(o) => o.clone(),
        None => default_output(&args.scene.scene),
    };
    let opts = options(args.scene.threads, args.tile)?;
    if !(args.checkpoint_every >= 0.0 && args.checkpoint_every.is_finite()) {
        bail!("--checkpoint-every must be a number of seconds, 0 or more");
    }
    // More seconds than a Duration holds (about 585 billion years) means never.
    let every = Duration::try_from_secs_f64(args.checkpoint_every).unwrap_or(Duration::MAX);
    let scene = load(&args.scene, args.depth, args.seed)?;
    let shard = match &args.shard {
        Some(spec) => Some(Shard::parse(spec, |k| std::env::var(k).ok())?),
        None => None,
    };
    let samples = args.samples.as_deref().map(parse_samples).transpose()?;
    let split = match args.split {
        SplitArg::Samples => Split::Samples,
        SplitArg::Rows => Split::Rows,
    };
    let job = shard::job(&scene, shard, split, samples)?;
    // Every part is a piece of the image of the scene's samples per pixel.
    let target = scene.settings.samples_per_pixel;
    if let Some(r) = samples
        && r.end > target
    {
        bail!(
            "--samples {}..{} goes past the {target} samples per pixel of the image; raise --spp",
            r.start,
            r.end
        );
    }
    // A shard or sample range always writes a part, even one that happens to be the whole
    // render (a Slurm array of one task), so a merge can take it.
    let partial = shard.is_some() || samples.is_some();
    // Refuse an output that cannot be written before spending minutes on the render.
    if !partial {
        Format::from_path(&output)?;
    }
    tessera::film::check_writable(&output)?;
    let mut state = match &args.checkpoint {
        Some(path) if path.exists() => resume(&scene, path, job, args.quiet)?,
        Some(path) => {
            tessera::film::check_writable(path)?;
            Progress::new(job, args.tile)
        }
        None => Progress::new(job, args.tile),
    };
    let stop = Arc::new(AtomicBool::new(false));
    if args.checkpoint.is_some() {
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            signal_hook::flag::register(signal, Arc::clone(&stop))
                .context("could not install the signal handler")?;
        }
    }
    let bar = progress_bar(state.remaining_samples(), args.quiet);
    // A checkpoint that cannot be saved (a full disk) is reported once, then counted: the
    // render goes on, and its image is written if the image's own disk has room.
    let mut failed_saves = 0u32;
    let mut save = |p: &Progress| {
        if let Some(path) = &args.checkpoint
            && let Err(e) = Part::from_progress(&scene, p, target).save(path)
        {
            if failed_saves == 0 {
                bar.suspend(|| {
                    note(format_args!(
                        "tessera: warning: could not save the checkpoint: {e}; rendering goes on"
                    ))
                });
            }
            failed_saves += 1;
        }
    };
    let control = Control {
        stop: &stop,
        on_samples: &|n| bar.inc(n),
        on_snapshot: args
            .checkpoint
            .as_ref()
            .map(|_| (&mut save as Snapshot, every)),
    };
    let stats = render::render_job(&scene, &opts, &mut state, control)
        .context("could not start the thread pool")?;
    bar.finish_and_clear();
    if failed_saves > 1 {
        note(format_args!(
            "tessera: warning: {failed_saves} checkpoint saves failed in all"
        ));
    }
    if let Some(path) = &args.checkpoint {
        let saved = Part::from_progress(&scene, &state, target).save(path);
        if !state.is_complete() {
            saved.context(format!(
                "interrupted at {:.1}%, and the progress could not be saved",
                state.percent_done()
            ))?;
            note(format_args!(
                "tessera: interrupted at {:.1}%; progress is saved in {}. Run the same command again to resume.",
                state.percent_done(),
                path.display()
            ));
            std::process::exit(130);
        }
        if let Err(e) = saved {
            note(format_args!(
                "tessera: warning: could not save the finished checkpoint ({e}); writing the image"
            ));
        }
    }
    if partial {
        Part::from_progress(&scene, &state, target).save(&output)?;
    } else {
        state.film().save(&output, scene.settings.gamma)?;
    }
    if !args.quiet {
        let s = &scene.settings;
        let r = state.job.region;
        let what = if partial {
            format!(
                "partial render of pixels {}x{} at ({}, {}), samples {}..{} (combine parts with `tessera merge`)",
                r.width, r.height, r.x0, r.y0, state.job.samples.start, state.job.samples.end
            )
        } else if (r.width, r.height) != (s.width, s.height) {
            format!(
                "{}x{} cropped to {}x{} at ({}, {}), {} spp",
                s.width, s.height, r.width, r.height, r.x0, r.y0, s.samples_per_pixel
            )
        } else {
            format!("{}x{}, {} spp", s.width, s.height, s.samples_per_pixel)
        };
        note(format_args!(
            "{}: {what}, depth {}, seed {} | {}",
            output.display(),
            s.max_depth,
            s.seed,
            summary(&stats)
        ));
    }
    Ok(())
}

/// The state saved in checkpoint `path`, checked against this render and extended to its
/// sample range.
fn resume(scene: &Scene, path: &Path, job: Job, quiet: bool) -> Result<Progress> {
    let part = Part::load(path)?;
    part.check_scene(scene, path)?;
    let mut progress = part.progress();
    let (had, want) = (progress.job, job);
    if had.region != want.region || had.samples.start != want.samples.start {
        bail!(
            "{}: the checkpoint holds pixels {}x{} at ({}, {}) from sample {}, but this render is pixels {}x{} at ({}, {}) from sample {}; use another checkpoint file",
            path.display(),
            had.region.width,
            had.region.height,
            had.region.x0,
            had.region.y0,
            had.samples.start,
            want.region.width,
            want.region.height,
            want.region.x0,
            want.region.y0,
            want.samples.start
        );
    }
    if had.samples.end > want.samples.end {
        bail!(
            "{}: the checkpoint already goes to sample {}, past the {} this render asks for",
            path.display(),
            had.samples.end,
            want.samples.end
        );
    }
    progress.extend_to(want.samples.end);
    if !quiet {
        note(format_args!(
            "tessera: resuming from {} ({:.1}% done)",
            path.display(),
            progress.percent_done()
        ));
    }
    Ok(progress)
}

fn cmd_merge(paths: &[PathBuf], output: &Path) -> Result<()> {
    Format::from_path(output)?;
    let (film, gamma) = tessera::partial::merge_files(paths)?;
    film.save(output, gamma)?;
    note(format_args!(
        "{}: merged {} parts, {}x{}, {} spp",
        output.display(),
        paths.len(),
        film.width,
        film.height,
        film.samples_per_pixel
    ));
    Ok(())
}

fn default_output(scene: &Path) -> PathBuf {
    let stem = scene.file_stem().map_or("render".into(), |s| s.to_owned());
    let mut name = stem;
    name.push(".png");
    PathBuf::from(name)
}

fn progress_bar(total: u64, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{wide_bar}] {percent:>3}% of {human_len} samples, ETA {eta_precise}",
        )
        .expect("progress template is valid")
        .progress_chars("=> "),
    );
    bar
}

fn summary(stats: &RenderStats) -> String {
    format!(
        "{:.2} s wall, {:.3} M samples/s, {:.2} Mrays/s, {:.3} rays/sample, {} threads",
        stats.wall.as_secs_f64(),
        stats.samples_per_sec() / 1e6,
        stats.mrays_per_sec(),
        stats.rays_per_sample(),
        stats.threads
    )
}

/// Renders `repeat` times with `threads` workers; returns the run with the median speed.
fn median_run(scene: &Scene, threads: usize, repeat: u32) -> Result<RenderStats> {
    let opts = options(Some(threads), render::DEFAULT_TILE)?;
    let mut runs = (0..repeat.max(1))
        .map(|_| {
            Ok(render::render(scene, &opts, &|_| {})
                .context("could not start the thread pool")?
                .1)
        })
        .collect::<Result<Vec<RenderStats>>>()?;
    runs.sort_by(|a, b| a.samples_per_sec().total_cmp(&b.samples_per_sec()));
    Ok(runs[runs.len() / 2])
}

fn cmd_bench(args: BenchArgs) -> Result<()> {
    let mut scene_args = args.scene;
    scene_args.width = scene_args.width.or(Some(300));
    scene_args.spp = scene_args.spp.or(Some(8));
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = scene_args.threads.unwrap_or(cores);
    options(Some(threads), render::DEFAULT_TILE)?;
    let scene = load(&scene_args, None, None)?;
    // Thread scaling: 1 … available cores, each the median of `repeat` renders.
    let scaling = if args.no_scaling {
        Vec::new()
    } else {
        (1..=cores)
            .map(|t| median_run(&scene, t, args.repeat))
            .collect::<Result<Vec<_>>>()?
    };
    // The headline run at `threads`, unless the table already measured it.
    let stats = match scaling.iter().find(|r| r.threads == threads) {
        Some(r) => *r,
        None => median_run(&scene, threads, args.repeat)?,
    };
    let base = scaling.first().map_or(1.0, RenderStats::samples_per_sec);
    // Per thread count: samples/s, speedup over one thread, parallel efficiency.
    let rows: Vec<(usize, f64, f64, f64)> = scaling
        .iter()
        .map(|r| {
            let speedup = r.samples_per_sec() / base;
            let efficiency = speedup / r.threads as f64;
            (r.threads, r.samples_per_sec(), speedup, efficiency)
        })
        .collect();
    let s = &scene.settings;
    if args.json {
        let table: Vec<_> = rows
            .iter()
            .map(|&(threads, samples_per_sec, speedup, efficiency)| {
                serde_json::json!({
                    "threads": threads,
                    "samples_per_sec": samples_per_sec,
                    "speedup": speedup,
                    "efficiency": efficiency,
                })
            })
            .collect();
        let report = serde_json::json!({
            "samples_per_sec": stats.samples_per_sec(),
            "mrays_per_sec": stats.mrays_per_sec(),
            "rays_per_sample": stats.rays_per_sample(),
            "wall_s": stats.wall.as_secs_f64(),
            "threads": stats.threads,
            "width": s.width,
            "height": s.height,
            "spp": s.samples_per_pixel,
            "scaling": table,
        });
        print_out(&format!("{report}\n"))
    } else {
        let mut text = format!(
            "{}: {}x{}, {} spp, depth {}, median of {}\n{}\n",
            scene_args.scene.display(),
            s.width,
            s.height,
            s.samples_per_pixel,
            s.max_depth,
            args.repeat.max(1),
            summary(&stats)
        );
        if !rows.is_empty() {
            text.push_str("threads  M samples/s  speedup  efficiency\n");
            for (threads, samples_per_sec, speedup, efficiency) in rows {
                text.push_str(&format!(
                    "{threads:>7}  {:>11.3}  {speedup:>7.2}  {:>9.0}%\n",
                    samples_per_sec / 1e6,
                    100.0 * efficiency
                ));
            }
        }
        print_out(&text)
    }
}

fn cmd_compare(a: &Path, b: &Path) -> Result<()> {
    let d = tessera::compare::compare_files(a, b)?;
    print_out(&format!(
        "RMSE {:.6}  PSNR {:.2} dB  mean abs error {:.6}\n",
        d.rmse, d.psnr_db, d.mean_abs
    ))
}
