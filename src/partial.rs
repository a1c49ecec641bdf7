//! Partial renders on disk — shards and checkpoints — and merging them: a self-describing
//! binary file of exact fixed-point sums, so merged parts give the bytes of a single render.
//!
//! Layout: the 16-byte magic `TESSERA-PARTIAL\n`, the header length (u64, little endian),
//! the header as JSON, the region's sums (three u64 per pixel, row-major, little endian), and
//! a checksum (u64) of everything before it. Sums are integers, so adding parts in any order
//! gives exactly the sums of one uninterrupted render.

use crate::error::{Error, Result};
use crate::film::{Film, add_run, add_sums};
use crate::math::PixelRect;
use crate::render::{Job, Progress, SampleRange, percent, samples_done};
use crate::sampling::mix64;
use crate::scene::Scene;
use serde::{Deserialize, Serialize};
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 16] = b"TESSERA-PARTIAL\n";
const VERSION: u32 = 1;
/// Bytes before the header: the magic and the header's length.
const PREAMBLE: u64 = 24;
/// Bytes of the trailing checksum.
const CHECKSUM: u64 = 8;
/// Bytes of one pixel's sums.
const PIXEL: u64 = 24;
/// Pixels read at a time when a part's sums are streamed.
const CHUNK_PIXELS: usize = 1 << 14;

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

impl Header {
    pub fn region(&self) -> PixelRect {
        unrect(self.region)
    }

    pub fn samples(&self) -> SampleRange {
        SampleRange {
            start: self.samples[0],
            end: self.samples[1],
        }
    }

    pub fn is_complete(&self) -> bool {
        let len = self.samples().len();
        self.done.iter().all(|&d| d >= len)
    }

    /// The length in bytes of a file with this header, once it is known to be consistent.
    fn file_len(&self, header_len: u64) -> u64 {
        PREAMBLE + header_len + self.region().area() * PIXEL + CHECKSUM
    }

    /// Checks the header's claims against each other, so nothing sized by them is
    /// allocated before they are known to be sane.
    fn check(&self, path: &Path) -> Result<()> {
        let fail = |message: String| Err(part_error(path, message));
        if self.version != VERSION {
            return fail(format!(
                "has format version {}, this tessera reads {VERSION}",
                self.version
            ));
        }
        let region = self.region();
        let window = unrect(self.window);
        let image = PixelRect::full(self.width, self.height);
        if image.area() > crate::scene::MAX_PIXELS
            || !image.contains(&window)
            || !window.contains(&region)
            || region.area() == 0
        {
            return fail(format!(
                "has an impossible region {:?} for window {:?} of a {}x{} image",
                self.region, self.window, self.width, self.height
            ));
        }
        let len = self.samples().len();
        if self.samples[1] < self.samples[0]
            || self.tile == 0
            || self.done.len() as u64 != region.tile_count(self.tile)
            || self.done.iter().any(|&d| d > len)
        {
            return fail("has an inconsistent header (samples, tiles or progress)".to_owned());
        }
        Ok(())
    }
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

/// Checksum of a byte string of known length, fed in pieces: eight bytes at a time through
/// `mix64`, the last word padded with zeros.
struct Checksum {
    hash: u64,
    word: [u8; 8],
    filled: usize,
}

impl Checksum {
    fn new(total_len: u64) -> Self {
        Self {
            hash: mix64(total_len ^ 0x5eed),
            word: [0; 8],
            filled: 0,
        }
    }

    fn update(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let take = (8 - self.filled).min(bytes.len());
            self.word[self.filled..self.filled + take].copy_from_slice(&bytes[..take]);
            self.filled += take;
            bytes = &bytes[take..];
            if self.filled == 8 {
                self.hash = mix64(self.hash ^ u64::from_le_bytes(self.word));
                self.filled = 0;
            }
        }
    }

    fn finish(mut self) -> u64 {
        if self.filled > 0 {
            self.word[self.filled..].fill(0);
            self.hash = mix64(self.hash ^ u64::from_le_bytes(self.word));
        }
        self.hash
    }
}

