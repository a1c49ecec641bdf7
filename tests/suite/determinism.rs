//! The determinism contract: the same scene, settings and seed give the same bytes whatever
//! the thread count, the tile size, or how the image is cropped into regions.

use crate::common::*;
use tessera::math::PixelRect;
use tessera::scene::Overrides;

fn small_cover() -> tessera::scene::Scene {
    small("cover.toml")
}

/// A scene file at 72 pixels wide and 4 samples per pixel.
fn small(name: &str) -> tessera::scene::Scene {
    load(
        &scene_path(name),
        Overrides {
            width: Some(72),
            samples_per_pixel: Some(4),
            ..Overrides::default()
        },
    )
}

/// The cover, and *The Next Week*'s scenes whose random numbers differ most from the
/// first book's: motion blur (the rays' times), media (a random number per segment),
/// textures and everything at once.
const SCENES: [&str; 5] = [
    "cover.toml",
    "img-2.01-bouncing-spheres.toml",
    "img-2.15-earth-sphere.toml",
    "img-2.21-cornell-smoke.toml",
    "img-2.22-book2-final.toml",
];

#[test]
fn same_bytes_for_any_thread_count_and_tile_size() {
    for name in SCENES {
        let scene = small(name);
        let (reference, ref_stats) = render_with(&scene, 1, 16);
        let png = reference
            .encode(tessera::image_file::Format::Png, 2.0)
            .unwrap();
        for threads in [1, 2, 3, 8] {
            for tile in [8, 16, 64] {
                let (film, stats) = render_with(&scene, threads, tile);
                assert!(
                    film == reference,
                    "{name}: {threads} threads, tile {tile} changed the image"
                );
                assert_eq!(
                    stats.rays, ref_stats.rays,
                    "{name}: {threads} threads, tile {tile}"
                );
                assert_eq!(
                    film.encode(tessera::image_file::Format::Png, 2.0).unwrap(),
                    png
                );
            }
        }
    }
}

#[test]
fn different_seeds_give_different_images() {
    for name in SCENES {
        let a = render(&small(name));
        let mut other = small(name);
        other.settings.seed += 1;
        assert!(render(&other) != a, "{name}");
    }
}

#[test]
fn cropped_regions_equal_the_same_pixels_of_the_whole_image() {
    for name in SCENES {
        cropped_regions_equal_the_whole(name);
    }
}

fn cropped_regions_equal_the_whole(name: &str) {
    let scene = small(name);
    let whole = render(&scene);
    let (w, h) = (scene.settings.width, scene.settings.height);
    for window in [
        PixelRect {
            x0: 0,
            y0: 0,
            width: w / 2,
            height: h,
        },
        PixelRect {
            x0: w / 2,
            y0: 0,
            width: w - w / 2,
            height: h,
        },
        PixelRect {
            x0: 5,
            y0: 7,
            width: 13,
            height: 11,
        },
    ] {
        let mut part = scene.clone();
        part.settings.window = window;
        let film = render_with(&part, 3, 8).0;
        for y in 0..window.height {
            for x in 0..window.width {
                let got = film.sums[(y * window.width + x) as usize];
                let want = whole.sums[((y + window.y0) * w + x + window.x0) as usize];
                assert_eq!(got, want, "pixel ({x}, {y}) of {window:?}");
            }
        }
    }
}

/// Renders samples `range` of `tile` on every SIMD path this CPU runs, which must agree,
/// and checks the sums and ray count against each sample traced alone through the tree (the
/// reference, on the portable path); `what` names the case in a failure.
fn tile_equals_each_sample_alone(
    scene: &tessera::scene::Scene,
    tile: &PixelRect,
    range: tessera::job::SampleRange,
    what: &str,
) {
    use tessera::film::to_fixed;
    use tessera::integrator::PixelEvaluator;
    use tessera::job::SampleRange;
    use tessera::render::render_tile;
    use tessera::simd::{Path, Portable};
    let paths = Path::supported();
    let fast = render_tile(scene, tile, range, *paths.last().unwrap());
    for &path in &paths {
        let on_path = render_tile(scene, tile, range, path);
        assert_eq!(on_path.sums, fast.sums, "{what} {path}");
        assert_eq!(on_path.rays, fast.rays, "{what} {path}");
    }
    let mut alone = PixelEvaluator::with_candidates(Portable, scene, None);
    let mut rays = 0u64;
    for (i, y) in (tile.y0..tile.y0 + tile.height).enumerate() {
        for (j, x) in (tile.x0..tile.x0 + tile.width).enumerate() {
            let mut sum = [0u64; 3];
            for start in range.start..range.end {
                let one = SampleRange {
                    start,
                    end: start + 1,
                };
                alone.evaluate(x, y, one, |c, r| {
                    sum[0] += to_fixed(c.x);
                    sum[1] += to_fixed(c.y);
                    sum[2] += to_fixed(c.z);
                    rays += u64::from(r);
                });
            }
            let pixel = i * tile.width as usize + j;
            assert_eq!(
                fast.sums[pixel], sum,
                "{what}: pixel ({x}, {y}) of {tile:?}"
            );
        }
    }
    assert_eq!(fast.rays, rays, "{what}: {tile:?}");
}

