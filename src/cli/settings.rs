//! The command line checked and turned into what runs: each command's arguments validated
//! against each other and against the scene, and every output checked writable, before any
//! work starts.

use super::args::{BenchArgs, RenderArgs, SceneArgs, SimdArg, SplitArg};
use super::bench::workload::{self, Workload};
use anyhow::{Result, bail};
use std::path::{Path, PathBuf};
use std::time::Duration;
use tessera::atomic_file::check_writable;
use tessera::image_file::Format;
use tessera::job::Job;
use tessera::partial::RenderId;
use tessera::render::{self, RenderOptions};
use tessera::scene::{Overrides, Scene};
use tessera::shard::{self, Shard, Split, parse_samples};
use tessera::simd;

/// Where a render's result goes.
pub enum Output {
    /// The finished image, in the format its extension names.
    Image(PathBuf),
    /// A part file for `tessera merge`: the render is one part (a shard or a sample range).
    Part(PathBuf),
}

impl Output {
    pub fn path(&self) -> &Path {
        match self {
            Output::Image(p) | Output::Part(p) => p,
        }
    }
}

/// Where and how often a render saves its progress.
pub struct CheckpointSettings {
    pub path: PathBuf,
    /// The longest time between saves; zero saves after every tile.
    pub every: Duration,
}

/// A render, ready to run.
pub struct RenderSettings {
    pub scene: Scene,
    pub options: RenderOptions,
    /// What this process renders: the scene's window over all its samples, or one part.
    pub job: Job,
    /// The render the job belongs to (the whole image's samples per pixel included).
    pub render: RenderId,
    pub output: Output,
    pub checkpoint: Option<CheckpointSettings>,
    pub quiet: bool,
}

impl RenderSettings {
    pub fn new(args: RenderArgs) -> Result<Self> {
        let options = render_options(args.scene.threads, args.tile, args.scene.simd.path()?)?;
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
        let path = args
            .output
            .unwrap_or_else(|| default_output(&args.scene.scene));
        // A shard or sample range always writes a part, even one that happens to be the
        // whole render (a Slurm array of one task), so a merge can take it.
        let output = if shard.is_some() || samples.is_some() {
            Output::Part(path)
        } else {
            Format::from_path(&path)?;
            Output::Image(path)
        };
        // Refuse an output that cannot be written before spending minutes on the render.
        check_writable(output.path())?;
        let checkpoint = args
            .checkpoint
            .map(|path| CheckpointSettings { path, every });
        if let Some(c) = &checkpoint
            && !c.path.exists()
        {
            check_writable(&c.path)?;
        }
        Ok(Self {
            render: RenderId::of(&scene, target),
            scene,
            options,
            job,
            output,
            checkpoint,
            quiet: args.quiet,
        })
    }
}

/// What `tessera bench` is asked to do, checked.
pub enum BenchMode {
    Measure(Box<Measure>),
    Compare {
        old: PathBuf,
        new: PathBuf,
    },
    Chart {
        out: PathBuf,
        results: Vec<PathBuf>,
    },
    List,
    WriteWorkloads {
        path: PathBuf,
        threads: usize,
        simd: simd::Path,
    },
}

/// A measurement, ready to run.
pub struct Measure {
    pub workload: Workload,
    /// Threads of the headline result.
    pub threads: usize,
    /// The thread counts of the scaling table: 1, 2, 4, … and every CPU; empty for none.
    pub scaling: Vec<usize>,
    /// Measured renders per thread count.
    pub repeat: u32,
    pub warmup: u32,
    pub json: bool,
    pub out: Option<PathBuf>,
    /// The SIMD path of every render.
    pub simd: simd::Path,
}

impl BenchMode {
    pub fn new(args: BenchArgs) -> Result<Self> {
        if let Some(files) = args.compare {
            let [old, new] = <[PathBuf; 2]>::try_from(files)
                .map_err(|_| anyhow::anyhow!("--compare takes two result files"))?;
            return Ok(Self::Compare { old, new });
        }
        if let Some(mut files) = args.chart {
            let out = files.remove(0);
            check_writable(&out)?;
            return Ok(Self::Chart {
                out,
                results: files,
            });
        }
        if args.list {
            return Ok(Self::List);
        }
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = args.threads.unwrap_or(cpus);
        let simd = args.simd.path()?;
        render_options(Some(threads), render::DEFAULT_TILE, simd)?;
        if let Some(path) = args.write_workloads {
            check_writable(&path)?;
            return Ok(Self::WriteWorkloads {
                path,
                threads,
                simd,
            });
        }
        let workload = match &args.scene {
            Some(scene) => {
                let overrides = Overrides {
                    width: args.width,
                    samples_per_pixel: args.spp,
                    ..Overrides::default()
                };
                Workload::custom(scene, &overrides)?
            }
            None => {
                let default = workload::standard().first().map(|w| w.name.clone());
                let name = args.workload.or(default).unwrap_or_default();
                Workload::named(&name)?
            }
        };
        if let Some(out) = &args.out {
            check_writable(out)?;
        }
        // 1, 2, 4, … below every CPU, then every CPU.
        let mut scaling: Vec<usize> = std::iter::successors(Some(1usize), |n| n.checked_mul(2))
            .take_while(|&n| n < cpus)
            .collect();
        scaling.push(cpus);
        Ok(Self::Measure(Box::new(Measure {
            workload,
            threads,
            scaling: if args.no_scaling { Vec::new() } else { scaling },
            repeat: args.repeat.max(1),
            warmup: args.warmup,
            json: args.json,
            out: args.out,
            simd,
        })))
    }
}

impl SimdArg {
    /// The SIMD path `--simd` (or `TESSERA_SIMD`) names, if this CPU runs it.
    fn path(&self) -> Result<simd::Path> {
        simd::Path::choose(&self.name).map_err(|e| anyhow::anyhow!("--simd: {e}"))
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

/// Scheduling options, checked.
pub fn render_options(
    threads: Option<usize>,
    tile: u32,
    simd: simd::Path,
) -> Result<RenderOptions> {
    if threads == Some(0) {
        bail!("--threads must be at least 1");
    }
    if tile == 0 {
        bail!("--tile must be at least 1 pixel");
    }
    Ok(RenderOptions {
        threads,
        tile,
        simd,
    })
}

/// The scene's file name with `.png`.
fn default_output(scene: &Path) -> PathBuf {
    let stem = scene.file_stem().map_or("render".into(), |s| s.to_owned());
    let mut name = stem;
    name.push(".png");
    PathBuf::from(name)
}
