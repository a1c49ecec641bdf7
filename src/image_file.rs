//! Image files from a film: the formats (PNG, PPM, EXR) and their encoders, each pixel's value
//! taken through the tone map, with the film's recipe in the format's own metadata (a PNG
//! text chunk, an EXR header attribute; PPM has none); files are written atomically. And the
//! way back: an image's recipe and pixels, read as a stranger's file, with limits.

use crate::atomic_file::write_result_atomically_with;
use crate::error::{Error, Result};
use crate::exr_header::{self, SampleType};
use crate::film::Film;
use crate::input_file::open_regular;
use crate::png_header;
use crate::recipe::{self, Recipe};
use crate::tonemap::{encode_8bit, mean, mean_scale};
use std::io::{Seek, SeekFrom, Write};
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

    /// Encodes the image in `format`, without a recipe.
    pub fn encode(&self, format: Format, gamma: f32) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        self.write(format, gamma, None, &mut out)
            .map_err(|e| e.to_string())?;
        Ok(out)
    }

    /// Writes the image in `format` to `out`, with `recipe` in its metadata where the format
    /// has any, holding as little beside the sums as the format allows: PPM goes pixel by
    /// pixel, PNG needs one byte per channel, EXR a float per channel and its encoding.
    pub fn write(
        &self,
        format: Format,
        gamma: f32,
        recipe: Option<&Recipe>,
        out: &mut dyn Write,
    ) -> std::io::Result<()> {
        let (w, h) = (self.width, self.height);
        // A recipe no reader takes is not written: the caller leaves it out, and says so.
        // Its JSON is made once, checked and written.
        let recipe = match recipe.filter(|_| format != Format::Ppm) {
            Some(recipe) => Some(
                recipe
                    .carried_json()
                    .map_err(|why| std::io::Error::new(std::io::ErrorKind::InvalidInput, why))?,
            ),
            None => None,
        };
        match format {
            Format::Ppm => {
                write!(out, "P3\n{w} {h}\n255\n")?;
                for [r, g, b] in self.pixels_8bit(gamma) {
                    writeln!(out, "{r} {g} {b}")?;
                }
                Ok(())
            }
            Format::Png => {
                let png_error = |e: png::EncodingError| std::io::Error::other(e.to_string());
                let mut encoder = png::Encoder::new(out, w, h);
                encoder.set_color(png::ColorType::Rgb);
                encoder.set_depth(png::BitDepth::Eight);
                let mut writer = encoder.write_header().map_err(png_error)?;
                if let Some(recipe) = recipe {
                    // iTXt: UTF-8 and compressed; before the pixels, where readers look.
                    let mut chunk = png::text_metadata::ITXtChunk::new(recipe::KEY, recipe);
                    chunk.compressed = true;
                    writer.write_text_chunk(&chunk).map_err(png_error)?;
                }
                writer
                    .write_image_data(&self.to_rgb8(gamma))
                    .map_err(png_error)?;
                writer.finish().map_err(png_error)
            }
            Format::Exr => {
                use exr::prelude::*;
                let linear = self.linear();
                let width = w as usize;
                let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
                    let i = 3 * (p.y() * width + p.x());
                    (linear[i], linear[i + 1], linear[i + 2])
                });
                let mut image = Image::from_channels((width, h as usize), channels);
                if let Some(recipe) = recipe {
                    // The recipe's JSON is ASCII, which EXR text holds byte for byte.
                    let text = Text::new_or_none(recipe)
                        .ok_or_else(|| std::io::Error::other("recipe is not ASCII"))?;
                    image
                        .attributes
                        .other
                        .insert(Text::from(recipe::KEY), AttributeValue::Text(text));
                }
                let mut encoded = std::io::Cursor::new(Vec::new());
                image
                    .write()
                    .to_buffered(&mut encoded)
                    .map_err(|e| std::io::Error::other(e.to_string()))?;
                out.write_all(encoded.get_ref())
            }
        }
    }

    /// Writes the image to `path` in the format its extension names, atomically, with
    /// `recipe` in its metadata where the format has any; a finished file that cannot be
    /// renamed into place is kept (`write_result_atomically_with`).
    pub fn save(&self, path: &Path, gamma: f32, recipe: Option<&Recipe>) -> Result<()> {
        let format = Format::from_path(path)?;
        write_result_atomically_with(path, &mut |out| self.write(format, gamma, recipe, out))
    }
}