fn rect(x0: u32, y0: u32, width: u32, height: u32) -> PixelRect {
    PixelRect {
        x0,
        y0,
        width,
        height,
    }
}

/// The renderer tests a tile's camera rays against the few spheres picked for it
/// (`integrator::tile_candidates`) and makes each sample's camera ray while the one before is
/// traced. Tracing each sample alone (a range of one) through the whole hierarchy, the simple
/// reference (on the portable SIMD path), must give the very same sums and ray counts, on
/// every SIMD path this CPU runs.
#[test]
fn fast_tile_tracer_equals_tracing_each_sample_alone() {
    use tessera::integrator::tile_candidates;
    use tessera::job::SampleRange;
    let scene = load(
        &scene_path("cover.toml"),
        Overrides {
            width: Some(300),
            ..Overrides::default()
        },
    );
    let range = SampleRange { start: 5, end: 9 };
    // Sky, the three big spheres, the field of small ones, the ground near the camera, an
    // odd-sized tile, and one too wide for a candidate list.
    let tiles = [
        rect(0, 0, 16, 16),
        rect(140, 80, 16, 16),
        rect(60, 120, 16, 16),
        rect(200, 184, 16, 16),
        rect(37, 101, 9, 13),
        rect(0, 100, 300, 8),
    ];
    let mut listed = 0;
    for tile in &tiles {
        listed += usize::from(tile_candidates(&scene, tile).is_some());
        tile_equals_each_sample_alone(&scene, tile, range, "cover");
    }
    assert!(listed >= 4, "only {listed} tiles had candidate lists");
    assert!(tile_candidates(&scene, &tiles[5]).is_none());
}

#[test]
fn paths_traced_sixteen_at_a_time_equal_tracing_each_sample_alone() {
    // The Cornell box with its blocks, and with its smoke (media): a tile's paths go sixteen
    // at a time (`integrator::trace_tile`), each lane taking the next sample as its path
    // ends; every pixel's sums and the ray count must be those of each sample traced alone,
    // on every SIMD path, whatever the tile's shape and the samples' range.
    use tessera::job::SampleRange;
    for name in [
        "img-2.20-cornell-standard.toml",
        "img-2.21-cornell-smoke.toml",
    ] {
        let scene = load(
            &scene_path(name),
            Overrides {
                width: Some(60),
                ..Overrides::default()
            },
        );
        assert!(scene.batches_paths(), "{name}");
        // A corner, the lamp's rows, a block, one pixel, a row, and fewer pixels than lanes.
        let tiles = [
            rect(0, 0, 16, 16),
            rect(24, 0, 13, 9),
            rect(30, 40, 16, 16),
            rect(59, 59, 1, 1),
            rect(0, 30, 60, 1),
            rect(10, 10, 3, 2),
        ];
        let ranges = [(0, 4), (3, 10), (0, 1), (5, 25), (1, 3), (0, 2)];
        for (tile, (start, end)) in tiles.iter().zip(ranges) {
            tile_equals_each_sample_alone(&scene, tile, SampleRange { start, end }, name);
        }
    }
}

/// A watcher that records what it is told, and stops the job once a pass is done if asked.
struct Recorder<'a> {
    stop_after_pass: Option<(usize, &'a std::sync::atomic::AtomicBool)>,
    passes: Vec<u32>,
    spp_seen: Vec<u32>,
    work: (u64, u64),
    folds: usize,
}

