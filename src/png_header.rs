//! A PNG file's header read as a stranger's: its chunks walked within bounds (at most
//! `MAX_PNG_CHUNKS`, every length inside the file, one IHDR first, an IEND last) for its size,
//! tessera's recipe (an iTXt chunk, inflated no further than a recipe may be; one in a tEXt
//! or zTXt chunk, or under a keyword exiftool takes for its, is refused), the chunks that
//! change how a viewer shows it and the header of its pixels' zlib stream, the others skipped
//! unread (a text chunk past its keyword). Below the scene, whose image textures are walked
//! so before a decoder keeps their chunks, and the image files.

use crate::metadata::{KEY, MAX_BYTES};
use std::io::{Read, Seek};

/// What a PNG file says of itself.
#[derive(Clone, Debug)]
pub struct PngHeader {
    pub width: u32,
    pub height: u32,
    /// The recipe's text, at most `MAX_BYTES` of it, not yet checked.
    pub recipe: Option<String>,
    /// The chunks tessera does not write that change how a viewer shows the picture, each
    /// said in words.
    pub display_changes: Vec<String>,
    /// The first two bytes of the pixels' zlib stream, where the first IDAT chunk holds
    /// both (tessera's always does): its method, the window it declares, whether it needs a
    /// preset dictionary.
    pub zlib_header: Option<[u8; 2]>,
}

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];

/// The most chunks a PNG may have: tessera writes a handful (its pixels in a few IDAT
/// chunks), and each chunk costs a read.
pub const MAX_PNG_CHUNKS: u64 = 1 << 16;

/// PNG chunks tessera does not write that change how a viewer shows the picture, and how.
const DISPLAY_CHUNKS: [(&[u8; 4], &str); 14] = [
    (b"acTL", "an animation"),
    (b"fcTL", "an animation frame"),
    (b"fdAT", "an animation frame's pixels"),
    (b"tRNS", "transparency"),
    (b"gAMA", "another gamma"),
    (b"cHRM", "other primaries and white point"),
    (b"sRGB", "a rendering intent"),
    (b"iCCP", "an ICC colour profile"),
    (b"cICP", "coding-independent colour information"),
    (b"mDCV", "mastering display colour volume"),
    (b"cLLI", "content light levels"),
    (b"eXIf", "EXIF data, which can turn or flip the picture"),
    (
        b"pHYs",
        "a pixel aspect ratio, which can stretch the picture",
    ),
    // Apple's decoders decode the rows after the place an iDOT chunk points to as a zlib
    // stream of their own, in parallel: a file can hold pixels that every other decoder
    // reads and, for those rows, others that macOS and iOS show (an "ambiguous PNG").
    (
        b"iDOT",
        "Apple's index for parallel decoding, with which macOS and iOS can show other pixels",
    ),
];

/// A chunk of the type `kind` in words, with its article: "an iCCP chunk", "a tRNS chunk".
/// A type is read as a word, as the project writes "an IDAT chunk": "an" where it begins
/// with a vowel other than `u` (said "you"). Bytes that are not letters are escaped.
fn a_chunk(kind: &[u8; 4]) -> String {
    let article = if matches!(kind[0].to_ascii_lowercase(), b'a' | b'e' | b'i' | b'o') {
        "an"
    } else {
        "a"
    };
    format!(
        "{article} {} chunk",
        String::from_utf8_lossy(kind).escape_debug()
    )
}