/// A part file opened for reading: its header read and checked against the file's real
/// length, its sums not yet read. Every size the header claims is checked before anything
/// of that size is allocated, so a small crafted file cannot make a reader ask for gigabytes.
pub struct PartReader<R> {
    path: PathBuf,
    header: Header,
    reader: R,
    checksum: Checksum,
}

impl PartReader<BufReader<std::fs::File>> {
    /// Opens the part file at `path` and reads its header.
    pub fn open(path: &Path) -> Result<Self> {
        let io = |cause| Error::Io {
            path: path.to_owned(),
            cause,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        PartReader::new(BufReader::new(file), len, path)
    }
}

impl<R: Read> PartReader<R> {
    /// Reads and checks the header of the `len`-byte part that `reader` holds; `path` names
    /// it in errors.
    pub fn new(mut reader: R, len: u64, path: &Path) -> Result<Self> {
        let fail = |message: String| Err(part_error(path, message));
        let mut preamble = [0u8; PREAMBLE as usize];
        let got = read_up_to(&mut reader, &mut preamble, path)?;
        if got < MAGIC.len() || preamble[..MAGIC.len()] != MAGIC[..] {
            return fail("is not a tessera partial render (no TESSERA-PARTIAL header)".to_owned());
        }
        if got < preamble.len() || len < PREAMBLE + CHECKSUM {
            return fail(format!("is truncated ({len} bytes)"));
        }
        let header_len = u64::from_le_bytes(preamble[16..].try_into().expect("8 bytes"));
        if header_len > len - PREAMBLE - CHECKSUM {
            return fail(format!(
                "is truncated ({len} bytes, its header alone claims {header_len})"
            ));
        }
        let mut text = vec![0u8; header_len as usize];
        if read_up_to(&mut reader, &mut text, path)? < text.len() {
            return fail(format!("is truncated ({len} bytes)"));
        }
        let header: Header = match serde_json::from_slice(&text) {
            Ok(h) => h,
            Err(e) => return fail(format!("has a corrupt header: {e}")),
        };
        header.check(path)?;
        let expected = header.file_len(header_len);
        if len != expected {
            return fail(format!(
                "is truncated or padded ({len} bytes, expected {expected})"
            ));
        }
        let mut checksum = Checksum::new(len - CHECKSUM);
        checksum.update(&preamble);
        checksum.update(&text);
        Ok(Self {
            path: path.to_owned(),
            header,
            reader,
            checksum,
        })
    }

    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Reads the sums, row-major over the region, handing them to `each` a chunk at a time,
    /// then checks the checksum. What `each` was given is sound only if this returns `Ok`.
    pub fn read_sums(mut self, mut each: impl FnMut(&[[u64; 3]])) -> Result<()> {
        let mut left = self.header.region().area();
        let mut bytes = vec![0u8; CHUNK_PIXELS.min(left as usize) * PIXEL as usize];
        let mut sums = Vec::with_capacity(CHUNK_PIXELS.min(left as usize));
        while left > 0 {
            let n = CHUNK_PIXELS.min(left as usize);
            let chunk = &mut bytes[..n * PIXEL as usize];
            self.read_exact(chunk)?;
            self.checksum.update(chunk);
            sums.clear();
            sums.extend(chunk.chunks_exact(PIXEL as usize).map(|px| {
                let word = |i: usize| {
                    u64::from_le_bytes(px[i * 8..i * 8 + 8].try_into().expect("8 bytes"))
                };
                [word(0), word(1), word(2)]
            }));
            each(&sums);
            left -= n as u64;
        }
        let mut stored = [0u8; CHECKSUM as usize];
        self.read_exact(&mut stored)?;
        if self.checksum.finish() != u64::from_le_bytes(stored) {
            return Err(part_error(
                &self.path,
                "is corrupt (checksum mismatch)".to_owned(),
            ));
        }
        Ok(())
    }

    /// The header and all the sums.
    pub fn read_part(self) -> Result<Part> {
        let header = self.header.clone();
        let mut sums = Vec::with_capacity(header.region().area() as usize);
        self.read_sums(|chunk| sums.extend_from_slice(chunk))?;
        Ok(Part { header, sums })
    }

