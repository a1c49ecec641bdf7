//! A PNG file's header read as a stranger's: its chunks walked within bounds (at most
//! `MAX_PNG_CHUNKS`, every length inside the file, one IHDR first, an IEND last) for its size,
//! tessera's recipe (an iTXt chunk, inflated no further than a recipe may be) and the chunks
//! that change how a viewer shows it, the others skipped unread. Below the scene, whose
//! image textures are walked so before a decoder keeps their chunks, and the image files.

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
                "has a {} chunk at byte {at} claiming {length} bytes, past the file's end",
                String::from_utf8_lossy(&kind).escape_debug()
            ));
        }
        // One IHDR chunk, first, of 13 bytes, as a PNG has: a second one would be another
        // image's size, which a decoder ignores but a header reader might report.
        let is_ihdr = &kind == b"IHDR";
        if chunks == 0 && !is_ihdr {
            return Err(format!(
                "does not begin with its IHDR chunk (a {} chunk at byte 8), as a PNG must",
                String::from_utf8_lossy(&kind).escape_debug()
            ));
        }
        if is_ihdr && chunks > 0 {
            return Err(format!("has a second IHDR chunk at byte {at}"));
        }
        if is_ihdr && length != 13 {
            return Err(format!(
                "has an IHDR chunk of {length} bytes, not the 13 of a PNG"
            ));
        }
        if let Some((_, how)) = DISPLAY_CHUNKS.iter().find(|(k, _)| **k == kind) {
            let said = format!(
                "a {} chunk, which tessera does not write: {how}",
                String::from_utf8_lossy(&kind)
            );
            if !display_changes.contains(&said) {
                display_changes.push(said);
            }
        }
        match &kind {
            b"IHDR" => {
                let mut data = [0u8; 13];
                r.read_exact(&mut data).map_err(|e| e.to_string())?;
                skip(&mut r, 4)?;
                let w = u32::from_be_bytes(data[..4].try_into().expect("4 bytes"));
                let h = u32::from_be_bytes(data[4..8].try_into().expect("4 bytes"));
                size = Some((w, h));
            }
            b"iTXt" if length <= MAX_BYTES as u64 + 1024 => {
                let mut data = vec![0u8; length as usize];
                r.read_exact(&mut data).map_err(|e| e.to_string())?;
                let mut crc = [0u8; 4];
                r.read_exact(&mut crc).map_err(|e| e.to_string())?;
                let mut hasher = crc32fast::Hasher::new();
                hasher.update(&kind);
                hasher.update(&data);
                if hasher.finalize() != u32::from_be_bytes(crc) {
                    return Err(format!("has a damaged iTXt chunk at byte {at} (bad CRC)"));
                }
                if let Some(text) = recipe_of_itxt(&data)? {
                    if found.is_some() {
                        return Err("has two recipes".to_owned());
                    }
                    found = Some(text);
                }
            }
            b"iTXt" => {
                // Too long to be a recipe; a recipe so long is refused, not skipped.
                let mut start = [0u8; 15];
                let n = (length as usize).min(start.len());
                r.read_exact(&mut start[..n]).map_err(|e| e.to_string())?;
                if start[..n].starts_with(KEY.as_bytes()) {
                    return Err(format!(
                        "has a recipe chunk of {length} bytes, more than a recipe may have"
                    ));
                }
                skip(&mut r, length as i64 - n as i64 + 4)?;
            }
            b"IEND" => break,
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
    })
}

/// The recipe in an iTXt chunk's `data`, when the chunk is tessera's.
fn recipe_of_itxt(data: &[u8]) -> Result<Option<String>, String> {
    let mut fields = data.splitn(2, |&b| b == 0);
    if fields.next() != Some(KEY.as_bytes()) {
        return Ok(None);
    }
    let rest = fields.next().unwrap_or_default();
    let bad = || "has a malformed recipe chunk".to_owned();
    let (&compressed, rest) = rest.split_first().ok_or_else(bad)?;
    let (&method, rest) = rest.split_first().ok_or_else(bad)?;
    // Language tag and translated keyword, each ended by a zero byte.
    let mut parts = rest.splitn(3, |&b| b == 0);
    let (_, _, text) = (
        parts.next(),
        parts.next().ok_or_else(bad)?,
        parts.next().ok_or_else(bad)?,
    );
    let bytes = match (compressed, method) {
        (0, _) if text.len() <= MAX_BYTES => text.to_vec(),
        (0, _) => {
            return Err(format!(
                "has a recipe of {} bytes, more than {}",
                text.len(),
                MAX_BYTES
            ));
        }
        (1, 0) => fdeflate::decompress_to_vec_bounded(text, MAX_BYTES).map_err(|e| match e {
            fdeflate::BoundedDecompressionError::OutputTooLarge { .. } => format!(
                "has a compressed recipe that inflates beyond the {} bytes a recipe may have",
                MAX_BYTES
            ),
            _ => "has a compressed recipe that does not inflate".to_owned(),
        })?,
        _ => return Err(bad()),
    };
    String::from_utf8(bytes)
        .map(Some)
        .map_err(|_| "has a recipe that is not UTF-8 text".to_owned())
}
