//! Adding complete parts of one render into the image they cover, after checking, from
//! their headers alone, that they make exactly that image.

use super::{Part, PartReader, RenderId, part_error};
use crate::error::{Error, Result};
use crate::film::{Film, add_run, add_sums};
use crate::math::PixelRect;
use std::path::{Path, PathBuf};

/// What a set of parts makes once merged: the window, its samples per pixel, its gamma.
struct Whole {
    window: PixelRect,
    samples_per_pixel: u32,
    gamma: f32,
}

/// Checks, from their headers alone, that parts add up to one whole render: they share
/// scene and settings, are finished, overlap nowhere (no pixel gets a sample index twice) and
/// cover the whole window over sample indices `0..N` for one `N`.
fn check_set(parts: &[(&Path, &Part)]) -> Result<Whole> {
    let Some(&(first_path, first)) = parts.first() else {
        return Err(Error::Merge("no partial renders given".to_owned()));
    };
    let base = &first.render;
    for &(path, part) in parts {
        let r = &part.render;
        let mismatch = match r.mismatch(base) {
            None if r.target != base.target => Some((
                "sample count",
                format!("an image of {} spp", r.target),
                base.target.to_string(),
            )),
            other => other,
        };
        if let Some((what, theirs, ours)) = mismatch {
            return Err(part_error(
                path,
                format!(
                    "belongs to another render than {}: different {what} ({theirs} vs {ours})",
                    first_path.display()
                ),
            ));
        }
        if !part.is_complete() {
            return Err(part_error(
                path,
                format!(
                    "is an unfinished render ({:.1}% done); finish it by running its render command again",
                    part.state.percent_done()
                ),
            ));
        }
    }
    let window = base.window;
    let total = base.target;
    if let Some(&(path, p)) = parts.iter().find(|(_, p)| p.state.job.samples.end > total) {
        return Err(part_error(
            path,
            format!(
                "holds samples up to {}, past the {total} of the image",
                p.state.job.samples.end
            ),
        ));
    }
    let covered: u128 = parts
        .iter()
        .map(|(_, p)| {
            let job = p.state.job;
            u128::from(job.region.area()) * u128::from(job.samples.len())
        })
        .sum();
    let needed = u128::from(window.area()) * u128::from(total);
    // Counted from the headers alone, with nothing allocated: fewer pixel-samples than the
    // image needs leave a gap, overlap or not. The search for an overlap below keeps four
    // bytes a pixel of the window, which a header may claim at `scene::MAX_PIXELS` (1 GiB):
    // two one-pixel parts of the largest image once asked for it before their gap was seen
    // (`ulimit -v 1048576`: "memory allocation of 1073741824 bytes failed", abort). Parts
    // that claim at least the window's pixel-samples claim at least its pixels, whose
    // image of 24 bytes a pixel a merge allocates next.
    if covered < needed {
        let listing: Vec<String> = parts
            .iter()
            .map(|(path, p)| {
                let (r, s) = (p.state.job.region, p.state.job.samples);
                format!(
                    "{}: pixels {}x{} at ({}, {}), samples {}..{}",
                    path.display(),
                    r.width,
                    r.height,
                    r.x0,
                    r.y0,
                    s.start,
                    s.end
                )
            })
            .collect();
        return Err(Error::Merge(format!(
            "the parts leave gaps: they hold {covered} pixel-samples of the {needed} that \
                 {}x{} pixels × samples 0..{total} need; a shard is missing. Parts: {}",
            window.width,
            window.height,
            // One line, as every error is printed: a newline would show as `\u{a}`.
            listing.join("; ")
        )));
    }
    if let Some(found) = overlap(parts, base.window).found {
        let (a, b) = (parts[found.0], parts[found.1]);
        let (sa, sb) = (a.1.state.job.samples, b.1.state.job.samples);
        return Err(part_error(
            b.0,
            format!(
                "overlaps {}: both hold samples {}..{} of some pixels",
                a.0.display(),
                sa.start.max(sb.start),
                sa.end.min(sb.end)
            ),
        ));
    }
    // Parts inside the window, overlapping nowhere, holding as many pixel-samples as it
    // needs, cover it exactly; more than it needs overlap somewhere, which `overlap` finds:
    // this is said only were it to miss one.
    if covered != needed {
        return Err(Error::Merge(format!(
            "the parts hold {covered} pixel-samples, more than the {needed} that {}x{} pixels \
             × samples 0..{total} need, so some overlap",
            window.width, window.height
        )));
    }
    Ok(Whole {
        window,
        samples_per_pixel: total,
        gamma: base.gamma,
    })
}

/// What `overlap` found, and the pixels it looked at to find it.
struct Overlap {
    /// Two parts, by index, that hold the same sample of some pixel: the one with the
    /// earlier first sample, then the other.
    found: Option<(usize, usize)>,
    /// Pixels looked at: one per pixel of each part, at most (tests bound it).
    #[cfg_attr(not(test), allow(dead_code))]
    steps: u64,
}