/// The pixels of an image file as its format stores them.
#[derive(Clone, Debug, PartialEq)]
pub enum Pixels {
    /// 8-bit RGB, row-major.
    Rgb8(Vec<u8>),
    /// Linear 32-bit float RGB, row-major.
    Linear(Vec<f32>),
    /// Not a layout tessera writes (a program re-saved it another way): named, not read.
    Other(String),
}

/// What an image file says of itself: its size and its recipe's text, if it has one.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageHeader {
    pub format: Format,
    pub width: u32,
    pub height: u32,
    /// The recipe's text, at most `recipe::MAX_BYTES` of it, not yet checked.
    pub recipe: Option<String>,
    /// What the file holds that tessera does not write and that changes how a viewer shows
    /// the picture (an animation, a colour profile, another frame), each said in words.
    pub display_changes: Vec<String>,
    /// An EXR file's sample type (PNG: `None`).
    pub samples: Option<SampleType>,
    /// A PNG's zlib stream header (`PngHeader::zlib_header`; EXR: `None`).
    pub zlib_header: Option<[u8; 2]>,
    /// Where an EXR's chunks lie (PNG: `None`).
    pub exr_layout: Option<exr_header::ExrLayout>,
}

impl ImageHeader {
    fn of_png(h: png_header::PngHeader) -> Self {
        ImageHeader {
            format: Format::Png,
            width: h.width,
            height: h.height,
            recipe: h.recipe,
            display_changes: h.display_changes,
            samples: None,
            zlib_header: h.zlib_header,
            exr_layout: None,
        }
    }
}

fn image_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Image {
        path: path.to_owned(),
        message: message.into(),
    }
}

/// Reads the size and the recipe text of the PNG or EXR file at `path`, touching nothing
/// else: no pixel is decoded, every length is checked before anything of that length is
/// read, and a compressed recipe is inflated no further than `recipe::MAX_BYTES`.
pub fn read_header(path: &Path) -> Result<ImageHeader> {
    let header = read_any_header(path)?;
    if u64::from(header.width) * u64::from(header.height) > crate::scene::MAX_PIXELS {
        return Err(image_error(
            path,
            format!(
                "is {}x{}, more pixels than tessera makes",
                header.width, header.height
            ),
        ));
    }
    Ok(header)
}