/// Walks a PNG's chunks (`len` bytes in all) for its size, the recipe's iTXt chunk and the
/// chunks that change how it is shown, skipping the others unread.
pub fn read<R: Read + Seek>(r: R, len: u64) -> Result<PngHeader, String> {
    let mut r = std::io::BufReader::new(r);
    let mut signature = [0u8; 8];
    if r.read_exact(&mut signature).is_err() || signature != PNG_SIGNATURE {
        return Err("is not a PNG file".to_owned());
    }
    let (mut at, mut size, mut found) = (8u64, None, None);
    let mut display_changes = Vec::new();
    let (mut zlib_header, mut idat_seen, mut idat_ended) = (None, false, false);
    // IHDR's colour type and the entries of the palette before, for a tRNS chunk's length.
    let (mut color, mut entries) = (None, None);
    // Skips `n` bytes, within the buffer where it can.
    let skip =
        |r: &mut std::io::BufReader<R>, n: i64| r.seek_relative(n).map_err(|e| e.to_string());
    for chunks in 0.. {
        if chunks == MAX_PNG_CHUNKS {
            return Err(format!(
                "has more than {MAX_PNG_CHUNKS} chunks; tessera writes a handful"
            ));
        }
        let mut head = [0u8; 8];
        if r.read_exact(&mut head).is_err() {
            return Err(format!("is truncated at byte {at} (no IEND chunk)"));
        }
        let length = u64::from(u32::from_be_bytes(head[..4].try_into().expect("4 bytes")));
        let kind: [u8; 4] = head[4..].try_into().expect("4 bytes");
        // The data and its CRC must lie inside the file: no length is trusted further.
        if length > (1 << 31) - 1 || at + 12 + length > len {
            return Err(format!(
                "has {} at byte {at} claiming {}, past the file's end",
                a_chunk(&kind),
                crate::text::count(length, "byte")
            ));
        }
        // One IHDR chunk, first, of 13 bytes, as a PNG has: a second one would be another
        // image's size, which a decoder ignores but a header reader might report.
        let is_ihdr = &kind == b"IHDR";
        if chunks == 0 && !is_ihdr {
            return Err(format!(
                "does not begin with its IHDR chunk ({} at byte 8), as a PNG must",
                a_chunk(&kind)
            ));
        }
        if is_ihdr && chunks > 0 {
            return Err(format!("has a second IHDR chunk at byte {at}"));
        }
        if is_ihdr && length != 13 {
            return Err(format!(
                "has an IHDR chunk of {}, not the 13 of a PNG",
                crate::text::count(length, "byte")
            ));
        }
        // A palette is whole entries of three bytes: libpng refuses a palette image's
        // PLTE chunk of any other length ("PLTE: invalid"), and the PNG decoder here
        // indexes past the chunk's end where it expands the pixels (a 4-byte palette once
        // ended `compare` in a panic, "range end index 3 out of range for slice of length
        // 1").
        if &kind == b"PLTE" && length % 3 != 0 {
            return Err(format!(
                "has a PLTE chunk of {} at byte {at}, not whole entries of 3 bytes as a \
                 palette is (libpng refuses the file)",
                crate::text::count(length, "byte")
            ));
        }
        if &kind == b"PLTE" {
            entries = Some(length / 3);
        }
        // A chunk's type is four ASCII letters: libpng refuses a file of any other ("invalid
        // chunk type"), where the PNG decoder skips it as an unknown chunk of no importance.
        if !kind.iter().all(u8::is_ascii_alphabetic) {
            let said = format!(
                "a chunk of the type `{}`, not four letters as a PNG chunk's type is: libpng \
                 refuses the file, and viewers built on it show nothing",
                String::from_utf8_lossy(&kind).escape_debug()
            );
            if !display_changes.contains(&said) {
                display_changes.push(said);
            }
        }
        if let Some((_, how)) = DISPLAY_CHUNKS.iter().find(|(k, _)| **k == kind) {
            let said = format!("{}, which tessera does not write: {how}", a_chunk(&kind));
            if !display_changes.contains(&said) {
                display_changes.push(said);
            }
        }
        // After the words every tRNS chunk has, what its length says.
        if &kind == b"tRNS" {
            display_changes.extend(color.and_then(|c| misfit_transparency(length, c, entries)));
        }
        // EXIF in a chunk named `eXIf` but for its case (`exIf`, the case of the chunk's
        // first proposal, `EXIF`), or in a `zxIf` chunk of compressed EXIF: libpng, the
        // decoder here and browsers skip it, but exiftool reads it as eXIf (its `%stdCase`)
        // and shows its orientation, by which a viewer that takes it turns or flips the
        // picture.
        let lower = kind.to_ascii_lowercase();
        if (&lower == b"exif" && &kind != b"eXIf") || &lower == b"zxif" {
            let said = format!(
                "{}, which tessera does not write: EXIF data that exiftool reads as eXIf's, \
                 which can turn or flip the picture",
                a_chunk(&kind)
            );
            if !display_changes.contains(&said) {
                display_changes.push(said);
            }
        }
        // A critical chunk after the pixels: libpng refuses an unknown one there (and takes
        // no palette there), so a viewer built on it shows nothing or another picture, where
        // the decoder here stops at the last row.
        if idat_seen && kind[0].is_ascii_uppercase() && !matches!(&kind, b"IDAT" | b"IEND") {
            display_changes.push(format!(
                "{} after the pixels, a critical chunk where libpng refuses one",
                a_chunk(&kind)
            ));
        }
        // An IDAT chunk after another that follows the pixels' chunks: the decoder here
        // reads the pixels from the first run and stops, but libpng reads this one at the
        // file's end ("Too many IDATs found") and refuses the file where its CRC is wrong
        // (a critical chunk's); it is not read here, as a chunk so placed is not tessera's.
        if &kind == b"IDAT" && idat_ended {
            let said = format!(
                "an IDAT chunk at byte {at} after another chunk that follows the pixels: \
                 libpng reads it at the end (\"Too many IDATs found\") and refuses the file \
                 where its CRC is wrong"
            );
            display_changes.push(said);
        }
        idat_ended |= idat_seen && &kind != b"IDAT";
        match &kind {
            b"IHDR" => {
                let mut data = [0u8; 13];
                r.read_exact(&mut data).map_err(|e| e.to_string())?;
                skip(&mut r, 4)?;
                let w = u32::from_be_bytes(data[..4].try_into().expect("4 bytes"));
                let h = u32::from_be_bytes(data[4..8].try_into().expect("4 bytes"));
                size = Some((w, h));
                color = Some(data[9]);
            }
            b"iTXt" => {
                // Its keyword first: only tessera's recipe chunk is read further. Another is
                // skipped unread, as every other chunk is: 65,536 text chunks of 1 MiB, a
                // sparse file of 64 GiB on 256 MiB of disk, were once read whole, minutes.
                let (keyword, n) = read_keyword(&mut r, length)?;
                if keyword != Keyword::Recipe {
                    keyword.refuse_a_lookalike(&kind)?;
                    skip(&mut r, length as i64 - n as i64 + 4)?;
                } else if length > MAX_BYTES as u64 + 1024 {
                    // Too long to be a recipe; a recipe so long is refused, not skipped.
                    return Err(format!(
                        "has a recipe chunk of {length} bytes, more than a recipe may have"
                    ));
                } else {
                    let mut data = format!("{KEY}\0").into_bytes();
                    data.resize(length as usize, 0);
                    r.read_exact(&mut data[n..]).map_err(|e| e.to_string())?;
                    let mut crc = [0u8; 4];
                    r.read_exact(&mut crc).map_err(|e| e.to_string())?;
                    let mut hasher = crc32fast::Hasher::new();
                    hasher.update(&kind);
                    hasher.update(&data);
                    if hasher.finalize() != u32::from_be_bytes(crc) {
                        return Err(format!("has a damaged iTXt chunk at byte {at} (bad CRC)"));
                    }
                    if let Some(text) = recipe_of_itxt(&data, at)? {
                        if found.is_some() {
                            return Err("has two recipes".to_owned());
                        }
                        found = Some(text);
                    }
                }
            }
            b"tEXt" | b"zTXt" => {
                // A recipe where tessera writes none: a reader of PNG text could show it for
                // the image in place of the one checked (Python's PIL keeps a keyword's last).
                let (keyword, n) = read_keyword(&mut r, length)?;
                keyword.refuse_a_lookalike(&kind)?;
                if keyword == Keyword::Recipe {
                    return Err(format!(
                        "has a recipe in {}, where tessera writes none: readers of PNG text \
                         may show it in place of the one checked",
                        a_chunk(&kind)
                    ));
                }
                skip(&mut r, length as i64 - n as i64 + 4)?;
            }
            // Only the first: a stream whose header is split over chunks has none taken,
            // rather than two bytes of its middle taken for it.
            b"IDAT" if !idat_seen && length >= 2 => {
                idat_seen = true;
                let mut two = [0u8; 2];
                r.read_exact(&mut two).map_err(|e| e.to_string())?;
                zlib_header = Some(two);
                skip(&mut r, length as i64 - 2 + 4)?;
            }
            b"IDAT" => {
                idat_seen = true;
                skip(&mut r, length as i64 + 4)?;
            }
            b"IEND" => {
                // Its CRC: the decoder here stops at the last row and never reads it, where
                // libpng checks it at the end (png_read_end, as a critical chunk's, so
                // "IEND: CRC error" fails the file; browsers differ). What follows the end is
                // walked as exiftool walks it (past IEND's head and CRC, whatever length it
                // claims).
                let mut crc = [0u8; 4];
                r.read_exact(&mut crc).map_err(|e| e.to_string())?;
                display_changes.extend(damaged_end(length, crc, at));
                check_after_end(&mut r, at + 12, len, chunks + 1)?;
                break;
            }
            _ => skip(&mut r, length as i64 + 4)?,
        }
        at += 12 + length;
    }
    let (width, height) = size.ok_or("has no IHDR chunk")?;
    Ok(PngHeader {
        width,
        height,
        recipe: found,
        display_changes,
        zlib_header,
    })
}

