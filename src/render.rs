//! Running a job: cutting its region into tiles, spreading them over a rayon pool, folding
//! finished tiles into the job's state in batches, and handing out snapshots to save. The only
//! module that knows threads; what a sample is, is the integrator's business.

use crate::film::{Film, to_fixed};
use crate::integrator::PixelEvaluator;
use crate::job::{Job, JobState, SampleRange};
use crate::math::{Color, PixelRect};
use crate::scene::Scene;
use crate::simd::{self, Isa, Kernel};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Default tile edge in pixels.
pub const DEFAULT_TILE: u32 = 16;

/// How to schedule a render. None of these change the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderOptions {
    /// Worker threads; `None` uses rayon's global pool (one per core).
    pub threads: Option<usize>,
    /// Tile edge in pixels.
    pub tile: u32,
    /// The SIMD path of the hot code; every path gives the same bytes.
    pub simd: simd::Path,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            threads: None,
            tile: DEFAULT_TILE,
            simd: simd::Path::best(),
        }
    }
}

/// Counts and timing of a finished render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderStats {
    pub samples: u64,
    pub rays: u64,
    pub wall: Duration,
    pub threads: usize,
}

impl RenderStats {
    pub fn samples_per_sec(&self) -> f64 {
        self.samples as f64 / self.wall.as_secs_f64().max(1e-9)
    }
    pub fn mrays_per_sec(&self) -> f64 {
        self.rays as f64 / self.wall.as_secs_f64().max(1e-9) / 1e6
    }
    pub fn rays_per_sample(&self) -> f64 {
        self.rays as f64 / self.samples.max(1) as f64
    }
}

/// A callback that sees the job's state, e.g. to save a checkpoint.
pub type Snapshot<'a> = &'a mut dyn FnMut(&JobState);

/// What a running job reports to and hears from its caller.
pub struct Control<'a> {
    /// Set (e.g. by a signal handler) to stop taking new tiles; the job returns early.
    pub stop: &'a AtomicBool,
    /// Called as each tile finishes, with its worth in samples of the job's estimated work:
    /// the calls add up to the samples left, but a costly tile counts for more than its own
    /// samples and a cheap one for less, so the running total tracks the time spent.
    pub on_samples: &'a (dyn Fn(u64) + Sync),
    /// Called with the state at most every `interval` while the job runs, e.g. to save a
    /// checkpoint; a zero interval calls it after every tile.
    pub on_snapshot: Option<(Snapshot<'a>, Duration)>,
}

/// Renders the whole image (the scene's window, all its samples).
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Film, RenderStats), rayon::ThreadPoolBuildError> {
    let mut state = JobState::new(Job::whole(scene), options.tile);
    let stop = AtomicBool::new(false);
    let control = Control {
        stop: &stop,
        on_samples: progress,
        on_snapshot: None,
    };
    let stats = render_job(scene, options, &mut state, control)?;
    Ok((state.into_film(), stats))
}

