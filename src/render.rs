//! Running a job: cutting its region into tiles (and, for a watched render, its samples into
//! passes), spreading them over a rayon pool, folding finished tiles into the job's state in
//! batches, and handing its state out to be saved or shown. The only module that knows the
//! workers' threads; what a sample is, is the integrator's business.

use crate::film::{Film, to_fixed};
use crate::integrator::{self, PixelEvaluator};
use crate::job::{Job, JobState, SampleRange};
use crate::math::{Color, PixelRect};
use crate::scene::{Scene, Shading};
use crate::simd::{self, Isa, Kernel};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
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

/// A callback that saves the job's state now and then, e.g. as a checkpoint.
pub type ProgressSaver<'a> = &'a mut dyn FnMut(&JobState);

/// What a running job reports to and hears from its caller.
pub struct Control<'a> {
    /// Set (e.g. by a signal handler) to stop: no new tile is taken and the busy ones are
    /// given up at their next pixel; the job returns early.
    pub stop: &'a AtomicBool,
    /// Called as each tile finishes, with its worth in samples of the job's estimated work:
    /// the calls add up to the samples left, but a costly tile counts for more than its own
    /// samples and a cheap one for less, so the running total tracks the time spent.
    pub on_samples: &'a (dyn Fn(u64) + Sync),
    /// Called with the state at most every `interval` while the job runs, e.g. to save a
    /// checkpoint; a zero interval calls it after every tile.
    pub on_progress: Option<(ProgressSaver<'a>, Duration)>,
    /// Renders the samples in progressive passes over the whole region (see `passes`)
    /// instead of each tile's samples at once, so the image sharpens everywhere together.
    /// The sums, and so the image, are the same either way.
    pub progressive: bool,
    /// Told, on the thread that folds tiles, what each batch of finished tiles changed.
    pub watch: Option<&'a mut dyn Watch>,
}

/// Sees a job's state as it grows, from the one thread that folds finished tiles into it
/// (a live preview). Its calls hold up only that thread, never a worker.
pub trait Watch {
    /// Before any tile is rendered: the state the job starts from (resumed or new).
    fn started(&mut self, state: &JobState, progress: &Progress);
    /// After the tiles `folded` (indices into the region's tiles) were added to `state`.
    fn folded(&mut self, state: &JobState, folded: &[usize], progress: &Progress);
}

/// How far a running job has come, for a watcher.
pub struct Progress<'a> {
    /// Samples and rays rendered by this run (a resumed job's earlier ones not counted).
    pub samples: u64,
    pub rays: u64,
    /// Time since the run started.
    pub elapsed: Duration,
    /// Estimated work done and in all, in samples weighted by each tile's cost (see `plan`):
    /// their ratio is the honest fraction of the run's time spent.
    pub work_done: u64,
    pub work_total: u64,
    /// The pass being rendered (0-based; `passes.len()` once all are done), and every pass's
    /// end, in samples per pixel counted from the job's first sample.
    pub pass: usize,
    pub passes: &'a [u32],
    /// The tiles the workers are rendering now.
    pub active: &'a ActiveTiles,
}

/// The tile each worker is rendering, one cache line per worker so that workers never share
/// a line: a worker writes its slot as it takes a tile and once it has handed it in.
pub struct ActiveTiles {
    slots: Vec<ActiveSlot>,
}

#[repr(align(128))]
struct ActiveSlot(AtomicUsize);

impl ActiveTiles {
    fn new(threads: usize) -> Self {
        Self {
            slots: (0..threads.max(1))
                .map(|_| ActiveSlot(AtomicUsize::new(0)))
                .collect(),
        }
    }

    fn set(&self, tile: Option<usize>) {
        let worker = rayon::current_thread_index().unwrap_or(0) % self.slots.len();
        self.slots[worker]
            .0
            .store(tile.map_or(0, |t| t + 1), Ordering::Relaxed);
    }

    /// The tiles being rendered now, by index, in worker order.
    pub fn tiles(&self) -> Vec<usize> {
        (self.slots.iter())
            .filter_map(|s| s.0.load(Ordering::Relaxed).checked_sub(1))
            .collect()
    }
}

