//! The command line as typed: clap's view of commands, flags and their values, before any of
//! them is checked against the others (that is `settings`).

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use tessera::render;

pub const DEFAULT_SCENE: &str = "scenes/cover.toml";

#[derive(Parser)]
#[command(
    name = "tessera",
    about = "A deterministic multicore path tracer of Ray Tracing in One Weekend"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Render a scene file to an image (.png, .ppm or .exr).
    Render(RenderArgs),
    /// Benchmark a standard workload (validated by its image hash) or a scene: samples/s
    /// with their spread over 1, 2, 4, … threads, as text or JSON; compare or chart results.
    Bench(BenchArgs),
    /// Combine partial renders (shards, sample ranges) into one image, byte-identical to a
    /// single render of the same scene and settings.
    Merge {
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
    },
    /// Print the recipe an image carries: the scene, the settings, the build, the hash of
    /// its exact sums.
    Info {
        image: PathBuf,
        /// The recipe as tessera wrote it (JSON).
        #[arg(long)]
        json: bool,
    },
    /// Render an image again from the recipe it carries (no scene file needed) and say
    /// whether it is bit for bit what the recipe makes: exit 0 `identical`, 1 `differs`.
    Reproduce(ReproduceArgs),
    /// Print the RMSE and PSNR between two images of equal size (PNG, PPM, EXR or JPEG).
    Compare { a: PathBuf, b: PathBuf },
    /// The benchmark results kept in the local database: list them, import others'.
    Results(ResultsArgs),
}

/// The results database's place, shared by `bench` and `results`.
#[derive(Args)]
pub struct DbArg {
    /// The results database [default: $XDG_DATA_HOME/tessera/results.db, else
    /// ~/.local/share/tessera/results.db].
    #[arg(long, global = true, env = "TESSERA_DB", value_name = "PATH")]
    pub db: Option<PathBuf>,
}

#[derive(Args)]
pub struct ResultsArgs {
    #[command(flatten)]
    pub db: DbArg,
    #[command(subcommand)]
    pub command: ResultsCommand,
}

#[derive(Subcommand)]
pub enum ResultsCommand {
    /// The runs, newest first: when, machine, CPU, build, workload, threads, samples/s with
    /// their spread, validation.
    List {
        /// Only this workload (`quick`, `cover`, `custom`).
        #[arg(long)]
        workload: Option<String>,
        /// Only this machine: a machine id's start, or part of a CPU model.
        #[arg(long)]
        machine: Option<String>,
        /// Only builds of this commit (its start).
        #[arg(long)]
        commit: Option<String>,
        /// At most this many runs.
        #[arg(long, value_name = "N")]
        limit: Option<u32>,
    },
    /// Add results (JSON files of `bench --out`) from other machines; a result already in
    /// the database is not added twice, and one bad file adds nothing.
    Import {
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
    },
    /// One row per machine and build: the median samples/s of its runs at their thread
    /// count, the spread, and per thread; best first. Only `valid` runs unless --all.
    Rank {
        #[arg(long, default_value = "cover")]
        workload: String,
        /// Count unvalidated and invalid runs too.
        #[arg(long)]
        all: bool,
    },
    /// Two sets of runs thread count by thread count, each a run id, a machine (`m-…`) or a
    /// commit (its start); `run:`, `machine:` or `commit:` before it says which.
    Compare {
        a: String,
        b: String,
        /// The workload (default: that of A's newest run).
        #[arg(long)]
        workload: Option<String>,
        /// Only runs on this SIMD path (default: that of A's newest run).
        #[arg(long)]
        simd: Option<String>,
    },
    /// One machine's speed over commits, flagging a drop beyond the runs' own spread.
    History {
        /// The machine: a machine id's start, or part of a CPU model.
        #[arg(long, required = true)]
        machine: String,
        #[arg(long, default_value = "cover")]
        workload: String,
        /// The thread count (default: that of the machine's newest run).
        #[arg(long)]
        threads: Option<i64>,
        /// The SIMD path (default: that of the machine's newest run).
        #[arg(long)]
        simd: Option<String>,
    },
    /// A self-contained HTML report (no script, nothing fetched): the ranking and charts of
    /// samples/s by machine, speed against threads, and history over commits.
    Report {
        /// The HTML file to write.
        #[arg(short, long, required = true)]
        output: PathBuf,
        #[arg(long, default_value = "cover")]
        workload: String,
        /// Count unvalidated and invalid runs too.
        #[arg(long)]
        all: bool,
    },
    /// Every result, oldest first, as JSON lines (one result per line).
    Export {
        /// JSON lines (the one format).
        #[arg(long, required = true)]
        jsonl: bool,
    },
}

