//! The image being accumulated: exact fixed-point sums of sample radiance per pixel, the tone
//! map to 8-bit, and the only code that writes image files (always whole or not at all).

use crate::error::{Error, Result};
use crate::math::PixelRect;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Fractional bits of the fixed-point radiance sums. Integer sums are associative, so the
/// total of a pixel does not depend on how its samples were grouped or ordered; 2⁻²⁴ is far
/// below what 8-bit or half-float output can show.
pub const FRAC_BITS: u32 = 24;
const ONE: f64 = (1u64 << FRAC_BITS) as f64;
/// Per-sample radiance is clamped to this, which bounds a sum of 2²⁰ samples below 2⁶⁴.
const MAX_SAMPLE: f32 = (1u32 << 20) as f32;

/// Converts one sample's channel to fixed point; NaN and negative values count as zero.
#[inline]
pub fn to_fixed(c: f32) -> u64 {
    // Selects, not branches: NaN and negatives to zero, then the clamp (each one
    // instruction on x86, where `f32::max`/`min` take several for their NaN rule).
    let c = if c > 0.0 { c } else { 0.0 };
    let c = if c < MAX_SAMPLE { c } else { MAX_SAMPLE };
    // Round half up; `f64::round` is a library call, this is two instructions (zero stays
    // zero). Through i64: x86 converts to signed integers in one instruction, unsigned in
    // many.
    (f64::from(c) * ONE + 0.5) as i64 as u64
}

/// `count` zero sums, written now rather than left to the allocator's zero pages: a page
/// first read then written during a render faults twice, and the second fault flushes that
/// page's mapping from every core running the render (an interrupt per page on each worker).
pub fn zeroed_sums(count: usize) -> Vec<[u64; 3]> {
    let mut sums = Vec::with_capacity(count);
    sums.resize(count, [0; 3]);
    sums
}

/// An image of per-pixel radiance sums over `samples_per_pixel` samples each.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub samples_per_pixel: u32,
    /// Row-major, top row first; fixed-point sums of R, G and B.
    pub sums: Vec<[u64; 3]>,
}

/// An image file format, chosen by the output path's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// 8-bit, gamma-encoded PNG.
    Png,
    /// Plain-text P3 PPM, written as the book writes it.
    Ppm,
    /// Linear 32-bit float OpenEXR.
    Exr,
}

impl Format {
    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(Format::Png),
            Some("ppm") => Ok(Format::Ppm),
            Some("exr") => Ok(Format::Exr),
            other => Err(Error::Image {
                path: path.to_owned(),
                message: format!(
                    "unsupported output extension {}; use .png, .ppm or .exr",
                    other.map_or("(none)".to_owned(), |e| format!("`.{e}`"))
                ),
            }),
        }
    }
}

impl Film {
    pub fn new(width: u32, height: u32, samples_per_pixel: u32) -> Self {
        Self {
            width,
            height,
            samples_per_pixel,
            sums: vec![[0; 3]; width as usize * height as usize],
        }
    }