/// What is said of a tRNS chunk of `length` bytes in an image of the colour type `color`
/// (IHDR's) whose palette before it has `entries` entries, if its length is not one libpng
/// reads: two bytes of a greyscale image, six of an RGB one, one to `entries` of a palette
/// image, none of an image of an alpha channel. libpng ignores any other (a benign error,
/// "invalid"), where the PNG decoder here takes the first bytes of one longer than its
/// colour type's (and a palette's alpha for its entries): viewers built on the one show the
/// picture opaque, those built on the other show it transparent where the colour is.
fn misfit_transparency(length: u64, color: u8, entries: Option<u64>) -> Option<String> {
    let (kind, holds) = match color {
        0 => ("a greyscale", 2),
        2 => ("an RGB", 6),
        3 => {
            let entries = entries?;
            return (length > entries).then(|| {
                format!(
                    "a tRNS chunk of {length} {}, more than the {entries} of its palette: \
                     libpng ignores it (viewers built on it show the picture opaque), the \
                     decoder here takes the alpha of the entries it has",
                    if length == 1 { "entry" } else { "entries" }
                )
            });
        }
        4 | 6 => {
            return Some(
                "a tRNS chunk in an image of an alpha channel, which libpng and the decoder \
                 here ignore"
                    .to_owned(),
            );
        }
        _ => return None,
    };
    let taken = if length > holds {
        format!(
            "libpng ignores it (viewers built on it show the picture opaque), the decoder \
             here takes its first {holds} bytes for the transparent colour"
        )
    } else if length < holds {
        "libpng and the decoder here ignore it".to_owned()
    } else {
        return None;
    };
    let bytes = if length == 1 { "byte" } else { "bytes" };
    Some(format!(
        "a tRNS chunk of {length} {bytes}, where {kind} image's holds {holds}: {taken}"
    ))
}