/// Finds two parts of `parts`, all inside `window`, that hold the same sample index of some
/// pixel. The parts are taken in order of their first sample, and each pixel of the window
/// keeps how far in samples the parts so far reach there: a part that starts short of that
/// at one of its pixels overlaps one before it. Time follows the parts' pixels, which their
/// files hold as sums, not the square of their number (comparing every pair took 8.7 s for
/// 100,000 one-pixel part files, and 1,000,000 would take minutes); the reach takes four
/// bytes a pixel, freed before the image's 24 are allocated.
fn overlap(parts: &[(&Path, &Part)], window: PixelRect) -> Overlap {
    let job = |i: usize| parts[i].1.state.job;
    let mut order: Vec<usize> = (0..parts.len())
        .filter(|&i| !job(i).samples.is_empty())
        .collect();
    order.sort_by_key(|&i| job(i).samples.start);
    let mut steps = 0;
    if order.len() < 2 {
        // One part overlaps nothing: no reach to allocate.
        return Overlap { found: None, steps };
    }
    let mut reach = vec![0u32; window.area() as usize];
    for (k, &i) in order.iter().enumerate() {
        let (r, samples) = (job(i).region, job(i).samples);
        for y in r.y0..r.y0 + r.height {
            let row = (y - window.y0) as usize * window.width as usize;
            let at = row + (r.x0 - window.x0) as usize;
            for (x, reached) in (r.x0..).zip(&mut reach[at..at + r.width as usize]) {
                steps += 1;
                if samples.start < *reached {
                    // Some part before holds sample `samples.start` of this pixel.
                    let holds = |j: &&usize| {
                        let o = job(**j);
                        let (ox, oy) = (o.region.x0, o.region.y0);
                        (ox..ox + o.region.width).contains(&x)
                            && (oy..oy + o.region.height).contains(&y)
                            && o.samples.start <= samples.start
                            && samples.start < o.samples.end
                    };
                    if let Some(&j) = order[..k].iter().find(holds) {
                        return Overlap {
                            found: Some((j, i)),
                            steps,
                        };
                    }
                }
                *reached = (*reached).max(samples.end);
            }
        }
    }
    Overlap { found: None, steps }
}

/// Adds complete parts of one render, already in memory, into the image they cover together
/// (see `check_set` for what they must be). Returns the image and its gamma.
pub fn merge(parts: &[(PathBuf, Part)]) -> Result<(Film, f32)> {
    let named: Vec<(&Path, &Part)> = parts.iter().map(|(p, part)| (p.as_path(), part)).collect();
    let whole = check_set(&named)?;
    let mut film = whole.film();
    for (_, part) in parts {
        let state = &part.state;
        add_sums(&mut film.sums, whole.window, &state.sums, state.job.region);
    }
    Ok((film, whole.gamma))
}

/// Merges the part files `paths` into the image they cover together (see `check_set`),
/// reading one part at a time a chunk at a time: memory stays about one image whatever the
/// number of parts. Every part is checked, by its header, before any sums are read, and
/// one another user owns is refused (`PartReader::open_own`).
/// Gives the film and the render the parts belong to: the first part's, with the recipe
/// source every part carries (none unless all carry the same).
pub fn merge_files(paths: &[PathBuf]) -> Result<(Film, RenderId)> {
    let headers = paths
        .iter()
        .map(|path| Ok((path.as_path(), PartReader::open_own(path)?.into_header())))
        .collect::<Result<Vec<(&Path, Part)>>>()?;
    let named: Vec<(&Path, &Part)> = headers.iter().map(|(p, h)| (*p, h)).collect();
    let whole = check_set(&named)?;
    let mut film = whole.film();
    for (path, header) in &headers {
        let reader = PartReader::open_own(path)?;
        if reader.header() != header {
            return Err(part_error(path, "changed while being merged".to_owned()));
        }
        let region = header.state.job.region;
        let mut at = 0;
        reader.read_sums(|run| {
            add_run(&mut film.sums, whole.window, region, at, run);
            at += run.len() as u64;
        })?;
    }
    let mut render = headers[0].1.render.clone();
    if (headers.iter()).any(|(_, h)| h.render.recipe != render.recipe) {
        render.recipe = None;
    }
    Ok((film, render))
}

