//! The difference of two images of equal size: RMSE, PSNR and mean absolute error.

use crate::error::{Error, Result};
use std::io::Seek;
use std::path::Path;

mod jpeg;
#[cfg(test)]
mod tests;

use jpeg::{JPEG_ICC_PROFILE, jpeg_display_changes, late_adobe_change};

/// The most pixels an image may have to be compared: 4096x4096. Each is held as three
/// floats beside the decoder's buffer (up to eight bytes a pixel, 16-bit RGBA), so two such
/// images take at most about 530 MB; the size a file claims is checked against it before
/// anything is decoded.
pub const MAX_COMPARED_PIXELS: u64 = 1 << 24;

/// The longest file `compare` reads: 20 bytes a pixel of `MAX_COMPARED_PIXELS` and 1 MiB,
/// more than an image of that many pixels takes in any format it reads (16 bytes a pixel as
/// float RGBA EXR without compression, 18 as PPM text of 16-bit values). Reading takes time
/// that follows the file's length, whatever the size its header claims: a PPM whose header
/// is a comment of 100 GiB (a sparse file, a few KiB of disk) was once read for 12 minutes.
pub const MAX_COMPARED_BYTES: u64 = MAX_COMPARED_PIXELS * 20 + (1 << 20);

/// The longest JPEG `compare` reads: its decoder holds the whole file in memory, so a sparse
/// JPEG of 4 GiB once took 4.2 GB. 8 bytes a pixel of `MAX_COMPARED_PIXELS` and 1 MiB, more
/// than twice the 3 bytes a pixel its pixels hold uncompressed.
pub const MAX_COMPARED_JPEG_BYTES: u64 = MAX_COMPARED_PIXELS * 8 + (1 << 20);

/// Difference statistics of two images, over all pixels and RGB channels, values in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    pub rmse: f64,
    /// Mean absolute error.
    pub mean_abs: f64,
    /// Peak signal-to-noise ratio in dB for peak 1.0; infinite for identical images.
    pub psnr_db: f64,
    /// What either file's header holds that changes how a viewer shows the picture, beyond
    /// the values measured (a PNG's transparency or animation chunks, an EXR's thumbnail),
    /// with the file's path; empty for files measured in memory.
    pub display_changes: Vec<(std::path::PathBuf, String)>,
}