/// What an IEND chunk at byte `at` of `length` bytes, whose head is followed by `crc`, says
/// that a PNG's end does not: a wrong CRC, which libpng refuses as a critical chunk's, so
/// that viewers built on it show nothing (the decoder here and `compare` never read it), or
/// data, which a PNG's IEND has none of and libpng calls invalid (its CRC is then over data
/// not read here).
fn damaged_end(length: u64, crc: [u8; 4], at: u64) -> Option<String> {
    if length != 0 {
        Some(format!(
            "an IEND chunk at byte {at} of {}, where a PNG's holds none: libpng calls it \
             invalid and refuses the file where its CRC over them is wrong",
            crate::text::count(length, "byte")
        ))
    } else if u32::from_be_bytes(crc) != crc32fast::hash(b"IEND") {
        Some(format!(
            "an IEND chunk at byte {at} whose CRC is wrong: libpng refuses the file at its end \
             (\"IEND: CRC error\"), and viewers built on it may show nothing"
        ))
    } else {
        None
    }
}

/// Walks the bytes after a PNG's IEND chunk (from byte `at` of `len`) for a recipe: a PNG
/// ends at IEND, and no decoder and not tessera reads past it, but exiftool goes on reading
/// chunks there, to the first that does not fit in the file, and shows their text (a
/// keyword's later chunk in place of the one before IEND). A text chunk there whose keyword
/// is the recipe's, or one exiftool takes for it, is refused; other bytes are let be (a
/// program may append its own). `chunks` were walked before, of `MAX_PNG_CHUNKS` in all.
fn check_after_end<R: Read + Seek>(
    r: &mut std::io::BufReader<R>,
    mut at: u64,
    len: u64,
    mut chunks: u64,
) -> Result<(), String> {
    while at + 12 <= len {
        if chunks == MAX_PNG_CHUNKS {
            return Err(format!(
                "has more than {MAX_PNG_CHUNKS} chunks, counting those after its IEND chunk \
                 (where a reader of PNG text, exiftool, reads on for text chunks)"
            ));
        }
        let mut head = [0u8; 8];
        r.read_exact(&mut head).map_err(|e| e.to_string())?;
        let length = u64::from(u32::from_be_bytes(head[..4].try_into().expect("4 bytes")));
        let kind: [u8; 4] = head[4..].try_into().expect("4 bytes");
        if length > (1 << 31) - 1 || at + 12 + length > len {
            return Ok(());
        }
        let n = if matches!(&kind, b"tEXt" | b"zTXt" | b"iTXt") {
            let (keyword, n) = read_keyword(r, length)?;
            if keyword != Keyword::Other {
                return Err(format!(
                    "has a text chunk ({}) of the keyword `{}` after its IEND chunk, at byte {at}: a \
                     PNG ends at IEND and tessera reads no recipe past it, but a reader of PNG \
                     text (exiftool) reads on and may show it in place of the one checked",
                    String::from_utf8_lossy(&kind),
                    keyword.shown()
                ));
            }
            n as i64
        } else {
            0
        };
        r.seek_relative(length as i64 - n + 4)
            .map_err(|e| e.to_string())?;
        at += 12 + length;
        chunks += 1;
    }
    Ok(())
}