#[derive(Args)]
pub struct ReproduceArgs {
    /// A PNG or EXR image tessera wrote.
    pub image: PathBuf,
    /// Also write the re-rendered image here (with its recipe).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Write the recipe's scene file here and stop.
    #[arg(long, value_name = "FILE")]
    pub extract_scene: Option<PathBuf>,
    /// Worker threads (default: one per core); the image does not change.
    #[arg(long)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub simd: SimdArg,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(Args)]
pub struct SceneArgs {
    /// Scene file (TOML).
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    /// Image width in pixels; the height keeps the scene's aspect ratio.
    #[arg(long)]
    pub width: Option<u32>,
    /// Samples per pixel.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub simd: SimdArg,
}

/// `--simd`, shared by `render` and `bench`.
#[derive(Args)]
pub struct SimdArg {
    /// SIMD path of the hot code: auto (the fastest this CPU runs), portable, avx2 or
    /// avx512. Every path gives the same image; one the CPU lacks is refused.
    #[arg(
        long = "simd",
        env = "TESSERA_SIMD",
        default_value = "auto",
        value_name = "PATH"
    )]
    pub name: String,
}

#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output image; its extension picks the format (default: the scene's name with .png).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Maximum ray segments per path.
    #[arg(long)]
    pub depth: Option<u32>,
    /// Seed of every random number of the render.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Tile edge in pixels (scheduling only; the image does not change).
    #[arg(long, default_value_t = render::DEFAULT_TILE)]
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
    #[arg(long, default_value_t = 10.0, value_name = "SECS")]
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

/// How to watch a render.
#[derive(Args)]
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
    #[arg(long, value_name = "SECS")]
    pub preview_every: Option<f64>,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum SplitArg {
    Samples,
    Rows,
}

#[derive(Args)]
pub struct BenchArgs {
    /// Scene file of a custom workload (default: the standard workload --workload names).
    pub scene: Option<PathBuf>,
    /// Standard workload: `quick` (default, seconds) or `cover` (the full book cover);
    /// `--list` describes them. Its image is checked against the hash it must produce.
    #[arg(long, conflicts_with = "scene")]
    pub workload: Option<String>,
    /// Image width of a custom workload.
    #[arg(long, requires = "scene")]
    pub width: Option<u32>,
    /// Samples per pixel of a custom workload.
    #[arg(long, requires = "scene")]
    pub spp: Option<u32>,
    /// Threads of the headline result (default: every CPU).
    #[arg(long)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub simd: SimdArg,
    /// Measured renders per thread count; the median is reported with min and max.
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
    /// Renders before measuring, not counted.
    #[arg(long, default_value_t = 1)]
    pub warmup: u32,
    /// Measure only the headline thread count, not 1, 2, 4, … every CPU.
    #[arg(long)]
    pub no_scaling: bool,
    /// Print the JSON result instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the JSON result to FILE (atomically).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub db: DbArg,
    /// Do not record the result in the results database.
    #[arg(long)]
    pub no_save: bool,
    /// Compare two JSON results of the same workload, thread count by thread count.
    #[arg(long, num_args = 2, value_names = ["OLD", "NEW"], conflicts_with_all = ["scene", "workload"])]
    pub compare: Option<Vec<PathBuf>>,
    /// Draw samples/s against threads of JSON results as an SVG chart: `--chart OUT.svg A.json [B.json …]`.
    #[arg(long, num_args = 2.., value_names = ["SVG", "RESULT"], conflicts_with_all = ["scene", "workload", "compare"])]
    pub chart: Option<Vec<PathBuf>>,
    /// List the standard workloads.
    #[arg(long)]
    pub list: bool,
    /// Render each standard workload once and write the workloads file with their image
    /// hashes (after a deliberate change of the image): `--write-workloads benches/workloads.toml`.
    #[arg(long, value_name = "FILE")]
    pub write_workloads: Option<PathBuf>,
}
