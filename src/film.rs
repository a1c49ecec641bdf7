//! The image being accumulated: exact fixed-point sums of sample radiance per pixel, how they
//! are added and hashed. What they look like is `tonemap`'s business, and files are
//! `image_file`'s.

use crate::math::PixelRect;

/// Fractional bits of the fixed-point radiance sums. Integer sums are associative, so the
/// total of a pixel does not depend on how its samples were grouped or ordered; 2⁻²⁴ is far
/// below what 8-bit or half-float output can show.
pub const FRAC_BITS: u32 = 24;
pub(crate) const ONE: f64 = (1u64 << FRAC_BITS) as f64;
/// Per-sample radiance is clamped to this, which bounds a sum of fewer than 2²⁰ samples
/// below 2⁶⁴; a larger sum stays at 2⁶⁴ - 1, the brightest value (every sum saturates).
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

impl Film {
    pub fn new(width: u32, height: u32, samples_per_pixel: u32) -> Self {
        Self {
            width,
            height,
            samples_per_pixel,
            sums: vec![[0; 3]; width as usize * height as usize],
        }
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
}