/// Output kept of the pixels' stream while it is inflated: a deflate stream reaches at most
/// 32 KiB back.
const WINDOW: usize = 32 << 10;

/// Inflates the zlib stream of the pixels of the PNG `r` is at the start of (its IDAT
/// chunks, already walked by `read`) to its end, checksum included, keeping only a window of
/// what it gives: the PNG decoder stops once it has every row, so a stream cut after them
/// (without its end or its Adler-32 checksum) decodes there, where libpng refuses it ("Not
/// enough image data": Firefox, GIMP, pngfix). Says why a stream does not end as a stream
/// must, gives more than `most` bytes (more than the image's rows take: the time it
/// takes is bounded by the image's size, not by what a small stream can inflate to), or
/// ends before the rows its IHDR chunk claims (`row_bytes`): the decoder is handed room
/// for every row before it finds them missing, and a file of 65 bytes claiming 4096x4096
/// 16-bit RGBA pixels once had 137 MB filled for them.
pub fn check_zlib_stream_ends<R: Read>(r: R, most: u64) -> Result<u64, String> {
    let mut r = std::io::BufReader::new(r);
    let io = |e: std::io::Error| format!("could not be read: {e}");
    let mut signature = [0u8; 8];
    r.read_exact(&mut signature).map_err(io)?;
    let mut inflater = fdeflate::Decompressor::new();
    let mut output = vec![0u8; 4 * WINDOW];
    let (mut filled, mut idat_seen, mut made_in_all) = (0, false, 0u64);
    // The bytes the rows take, once the IHDR chunk is read (none where it says what no
    // decoder reads: the decoder is then the judge). Rows of more than `most` bytes are an
    // image larger than the caller reads, which it refuses by its size, as such.
    let mut least = 0u128;
    let mut input = vec![0u8; 64 << 10];
    for _ in 0..MAX_PNG_CHUNKS {
        let mut head = [0u8; 8];
        if r.read_exact(&mut head).is_err() {
            break;
        }
        let length = u64::from(u32::from_be_bytes(head[..4].try_into().expect("4 bytes")));
        if &head[4..] == b"IHDR" && length == 13 {
            let mut ihdr = [0u8; 13 + 4];
            r.read_exact(&mut ihdr).map_err(io)?;
            least = row_bytes(&ihdr[..13]);
            continue;
        }
        if &head[4..] != b"IDAT" {
            if idat_seen {
                break;
            }
            std::io::copy(&mut (&mut r).take(length + 4), &mut std::io::sink()).map_err(io)?;
            continue;
        }
        idat_seen = true;
        let mut left = length;
        while left > 0 {
            let n = left.min(input.len() as u64) as usize;
            r.read_exact(&mut input[..n]).map_err(io)?;
            left -= n as u64;
            let mut data = &input[..n];
            while !data.is_empty() && !inflater.is_done() {
                if filled == output.len() {
                    output.copy_within(filled - WINDOW.., 0);
                    filled = WINDOW;
                }
                let (read, made) = inflater
                    .read(data, &mut output, filled, false)
                    .map_err(inflate_failure)?;
                data = &data[read..];
                filled += made;
                made_in_all += made as u64;
                if made_in_all > most {
                    return Err(format!(
                        "a zlib stream that inflates to more than {most} bytes, more than its \
                         image's rows take"
                    ));
                }
            }
        }
        let mut crc = [0u8; 4];
        r.read_exact(&mut crc).map_err(io)?;
    }
    if !idat_seen {
        Err("no IDAT chunk, where a PNG keeps them".to_owned())
    } else if inflater.is_done() && u128::from(made_in_all) < least && least <= u128::from(most) {
        Err(format!(
            "a zlib stream that inflates to {}, fewer than the {least} its image's rows \
             take, which libpng refuses (\"Not enough image data\")",
            crate::text::count(made_in_all, "byte")
        ))
    } else if inflater.is_done() {
        Ok(made_in_all)
    } else {
        Err(
            "a zlib stream that ends without its end and checksum, which libpng refuses \
             (\"Not enough image data\")"
                .to_owned(),
        )
    }
}

