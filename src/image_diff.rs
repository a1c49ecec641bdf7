//! The difference of two images of equal size: RMSE, PSNR and mean absolute error.

use crate::error::{Error, Result};
use std::io::Seek;
use std::path::Path;

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
                    crate::png_header::check_zlib_stream_ends(&mut file, MAX_COMPARED_PIXELS * 10)
                        .map_err(|why| format!("has pixels that do not decode: {why}"))?;
                    file.seek(std::io::SeekFrom::Start(0))
                        .map_err(|e| format!("could not be read: {e}"))?;
                    let past = crate::png_header::palette_index_past_its_entries(
                        &mut file,
                        MAX_COMPARED_PIXELS * 2,
                    );
                    Ok(h.display_changes.into_iter().chain(past).collect())
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

/// The most segments of a JPEG walked for its EXIF ones: the book's earth map has a dozen.
const MAX_JPEG_SEGMENTS: usize = 1 << 16;

/// What compare lists of a JPEG with a colour profile.
const JPEG_ICC_PROFILE: &str = "an ICC colour profile (an APP2 segment)";

/// What a JPEG's segments before its pixels hold that viewers read otherwise than its
/// decoder: more than one EXIF segment (APP1), of which browsers (Firefox, Chrome) read the
/// first and the decoder the last, so that a first one saying "turned" and a last one
/// saying "upright" show a picture turned, whose values are measured upright; and, in a
/// file of three components, colours the decoder takes as RGB where libjpeg takes them as
/// YCbCr, measuring colours no viewer built on libjpeg shows. libjpeg takes a JFIF segment
/// (APP0)'s word (YCbCr) first, then an Adobe segment (APP14)'s transform (0: RGB), and
/// only without either the components' names ('R', 'G', 'B': RGB); the decoder takes those
/// names first, then Adobe's word, and never JFIF's. In a file of four components, an
/// Adobe transform of 1 (YCbCr, which four components cannot be) is YCCK to libjpeg and
/// CMYK to the decoder. A file that is not a JPEG as far as its pixels is its decoder's to
/// refuse. A colour profile is listed wherever libjpeg finds one (an APP2 segment of 14
/// bytes or more, named ICC_PROFILE): the decoder takes none split over 255 segments, or
/// with a segment of no bytes of the profile, where libjpeg takes it whole. The EXIF
/// orientation libexif's viewers read (IFD0's first, or else IFD1's) is listed where the
/// decoder does not read it (it reads IFD0's first, of type SHORT and one value) and it does
/// not say upright; an EXIF segment whose IFD0 or its values lie past its end is refused.
/// Also what the segments say (`at_scan`: whether `r` is left just past the first scan's
/// marker, FF DA).
fn jpeg_display_changes<R: std::io::Read + Seek>(
    r: &mut std::io::BufReader<R>,
) -> std::result::Result<(Vec<String>, JpegSegments), String> {
    let mut segments = jpeg_segments(r).unwrap_or_default();
    let mut changes = Vec::new();
    // What lies past the segments walked is unread: an EXIF segment saying "turned" or an
    // Adobe segment there changed how viewers show the picture, unlisted.
    if segments.unwalked {
        return Err(format!(
            "has more than {MAX_JPEG_SEGMENTS} segments before its first scan, more than are \
             walked for what changes how it is shown (a JPEG has a dozen)"
        ));
    }
    if let Some(fault) = segments.exif_fault.take() {
        return Err(fault);
    }
    if let Some(odd) = segments.odd_orientation.take() {
        changes.push(format!(
            "an EXIF orientation {odd}, which libexif, and the viewers built on it, read \
             otherwise than the decoder: it turns or flips the picture"
        ));
    }
    if segments.exif >= 2 {
        changes.push(format!(
            "{} EXIF segments (APP1), each of which can turn or flip the picture: viewers \
             read the first, the decoder measured the last",
            segments.exif
        ));
    }
    let named_rgb = segments.names == Some(*b"RGB");
    let adobe_rgb = segments.adobe_transform == Some(0);
    let libjpeg_rgb =
        !segments.jfif && (adobe_rgb || segments.adobe_transform.is_none() && named_rgb);
    if segments.components == Some(3) && (named_rgb || adobe_rgb) && !libjpeg_rgb {
        let said = if segments.jfif {
            "a JFIF segment (APP0), which says its colours are YCbCr"
        } else {
            "an Adobe segment (APP14), which says its colours are YCbCr"
        };
        let not = if adobe_rgb {
            "an Adobe segment (APP14) that says they are not"
        } else {
            "components named 'R', 'G' and 'B'"
        };
        changes.push(format!(
            "{said}, and {not}: libjpeg, and the viewers built on it, show them as YCbCr, \
             the decoder measured them as RGB"
        ));
    }
    if segments.components == Some(4) && segments.adobe_transform == Some(1) {
        changes.push(
            "four components and an Adobe segment (APP14) that says they are YCbCr: libjpeg, \
             and the viewers built on it, show them as YCCK, the decoder measured them as CMYK"
                .to_owned(),
        );
    }
    if segments.icc > 0 {
        changes.push(JPEG_ICC_PROFILE.to_owned());
    }
    Ok((changes, segments))
}

/// What is said of the Adobe segments (APP14) of the colour transforms `late` after the first
/// scan of the JPEG whose segments before it are `seen`, if one changes what the decoder
/// measures. libjpeg takes a JPEG's colours from the segments before its first scan and
/// reads past later ones; the decoder takes each as it comes and converts the colours of a
/// file of several scans (a progressive one) by the last at their end (of one scan, as it
/// reads it, before a later Adobe segment): a JPEG libjpeg shows
/// as RGB (an Adobe transform 0 before its first scan, no JFIF segment) was measured as
/// YCbCr with an Adobe transform 1 before its second scan, and so called identical to the
/// same scans after a JFIF segment, which libjpeg shows as YCbCr 10.65 dB apart. Those that
/// leave the decoder's reading as it was are not listed: of three components read as YCbCr,
/// a transform of 1 or 2 (YCCK, taken as YCbCr of three); of four, the transform it read
/// (0: CMYK, 2: YCCK); of one, 1. Of three read as RGB (named 'R', 'G', 'B', or an Adobe
/// transform 0 before the scan), any: a later 0 is CMYK of three components.
fn late_adobe_change(seen: &JpegSegments, late: &std::collections::BTreeSet<u8>) -> Option<String> {
    let rgb = seen.names == Some(*b"RGB") || seen.adobe_transform == Some(0);
    let keeps = |t: u8| match seen.components {
        Some(3) => !rgb && t != 0,
        Some(4) => {
            t == if seen.adobe_transform == Some(2) {
                2
            } else {
                0
            }
        }
        Some(1) => t == 1,
        _ => false,
    };
    let t = late.iter().copied().find(|&t| !keeps(t))?;
    Some(format!(
        "an Adobe segment (APP14) of colour transform {t} after its first scan: libjpeg, and \
         the viewers built on it, read past it, the decoder measured the colours by it"
    ))
}

/// What the segments of a JPEG before its first scan say of how it is shown.
#[derive(Default)]
struct JpegSegments {
    /// Its EXIF segments (APP1).
    exif: usize,
    /// What its first EXIF segment that does not read says of it: an IFD or a value past
    /// its end, or no TIFF header.
    exif_fault: Option<String>,
    /// An orientation of its EXIF segments that libexif reads otherwise than the decoder and
    /// that does not say upright, described.
    odd_orientation: Option<String>,
    /// Whether the walk stopped just past the first scan's marker.
    at_scan: bool,
    /// Whether the walk stopped at `MAX_JPEG_SEGMENTS` segments, before the first scan.
    unwalked: bool,
    /// Its segments (APP2) of a colour profile, as libjpeg takes one (14 bytes or more).
    icc: usize,
    /// Whether it has a JFIF segment (APP0) libjpeg reads as one (14 bytes or more).
    jfif: bool,
    /// The colour transform of its last Adobe segment (APP14), if it has one.
    adobe_transform: Option<u8>,
    /// The components of its frame, if its frame comes before the first scan.
    components: Option<u8>,
    /// The names (one byte each) of its frame's first three components.
    names: Option<[u8; 3]>,
    /// Its first frame header of a kind the decoder reads, if it comes before the first scan.
    frame: Option<crate::jpeg_end::Frame>,
}

