//! What rendering a recipe costs, judged three times: from what it claims before its scene
//! is built, from a few of its paths traced against as many of the book cover's, and, as
//! it renders, by the time four covers take on this machine. A stranger's recipe can hide
//! cost from the first two (a ray into a million coincident spheres in a corner the probe
//! misses); the third stops it anyway.

use crate::error::{Error, Result};
use crate::job::SampleRange;
use crate::math::PixelRect;
use crate::recipe::{Effective, Recipe};
use crate::render::render_tile;
use crate::scene::Scene;
use crate::simd;
use crate::text::{count, significant, terminal_safe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The book cover's work: 1200x800 pixels at 500 samples per pixel, up to 50 bounces.
pub const COVER_RAYS: f64 = 1200.0 * 800.0 * 500.0 * 50.0;
/// The book cover's samples: 1200x800 pixels at 500 per pixel.
pub const COVER_SAMPLES: f64 = 1200.0 * 800.0 * 500.0;
/// The most work a recipe gets rendered unasked, in book covers (a few minutes on two cores).
pub const UNASKED_COVERS: f64 = 4.0;
/// The most pixels a recipe gets rendered unasked, whatever its samples: 8192x4096, whose
/// film alone (three 64-bit sums a pixel) is 800 MB. A recipe may claim 2^28 pixels, a
/// 6.4 GB film, at one sample each: little work, but more memory than many machines have.
pub const UNASKED_PIXELS: u64 = 1 << 25;

/// The probe's pixels: one in each cell of a 32x32 grid over the window, at a place in the
/// cell drawn from a fixed hash, one sample each, its index drawn too.
const PROBE_GRID: u32 = 32;
/// How long the recipe's paths are traced at most for the probe (checked after each path).
const PROBE_TIME: Duration = Duration::from_millis(300);
/// How many times the cover's and the recipe's paths are traced in turn, the least time of
/// each kept.
const PROBE_ROUNDS: usize = 3;
/// The longest path the probe traces: the books' 50 and more. A recipe asking for longer
/// paths is judged as if each of its paths went on at the probe's cost per bounce.
const PROBE_DEPTH: u32 = 64;
/// How much longer than four covers' time on this machine a render may take before it is
/// stopped: the probe's measure is rough, and so is a render's speed on a busy machine.
const TIME_SLACK: f64 = 2.0;
/// The least time a render is given before it is stopped.
const MIN_TIME: Duration = Duration::from_secs(60);
/// The environment variable that sets the time a render is given, in seconds.
pub const BUDGET_VARIABLE: &str = "TESSERA_REPRODUCE_SECONDS";

/// The work a recipe asks for: first from what it claims, then (`measured`) at what its
/// paths cost.
pub struct Work {
    pub claimed: Effective,
    /// In book covers' rays, every path its longest, each ray costing what one of the
    /// cover's does.
    pub covers: f64,
    /// The pixels it renders (its window's).
    pub pixels: u64,
    /// Once its scene is built and a few of its paths traced.
    pub measured: Option<Measured>,
}

/// What the probe found.
#[derive(Clone, Copy, Debug)]
pub struct Measured {
    /// One of the recipe's paths as a multiple of one of the cover's.
    pub cost: f64,
    /// The recipe's work at that cost, in book covers.
    pub covers: f64,
    /// One of the cover's paths on this machine, on one thread, in seconds.
    pub cover_path_seconds: f64,
}

impl Work {
    pub fn of(recipe: &Recipe) -> Self {
        let claimed = recipe.image;
        let pixels = u64::from(claimed.window[2]) * u64::from(claimed.window[3]);
        let samples = pixels * u64::from(claimed.samples_per_pixel);
        Work {
            claimed,
            covers: samples as f64 * f64::from(claimed.max_depth) / COVER_RAYS,
            pixels,
            measured: None,
        }
    }

    /// The work, its paths' cost measured on `scene` (the recipe's, built) against the book
    /// cover's scene `cover` (at any size): what the claim alone cannot tell, such as a ray
    /// that meets a million coincident spheres. `scene`'s depth is lowered to the probe's
    /// while it traces, and given back.
    pub fn measured(mut self, scene: &mut Scene, cover: &Scene) -> Self {
        // The cover first once unmeasured, to warm the caches and the clock; then the cover
        // and the recipe in turn, the least of each kept: what the rest of a busy machine
        // takes from one round, another round does not lose. The recipe's probe is repeated
        // only while it is short (a costly recipe is plainly costly the first time).
        probe(cover, Duration::MAX);
        let depth = scene.settings.max_depth;
        scene.settings.max_depth = depth.min(PROBE_DEPTH);
        let mut cover_path_seconds = f64::INFINITY;
        let mut per_path = f64::INFINITY;
        let mut recipe_seconds = Duration::ZERO;
        for _ in 0..PROBE_ROUNDS {
            cover_path_seconds = cover_path_seconds.min(probe(cover, Duration::MAX));
            if recipe_seconds < PROBE_TIME / 8 {
                let start = Instant::now();
                per_path = per_path.min(probe(scene, PROBE_TIME));
                recipe_seconds += start.elapsed();
            }
        }
        scene.settings.max_depth = depth;
        let cover_path_seconds = cover_path_seconds.max(1e-9);
        if depth > PROBE_DEPTH {
            per_path *= f64::from(depth) / f64::from(PROBE_DEPTH);
        }
        let cost = per_path / cover_path_seconds;
        let samples = self.pixels as f64 * f64::from(self.claimed.samples_per_pixel);
        self.measured = Some(Measured {
            cost,
            covers: samples * cost / COVER_SAMPLES,
            cover_path_seconds,
        });
        self
    }

    /// Why the recipe of `image` is not rendered unasked, if it is more than that: the
    /// message, ending with `allow`, what renders it anyway (`--any-cost` on the command
    /// line).
    pub fn refusal(&self, image: &std::path::Path, allow: &str) -> Option<String> {
        let measured_beyond = self.measured.is_some_and(|m| m.covers > UNASKED_COVERS);
        let beyond = if self.covers > UNASKED_COVERS || measured_beyond {
            format!("more than the {UNASKED_COVERS} book covers' work")
        } else if self.pixels > UNASKED_PIXELS {
            format!("more than the {UNASKED_PIXELS} pixels")
        } else {
            return None;
        };
        Some(format!(
            "{}: its recipe asks for {self}, {beyond} that reproduce renders unasked; pass \
             {allow} to render it anyway",
            image.display()
        ))
    }

    /// How long a render of it on `threads` threads (default: one per core, as a render's)
    /// may take unasked: `TESSERA_REPRODUCE_SECONDS` where it is set, else twice what four
    /// book covers take on this machine, as the probe measured the cover, and at least a
    /// minute. None before it is measured.
    pub fn time_budget(&self, threads: Option<usize>) -> Result<Option<Duration>> {
        let Some(m) = self.measured else {
            return Ok(None);
        };
        if let Some(given) = std::env::var_os(BUDGET_VARIABLE) {
            let seconds = given.to_str().and_then(|s| s.trim().parse::<f64>().ok());
            return match seconds {
                Some(s) if s > 0.0 && s <= 1e9 => Ok(Some(Duration::from_secs_f64(s))),
                _ => Err(Error::Setting {
                    field: BUDGET_VARIABLE.into(),
                    message: format!(
                        "must be a number of seconds above 0, at most 10⁹, got {}",
                        terminal_safe(&given.to_string_lossy(), 40)
                    ),
                }),
            };
        }
        let threads = threads.unwrap_or_else(rayon::current_num_threads).max(1);
        let seconds = UNASKED_COVERS * COVER_SAMPLES * m.cover_path_seconds / threads as f64;
        Ok(Some(
            Duration::from_secs_f64(seconds * TIME_SLACK).max(MIN_TIME),
        ))
    }
}

impl std::fmt::Display for Work {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = &self.claimed;
        write!(
            f,
            "{}x{} pixels at {} per pixel, paths of up to {}: ",
            c.window[2],
            c.window[3],
            count(c.samples_per_pixel, "sample"),
            count(c.max_depth, "bounce"),
        )?;
        match self.measured {
            Some(m) => write!(
                f,
                "about {} book covers' work (its paths, traced, cost {} times the cover's)",
                significant(m.covers, 2),
                significant(m.cost, 2)
            ),
            None => write!(
                f,
                "at most {} book covers' work",
                significant(self.covers, 2)
            ),
        }
    }
}