/// What is said of a PNG whose pixels' zlib stream begins with `header` (its first IDAT
/// chunk's first two bytes) and inflates to `inflated` bytes, where it declares a window
/// smaller than what it inflates to: libpng inflates with the window a stream declares, so
/// a stream reaching further back than it is a broken picture there (Firefox, GIMP), where
/// the decoder here, which takes no notice of the window, reads it whole. A stream declaring
/// its window no wider than what it inflates to (as encoders that fit the window to the
/// data write it) is none.
pub fn narrow_window(header: Option<[u8; 2]>, inflated: u64) -> Option<String> {
    let [method, _] = header?;
    if method & 0x0f != 8 || method >> 4 >= 7 {
        return None;
    }
    let window = 1u64 << ((method >> 4) + 8);
    (inflated > window).then(|| {
        format!(
            "a zlib stream declaring a window of {window} bytes that inflates to {inflated}: \
             libpng inflates with the window declared and refuses the file where the stream \
             reaches further back (viewers built on it show a broken picture)"
        )
    })
}

/// The bytes the rows of the image an IHDR chunk's data `ihdr` describes take inflated: each
/// row of each Adam7 pass (of an interlaced image) or of the image, its filter byte and its
/// pixels' bits in whole bytes; 0 for a bit depth or colour type PNG does not have.
fn row_bytes(ihdr: &[u8]) -> u128 {
    let side = |at: usize| u128::from(u32::from_be_bytes([0, 1, 2, 3].map(|i| ihdr[at + i])));
    let (width, height, depth) = (side(0), side(4), u128::from(ihdr[8]));
    let samples = match (ihdr[9], ihdr[8]) {
        (0, 1 | 2 | 4 | 8 | 16) => 1,
        (3, 1 | 2 | 4 | 8) => 1,
        (2 | 6, 8 | 16) => 3 + u128::from(ihdr[9] == 6),
        (4, 8 | 16) => 2,
        _ => return 0,
    };
    let rows = |(x0, y0, dx, dy): (usize, usize, usize, usize)| {
        let pixels = width.saturating_sub(x0 as u128).div_ceil(dx as u128);
        let lines = height.saturating_sub(y0 as u128).div_ceil(dy as u128);
        if pixels == 0 {
            return 0;
        }
        lines * (1 + (pixels * samples * depth).div_ceil(8))
    };
    if ihdr[12] == 1 {
        ADAM7_PASSES.into_iter().map(rows).sum()
    } else {
        rows((0, 0, 1, 1))
    }
}

/// What a failure to inflate the pixels' stream says of it.
fn inflate_failure(e: fdeflate::DecompressionError) -> String {
    match e {
        fdeflate::DecompressionError::WrongChecksum => {
            "a zlib stream whose Adler-32 checksum is wrong, which libpng refuses".to_owned()
        }
        e => format!("a zlib stream that does not inflate ({e:?})"),
    }
}

/// The most bytes of a text chunk's keyword read: PNG allows 79. A longer one, made so far
/// only of tessera's keyword and characters exiftool drops from a name, is taken for a
/// lookalike of the recipe's (what follows is not read).
const MAX_KEYWORD_READ: u64 = 1024;

/// What a text chunk's keyword is to tessera.
#[derive(Debug, PartialEq)]
enum Keyword {
    /// `tessera-recipe`, byte for byte.
    Recipe,
    /// Another keyword that exiftool names as it names the recipe's, `Tessera-recipe`: it
    /// capitalises the character after a run of white space and drops the run, drops every
    /// character but ASCII letters, digits, `-` and `_` (punctuation, controls, Latin-1),
    /// and capitalises the first letter (`s/\s+(.)/\u$1/g`, `tr/-_a-zA-Z0-9//dc`,
    /// `ucfirst` in Image::ExifTool), and of two chunks of one name shows the later. The
    /// case of the other letters is kept: `TESSERA-RECIPE` is a name of its own. The
    /// keyword's first bytes, for the message.
    Lookalike(Vec<u8>),
    /// Any other, or none (a chunk without the zero byte that ends its keyword, which
    /// readers of PNG text skip).
    Other,
}