    fn read_exact(&mut self, buf: &mut [u8]) -> Result<()> {
        if read_up_to(&mut self.reader, buf, &self.path)? < buf.len() {
            return Err(part_error(
                &self.path,
                "is truncated (it changed while being read)".to_owned(),
            ));
        }
        Ok(())
    }
}

/// Fills `buf` from `reader` as far as it goes; returns the bytes read.
fn read_up_to(reader: &mut impl Read, buf: &mut [u8], path: &Path) -> Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(cause) => {
                return Err(Error::Io {
                    path: path.to_owned(),
                    cause,
                });
            }
        }
    }
    Ok(filled)
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
        self.header.region()
    }

    pub fn samples(&self) -> SampleRange {
        self.header.samples()
    }

    pub fn is_complete(&self) -> bool {
        self.header.is_complete()
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
        let mut sum = Checksum::new(out.len() as u64);
        sum.update(&out);
        out.extend_from_slice(&sum.finish().to_le_bytes());
        out
    }

    /// Parses and checks a part; `path` names it in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Part> {
        PartReader::new(bytes, bytes.len() as u64, path)?.read_part()
    }

    pub fn load(path: &Path) -> Result<Part> {
        PartReader::open(path)?.read_part()
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

/// What a set of parts makes once merged: the window, its samples per pixel, its gamma.
struct Whole {
    window: PixelRect,
    samples_per_pixel: u32,
    gamma: f32,
}

/// Checks, from their headers alone, that parts add up to one whole render: they share
/// scene and settings, are finished, overlap nowhere (no pixel gets a sample index twice) and
/// cover the whole window over sample indices `0..N` for one `N`.
fn check_set(parts: &[(&Path, &Header)]) -> Result<Whole> {
    let Some(&(first_path, base)) = parts.first() else {
        return Err(Error::Merge("no partial renders given".to_owned()));
    };
    for &(path, h) in parts {
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
        if !h.is_complete() {
            let (region, len) = (h.region(), h.samples().len());
            let done = samples_done(region, h.tile, &h.done, len);
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
    for (i, &(path_a, a)) in parts.iter().enumerate() {
        for &(path_b, b) in &parts[i + 1..] {
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
    if let Some(&(path, p)) = parts.iter().find(|(_, p)| p.samples().end > total) {
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
    Ok(Whole {
        window,
        samples_per_pixel: total,
        gamma: base.gamma,
    })
}

/// Adds complete parts of one render, already in memory, into the image they cover together
/// (see `check_set` for what they must be). Returns the image and its gamma.
pub fn merge(parts: &[(PathBuf, Part)]) -> Result<(Film, f32)> {
    let headers: Vec<(&Path, &Header)> = parts
        .iter()
        .map(|(path, part)| (path.as_path(), &part.header))
        .collect();
    let whole = check_set(&headers)?;
    let mut film = whole.film();
    for (_, part) in parts {
        add_sums(&mut film.sums, whole.window, &part.sums, part.region());
    }
    Ok((film, whole.gamma))
}

/// Merges the part files `paths` into the image they cover together (see `check_set`),
/// reading one part at a time a chunk at a time: memory stays about one image whatever the
/// number of parts. Every part is checked, by its header, before any sums are read.
pub fn merge_files(paths: &[PathBuf]) -> Result<(Film, f32)> {
    let headers = paths
        .iter()
        .map(|path| Ok((path.as_path(), PartReader::open(path)?.header)))
        .collect::<Result<Vec<(&Path, Header)>>>()?;
    let refs: Vec<(&Path, &Header)> = headers.iter().map(|(p, h)| (*p, h)).collect();
    let whole = check_set(&refs)?;
    let mut film = whole.film();
    for (path, header) in &headers {
        let reader = PartReader::open(path)?;
        if reader.header() != header {
            return Err(part_error(path, "changed while being merged".to_owned()));
        }
        let region = header.region();
        let mut at = 0;
        reader.read_sums(|run| {
            add_run(&mut film.sums, whole.window, region, at, run);
            at += run.len() as u64;
        })?;
    }
    Ok((film, whole.gamma))
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
