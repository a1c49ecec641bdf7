//! Rendering an image: cutting it into tiles, spreading them over a rayon pool, and taking
//! every sample's random numbers from its own seed. The only module that knows threads.

use crate::bvh::{Candidates, TraversalStack};
use crate::film::{Film, add_sums, to_fixed};
use crate::integrator;
use crate::math::{Color, PixelRect};
use crate::ray::Ray;
use crate::sampling::{PixelSeed, Sampler};
use crate::scene::{Scene, Shading};
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
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            threads: None,
            tile: DEFAULT_TILE,
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

/// A range of sample indices `start..end`, rendered for every pixel of a region.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SampleRange {
    pub start: u32,
    pub end: u32,
}

impl SampleRange {
    pub fn len(&self) -> u32 {
        self.end.saturating_sub(self.start)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A unit of rendering: the pixels of `region` (inside the scene's window) over the sample
/// indices `samples`. A whole render is the window over `0..samples_per_pixel`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Job {
    pub region: PixelRect,
    pub samples: SampleRange,
}

impl Job {
    /// The whole image the scene describes.
    pub fn whole(scene: &Scene) -> Self {
        Job {
            region: scene.settings.window,
            samples: SampleRange {
                start: 0,
                end: scene.settings.samples_per_pixel,
            },
        }
    }
}

/// A job's accumulated state: the sums so far and how many samples of the job's range each
/// tile has finished. Tiles finish whole, so the state is exact at every point, and adding the
/// rest of the samples later gives the same integers as rendering them in one go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Progress {
    pub job: Job,
    /// Tile edge in pixels; `done` follows `job.region.tiles(tile)`.
    pub tile: u32,
    /// Samples finished per tile, counted from `job.samples.start`.
    pub done: Vec<u32>,
    /// Fixed-point sums over the region, row-major.
    pub sums: Vec<[u64; 3]>,
}

impl Progress {
    pub fn new(job: Job, tile: u32) -> Self {
        let tile = tile.max(1);
        Progress {
            done: vec![0; job.region.tiles(tile).len()],
            sums: vec![[0; 3]; job.region.area() as usize],
            job,
            tile,
        }
    }

    pub fn is_complete(&self) -> bool {
        self.done.iter().all(|&d| d >= self.job.samples.len())
    }

    /// Samples of the whole job, over all pixels.
    pub fn total_samples(&self) -> u64 {
        self.job.region.area() * u64::from(self.job.samples.len())
    }

    /// Samples finished, over all pixels.
    pub fn finished_samples(&self) -> u64 {
        samples_done(
            self.job.region,
            self.tile,
            &self.done,
            self.job.samples.len(),
        )
    }

    /// Samples still to render.
    pub fn remaining_samples(&self) -> u64 {
        self.total_samples() - self.finished_samples()
    }

    /// How much of the job is done, in percent.
    pub fn percent_done(&self) -> f64 {
        percent(self.finished_samples(), self.total_samples())
    }

    /// Extends the job to more samples (progressive rendering): finished tiles keep their sums.
    pub fn extend_to(&mut self, end: u32) {
        self.job.samples.end = self.job.samples.end.max(end);
    }

    fn add_tile(&mut self, index: usize, tile: &PixelRect, sums: &[[u64; 3]]) {
        add_sums(&mut self.sums, self.job.region, sums, *tile);
        self.done[index] = self.job.samples.len();
    }

