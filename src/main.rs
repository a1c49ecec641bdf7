//! The `tessera` command line: parses arguments, loads the scene, renders, saves and reports.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use tessera::film::Format;
use tessera::render::{self, RenderOptions, RenderStats};
use tessera::scene::{Overrides, Scene};

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
    /// No progress bar and no summary line.
    #[arg(long, short)]
    quiet: bool,
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
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => cmd_render(args),
        Command::Bench(args) => cmd_bench(args),
        Command::Compare { a, b } => cmd_compare(&a, &b),
    };
    if let Err(e) = result {
        eprintln!("tessera: error: {e:#}");
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
    // Refuse a bad output name before spending minutes on the render.
    Format::from_path(&output)?;
    let opts = options(args.scene.threads, args.tile)?;
    let scene = load(&args.scene, args.depth, args.seed)?;
    let bar = progress_bar(scene.total_samples(), args.quiet);
    let (film, stats) = render::render(&scene, &opts, &|n| bar.inc(n))
        .context("could not start the thread pool")?;
    bar.finish_and_clear();
    film.save(&output, scene.settings.gamma)?;
    if !args.quiet {
        let s = &scene.settings;
        let w = s.window;
        let crop = if (w.width, w.height) == (s.width, s.height) {
            String::new()
        } else {
            format!(
                " cropped to {}x{} at ({}, {})",
                w.width, w.height, w.x0, w.y0
            )
        };
        eprintln!(
            "{}: {}x{}{crop}, {} spp, depth {}, seed {} | {}",
            output.display(),
            s.width,
            s.height,
            s.samples_per_pixel,
            s.max_depth,
            s.seed,
            summary(&stats)
        );
    }
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
    let stats = median_run(&scene, threads, args.repeat)?;
    // Thread scaling: 1 … available cores, each the median of `repeat` renders.
    let scaling = if args.no_scaling {
        Vec::new()
    } else {
        (1..=cores)
            .map(|t| median_run(&scene, t, args.repeat))
            .collect::<Result<Vec<_>>>()?
    };
    let base = scaling.first().map_or(1.0, RenderStats::samples_per_sec);
    let s = &scene.settings;
    if args.json {
        let table: Vec<_> = scaling
            .iter()
            .map(|r| {
                let speedup = r.samples_per_sec() / base;
                serde_json::json!({
                    "threads": r.threads,
                    "samples_per_sec": r.samples_per_sec(),
                    "speedup": speedup,
                    "efficiency": speedup / r.threads as f64,
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
        if !scaling.is_empty() {
            println!("threads  M samples/s  speedup  efficiency");
            for r in &scaling {
                let speedup = r.samples_per_sec() / base;
                println!(
                    "{:>7}  {:>11.3}  {:>7.2}  {:>9.0}%",
                    r.threads,
                    r.samples_per_sec() / 1e6,
                    speedup,
                    100.0 * speedup / r.threads as f64
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