/// Renders what `state` still lacks, tile by tile over a rayon pool, until it is complete or
/// `control.stop` is set. Finished tiles are folded into `state` on the calling thread, so a
/// snapshot is always consistent.
pub fn render_job(
    scene: &Scene,
    options: &RenderOptions,
    state: &mut JobState,
    mut control: Control,
) -> Result<RenderStats, rayon::ThreadPoolBuildError> {
    let start = Instant::now();
    let pool = match options.threads {
        Some(n) => Some(rayon::ThreadPoolBuilder::new().num_threads(n).build()?),
        None => None,
    };
    let threads = pool
        .as_ref()
        .map_or_else(rayon::current_num_threads, |p| p.current_num_threads());
    let tiles = state.job.region.tiles(state.tile);
    let unfinished = state.unfinished_tiles();
    let todo = match &pool {
        Some(p) => p.install(|| plan(scene, unfinished, options.simd)),
        None => plan(scene, unfinished, options.simd),
    };
    let (sender, receiver) = std::sync::mpsc::channel::<Vec<(usize, TileResult)>>();
    let (stop, on_samples) = (control.stop, control.on_samples);
    let mut samples = 0u64;
    let mut rays = 0u64;
    std::thread::scope(|scope| {
        let work = move || {
            todo.par_iter().for_each_init(
                || TileBatch::new(sender.clone()),
                |batch, task| {
                    if stop.load(Ordering::Relaxed) {
                        return;
                    }
                    let result = render_tile(scene, &task.tile, task.range, options.simd);
                    on_samples(task.worth);
                    batch.push(task.index, result);
                },
            );
        };
        scope.spawn(move || match &pool {
            Some(p) => p.install(work),
            None => work(),
        });
        let mut last_snapshot = Instant::now();
        for (index, result) in receiver.into_iter().flatten() {
            let tile = tiles[index];
            samples += tile.area() * u64::from(state.job.samples.len() - state.done[index]);
            rays += result.rays;
            state.add_tile(index, &tile, &result.sums);
            if let Some((snapshot, interval)) = control.on_snapshot.as_mut()
                && last_snapshot.elapsed() >= *interval
            {
                snapshot(state);
                last_snapshot = Instant::now();
            }
        }
    });
    Ok(RenderStats {
        samples,
        rays,
        wall: start.elapsed(),
        threads,
    })
}

/// A tile to render: its index in the job, its pixels and samples, and the progress it is
/// worth, in samples of the job's estimated work (see `plan`).
struct Task {
    index: usize,
    tile: PixelRect,
    range: SampleRange,
    worth: u64,
}

/// Samples of each tile a cost probe renders (at most four pixels of it).
const PROBE_SAMPLES: u32 = 2;
/// Below this many samples per pixel a render is too short to be worth probing.
const PROBE_FROM_SPP: u32 = 8;

/// Gives each unfinished tile a share of the remaining samples in proportion to its
/// estimated cost, so progress (and the ETA drawn from it) follows the work rather than the
/// sample count: a tile of sky costs a fraction of a tile of ground. Tiles keep their raster
/// order: costliest first measured 0.7% slower on one thread (neighbouring tiles share
/// caches and branch history), and rayon's stealing already ends a render evenly.
fn plan(scene: &Scene, todo: Vec<(usize, PixelRect, SampleRange)>, simd: simd::Path) -> Vec<Task> {
    let samples = |tile: &PixelRect, range: &SampleRange| tile.area() * u64::from(range.len());
    let probe = todo
        .first()
        .is_some_and(|(_, _, r)| r.len() >= PROBE_FROM_SPP);
    let costs: Vec<f64> = todo
        .par_iter()
        .map(|(_, tile, range)| {
            let per_sample = if probe {
                probe_cost(scene, tile, simd)
            } else {
                1.0
            };
            per_sample * samples(tile, range) as f64
        })
        .collect();
    let total_samples: u64 = todo.iter().map(|(_, t, r)| samples(t, r)).sum();
    let total_cost: f64 = costs.iter().sum();
    // Worth by cumulative rounding, so the worths add up to exactly the samples left.
    let (mut cost_so_far, mut given) = (0.0, 0u64);
    (todo.iter().zip(&costs))
        .map(|(&(index, tile, range), &cost)| {
            cost_so_far += cost;
            let upto = if total_cost > 0.0 && total_cost.is_finite() {
                ((cost_so_far / total_cost) * total_samples as f64).round() as u64
            } else {
                given + samples(&tile, &range)
            };
            let worth = upto.min(total_samples).saturating_sub(given);
            given += worth;
            Task {
                index,
                tile,
                range,
                worth,
            }
        })
        .collect()
}