/// An RGB image as floats in [0, 1]: 8-bit formats scaled, EXR's linear values clamped (NaN
/// counts as 0, and `difference_of_files` lists it), so an over-bright float image compares
/// as a display would show it.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl RgbImage {
    /// Decodes the image at `path` (any format the `image` crate reads, by its extension or
    /// else its content), once the size its header claims is found within
    /// `MAX_COMPARED_PIXELS`.
    pub fn load(path: &Path) -> Result<Self> {
        let (decoder, _, format) = Self::decoder(path)?;
        Self::decode(path, decoder, format).map(|(image, _)| image)
    }

    /// The pixels of the image at `path` from `decoder` (of `format`), its header already
    /// read, and how many of its values were NaN (a float image's), each taken as 0.
    ///
    /// The memory the decode takes is asked of the system first, and a refusal is an error
    /// that says how much it was: the decoder's buffer and the floats are reserved with
    /// `try_reserve_exact` and held, and what the EXR and JPEG decoders take beside them
    /// (`decoder_scratch`) is reserved and given back just before they take it. Under
    /// `ulimit -v` of 300 MB, `compare` of two real 4096x4096 PNGs once ended in a panic within
    /// the image crate's `to_rgb32f` (which reserves with `try_reserve` and unwraps it),
    /// whose backtrace then waited forever on a lock it held.
    /// The floats are the image crate's own conversion (`to_rgb32f`), made a band of rows at
    /// a time into the floats reserved: the values are those it gives the whole image.
    fn decode(
        path: &Path,
        decoder: impl image::ImageDecoder,
        format: Option<image::ImageFormat>,
    ) -> Result<(Self, usize)> {
        let (width, height) = decoder.dimensions();
        let color = decoder.color_type();
        let decoded = decoder.total_bytes();
        let floats = u64::from(width) * u64::from(height) * 3;
        let scratch = decoder_scratch(format, decoded);
        let needed = decoded
            .saturating_add(floats.saturating_mul(4))
            .saturating_add(scratch);
        let refused = || Error::Image {
            path: path.to_owned(),
            message: format!(
                "could not be compared: its {width}x{height} pixels take {needed} bytes of \
                 memory to compare ({decoded} decoded, {} as floats and {scratch} within the \
                 decoder), which the system refused",
                floats * 4
            ),
        };
        let mut bytes = Vec::<u8>::new();
        let mut data = Vec::<f32>::new();
        let mut probe = Vec::<u8>::new();
        usize::try_from(decoded)
            .ok()
            .and_then(|n| bytes.try_reserve_exact(n).ok())
            .and_then(|()| usize::try_from(floats).ok())
            .and_then(|n| data.try_reserve_exact(n).ok())
            .and_then(|()| usize::try_from(scratch).ok())
            .and_then(|n| probe.try_reserve_exact(n).ok())
            .ok_or_else(refused)?;
        drop(probe);
        bytes.resize(bytes.capacity(), 0);
        let fail = |e: image::ImageError| Error::Image {
            path: path.to_owned(),
            message: decode_failure(&e),
        };
        decoder.read_image(&mut bytes).map_err(fail)?;
        // Whole rows a band (the decoder's buffer is `height` rows of as many bytes).
        let row = (bytes.len() / usize::try_from(height).unwrap_or(usize::MAX).max(1)).max(1);
        let rows = (CONVERTED_BAND_BYTES / row).max(1);
        let mut nans = 0;
        for band in bytes.chunks(row * rows) {
            let band_rows = u32::try_from(band.len() / row).unwrap_or(u32::MAX);
            let rgb = band_rgb32f(color, width, band_rows, band).ok_or_else(|| Error::Image {
                path: path.to_owned(),
                message: format!("has pixels of a colour type ({color:?}) compare does not read"),
            })?;
            nans += rgb.iter().filter(|c| c.is_nan()).count();
            data.extend(rgb.into_raw().into_iter().map(unit));
        }
        let image = Self {
            width,
            height,
            data,
        };
        Ok((image, nans))
    }

    /// A decoder of the image at `path` (`decoder`), and what its header holds that changes
    /// how a viewer shows the picture: a PNG's chunks and an EXR's attributes (walked by
    /// `decoder`), an alpha channel in any format (the values measured are the colour
    /// channels only, so a transparent image and an opaque one of the same colours would
    /// otherwise be identical), and a JPEG's EXIF orientation and colour profile (and more
    /// than one EXIF segment).
    fn opened(
        path: &Path,
    ) -> Result<(
        impl image::ImageDecoder,
        Vec<String>,
        Option<image::ImageFormat>,
    )> {
        use image::ImageDecoder;
        let (mut decoder, mut display_changes, format) = Self::decoder(path)?;
        let fail = |e: image::ImageError| Error::Image {
            path: path.to_owned(),
            message: format!("has a header that does not decode: {e}"),
        };
        if decoder.color_type().has_alpha() {
            display_changes.push(format!(
                "an alpha channel ({:?}), which compare does not measure: transparency",
                decoder.original_color_type()
            ));
        }
        // A PNG's EXIF and colour profile are among the chunks walked; a JPEG's are in its
        // APP1 and APP2 segments, which its decoder reads.
        if format == Some(image::ImageFormat::Jpeg) {
            let orientation = decoder.orientation().map_err(fail)?;
            if orientation != image::metadata::Orientation::NoTransforms {
                display_changes.push(format!(
                    "an EXIF orientation ({orientation:?}), which turns or flips the picture"
                ));
            }
            // Its segments were walked for a profile as libjpeg reads one; the decoder's
            // is one it finds past that walk.
            if !display_changes.iter().any(|c| c == JPEG_ICC_PROFILE)
                && decoder.icc_profile().map_err(fail)?.is_some()
            {
                display_changes.push(JPEG_ICC_PROFILE.to_owned());
            }
        }
        Ok((decoder, display_changes, format))
    }

    /// A decoder of the image at `path` with its header read and its size checked, what the
    /// header holds that changes how a viewer shows the picture (a PNG's or an EXR's
    /// `display_changes`), and the format it is read as.
    fn decoder(
        path: &Path,
    ) -> Result<(
        impl image::ImageDecoder,
        Vec<String>,
        Option<image::ImageFormat>,
    )> {
        use image::ImageDecoder;
        let fail = |message: String| Error::Image {
            path: path.to_owned(),
            message,
        };
        let file = crate::input_file::open_regular(path).map_err(|cause| Error::Io {
            path: path.to_owned(),
            cause,
        })?;
        let len = file.metadata().map_err(|cause| Error::Io {
            path: path.to_owned(),
            cause,
        })?;
        let len = len.len();
        let mut reader = image::ImageReader::new(std::io::BufReader::new(file));
        let mut display_changes = Vec::new();
        match image::ImageFormat::from_path(path) {
            Ok(format) => reader.set_format(format),
            Err(_) => {
                reader = reader
                    .with_guessed_format()
                    .map_err(|e| fail(e.to_string()))?
            }
        }
        let most = match reader.format() {
            Some(image::ImageFormat::Jpeg) => MAX_COMPARED_JPEG_BYTES,
            _ => MAX_COMPARED_BYTES,
        };
        if len > most {
            return Err(fail(format!(
                "is {len} bytes long, more than the {most} an image of at most \
                 {MAX_COMPARED_PIXELS} pixels (4096x4096) takes in its format"
            )));
        }
        if let Some(
            format @ (image::ImageFormat::OpenExr
            | image::ImageFormat::Png
            | image::ImageFormat::Pnm
            | image::ImageFormat::Jpeg),
        ) = reader.format()
        {
            // The `exr` crate keeps every attribute of a header, the PNG decoder every text
            // chunk, whatever their count, and the PNM decoder every line of a PAM header,
            // whatever its length: the chunks, attributes or lines are walked within bounds
            // first, and the file read again from its start. A JPEG's segments are walked
            // for the EXIF ones, which its decoder reads otherwise than viewers do.
            let mut file = reader.into_inner();
            let walked = match format {
                // The pixels' zlib stream is inflated to its end first, checksum included:
                // the decoder stops at the last row and takes no notice of the checksum,
                // where libpng refuses a stream without its end or of a wrong checksum. At
                // most 8 bytes a pixel (16-bit RGBA) and a filter byte a row of each pass.
                image::ImageFormat::Png => crate::png_header::read(&mut file, len).and_then(|h| {
                    file.seek(std::io::SeekFrom::Start(0))
                        .map_err(|e| format!("could not be read: {e}"))?;
                    let inflated = crate::png_header::check_zlib_stream_ends(
                        &mut file,
                        MAX_COMPARED_PIXELS * 10,
                    )
                    .map_err(|why| format!("has pixels that do not decode: {why}"))?;
                    let narrow = crate::png_header::narrow_window(h.zlib_header, inflated);
                    file.seek(std::io::SeekFrom::Start(0))
                        .map_err(|e| format!("could not be read: {e}"))?;
                    let past = crate::png_header::palette_index_past_its_entries(
                        &mut file,
                        MAX_COMPARED_PIXELS * 2,
                    );
                    Ok(h.display_changes
                        .into_iter()
                        .chain(narrow)
                        .chain(past)
                        .collect())
                }),
                // A sample past the maxval is taken as the brightest by the decoder, where
                // Netpbm refuses the file: the samples are walked for one.
                image::ImageFormat::Pnm => {
                    crate::pnm_header::check_bounds(&mut file).and_then(|()| {
                        file.seek(std::io::SeekFrom::Start(0))
                            .map_err(|e| format!("could not be read: {e}"))?;
                        // The decoder makes room for every sample its header claims before
                        // it reads one: a file too short for them is refused first.
                        crate::pnm_header::check_length(&mut file, len)?;
                        file.seek(std::io::SeekFrom::Start(0))
                            .map_err(|e| format!("could not be read: {e}"))?;
                        Ok(crate::pnm_header::sample_past_maxval(&mut file)
                            .into_iter()
                            .collect())
                    })
                }
                // The decoder fills what a file cut short lacks with grey rather than
                // failing: a JPEG must end (as a texture must).
                // The end is looked for from the first scan, where the walk stopped, or from
                // the start where it stopped elsewhere, and with it the Adobe segments
                // between the scans.
                image::ImageFormat::Jpeg => {
                    jpeg_display_changes(&mut file).and_then(|(mut changes, segments)| {
                        let at_scan = segments.at_scan;
                        let from = if at_scan {
                            Ok(())
                        } else {
                            file.seek(std::io::SeekFrom::Start(0)).map(drop)
                        };
                        let after = from
                            .and_then(|()| crate::jpeg_end::after_scan(&mut file, at_scan))
                            .map_err(|e| format!("could not be read: {e}"))?;
                        if !after.ends {
                            return Err("ends before its image does (a truncated file?): no \
                                        end marker after its last scan"
                                .to_owned());
                        }
                        // A frame of a kind the decoder does not read is refused by its
                        // kind, not by the decoder's words for what it then meets.
                        let marker = segments.frame_marker.or(after.frame_marker);
                        if let Some(why) = marker.and_then(crate::jpeg_end::unread_frame) {
                            return Err(why);
                        }
                        // The decoder fills what the scans lack, as large as the frame
                        // claims: too little coded data for its blocks is refused undecoded.
                        // A frame of more pixels than are compared is refused below, by its
                        // size.
                        let frame = segments
                            .frame
                            .as_ref()
                            .or(after.frame.as_ref())
                            .filter(|f| {
                                u64::from(f.width) * u64::from(f.height) <= MAX_COMPARED_PIXELS
                            });
                        if let Some(why) = frame.and_then(|f| f.too_short(after.coded_bytes)) {
                            return Err(why);
                        }
                        // And so it fills a scan cut short whose end marker is put back: its
                        // codes are followed to each block, from the file's start.
                        file.seek(std::io::SeekFrom::Start(0))
                            .map_err(|e| format!("could not be read: {e}"))?;
                        if let Some(why) = crate::jpeg_end::sequential_fault(&mut file)
                            .map_err(|e| format!("could not be read: {e}"))?
                        {
                            return Err(why);
                        }
                        if after.scans > 1 {
                            changes.extend(late_adobe_change(&segments, &after.late_adobe));
                        }
                        Ok(changes)
                    })
                }
                // Its pixels decoded (its data window's, all channels) may take no more
                // than the longest file read: as many as an image without compression.
                _ => crate::exr_header::display_changes(&mut file, len, MAX_COMPARED_BYTES),
            };
            display_changes = walked.map_err(fail)?;
            file.seek(std::io::SeekFrom::Start(0))
                .map_err(|cause| Error::Io {
                    path: path.to_owned(),
                    cause,
                })?;
            reader = image::ImageReader::with_format(file, format);
        }
        // The decoder's own buffer, at most four 32-bit floats a pixel (an EXR with alpha).
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(MAX_COMPARED_PIXELS * 16 + (1 << 20));
        reader.limits(limits);
        let format = reader.format();
        let decoder = reader.into_decoder().map_err(|e| fail(e.to_string()))?;
        let (width, height) = decoder.dimensions();
        // A PNM may claim a width or height of 0 (PNG and EXR cannot): two such files
        // were `identical` (RMSE 0, PSNR inf), a verdict on no pixels at all.
        if width == 0 || height == 0 {
            return Err(fail(format!(
                "is {width}x{height}: an image to compare has at least one pixel"
            )));
        }
        if u64::from(width) * u64::from(height) > MAX_COMPARED_PIXELS {
            return Err(fail(format!(
                "{width}x{height} is more than the {MAX_COMPARED_PIXELS} pixels (4096x4096) \
                 an image may have to be compared"
            )));
        }
        Ok((decoder, display_changes, format))
    }

    /// Wraps 8-bit RGB values.
    pub fn from_rgb8(width: u32, height: u32, bytes: &[u8]) -> Self {
        Self {
            width,
            height,
            data: bytes.iter().map(|&b| f32::from(b) / 255.0).collect(),
        }
    }
}

