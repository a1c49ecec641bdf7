//! The determinism contract: the same scene, settings and seed give the same bytes whatever
//! the thread count, the tile size, or how the image is cropped into regions.

mod common;

use common::*;
use tessera::math::PixelRect;
use tessera::scene::Overrides;

fn small_cover() -> tessera::scene::Scene {
    load(
        &scene_path("cover.toml"),
        Overrides {
            width: Some(72),
            samples_per_pixel: Some(4),
            ..Overrides::default()
        },
    )
}

#[test]
fn same_bytes_for_any_thread_count_and_tile_size() {
    let scene = small_cover();
    let (reference, ref_stats) = render_with(&scene, 1, 16);
    let png = reference.encode(tessera::film::Format::Png, 2.0).unwrap();
    for threads in [1, 2, 3, 8] {
        for tile in [8, 16, 64] {
            let (film, stats) = render_with(&scene, threads, tile);
            assert!(
                film == reference,
                "{threads} threads, tile {tile} changed the image"
            );
            assert_eq!(stats.rays, ref_stats.rays, "{threads} threads, tile {tile}");
            assert_eq!(film.encode(tessera::film::Format::Png, 2.0).unwrap(), png);
        }
    }
}

#[test]
fn different_seeds_give_different_images() {
    let a = render(&small_cover());
    let mut other = small_cover();
    other.settings.seed += 1;
    assert!(render(&other) != a);
}

#[test]
fn cropped_regions_equal_the_same_pixels_of_the_whole_image() {
    let scene = small_cover();
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