    /// The finished image of the region. Panics if the job is not complete.
    pub fn film(&self) -> Film {
        assert!(self.is_complete(), "film of an unfinished job");
        Film {
            width: self.job.region.width,
            height: self.job.region.height,
            samples_per_pixel: self.job.samples.len(),
            sums: self.sums.clone(),
        }
    }
}

/// Samples finished over `region` when its tiles of edge `tile` have each done `done[i]` of
/// `len` samples.
pub fn samples_done(region: PixelRect, tile: u32, done: &[u32], len: u32) -> u64 {
    region
        .tiles(tile)
        .iter()
        .zip(done)
        .map(|(t, &d)| t.area() * u64::from(d.min(len)))
        .sum()
}

/// `done` of `total`, in percent (0 of nothing is 0%).
pub fn percent(done: u64, total: u64) -> f64 {
    100.0 * done as f64 / total.max(1) as f64
}

/// A callback that sees the job's state, e.g. to save a checkpoint.
pub type Snapshot<'a> = &'a mut dyn FnMut(&Progress);

/// What a running job reports to and hears from its caller.
pub struct Control<'a> {
    /// Set (e.g. by a signal handler) to stop taking new tiles; the job returns early.
    pub stop: &'a AtomicBool,
    /// Called with the number of samples of each finished tile.
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
    let mut state = Progress::new(Job::whole(scene), options.tile);
    let stop = AtomicBool::new(false);
    let control = Control {
        stop: &stop,
        on_samples: progress,
        on_snapshot: None,
    };
    let stats = render_job(scene, options, &mut state, control)?;
    Ok((state.film(), stats))
}