/// The segments of the JPEG `r` is at the start of, up to its first scan (or its first
/// `MAX_JPEG_SEGMENTS` segments, `unwalked`), each skipped past its first sixteen bytes, and
/// what lies between segments skipped as libjpeg skips it.
fn jpeg_segments<R: std::io::Read + Seek>(
    r: &mut std::io::BufReader<R>,
) -> std::io::Result<JpegSegments> {
    use std::io::Read;
    let mut seen = JpegSegments::default();
    let mut two = [0u8; 2];
    r.read_exact(&mut two)?;
    if two != [0xff, 0xd8] {
        return Ok(seen);
    }
    // One marker more than the segments: the first scan's, after as many as are walked.
    for _ in 0..=MAX_JPEG_SEGMENTS {
        // The next marker, as libjpeg finds it: bytes other than 0xFF before it, and FF 00,
        // are skipped (libjpeg warns of them and reads on, as the decoder does), then fill
        // bytes.
        let mut byte = [0u8; 1];
        loop {
            r.read_exact(&mut byte)?;
            while byte[0] != 0xff {
                r.read_exact(&mut byte)?;
            }
            while byte[0] == 0xff {
                r.read_exact(&mut byte)?;
            }
            if byte[0] != 0 {
                break;
            }
        }
        match byte[0] {
            // Markers without a length: restarts and TEM.
            0xd0..=0xd7 | 0x01 => continue,
            // The first scan (the pixels), or what no segment begins with.
            0xd8..=0xda => {
                seen.at_scan = byte[0] == 0xda;
                return Ok(seen);
            }
            _ => {}
        }
        r.read_exact(&mut two)?;
        let rest = i64::from(u16::from_be_bytes(two)) - 2;
        let mut head = [0u8; 16];
        let n = usize::try_from(rest).unwrap_or(0).min(head.len());
        r.read_exact(&mut head[..n])?;
        let head = &head[..n];
        match byte[0] {
            0xe1 if head.starts_with(b"Exif\0\0") => {
                seen.exif += 1;
                // A segment's length is two bytes: at most 64 KiB is read.
                let mut tiff = head[6..].to_vec();
                let more = u64::try_from(rest).unwrap_or(0) - n as u64;
                r.by_ref().take(more).read_to_end(&mut tiff)?;
                if tiff.len() as u64 != more + n as u64 - 6 {
                    return Err(std::io::ErrorKind::UnexpectedEof.into());
                }
                match exif_orientations(&tiff) {
                    Err(why) if seen.exif_fault.is_none() => {
                        seen.exif_fault = Some(format!(
                            "has an EXIF segment (APP1) that does not read: {why}"
                        ));
                    }
                    Ok(found) if seen.odd_orientation.is_none() => {
                        seen.odd_orientation = odd_orientation(&found);
                    }
                    _ => {}
                }
                continue;
            }
            // The frame header the decoder reads (the first; it refuses a second), whole: the
            // sampling factors of each component say how many blocks it claims.
            0xc0..=0xc2 if seen.frame.is_none() => {
                let mut body = head.to_vec();
                let more = u64::try_from(rest).unwrap_or(0) - n as u64;
                r.by_ref().take(more).read_to_end(&mut body)?;
                if body.len() as u64 != more + n as u64 {
                    return Err(std::io::ErrorKind::UnexpectedEof.into());
                }
                if n >= 6 {
                    seen.components = Some(head[5]);
                    seen.names = (n >= 13).then(|| [head[6], head[9], head[12]]);
                }
                seen.frame = crate::jpeg_end::Frame::parse(byte[0], &body);
                continue;
            }
            0xe2 if head.starts_with(b"ICC_PROFILE\0") && n >= 14 => seen.icc += 1,
            0xe0 if head.starts_with(b"JFIF\0") && n >= 14 => seen.jfif = true,
            0xee if head.starts_with(b"Adobe") && n >= 12 => seen.adobe_transform = Some(head[11]),
            // A frame's header: precision, height, width, then its components, three bytes
            // each, the first its name.
            0xc0..=0xc3 | 0xc5..=0xc7 | 0xc9..=0xcb | 0xcd..=0xcf if n >= 6 => {
                seen.components = Some(head[5]);
                seen.names = (n >= 13).then(|| [head[6], head[9], head[12]]);
            }
            _ => {}
        }
        r.seek_relative(rest.max(0) - n as i64)?;
    }
    seen.unwalked = true;
    Ok(seen)
}

/// An EXIF orientation entry (tag 0x0112): the IFD it is in (0 or 1), its type, its count
/// and its first value as libexif reads it (`None` for a type libexif does not read as a
/// number), in the order of the entries.
struct ExifOrientation {
    ifd: u8,
    kind: u16,
    count: u32,
    value: Option<u16>,
}