impl Whole {
    fn film(&self) -> Film {
        Film::new(
            self.window.width,
            self.window.height,
            self.samples_per_pixel,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::part;
    use super::*;

    #[test]
    fn merge_needs_exact_cover() {
        let full = PixelRect::full(8, 6);
        let top = PixelRect {
            x0: 0,
            y0: 0,
            width: 8,
            height: 3,
        };
        let bottom = PixelRect {
            x0: 0,
            y0: 3,
            width: 8,
            height: 3,
        };
        let named = |p: Part| (PathBuf::from("p"), p);
        let ok = merge(&[named(part(top, [0, 9])), named(part(bottom, [0, 9]))]).unwrap();
        assert_eq!(ok.0.samples_per_pixel, 9);
        let short = merge(&[named(part(full, [0, 4]))]).unwrap_err().to_string();
        assert!(short.contains("gaps"), "{short}");
        assert!(merge(&[named(part(full, [0, 4])), named(part(full, [4, 9]))]).is_ok());
        let gap = merge(&[named(part(top, [0, 9]))]).unwrap_err().to_string();
        assert!(gap.contains("gaps"), "{gap}");
        // One line, as every error is printed: a newline between the parts showed as `\u{a}`.
        let listed = "a shard is missing. Parts: p: pixels 8x3 at (0, 0), samples 0..9";
        assert!(!gap.contains('\n') && gap.ends_with(listed), "{gap}");
        let two = merge(&[named(part(top, [0, 4])), named(part(top, [4, 9]))]);
        let two = two.unwrap_err().to_string();
        assert!(
            two.ends_with("samples 0..4; p: pixels 8x3 at (0, 0), samples 4..9"),
            "{two}"
        );
        let overlap = merge(&[named(part(full, [0, 9])), named(part(top, [3, 5]))]);
        assert!(overlap.unwrap_err().to_string().contains("overlaps"));
        // Too few pixel-samples leave a gap, said from the count alone, overlap or not.
        let both = merge(&[named(part(full, [0, 4])), named(part(top, [3, 5]))]);
        assert!(both.unwrap_err().to_string().contains("gaps"));
        let hole = merge(&[named(part(full, [0, 4])), named(part(full, [5, 9]))]);
        assert!(hole.unwrap_err().to_string().contains("gaps"));
    }

    /// The pairs of `parts` that hold a sample of some pixel in common, found by comparing
    /// every pair.
    fn overlapping_pairs(parts: &[(&Path, &Part)]) -> Vec<(usize, usize)> {
        let mut pairs = Vec::new();
        for (i, a) in parts.iter().enumerate() {
            for (j, b) in parts.iter().enumerate().skip(i + 1) {
                let (ja, jb) = (a.1.state.job, b.1.state.job);
                let (ra, rb) = (ja.region, jb.region);
                let pixels = ra.x0 < rb.x0 + rb.width
                    && rb.x0 < ra.x0 + ra.width
                    && ra.y0 < rb.y0 + rb.height
                    && rb.y0 < ra.y0 + ra.height;
                let (sa, sb) = (ja.samples, jb.samples);
                let samples = sa.start.max(sb.start) < sa.end.min(sb.end);
                if pixels && samples {
                    pairs.push((i, j));
                }
            }
        }
        pairs
    }

    #[test]
    fn overlaps_are_found_as_comparing_every_pair_finds_them() {
        let mut seed = 7u64;
        let mut draw = |n: u32| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) % u64::from(n)) as u32
        };
        let path = Path::new("p");
        for _ in 0..2000 {
            let parts: Vec<Part> = (0..1 + draw(5))
                .map(|_| {
                    let (x0, y0) = (draw(8), draw(6));
                    let region = PixelRect {
                        x0,
                        y0,
                        width: 1 + draw(8 - x0),
                        height: 1 + draw(6 - y0),
                    };
                    let start = draw(9);
                    part(region, [start, start + draw(10 - start)])
                })
                .collect();
            let named: Vec<(&Path, &Part)> = parts.iter().map(|p| (path, p)).collect();
            let pairs = overlapping_pairs(&named);
            match overlap(&named, PixelRect::full(8, 6)).found {
                None => assert!(pairs.is_empty(), "missed {pairs:?} of {parts:?}"),
                Some((a, b)) => {
                    let pair = (a.min(b), a.max(b));
                    assert!(pairs.contains(&pair), "{pair:?} of {parts:?}");
                }
            }
        }
    }

    /// 20,000 one-pixel parts: each pixel is looked at once, where comparing every pair made
    /// 200 million comparisons (and 100,000 parts, 5 billion: 8.7 s).
    #[test]
    fn many_parts_cost_one_step_a_pixel() {
        let (width, height) = (200, 100);
        let mut parts = Vec::new();
        for y in 0..height {
            for x in 0..width {
                let pixel = PixelRect {
                    x0: x,
                    y0: y,
                    width: 1,
                    height: 1,
                };
                let mut p = part(pixel, [0, 9]);
                p.render.width = width;
                p.render.height = height;
                p.render.window = PixelRect::full(width, height);
                parts.push(p);
            }
        }
        let path = Path::new("p");
        let named: Vec<(&Path, &Part)> = parts.iter().map(|p| (path, p)).collect();
        let window = PixelRect::full(width, height);
        let clean = overlap(&named, window);
        assert_eq!((clean.found, clean.steps), (None, 20_000));
        assert!(check_set(&named).is_ok());
        let mut twice = named.clone();
        twice.push(named[12_345]);
        let found = overlap(&twice, window);
        assert_eq!(found.found, Some((12_345, 20_000)));
        assert!(found.steps <= 20_001, "{}", found.steps);
    }
}