impl Keyword {
    /// Refuses a lookalike of the recipe's keyword in a `kind` chunk: exiftool would show
    /// its text, which tessera does not check, as the image's recipe.
    fn refuse_a_lookalike(&self, kind: &[u8; 4]) -> Result<(), String> {
        if !matches!(self, Keyword::Lookalike(_)) {
            return Ok(());
        }
        Err(format!(
            "has a text chunk ({}) of the keyword `{}`, which a reader of PNG text (exiftool) \
             takes for tessera's `{KEY}`: its text may be shown in place of the one checked",
            String::from_utf8_lossy(kind),
            self.shown()
        ))
    }

    /// The keyword as a message quotes it: its first 80 characters, escaped.
    fn shown(&self) -> String {
        match self {
            Keyword::Recipe => KEY.to_owned(),
            Keyword::Lookalike(start) => String::from_utf8_lossy(start)
                .escape_debug()
                .take(80)
                .collect(),
            Keyword::Other => String::new(),
        }
    }
}

/// The keyword of a text chunk of `length` bytes, read as far as the zero byte that ends it
/// (at most `MAX_KEYWORD_READ` bytes), and how many bytes were read. It is told apart from
/// tessera's at its first letter, digit, `-` or `_` that, as exiftool names it, is not the
/// next of tessera's name: the first compared without its case, the others with it (one
/// after white space capitalised).
fn read_keyword<R: Read>(r: &mut R, length: u64) -> Result<(Keyword, usize), String> {
    let key = KEY.as_bytes();
    let mut start = Vec::new();
    let (mut matched, mut exact, mut after_space) = (0, true, false);
    let mut byte = [0u8; 1];
    while (start.len() as u64) < length.min(MAX_KEYWORD_READ) {
        r.read_exact(&mut byte).map_err(|e| e.to_string())?;
        let b = byte[0];
        if b == 0 {
            let n = start.len() + 1;
            return Ok(
                match (exact && start.len() == key.len(), matched == key.len()) {
                    (true, _) => (Keyword::Recipe, n),
                    (false, true) => (Keyword::Lookalike(start), n),
                    (false, false) => (Keyword::Other, n),
                },
            );
        }
        exact &= key.get(start.len()) == Some(&b);
        start.push(b);
        // Perl's `\s` on bytes: ASCII white space only.
        let named = if after_space {
            b.to_ascii_uppercase()
        } else {
            b
        };
        after_space = matches!(b, b' ' | b'\t' | b'\n' | 0x0b | 0x0c | b'\r');
        if named.is_ascii_alphanumeric() || named == b'-' || named == b'_' {
            let same = |k: &u8| match matched {
                0 => k.eq_ignore_ascii_case(&named),
                _ => *k == named,
            };
            if key.get(matched).is_none_or(|k| !same(k)) {
                return Ok((Keyword::Other, start.len()));
            }
            matched += 1;
        }
    }
    let n = start.len();
    // The chunk's end without a zero byte: no keyword. The most read: what follows could
    // still make tessera's name.
    Ok(if n as u64 == length {
        (Keyword::Other, n)
    } else {
        (Keyword::Lookalike(start), n)
    })
}

