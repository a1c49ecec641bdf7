//! Image files from a film: the formats (PNG, PPM, EXR) and their encoders, each pixel's value
//! taken through the tone map; files are written atomically.

use crate::atomic_file::write_atomically_with;
use crate::error::{Error, Result};
use crate::film::Film;
use crate::tonemap::{encode_8bit, mean, mean_scale};
use std::io::Write;
use std::path::Path;

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
    /// The mean linear radiance of each pixel, row-major, computed from the sums as they are
    /// read (every output format goes through here).
    pub(crate) fn pixels(&self) -> impl Iterator<Item = [f32; 3]> + '_ {
        let scale = mean_scale(self.samples_per_pixel);
        self.sums.iter().map(move |s| s.map(|c| mean(c, scale)))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::to_fixed;

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
}
