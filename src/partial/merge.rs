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
    for (i, &(path_a, a)) in parts.iter().enumerate() {
        for &(path_b, b) in &parts[i + 1..] {
            let (ra, rb) = (a.state.job.region, b.state.job.region);
            let pixels_meet = ra.x0 < rb.x0 + rb.width
                && rb.x0 < ra.x0 + ra.width
                && ra.y0 < rb.y0 + rb.height
                && rb.y0 < ra.y0 + ra.height;
            let (sa, sb) = (a.state.job.samples, b.state.job.samples);
            let samples_meet = sa.start < sb.end && sb.start < sa.end;
            if pixels_meet && samples_meet {
                return Err(part_error(
                    path_b,
                    format!(
                        "overlaps {}: both hold samples {}..{} of some pixels",
                        path_a.display(),
                        sa.start.max(sb.start),
                        sa.end.min(sb.end)
                    ),
                ));
            }
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
    if covered != needed {
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
                 {}x{} pixels × samples 0..{total} need; a shard is missing. Parts:\n  {}",
            window.width,
            window.height,
            listing.join("\n  ")
        )));
    }
    Ok(Whole {
        window,
        samples_per_pixel: total,
        gamma: base.gamma,
    })
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
/// number of parts. Every part is checked, by its header, before any sums are read.
/// Gives the film and the render the parts belong to: the first part's, with the recipe
/// source every part carries (none unless all carry the same).
pub fn merge_files(paths: &[PathBuf]) -> Result<(Film, RenderId)> {
    let headers = paths
        .iter()
        .map(|path| Ok((path.as_path(), PartReader::open(path)?.into_header())))
        .collect::<Result<Vec<(&Path, Part)>>>()?;
    let named: Vec<(&Path, &Part)> = headers.iter().map(|(p, h)| (*p, h)).collect();
    let whole = check_set(&named)?;
    let mut film = whole.film();
    for (path, header) in &headers {
        let reader = PartReader::open(path)?;
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
        let overlap = merge(&[named(part(full, [0, 4])), named(part(top, [3, 5]))]);
        assert!(overlap.unwrap_err().to_string().contains("overlaps"));
        let hole = merge(&[named(part(full, [0, 4])), named(part(full, [5, 9]))]);
        assert!(hole.unwrap_err().to_string().contains("gaps"));
    }
}
