//! The command line checked and turned into what runs: each command's arguments validated
//! against each other and against the scene, and every output checked writable, before any
//! work starts.

use super::args::{
    BenchArgs, PreviewArgs, RenderArgs, ResultsArgs, ResultsCommand, SceneArgs, SimdArg, SplitArg,
};
use super::bench::workload::{self, Workload};
use super::results::ResultsMode;
use super::results::db::{self, Filter};
use anyhow::{Result, bail};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::time::Duration;
use tessera::atomic_file::check_writable;
use tessera::image_file::Format;
use tessera::job::Job;
use tessera::math::PixelRect;
use tessera::partial::RenderId;
use tessera::recipe::Source;
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

/// Seconds between writes of the preview file, unless `--preview-every` says otherwise.
const PREVIEW_EVERY_SECS: f64 = 2.0;

/// How a render is watched: a live viewer, a preview file, both or neither.
#[derive(Default)]
pub struct PreviewSettings {
    /// The viewer's listener, bound before the render starts.
    pub listener: Option<TcpListener>,
    /// Serve the final frame after the render until Ctrl-C.
    pub hold: bool,
    /// The preview file and the time between its writes.
    pub file: Option<(PathBuf, Duration)>,
}

impl PreviewSettings {
    pub fn is_on(&self) -> bool {
        self.listener.is_some() || self.file.is_some()
    }

    /// Checks `--preview`, `--preview-hold`, `--preview-file` and `--preview-every`, and
    /// binds the viewer.
    fn new(args: &PreviewArgs) -> Result<Self> {
        let file = match &args.preview_file {
            Some(path) => {
                if Format::from_path(path)? != Format::Png {
                    bail!("--preview-file must name a .png file");
                }
                check_writable(path)?;
                let every = seconds(
                    "--preview-every",
                    args.preview_every.unwrap_or(PREVIEW_EVERY_SECS),
                )?;
                if every.is_zero() {
                    bail!("--preview-every must be more than 0 seconds");
                }
                Some((path.clone(), every))
            }
            None => None,
        };
        if file.is_none() && args.preview_every.is_some() {
            bail!("--preview-every needs --preview-file");
        }
        let listener = match &args.preview {
            Some(spec) => Some(bind_preview(spec)?),
            None => None,
        };
        Ok(Self {
            listener,
            hold: args.preview_hold,
            file,
        })
    }
}

/// A number of seconds from the command line, checked.
fn seconds(flag: &str, secs: f64) -> Result<Duration> {
    if !(secs >= 0.0 && secs.is_finite()) {
        bail!("{flag} must be a number of seconds, 0 or more");
    }
    // More seconds than a Duration holds (about 585 billion years) means never.
    Ok(Duration::try_from_secs_f64(secs).unwrap_or(Duration::MAX))
}

/// The address `--preview=SPEC` names: `ADDR:PORT` or `[IPv6]:PORT` with an IP address,
/// `localhost:PORT`, or a bare `PORT` (on 127.0.0.1). Names are not looked up: a viewer
/// listens on this machine's own addresses.
fn preview_address(spec: &str) -> Result<SocketAddr> {
    let spec = spec.trim();
    if let Ok(port) = spec.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    if let Ok(addr) = spec.parse::<SocketAddr>() {
        return Ok(addr);
    }
    match spec.rsplit_once(':') {
        Some((host, port)) if host.eq_ignore_ascii_case("localhost") => {
            if let Ok(port) = port.parse::<u16>() {
                return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
            }
        }
        _ => {}
    }
    bail!(
        "--preview: `{spec}` is not an address; write ADDR:PORT (127.0.0.1:8080), \
         [::1]:8080, localhost:8080 or a port alone"
    )
}

/// Binds the viewer's listener now, so that an address in use, one that is not this
/// machine's or a port without permission is an error before the render starts.
fn bind_preview(spec: &str) -> Result<TcpListener> {
    let addr = preview_address(spec)?;
    TcpListener::bind(addr).map_err(|e| {
        use std::io::ErrorKind;
        let why = match e.kind() {
            ErrorKind::AddrInUse => {
                "is in use by another program; choose another port, or leave it out for a free one"
                    .to_owned()
            }
            ErrorKind::PermissionDenied => {
                format!("needs a permission this user lacks (ports below 1024 need root): {e}")
            }
            ErrorKind::AddrNotAvailable => format!("is not an address of this machine: {e}"),
            _ => format!("cannot be listened on: {e}"),
        };
        anyhow::anyhow!("--preview: {addr} {why}")
    })
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
    pub preview: PreviewSettings,
    /// What the job is, in a few words: the whole image, a crop, a shard or samples.
    pub job_label: String,
    /// The scene file as given.
    pub scene_file: PathBuf,
    pub quiet: bool,
}

