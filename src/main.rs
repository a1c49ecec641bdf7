//! The `tessera` command line: parses arguments, loads the scene, renders, saves and reports.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
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
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => cmd_render(args),
        Command::Bench(args) => cmd_bench(args),
        Command::Merge { parts, output } => cmd_merge(&parts, &output),
        Command::Compare { a, b } => cmd_compare(&a, &b),
    };
    if let Err(e) = result {
        eprintln!("tessera: error: {e:#}");
        std::process::exit(2);
    }
}

/// A build made for AVX2 (see `.cargo/config.toml`) would die of an illegal instruction on a
/// CPU without it; say so instead, before anything runs.
fn require_build_features() {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    if !std::is_x86_feature_detected!("avx2") {
        eprintln!(
            "tessera: error: this build needs a CPU with AVX2; build a portable one with \
             RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release"
        );
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
    let partial = job != Job::whole(&scene);
    if !partial {
        // Refuse a bad output name before spending minutes on the render.
        Format::from_path(&output)?;
    }
    let mut state = match &args.checkpoint {
        Some(path) if path.exists() => resume(&scene, path, job, args.quiet)?,
        _ => Progress::new(job, args.tile),
    };
    let stop = Arc::new(AtomicBool::new(false));
    if args.checkpoint.is_some() {
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            signal_hook::flag::register(signal, Arc::clone(&stop))
                .context("could not install the signal handler")?;
        }
    }
    let bar = progress_bar(state.remaining_samples(), args.quiet);
    let mut save = |p: &Progress| {
        if let Some(path) = &args.checkpoint
            && let Err(e) = Part::from_progress(&scene, p, target).save(path)
        {
            bar.suspend(|| eprintln!("tessera: warning: could not save the checkpoint: {e}"));
        }
    };
    let every = Duration::from_secs_f64(args.checkpoint_every);
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
    if let Some(path) = &args.checkpoint {
        Part::from_progress(&scene, &state, target).save(path)?;
        if !state.is_complete() {
            eprintln!(
                "tessera: interrupted at {:.1}%; progress is saved in {}. Run the same command again to resume.",
                state.percent_done(),
                path.display()
            );
            std::process::exit(130);
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
        eprintln!(
            "{}: {what}, depth {}, seed {} | {}",
            output.display(),
            s.max_depth,
            s.seed,
            summary(&stats)
        );
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
        eprintln!(
            "tessera: resuming from {} ({:.1}% done)",
            path.display(),
            progress.percent_done()
        );
    }
    Ok(progress)
}

fn cmd_merge(paths: &[PathBuf], output: &Path) -> Result<()> {
    Format::from_path(output)?;
    let (film, gamma) = tessera::partial::merge_files(paths)?;
    film.save(output, gamma)?;
    eprintln!(
        "{}: merged {} parts, {}x{}, {} spp",
        output.display(),
        paths.len(),
        film.width,
        film.height,
        film.samples_per_pixel
    );
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
        println!("{report}");
    } else {
        println!(
            "{}: {}x{}, {} spp, depth {}, median of {}",
            scene_args.scene.display(),
            s.width,
            s.height,
            s.samples_per_pixel,
            s.max_depth,
            args.repeat.max(1)
        );
        println!("{}", summary(&stats));
        if !rows.is_empty() {
            println!("threads  M samples/s  speedup  efficiency");
            for (threads, samples_per_sec, speedup, efficiency) in rows {
                println!(
                    "{threads:>7}  {:>11.3}  {speedup:>7.2}  {:>9.0}%",
                    samples_per_sec / 1e6,
                    100.0 * efficiency
                );
            }
        }
    }
    Ok(())
}

fn cmd_compare(a: &Path, b: &Path) -> Result<()> {
    let d = tessera::compare::compare_files(a, b)?;
    println!(
        "RMSE {:.6}  PSNR {:.2} dB  mean abs error {:.6}",
        d.rmse, d.psnr_db, d.mean_abs
    );
    Ok(())
}