impl tessera::render::Watch for Recorder<'_> {
    fn started(&mut self, state: &tessera::job::JobState, p: &tessera::render::Progress) {
        self.passes = p.passes.to_vec();
        self.spp_seen.push(state.min_done());
    }
    fn folded(
        &mut self,
        state: &tessera::job::JobState,
        folded: &[usize],
        p: &tessera::render::Progress,
    ) {
        self.folds += folded.len();
        self.spp_seen.push(state.min_done());
        self.work = (p.work_done, p.work_total);
        if let Some((pass, stop)) = self.stop_after_pass
            && p.pass > pass
        {
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

fn render_progressive(
    scene: &tessera::scene::Scene,
    state: &mut tessera::job::JobState,
    threads: usize,
    recorder: &mut Recorder,
    stop: &std::sync::atomic::AtomicBool,
) {
    let options = tessera::render::RenderOptions {
        threads: Some(threads),
        tile: state.tile,
        ..Default::default()
    };
    let control = tessera::render::Control {
        stop,
        on_samples: &|_| {},
        on_progress: None,
        progressive: true,
        watch: Some(recorder),
    };
    tessera::render::render_job(scene, &options, state, control).unwrap();
}

#[test]
fn progressive_passes_give_the_same_sums_as_whole_tiles() {
    use std::sync::atomic::AtomicBool;
    use tessera::job::{Job, JobState};
    let mut scene = small_cover();
    scene.settings.samples_per_pixel = 13;
    let reference = render(&scene);
    for threads in [1, 2, 3] {
        for tile in [8, 16] {
            let stop = AtomicBool::new(false);
            let mut state = JobState::new(Job::whole(&scene), tile);
            let mut recorder = Recorder {
                stop_after_pass: None,
                passes: Vec::new(),
                spp_seen: Vec::new(),
                work: (0, 0),
                folds: 0,
            };
            render_progressive(&scene, &mut state, threads, &mut recorder, &stop);
            assert_eq!(recorder.passes, [1, 4, 13]);
            assert_eq!(
                recorder.folds,
                state.done.len() * 3,
                "one fold per tile per pass"
            );
            assert!(recorder.spp_seen.is_sorted(), "{:?}", recorder.spp_seen);
            assert_eq!(recorder.work.0, recorder.work.1, "all the work is done");
            assert!(
                state.into_film() == reference,
                "{threads} threads, tile {tile}: progressive passes changed the image"
            );
        }
    }
}

#[test]
fn a_progressive_render_stopped_between_passes_resumes_to_the_same_sums() {
    use std::sync::atomic::AtomicBool;
    use tessera::job::{Job, JobState};
    let mut scene = small_cover();
    scene.settings.samples_per_pixel = 21;
    let reference = render(&scene);
    let stop = AtomicBool::new(false);
    let mut state = JobState::new(Job::whole(&scene), 8);
    let mut recorder = Recorder {
        stop_after_pass: Some((1, &stop)),
        passes: Vec::new(),
        spp_seen: Vec::new(),
        work: (0, 0),
        folds: 0,
    };
    render_progressive(&scene, &mut state, 2, &mut recorder, &stop);
    assert!(!state.is_complete(), "stopped early");
    let counts: std::collections::BTreeSet<u32> = state.done.iter().copied().collect();
    assert!(counts.iter().all(|d| (4..21).contains(d)), "{counts:?}");
    // Resumed tile at a time, then progressively from a state whose tiles differ.
    let mut resumed = state.clone();
    render_progressive(
        &scene,
        &mut resumed,
        2,
        &mut Recorder {
            stop_after_pass: None,
            passes: Vec::new(),
            spp_seen: Vec::new(),
            work: (0, 0),
            folds: 0,
        },
        &AtomicBool::new(false),
    );
    assert!(resumed.into_film() == reference);
    let mut whole_tiles = state;
    let options = tessera::render::RenderOptions {
        threads: Some(1),
        tile: 8,
        ..Default::default()
    };
    let control = tessera::render::Control {
        stop: &AtomicBool::new(false),
        on_samples: &|_| {},
        on_progress: None,
        progressive: false,
        watch: None,
    };
    tessera::render::render_job(&scene, &options, &mut whole_tiles, control).unwrap();
    assert!(whole_tiles.into_film() == reference);
}

#[test]
fn passes_double_up_to_the_samples() {
    use tessera::render::passes;
    assert_eq!(passes(1), [1]);
    assert_eq!(passes(2), [1, 2]);
    assert_eq!(passes(4), [1, 4]);
    assert_eq!(passes(5), [1, 4, 5]);
    assert_eq!(passes(500), [1, 4, 16, 64, 256, 500]);
    assert_eq!(passes(1024), [1, 4, 16, 64, 256, 1024]);
    assert_eq!(passes(u32::MAX).len(), 17);
    assert_eq!(passes(0), [0]);
}