impl RenderSettings {
    pub fn new(args: RenderArgs) -> Result<Self> {
        // `--preview 8080` takes 8080 as the scene file: say what was meant.
        let scene_arg = args.scene.scene.to_string_lossy();
        if !args.scene.scene.exists() && preview_address(&scene_arg).is_ok() {
            bail!(
                "`{scene_arg}` looks like an address, not a scene file; to choose the viewer's \
                 address write --preview={scene_arg}"
            );
        }
        let options = render_options(args.scene.threads, args.tile, args.scene.simd.path()?)?;
        let every = seconds("--checkpoint-every", args.checkpoint_every)?;
        let (scene, source) = load(&args.scene, args.depth, args.seed)?;
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
        let job_label = match (shard, samples) {
            (Some(s), _) => format!("shard {}/{}", s.index, s.count),
            (None, Some(r)) => format!("samples {}..{}", r.start, r.end),
            (None, None)
                if job.region != PixelRect::full(scene.settings.width, scene.settings.height) =>
            {
                let r = job.region;
                format!("crop {}x{} at ({}, {})", r.width, r.height, r.x0, r.y0)
            }
            (None, None) => "whole image".to_owned(),
        };
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
        // Last, so that the port is taken only once everything else is known to be right.
        let preview = PreviewSettings::new(&args.preview)?;
        Ok(Self {
            render: RenderId {
                recipe: (!args.no_provenance).then_some(source),
                ..RenderId::of(&scene, target)
            },
            scene,
            options,
            job,
            output,
            checkpoint,
            preview,
            job_label,
            scene_file: args.scene.scene,
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
    /// Whether `--simd` (or `TESSERA_SIMD`) named it, rather than `auto`.
    pub simd_chosen: bool,
    /// The results database to record the result in; `None`: not recorded.
    pub save: Option<SaveTo>,
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
        let simd_chosen = args.simd.name != "auto";
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
        let save = match (args.no_save, args.db.db) {
            (true, _) => None,
            (false, Some(path)) => Some(SaveTo { path, chosen: true }),
            (false, None) => db::default_path().map(|path| SaveTo {
                path,
                chosen: false,
            }),
        };
        Ok(Self::Measure(Box::new(Measure {
            workload,
            threads,
            scaling: if args.no_scaling { Vec::new() } else { scaling },
            repeat: args.repeat.max(1),
            warmup: args.warmup,
            json: args.json,
            out: args.out,
            simd,
            simd_chosen,
            save,
        })))
    }
}

/// Where `bench` records its result.
pub struct SaveTo {
    pub path: PathBuf,
    /// Named by `--db` or `TESSERA_DB`: a database that cannot be used is an error. The
    /// default one is only a warning when it cannot be created (a read-only home, a
    /// container); one that exists but cannot be used is an error all the same.
    pub chosen: bool,
}

impl ResultsMode {
    pub fn new(args: ResultsArgs) -> Result<Self> {
        let db = db::resolve(args.db.db)?;
        Ok(match args.command {
            ResultsCommand::List {
                workload,
                machine,
                commit,
                limit,
            } => Self::List {
                db,
                filter: Filter {
                    workload,
                    machine,
                    commit,
                    limit,
                },
            },
            ResultsCommand::Import { files } => Self::Import { db, files },
            ResultsCommand::Rank { workload, all } => Self::Rank { db, workload, all },
            ResultsCommand::Compare {
                a,
                b,
                workload,
                simd,
            } => Self::Compare {
                db,
                a,
                b,
                workload,
                simd,
            },
            ResultsCommand::History {
                machine,
                workload,
                threads,
                simd,
            } => Self::History {
                db,
                machine,
                workload,
                threads,
                simd,
            },
            ResultsCommand::Export { jsonl: _ } => Self::Export { db },
            ResultsCommand::Report {
                output,
                workload,
                all,
            } => {
                check_writable(&output)?;
                Self::Report {
                    db,
                    output,
                    workload,
                    all,
                }
            }
        })
    }
}

impl SimdArg {
    /// The SIMD path `--simd` (or `TESSERA_SIMD`) names, if this CPU runs it.
    pub(super) fn path(&self) -> Result<simd::Path> {
        simd::Path::choose(&self.name).map_err(|e| anyhow::anyhow!("--simd: {e}"))
    }
}

/// The scene file, parsed with the command line's overrides, and its recipe source: the
/// text parsed is the text recorded.
fn load(args: &SceneArgs, depth: Option<u32>, seed: Option<u64>) -> Result<(Scene, Source)> {
    let overrides = Overrides {
        width: args.width,
        samples_per_pixel: args.spp,
        max_depth: depth,
        seed,
    };
    let text = Scene::read_text(&args.scene)?;
    let scene = Scene::parse(&text, &args.scene, &overrides)?;
    Ok((scene, Source::new(&args.scene, &text, overrides)))
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
