//! Partial renders on disk — shards and checkpoints — and merging them: a self-describing
//! binary file of exact fixed-point sums, so merged parts give the bytes of a single render.
//!
//! Layout: the 16-byte magic `TESSERA-PARTIAL\n`, the header length (u64, little endian),
//! the header as JSON, the region's sums (three u64 per pixel, row-major, little endian), and
//! a checksum (u64) of everything before it. Sums are integers, so adding parts in any order
//! gives exactly the sums of one uninterrupted render.

use crate::error::{Error, Result};
use crate::film::{Film, add_sums};
use crate::math::PixelRect;
use crate::render::{Job, Progress, SampleRange, percent, samples_done};
use crate::sampling::mix64;
use crate::scene::Scene;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 16] = b"TESSERA-PARTIAL\n";
const VERSION: u32 = 1;

/// What a part is a part of, and which part it is.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    pub version: u32,
    /// `Scene::fingerprint` in hex: scene contents and every setting but spp and crop.
    pub fingerprint: String,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    pub max_depth: u32,
    pub gamma: f32,
    /// The scene's window `[x, y, width, height]`: what a merge must cover.
    pub window: [u32; 4],
    /// The pixels this part holds, `[x, y, width, height]`.
    pub region: [u32; 4],
    /// The sample indices this part is for, `[start, end)`.
    pub samples: [u32; 2],
    /// Samples per pixel of the finished image: a merge must cover sample indices
    /// `0..target` of every pixel of `window`.
    pub target: u32,
    /// Tile edge; `done` has one entry per tile of `region`.
    pub tile: u32,
    /// Samples finished per tile, from `samples[0]`; all equal to the range length once the
    /// part is complete.
    pub done: Vec<u32>,
}

/// A partial render: its header and its sums.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    pub header: Header,
    pub sums: Vec<[u64; 3]>,
}

fn rect(r: PixelRect) -> [u32; 4] {
    [r.x0, r.y0, r.width, r.height]
}

fn unrect(r: [u32; 4]) -> PixelRect {
    PixelRect {
        x0: r[0],
        y0: r[1],
        width: r[2],
        height: r[3],
    }
}

/// Checksum of a byte string, eight bytes at a time through `mix64`.
fn checksum(bytes: &[u8]) -> u64 {
    let mut h = mix64(bytes.len() as u64 ^ 0x5eed);
    for chunk in bytes.chunks(8) {
        let mut word = [0u8; 8];
        word[..chunk.len()].copy_from_slice(chunk);
        h = mix64(h ^ u64::from_le_bytes(word));
    }
    h
}

impl Part {
    /// The part holding `progress` of `scene`, one piece of an image of `target` samples
    /// per pixel.
    pub fn from_progress(scene: &Scene, progress: &Progress, target: u32) -> Part {
        let s = &scene.settings;
        Part {
            header: Header {
                version: VERSION,
                fingerprint: format!("{:016x}", scene.fingerprint()),
                seed: s.seed,
                width: s.width,
                height: s.height,
                max_depth: s.max_depth,
                gamma: s.gamma,
                window: rect(s.window),
                region: rect(progress.job.region),
                samples: [progress.job.samples.start, progress.job.samples.end],
                target,
                tile: progress.tile,
                done: progress.done.clone(),
            },
            sums: progress.sums.clone(),
        }
    }

    pub fn region(&self) -> PixelRect {
        unrect(self.header.region)
    }

    pub fn samples(&self) -> SampleRange {
        SampleRange {
            start: self.header.samples[0],
            end: self.header.samples[1],
        }
    }

    pub fn is_complete(&self) -> bool {
        let len = self.samples().len();
        self.header.done.iter().all(|&d| d >= len)
    }

    /// The render state this part records, to resume or extend it.
    pub fn progress(&self) -> Progress {
        Progress {
            job: Job {
                region: self.region(),
                samples: self.samples(),
            },
            tile: self.header.tile,
            done: self.header.done.clone(),
            sums: self.sums.clone(),
        }
    }