    /// The mean linear radiance of each pixel, row-major, computed from the sums as they are
    /// read (every output format goes through here).
    fn pixels(&self) -> impl Iterator<Item = [f32; 3]> + '_ {
        let scale = 1.0 / (ONE * f64::from(self.samples_per_pixel.max(1)));
        self.sums
            .iter()
            .map(move |s| s.map(|c| (c as f64 * scale) as f32))
    }

    /// The 8-bit values of each pixel, row-major (see `encode_8bit`).
    fn pixels_8bit(&self, gamma: f32) -> impl Iterator<Item = [u8; 3]> + '_ {
        self.pixels().map(move |p| p.map(|c| encode_8bit(c, gamma)))
    }

    /// Mean linear radiance of every pixel, row-major RGB.
    pub fn linear(&self) -> Vec<f32> {
        self.pixels().flatten().collect()
    }

    /// 8-bit values as the book computes them: `256 · clamp(c^(1/γ), 0, 0.999)`, made
    /// straight from the sums (no image of floats in between).
    pub fn to_rgb8(&self, gamma: f32) -> Vec<u8> {
        let mut rgb = Vec::with_capacity(self.sums.len() * 3);
        for p in self.pixels_8bit(gamma) {
            rgb.extend(p);
        }
        rgb
    }

    /// Mean radiance over all pixels and channels, summed in a fixed order.
    pub fn mean_radiance(&self) -> f64 {
        let total: u128 = self
            .sums
            .iter()
            .map(|s| s.iter().map(|&c| u128::from(c)).sum::<u128>())
            .sum();
        total as f64
            / (ONE * f64::from(self.samples_per_pixel.max(1)) * 3.0 * self.sums.len().max(1) as f64)
    }

    /// XXH3-128 of the image's exact content: width, height and samples per pixel (u32), then
    /// every pixel's fixed-point sums (u64), all little endian, row by row. Equal hashes mean
    /// equal images, bit for bit, whatever the machine; `tessera bench` validates with it.
    pub fn content_hash(&self) -> u128 {
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        for n in [self.width, self.height, self.samples_per_pixel] {
            hasher.update(&n.to_le_bytes());
        }
        write_sums_le(&self.sums, &mut |bytes| {
            hasher.update(bytes);
            Ok(())
        })
        .expect("hashing cannot fail");
        hasher.digest128()
    }

    /// Encodes the image in `format`.
    pub fn encode(&self, format: Format, gamma: f32) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        self.write(format, gamma, &mut out)
            .map_err(|e| e.to_string())?;
        Ok(out)
    }

    /// Writes the image in `format` to `out`, holding as little beside the sums as the format
    /// allows: PPM goes pixel by pixel, PNG needs one byte per channel, EXR a float per
    /// channel and its encoding.
    pub fn write(&self, format: Format, gamma: f32, out: &mut dyn Write) -> std::io::Result<()> {
        let (w, h) = (self.width, self.height);
        let encoder_error = |e: image::ImageError| std::io::Error::other(e.to_string());
        match format {
            Format::Ppm => {
                write!(out, "P3\n{w} {h}\n255\n")?;
                for [r, g, b] in self.pixels_8bit(gamma) {
                    writeln!(out, "{r} {g} {b}")?;
                }
                Ok(())
            }
            Format::Png => {
                use image::ImageEncoder;
                image::codecs::png::PngEncoder::new(out)
                    .write_image(&self.to_rgb8(gamma), w, h, image::ExtendedColorType::Rgb8)
                    .map_err(encoder_error)
            }
            Format::Exr => {
                let img = image::Rgb32FImage::from_raw(w, h, self.linear())
                    .ok_or_else(|| std::io::Error::other("image buffer has the wrong size"))?;
                let mut encoded = std::io::Cursor::new(Vec::new());
                img.write_to(&mut encoded, image::ImageFormat::OpenExr)
                    .map_err(encoder_error)?;
                out.write_all(encoded.get_ref())
            }
        }
    }

    /// Writes the image to `path` in the format its extension names, atomically.
    pub fn save(&self, path: &Path, gamma: f32) -> Result<()> {
        let format = Format::from_path(path)?;
        write_atomically_with(path, &mut |out| self.write(format, gamma, out))
    }
}

/// Hands `sums` to `write` as little-endian bytes (three u64 per pixel, in order), a chunk of
/// pixels at a time: the layout of part files and of `Film::content_hash`.
pub fn write_sums_le(
    sums: &[[u64; 3]],
    write: &mut dyn FnMut(&[u8]) -> std::io::Result<()>,
) -> std::io::Result<()> {
    const CHUNK_PIXELS: usize = 1 << 14;
    let mut chunk = Vec::with_capacity(CHUNK_PIXELS.min(sums.len()) * 24);
    for pixels in sums.chunks(CHUNK_PIXELS) {
        chunk.clear();
        for c in pixels.iter().flatten() {
            chunk.extend_from_slice(&c.to_le_bytes());
        }
        write(&chunk)?;
    }
    Ok(())
}

/// Adds `sums`, the row-major sums of the pixels `rect`, into `into`, the row-major sums of
/// the pixels `frame`, which contains `rect`. Integer addition: the order never matters.
pub fn add_sums(into: &mut [[u64; 3]], frame: PixelRect, sums: &[[u64; 3]], rect: PixelRect) {
    add_run(into, frame, rect, 0, sums);
}

/// Adds `run`, the sums of consecutive pixels of `rect` in row-major order from its
/// `start`-th pixel, into `into`, the row-major sums of the pixels `frame`, which contains
/// `rect`. Saturating integer addition: the order never matters, and a sum too large for 64
/// bits stays the brightest value instead of wrapping round to black.
pub fn add_run(
    into: &mut [[u64; 3]],
    frame: PixelRect,
    rect: PixelRect,
    start: u64,
    mut run: &[[u64; 3]],
) {
    debug_assert!(frame.contains(&rect));
    let width = u64::from(rect.width);
    let mut at = start;
    while !run.is_empty() {
        let (row, column) = (at / width, at % width);
        let n = ((width - column) as usize).min(run.len());
        let y = (rect.y0 - frame.y0) as usize + row as usize;
        let begin = y * frame.width as usize + (rect.x0 - frame.x0) as usize + column as usize;
        for (acc, add) in into[begin..begin + n].iter_mut().zip(&run[..n]) {
            for c in 0..3 {
                acc[c] = acc[c].saturating_add(add[c]);
            }
        }
        run = &run[n..];
        at += n as u64;
    }
}

/// `256 · clamp(c^(1/γ), 0, 0.999)`, truncated, as the book's `write_color`.
#[inline]
pub fn encode_8bit(c: f32, gamma: f32) -> u8 {
    let c = if gamma == 2.0 {
        c.max(0.0).sqrt()
    } else if gamma == 1.0 {
        c
    } else {
        crate::math::pow(c, 1.0 / gamma)
    };
    (256.0 * c.clamp(0.0, 0.999)) as u8
}

