//! The tests of `image_diff`: measures, headers that change what a viewer shows, and
//! refusals before decoding, on files built here.

use super::jpeg::MAX_JPEG_SEGMENTS;
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

/// A PNM of a width or height of 0 (which PNG and EXR cannot be): two such files compared
/// `identical` (RMSE 0, PSNR inf), a verdict on no pixels. Each is refused by its size.
#[test]
fn an_image_of_no_pixels_is_refused() {
    let dir = std::env::temp_dir().join(format!("tessera-no-pixels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, bytes, size) in [
        ("wide.pgm", &b"P5\n2 0\n255\n"[..], "2x0"),
        ("none.ppm", b"P6\n0 0\n255\n", "0x0"),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = difference_of_files(&path, &path).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "is {size}: an image to compare has at least one pixel"
            )),
            "{name}: {e}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// compare measures the colour channels only: an image with an alpha channel (a PNG of
/// colour type 4 or 6, an EXR with an `A` channel, a PAM of tuple type RGB_ALPHA) once
/// compared `identical` with an opaque one of the same colours, though a viewer shows
/// it transparent. It is listed, as a PNG's tRNS chunk is.
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
            let rgba = SpecificChannels::rgba(|_: Vec2<usize>| (0.5f32, 0.25f32, 1.0f32, 0.0f32));
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let ycck = include_bytes!("../../tests/data/ycck-8x8.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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

/// The earth map cut at half its coded data and its end marker put back was measured with
/// its lower half grey (as libjpeg shows it, with a warning), and so called identical to a
/// picture of that grey: it holds more coded data than `too_short` asks. It is refused as
/// a texture is, by the scan whose data ends and the block it ends at.
#[test]
fn a_jpeg_whose_scan_ends_before_its_blocks_is_refused() {
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
    let scan = jpeg.windows(2).position(|w| w == [0xff, 0xda]).unwrap();
    let cut = [&jpeg[..scan + (jpeg.len() - scan) / 2], &[0xff, 0xd9]].concat();
    let dir = std::env::temp_dir().join(format!("tessera-jpeg-scan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("cut.jpg"), &cut).unwrap();
    let e = difference_of_files(&dir.join("cut.jpg"), &dir.join("cut.jpg")).err();
    std::fs::remove_dir_all(&dir).unwrap();
    let e = e.map(|e| e.to_string()).unwrap_or_default();
    assert!(
        e.contains("has a scan (scan 1) whose coded data ends at its block"),
        "{e}"
    );
}

/// The decoder reads frames of Huffman coding, baseline, extended and progressive (SOF0 to
/// SOF2), and skips a frame header of another kind as an unknown segment: the earth map's
/// frame header marked arithmetic-coded (SOF9), lossless (SOF3) or hierarchical (SOF5) was
/// refused with "Number of components cannot be zero", a fault the file does not have. It
/// is refused by the kind of its frame, named.
#[test]
fn a_jpeg_of_a_frame_kind_the_decoder_does_not_read_is_refused_by_its_kind() {
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
    let sof = jpeg.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
    let dir = std::env::temp_dir().join(format!("tessera-jpeg-kind-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a.jpg"), jpeg).unwrap();
    let mut refusals = Vec::new();
    for (marker, kind) in [
        (0xc9, "arithmetic coding (SOF9)"),
        (0xca, "arithmetic coding (SOF10)"),
        (0xc3, "lossless (SOF3)"),
        (0xc5, "hierarchical (SOF5)"),
    ] {
        let mut other = jpeg.to_vec();
        other[sof + 1] = marker;
        std::fs::write(dir.join("b.jpg"), &other).unwrap();
        let e = difference_of_files(&dir.join("a.jpg"), &dir.join("b.jpg")).err();
        refusals.push((kind, e.map(|e| e.to_string()).unwrap_or_default()));
    }
    // An extended frame (SOF1) of 8 bits is read as the baseline one is.
    let mut extended = jpeg.to_vec();
    extended[sof + 1] = 0xc1;
    std::fs::write(dir.join("b.jpg"), &extended).unwrap();
    let same = difference_of_files(&dir.join("a.jpg"), &dir.join("b.jpg"));
    std::fs::remove_dir_all(&dir).unwrap();
    for (kind, e) in refusals {
        assert!(
            e.contains("b.jpg")
                && e.contains(kind)
                && e.contains("a kind the decoder does not read"),
            "{kind}: {e}"
        );
    }
    assert_eq!(same.unwrap().rmse, 0.0);
}

/// An FF D9 within a segment after a scan (a comment between two scans of a
/// progressive file) once counted as the end: a progressive JPEG cut within such a
/// comment was measured from the scans the decoder had. The segment is skipped by its
/// length, as libjpeg skips it ("Premature end of JPEG file").
#[test]
fn a_jpeg_cut_within_a_segment_after_its_scan_is_refused() {
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../tests/data/progressive-8x8.jpg");
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
    let earth = include_bytes!("../../scenes/earthmap.jpg");
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
    let jpeg = include_bytes!("../../scenes/earthmap.jpg");
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