/// Renders what `state` still lacks, tile by tile over a rayon pool, until it is complete or
/// `control.stop` is set. Finished tiles are folded into `state` on the calling thread, so a
/// snapshot is always consistent.
pub fn render_job(
    scene: &Scene,
    options: &RenderOptions,
    state: &mut Progress,
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
    let todo: Vec<(usize, PixelRect, SampleRange)> = tiles
        .iter()
        .enumerate()
        .filter(|(i, _)| state.done[*i] < state.job.samples.len())
        .map(|(i, t)| {
            let from = state.job.samples.start + state.done[i];
            (
                i,
                *t,
                SampleRange {
                    start: from,
                    end: state.job.samples.end,
                },
            )
        })
        .collect();
    let (sender, receiver) = std::sync::mpsc::channel::<Vec<(usize, TileResult)>>();
    let (stop, on_samples) = (control.stop, control.on_samples);
    let mut samples = 0u64;
    let mut rays = 0u64;
    std::thread::scope(|scope| {
        let work = move || {
            todo.par_iter().for_each_init(
                || TileBatch::new(sender.clone()),
                |batch, (i, tile, range)| {
                    if stop.load(Ordering::Relaxed) {
                        return;
                    }
                    let result = render_tile_samples(scene, tile, *range);
                    on_samples(tile.area() * u64::from(range.len()));
                    batch.push(*i, result);
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

/// Finished tiles on their way from a worker to the thread folding them into the image,
/// sent a few at a time: one message per tile woke that thread, and switched it in on a
/// worker's core, a thousand times a second. Whatever is left is sent when the batch is
/// dropped, as its worker finishes.
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

/// Renders all the scene's samples of one tile.
pub fn render_tile(scene: &Scene, tile: &PixelRect) -> TileResult {
    let all = SampleRange {
        start: 0,
        end: scene.settings.samples_per_pixel,
    };
    render_tile_samples(scene, tile, all)
}

/// Renders the samples `range` of every pixel of one tile.
pub fn render_tile_samples(scene: &Scene, tile: &PixelRect, range: SampleRange) -> TileResult {
    let mut sums = Vec::with_capacity(tile.area() as usize);
    let mut rays = 0u64;
    let mut stack = scene.new_stack();
    let path = scene.settings.shading == Shading::Path && scene.settings.max_depth > 0;
    // Camera rays of one tile can reach only a few spheres: path tracing tests those alone.
    let primary = path.then(|| scene.camera_candidates(tile)).flatten();
    for y in tile.y0..tile.y0 + tile.height {
        for x in tile.x0..tile.x0 + tile.width {
            let seed = PixelSeed::new(scene.settings.seed, x, y);
            let mut acc = [0u64; 3];
            let mut add = |c: Color, r: u32| {
                acc[0] += to_fixed(c.x);
                acc[1] += to_fixed(c.y);
                acc[2] += to_fixed(c.z);
                rays += u64::from(r);
            };
            if path {
                trace_pixel_paths(scene, x, y, seed, range, primary.as_ref(), &mut stack, add);
            } else {
                for sample in range.start..range.end {
                    let (c, r) = trace_sample(scene, x, y, seed.sample(sample), &mut stack);
                    add(c, r);
                }
            }
            sums.push(acc);
        }
    }
    TileResult { sums, rays }
}

/// Path traces samples `range` of pixel `(x, y)`, handing each one's radiance and ray count
/// to `add` in sample order. Software pipelining: the next sample's camera ray is made
/// before this sample's path is traced. It depends on nothing the path computes and has no
/// branch of its own, so the processor works it out while the path waits on its long chains
/// of arithmetic, and no mispredicted branch of the path can undo it. It comes after this
/// sample's camera hit, not before: made first, it reached the head of the reorder window
/// before its own chain was done and held up what followed (measured 2–4% slower). Each
/// sample's own arithmetic is exactly `trace_sample`'s.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn trace_pixel_paths(
    scene: &Scene,
    x: u32,
    y: u32,
    seed: PixelSeed,
    range: SampleRange,
    primary: Option<&Candidates>,
    stack: &mut TraversalStack,
    mut add: impl FnMut(Color, u32),
) {
    if range.start >= range.end {
        return;
    }
    let mut next = camera_sample(scene, x, y, seed.sample(range.start));
    for sample in range.start..range.end {
        let (ray, mut rng) = next.clone();
        let hit = integrator::camera_hit(scene, &ray, primary, stack);
        if sample + 1 < range.end {
            next = camera_sample(scene, x, y, seed.sample(sample + 1));
        }
        let r = integrator::path_trace_from(scene, ray, hit, &mut rng, stack);
        add(r.color, r.rays);
    }
}

/// The camera ray of one sample of pixel `(x, y)`, drawn with the sample's generator `rng`,
/// and the generator after those draws.
#[inline(always)]
fn camera_sample(scene: &Scene, x: u32, y: u32, mut rng: Sampler) -> (Ray, Sampler) {
    let (u, v) = film_coordinates(scene, x, y, &mut rng);
    (scene.camera.ray(u, v, &mut rng), rng)
}

/// One camera sample of pixel `(x, y)` (top row is `y = 0`): its radiance and ray count,
/// traced on its own through the hierarchy. Everything random in it is drawn from the
/// sample's own generator.
pub fn sample_pixel(
    scene: &Scene,
    x: u32,
    y: u32,
    sample: u32,
    stack: &mut TraversalStack,
) -> (Color, u32) {
    let rng = Sampler::for_sample(scene.settings.seed, x, y, sample);
    trace_sample(scene, x, y, rng, stack)
}

/// One camera sample of pixel `(x, y)` drawn with the sample's generator `rng`, traced
/// through the hierarchy.
#[inline]
fn trace_sample(
    scene: &Scene,
    x: u32,
    y: u32,
    mut rng: Sampler,
    stack: &mut TraversalStack,
) -> (Color, u32) {
    if scene.settings.shading == Shading::Uv {
        let (u, v) = film_coordinates(scene, x, y, &mut rng);
        return (Color::new(u, v, 0.25), 0);
    }
    let (ray, mut rng) = camera_sample(scene, x, y, rng);
    let r = integrator::radiance(scene, ray, &mut rng, stack);
    (r.color, r.rays)
}

/// Where one sample of pixel `(x, y)` falls on the film, in the book's coordinates, drawing
/// its jitter from `rng`.
#[inline]
fn film_coordinates(scene: &Scene, x: u32, y: u32, rng: &mut Sampler) -> (f32, f32) {
    let s = &scene.settings;
    let (du, dv) = if s.jitter {
        (rng.uniform(), rng.uniform())
    } else {
        (0.0, 0.0)
    };
    // The book's mapping, v counted up from the bottom row.
    let j = s.height - 1 - y;
    scene.film_point(x as f32 + du, j as f32 + dv)
}
