//! The tone map: a pixel's mean radiance from its exact sum and sample count, and the book's
//! 8-bit encoding of it. The image writer and the live preview both go through here, so a
//! preview of a finished pixel shows the very byte the image file holds.

use crate::film::ONE;

/// The factor that turns a fixed-point sum of `samples` samples into their mean radiance.
#[inline]
pub fn mean_scale(samples: u32) -> f64 {
    1.0 / (ONE * f64::from(samples.max(1)))
}

/// The mean radiance of a channel whose fixed-point sum is `sum`, with `scale` from
/// `mean_scale`.
#[inline]
pub fn mean(sum: u64, scale: f64) -> f32 {
    (sum as f64 * scale) as f32
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::to_fixed;

    #[test]
    fn eight_bit_encoding_matches_the_book() {
        assert_eq!(encode_8bit(0.0, 2.0), 0);
        assert_eq!(encode_8bit(1.0, 2.0), 255);
        assert_eq!(encode_8bit(0.25, 2.0), 128);
        assert_eq!(encode_8bit(0.25, 1.0), 64);
        assert_eq!(encode_8bit(7.0, 1.0), 255);
    }

    #[test]
    fn means_undo_the_fixed_point() {
        let sum = to_fixed(0.25) * 4;
        assert_eq!(mean(sum, mean_scale(4)), 0.25);
        assert_eq!(mean(to_fixed(3.0), mean_scale(1)), 3.0);
        // No samples yet reads as one, not a division by zero.
        assert_eq!(mean(0, mean_scale(0)), 0.0);
    }
}