/// The most bytes of decoded pixels converted to floats at a time (`RgbImage::decode`): a
/// band of rows of at most 1 MiB (one row where a row is longer).
const CONVERTED_BAND_BYTES: usize = 1 << 20;

/// The bytes a decoder of `format` takes beside the buffer of `decoded` bytes it fills: the
/// EXR decoder its own copy of the whole picture (four bytes a value, as many as it hands
/// on), the JPEG decoder a progressive file's coefficients (two bytes a sample); the PNG and
/// PNM decoders a few rows.
fn decoder_scratch(format: Option<image::ImageFormat>, decoded: u64) -> u64 {
    match format {
        Some(image::ImageFormat::OpenExr) => decoded,
        Some(image::ImageFormat::Jpeg) => decoded.saturating_mul(2),
        _ => 0,
    }
}

/// The floats the image crate's `to_rgb32f` gives for `band`, `rows` rows of `width` pixels
/// of the colour type `color` as the decoder wrote them (its samples in native byte order),
/// the image's colour space taken as `DynamicImage::from_decoder` takes it; None for a
/// colour type it does not decode to.
fn band_rgb32f(
    color: image::ColorType,
    width: u32,
    rows: u32,
    band: &[u8],
) -> Option<image::Rgb32FImage> {
    use image::{ColorType as C, DynamicImage as D, ImageBuffer};
    let u16s = || {
        band.chunks_exact(2)
            .map(|b| u16::from_ne_bytes([b[0], b[1]]))
            .collect::<Vec<_>>()
    };
    let f32s = || {
        band.chunks_exact(4)
            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
            .collect::<Vec<_>>()
    };
    let mut image = match color {
        C::L8 => ImageBuffer::from_raw(width, rows, band.to_vec()).map(D::ImageLuma8),
        C::La8 => ImageBuffer::from_raw(width, rows, band.to_vec()).map(D::ImageLumaA8),
        C::Rgb8 => ImageBuffer::from_raw(width, rows, band.to_vec()).map(D::ImageRgb8),
        C::Rgba8 => ImageBuffer::from_raw(width, rows, band.to_vec()).map(D::ImageRgba8),
        C::L16 => ImageBuffer::from_raw(width, rows, u16s()).map(D::ImageLuma16),
        C::La16 => ImageBuffer::from_raw(width, rows, u16s()).map(D::ImageLumaA16),
        C::Rgb16 => ImageBuffer::from_raw(width, rows, u16s()).map(D::ImageRgb16),
        C::Rgba16 => ImageBuffer::from_raw(width, rows, u16s()).map(D::ImageRgba16),
        C::Rgb32F => ImageBuffer::from_raw(width, rows, f32s()).map(D::ImageRgb32F),
        C::Rgba32F => ImageBuffer::from_raw(width, rows, f32s()).map(D::ImageRgba32F),
        _ => None,
    }?;
    image.set_rgb_primaries(image::metadata::Cicp::SRGB.primaries);
    image.set_transfer_function(image::metadata::Cicp::SRGB.transfer);
    Some(image.to_rgb32f())
}

