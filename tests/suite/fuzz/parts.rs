//! Mutated partial files: refused by name, never believed past their real length.

use super::harness::*;
use super::scenes::{NUMBERS, number_spans};
use crate::common::GOOD;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use tessera::job::{Job, JobState, SampleRange};
use tessera::math::PixelRect;
use tessera::partial::Part;
use tessera::render::{self, RenderOptions};
use tessera::scene::{Overrides, Scene};
use tessera::shard::{self, Shard};

/// A small scene whose parts the partial-file cases start from.
pub(crate) fn part_scene() -> String {
    GOOD.replace("samples_per_pixel = 1", "samples_per_pixel = 4")
}

/// Real parts of `part_scene()`: the whole render, a sample range, a band of rows, and an
/// unfinished checkpoint.
fn seed_parts(scene: &Scene) -> Vec<Part> {
    let options = RenderOptions {
        threads: Some(1),
        tile: 4,
        ..RenderOptions::default()
    };
    let whole = Job::whole(scene);
    let rows = shard::job(
        scene,
        Some(Shard { index: 1, count: 3 }),
        shard::Split::Rows,
        None,
    )
    .unwrap();
    let range = Job {
        samples: SampleRange { start: 1, end: 3 },
        ..whole
    };
    let mut parts = Vec::new();
    for job in [whole, rows, range] {
        let mut state = JobState::new(job, 4);
        let stop = AtomicBool::new(false);
        let control = render::Control {
            stop: &stop,
            on_samples: &|_| {},
            on_progress: None,
            progressive: false,
            watch: None,
        };
        render::render_job(scene, &options, &mut state, control).unwrap();
        parts.push(Part::of(scene, state, 4));
    }
    let mut unfinished = parts[0].clone();
    unfinished.state.done[1] = 1;
    parts.push(unfinished);
    parts
}

const U32S: &[u32] = &[
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    12,
    16,
    255,
    16384,
    65536,
    1 << 28,
    u32::MAX - 1,
    u32::MAX,
];

/// One random change to a part: to its header's fields (the file is then written with a
/// valid checksum, so the deeper checks are reached) or to its bytes.
fn mutate_part(g: &mut Gen, part: &mut Part, bytes: &mut Option<Vec<u8>>) {
    let n = |g: &mut Gen| U32S[g.below(U32S.len())];
    if let Some(b) = bytes.as_mut() {
        match g.below(5) {
            0 if !b.is_empty() => {
                let i = g.below(b.len());
                b[i] ^= 1 << g.below(8);
            }
            1 => b.truncate(g.below(b.len() + 1)),
            2 => {
                let more = g.below(64);
                b.extend((0..more).map(|k| k as u8));
            }
            3 if b.len() >= 24 => {
                let claims = [0u64, 1, 8, 1 << 20, 1 << 32, u64::MAX, u64::MAX - 23];
                let claim = claims[g.below(claims.len())];
                b[16..24].copy_from_slice(&claim.to_le_bytes());
            }
            _ => {
                // A header value rewritten in the JSON text (its length word follows).
                let spans = number_spans(b);
                if let Some(&(a, e)) = spans.get(g.below(spans.len())) {
                    b.splice(a..e, g.pick(NUMBERS).bytes());
                }
            }
        }
        return;
    }
    let (render, state) = (&mut part.render, &mut part.state);
    match g.below(13) {
        // A coherent claim of a huge image, which only the file's length belies.
        11 | 12 => {
            let (w, h) = g.pick(&[
                (16384, 16384),
                (65536, 4096),
                (1, 1 << 28),
                (1 << 14, 1 << 13),
            ]);
            (render.width, render.height) = (w, h);
            render.window = PixelRect::full(w, h);
            state.job.region = PixelRect::full(w, h);
            if g.chance(50) {
                state.tile = 1;
            }
        }
        0 => render.width = n(g),
        1 => render.height = n(g),
        2 => *corner(&mut render.window, g.below(4)) = n(g),
        3 => *corner(&mut state.job.region, g.below(4)) = n(g),
        4 if g.chance(50) => state.job.samples.start = n(g),
        4 => state.job.samples.end = n(g),
        5 => render.target = n(g),
        6 => state.tile = n(g),
        7 => match g.below(3) {
            0 => state.done.clear(),
            1 => state.done.push(n(g)),
            _ => {
                if let Some(d) = state.done.first_mut() {
                    *d = n(g);
                }
            }
        },
        8 => part.version = n(g),
        9 => {
            let keep = g.below(state.sums.len() + 2);
            state.sums.resize(keep, [u64::MAX, 0, 1 << 40]);
        }
        _ => {
            for s in state.sums.iter_mut() {
                *s = [u64::MAX; 3];
            }
        }
    }
}

/// One of a rectangle's four numbers: x, y, width, height.
fn corner(r: &mut PixelRect, i: usize) -> &mut u32 {
    match i {
        0 => &mut r.x0,
        1 => &mut r.y0,
        2 => &mut r.width,
        _ => &mut r.height,
    }
}

/// Checks one part's bytes: reading never panics nor allocates beyond the ceiling; what is
/// accepted is consistent, and merging or resuming it never panics.
fn check_part_case(scene: &Scene, bytes: &[u8]) -> Result<Outcome, String> {
    let path = Path::new("fuzz.part");
    let part = match Part::from_bytes(bytes, path) {
        Ok(part) => part,
        Err(e) => {
            let message = e.to_string();
            return if message.starts_with("fuzz.part: ") {
                Ok(Outcome::Refused)
            } else {
                Err(format!("a refusal that does not name the file: {message}"))
            };
        }
    };
    let state = &part.state;
    if state.sums.len() as u64 != state.job.region.area() {
        return Err(format!(
            "accepted {} sums for region {:?}",
            state.sums.len(),
            state.job.region
        ));
    }
    let named = vec![(PathBuf::from("fuzz.part"), part.clone())];
    if let Ok((film, _)) = tessera::partial::merge(&named)
        && film.sums.len() as u64 != u64::from(film.width) * u64::from(film.height)
    {
        return Err("merged into a film of the wrong size".to_owned());
    }
    let mut job = state.job;
    job.samples.end = job.samples.end.saturating_add(1);
    if let Ok(resumed) = part.resume(scene, job, path) {
        let _ = (resumed.percent_done(), resumed.unfinished_tiles());
    }
    Ok(Outcome::Accepted)
}

#[test]
fn mutated_partial_files_are_refused_cleanly_and_never_believed() {
    let scene = Scene::parse(&part_scene(), Path::new("part.toml"), &Overrides::default()).unwrap();
    let parts = seed_parts(&scene);
    run_family(
        "part",
        20_000,
        // The files here are a few kilobytes: reading one never needs 16 MiB.
        16 << 20,
        |g| {
            let mut part = parts[g.below(parts.len())].clone();
            // Half the cases change fields, then write a file with a valid checksum; half
            // change the bytes.
            let mut bytes = g.chance(50).then(|| part.to_bytes());
            for _ in 0..1 + g.below(3) {
                mutate_part(g, &mut part, &mut bytes);
            }
            let bytes = bytes.unwrap_or_else(|| part.to_bytes());
            let head = String::from_utf8_lossy(&bytes[..bytes.len().min(400)]).into_owned();
            let shown = format!("{} bytes, beginning {head:?}", bytes.len());
            (bytes, shown)
        },
        |bytes| check_part_case(&scene, bytes),
    );
}