/// `read_header` of any size.
fn read_any_header(path: &Path) -> Result<ImageHeader> {
    // An image to read is named by its extension as one to write is, but refused in a
    // reader's words: `from_path`'s "unsupported output extension" named no output here.
    let format = Format::from_path(path).map_err(|_| {
        let ext = path.extension().map(|e| e.to_string_lossy());
        image_error(
            path,
            format!(
                "is not a .png or .exr image ({}): a recipe is read from an image tessera \
                 wrote, PNG or EXR, named by its extension",
                ext.map_or("it has no extension".to_owned(), |e| format!(
                    "its extension is `.{e}`"
                ))
            ),
        )
    })?;
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    if format == Format::Ppm {
        return Err(image_error(
            path,
            "is a PPM file, which has no metadata to carry a recipe",
        ));
    }
    let mut file = open_regular(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    header_of(&mut file, len, format).map_err(|message| image_error(path, message))
}

/// The header of the `len`-byte PNG or EXR file `file` (`format`), read from its start.
fn header_of(
    file: &mut std::fs::File,
    len: u64,
    format: Format,
) -> std::result::Result<ImageHeader, String> {
    match format {
        Format::Ppm => Err("is a PPM file, which has no metadata to carry a recipe".to_owned()),
        Format::Png => png_header::read(file, len).map(ImageHeader::of_png),
        Format::Exr => {
            let h = exr_header::read(std::io::BufReader::new(&mut *file), len)?;
            let mut display_changes = h.display_changes;
            // Where the offset table points, judged before anything is rendered: a chunk
            // of none of the image's tiles or scan lines is refused, one of another's is
            // what changes how it is shown (OpenEXR refuses the file).
            if too_many_chunks(h.width, h.height, &h.layout).is_none() {
                file.seek(SeekFrom::Start(0))
                    .map_err(|e| format!("could not be read: {e}"))?;
                display_changes.extend(exr_header::misplaced_chunk(
                    &mut *file, h.width, h.height, &h.layout,
                )?);
            }
            Ok(ImageHeader {
                format,
                width: h.width,
                height: h.height,
                recipe: h.recipe,
                display_changes,
                samples: h.samples,
                zlib_header: None,
                exr_layout: Some(h.layout),
            })
        }
    }
}

/// What is said of the chunks of a `width` x `height` EXR file of `layout` when they are
/// more than its pixels are read from: tessera writes a chunk a row; a file of more, and
/// more than a file of another program is read with, is not one it wrote, and its decoder
/// would take some 72 bytes to place each (`exr_header::MAX_CHUNKS_READ`). None where they
/// are read (and their places judged).
fn too_many_chunks(width: u32, height: u32, layout: &exr_header::ExrLayout) -> Option<String> {
    let most = u64::from(height).max(exr_header::MAX_CHUNKS_READ);
    let chunks = exr_header::chunks_of(width, height, layout)?;
    (chunks > most).then(|| {
        format!(
            "{chunks} chunks (blocks of scan lines or tiles), more than the {most} read of an \
             image of {height} rows (tessera writes a chunk a row)"
        )
    })
}

/// Opens the image at `path` whose pixels are to be read, and reads its header again from
/// that handle: it must be `header` whole (size, sample type, recipe, what changes how it is
/// shown). A render takes minutes, and whoever can write where the image lies could put
/// another file at `path` meanwhile, of the same size but with another recipe or an
/// animation; the verdict is then on the file whose header was checked, or on none.
fn open_as_checked(path: &Path, header: &ImageHeader) -> Result<std::fs::File> {
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    let mut file = open_regular(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    // A decoder reads all that comes before the pixels, whatever its length, which a sparse
    // file makes as large as it likes on little disk (65,536 text chunks of 1 MiB: 64 GiB).
    // An image of its size takes at most 16 bytes a pixel (float RGB EXR), 32 a row (an
    // EXR's offset and block header for each scan line, a PNG's filter byte) and its recipe.
    let (width, height) = (u64::from(header.width), u64::from(header.height));
    let most = width * height * 16 + height * 32 + (64 << 20);
    if len > most {
        return Err(image_error(
            path,
            format!(
                "is {len} bytes long, more than the {most} an image of {}x{} takes: its pixels \
                 are not read",
                header.width, header.height
            ),
        ));
    }
    let again =
        header_of(&mut file, len, header.format).map_err(|message| image_error(path, message))?;
    if again != *header {
        return Err(image_error(
            path,
            "changed while it was checked: its header, recipe or chunks are no longer those \
             read before the render",
        ));
    }
    file.seek(SeekFrom::Start(0)).map_err(io)?;
    Ok(file)
}

/// `read_header` of PNG bytes in memory.
pub fn png_header_of(bytes: &[u8]) -> std::result::Result<ImageHeader, String> {
    png_header::read(std::io::Cursor::new(bytes), bytes.len() as u64).map(ImageHeader::of_png)
}

/// Decodes the pixels of the image at `path`, which `header` describes: as 8-bit RGB for
/// PNG, linear float RGB for EXR, or the name of another layout. Nothing larger than the
/// header's size (already checked by the caller) is allocated. The pixels are read from a
/// handle whose header is `header` whole (`open_as_checked`).
pub fn read_pixels(path: &Path, header: &ImageHeader) -> Result<Pixels> {
    let count = u64::from(header.width) * u64::from(header.height);
    if count > crate::scene::MAX_PIXELS {
        return Err(image_error(
            path,
            format!(
                "is {}x{}, more pixels than tessera makes",
                header.width, header.height
            ),
        ));
    }
    match header.format {
        Format::Ppm => Err(image_error(path, "is a PPM file")),
        Format::Png => {
            // tessera's encoder begins the pixels' zlib stream with 0x78: deflate with a
            // 32 KiB window, no preset dictionary. libpng (Firefox, GIMP) inflates with the
            // window the stream declares, so one that reaches further back than a smaller
            // window declared is a broken picture there, though this decoder, which takes
            // no notice of the window, reads it whole.
            match header.zlib_header {
                Some([0x78, flags]) if flags & 0x20 == 0 => {}
                Some([method, flags]) => {
                    return Ok(Pixels::Other(format!(
                        "a zlib stream declaring {}{}, which libpng decodes with what it \
                         declares",
                        if method & 0x0f == 8 && method >> 4 < 8 {
                            format!("a window of {} bytes", 1u32 << ((method >> 4) + 8))
                        } else {
                            format!("the method 0x{method:02x}")
                        },
                        if flags & 0x20 != 0 {
                            " and a preset dictionary"
                        } else {
                            ""
                        }
                    )));
                }
                None => {
                    return Ok(Pixels::Other(
                        "a zlib stream whose header is not in its first IDAT chunk".into(),
                    ));
                }
            }
            let mut file = open_as_checked(path, header)?;
            let budget = count as usize * 8 + (1 << 24);
            // A stream that ends after its last row without its end and checksum decodes
            // here, as libpng refuses it; it is inflated to its end first, its Adler-32
            // checked (so the decoder need not check it again).
            png_header::check_zlib_stream_ends(&mut file, budget as u64).map_err(|why| {
                image_error(path, format!("has pixels that do not decode: {why}"))
            })?;
            file.seek(SeekFrom::Start(0)).map_err(|cause| Error::Io {
                path: path.to_owned(),
                cause,
            })?;
            let mut decoder = png::Decoder::new_with_limits(
                std::io::BufReader::new(file),
                png::Limits { bytes: budget },
            );
            decoder.set_ignore_text_chunk(true);
            let mut reader = decoder
                .read_info()
                .map_err(|e| image_error(path, format!("is not a readable PNG file: {e}")))?;
            let info = reader.info();
            let layout = (info.color_type, info.bit_depth);
            if layout != (png::ColorType::Rgb, png::BitDepth::Eight) {
                // Said in words ("16-bit RGB", "8-bit palette"), not the decoder's names.
                let colour = match layout.0 {
                    png::ColorType::Grayscale => "grey",
                    png::ColorType::GrayscaleAlpha => "grey and alpha",
                    png::ColorType::Rgb => "RGB",
                    png::ColorType::Rgba => "RGBA",
                    png::ColorType::Indexed => "palette",
                };
                return Ok(Pixels::Other(format!("{}-bit {colour}", layout.1 as u8)));
            }
            let size = reader
                .output_buffer_size()
                .ok_or_else(|| image_error(path, "is too large"))?;
            let mut buf = vec![0u8; size];
            reader
                .next_frame(&mut buf)
                .map_err(|e| image_error(path, format!("has pixels that do not decode: {e}")))?;
            Ok(Pixels::Rgb8(buf))
        }
        Format::Exr => {
            use exr::prelude::*;
            if header.samples != Some(crate::exr_header::SampleType::Float) {
                let samples = header
                    .samples
                    .map_or("mixed".to_owned(), |s| format!("{s:?}"));
                return Ok(Pixels::Other(format!("{} samples", samples.to_lowercase())));
            }
            let mut file = open_as_checked(path, header)?;
            let io = |cause| crate::error::Error::Io {
                path: path.to_owned(),
                cause,
            };
            // The chunks' places were judged with the header (`header_of`), read again from
            // this handle.
            if let Some(too_many) = (header.exr_layout.as_ref())
                .and_then(|layout| too_many_chunks(header.width, header.height, layout))
            {
                return Ok(Pixels::Other(too_many));
            }
            file.seek(SeekFrom::Start(0)).map_err(io)?;
            let width = header.width as usize;
            let image = read()
                .no_deep_data()
                .largest_resolution_level()
                .rgb_channels(
                    |resolution, _| vec![0f32; resolution.width() * resolution.height() * 3],
                    move |pixels: &mut Vec<f32>, p: Vec2<usize>, (r, g, b): (f32, f32, f32)| {
                        let i = 3 * (p.y() * width + p.x());
                        if i + 2 < pixels.len() {
                            pixels[i..i + 3].copy_from_slice(&[r, g, b]);
                        }
                    },
                )
                .first_valid_layer()
                .all_attributes()
                .from_buffered(std::io::BufReader::new(file));
            match image {
                Ok(image) => Ok(Pixels::Linear(image.layer_data.channel_data.pixels)),
                Err(exr::error::Error::NotSupported(what)) => Ok(Pixels::Other(what.into_owned())),
                Err(e) => Err(image_error(
                    path,
                    format!("has pixels that do not decode: {e}"),
                )),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::to_fixed;

    /// An image to read whose extension is not PNG's or EXR's is refused in a reader's
    /// words: `tessera info a.jpg` said "unsupported output extension `.jpg`".
    #[test]
    fn an_image_to_read_of_another_extension_is_refused_as_an_input() {
        for (name, said) in [
            ("a.jpg", "its extension is `.jpg`"),
            ("/dev/zero", "it has no extension"),
        ] {
            let e = read_header(Path::new(name)).unwrap_err().to_string();
            assert_eq!(
                e,
                format!(
                    "{name}: is not a .png or .exr image ({said}): a recipe is read from an \
                     image tessera wrote, PNG or EXR, named by its extension"
                )
            );
        }
    }

    #[test]
    fn ppm_is_the_books_plain_text() {
        let mut film = Film::new(2, 1, 1);
        film.sums[0] = [to_fixed(1.0), 0, to_fixed(0.25)];
        let text = String::from_utf8(film.encode(Format::Ppm, 1.0).unwrap()).unwrap();
        assert_eq!(text, "P3\n2 1\n255\n255 0 64\n0 0 0\n");
    }

    /// A file put at the image's path while its recipe renders, of the same size and
    /// pixels but with another recipe or a chunk that changes how it is shown, once passed
    /// for the file checked: only the size (and an EXR's sample type) was read again.
    #[test]
    fn pixels_are_read_only_from_a_file_whose_header_is_the_one_checked() {
        use crate::scene::{Overrides, Scene};
        let dir = std::env::temp_dir().join(format!("tessera-swapped-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut film = Film::new(4, 2, 1);
        film.sums[3] = [to_fixed(0.5), 0, to_fixed(1.0)];
        let recipe_of = |seed: u64| {
            let text = format!(
                "[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 1\nseed = {seed}\n"
            );
            let scene = Scene::parse(&text, Path::new("s.toml"), &Overrides::default()).unwrap();
            let source = recipe::Source::new(Path::new("s.toml"), &text, Overrides::default());
            Recipe::new(&source, &scene, &film)
        };
        for name in ["a.png", "a.exr"] {
            let path = dir.join(name);
            film.save(&path, 2.0, Some(&recipe_of(1))).unwrap();
            let header = read_header(&path).unwrap();
            assert!(read_pixels(&path, &header).is_ok(), "{name}");
            // Another recipe, the same pixels.
            film.save(&path, 2.0, Some(&recipe_of(2))).unwrap();
            let e = read_pixels(&path, &header).unwrap_err().to_string();
            assert!(e.contains("changed while it was checked"), "{name}: {e}");
        }
        // The same recipe and pixels, with an animation's chunk after the header.
        let path = dir.join("a.png");
        film.save(&path, 2.0, Some(&recipe_of(1))).unwrap();
        let header = read_header(&path).unwrap();
        let png = std::fs::read(&path).unwrap();
        let mut actl = 8u32.to_be_bytes().to_vec();
        actl.extend(b"acTL\0\0\0\x01\0\0\0\0");
        actl.extend(crc32fast::hash(&actl[4..]).to_be_bytes());
        std::fs::write(&path, [&png[..33], &actl[..], &png[33..]].concat()).unwrap();
        let e = read_pixels(&path, &header).unwrap_err().to_string();
        assert!(e.contains("changed while it was checked"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A tessera PNG re-saved by another program as 16-bit samples or a palette, its
    /// recipe kept, is said to be stored so in words ("16-bit RGB"), where the decoder's
    /// names were shown ("Rgb 16-bit", "Indexed 8-bit").
    #[test]
    fn a_png_stored_in_another_layout_is_said_so_in_words() {
        use crate::scene::{Overrides, Scene};
        let dir = std::env::temp_dir().join(format!("tessera-layout-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let film = Film::new(2, 1, 1);
        let text = "[image]\nwidth = 2\nheight = 1\nsamples_per_pixel = 1\nmax_depth = 1\n";
        let scene = Scene::parse(text, Path::new("s.toml"), &Overrides::default()).unwrap();
        let source = recipe::Source::new(Path::new("s.toml"), text, Overrides::default());
        let path = dir.join("a.png");
        film.save(&path, 2.0, Some(&Recipe::new(&source, &scene, &film)))
            .unwrap();
        let recipe = read_header(&path).unwrap().recipe.unwrap();
        for (colour, depth, data, said) in [
            (
                png::ColorType::Rgb,
                png::BitDepth::Sixteen,
                vec![0; 12],
                "16-bit RGB",
            ),
            (
                png::ColorType::Grayscale,
                png::BitDepth::Eight,
                vec![0; 2],
                "8-bit grey",
            ),
        ] {
            let mut file = Vec::new();
            let mut encoder = png::Encoder::new(&mut file, 2, 1);
            encoder.set_color(colour);
            encoder.set_depth(depth);
            encoder
                .add_itxt_chunk(recipe::KEY.to_owned(), recipe.clone())
                .unwrap();
            let mut writer = encoder.write_header().unwrap();
            writer.write_image_data(&data).unwrap();
            writer.finish().unwrap();
            std::fs::write(&path, file).unwrap();
            let header = read_header(&path).unwrap();
            match read_pixels(&path, &header) {
                Ok(Pixels::Other(layout)) => assert_eq!(layout, said),
                _ => panic!("{said}: not said to be stored otherwise"),
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// tessera writes a chunk a row; a file of another program may claim a chunk a pixel
    /// (tiles of one pixel), each of which the `exr` crate takes some 72 bytes to place
    /// before it decodes a pixel. Its pixels are not read: the file is not as tessera
    /// writes it. This one is its header alone, of 1100x1000 tiles.
    #[test]
    fn an_exr_of_more_chunks_than_tessera_writes_is_not_read() {
        let dir = std::env::temp_dir().join(format!("tessera-chunks-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut channels = Vec::new();
        for name in [b"B", b"G", b"R"] {
            channels.extend([&name[..], b"\0"].concat());
            channels.extend([2, 0, 1, 1].iter().flat_map(|v: &i32| v.to_le_bytes()));
        }
        channels.push(0);
        let window: Vec<u8> = [0, 0, 1099, 999]
            .iter()
            .flat_map(|v: &i32| v.to_le_bytes())
            .collect();
        let tiles = [&1u32.to_le_bytes()[..], &1u32.to_le_bytes(), &[0]].concat();
        let mut file = vec![0x76, 0x2f, 0x31, 0x01, 2, 2, 0, 0];
        for (name, kind, value) in [
            ("channels", "chlist", channels),
            ("compression", "compression", vec![0]),
            ("dataWindow", "box2i", window.clone()),
            ("displayWindow", "box2i", window),
            ("tiles", "tiledesc", tiles),
        ] {
            file.extend([name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat());
            file.extend((value.len() as u32).to_le_bytes());
            file.extend(value);
        }
        file.push(0);
        let path = dir.join("tiles.exr");
        std::fs::write(&path, &file).unwrap();
        let header = read_header(&path).unwrap();
        let pixels = read_pixels(&path, &header);
        std::fs::remove_dir_all(&dir).unwrap();
        match pixels {
            Ok(Pixels::Other(why)) => assert!(
                why.starts_with(
                    "1100000 chunks (blocks of scan lines or tiles), more than the 1048576"
                ),
                "{why}"
            ),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn formats_follow_the_extension() {
        assert_eq!(Format::from_path(Path::new("a.PNG")).unwrap(), Format::Png);
        assert_eq!(Format::from_path(Path::new("a.exr")).unwrap(), Format::Exr);
        assert!(Format::from_path(Path::new("a.jpg")).is_err());
        assert!(Format::from_path(Path::new("a")).is_err());
    }

    /// A recipe no reader takes is never written: `unrendered` foretells it, and writing one
    /// is an error, whatever the format with metadata.
    #[test]
    fn a_recipe_too_long_for_its_readers_is_not_written() {
        use crate::scene::{Overrides, Scene};
        let film = Film::new(4, 2, 1);
        let head = "[image]\nwidth = 4\nheight = 2\nsamples_per_pixel = 1\nmax_depth = 1\n";
        for (comment, fits) in [(recipe::MAX_BYTES / 2, true), (recipe::MAX_BYTES, false)] {
            let text = format!("{head}#{}\n", "x".repeat(comment));
            let scene = Scene::parse(&text, Path::new("s.toml"), &Overrides::default()).unwrap();
            let source = recipe::Source::new(Path::new("s.toml"), &text, Overrides::default());
            let recipe = Recipe::new(&source, &scene, &film);
            let unrendered = Recipe::unrendered(&source, &scene);
            assert_eq!(unrendered.to_json().len(), recipe.to_json().len());
            assert_eq!(unrendered.why_not_carried().is_none(), fits);
            assert_eq!(recipe.why_not_carried().is_none(), fits);
            for format in [Format::Png, Format::Exr] {
                let written = film.write(format, 2.0, Some(&recipe), &mut Vec::new());
                match written {
                    Ok(()) => assert!(fits, "{format:?}"),
                    Err(e) => {
                        assert!(!fits, "{format:?}: {e}");
                        assert!(e.to_string().contains("an image may carry"), "{e}");
                    }
                }
            }
            // A PPM carries no recipe, so has none too long.
            assert!(
                film.write(Format::Ppm, 2.0, Some(&recipe), &mut Vec::new())
                    .is_ok()
            );
        }
    }
}