    /// Refuses a part made from another scene or other settings than `scene`'s.
    pub fn check_scene(&self, scene: &Scene, path: &Path) -> Result<()> {
        let expected = &scene.settings;
        let fingerprint = format!("{:016x}", scene.fingerprint());
        let h = &self.header;
        let mismatch = |what: &str, theirs: String, ours: String| {
            Err(part_error(
                path,
                format!("was rendered with a different {what} ({theirs}, this render has {ours})"),
            ))
        };
        if h.fingerprint != fingerprint {
            if (h.width, h.height) != (expected.width, expected.height) {
                return mismatch(
                    "image size",
                    format!("{}x{}", h.width, h.height),
                    format!("{}x{}", expected.width, expected.height),
                );
            }
            if h.seed != expected.seed {
                return mismatch("seed", h.seed.to_string(), expected.seed.to_string());
            }
            if h.max_depth != expected.max_depth {
                return mismatch(
                    "depth",
                    h.max_depth.to_string(),
                    expected.max_depth.to_string(),
                );
            }
            return mismatch("scene", h.fingerprint.clone(), fingerprint);
        }
        if h.window != rect(expected.window) {
            return mismatch(
                "crop window",
                format!("{:?}", h.window),
                format!("{:?}", rect(expected.window)),
            );
        }
        Ok(())
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let header = serde_json::to_vec(&self.header).expect("header serialises");
        let mut out = Vec::with_capacity(16 + 8 + header.len() + self.sums.len() * 24 + 8);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(header.len() as u64).to_le_bytes());
        out.extend_from_slice(&header);
        for px in &self.sums {
            for c in px {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        let sum = checksum(&out);
        out.extend_from_slice(&sum.to_le_bytes());
        out
    }

    /// Parses and checks a part; `path` names it in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Part> {
        let fail = |message: String| Err(part_error(path, message));
        if bytes.len() < 16 || &bytes[..16] != MAGIC {
            return fail("is not a tessera partial render (no TESSERA-PARTIAL header)".to_owned());
        }
        if bytes.len() < 24 + 8 {
            return fail(format!("is truncated ({} bytes)", bytes.len()));
        }
        let header_len = u64::from_le_bytes(bytes[16..24].try_into().expect("8 bytes"));
        let header_end = 24u64.saturating_add(header_len);
        if header_end > bytes.len() as u64 {
            return fail(format!(
                "is truncated ({} bytes, header alone needs {header_end})",
                bytes.len()
            ));
        }
        let header_end = header_end as usize;
        let header: Header = match serde_json::from_slice(&bytes[24..header_end]) {
            Ok(h) => h,
            Err(e) => return fail(format!("has a corrupt header: {e}")),
        };
        if header.version != VERSION {
            return fail(format!(
                "has format version {}, this tessera reads {VERSION}",
                header.version
            ));
        }
        let region = unrect(header.region);
        let window = unrect(header.window);
        let image = PixelRect::full(header.width, header.height);
        if image.area() > crate::scene::MAX_PIXELS
            || !image.contains(&window)
            || !window.contains(&region)
            || region.area() == 0
        {
            return fail(format!(
                "has an impossible region {:?} for window {:?} of a {}x{} image",
                header.region, header.window, header.width, header.height
            ));
        }
        let len = header.samples[1].saturating_sub(header.samples[0]);
        if header.samples[1] < header.samples[0]
            || header.tile == 0
            || header.done.len() != region.tiles(header.tile).len()
            || header.done.iter().any(|&d| d > len)
        {
            return fail("has an inconsistent header (samples, tiles or progress)".to_owned());
        }
        let expected = (header_end as u64).saturating_add(region.area().saturating_mul(24)) + 8;
        if bytes.len() as u64 != expected {
            return fail(format!(
                "is truncated or padded ({} bytes, expected {expected})",
                bytes.len()
            ));
        }
        let body_end = bytes.len() - 8;
        let stored = u64::from_le_bytes(bytes[body_end..].try_into().expect("8 bytes"));
        if checksum(&bytes[..body_end]) != stored {
            return fail("is corrupt (checksum mismatch)".to_owned());
        }
        let sums = bytes[header_end..body_end]
            .chunks_exact(24)
            .map(|px| {
                let w = |i: usize| {
                    u64::from_le_bytes(px[i * 8..i * 8 + 8].try_into().expect("8 bytes"))
                };
                [w(0), w(1), w(2)]
            })
            .collect();
        Ok(Part { header, sums })
    }

    pub fn load(path: &Path) -> Result<Part> {
        let bytes = std::fs::read(path).map_err(|cause| Error::Io {
            path: path.to_owned(),
            cause,
        })?;
        Part::from_bytes(&bytes, path)
    }

    /// Writes the part atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        crate::film::write_atomically(path, &self.to_bytes())
    }
}

fn part_error(path: &Path, message: String) -> Error {
    Error::Partial {
        path: path.to_owned(),
        message,
    }
}