/// The orientation entries of the TIFF structure `tiff` (an EXIF segment past its
/// "Exif\0\0"), in its IFD0 and IFD1 (the one IFD0 says is next, as libexif reads; no
/// further), or why it does not read: no TIFF header, IFD0, its entries or an orientation's
/// value in it past its end. Of an IFD1 past its end, nothing is read; of one running past
/// it, the entries within it, as libexif reads. No count it claims is allocated for.
fn exif_orientations(tiff: &[u8]) -> std::result::Result<Vec<ExifOrientation>, String> {
    let big = match tiff.get(..4) {
        Some(b"II*\0") => false,
        Some(b"MM\0*") => true,
        _ => return Err("no TIFF header ('II*' or 'MM*') after its \"Exif\"".to_owned()),
    };
    let u16_at = |at: usize| {
        let b = tiff.get(at..at.checked_add(2)?)?;
        Some(if big {
            u16::from_be_bytes([b[0], b[1]])
        } else {
            u16::from_le_bytes([b[0], b[1]])
        })
    };
    let u32_at = |at: usize| {
        let b: [u8; 4] = tiff.get(at..at.checked_add(4)?)?.try_into().ok()?;
        Some(if big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    };
    let past = |what: String| format!("it ends ({} bytes) before {what}", tiff.len());
    let mut found = Vec::new();
    let mut at = u32_at(4).unwrap_or(0) as usize;
    for ifd in 0..2u8 {
        // Cameras' files have an IFD1 that lies past the segment, or runs past it: libexif
        // skips the one ("Bogus offset of IFD1"), reads those entries of the other that fit
        // and skips an orientation whose values lie past the end, and so does this walk.
        // IFD0 must read whole.
        let Some(entries) = u16_at(at) else {
            if ifd == 1 {
                break;
            }
            return Err(past(format!("its IFD{ifd} (at byte {at})")));
        };
        let table = at + 2;
        let fit = tiff.len().saturating_sub(table) / 12;
        if ifd == 0 && fit < usize::from(entries) {
            return Err(past(format!(
                "the {entries} entries of its IFD{ifd} (from byte {table})"
            )));
        }
        let entries = usize::from(entries).min(fit);
        for entry in (0..entries).map(|i| table + 12 * i) {
            if u16_at(entry) != Some(0x0112) {
                continue;
            }
            let (kind, count) = (
                u16_at(entry + 2).unwrap_or(0),
                u32_at(entry + 4).unwrap_or(0),
            );
            let size = match kind {
                1 | 6 => 1,
                3 | 8 => 2,
                4 | 9 => 4,
                _ => 0,
            };
            let bytes = u64::from(count) * size;
            let value = if bytes == 0 {
                None
            } else {
                let from = if bytes <= 4 {
                    entry + 8
                } else {
                    u32_at(entry + 8).unwrap_or(0) as usize
                };
                let value = match size {
                    1 => tiff.get(from).map(|&b| u16::from(b)),
                    2 => u16_at(from),
                    _ => u32_at(from).map(|v| v as u16),
                };
                if value.is_none() || (from as u64).saturating_add(bytes) > tiff.len() as u64 {
                    if ifd == 1 {
                        continue;
                    }
                    return Err(past(format!(
                        "the {count} values of its IFD{ifd}'s orientation (at byte {from})"
                    )));
                }
                value
            };
            found.push(ExifOrientation {
                ifd,
                kind,
                count,
                value,
            });
        }
        match u32_at(table + 12 * entries) {
            Some(0) | None => break,
            Some(next) => at = next as usize,
        }
    }
    Ok(found)
}

/// What is said of the orientation entries `found`, if the one libexif reads is one the
/// decoder does not (the decoder reads the first in IFD0 of type SHORT and one value) and
/// it does not say upright (1). libexif keeps the first of an IFD's orientations and
/// viewers ask for IFD0's before IFD1's: the first of `found`, which lists IFD0's first.
fn odd_orientation(found: &[ExifOrientation]) -> Option<String> {
    let odd = found.first()?;
    if odd.value == Some(1) || odd.ifd == 0 && odd.kind == 3 && odd.count == 1 {
        return None;
    }
    let value = odd.value.map_or("no number".to_owned(), |v| v.to_string());
    let also = if found.len() > 1 {
        format!(", one of {} orientation entries", found.len())
    } else {
        String::new()
    };
    let kind = match odd.kind {
        1 => "BYTE".to_owned(),
        3 => "SHORT".to_owned(),
        4 => "LONG".to_owned(),
        6 => "SBYTE".to_owned(),
        8 => "SSHORT".to_owned(),
        9 => "SLONG".to_owned(),
        kind => format!("type {kind}"),
    };
    Some(format!(
        "({value}) in IFD{}, a {kind} of {} value(s){also}",
        odd.ifd, odd.count
    ))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_have_infinite_psnr() {
        let a = RgbImage::from_rgb8(2, 1, &[1, 2, 3, 4, 5, 6]);
        let d = difference(&a, &a).unwrap();
        assert_eq!(d.rmse, 0.0);
        assert!(d.psnr_db.is_infinite());
    }

    #[test]
    fn float_images_compare_clamped_to_the_unit_range() {
        let dir = std::env::temp_dir().join(format!("tessera-compare-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Linear values far above 1 (and below 0) read as white (and black), as an 8-bit
        // image of them shows.
        let mut film = crate::film::Film::new(2, 1, 1);
        film.sums[0] = [crate::film::to_fixed(1e5); 3];
        film.sums[1] = [crate::film::to_fixed(0.5), 0, crate::film::to_fixed(3.0)];
        let exr = dir.join("bright.exr");
        film.save(&exr, 1.0, None).unwrap();
        let loaded = RgbImage::load(&exr).unwrap();
        assert_eq!(loaded.data, [1.0, 1.0, 1.0, 0.5, 0.0, 1.0]);
        let white = RgbImage::from_rgb8(2, 1, &[255, 255, 255, 0, 0, 0]);
        let d = difference(&loaded, &white).unwrap();
        assert!(d.psnr_db > 0.0 && d.rmse <= 1.0, "{d:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A file's name and bytes.
    type File<'a> = (&'a str, &'a [u8]);

    /// The changes listed for `b` compared with `a`, both written into a directory of
    /// their own.
    fn listed(name: &str, a: File, b: File) -> Vec<String> {
        let dir = std::env::temp_dir().join(format!("tessera-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(a.0), a.1).unwrap();
        std::fs::write(dir.join(b.0), b.1).unwrap();
        let d = difference_of_files(&dir.join(a.0), &dir.join(b.0)).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(d.rmse, 0.0, "{name}: the same colour values");
        d.display_changes
            .into_iter()
            .map(|(path, change)| {
                assert!(path.ends_with(b.0), "{name}: {path:?}: {change}");
                change
            })
            .collect()
    }

    fn png(color: png::ColorType, pixels: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, 2, 1);
        encoder.set_color(color);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().unwrap();
        writer.write_image_data(pixels).unwrap();
        writer.finish().unwrap();
        out
    }

    /// A palette PNG whose pixel's index lies past the palette's entries shows black in
    /// libpng and the decoder here, the palette's last colour in Chrome: compared with a
    /// red and black PNG it was `inf dB (identical)`. It is listed.
    #[test]
    fn a_palette_index_past_the_palette_s_entries_is_listed() {
        let indexed = |pixels: &[u8]| {
            let mut out = Vec::new();
            let mut encoder = png::Encoder::new(&mut out, 2, 1);
            encoder.set_color(png::ColorType::Indexed);
            encoder.set_depth(png::BitDepth::Eight);
            encoder.set_palette(vec![255, 0, 0]);
            let mut writer = encoder.write_header().unwrap();
            writer.write_image_data(pixels).unwrap();
            writer.finish().unwrap();
            out
        };
        let rgb = png(png::ColorType::Rgb, &[255, 0, 0, 0, 0, 0]);
        let changes = listed("png-palette", ("a.png", &rgb), ("b.png", &indexed(&[0, 5])));
        assert!(
            changes.len() == 1 && changes[0].contains("a pixel (1, 0) of palette index 5"),
            "{changes:?}"
        );
        let red = png(png::ColorType::Rgb, &[255, 0, 0, 255, 0, 0]);
        assert!(
            listed(
                "png-palette-in",
                ("a.png", &red),
                ("b.png", &indexed(&[0, 0]))
            )
            .is_empty()
        );
    }

    /// A palette PNG whose PLTE chunk is not whole entries of three bytes (4 bytes here)
    /// ended compare in a panic within the PNG decoder, which indexed past the palette's end
    /// expanding the pixels (exit 101). It is refused before the pixels are decoded.
    #[test]
    fn a_palette_of_a_partial_entry_is_refused_before_decoding() {
        let mut palette = Vec::new();
        let mut encoder = png::Encoder::new(&mut palette, 2, 1);
        encoder.set_color(png::ColorType::Indexed);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_palette(vec![255, 0, 0, 7]);
        let mut writer = encoder.write_header().unwrap();
        writer.write_image_data(&[0, 0]).unwrap();
        writer.finish().unwrap();
        let dir = std::env::temp_dir().join(format!("tessera-png-plte4-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let red = png(png::ColorType::Rgb, &[255, 0, 0, 255, 0, 0]);
        std::fs::write(dir.join("a.png"), red).unwrap();
        std::fs::write(dir.join("b.png"), palette).unwrap();
        let said = difference_of_files(&dir.join("a.png"), &dir.join("b.png"));
        std::fs::remove_dir_all(&dir).unwrap();
        let e = said.unwrap_err().to_string();
        assert!(
            e.contains("b.png") && e.contains("a PLTE chunk of 4 bytes"),
            "{e}"
        );
    }

    /// A PNG whose IEND chunk's CRC is wrong, which libpng refuses at its end, was
    /// `inf dB (identical)` to the same PNG whole. It is listed, naming the chunk.
    #[test]
    fn a_png_whose_iend_crc_is_wrong_is_listed() {
        let whole = png(png::ColorType::Rgb, &[255, 0, 0, 0, 0, 0]);
        let mut damaged = whole.clone();
        *damaged.last_mut().unwrap() ^= 1;
        let changes = listed("png-iend-crc", ("a.png", &whole), ("b.png", &damaged));
        assert!(
            changes.len() == 1 && changes[0].contains("an IEND chunk at byte"),
            "{changes:?}"
        );
        assert!(listed("png-iend-whole", ("a.png", &whole), ("b.png", &whole)).is_empty());
    }

    /// compare measures the colour channels only: an image with an alpha channel (a PNG of
    /// colour type 4 or 6, an EXR with an `A` channel, a PAM of tuple type RGB_ALPHA) once
    /// compared `identical` with an opaque one of the same colours, though a viewer shows
    /// it transparent. It is listed, as a PNG's tRNS chunk is.
    /// A PPM whose samples go past its maxval (200 where it is 100) was measured as white
    /// and called identical with a white PPM, though Netpbm refuses it; it is listed now.
    #[test]
    fn a_pnm_sample_past_its_maxval_is_listed() {
        let white: &[u8] = b"P6\n2 1\n255\n\xff\xff\xff\xff\xff\xff";
        let past: &[u8] = b"P6\n2 1\n100\n\x64\x64\x64\xc8\xc8\xc8";
        let said = listed("pnm-maxval", ("white.ppm", white), ("past.ppm", past));
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].contains("past its maxval of 100"), "{said:?}");
        let within: &[u8] = b"P6\n2 1\n100\n\x64\x64\x64\x64\x64\x64";
        assert!(listed("pnm-within", ("white.ppm", white), ("within.ppm", within)).is_empty());
    }

    #[test]
    fn an_alpha_channel_is_listed_not_called_identical() {
        let opaque = png(png::ColorType::Rgb, &[200, 100, 50, 200, 100, 50]);
        let clear = png(png::ColorType::Rgba, &[200, 100, 50, 0, 200, 100, 50, 0]);
        let grey = png(png::ColorType::Grayscale, &[128, 128]);
        let grey_clear = png(png::ColorType::GrayscaleAlpha, &[128, 0, 128, 0]);
        let pam = b"P7\nWIDTH 2\nHEIGHT 1\nDEPTH 4\nMAXVAL 255\nTUPLTYPE RGB_ALPHA\nENDHDR\n\
                    \xc8\x64\x32\x00\xc8\x64\x32\x00";
        let exr = |alpha: bool| {
            use exr::prelude::*;
            let mut out = std::io::Cursor::new(Vec::new());
            if alpha {
                let rgba =
                    SpecificChannels::rgba(|_: Vec2<usize>| (0.5f32, 0.25f32, 1.0f32, 0.0f32));
                let image = Image::from_channels((2, 1), rgba);
                image.write().to_buffered(&mut out).unwrap();
            } else {
                let rgb = SpecificChannels::rgb(|_: Vec2<usize>| (0.5f32, 0.25f32, 1.0f32));
                let image = Image::from_channels((2, 1), rgb);
                image.write().to_buffered(&mut out).unwrap();
            }
            out.into_inner()
        };
        let cases: [(&str, File, File); 4] = [
            ("rgba", ("a.png", &opaque), ("clear.png", &clear)),
            ("grey-alpha", ("a.png", &grey), ("clear.png", &grey_clear)),
            ("pam", ("a.png", &opaque), ("clear.pam", pam)),
            ("exr", ("a.exr", &exr(false)), ("clear.exr", &exr(true))),
        ];
        for (name, a, b) in cases {
            let changes = listed(name, a, b);
            assert!(
                changes.len() == 1 && changes[0].contains("an alpha channel"),
                "{name}: {changes:?}"
            );
            assert!(listed(name, a, a).is_empty(), "{name}: opaque");
        }
    }

    /// The decoder measures an EXR's display window, cropping what lies outside it, where
    /// viewers built on OpenEXR (GIMP, Blender) show its data window: an EXR of 4x1 pixels,
    /// two of them red, in a display window of 2x1 was `inf dB (identical)` with the 2x1
    /// image of its first two. A display window other than the data window is listed, as
    /// `reproduce` names it.
    #[test]
    fn an_exr_display_window_other_than_its_data_window_is_listed() {
        use exr::prelude::*;
        let exr = |width: usize, display: Option<usize>| {
            let rgb = SpecificChannels::rgb(|at: Vec2<usize>| {
                (if at.0 < 2 { 0.5f32 } else { 1.0 }, 0.25f32, 0.0f32)
            });
            let mut image = Image::from_channels((width, 1), rgb);
            if let Some(display) = display {
                image.attributes.display_window = IntegerBounds::new((0, 0), (display, 1));
            }
            let mut out = std::io::Cursor::new(Vec::new());
            image.write().to_buffered(&mut out).unwrap();
            out.into_inner()
        };
        let (two, overscan) = (exr(2, None), exr(4, Some(2)));
        let changes = listed("exr-window", ("two.exr", &two), ("overscan.exr", &overscan));
        assert_eq!(
            changes,
            ["a displayWindow other than its dataWindow: viewers show another frame"]
        );
        assert!(listed("exr-window", ("a.exr", &two), ("b.exr", &two)).is_empty());
    }

    /// OpenEXR's RGBA interface (`RgbaInputFile`: exrdisplay, ImageMagick) reads a `Y`
    /// channel, grey, in place of R, G and B wherever one is there, and `RY` and `BY` with
    /// it: an EXR of the R, G and B of another and a `Y` of zeros, which those viewers show
    /// black, was `inf dB (identical)` with it. Such channels are listed; another channel
    /// (a depth) is not.
    #[test]
    fn an_exr_s_luminance_or_chroma_channels_are_listed() {
        use exr::prelude::*;
        let exr = |extra: &[&str]| {
            let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = ["R", "G", "B"]
                .iter()
                .map(|name| AnyChannel::new(*name, FlatSamples::F32(vec![0.5; 2])))
                .collect();
            channels.extend(
                extra
                    .iter()
                    .map(|name| AnyChannel::new(*name, FlatSamples::F32(vec![0.0; 2]))),
            );
            let image = Image::from_channels((2, 1), AnyChannels::sort(channels));
            let mut out = std::io::Cursor::new(Vec::new());
            image.write().to_buffered(&mut out).unwrap();
            out.into_inner()
        };
        let rgb = exr(&[]);
        for (name, extra, said) in [
            ("exr-y", &["Y"][..], "(`Y`)"),
            ("exr-ry-by", &["RY", "BY"][..], "(`BY`, `RY`)"),
        ] {
            let changes = listed(name, ("rgb.exr", &rgb), ("b.exr", &exr(extra)));
            assert_eq!(
                changes,
                [format!(
                    "luminance or chroma channels {said}, which viewers built on OpenEXR's \
                     RGBA interface (exrdisplay, ImageMagick) show in place of the R, G and B \
                     the decoder measured"
                )],
                "{name}"
            );
        }
        assert!(listed("exr-z", ("rgb.exr", &rgb), ("b.exr", &exr(&["Z"]))).is_empty());
    }

    /// The header of a scan-line EXR of float B, G, R in ZIP blocks of 16 lines, with a data
    /// window of `data` and a display window of `display` (width, height) pixels: no chunk,
    /// no offset table.
    fn float_rgb_zip_header(data: (u32, u32), display: (u32, u32)) -> Vec<u8> {
        let attribute = |name: &str, kind: &str, value: &[u8]| {
            let mut a = [name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat();
            a.extend((value.len() as u32).to_le_bytes());
            a.extend(value);
            a
        };
        let window = |(x, y): (u32, u32)| -> Vec<u8> {
            [0, 0, x as i32 - 1, y as i32 - 1]
                .iter()
                .flat_map(|v: &i32| v.to_le_bytes())
                .collect()
        };
        let mut channels = Vec::new();
        for name in [b"B", b"G", b"R"] {
            channels.extend(name);
            channels.push(0);
            channels.extend([2i32, 0, 1, 1].iter().flat_map(|v| v.to_le_bytes()));
        }
        channels.push(0);
        let mut file = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        for (name, kind, value) in [
            ("channels", "chlist", channels),
            ("compression", "compression", vec![3]),
            ("dataWindow", "box2i", window(data)),
            ("displayWindow", "box2i", window(display)),
            ("lineOrder", "lineOrder", vec![0]),
            ("pixelAspectRatio", "float", 1f32.to_le_bytes().to_vec()),
            ("screenWindowCenter", "v2f", vec![0; 8]),
            ("screenWindowWidth", "float", 1f32.to_le_bytes().to_vec()),
        ] {
            file.extend(attribute(name, kind, &value));
        }
        file.push(0);
        file
    }

    /// The `exr` crate inflates every block of an EXR's data window, whatever the display
    /// window the decoder is asked for: a file of 3 MiB of ZIP blocks of zeros whose data
    /// window was 2^24 x 16 pixels and display window one pixel asked for 6 GiB and ended
    /// tessera on the failed allocation. Pixels that take more decoded than the longest
    /// file compare reads are refused before the decoder sees the file; here a data window
    /// of 2^21 x 16 float RGB, 384 MiB, from a file of a few hundred KiB.
    #[test]
    fn an_exr_whose_data_window_inflates_past_the_bound_is_refused() {
        let (width, lines) = (1u32 << 21, 16u32);
        let mut file = float_rgb_zip_header((width, lines), (1, 1));
        // One block of 16 lines of zeros, as ZIP compresses them.
        let mut zip = fdeflate::Compressor::new(Vec::new()).unwrap();
        let zeros = vec![0u8; 1 << 20];
        for _ in 0..(u64::from(width) * u64::from(lines) * 12) >> 20 {
            zip.write_data(&zeros).unwrap();
        }
        let zip = zip.finish().unwrap();
        file.extend((file.len() as u64 + 8).to_le_bytes());
        file.extend(0i32.to_le_bytes());
        file.extend((zip.len() as u32).to_le_bytes());
        file.extend(zip);
        let dir = std::env::temp_dir().join(format!("tessera-exr-bomb-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (bomb, one) = (dir.join("bomb.exr"), dir.join("one.exr"));
        std::fs::write(&bomb, &file).unwrap();
        let mut black = crate::film::Film::new(1, 1, 1);
        black.sums[0] = [0; 3];
        black.save(&one, 1.0, None).unwrap();
        let said = difference_of_files(&one, &bomb).map(|d| d.rmse);
        std::fs::remove_dir_all(&dir).unwrap();
        let e = said.unwrap_err().to_string();
        assert!(
            e.contains("has pixels that take 402653184 bytes decoded (a data window of 2097152x16"),
            "{e}"
        );
    }

    /// The decoder makes room for every pixel a header claims before it reads a chunk: an
    /// EXR of 313 bytes, a header of 4096x4096 float RGB in ZIP blocks and nothing after it,
    /// had 201 MB reserved (`compare` ended on the failed allocation under `ulimit -v
    /// 200000`). A header whose chunks the file cannot hold (with the fewest bytes ZIP stores
    /// its pixels in) is refused before the decoder sees it.
    #[test]
    fn an_exr_whose_chunks_are_not_in_the_file_is_refused_before_decoding() {
        let file = float_rgb_zip_header((4096, 4096), (4096, 4096));
        let dir = std::env::temp_dir().join(format!("tessera-exr-short-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let short = dir.join("short.exr");
        std::fs::write(&short, &file).unwrap();
        let said = difference_of_files(&short, &short).map(|d| d.rmse);
        std::fs::remove_dir_all(&dir).unwrap();
        let e = said.unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "is cut short: its header claims 256 chunks (blocks of scan lines or tiles of a \
                 data window of 4096x4096), which take at least {} bytes with the header, and \
                 the file has {}",
                file.len() + 256 * 16 + 4096 * 4096 * 12 / 1032,
                file.len()
            )),
            "{e}"
        );
    }

    /// A NaN is measured as 0, so an EXR of NaN once compared identical with a black one,
    /// though viewers show NaN as they choose (some black, some a warning colour). Each NaN
    /// value is counted and listed.
    #[test]
    fn nan_values_are_listed_not_called_identical_with_black() {
        let exr = |red: f32| {
            use exr::prelude::*;
            let mut out = std::io::Cursor::new(Vec::new());
            let rgb = SpecificChannels::rgb(move |at: Vec2<usize>| {
                (if at.0 == 0 { red } else { 0.0f32 }, 0.0f32, 0.0f32)
            });
            Image::from_channels((2, 1), rgb)
                .write()
                .to_buffered(&mut out)
                .unwrap();
            out.into_inner()
        };
        let (black, nan) = (exr(0.0), exr(f32::NAN));
        let changes = listed("nan", ("black.exr", &black), ("nan.exr", &nan));
        assert_eq!(
            changes,
            ["1 NaN value (measured as 0; viewers differ in what they show for one)"]
        );
        assert!(listed("nan", ("a.exr", &black), ("b.exr", &black)).is_empty());
    }

    /// A JPEG's EXIF orientation (an APP1 segment) turns or flips the picture in viewers,
    /// and its ICC profile (APP2) changes its colours, as a PNG's eXIf and iCCP chunks do:
    /// the same values were once called identical. They are listed.
    #[test]
    fn a_jpeg_s_orientation_and_colour_profile_are_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        let with = |marker: u8, segment: &[u8]| {
            let length = u16::try_from(segment.len() + 2).unwrap().to_be_bytes();
            [&jpeg[..2], &[0xff, marker], &length, segment, &jpeg[2..]].concat()
        };
        // A little-endian TIFF header, one IFD entry: Orientation (0x0112), SHORT, 3.
        let exif = [
            &b"Exif\0\0II*\0\x08\0\0\0\x01\0"[..],
            &[0x12, 0x01, 3, 0, 1, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0],
        ]
        .concat();
        let turned = with(0xe1, &exif);
        let profile = with(0xe2, &[&b"ICC_PROFILE\0\x01\x01"[..], &[0; 128]].concat());
        let changes = listed("jpeg-exif", ("a.jpg", jpeg), ("b.jpg", &turned));
        assert!(
            changes.len() == 1 && changes[0].contains("EXIF orientation (Rotate180)"),
            "{changes:?}"
        );
        let changes = listed("jpeg-icc", ("a.jpg", jpeg), ("b.jpg", &profile));
        assert!(
            changes.len() == 1 && changes[0].contains("ICC colour profile"),
            "{changes:?}"
        );
        assert!(listed("jpeg", ("a.jpg", jpeg), ("b.jpg", jpeg)).is_empty());
    }

    /// libjpeg skips bytes between two segments that are not a marker (warning "Corrupt
    /// JPEG data: 1 extraneous bytes before marker"), and so does the decoder; the walk of
    /// the segments stopped at them. A JFIF segment, one such byte, then an RGB JPEG's
    /// Adobe segment (transform 0): libjpeg shows YCbCr, the decoder measured RGB, and
    /// compare called it identical to the RGB JPEG. It is listed.
    #[test]
    fn a_jpeg_s_segments_past_bytes_libjpeg_skips_are_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        let adobe = [&[0xff, 0xee, 0, 14][..], b"Adobe\0\x64\0\0\0\0\0"].concat();
        // The earth map is JFIF: its own APP0 first, then the stray bytes and Adobe's.
        assert_eq!(&jpeg[6..11], b"JFIF\0");
        let app0 = 4 + usize::from(u16::from_be_bytes([jpeg[4], jpeg[5]]));
        for (name, stray) in [
            ("jpeg-stray", &[0u8][..]),
            ("jpeg-stray-ff00", &[0xff, 0, 7]),
        ] {
            let dir = std::env::temp_dir().join(format!("tessera-{name}-{}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
            let b = [&jpeg[..app0], stray, &adobe, &jpeg[app0..]].concat();
            std::fs::write(dir.join("b.jpg"), b).unwrap();
            let d = difference_of_files(&dir.join("a.jpg"), &dir.join("b.jpg")).unwrap();
            std::fs::remove_dir_all(&dir).unwrap();
            assert!(
                d.display_changes.len() == 1 && d.display_changes[0].1.contains("JFIF segment"),
                "{name}: {:?}",
                d.display_changes
            );
        }
    }

    /// libjpeg takes a colour profile split over 255 APP2 segments, or over two of which
    /// one holds none of its bytes; the decoder takes neither, and compare called both
    /// identical to the same picture without one (djpeg -icc extracts the whole profile).
    /// Both are listed.
    #[test]
    fn a_jpeg_s_colour_profile_libjpeg_takes_and_the_decoder_does_not_is_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        let icc = |seq: u8, count: u8, bytes: &[u8]| {
            let segment = [&b"ICC_PROFILE\0"[..], &[seq, count], bytes].concat();
            let length = u16::try_from(segment.len() + 2).unwrap().to_be_bytes();
            [&[0xff, 0xe2][..], &length, &segment].concat()
        };
        let with = |segments: Vec<Vec<u8>>| [&jpeg[..2], &segments.concat(), &jpeg[2..]].concat();
        let empty_second = with(vec![icc(1, 2, &[0; 128]), icc(2, 2, &[])]);
        let in_255 = with((1..=255).map(|seq| icc(seq, 255, &[0; 4])).collect());
        for (name, b) in [("jpeg-icc-empty", &empty_second), ("jpeg-icc-255", &in_255)] {
            let changes = listed(name, ("a.jpg", jpeg), ("b.jpg", b));
            assert_eq!(changes, [JPEG_ICC_PROFILE], "{name}");
        }
    }

    /// libjpeg takes a JFIF segment's word that a three-component JPEG is YCbCr over an
    /// Adobe segment's (transform 0, RGB); the decoder takes Adobe's. The earth map with
    /// such a segment added is shown as it was, but was measured at 9.26 dB from it, and
    /// at 73 dB (near identical) from the picture of its YCbCr values taken as RGB, which
    /// no viewer built on libjpeg shows. It is listed; without JFIF, both take it as RGB.
    #[test]
    fn a_jpeg_of_jfif_and_an_adobe_rgb_transform_is_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        let adobe = |transform: u8| {
            let segment = [&b"Adobe\0\x64\0\0\0\0"[..], &[transform]].concat();
            let length = u16::try_from(segment.len() + 2).unwrap().to_be_bytes();
            [&[0xff, 0xee][..], &length, &segment].concat()
        };
        // What is listed of `b` against the earth map, whatever the values measured.
        let changes = |name: &str, b: &[u8]| {
            let dir = std::env::temp_dir().join(format!("tessera-{name}-{}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
            std::fs::write(dir.join("b.jpg"), b).unwrap();
            let d = difference_of_files(&dir.join("a.jpg"), &dir.join("b.jpg")).unwrap();
            std::fs::remove_dir_all(&dir).unwrap();
            d.display_changes
                .into_iter()
                .map(|(_, change)| change)
                .collect::<Vec<_>>()
        };
        assert_eq!(&jpeg[6..11], b"JFIF\0");
        let rgb = [&jpeg[..2], &adobe(0), &jpeg[2..]].concat();
        let listed = changes("jpeg-jfif-adobe", &rgb);
        assert!(
            listed.len() == 1 && listed[0].contains("an Adobe segment (APP14)"),
            "{listed:?}"
        );
        let ycbcr = [&jpeg[..2], &adobe(1), &jpeg[2..]].concat();
        assert_eq!(changes("jpeg-jfif-adobe-1", &ycbcr), Vec::<String>::new());
        let app0 = 4 + usize::from(u16::from_be_bytes([jpeg[4], jpeg[5]]));
        let without_jfif = [&jpeg[..2], &adobe(0), &jpeg[app0..]].concat();
        assert_eq!(changes("jpeg-adobe", &without_jfif), Vec::<String>::new());
    }

    /// The decoder takes a JPEG whose components are named 'R', 'G' and 'B' as RGB, where
    /// libjpeg takes a JFIF segment's or an Adobe segment's word (YCbCr) first: the earth
    /// map so renamed is shown as it was, but was measured at 9.26 dB from it, and at
    /// 73 dB (near identical, nothing listed) from its YCbCr values taken as RGB. It is
    /// listed; without either segment, both take the names' word (RGB).
    #[test]
    fn a_jpeg_of_components_named_rgb_that_libjpeg_shows_as_ycbcr_is_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        // The earth map with its components (1, 2, 3) named 'R', 'G', 'B' in its frame and
        // its scan.
        let mut named = jpeg.to_vec();
        let mut at = 2;
        while named[at + 1] != 0xda {
            let length = usize::from(u16::from_be_bytes([named[at + 2], named[at + 3]]));
            if named[at + 1] == 0xc0 {
                for k in 0..3 {
                    named[at + 10 + 3 * k] = b"RGB"[k];
                }
            }
            at += 2 + length;
        }
        for k in 0..3 {
            assert_eq!(named[at + 5 + 2 * k], 1 + k as u8);
            named[at + 5 + 2 * k] = b"RGB"[k];
        }
        let segment = |marker: u8, bytes: &[u8]| {
            let length = u16::try_from(bytes.len() + 2).unwrap().to_be_bytes();
            [&[0xff, marker][..], &length, bytes].concat()
        };
        let adobe =
            |transform: u8| segment(0xee, &[&b"Adobe\0\x64\0\0\0\0"[..], &[transform]].concat());
        let app0 = 4 + usize::from(u16::from_be_bytes([jpeg[4], jpeg[5]]));
        let without_jfif = [&named[..2], &named[app0..]].concat();
        let cases: [(&str, Vec<u8>, &str); 5] = [
            ("jfif", named.clone(), "a JFIF segment (APP0)"),
            (
                "adobe-1",
                [&named[..2], &adobe(1), &named[app0..]].concat(),
                "an Adobe segment (APP14), which says",
            ),
            ("names", without_jfif.clone(), ""),
            (
                "adobe-0",
                [&named[..2], &adobe(0), &named[app0..]].concat(),
                "",
            ),
            // A JFIF segment shorter than libjpeg reads as one says nothing to it.
            (
                "short-jfif",
                [&named[..2], &segment(0xe0, b"JFIF\0"), &named[app0..]].concat(),
                "",
            ),
        ];
        for (name, b, said) in cases {
            let a = ("a.jpg", &without_jfif[..]);
            let changes = listed(&format!("jpeg-named-{name}"), a, ("b.jpg", &b));
            if said.is_empty() {
                assert!(changes.is_empty(), "{name}: {changes:?}");
            } else {
                assert!(
                    changes.len() == 1
                        && changes[0].starts_with(said)
                        && changes[0].contains("components named 'R', 'G' and 'B'"),
                    "{name}: {changes:?}"
                );
            }
        }
    }

    /// An Adobe segment of transform 1 in a JPEG of four components is YCCK to libjpeg
    /// (ImageMagick: "Unknown Adobe color transform code 1", and the YCCK picture) and CMYK
    /// to the decoder: the earth map so made was measured at 72.52 dB (nothing listed) from
    /// ImageMagick's picture of its CMYK reading, 8.86 dB from what it shows. It is listed.
    #[test]
    fn a_jpeg_of_four_components_and_an_adobe_ycbcr_transform_is_listed() {
        let ycck = include_bytes!("../tests/data/ycck-8x8.jpg");
        let transform = ycck.windows(5).position(|w| w == b"Adobe").unwrap() + 11;
        assert_eq!(ycck[transform], 2);
        let with = |t: u8| {
            let mut jpeg = ycck.to_vec();
            jpeg[transform] = t;
            jpeg
        };
        let (cmyk, ycbcr) = (with(0), with(1));
        let changes = listed("jpeg-four-adobe-1", ("a.jpg", &cmyk), ("b.jpg", &ycbcr));
        assert!(
            changes.len() == 1 && changes[0].contains("show them as YCCK"),
            "{changes:?}"
        );
        assert!(listed("jpeg-four-adobe-0", ("a.jpg", &cmyk), ("b.jpg", &cmyk)).is_empty());
    }

    /// The decoder fills a JPEG cut short with grey: the earth map's first 80,000 bytes
    /// were measured (9.59 dB from the whole), and called identical to a picture of that
    /// grey, where a texture of them is refused. It is refused as a texture is; bytes after
    /// the end marker are not a truncation.
    #[test]
    fn a_jpeg_cut_short_is_refused() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        let dir = std::env::temp_dir().join(format!("tessera-jpeg-cut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
        std::fs::write(dir.join("cut.jpg"), &jpeg[..80_000]).unwrap();
        std::fs::write(dir.join("after.jpg"), [&jpeg[..], b"appended"].concat()).unwrap();
        let cut = difference_of_files(&dir.join("a.jpg"), &dir.join("cut.jpg")).err();
        let after = difference_of_files(&dir.join("a.jpg"), &dir.join("after.jpg"));
        std::fs::remove_dir_all(&dir).unwrap();
        let cut = cut.map(|e| e.to_string()).unwrap_or_default();
        assert!(cut.contains("ends before its image does"), "{cut}");
        assert_eq!(after.unwrap().rmse, 0.0);
    }

    /// An FF D9 within a segment after a scan (a comment between two scans of a
    /// progressive file) once counted as the end: a progressive JPEG cut within such a
    /// comment was measured from the scans the decoder had. The segment is skipped by its
    /// length, as libjpeg skips it ("Premature end of JPEG file").
    #[test]
    fn a_jpeg_cut_within_a_segment_after_its_scan_is_refused() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        let (pixels, end) = jpeg.split_at(jpeg.len() - 2);
        assert_eq!(end, [0xff, 0xd9]);
        let comment = b"\xff\xfe\x00\x0fhello\xff\xd9 there";
        let dir = std::env::temp_dir().join(format!("tessera-jpeg-com-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
        std::fs::write(dir.join("cut.jpg"), [pixels, &comment[..11]].concat()).unwrap();
        std::fs::write(dir.join("whole.jpg"), [pixels, comment, end].concat()).unwrap();
        let cut = difference_of_files(&dir.join("a.jpg"), &dir.join("cut.jpg")).err();
        let whole = difference_of_files(&dir.join("a.jpg"), &dir.join("whole.jpg"));
        std::fs::remove_dir_all(&dir).unwrap();
        let cut = cut.map(|e| e.to_string()).unwrap_or_default();
        assert!(cut.contains("ends before its image does"), "{cut}");
        assert_eq!(whole.unwrap().rmse, 0.0);
    }

    /// libexif (and eog, and the viewers built on it) reads an orientation of type LONG,
    /// of two values, the first of two in IFD0, or one in IFD1 (the thumbnail's) and turns
    /// the picture by it; the decoder reads only the first SHORT of one value in IFD0: such
    /// pictures were once called identical. They are listed; an EXIF segment whose IFDs lie
    /// past its end is refused, and one whose IFD1 is its IFD0 again is walked once more.
    #[test]
    fn a_jpeg_orientation_libexif_reads_is_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        // A TIFF header (`big` or little-endian), IFD0 at byte 8 of `ifd0` entries (tag,
        // type, count, value) and then IFD1 of `ifd1` entries, if any.
        let exif = |big: bool, ifd0: &[(u16, u16, u32, u32)], ifd1: &[(u16, u16, u32, u32)]| {
            let (u16b, u32b) = if big {
                (
                    u16::to_be_bytes as fn(u16) -> [u8; 2],
                    u32::to_be_bytes as fn(u32) -> [u8; 4],
                )
            } else {
                (
                    u16::to_le_bytes as fn(u16) -> [u8; 2],
                    u32::to_le_bytes as fn(u32) -> [u8; 4],
                )
            };
            let ifd = |entries: &[(u16, u16, u32, u32)], next: u32| {
                let mut out = u16b(entries.len() as u16).to_vec();
                for &(tag, kind, count, value) in entries {
                    out.extend([u16b(tag), u16b(kind)].concat());
                    out.extend(u32b(count));
                    out.extend(if kind == 3 {
                        [u16b(value as u16), [0, 0]].concat()
                    } else {
                        u32b(value).to_vec()
                    });
                }
                out.extend(u32b(next));
                out
            };
            let next = if ifd1.is_empty() {
                0
            } else {
                8 + 6 + 12 * ifd0.len() as u32
            };
            let mut segment = [&b"Exif\0\0"[..], if big { b"MM\0*" } else { b"II*\0" }].concat();
            segment.extend(u32b(8));
            segment.extend(ifd(ifd0, next));
            if !ifd1.is_empty() {
                segment.extend(ifd(ifd1, 0));
            }
            let length = u16::try_from(segment.len() + 2).unwrap().to_be_bytes();
            [&jpeg[..2], &[0xff, 0xe1], &length, &segment, &jpeg[2..]].concat()
        };
        let turned = |name: &str, file: &[u8]| {
            let changes = listed(name, ("a.jpg", jpeg), ("b.jpg", file));
            assert!(
                changes.len() == 1 && changes[0].contains("libexif"),
                "{name}: {changes:?}"
            );
        };
        for big in [false, true] {
            turned("jpeg-exif-long", &exif(big, &[(0x112, 4, 1, 6)], &[]));
            turned("jpeg-exif-count", &exif(big, &[(0x112, 3, 2, 6)], &[]));
            let first_long = [(0x112, 4, 1, 6), (0x112, 3, 1, 1)];
            turned("jpeg-exif-twice", &exif(big, &first_long, &[]));
            turned(
                "jpeg-exif-ifd1",
                &exif(big, &[(0x10f, 3, 1, 0)], &[(0x112, 3, 1, 8)]),
            );
            let upright = exif(big, &[(0x112, 4, 1, 1)], &[(0x112, 3, 1, 1)]);
            assert!(listed("jpeg-exif-upright", ("a.jpg", jpeg), ("b.jpg", &upright)).is_empty());
        }
        // IFD1 is IFD0 again (a loop): walked twice, its orientation says upright.
        let mut looped = exif(false, &[(0x112, 3, 1, 1)], &[]);
        let at = 2 + 4 + 6 + 8 + 2 + 12;
        looped[at..at + 4].copy_from_slice(&8u32.to_le_bytes());
        assert!(listed("jpeg-exif-loop", ("a.jpg", jpeg), ("b.jpg", &looped)).is_empty());
        // IFD0 past the segment's end; 65535 entries in a segment of one.
        let dir = std::env::temp_dir().join(format!("tessera-exif-past-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut far = exif(false, &[(0x112, 3, 1, 6)], &[]);
        far[2 + 4 + 6 + 4..][..4].copy_from_slice(&60000u32.to_le_bytes());
        let mut many = exif(false, &[(0x112, 3, 1, 6)], &[]);
        many[2 + 4 + 6 + 8..][..2].copy_from_slice(&u16::MAX.to_le_bytes());
        for (name, file, says) in [
            ("far.jpg", far, "its IFD0 (at byte 60000)"),
            ("many.jpg", many, "65535 entries"),
        ] {
            std::fs::write(dir.join(name), file).unwrap();
            let err = difference_of_files(&dir.join(name), &dir.join(name))
                .unwrap_err()
                .to_string();
            assert!(err.contains("EXIF segment") && err.contains(says), "{err}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// libexif's viewers (eog) take IFD0's orientation before IFD1's, and the first of an
    /// IFD's two: an IFD1 orientation (6) left from before a lossless turn whose IFD0 says
    /// upright, or a second IFD0 one, was once listed as turning the picture.
    #[test]
    fn a_jpeg_orientation_libexif_does_not_read_is_not_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        // Little-endian: IFD0 at byte 8 of `ifd0` orientation entries (type, count, value),
        // then IFD1 of `ifd1` ones.
        let exif = |ifd0: &[(u16, u32, u32)], ifd1: &[(u16, u32, u32)]| {
            let ifd = |entries: &[(u16, u32, u32)], next: u32| {
                let mut out = (entries.len() as u16).to_le_bytes().to_vec();
                for &(kind, count, value) in entries {
                    out.extend(0x112u16.to_le_bytes());
                    out.extend(kind.to_le_bytes());
                    out.extend(count.to_le_bytes());
                    out.extend(value.to_le_bytes());
                }
                out.extend(next.to_le_bytes());
                out
            };
            let mut segment = b"Exif\0\0II*\0".to_vec();
            segment.extend(8u32.to_le_bytes());
            segment.extend(ifd(ifd0, 8 + 6 + 12 * ifd0.len() as u32));
            segment.extend(ifd(ifd1, 0));
            let length = u16::try_from(segment.len() + 2).unwrap().to_be_bytes();
            [&jpeg[..2], &[0xff, 0xe1], &length, &segment, &jpeg[2..]].concat()
        };
        for (name, file) in [
            ("ifd1-left", exif(&[(3, 1, 1)], &[(3, 1, 6)])),
            ("second-in-ifd0", exif(&[(3, 1, 1), (4, 1, 6)], &[])),
        ] {
            let changes = listed(&format!("jpeg-{name}"), ("a.jpg", jpeg), ("b.jpg", &file));
            assert!(changes.is_empty(), "{name}: {changes:?}");
        }
        // A LONG first in IFD0 is what libexif reads, whatever IFD1 says.
        let long = exif(&[(4, 1, 6)], &[(3, 1, 1)]);
        let changes = listed("jpeg-long-first", ("a.jpg", jpeg), ("b.jpg", &long));
        assert!(
            changes.len() == 1 && changes[0].contains("(6) in IFD0, a LONG"),
            "{changes:?}"
        );
    }

    /// Cameras' files have an IFD1 offset past the EXIF segment's end, or an IFD1 running
    /// past it: libexif skips what does not fit ("Bogus offset of IFD1") and every viewer
    /// shows the picture, which compare once refused. What fits is read as libexif reads it.
    #[test]
    fn a_jpeg_whose_exif_ifd1_lies_past_its_end_is_read_as_libexif_reads() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        // Little-endian: IFD0 at byte 8 of one entry (Make), its next IFD at `next`, then
        // `ifd1` (its count and entries as bytes).
        let exif = |next: u32, ifd1: &[u8]| {
            let mut segment = b"Exif\0\0II*\0".to_vec();
            segment.extend(8u32.to_le_bytes());
            segment.extend(1u16.to_le_bytes());
            segment.extend([0x0f, 0x01, 2, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
            segment.extend(next.to_le_bytes());
            segment.extend(ifd1);
            let length = u16::try_from(segment.len() + 2).unwrap().to_be_bytes();
            [&jpeg[..2], &[0xff, 0xe1], &length, &segment, &jpeg[2..]].concat()
        };
        let entry = |kind: u16, count: u32, value: u32| {
            [
                &0x112u16.to_le_bytes()[..],
                &kind.to_le_bytes(),
                &count.to_le_bytes(),
                &value.to_le_bytes(),
            ]
            .concat()
        };
        // The TIFF structure's IFD0 ends at byte 26, where IFD1 begins if it reads.
        let unread: [(&str, Vec<u8>); 4] = [
            ("far", exif(0xffff_fff0, &[])),
            ("just-past", exif(26 + 100, &[])),
            ("half-a-count", exif(26, &[1])),
            // IFD1's orientation (two LONGs) lies past the end: libexif skips it.
            (
                "value-past",
                exif(26, &[&1u16.to_le_bytes()[..], &entry(4, 2, 60000)].concat()),
            ),
        ];
        for (name, file) in unread {
            let changes = listed(
                &format!("jpeg-ifd1-{name}"),
                ("a.jpg", jpeg),
                ("b.jpg", &file),
            );
            assert!(changes.is_empty(), "{name}: {changes:?}");
        }
        // 65535 entries claimed, one within the segment: its orientation is read.
        let many = exif(26, &[&u16::MAX.to_le_bytes()[..], &entry(3, 1, 8)].concat());
        let changes = listed("jpeg-ifd1-many", ("a.jpg", jpeg), ("b.jpg", &many));
        assert!(
            changes.len() == 1 && changes[0].contains("(8) in IFD1"),
            "{changes:?}"
        );
    }

    /// libjpeg takes a JPEG's colours from the segments before its first scan, the decoder
    /// takes an Adobe segment (APP14) between its scans too: a progressive JPEG libjpeg shows
    /// as RGB (an Adobe transform 0 first, no JFIF segment) with an Adobe transform 1 before
    /// its second scan was measured as YCbCr and called `inf dB (identical)` to the same
    /// scans after a JFIF segment, which libjpeg (Pillow 13) shows 10.65 dB apart. It is
    /// listed; one that leaves the decoder's reading as it was is not.
    #[test]
    fn a_jpeg_adobe_segment_after_its_first_scan_is_listed() {
        // Pillow's, of 8x8 pixels: a JFIF segment (APP0) first, then ten scans.
        let jpeg = include_bytes!("../tests/data/progressive-8x8.jpg");
        let scans: Vec<usize> = (0..jpeg.len() - 1)
            .filter(|&i| jpeg[i..i + 2] == [0xff, 0xda])
            .collect();
        assert_eq!(scans.len(), 10);
        let adobe = |t: u8| [&b"\xff\xee\0\x0eAdobe\0\x64\0\0\0\0"[..], &[t]].concat();
        let jfif = 2 + 2 + usize::from(u16::from_be_bytes([jpeg[4], jpeg[5]]));
        assert_eq!(&jpeg[6..10], b"JFIF");
        // No JFIF segment, an Adobe transform 0 before the first scan: RGB to both.
        let rgb = [
            &jpeg[..2],
            &jpeg[jfif..scans[0]],
            &adobe(0),
            &jpeg[scans[0]..],
        ]
        .concat();
        let second = scans[1] - jfif + 2 + adobe(0).len();
        let late = [&rgb[..second], &adobe(1), &rgb[second..]].concat();
        let changes = listed("jpeg-late-adobe", ("a.jpg", jpeg), ("b.jpg", &late));
        assert!(
            changes.len() == 1 && changes[0].contains("transform 1 after its first scan"),
            "{changes:?}"
        );
        // YCbCr (JFIF) and a later transform 1: YCbCr to both.
        let second = scans[1];
        let kept = [&jpeg[..second], &adobe(1), &jpeg[second..]].concat();
        assert!(listed("jpeg-late-adobe-1", ("a.jpg", jpeg), ("b.jpg", &kept)).is_empty());
        // After the only scan of the earth map (baseline), read before it: not listed.
        let earth = include_bytes!("../scenes/earthmap.jpg");
        let (pixels, end) = earth.split_at(earth.len() - 2);
        let tail = [pixels, &adobe(0), end].concat();
        assert!(listed("jpeg-tail-adobe", ("a.jpg", earth), ("b.jpg", &tail)).is_empty());
        // A later transform 0 of three components: CMYK to the decoder, not the same values.
        let dir = std::env::temp_dir().join(format!("tessera-late-0-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cmyk = [&jpeg[..second], &adobe(0), &jpeg[second..]].concat();
        std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
        std::fs::write(dir.join("b.jpg"), cmyk).unwrap();
        let d = difference_of_files(&dir.join("a.jpg"), &dir.join("b.jpg")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            d.display_changes.len() == 1 && d.display_changes[0].1.contains("transform 0"),
            "{:?}",
            d.display_changes
        );
    }

    /// Browsers read a JPEG's first EXIF segment, its decoder the last: a first one saying
    /// "turned" before a last one saying "upright" showed a turned picture that compare
    /// called `inf dB (identical)` to the upright one.
    #[test]
    fn a_jpeg_of_two_exif_segments_is_listed() {
        let jpeg = include_bytes!("../scenes/earthmap.jpg");
        // A big-endian TIFF header, one IFD entry: Orientation (0x0112), SHORT, `turn`.
        let exif = |turn: u8| {
            let segment = [
                &b"Exif\0\0MM\0*\0\0\0\x08\0\x01"[..],
                &[0x01, 0x12, 0, 3, 0, 0, 0, 1, 0, turn, 0, 0, 0, 0, 0, 0],
            ]
            .concat();
            let length = u16::try_from(segment.len() + 2).unwrap().to_be_bytes();
            [&[0xff, 0xe1][..], &length, &segment].concat()
        };
        let twice = [&jpeg[..2], &exif(6), &exif(1), &jpeg[2..]].concat();
        let changes = listed("jpeg-two-exif", ("a.jpg", jpeg), ("b.jpg", &twice));
        assert!(
            changes.len() == 1 && changes[0].contains("2 EXIF segments"),
            "{changes:?}"
        );
        let once = [&jpeg[..2], &exif(1), &jpeg[2..]].concat();
        assert!(listed("jpeg-one-exif", ("a.jpg", jpeg), ("b.jpg", &once)).is_empty());
        // After as many empty comments (FF FE 00 02, 256 KiB) as the walk takes, the two
        // segments went unread: `inf dB (identical)`, nothing listed. Such a file is refused.
        let comments = |n| b"\xff\xfe\x00\x02".repeat(n);
        let walked = [&jpeg[..2], &comments(MAX_JPEG_SEGMENTS - 100), &twice[2..]].concat();
        let changes = listed("jpeg-walked-exif", ("a.jpg", jpeg), ("b.jpg", &walked));
        assert!(
            changes.len() == 1 && changes[0].contains("2 EXIF segments"),
            "{changes:?}"
        );
        let hidden = [&jpeg[..2], &comments(MAX_JPEG_SEGMENTS), &twice[2..]].concat();
        let dir = std::env::temp_dir().join(format!("tessera-jpeg-many-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
        std::fs::write(dir.join("b.jpg"), &hidden).unwrap();
        let d = difference_of_files(&dir.join("a.jpg"), &dir.join("b.jpg"));
        std::fs::remove_dir_all(&dir).unwrap();
        let refused = d.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(
            refused.contains("b.jpg") && refused.contains("more than 65536 segments"),
            "{refused}"
        );
    }

    #[test]
    fn psnr_of_a_uniform_offset() {
        let a = RgbImage::from_rgb8(1, 1, &[0, 0, 0]);
        let b = RgbImage::from_rgb8(1, 1, &[255, 255, 255]);
        let d = difference(&a, &b).unwrap();
        assert!((d.rmse - 1.0).abs() < 1e-12);
        assert!(d.psnr_db.abs() < 1e-9);
        let c = RgbImage::from_rgb8(2, 1, &[0; 6]);
        assert!(difference(&a, &c).is_err());
    }
}