/// The ends of a progressive render's passes over samples `0..len` of the job: 1, 4, 16,
/// 64, … samples per pixel, then `len`. Each pass quadruples the samples, so it halves the
/// noise, and an image is there after a first pass of one sample. Passes cost little, but
/// not nothing: a pixel visited again starts its samples afresh (its first camera ray made
/// without the overlap the next ones get), so doubling (ten passes for 500 samples) measured
/// 2.3% slower than one pass, where quadrupling visits a pixel log₄(len) times.
pub fn passes(len: u32) -> Vec<u32> {
    let mut ends: Vec<u32> = std::iter::successors(Some(1u32), |n| n.checked_mul(4))
        .take_while(|&n| n < len)
        .collect();
    ends.push(len);
    ends
}

/// Renders the whole image (the scene's window, all its samples).
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Film, RenderStats), rayon::ThreadPoolBuildError> {
    let stop = AtomicBool::new(false);
    let done = render_unless(scene, options, progress, &stop)?;
    Ok(done.expect("a render nothing stops is finished"))
}

/// `render`, given up (`None`) soon after `stop` is set.
pub fn render_unless(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
    stop: &AtomicBool,
) -> Result<Option<(Film, RenderStats)>, rayon::ThreadPoolBuildError> {
    let mut state = JobState::new(Job::whole(scene), options.tile);
    let control = Control {
        stop,
        on_samples: progress,
        on_progress: None,
        progressive: false,
        watch: None,
    };
    let stats = render_job(scene, options, &mut state, control)?;
    Ok(state.is_complete().then(|| (state.into_film(), stats)))
}