/// Adds complete parts of one render into the image they cover together. They must share
/// scene and settings, be finished, overlap nowhere (no pixel gets a sample index twice) and
/// cover the whole window over sample indices `0..N` for one `N`. Returns the image (with
/// `N` samples per pixel) and its gamma.
pub fn merge(parts: &[(PathBuf, Part)]) -> Result<(Film, f32)> {
    let Some((first_path, first)) = parts.first() else {
        return Err(Error::Merge("no partial renders given".to_owned()));
    };
    let base = &first.header;
    for (path, part) in parts {
        let h = &part.header;
        let same = h.fingerprint == base.fingerprint
            && h.seed == base.seed
            && (h.width, h.height, h.max_depth) == (base.width, base.height, base.max_depth)
            && h.gamma.to_bits() == base.gamma.to_bits()
            && h.window == base.window
            && h.target == base.target;
        if !same {
            let what = if h.seed != base.seed {
                format!("seed {} (vs {})", h.seed, base.seed)
            } else if h.target != base.target {
                format!(
                    "sample count: an image of {} spp (vs {})",
                    h.target, base.target
                )
            } else if (h.width, h.height) != (base.width, base.height) {
                format!(
                    "size {}x{} (vs {}x{})",
                    h.width, h.height, base.width, base.height
                )
            } else {
                format!(
                    "scene or settings (fingerprint {} vs {})",
                    h.fingerprint, base.fingerprint
                )
            };
            return Err(part_error(
                path,
                format!(
                    "belongs to another render than {}: different {what}",
                    first_path.display()
                ),
            ));
        }
        if !part.is_complete() {
            let (region, len) = (part.region(), part.samples().len());
            let done = samples_done(region, part.header.tile, &part.header.done, len);
            let total = region.area() * u64::from(len);
            return Err(part_error(
                path,
                format!(
                    "is an unfinished render ({:.1}% done); finish it by running its render command again",
                    percent(done, total)
                ),
            ));
        }
    }
    for (i, (path_a, a)) in parts.iter().enumerate() {
        for (path_b, b) in &parts[i + 1..] {
            let (ra, rb) = (a.region(), b.region());
            let pixels_meet = ra.x0 < rb.x0 + rb.width
                && rb.x0 < ra.x0 + ra.width
                && ra.y0 < rb.y0 + rb.height
                && rb.y0 < ra.y0 + ra.height;
            let (sa, sb) = (a.samples(), b.samples());
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
    let window = unrect(base.window);
    let total = base.target;
    if let Some((path, p)) = parts.iter().find(|(_, p)| p.samples().end > total) {
        return Err(part_error(
            path,
            format!(
                "holds samples up to {}, past the {total} of the image",
                p.samples().end
            ),
        ));
    }
    let covered: u128 = parts
        .iter()
        .map(|(_, p)| u128::from(p.region().area()) * u128::from(p.samples().len()))
        .sum();
    let needed = u128::from(window.area()) * u128::from(total);
    if covered != needed {
        let listing: Vec<String> = parts
            .iter()
            .map(|(path, p)| {
                let (r, s) = (p.region(), p.samples());
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
    let mut film = Film::new(window.width, window.height, total);
    for (_, part) in parts {
        add_sums(&mut film.sums, window, &part.sums, part.region());
    }
    Ok((film, base.gamma))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(region: PixelRect, samples: [u32; 2]) -> Part {
        let job = Job {
            region,
            samples: SampleRange {
                start: samples[0],
                end: samples[1],
            },
        };
        let mut progress = Progress::new(job, 4);
        progress
            .done
            .iter_mut()
            .for_each(|d| *d = job.samples.len());
        progress
            .sums
            .iter_mut()
            .enumerate()
            .for_each(|(i, s)| *s = [i as u64, 1, 2]);
        Part {
            header: Header {
                version: VERSION,
                fingerprint: "00".to_owned(),
                seed: 1,
                width: 8,
                height: 6,
                max_depth: 5,
                gamma: 2.0,
                window: [0, 0, 8, 6],
                region: rect(region),
                samples,
                target: 9,
                tile: 4,
                done: progress.done.clone(),
            },
            sums: progress.sums,
        }
    }

    #[test]
    fn bytes_round_trip() {
        let p = part(
            PixelRect {
                x0: 2,
                y0: 1,
                width: 5,
                height: 4,
            },
            [3, 9],
        );
        let bytes = p.to_bytes();
        assert_eq!(Part::from_bytes(&bytes, Path::new("p")).unwrap(), p);
    }

    #[test]
    fn every_truncation_and_every_flipped_byte_is_caught() {
        let bytes = part(
            PixelRect {
                x0: 0,
                y0: 0,
                width: 3,
                height: 2,
            },
            [0, 4],
        )
        .to_bytes();
        for len in 0..bytes.len() {
            assert!(
                Part::from_bytes(&bytes[..len], Path::new("p")).is_err(),
                "truncated to {len}"
            );
        }
        for i in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[i] ^= 0x10;
            assert!(
                Part::from_bytes(&bad, Path::new("p")).is_err(),
                "byte {i} flipped"
            );
        }
    }

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