/// The estimated cost of one of `tile`'s samples, in units of a bounce ray: renders a few
/// samples of up to four pixels at its centre and counts their rays; a sample costs about
/// half a bounce ray besides (its camera ray, mostly against a short candidate list, and its
/// set-up). What the probe renders is thrown away.
fn probe_cost(scene: &Scene, tile: &PixelRect, simd: simd::Path) -> f64 {
    let (w, h) = (tile.width.min(2), tile.height.min(2));
    let probe = PixelRect {
        x0: tile.x0 + (tile.width - w) / 2,
        y0: tile.y0 + (tile.height - h) / 2,
        width: w,
        height: h,
    };
    let range = SampleRange {
        start: 0,
        end: PROBE_SAMPLES,
    };
    let rays = render_tile(scene, &probe, range, simd).rays;
    let samples = (probe.area() * u64::from(PROBE_SAMPLES)).max(1);
    0.5 + (rays as f64 / samples as f64 - 1.0).max(0.0)
}

/// Finished tiles on their way from a worker to the thread folding them into the job's
/// state, sent a few at a time (at most `HOLD` late): a message per tile would wake that
/// thread, and switch it in on a worker's core, a thousand times a second. Whatever is left
/// is sent when the batch is dropped, as its worker finishes.
struct TileBatch {
    sender: std::sync::mpsc::Sender<Vec<(usize, TileResult)>>,
    tiles: Vec<(usize, TileResult)>,
    since: Instant,
}

impl TileBatch {
    /// The longest a finished tile waits before it is sent.
    const HOLD: Duration = Duration::from_millis(20);

    fn new(sender: std::sync::mpsc::Sender<Vec<(usize, TileResult)>>) -> Self {
        Self {
            sender,
            tiles: Vec::new(),
            since: Instant::now(),
        }
    }

    fn push(&mut self, index: usize, result: TileResult) {
        self.tiles.push((index, result));
        if self.since.elapsed() >= Self::HOLD {
            self.send();
        }
    }

    fn send(&mut self) {
        if !self.tiles.is_empty() {
            // The receiver outlives the workers; a failed send cannot happen.
            let _ = self.sender.send(std::mem::take(&mut self.tiles));
        }
        self.since = Instant::now();
    }
}

impl Drop for TileBatch {
    fn drop(&mut self) {
        self.send();
    }
}

/// One finished tile: fixed-point sums per pixel (row-major) and the rays traced.
#[derive(Clone, Debug)]
pub struct TileResult {
    pub sums: Vec<[u64; 3]>,
    pub rays: u64,
}

/// Renders the samples `range` of every pixel of one tile, compiled for the SIMD path `simd`.
pub fn render_tile(
    scene: &Scene,
    tile: &PixelRect,
    range: SampleRange,
    simd: simd::Path,
) -> TileResult {
    simd::dispatch(simd, TileKernel { scene, tile, range })
}

/// `render_tile`'s work, for `simd::dispatch` to compile for each path.
struct TileKernel<'a> {
    scene: &'a Scene,
    tile: &'a PixelRect,
    range: SampleRange,
}

impl Kernel for TileKernel<'_> {
    type Output = TileResult;

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) -> TileResult {
        render_tile_on(isa, self.scene, self.tile, self.range)
    }
}

#[inline(always)]
fn render_tile_on<I: Isa>(
    isa: I,
    scene: &Scene,
    tile: &PixelRect,
    range: SampleRange,
) -> TileResult {
    let mut pixels = PixelEvaluator::for_tile(isa, scene, tile);
    let mut sums = Vec::with_capacity(tile.area() as usize);
    let mut rays = 0u64;
    for y in tile.y0..tile.y0 + tile.height {
        for x in tile.x0..tile.x0 + tile.width {
            let mut acc = [0u64; 3];
            pixels.evaluate(x, y, range, |c: Color, r: u32| {
                acc[0] += to_fixed(c.x);
                acc[1] += to_fixed(c.y);
                acc[2] += to_fixed(c.z);
                rays += u64::from(r);
            });
            sums.push(acc);
        }
    }
    TileResult { sums, rays }
}