/// The temporary file beside `path` that `write_atomically` writes first.
fn temporary_beside(path: &Path) -> Result<PathBuf> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().ok_or_else(|| Error::Image {
        path: path.to_owned(),
        message: "output path has no file name".to_owned(),
    })?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    Ok(dir.join(tmp_name))
}

/// True when `path` exists and is neither a file nor a directory: a device such as
/// `/dev/null`, or a pipe.
fn is_special(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Checks, before any work is spent on it, that `write_atomically` can write `path`: its
/// directory exists and takes a new file, and `path` is not a directory.
pub fn check_writable(path: &Path) -> Result<()> {
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    if path.is_dir() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a directory, not a file name",
        )));
    }
    if is_special(path) {
        // Written in place; opening a pipe now would wait for its reader.
        return Ok(());
    }
    let tmp = temporary_beside(path)?;
    std::fs::File::create(&tmp).map_err(io)?;
    std::fs::remove_file(&tmp).map_err(io)
}

/// Writes `bytes` to a temporary file beside `path`, syncs it and renames it over `path`, so
/// a reader (or a crash) never sees a half-written file and an old file survives a failure.
/// A device or a pipe (`-o /dev/null`) is written in place: renaming a file over it would
/// replace the device itself.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically_with(path, &mut |out| out.write_all(bytes))
}

/// `write_atomically` of what `write` writes, streamed through a buffer rather than made
/// whole in memory first.
pub fn write_atomically_with(
    path: &Path,
    write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    let buffered =
        |file: std::fs::File, write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>| {
            let mut out = std::io::BufWriter::with_capacity(1 << 16, file);
            write(&mut out)?;
            out.into_inner()
                .map_err(std::io::IntoInnerError::into_error)
        };
    if is_special(path) {
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io)?;
        return buffered(f, write).map(drop).map_err(io);
    }
    let tmp = temporary_beside(path)?;
    let result = (|| {
        let f = buffered(std::fs::File::create(&tmp)?, write)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_point_round_trips_and_ignores_nan() {
        assert_eq!(to_fixed(1.0), 1 << FRAC_BITS);
        assert_eq!(to_fixed(f32::NAN), 0);
        assert_eq!(to_fixed(-3.0), 0);
        assert_eq!(to_fixed(f32::INFINITY), (1u64 << 20) << FRAC_BITS);
        assert_eq!(to_fixed(f32::NEG_INFINITY), 0);
        assert_eq!(to_fixed(0.0), 0);
        assert_eq!(to_fixed(-0.0), 0);
        // Half a unit of the last place rounds up; just under it, down.
        let half = 0.5 / (1u64 << FRAC_BITS) as f32;
        assert_eq!(to_fixed(half), 1);
        assert_eq!(to_fixed(half * (1.0 - f32::EPSILON)), 0);
        assert_eq!(to_fixed(3.0 * half), 2);
        assert_eq!(to_fixed(f32::MIN_POSITIVE), 0);
        assert_eq!(to_fixed(MAX_SAMPLE * 2.0), to_fixed(MAX_SAMPLE));
    }

    #[test]
    fn eight_bit_encoding_matches_the_book() {
        assert_eq!(encode_8bit(0.0, 2.0), 0);
        assert_eq!(encode_8bit(1.0, 2.0), 255);
        assert_eq!(encode_8bit(0.25, 2.0), 128);
        assert_eq!(encode_8bit(0.25, 1.0), 64);
        assert_eq!(encode_8bit(7.0, 1.0), 255);
    }

    #[test]
    fn ppm_is_the_books_plain_text() {
        let mut film = Film::new(2, 1, 1);
        film.sums[0] = [to_fixed(1.0), 0, to_fixed(0.25)];
        let text = String::from_utf8(film.encode(Format::Ppm, 1.0).unwrap()).unwrap();
        assert_eq!(text, "P3\n2 1\n255\n255 0 64\n0 0 0\n");
    }

    #[test]
    fn formats_follow_the_extension() {
        assert_eq!(Format::from_path(Path::new("a.PNG")).unwrap(), Format::Png);
        assert_eq!(Format::from_path(Path::new("a.exr")).unwrap(), Format::Exr);
        assert!(Format::from_path(Path::new("a.jpg")).is_err());
        assert!(Format::from_path(Path::new("a")).is_err());
    }

    #[test]
    fn devices_are_written_in_place_not_replaced() {
        let null = Path::new("/dev/null");
        if !is_special(null) {
            return; // not a Unix machine
        }
        check_writable(null).unwrap();
        write_atomically(null, b"into the void").unwrap();
        assert!(is_special(null), "/dev/null was replaced by a file");
        let full = write_atomically(Path::new("/dev/full"), b"x");
        assert!(full.is_err_and(|e| e.to_string().contains("/dev/full")));
    }

    #[test]
    fn atomic_write_replaces_whole_file() {
        let dir = std::env::temp_dir().join(format!("tessera-film-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.ppm");
        write_atomically(&p, b"first").unwrap();
        write_atomically(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        let leftovers = std::fs::read_dir(&dir).unwrap().count();
        assert_eq!(leftovers, 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