/// The time one path of `scene` takes on the probe's pixels, on one thread, in seconds of
/// that thread's own time on a CPU (`ThreadClock`), tracing for no longer than about `limit`
/// of the wall clock (one path at least).
fn probe(scene: &Scene, limit: Duration) -> f64 {
    let window = scene.settings.window;
    let spp = scene.settings.samples_per_pixel.max(1);
    let simd = simd::Path::best();
    let start = Instant::now();
    let clock = ThreadClock::start();
    let mut paths = 0u64;
    'grid: for j in 0..PROBE_GRID {
        for i in 0..PROBE_GRID {
            let hash = mix(u64::from(j) << 32 | u64::from(i));
            let tile = PixelRect {
                x0: window.x0 + cell_place(window.width, i, hash),
                y0: window.y0 + cell_place(window.height, j, hash >> 32),
                width: 1,
                height: 1,
            };
            // A sample drawn among the pixel's, not always its first: a window of one pixel
            // is then still 1,024 paths.
            let sample = (mix(hash) % u64::from(spp)) as u32;
            let samples = SampleRange {
                start: sample,
                end: sample + 1,
            };
            render_tile(scene, &tile, samples, simd);
            paths += 1;
            if start.elapsed() > limit {
                break 'grid;
            }
        }
    }
    clock.seconds() / paths as f64
}