/// What a decoder's failure says of the file: a file that ends within its pixels says so
/// (the decoders' own words for it are "failed to fill whole buffer").
fn decode_failure(e: &image::ImageError) -> String {
    match e {
        image::ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "ends before its image does (a truncated file?)".to_owned()
        }
        image::ImageError::IoError(io) => format!("could not be read: {io}"),
        e => format!("has pixels that do not decode: {e}"),
    }
}

/// `c` clamped to [0, 1]; NaN is 0.
fn unit(c: f32) -> f32 {
    if c > 0.0 { c.min(1.0) } else { 0.0 }
}

/// What is said of two images of the sizes `a` and `b`, if they differ.
fn sizes_differ(a: (u32, u32), b: (u32, u32)) -> Option<String> {
    (a != b).then(|| format!("images differ in size: {}x{} and {}x{}", a.0, a.1, b.0, b.1))
}

/// The difference of two images; they must have the same size.
pub fn difference(a: &RgbImage, b: &RgbImage) -> std::result::Result<Difference, String> {
    if let Some(differ) = sizes_differ((a.width, a.height), (b.width, b.height)) {
        return Err(differ);
    }
    let n = a.data.len().max(1) as f64;
    let (mut sq, mut abs) = (0.0f64, 0.0f64);
    for (x, y) in a.data.iter().zip(&b.data) {
        let d = f64::from(*x) - f64::from(*y);
        sq += d * d;
        abs += d.abs();
    }
    let rmse = (sq / n).sqrt();
    Ok(Difference {
        rmse,
        mean_abs: abs / n,
        psnr_db: if rmse == 0.0 {
            f64::INFINITY
        } else {
            -20.0 * rmse.log10()
        },
        display_changes: Vec::new(),
    })
}