/// Renders what `state` still lacks, tile by tile over a rayon pool, until it is complete or
/// `control.stop` is set. Finished tiles are folded into `state` on the calling thread, so
/// what is saved or shown is always consistent.
pub fn render_job(
    scene: &Scene,
    options: &RenderOptions,
    state: &mut JobState,
    mut control: Control,
) -> Result<RenderStats, rayon::ThreadPoolBuildError> {
    let start = Instant::now();
    let tiles = state.job.region.tiles(state.tile);
    // A pool holds no more threads than there are tiles to give them: the threads past that
    // would only look for work, and thousands of them looking (`--threads 4096` for a small
    // image) cost seconds. Which thread renders a tile changes no byte.
    let pool = match options.threads {
        Some(n) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(n.min(tiles.len()).max(1))
                .build()?,
        ),
        None => None,
    };
    let threads = pool
        .as_ref()
        .map_or_else(rayon::current_num_threads, |p| p.current_num_threads());
    let ends = if control.progressive {
        passes(state.job.samples.len())
    } else {
        vec![state.job.samples.len()]
    };
    let todo = match &pool {
        Some(p) => p.install(|| plan(scene, state, &ends, options.simd, control.stop)),
        None => plan(scene, state, &ends, options.simd, control.stop),
    };
    let work_total: u64 = todo.iter().flatten().map(|t| t.worth).sum();
    let mut left_in_pass: Vec<usize> = todo.iter().map(Vec::len).collect();
    let active = ActiveTiles::new(threads);
    let watched = control.watch.is_some();
    let (sender, receiver) = std::sync::mpsc::channel::<Vec<Finished>>();
    let (stop, on_samples) = (control.stop, control.on_samples);
    let (mut samples, mut rays, mut work_done) = (0u64, 0u64, 0u64);
    let progress = |samples, rays, work_done, left: &[usize]| Progress {
        samples,
        rays,
        elapsed: start.elapsed(),
        work_done,
        work_total,
        pass: left.iter().position(|&n| n > 0).unwrap_or(left.len()),
        passes: &ends,
        active: &active,
    };
    if let Some(watch) = control.watch.as_mut() {
        watch.started(state, &progress(0, 0, 0, &left_in_pass));
    }
    let mut folded = Vec::new();
    std::thread::scope(|scope| {
        let active = &active;
        let work = move || {
            for pass in &todo {
                if stop.load(Ordering::Relaxed) {
                    return;
                }
                pass.par_iter().for_each_init(
                    || TileBatch::new(sender.clone()),
                    |batch, task| {
                        if stop.load(Ordering::Relaxed) {
                            return;
                        }
                        if watched {
                            active.set(Some(task.index));
                        }
                        let Some(result) = render_tile_unless(
                            scene,
                            &task.tile,
                            task.range,
                            options.simd,
                            Some(stop),
                        ) else {
                            if watched {
                                active.set(None);
                            }
                            return;
                        };
                        on_samples(task.worth);
                        batch.push(Finished {
                            index: task.index,
                            pass: task.pass,
                            done_after: task.done_after,
                            worth: task.worth,
                            result,
                        });
                        // Cleared after the hand-in, not before: the folding thread, woken
                        // by it, reads the slots at once, and on a busy machine it ran
                        // before this worker took its next tile, so that a one-thread
                        // render's viewer showed no tile at all.
                        if watched {
                            active.set(None);
                        }
                    },
                );
            }
        };
        scope.spawn(move || match &pool {
            Some(p) => p.install(work),
            None => work(),
        });
        let mut last_saved = Instant::now();
        for batch in receiver {
            folded.clear();
            for f in batch {
                let tile = tiles[f.index];
                samples += tile.area() * u64::from(f.done_after - state.done[f.index]);
                rays += f.result.rays;
                work_done += f.worth;
                left_in_pass[f.pass] -= 1;
                state.add_samples(f.index, &tile, &f.result.sums, f.done_after);
                folded.push(f.index);
            }
            if let Some(watch) = control.watch.as_mut() {
                watch.folded(
                    state,
                    &folded,
                    &progress(samples, rays, work_done, &left_in_pass),
                );
            }
            if let Some((save, interval)) = control.on_progress.as_mut()
                && last_saved.elapsed() >= *interval
            {
                save(state);
                last_saved = Instant::now();
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

/// A tile to render: its index in the job, its pixels and samples, the pass it belongs to,
/// the job's samples it has after it (counted from the job's first), and the progress it is
/// worth, in samples of the job's estimated work (see `plan`).
struct Task {
    index: usize,
    tile: PixelRect,
    range: SampleRange,
    pass: usize,
    done_after: u32,
    worth: u64,
}

/// A rendered task on its way to the folding thread.
struct Finished {
    index: usize,
    pass: usize,
    done_after: u32,
    worth: u64,
    result: TileResult,
}

/// Samples of each tile a cost probe renders (at most four pixels of it).
const PROBE_SAMPLES: u32 = 2;
/// Below this many samples per pixel a render is too short to be worth probing.
const PROBE_FROM_SPP: u32 = 8;

/// The tasks of each pass, whose ends `ends` are counted in samples from the job's first: a
/// tile with fewer samples than a pass's end renders up to it in that pass. Each task gets a
/// share of the remaining samples in proportion to its estimated cost, so progress (and the
/// ETA drawn from it) follows the work rather than the sample count: a tile of sky costs a
/// fraction of a tile of ground. Tiles keep their raster order: costliest first measured 0.7%
/// slower on one thread (neighbouring tiles share caches and branch history), and rayon's
/// stealing already ends a render evenly. The probes look at `stop` as a render does: once it
/// is set, the tiles left unprobed cost a sample each (a probe of a costly scene's tiles
/// once ran on for minutes past a stop, at no look at all).
fn plan(
    scene: &Scene,
    state: &JobState,
    ends: &[u32],
    simd: simd::Path,
    stop: &AtomicBool,
) -> Vec<Vec<Task>> {
    let samples = |tile: &PixelRect, range: &SampleRange| tile.area() * u64::from(range.len());
    let unfinished = state.unfinished_tiles();
    let probe = unfinished
        .first()
        .is_some_and(|(_, _, r)| r.len() >= PROBE_FROM_SPP);
    // Each unfinished tile's cost per sample, measured once whatever the passes.
    let per_sample: Vec<f64> = unfinished
        .par_iter()
        .map(|(_, tile, _)| {
            if probe {
                probe_cost(scene, tile, simd, stop).unwrap_or(1.0)
            } else {
                1.0
            }
        })
        .collect();
    let start = state.job.samples.start;
    let mut passes: Vec<Vec<(usize, PixelRect, SampleRange, f64)>> = Vec::new();
    let mut done: Vec<u32> = unfinished.iter().map(|(_, _, r)| r.start - start).collect();
    for &end in ends {
        let mut pass = Vec::new();
        for (k, &(index, tile, _)) in unfinished.iter().enumerate() {
            if done[k] < end {
                let range = SampleRange {
                    start: start + done[k],
                    end: start + end,
                };
                pass.push((
                    index,
                    tile,
                    range,
                    per_sample[k] * samples(&tile, &range) as f64,
                ));
                done[k] = end;
            }
        }
        passes.push(pass);
    }
    let all = || passes.iter().flatten();
    let total_samples: u64 = all().map(|(_, t, r, _)| samples(t, r)).sum();
    let total_cost: f64 = all().map(|p| p.3).sum();
    // Worth by cumulative rounding, so the worths add up to exactly the samples left.
    let (mut cost_so_far, mut given) = (0.0, 0u64);
    (passes.iter().enumerate())
        .map(|(pass, tasks)| {
            (tasks.iter())
                .map(|&(index, tile, range, cost)| {
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
                        pass,
                        done_after: range.end - start,
                        worth,
                    }
                })
                .collect()
        })
        .collect()
}

/// The estimated cost of one of `tile`'s samples, in units of a bounce ray: renders a few
/// samples of up to four pixels at its centre and counts their rays; a sample costs about
/// half a bounce ray besides (its camera ray, mostly against a short candidate list, and its
/// set-up). What the probe renders is thrown away. None once `stop` is set.
fn probe_cost(scene: &Scene, tile: &PixelRect, simd: simd::Path, stop: &AtomicBool) -> Option<f64> {
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
    if stop.load(Ordering::Relaxed) {
        return None;
    }
    let rays = render_tile_unless(scene, &probe, range, simd, Some(stop))?.rays;
    let samples = (probe.area() * u64::from(PROBE_SAMPLES)).max(1);
    Some(0.5 + (rays as f64 / samples as f64 - 1.0).max(0.0))
}

/// Finished tiles on their way from a worker to the thread folding them into the job's
/// state, sent a few at a time (at most `HOLD` late): a message per tile would wake that
/// thread, and switch it in on a worker's core, a thousand times a second. Whatever is left
/// is sent when the batch is dropped, as its worker finishes.
struct TileBatch {
    sender: std::sync::mpsc::Sender<Vec<Finished>>,
    tiles: Vec<Finished>,
    since: Instant,
}

impl TileBatch {
    /// The longest a finished tile waits before it is sent.
    const HOLD: Duration = Duration::from_millis(20);

    fn new(sender: std::sync::mpsc::Sender<Vec<Finished>>) -> Self {
        Self {
            sender,
            tiles: Vec::new(),
            since: Instant::now(),
        }
    }

    fn push(&mut self, finished: Finished) {
        self.tiles.push(finished);
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
    render_tile_unless(scene, tile, range, simd, None)
        .expect("a tile without a stop flag is always finished")
}

/// `render_tile`, given up (`None`) at the next pixel once `stop` is set: a render at a
/// million samples per pixel stops within about a pixel's work, not a tile's.
pub fn render_tile_unless(
    scene: &Scene,
    tile: &PixelRect,
    range: SampleRange,
    simd: simd::Path,
    stop: Option<&AtomicBool>,
) -> Option<TileResult> {
    // Two kernels, each compiled on its own for every path: the first book's scenes run
    // the code they always ran, untouched by The Next Week's.
    if scene.needs_full_paths() {
        simd::dispatch(
            simd,
            TileKernel::<true> {
                scene,
                tile,
                range,
                stop,
            },
        )
    } else {
        simd::dispatch(
            simd,
            TileKernel::<false> {
                scene,
                tile,
                range,
                stop,
            },
        )
    }
}

/// The samples of a pixel rendered between two looks at a stop flag: more than any book
/// figure's pixel has, so that an ordinary render looks once a pixel.
const STOP_RUN: u32 = 4096;

/// The samples of a pixel rendered between two looks at a stop flag, for paths of at most
/// `max_depth` rays: `STOP_RUN`, or as many as keep within `integrator::STOP_RAYS`, at
/// least one. A sample's path may be 65,536 bounces (in fog of albedo 1, every one is), so
/// 4,096 such samples were a minute between looks.
fn stop_run(max_depth: u32) -> u32 {
    let most = integrator::STOP_RAYS / (u64::from(max_depth) + 1);
    most.clamp(1, u64::from(STOP_RUN)) as u32
}

/// `render_tile`'s work, for `simd::dispatch` to compile for each path; `FULL`: a scene
/// that needs *The Next Week*'s paths (`Scene::needs_full_paths`).
struct TileKernel<'a, const FULL: bool> {
    scene: &'a Scene,
    tile: &'a PixelRect,
    range: SampleRange,
    stop: Option<&'a AtomicBool>,
}

impl<const FULL: bool> Kernel for TileKernel<'_, FULL> {
    type Output = Option<TileResult>;

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) -> Option<TileResult> {
        render_tile_on::<I, FULL>(isa, self.scene, self.tile, self.range, self.stop)
    }
}

#[inline(always)]
fn render_tile_on<I: Isa, const FULL: bool>(
    isa: I,
    scene: &Scene,
    tile: &PixelRect,
    range: SampleRange,
    stop: Option<&AtomicBool>,
) -> Option<TileResult> {
    let stopped = || stop.is_some_and(|stop| stop.load(Ordering::Relaxed));
    let settings = &scene.settings;
    if FULL && scene.batches_paths() && settings.shading == Shading::Path && settings.max_depth > 0
    {
        // Paths sixteen at a time (see `integrator::trace_tile`): the same sums.
        let mut sums = vec![[0u64; 3]; tile.area() as usize];
        let mut rays = 0u64;
        let run = if stop.is_some() {
            stop_run(settings.max_depth)
        } else {
            u32::MAX
        };
        let finished = integrator::trace_tile(isa, scene, tile, range, stopped, run, |i, c, r| {
            add_sample(&mut sums[i], c);
            rays += u64::from(r);
        });
        return finished.then_some(TileResult { sums, rays });
    }
    let run = stop_run(settings.max_depth);
    let mut pixels = PixelEvaluator::for_tile(isa, scene, tile);
    let mut sums = Vec::with_capacity(tile.area() as usize);
    let mut rays = 0u64;
    for y in tile.y0..tile.y0 + tile.height {
        for x in tile.x0..tile.x0 + tile.width {
            if stopped() {
                return None;
            }
            let mut acc = [0u64; 3];
            // A pixel's samples in runs (`stop_run`) when something may stop the tile, so
            // that a pixel of billions of samples, or of very long paths, stops too; the
            // sums are the same (each sample's value is its own, and integers add in any
            // order).
            let mut start = range.start;
            while start < range.end {
                let end = match stop {
                    Some(_) => start.saturating_add(run).min(range.end),
                    None => range.end,
                };
                pixels.evaluate_as::<FULL>(x, y, SampleRange { start, end }, |c: Color, r: u32| {
                    add_sample(&mut acc, c);
                    rays += u64::from(r);
                });
                start = end;
                if start < range.end && stopped() {
                    return None;
                }
            }
            sums.push(acc);
        }
    }
    Some(TileResult { sums, rays })
}

/// Adds one sample's value to its pixel's sums, saturating as `film::add_run` does: a
/// scene may ask for 2^32 - 1 samples of a pixel, and 2^20 at the brightest value a sample
/// keeps already make 2^64, which wrapped round to black in one render and stayed the
/// brightest value when the same samples were rendered in parts and merged. Below that, the
/// same sums as plain addition.
#[inline(always)]
fn add_sample(acc: &mut [u64; 3], c: Color) {
    acc[0] = acc[0].saturating_add(to_fixed(c.x));
    acc[1] = acc[1].saturating_add(to_fixed(c.y));
    acc[2] = acc[2].saturating_add(to_fixed(c.z));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::add_sums;
    use crate::scene::Overrides;
    use std::path::Path;

    /// A pixel of 2^20 samples at the brightest value a sample keeps (a background of
    /// 10^7) sums to the brightest value, as its samples rendered in two parts and added
    /// do, in each of the three ways a tile is traced (the first book's, The Next Week's,
    /// a few quads' paths sixteen at a time): the sum once wrapped round to 0, a black
    /// pixel, where the parts merged gave white.
    #[test]
    fn a_pixel_s_sums_past_64_bits_are_the_brightest_however_its_samples_are_split() {
        let samples = 1u32 << 20;
        let head = format!(
            "[image]\nwidth = 1\nheight = 1\nsamples_per_pixel = {samples}\nmax_depth = 1\n\
             [materials.g]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n"
        );
        let far = "[[spheres]]\ncenter = [0.0, 0.0, -100.0]\nradius = 0.001\nmaterial = \"g\"\n";
        let quad = "[[quads]]\ncorner = [0.0, 0.0, -100.0]\nu = [0.001, 0.0, 0.0]\n\
                    v = [0.0, 0.001, 0.0]\nmaterial = \"g\"\n";
        let gradient = "[background]\ntype = \"gradient\"\nbottom = [1e7, 1e7, 1e7]\n\
                        top = [1e7, 1e7, 1e7]\n";
        let uniform = "[background]\ntype = \"uniform\"\ncolor = [1e7, 1e7, 1e7]\n";
        let tile = PixelRect::full(1, 1);
        for (what, body) in [
            ("the first book's", format!("{gradient}{far}")),
            ("The Next Week's", format!("{uniform}{far}")),
            ("a few quads'", format!("{uniform}{quad}")),
        ] {
            let text = format!("{head}{body}");
            let scene = Scene::parse(&text, Path::new("s.toml"), &Overrides::default()).unwrap();
            let range = |start, end| SampleRange { start, end };
            let whole = render_tile(&scene, &tile, range(0, samples), simd::Path::best());
            let mut parts = vec![[0u64; 3]];
            for half in [range(0, samples / 2), range(samples / 2, samples)] {
                let part = render_tile(&scene, &tile, half, simd::Path::best());
                add_sums(&mut parts, tile, &part.sums, tile);
            }
            assert_eq!(whole.sums, vec![[u64::MAX; 3]], "{what}");
            assert_eq!(whole.sums, parts, "{what}");
        }
    }

    /// A pool asked for more threads than the image has tiles holds one a tile (4,096 threads
    /// for a 4x3 image of 16-pixel tiles took 11 s of looking for work; its 12 tiles take
    /// 0.05 s), and renders the same sums.
    #[test]
    fn a_pool_holds_no_more_threads_than_tiles() {
        let text = "[image]\nwidth = 64\nheight = 48\nsamples_per_pixel = 1\nmax_depth = 2\n";
        let scene = Scene::parse(text, Path::new("s.toml"), &Overrides::default()).unwrap();
        let run = |threads| {
            let options = RenderOptions {
                threads: Some(threads),
                ..RenderOptions::default()
            };
            render(&scene, &options, &|_| {}).unwrap()
        };
        let (one, stats) = run(1);
        assert_eq!(stats.threads, 1);
        let (many, stats) = run(4096);
        assert_eq!(stats.threads, 12);
        assert_eq!(one, many);
    }

    /// The plan probes each tile unless the render is already stopped: a stop set before
    /// (or while) it probes leaves every tile left at a sample's cost, its worth its samples.
    /// The probes once ignored the stop: a scene of tiles whose paths take minutes each (a
    /// fog of 65,536 bounces among 30,000 coincident spheres) probed on for minutes past a
    /// Ctrl-C or a reproduce's time budget.
    #[test]
    fn a_plan_probes_no_tile_once_the_render_is_stopped() {
        // 32x16 pixels of two tiles: the left one sees a wall, whose paths bounce, the right
        // one the sky.
        let text = "[image]\nwidth = 32\nheight = 16\nsamples_per_pixel = 16\nmax_depth = 50\n\
                    [camera]\nlookfrom = [0.0, 0.0, 0.0]\nlookat = [0.0, 0.0, -1.0]\n\
                    vfov_deg = 40.0\n\
                    [materials.w]\ntype = \"lambertian\"\nalbedo = [0.9, 0.9, 0.9]\n\
                    [[quads]]\ncorner = [-100.0, -100.0, -1.0]\nu = [100.0, 0.0, 0.0]\n\
                    v = [0.0, 200.0, 0.0]\nmaterial = \"w\"\n";
        let scene = Scene::parse(text, Path::new("wall.toml"), &Overrides::default()).unwrap();
        let state = JobState::new(Job::whole(&scene), 16);
        let worths = |stop: bool| -> Vec<u64> {
            let stop = AtomicBool::new(stop);
            let tasks = plan(&scene, &state, &[16], simd::Path::best(), &stop);
            tasks.iter().flatten().map(|t| t.worth).collect()
        };
        let probed = worths(false);
        assert!(probed[0] > probed[1], "{probed:?}");
        assert_eq!(worths(true), vec![16 * 16 * 16; 2]);
    }

    #[test]
    fn a_stop_is_looked_at_within_stop_rays_however_long_the_paths() {
        // The books' depths keep a look a pixel; the longest paths allowed, a look a sample.
        assert_eq!(stop_run(50), 1285);
        for depth in [1, 50, 1000, 4096, 65_536, u32::MAX] {
            let run = stop_run(depth);
            assert!((1..=STOP_RUN).contains(&run), "{depth}: {run}");
            let rays = u64::from(run) * (u64::from(depth) + 1);
            assert!(rays <= integrator::STOP_RAYS || run == 1, "{depth}: {rays}");
        }
    }
}