/// The calling thread's time on a CPU since `start` (`CLOCK_THREAD_CPUTIME_ID`): the time
/// other processes take from the thread on a busy machine is not counted, as the wall clock
/// would count it (on two cores beside a test suite, the wall clock had a recipe's paths at
/// 0.5 to 3 times the cover's from one run to the next).
struct ThreadClock {
    start: Duration,
}

impl ThreadClock {
    fn start() -> Self {
        ThreadClock {
            start: thread_cpu_time(),
        }
    }

    fn seconds(&self) -> f64 {
        thread_cpu_time().saturating_sub(self.start).as_secs_f64()
    }
}

/// The calling thread's time on a CPU so far.
fn thread_cpu_time() -> Duration {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
    Duration::new(
        u64::try_from(t.tv_sec).unwrap_or(0),
        u32::try_from(t.tv_nsec).unwrap_or(0),
    )
}

/// A pixel of cell `k` of the probe's grid along a side of `size` pixels, drawn by `hash`:
/// within the cell, and within the side (a side shorter than the grid has cells of one
/// pixel, some of them the same).
fn cell_place(size: u32, k: u32, hash: u64) -> u32 {
    let (size, k, grid) = (u64::from(size), u64::from(k), u64::from(PROBE_GRID));
    let lo = size * k / grid;
    let hi = (size * (k + 1) / grid).max(lo + 1);
    (lo + hash % (hi - lo)).min(size.saturating_sub(1)) as u32
}

/// SplitMix64's finaliser: a fixed, well-spread hash of `x`.
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// What is said of a render of `image` that the time budget stopped after `elapsed`; `allow`
/// is what renders it anyway.
fn stopped_by_budget(image: &std::path::Path, elapsed: Duration, allow: &str) -> String {
    format!(
        "{}: stopped after {:.0} s, the time reproduce gives a recipe unasked \
         ({BUDGET_VARIABLE}, or twice what four book covers take on this machine): its recipe \
         costs more than its paths, traced, said; pass {allow} to render it anyway",
        image.display(),
        elapsed.as_secs_f64()
    )
}

/// Why a reproduce's render was not started: its cost, or a setting.
#[derive(Debug)]
pub enum NotStarted {
    /// The recipe's work, its paths traced, is more than reproduce renders unasked: the
    /// refusal, in words.
    Refused(String),
    /// The time budget's setting (`BUDGET_VARIABLE`) is wrong.
    Setting(Error),
}

/// A reproduce's render, judged and bounded (`render_judged`).
pub struct Judged<T> {
    /// What `render` returned.
    pub done: T,
    /// The work, with what the probe measured.
    pub work: Work,
    /// What to say when the time budget stopped the render (`render` then returned as
    /// stopped).
    pub over_budget: Option<String>,
    /// How long `render` ran.
    pub elapsed: Duration,
}