/// Loads two image files and gives their difference; their sizes are compared, and checked,
/// before either is decoded.
pub fn difference_of_files(a: &Path, b: &Path) -> Result<Difference> {
    use image::ImageDecoder;
    let (decoder_a, shown_a, format_a) = RgbImage::opened(a)?;
    let (decoder_b, shown_b, format_b) = RgbImage::opened(b)?;
    if let Some(message) = sizes_differ(decoder_a.dimensions(), decoder_b.dimensions()) {
        return Err(Error::Image {
            path: b.to_owned(),
            message,
        });
    }
    let (ia, nans_a) = RgbImage::decode(a, decoder_a, format_a)?;
    let (ib, nans_b) = RgbImage::decode(b, decoder_b, format_b)?;
    let mut d = difference(&ia, &ib).map_err(|message| Error::Image {
        path: b.to_owned(),
        message,
    })?;
    // A NaN is measured as black, but viewers differ in what they show for one (black,
    // a warning colour, or a spoilt picture): an image holding any is not called identical.
    let with_nans = |mut shown: Vec<String>, nans: usize| {
        if nans > 0 {
            shown.push(format!(
                "{nans} NaN value{} (measured as 0; viewers differ in what they show for one)",
                if nans == 1 { "" } else { "s" }
            ));
        }
        shown
    };
    let (shown_a, shown_b) = (with_nans(shown_a, nans_a), with_nans(shown_b, nans_b));
    d.display_changes = [(a, shown_a), (b, shown_b)]
        .into_iter()
        .flat_map(|(path, changes)| changes.into_iter().map(move |c| (path.to_owned(), c)))
        .collect();
    Ok(d)
}