/// The recipe in an iTXt chunk's `data` (the chunk at byte `at`), when the chunk is
/// tessera's. One that does not read is refused by the field that is wrong: its compression
/// flag or method, the zero bytes that end its language tag and translated keyword, its
/// text (inflated, then UTF-8).
fn recipe_of_itxt(data: &[u8], at: u64) -> Result<Option<String>, String> {
    let mut fields = data.splitn(2, |&b| b == 0);
    if fields.next() != Some(KEY.as_bytes()) {
        return Ok(None);
    }
    let rest = fields.next().unwrap_or_default();
    let bad = |what: String| format!("has a recipe chunk (iTXt '{KEY}' at byte {at}) of {what}");
    let (&compressed, rest) = rest
        .split_first()
        .ok_or_else(|| bad("no compression flag".to_owned()))?;
    let (&method, rest) = rest
        .split_first()
        .ok_or_else(|| bad("no compression method".to_owned()))?;
    // Language tag and translated keyword, each ended by a zero byte.
    let mut parts = rest.splitn(3, |&b| b == 0);
    let (_, _, text) = (
        parts.next(),
        parts
            .next()
            .ok_or_else(|| bad("no zero byte after its language tag".to_owned()))?,
        parts
            .next()
            .ok_or_else(|| bad("no zero byte after its translated keyword".to_owned()))?,
    );
    let bytes = match (compressed, method) {
        (0, _) if text.len() <= MAX_BYTES => text.to_vec(),
        (0, _) => {
            return Err(bad(format!(
                "a recipe of {} bytes, more than {}",
                text.len(),
                MAX_BYTES
            )));
        }
        (1, 0) => fdeflate::decompress_to_vec_bounded(text, MAX_BYTES).map_err(|e| match e {
            fdeflate::BoundedDecompressionError::OutputTooLarge { .. } => bad(format!(
                "compressed text that inflates beyond the {MAX_BYTES} bytes a recipe may have"
            )),
            _ => bad("compressed text that does not inflate (a damaged zlib stream)".to_owned()),
        })?,
        (1, method) => return Err(bad(format!("compression method {method}: 0 (zlib)"))),
        (flag, _) => {
            return Err(bad(format!(
                "compression flag {flag}: 0 (none) or 1 (zlib)"
            )));
        }
    };
    String::from_utf8(bytes).map(Some).map_err(|e| {
        bad(format!(
            "text that is not UTF-8 (a bad byte at {} of its text)",
            e.utf8_error().valid_up_to()
        ))
    })
}

/// Says where a palette PNG that `r` is at the start of has a pixel whose index lies past
/// its palette's entries, if one does: libpng and the decoder here show such a pixel
/// black, Chrome (Skia) the palette's last colour, so that viewers show different
/// pictures. A file that does not decode, or of another colour type, is none (the decoder
/// is the judge). At most `most` bytes of rows are held.
pub fn palette_index_past_its_entries<R: Read + Seek>(r: R, most: u64) -> Option<String> {
    let mut decoder = png::Decoder::new_with_limits(
        std::io::BufReader::new(r),
        png::Limits {
            bytes: usize::try_from(most).unwrap_or(usize::MAX),
        },
    );
    decoder.set_transformations(png::Transformations::IDENTITY);
    decoder.set_ignore_text_chunk(true);
    let mut reader = decoder.read_info().ok()?;
    let info = reader.info();
    if info.color_type != png::ColorType::Indexed {
        return None;
    }
    let entries = info.palette.as_ref().map_or(0, |p| p.len() / 3);
    let (width, height) = (info.width as usize, info.height as usize);
    let depth = info.bit_depth as usize;
    // An interlaced image's rows come pass by pass (Adam7), each of its pass's pixels only,
    // which lie `dx` apart from `x0` in the picture: a row of the first pass of an image 16
    // wide holds 2, where indexing it as 16 once panicked.
    let passes: &[(usize, usize, usize, usize)] = if info.interlaced {
        &ADAM7_PASSES
    } else {
        &[(0, 0, 1, 1)]
    };
    let mut places = passes.iter().flat_map(|&(x0, y0, dx, dy)| {
        let pixels = width.saturating_sub(x0).div_ceil(dx);
        (y0..height)
            .step_by(dy)
            .filter(move |_| pixels > 0)
            .map(move |y| (x0, dx, y, pixels))
    });
    while let Ok(Some(row)) = reader.next_row() {
        let (x0, dx, y, pixels) = places.next()?;
        let bits = row.data();
        let index = |i: usize| {
            let (byte, shift) = (i * depth / 8, 8 - depth - (i * depth % 8));
            bits.get(byte)
                .map_or(0, |b| usize::from(b >> shift) & ((1 << depth) - 1))
        };
        if let Some(i) = (0..pixels).find(|&i| index(i) >= entries) {
            return Some(format!(
                "a pixel ({}, {y}) of palette index {}, past the entries of its palette \
                 ({entries}): libpng shows it black, Chrome the palette's last colour",
                x0 + i * dx,
                index(i)
            ));
        }
    }
    None
}

/// The Adam7 passes of an interlaced PNG, each as the column and row of its first pixel and
/// the steps between its pixels across and down.
const ADAM7_PASSES: [(usize, usize, usize, usize); 7] = [
    (0, 0, 8, 8),
    (4, 0, 8, 8),
    (0, 4, 4, 8),
    (2, 0, 4, 4),
    (0, 2, 2, 4),
    (1, 0, 2, 2),
    (0, 1, 1, 2),
];

#[cfg(test)]
mod tests;