/// The rest of a reproduce once the recipe's scene is built, the same for every front end:
/// a few of the recipe's paths traced against those of `yardstick` (the `quick` workload's
/// scene, which the caller builds: workloads sit above this module) (`Work::measured`), a refusal
/// beyond `UNASKED_COVERS` unless `any_cost` (`allow` names the flag that lifts it),
/// `announce` told the work, then `render`, which stops soon after `stop` is set, stopped
/// also past the time budget unless `any_cost`.
#[allow(clippy::too_many_arguments)]
pub fn render_judged<T>(
    work: Work,
    scene: &mut Scene,
    yardstick: &Scene,
    image: &std::path::Path,
    allow: &str,
    any_cost: bool,
    threads: Option<usize>,
    stop: &AtomicBool,
    announce: impl FnOnce(&Work),
    render: impl FnOnce(&Scene) -> T,
) -> std::result::Result<Judged<T>, NotStarted> {
    // What the recipe's paths cost, traced: only the built scene can say.
    let work = work.measured(scene, yardstick);
    if let Some(refusal) = work.refusal(image, allow)
        && !any_cost
    {
        return Err(NotStarted::Refused(refusal));
    }
    announce(&work);
    let budget = if any_cost {
        None
    } else {
        work.time_budget(threads).map_err(NotStarted::Setting)?
    };
    let start = Instant::now();
    let scene = &*scene;
    let (done, timed_out) = within_budget(budget, stop, || render(scene));
    let elapsed = start.elapsed();
    Ok(Judged {
        done,
        work,
        over_budget: timed_out.then(|| stopped_by_budget(image, elapsed, allow)),
        elapsed,
    })
}

/// Runs `render`, which stops soon after `stop` is set, with `stop` set also once `budget`
/// (if any) has passed; the second value says whether the budget stopped it.
fn within_budget<T>(
    budget: Option<Duration>,
    stop: &AtomicBool,
    render: impl FnOnce() -> T,
) -> (T, bool) {
    let Some(budget) = budget else {
        return (render(), false);
    };
    let timed_out = AtomicBool::new(false);
    let (done, finished) = std::sync::mpsc::channel::<()>();
    let timed_out = &timed_out;
    let out = std::thread::scope(|s| {
        s.spawn(move || {
            if let Err(std::sync::mpsc::RecvTimeoutError::Timeout) = finished.recv_timeout(budget) {
                timed_out.store(true, Ordering::Relaxed);
                stop.store(true, Ordering::Relaxed);
            }
        });
        let out = render();
        drop(done);
        out
    });
    (out, timed_out.load(Ordering::Relaxed))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_stops_what_runs_past_it_and_nothing_else() {
        let stop = AtomicBool::new(false);
        let (n, timed_out) = within_budget(Some(Duration::from_secs(60)), &stop, || 7);
        assert_eq!((n, timed_out), (7, false));
        assert!(!stop.load(Ordering::Relaxed));
        let start = Instant::now();
        let ((), timed_out) = within_budget(Some(Duration::from_millis(50)), &stop, || {
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(5));
            }
        });
        assert!(timed_out && start.elapsed() < Duration::from_secs(10));
    }

    #[test]
    fn the_thread_clock_counts_the_thread_s_work_not_its_waiting() {
        let clock = ThreadClock::start();
        std::thread::sleep(Duration::from_millis(300));
        let asleep = clock.seconds();
        assert!(asleep < 0.1, "{asleep} s counted for a 0.3 s sleep");
        let clock = ThreadClock::start();
        let wall = Instant::now();
        let mut x = 1u64;
        while wall.elapsed() < Duration::from_millis(50) {
            x = std::hint::black_box(mix(x));
        }
        let busy = clock.seconds();
        assert!(
            busy > 0.0 && busy <= wall.elapsed().as_secs_f64() + 0.01,
            "{busy}"
        );
    }

    #[test]
    fn the_probe_s_places_stay_in_their_cells_and_the_window() {
        for size in [1u32, 5, 31, 32, 33, 1024, 4097] {
            let cell = size.div_ceil(PROBE_GRID);
            for k in 0..PROBE_GRID {
                let lo = (u64::from(size) * u64::from(k) / u64::from(PROBE_GRID)) as u32;
                for hash in [0u64, 1, 12345, u64::MAX] {
                    let at = cell_place(size, k, hash);
                    assert!(at < size, "{size} {k} {hash}: {at}");
                    assert!(
                        at >= lo.min(size - 1) && at < lo + cell.max(1),
                        "{size} {k}: {at}"
                    );
                }
            }
        }
        // Over a side of 1024, the 32 cells' places differ and every 32-row band holds one.
        let rows: Vec<u32> = (0..PROBE_GRID)
            .map(|k| cell_place(1024, k, mix(u64::from(k))))
            .collect();
        for (k, &row) in rows.iter().enumerate() {
            assert_eq!(row / 32, k as u32);
        }
        // The places within the cells are spread, not all at one offset.
        let offsets: std::collections::BTreeSet<u32> = rows.iter().map(|r| r % 32).collect();
        assert!(offsets.len() > 16, "{offsets:?}");
    }
}
