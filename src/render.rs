//! Rendering an image: cutting it into tiles, spreading them over a rayon pool, and taking
//! every sample's random numbers from its own seed. The only module that knows threads.

use crate::bvh::TraversalStack;
use crate::film::{Film, to_fixed};
use crate::integrator;
use crate::math::{Color, PixelRect};
use crate::sampling::Sampler;
use crate::scene::{Scene, Shading};
use rayon::prelude::*;
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

/// Renders the scene's window (the whole image unless it sets a crop). `progress` is called with the number of samples of each tile
/// as it finishes, from worker threads.
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Film, RenderStats), rayon::ThreadPoolBuildError> {
    let start = Instant::now();
    let run = || render_tiles(scene, options.tile, progress);
    let (film, rays, threads) = match options.threads {
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build()?;
            let (film, rays) = pool.install(run);
            (film, rays, n)
        }
        None => {
            let (film, rays) = run();
            (film, rays, rayon::current_num_threads())
        }
    };
    let stats = RenderStats {
        samples: scene.total_samples(),
        rays,
        wall: start.elapsed(),
        threads,
    };
    Ok((film, stats))
}

fn render_tiles(scene: &Scene, edge: u32, progress: &(dyn Fn(u64) + Sync)) -> (Film, u64) {
    let s = &scene.settings;
    let window = s.window;
    let list = window.tiles(edge);
    let done: Vec<(Vec<[u64; 3]>, u64)> = list
        .par_iter()
        .map(|tile| {
            let out = render_tile(scene, tile);
            progress(tile.area() * u64::from(s.samples_per_pixel));
            out
        })
        .collect();
    let mut film = Film::new(window.width, window.height, s.samples_per_pixel);
    let mut rays = 0;
    for (tile, (sums, tile_rays)) in list.iter().zip(done) {
        film.put_tile(tile.x0 - window.x0, tile.y0 - window.y0, tile.width, &sums);
        rays += tile_rays;
    }
    (film, rays)
}

/// Renders one tile: fixed-point sums per pixel (row-major) and the rays traced.
pub fn render_tile(scene: &Scene, tile: &PixelRect) -> (Vec<[u64; 3]>, u64) {
    let mut sums = Vec::with_capacity((tile.width * tile.height) as usize);
    let mut rays = 0u64;
    let mut stack = scene.new_stack();
    for y in tile.y0..tile.y0 + tile.height {
        for x in tile.x0..tile.x0 + tile.width {
            let mut acc = [0u64; 3];
            for sample in 0..scene.settings.samples_per_pixel {
                let (c, r) = sample_pixel(scene, x, y, sample, &mut stack);
                acc[0] += to_fixed(c.x);
                acc[1] += to_fixed(c.y);
                acc[2] += to_fixed(c.z);
                rays += u64::from(r);
            }
            sums.push(acc);
        }
    }
    (sums, rays)
}

/// One camera sample of pixel `(x, y)` (top row is `y = 0`): its radiance and ray count.
/// Everything random in it is drawn from the sample's own generator.
#[inline]
pub fn sample_pixel(
    scene: &Scene,
    x: u32,
    y: u32,
    sample: u32,
    stack: &mut TraversalStack,
) -> (Color, u32) {
    let s = &scene.settings;
    let mut rng = Sampler::for_sample(s.seed, x, y, sample);
    let (du, dv) = if s.jitter {
        (rng.uniform(), rng.uniform())
    } else {
        (0.0, 0.0)
    };
    // The book's mapping: u = (i + du) / (width - 1), v counted up from the bottom row.
    let j = s.height - 1 - y;
    let u = (x as f32 + du) / (s.width.max(2) - 1) as f32;
    let v = (j as f32 + dv) / (s.height.max(2) - 1) as f32;
    if s.shading == Shading::Uv {
        return (Color::new(u, v, 0.25), 0);
    }
    let ray = scene.camera.ray(u, v, &mut rng);
    let r = integrator::radiance(scene, ray, &mut rng, stack);
    (r.color, r.rays)
}
