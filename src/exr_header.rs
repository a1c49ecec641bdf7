//! The header of an OpenEXR file a stranger may have made, read by a small parser of its own
//! before any EXR library sees the file: one part only, no deep data, red, green and blue
//! channels only, a bounded number of attributes of bounded size, every size checked against
//! the file's length before it is read. It gives the image's size, the recipe's text and the
//! attributes that change how a viewer shows the picture, or that OpenEXR requires and it
//! lacks; and where its chunks lie, for a check that its offset table points each entry to
//! its own chunk, as OpenEXR requires.

use crate::metadata as recipe;
use std::io::Read;

/// The most attributes a header may have: tessera writes about ten.
pub const MAX_ATTRIBUTES: usize = 256;
/// The most bytes of one attribute's value: the recipe, at most `recipe::MAX_BYTES`, is
/// the largest tessera writes.
const MAX_VALUE: u64 = recipe::MAX_BYTES as u64 + 4096;
/// The most bytes of the whole header.
const MAX_HEADER: u64 = 4 * MAX_VALUE;
/// The longest attribute or channel name (EXR's long names).
const MAX_NAME: usize = 255;
/// The most channels of a channel list.
const MAX_CHANNELS: usize = 64;

const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
const TILED: u32 = 0x200;
const LONG_NAMES: u32 = 0x400;
const DEEP: u32 = 0x800;
const MULTIPART: u32 = 0x1000;

/// A channel's sample type, as EXR numbers them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleType {
    Uint,
    Half,
    Float,
}

/// What the header of an EXR file says, checked.
#[derive(Clone, Debug)]
pub struct ExrHeader {
    pub width: u32,
    pub height: u32,
    /// The sample type of the red, green and blue channels (all the same), or `None` when
    /// they differ.
    pub samples: Option<SampleType>,
    /// The recipe attribute's text, not yet checked.
    pub recipe: Option<String>,
    /// What the header holds that tessera does not write and that changes how a viewer
    /// shows the picture, each said in words.
    pub display_changes: Vec<String>,
    /// Where its chunks lie.
    pub layout: ExrLayout,
}

/// Attributes that change what a viewer shows, and how.
const DISPLAY_ATTRIBUTES: [(&str, &str); 8] = [
    ("chromaticities", "other primaries and white point"),
    ("whiteLuminance", "another white luminance"),
    ("adoptedNeutral", "another neutral colour"),
    ("renderingTransform", "a rendering transform"),
    ("lookModTransform", "a look transform"),
    ("envmap", "shown as an environment map"),
    ("multiView", "shown as several views"),
    // A small 8-bit image of its own, which file browsers show without decoding the pixels:
    // it can show anything.
    (
        "preview",
        "a preview image, which file browsers show as its thumbnail",
    ),
];

/// What is said of a display window other than the data window.
const DISPLAY_WINDOW: &str =
    "a displayWindow other than its dataWindow: viewers show another frame";

/// Attributes OpenEXR requires of every header, with their types, that the `exr` crate reads
/// a file without (taking defaults of its own): the OpenEXR library refuses such a file, so
/// every viewer built on it shows nothing where tessera decodes a picture.
const REQUIRED: [(&str, &str); 4] = [
    ("lineOrder", "lineOrder"),
    ("pixelAspectRatio", "float"),
    ("screenWindowCenter", "v2f"),
    ("screenWindowWidth", "float"),
];

/// The size in bytes of a value of each attribute type OpenEXR gives a fixed size (and
/// `floatvector`'s, a whole number of floats).
const SIZES: [(&str, usize); 24] = [
    ("box2i", 16),
    ("box2f", 16),
    ("chromaticities", 32),
    ("compression", 1),
    ("deepImageState", 1),
    ("double", 8),
    ("envmap", 1),
    ("float", 4),
    ("int", 4),
    ("keycode", 28),
    ("lineOrder", 1),
    ("m33f", 36),
    ("m33d", 72),
    ("m44f", 64),
    ("m44d", 128),
    ("rational", 8),
    ("tiledesc", 9),
    ("timecode", 8),
    ("v2i", 8),
    ("v2f", 8),
    ("v2d", 16),
    ("v3i", 12),
    ("v3f", 12),
    ("v3d", 24),
];

/// What is said of the attribute `name` of type `kind` whose value is `len` bytes long when
/// that is not the size of its type: OpenEXR refuses a header of such an attribute, whatever
/// its name, where the `exr` crate reads what it needs of it (the first byte of a
/// `compression` of two, the first float of a `pixelAspectRatio` of eight) or keeps it.
fn misfit(name: &str, kind: &str, len: usize) -> Option<String> {
    let fits = match SIZES.iter().find(|(k, _)| *k == kind) {
        Some(&(_, size)) => len == size,
        None => kind != "floatvector" || len.is_multiple_of(4),
    };
    (!fits).then(|| {
        format!(
            "an attribute `{}` of type {} of {}, not the size of its type, which OpenEXR \
             refuses: viewers built on it refuse the file",
            name.escape_debug(),
            kind.escape_debug(),
            crate::text::count(len as u64, "byte")
        )
    })
}

/// What is said of each attribute of `REQUIRED` missing from `attributes` (the names and
/// types of a header's attributes), as a change in how a viewer shows the picture.
fn lacking(attributes: &[(String, String)]) -> impl Iterator<Item = String> + '_ {
    REQUIRED
        .iter()
        .filter(|(name, kind)| !attributes.iter().any(|(n, k)| n == name && k == kind))
        .map(|(name, kind)| {
            format!(
                "no attribute {name} of type {kind}, which OpenEXR requires: viewers built on \
                 it refuse the file"
            )
        })
}

/// Reads a bounded amount, saying what was being read when the file ends early.
struct Bounded<R> {
    inner: R,
    /// Bytes left in the file.
    left: u64,
    /// Bytes of header read so far.
    read: u64,
}

impl<R: Read> Bounded<R> {
    fn bytes(&mut self, n: u64, what: &str) -> Result<Vec<u8>, String> {
        if n > self.left {
            return Err(format!(
                "is truncated: its {what} needs {}, and the file has {} left",
                crate::text::count(n, "byte"),
                crate::text::count(self.left, "byte")
            ));
        }
        self.read += n;
        if self.read > MAX_HEADER {
            return Err(format!(
                "has a header of more than {MAX_HEADER} bytes, more than tessera writes"
            ));
        }
        let mut buf = vec![0u8; n as usize];
        self.inner
            .read_exact(&mut buf)
            .map_err(|e| format!("could not be read: {e}"))?;
        self.left -= n;
        Ok(buf)
    }

    fn u32(&mut self, what: &str) -> Result<u32, String> {
        let b = self.bytes(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A zero-ended name of at most `MAX_NAME` bytes (empty: the end of a list).
    fn name(&mut self, what: &str) -> Result<String, String> {
        let mut name = Vec::new();
        loop {
            let b = self.bytes(1, what)?[0];
            if b == 0 {
                break;
            }
            if name.len() == MAX_NAME {
                return Err(format!("has a {what} longer than {MAX_NAME} bytes"));
            }
            name.push(b);
        }
        String::from_utf8(name).map_err(|_| format!("has a {what} that is not UTF-8"))
    }
}

fn i32_at(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// A `box2i` value: min x, min y, max x, max y.
fn box2i(value: &[u8], name: &str) -> Result<[i32; 4], String> {
    if value.len() != 16 {
        return Err(format!(
            "has a {name} of {}, not 16",
            crate::text::count(value.len() as u64, "byte")
        ));
    }
    Ok([0, 4, 8, 12].map(|at| i32_at(value, at)))
}

/// The channels of a `chlist` value: each name and sample type.
fn channels(value: &[u8]) -> Result<Vec<(String, SampleType)>, String> {
    let mut list = Vec::new();
    let mut rest = value;
    loop {
        let end = rest
            .iter()
            .position(|&b| b == 0)
            .ok_or("has a channel list without its end")?;
        if end == 0 {
            return Ok(list);
        }
        if end > MAX_NAME || list.len() == MAX_CHANNELS {
            return Err("has a channel list tessera does not write".to_owned());
        }
        let name = String::from_utf8_lossy(&rest[..end]).into_owned();
        let fields = rest
            .get(end + 1..end + 17)
            .ok_or("has a channel list cut short")?;
        let kind = match i32_at(fields, 0) {
            0 => SampleType::Uint,
            1 => SampleType::Half,
            2 => SampleType::Float,
            k => return Err(format!("has a channel of unknown sample type {k}")),
        };
        let sampling = (i32_at(fields, 8), i32_at(fields, 12));
        if sampling != (1, 1) {
            return Err(format!(
                "has a subsampled channel ({}x{}), which tessera does not write",
                sampling.0, sampling.1
            ));
        }
        list.push((name, kind));
        rest = &rest[end + 17..];
    }
}

/// Checks that the header of the `len`-byte EXR file `r` is at the start of keeps within
/// the bounds every header is read in (one part, no deep data, at most `MAX_ATTRIBUTES`
/// attributes of at most `MAX_VALUE` bytes), whatever its channels and attributes: for an
/// EXR another program may have made (an image texture, an image to compare), which the
/// `exr` crate then reads, keeping every attribute without a bound of its own; and that its
/// pixels take at most `most_decoded` bytes decoded (`Decoded`).
pub fn check_bounds<R: Read>(r: R, len: u64, most_decoded: u64) -> Result<(), String> {
    let mut decoded = Decoded::default();
    let header_len = walk(r, len, &mut |name, kind, value| {
        decoded.note(name, kind, &value);
        Ok(())
    })?;
    decoded.check(most_decoded, header_len, len)
}

/// What a header says of the bytes its pixels take decoded: the data window and the
/// channels' bytes a pixel. The `exr` crate inflates each block of every channel in full
/// before it hands the decoder the pixels it asks for (those of the display window, whose
/// size is the one checked): a file of 3 MiB whose data window is 2^24 x 16 pixels of ZIP
/// blocks (its display window one pixel) once asked for 6 GiB, and ended tessera on the
/// failed allocation.
/// And what it says of its chunks: their count (`MAX_CHUNKS_READ`).
#[derive(Default)]
struct Decoded {
    data: Option<[i32; 4]>,
    bytes_per_pixel: Option<u64>,
    compression: Option<u8>,
    tiles: Option<Tiles>,
}

impl Decoded {
    /// Takes note of the attribute `name` of type `kind`, where it is one of those that
    /// size the pixels or place the chunks.
    fn note(&mut self, name: &str, kind: &str, value: &[u8]) {
        match (name, kind) {
            ("dataWindow", "box2i") => self.data = box2i(value, "dataWindow").ok(),
            ("channels", "chlist") => self.bytes_per_pixel = bytes_per_pixel(value),
            ("compression", "compression") => self.compression = value.first().copied(),
            ("tiles", "tiledesc") => self.tiles = tiles(value),
            _ => {}
        }
    }

    /// Refuses pixels that take more than `most` bytes decoded, more than
    /// `MAX_CHUNKS_READ` chunks, and more chunks (or, uncompressed, more pixels) than the
    /// `len`-byte file, whose header is `header_len` bytes, holds. A header without what
    /// sizes them, or of an empty data window, is the decoder's to refuse.
    fn check(&self, most: u64, header_len: u64, len: u64) -> Result<(), String> {
        let Some(data) = self.data else {
            return Ok(());
        };
        let (Some(width), Some(height)) = (extent(data[0], data[2]), extent(data[1], data[3]))
        else {
            return Ok(());
        };
        let chunks = chunk_count(width, height, self.compression, self.tiles);
        if let Some(chunks) = chunks {
            check_chunks(chunks, width, height, MAX_CHUNKS_READ)?;
        }
        let decoded = self.bytes_per_pixel.map(|bytes| {
            (
                bytes,
                u128::from(width) * u128::from(height) * u128::from(bytes),
            )
        });
        if let Some((bytes, decoded)) = decoded
            && decoded > u128::from(most)
        {
            return Err(format!(
                "has pixels that take {decoded} bytes decoded (a data window of \
                 {width}x{height}, {bytes} bytes a pixel), more than the {most} an image's \
                 pixels may take here"
            ));
        }
        // The decoder makes room for every pixel from the header alone, before it reads a
        // chunk: a file of 313 bytes claiming 4096x4096 float RGB had 201 MB reserved, and
        // ended tessera where that much could not be. The chunks the header claims must be
        // in the file first, each at least `MIN_CHUNK_BYTES`, and the fewest bytes its
        // compression can store its pixels in (`least_stored`) too: a file of 4.4 KB that
        // held the offset table and 16 bytes a chunk of 4096x4096 float RGB of ZIP blocks had
        // 400 MB reserved before its first chunk failed to inflate.
        let Some(chunks) = chunks else {
            return Ok(());
        };
        let stored = match (self.compression, decoded) {
            (Some(compression), Some((_, decoded))) => {
                least_stored(compression, u64::try_from(decoded).unwrap_or(u64::MAX))
            }
            _ => 0,
        };
        let least = header_len
            .saturating_add(chunks.saturating_mul(MIN_CHUNK_BYTES))
            .saturating_add(stored);
        if least > len {
            // HTJ2K's floor is every pixel's bytes only because the decoder reads no other
            // chunk: a real HTJ2K file is not cut short, and is told why it is refused.
            if let Some(10 | 11) = self.compression {
                return Err(format!(
                    "is compressed with HTJ2K, which the decoder reads only where every chunk \
                     is stored uncompressed: its {} would take at least {least} bytes with \
                     the header, and the file has {len}",
                    crate::text::count(chunks, "chunk")
                ));
            }
            return Err(format!(
                "is cut short: its header claims {} (blocks of scan lines or tiles of a \
                 data window of {width}x{height}), which take at least {least} bytes with the \
                 header, and the file has {len}",
                crate::text::count(chunks, "chunk")
            ));
        }
        Ok(())
    }
}

/// The fewest bytes pixels that take `decoded` bytes decoded take stored in the compression
/// `compression` (as EXR numbers it), by the most each compression can shrink them: the
/// decoder makes room for them all from the header, so the bytes the file must hold follow
/// them. Without compression, and HTJ2K (which the decoder reads only where a chunk is stored
/// as it is, the same length decoded), all of them; RLE two bytes for a run of at most 128;
/// ZIP and ZIPS a deflate stream, at most 258 bytes for two bits (1032 to one); PXR24 the
/// same of floats cut to 24 bits (4/3 more); B44 and B44A at least 3 bytes for a block of
/// 16 halves (32 bytes), other channels as they are. PIZ (Huffman codes of runs) and DWAA and
/// DWAB (a zlib stream of run-length codes of a DCT: a flat picture shrinks some 66,000 to
/// one, a 4096x4096 image of floats to 3 KB) are given no floor: 16 bytes a chunk.
fn least_stored(compression: u8, decoded: u64) -> u64 {
    match compression {
        0 | 10 | 11 => decoded,
        1 => decoded / 64,
        2 | 3 => decoded / 1032,
        5 => decoded / 1376,
        6 | 7 => decoded / 32 * 3,
        _ => 0,
    }
}

/// The fewest bytes a chunk takes in a file: its offset table entry (8 bytes) and, in the
/// chunk, its first row or tile coordinates and its data's length (at least 8 more).
const MIN_CHUNK_BYTES: u64 = 16;

/// The most chunks (blocks of scan lines, or tiles of every level) of a file another
/// program made that are read. The `exr` crate takes about 72 bytes to place each chunk
/// before it decodes a pixel (its offset twice, and where it lies in the picture, 48
/// bytes), whatever the chunk holds: a column of 14 million scan lines of one pixel, one a
/// chunk (308 MB, within the length `compare` reads), took 1.0 GB to compare with itself,
/// where a square image of as many pixels takes 0.5 GB. Such chunks take at most 80 MB:
/// tessera writes one a row (4,096 for an image of 4,096 rows), and 16x16 tiles of
/// 4096x4096 pixels are 65,536.
pub const MAX_CHUNKS_READ: u64 = 1 << 20;

/// A tiled part's tile size and level mode (a `tiledesc` value's last byte: the levels in
/// its low four bits, the rounding of their sizes in the next).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Tiles {
    width: u32,
    height: u32,
    mode: u8,
}

/// The longest side of a tile: OpenEXR keeps it in an `int`.
const MAX_TILE_SIDE: u32 = i32::MAX as u32;

/// Refuses a `tiledesc` value of tiles with a side of no pixels, or past an `int`'s: no
/// tile OpenEXR makes, which the decoder refuses in its own words ("invalid: tile size").
fn tile_fault(value: &[u8]) -> Result<(), String> {
    match tile_size(value) {
        Some((w, h)) if !(1..=MAX_TILE_SIDE).contains(&w) || !(1..=MAX_TILE_SIDE).contains(&h) => {
            Err(format!(
                "has a tiles attribute of tiles of {w}x{h} pixels: each side must be from 1 \
                 to {MAX_TILE_SIDE}"
            ))
        }
        _ => Ok(()),
    }
}

/// The most a `compression` attribute may say: the last of OpenEXR's methods, HTJ2K32.
const LAST_COMPRESSION: u8 = 11;

/// Refuses the value of an attribute that places or decodes the pixels where it is none
/// OpenEXR defines, naming the attribute, where the decoder refused it in its own words
/// ("invalid: line order attribute value", "not supported: unknown compression method",
/// "invalid: tile size"), and `info` showed the file as sound: tiles of a side of no pixels
/// or past an `int`'s, a line order other than 0 to 2, a compression past HTJ2K32.
fn value_fault(name: &str, kind: &str, value: &[u8]) -> Result<(), String> {
    match (name, kind, value) {
        ("tiles", "tiledesc", _) => tile_fault(value),
        ("lineOrder", "lineOrder", &[order]) if order > 2 => Err(format!(
            "has a lineOrder attribute of {order}: OpenEXR defines 0 (increasing y), 1 \
             (decreasing y) and 2 (random y)"
        )),
        ("compression", "compression", &[method]) if method > LAST_COMPRESSION => Err(format!(
            "has a compression attribute of {method}: OpenEXR defines 0 (none) to \
             {LAST_COMPRESSION} (HTJ2K32)"
        )),
        _ => Ok(()),
    }
}

/// The tile description of a `tiledesc` value, None where it is cut short.
fn tiles(value: &[u8]) -> Option<Tiles> {
    let (width, height) = tile_size(value)?;
    Some(Tiles {
        width,
        height,
        mode: *value.get(8)?,
    })
}

/// The scan lines of a chunk of a file of scan lines of the compression `compression` (as
/// EXR numbers it): none, RLE and ZIPS one; ZIP and PXR24 16; PIZ, B44, B44A, DWAA and
/// HTJ2K32 32; DWAB and HTJ2K256 256. None for one the decoder does not know.
fn scan_lines_per_chunk(compression: u8) -> Option<u32> {
    match compression {
        0..=2 => Some(1),
        3 | 5 => Some(16),
        4 | 6..=8 | 11 => Some(32),
        9 | 10 => Some(256),
        _ => None,
    }
}

/// The chunks of a part of `width` x `height` pixels of the compression `compression`,
/// tiled as `tiles` says where it is, counted as the `exr` crate counts them (every level
/// of a mipmap or ripmap) before it reads the offset table: from the header alone. None
/// where the compression or the tiles are ones the decoder refuses.
fn chunk_count(
    width: u32,
    height: u32,
    compression: Option<u8>,
    tiles: Option<Tiles>,
) -> Option<u64> {
    let Some(tiles) = tiles else {
        return Some(u64::from(
            height.div_ceil(scan_lines_per_chunk(compression?)?),
        ));
    };
    if tiles.width == 0 || tiles.height == 0 {
        return None;
    }
    let round_up = tiles.mode >> 4 & 1 == 1;
    // The levels of a side of `size` pixels (log2 of it, rounded, and one), and the size
    // of the side at level `level` (halved that many times, rounded, at least one).
    let levels = |size: u32| {
        if round_up {
            u64::from(size).next_power_of_two().trailing_zeros() + 1
        } else {
            u32::BITS - size.leading_zeros()
        }
    };
    let side = |size: u32, level: u32| {
        let size = u64::from(size);
        if round_up {
            size.div_ceil(1 << level).max(1)
        } else {
            (size >> level).max(1)
        }
    };
    // Counts that pass 2^64 (tiles of one pixel of a data window of 2^32 x 2^32 and its
    // ripmap levels) are the most there are, not wrapped to a few.
    let of_level = |w: u64, h: u64| {
        w.div_ceil(u64::from(tiles.width))
            .saturating_mul(h.div_ceil(u64::from(tiles.height)))
    };
    match tiles.mode & 0xf {
        0 => Some(of_level(u64::from(width), u64::from(height))),
        1 => Some(
            (0..levels(width.max(height)))
                .map(|l| of_level(side(width, l), side(height, l)))
                .fold(0, u64::saturating_add),
        ),
        2 => Some(
            (0..levels(width))
                .flat_map(|x| (0..levels(height)).map(move |y| (x, y)))
                .map(|(x, y)| of_level(side(width, x), side(height, y)))
                .fold(0, u64::saturating_add),
        ),
        _ => None,
    }
}

/// Refuses `chunks` chunks of a `width` x `height` data window where they are more than
/// `most`.
fn check_chunks(chunks: u64, width: u32, height: u32, most: u64) -> Result<(), String> {
    if chunks > most {
        return Err(format!(
            "has {chunks} chunks (blocks of scan lines or tiles of a data window of \
             {width}x{height}), more than the {most} read here: the decoder takes some 72 bytes \
             to place each before it decodes a pixel"
        ));
    }
    Ok(())
}

/// The chunks of the `width` x `height` file of `layout` (counted as `chunk_count` counts
/// them), None where its compression or tiles are ones the decoder refuses: for a file
/// `read` has read the header of, which refuses mipmap and ripmap levels.
pub fn chunks_of(width: u32, height: u32, layout: &ExrLayout) -> Option<u64> {
    let tiles = layout.tiles.map(|(width, height)| Tiles {
        width,
        height,
        mode: 0,
    });
    chunk_count(width, height, layout.compression, tiles)
}

/// The bytes a pixel of the channels of a `chlist` value take decoded (a subsampled
/// channel counted whole, 4 for one of a sample type the decoder does not know), None
/// where the list is cut short.
fn bytes_per_pixel(value: &[u8]) -> Option<u64> {
    let (mut bytes, mut rest) = (0u64, value);
    loop {
        let end = rest.iter().position(|&b| b == 0)?;
        if end == 0 {
            return Some(bytes);
        }
        let fields = rest.get(end + 1..end + 17)?;
        bytes += if i32_at(fields, 0) == 1 { 2 } else { 4 };
        rest = &rest[end + 17..];
    }
}

/// The channels OpenEXR's RGBA interface (`RgbaInputFile`, which exrdisplay and ImageMagick
/// read through) reads in place of R, G and B wherever one is there: luminance (`Y`),
/// shown grey, and chroma (`RY`, `BY`), shown with it.
const LUMINANCE_CHROMA: [&str; 3] = ["Y", "RY", "BY"];

/// What is said of the luminance or chroma channels of a `chlist` value, if it has any
/// (`LUMINANCE_CHROMA`): the decoder measures R, G and B and reads past them, so that a file
/// of the same R, G and B and a `Y` of zeros, which those viewers show black, was
/// `identical`. A list cut short names those before its cut.
fn luminance_chroma(value: &[u8]) -> Option<String> {
    let mut found = Vec::new();
    let mut rest = value;
    while let Some(end) = rest.iter().position(|&b| b == 0).filter(|&end| end > 0) {
        let name = &rest[..end];
        if let Some(known) = LUMINANCE_CHROMA.iter().find(|n| n.as_bytes() == name) {
            found.push(format!("`{known}`"));
        }
        let Some(next) = rest.get(end + 17..) else {
            break;
        };
        rest = next;
    }
    (!found.is_empty()).then(|| {
        format!(
            "luminance or chroma channels ({}), which viewers built on OpenEXR's RGBA \
             interface (exrdisplay, ImageMagick) show in place of the R, G and B the decoder \
             measured",
            found.join(", ")
        )
    })
}

/// The longest name OpenEXR reads in a file without the long-names flag (`LONG_NAMES`): an
/// attribute's or a channel's of more bytes ends its read of the header.
const MAX_SHORT_NAME: usize = 31;

/// What is said of the channels of a `chlist` value that OpenEXR refuses and the `exr`
/// crate reads, if there are such: a name twice ("Attempt to add duplicate channel"), of
/// which the decoder measures one, or in a file without the long-names flag (`long_names`)
/// a name longer than `MAX_SHORT_NAME` bytes, which the decoder reads whatever the flag
/// (it refuses an attribute's). A list of B, G, R and a second R, the first red, was
/// `identical` to a red file, where every viewer built on OpenEXR refuses it. A list cut
/// short is judged as far as its cut.
fn refused_channels(value: &[u8], long_names: bool) -> Option<String> {
    // A set: the list may hold some 60,000 names within the bound on a value's bytes.
    let (mut names, mut rest) = (std::collections::BTreeSet::new(), value);
    while let Some(end) = rest.iter().position(|&b| b == 0).filter(|&end| end > 0) {
        let name = &rest[..end];
        let shown = || String::from_utf8_lossy(name).escape_debug().to_string();
        if names.contains(name) {
            return Some(format!(
                "a channel list that names `{}` twice, which OpenEXR refuses: viewers built \
                 on it refuse the file, where the decoder measured one of the two",
                shown()
            ));
        }
        if !long_names && name.len() > MAX_SHORT_NAME {
            return Some(format!(
                "a channel `{}` of a name of {} bytes in a file without the long-names flag, \
                 which OpenEXR refuses (it reads names of at most {MAX_SHORT_NAME} there): \
                 viewers built on it refuse the file",
                shown(),
                name.len()
            ));
        }
        names.insert(name);
        let Some(next) = rest.get(end + 17..) else {
            break;
        };
        rest = next;
    }
    None
}

/// `check_bounds` (`most_decoded` bytes of pixels), and what the file holds that changes how
/// a viewer shows the picture (`ExrHeader::display_changes`), whatever its channels, with an
/// offset table entry that points to another chunk's data (`misplaced_chunk`): for `compare`.
pub fn display_changes<R: Read + std::io::Seek>(
    mut r: R,
    len: u64,
    most_decoded: u64,
) -> Result<Vec<String>, String> {
    let (mut changes, mut attributes) = (Vec::new(), Vec::new());
    let (mut tiles, mut compression, mut data, mut display) = (None, None, None, None);
    let mut levels = false;
    let mut decoded = Decoded::default();
    let mut list = None;
    let header_len = walk(&mut r, len, &mut |name, kind, value| {
        attributes.push((name.to_owned(), kind.to_owned()));
        decoded.note(name, kind, &value);
        changes.extend(misfit(name, kind, value.len()));
        // What places the chunks; a value of the wrong size leaves the table unchecked,
        // the decoder the judge.
        match (name, kind) {
            ("compression", "compression") => compression = value.first().copied(),
            ("dataWindow", "box2i") => data = box2i(&value, "dataWindow").ok(),
            ("displayWindow", "box2i") => display = box2i(&value, "displayWindow").ok(),
            ("channels", "chlist") => {
                changes.extend(luminance_chroma(&value));
                list = Some(value.clone());
            }
            ("tiles", "tiledesc") => {
                tiles = tile_size(&value);
                // Levels past the first are the picture again at smaller sizes, which a
                // viewer may show zoomed out (and the decoder here never reads).
                levels = value.get(8).is_some_and(|mode| mode & 0xf != 0);
                if levels {
                    changes.push(
                        "holds mipmap or ripmap levels (the picture again at smaller sizes, \
                         which viewers show zoomed out), which tessera does not write"
                            .to_owned(),
                    );
                }
            }
            _ => {}
        }
        changes.extend(display_change(name, kind, &value)?);
        Ok(())
    })?;
    decoded.check(most_decoded, header_len, len)?;
    // The version's flags, which the walk read and checked, for the names' longest.
    if let Some(list) = list {
        let mut version = [0u8; 4];
        r.seek(std::io::SeekFrom::Start(4))
            .and_then(|_| r.read_exact(&mut version))
            .map_err(|e| format!("could not be read: {e}"))?;
        let long_names = u32::from_le_bytes(version) & LONG_NAMES != 0;
        changes.extend(refused_channels(&list, long_names));
    }
    changes.extend(lacking(&attributes));
    // The decoder measures the display window (what lies outside it cropped, what it
    // holds outside the data window black), where viewers built on OpenEXR (GIMP,
    // Blender) show the data window: the pixels measured are not those shown.
    if display.is_some_and(|d| Some(d) != data) {
        changes.push(DISPLAY_WINDOW.to_owned());
    }
    if let Some(data) = data
        && let (Some(width), Some(height)) = (extent(data[0], data[2]), extent(data[1], data[3]))
    {
        let layout = ExrLayout {
            header_len,
            tiles,
            levels,
            compression,
            top: data[1],
        };
        let misplaced = misplaced_chunk(&mut r, width, height, &layout)?;
        changes.extend(misplaced);
    }
    Ok(changes)
}

/// The width and height of a tile a `tiledesc` value gives, None where it is cut short.
fn tile_size(value: &[u8]) -> Option<(u32, u32)> {
    let size = |at: usize| Some(u32::from_le_bytes(value.get(at..at + 4)?.try_into().ok()?));
    Some((size(0)?, size(4)?))
}

/// The pixels a data window spans from `min` to `max` along one axis, None for none.
fn extent(min: i32, max: i32) -> Option<u32> {
    u32::try_from(i64::from(max) - i64::from(min) + 1)
        .ok()
        .filter(|&n| n > 0)
}

/// How the attribute `name` of type `kind` holding `value` changes how a viewer shows the
/// picture, if it does: a pixel aspect ratio other than 1, or one of `DISPLAY_ATTRIBUTES`.
fn display_change(name: &str, kind: &str, value: &[u8]) -> Result<Option<String>, String> {
    if (name, kind) == ("pixelAspectRatio", "float") {
        let ratio = f32::from_le_bytes(
            value
                .get(..4)
                .and_then(|v| v.try_into().ok())
                .ok_or("has a pixelAspectRatio that is not a number")?,
        );
        return Ok((ratio != 1.0).then(|| {
            format!("the attribute pixelAspectRatio is {ratio}, not 1: viewers stretch it")
        }));
    }
    Ok(DISPLAY_ATTRIBUTES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, how)| format!("the attribute {name}, which tessera does not write: {how}")))
}

/// What is done with each attribute of a header walked: its name, type and value.
type Visit<'a> = dyn FnMut(&str, &str, Vec<u8>) -> Result<(), String> + 'a;

/// Walks the header of the `len`-byte EXR file `r` is at the start of, within the bounds,
/// handing `visit` each attribute's name, type and value; gives the header's length.
fn walk<R: Read>(r: R, len: u64, visit: &mut Visit<'_>) -> Result<u64, String> {
    let mut r = Bounded {
        inner: r,
        left: len,
        read: 0,
    };
    if r.bytes(4, "signature").ok().as_deref() != Some(&MAGIC[..]) {
        return Err("is not an OpenEXR file".to_owned());
    }
    let version = r.u32("version")?;
    if version & 0xff != 2 {
        return Err(format!(
            "is an OpenEXR file of version {}, not 2",
            version & 0xff
        ));
    }
    if version & MULTIPART != 0 {
        return Err(
            "is a multi-part OpenEXR file: tessera writes and reads a single part".to_owned(),
        );
    }
    if version & DEEP != 0 {
        return Err("holds deep data, which tessera does not write".to_owned());
    }
    if version & !(0xff | TILED | LONG_NAMES) != 0 {
        return Err(format!(
            "has OpenEXR flags tessera does not know (0x{version:x})"
        ));
    }
    let mut seen = std::collections::HashSet::new();
    let tiled = version & TILED != 0;
    loop {
        let name = r.name("attribute name")?;
        if name.is_empty() {
            // A tiled file's tile description must be there; a scan-line file's must not.
            if seen.contains("tiles") != tiled {
                return Err(format!(
                    "has {} tile description where its version flags say {}: readers would \
                     decode it differently",
                    if tiled { "no" } else { "a" },
                    if tiled { "tiles" } else { "scan lines" }
                ));
            }
            return Ok(r.read);
        }
        if seen.len() == MAX_ATTRIBUTES {
            return Err(format!(
                "has more than {MAX_ATTRIBUTES} header attributes; tessera writes about ten"
            ));
        }
        if !seen.insert(name.clone()) {
            return Err(format!("has the attribute `{}` twice", name.escape_debug()));
        }
        let kind = r.name("attribute type")?;
        let size = r.u32("attribute size")?;
        if u64::from(size) > MAX_VALUE {
            return Err(format!(
                "has an attribute `{}` of {size} bytes, more than tessera reads",
                name.escape_debug()
            ));
        }
        let value = r.bytes(u64::from(size), "attribute")?;
        // A part's `type`, optional in a single-part file, where readers differ on which
        // to believe when it disagrees with the version flags (the `exr` crate takes a
        // `tiledimage` type for tiles whatever the flags say): it must agree with them.
        if name == "type" {
            let expected = if tiled { "tiledimage" } else { "scanlineimage" };
            if kind != "string" {
                return Err(format!(
                    "has the attribute `type` of type `{}`, not the type OpenEXR gives it \
                     (string)",
                    kind.escape_debug()
                ));
            }
            if value != expected.as_bytes() {
                return Err(format!(
                    "has the part type `{}` where its version flags say `{expected}`: readers \
                     would decode it differently",
                    String::from_utf8_lossy(&value).escape_debug()
                ));
            }
        }
        value_fault(&name, &kind, &value)?;
        visit(&name, &kind, value)?;
    }
}

/// Reads the header of the `len`-byte EXR file `r` is at the start of.
pub fn read<R: Read>(r: R, len: u64) -> Result<ExrHeader, String> {
    let (mut data, mut display, mut list, mut recipe) = (None, None, None, None);
    let (mut display_changes, mut attributes) = (Vec::new(), Vec::new());
    let (mut tiles, mut compression) = (None, None);
    let header_len = walk(r, len, &mut |name, kind, value| {
        attributes.push((name.to_owned(), kind.to_owned()));
        display_changes.extend(misfit(name, kind, value.len()));
        match (name, kind) {
            ("compression", "compression") => compression = value.first().copied(),
            ("dataWindow", "box2i") => data = Some(box2i(&value, "dataWindow")?),
            ("displayWindow", "box2i") => display = Some(box2i(&value, "displayWindow")?),
            ("channels", "chlist") => list = Some(channels(&value)?),
            ("pixelAspectRatio", "float") => {
                display_changes.extend(display_change(name, kind, &value)?);
            }
            ("tiles", "tiledesc") => {
                let mode = value.get(8).ok_or("has a tile description cut short")?;
                if mode & 0xf != 0 {
                    return Err(
                        "holds mipmap or ripmap levels, which tessera does not write".to_owned(),
                    );
                }
                tiles = tile_size(&value);
            }
            (key, "string") if key == recipe::KEY => {
                recipe = Some(String::from_utf8(value).map_err(|e| {
                    format!(
                        "has a recipe attribute (`{key}`) that is not UTF-8 text (a bad byte \
                         at {} of its value)",
                        e.utf8_error().valid_up_to()
                    )
                })?);
            }
            (key, kind) if key == recipe::KEY => {
                return Err(format!(
                    "has a recipe attribute (`{key}`) of type `{}`, not `string`",
                    kind.escape_debug()
                ));
            }
            ("dataWindow" | "displayWindow" | "channels" | "pixelAspectRatio" | "tiles", kind) => {
                return Err(format!(
                    "has the attribute `{name}` of type `{}`, not the type OpenEXR gives it",
                    kind.escape_debug()
                ));
            }
            (_, _) => display_changes.extend(display_change(name, kind, &value)?),
        }
        Ok(())
    })?;
    display_changes.extend(lacking(&attributes));
    let data = data.ok_or("has no dataWindow attribute")?;
    let list = list.ok_or("has no channels attribute")?;
    let names: Vec<&str> = list.iter().map(|(n, _)| n.as_str()).collect();
    if names != ["B", "G", "R"] {
        return Err(format!(
            "has the channels {}; tessera writes R, G and B only",
            names
                .iter()
                .map(|n| format!("`{}`", n.escape_debug()))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let samples = (list.iter().all(|(_, k)| *k == list[0].1)).then_some(list[0].1);
    if display.is_some_and(|d| d != data) {
        display_changes.push(DISPLAY_WINDOW.to_owned());
    }
    let (Some(width), Some(height)) = (extent(data[0], data[2]), extent(data[1], data[3])) else {
        return Err(format!("has an empty or inverted dataWindow {data:?}"));
    };
    Ok(ExrHeader {
        width,
        height,
        samples,
        recipe,
        display_changes,
        layout: ExrLayout {
            header_len,
            tiles,
            // Refused above.
            levels: false,
            compression,
            top: data[1],
        },
    })
}

/// Where an EXR file's chunks lie: what its offset table, which follows the header, must
/// say of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExrLayout {
    /// The header's length in bytes: where the offset table begins.
    pub header_len: u64,
    /// The width and height of a tile, in a tiled file.
    pub tiles: Option<(u32, u32)>,
    /// Whether the tiles have mipmap or ripmap levels past the first (their chunks say a
    /// level other than (0, 0)).
    pub levels: bool,
    /// The compression (as EXR numbers it), which sets the scan lines of a chunk.
    pub compression: Option<u8>,
    /// The data window's first row.
    pub top: i32,
}

/// The most chunks whose places are checked: one a pixel of the largest image `compare`
/// takes (4096x4096), far more than any layout tessera writes (64x64 tiles).
const MAX_CHUNKS: u64 = 1 << 24;

/// The low bits of an entry of the table as `misplaced_chunk` sorts it, which hold the
/// entry's index (`MAX_CHUNKS` of them), its place in the file above them.
const INDEX_BITS: u32 = 24;

/// Whether an offset table entry of the `width` x `height` EXR file `r` (`layout`) points
/// to a chunk that says it is another's, said in words: OpenEXR reads each tile or block of
/// scan lines at its entry and refuses a chunk of other coordinates (every viewer built on
/// it shows nothing), where the `exr` crate places each chunk where the chunk itself says,
/// so that a table of two entries swapped reads as the picture. None when each chunk is
/// where its entry says, or the table is not one to check (a layout or compression tessera
/// does not know): the decoder is then the judge. An entry that points where no chunk can
/// be (into the header or the table, past the file's end) or to a chunk whose data runs
/// past it is refused, naming the entry, where the decoder said only "invalid: scan line
/// block sample count" or "reference to missing bytes". The chunks are visited in the order
/// they lie in the file, through one buffer: a table of millions of entries takes a read of
/// the file, not a seek and a read for each.
pub fn misplaced_chunk<R: Read + std::io::Seek>(
    r: R,
    width: u32,
    height: u32,
    layout: &ExrLayout,
) -> Result<Option<String>, String> {
    chunk_places(r, width, height, layout).map_err(|e| match e {
        Placing::Io(e) => format!("could not be read: {e}"),
        Placing::Refused(why) => why,
    })
}

/// Why the chunks' places were not judged: the file could not be read, or an entry of the
/// offset table is refused (said in words).
enum Placing {
    Io(std::io::Error),
    Refused(String),
}

impl From<std::io::Error> for Placing {
    fn from(e: std::io::Error) -> Self {
        Placing::Io(e)
    }
}

/// `misplaced_chunk`, its refusals and failures apart.
fn chunk_places<R: Read + std::io::Seek>(
    mut r: R,
    width: u32,
    height: u32,
    layout: &ExrLayout,
) -> Result<Option<String>, Placing> {
    use std::io::SeekFrom;
    // Chunks across and down, and the scan lines of a chunk of a file of scan lines.
    let (columns, rows, lines) = match layout.tiles {
        Some((0, _) | (_, 0)) => return Ok(None),
        Some((w, h)) => (width.div_ceil(w), height.div_ceil(h), 0),
        None => {
            let Some(lines) = layout.compression.and_then(scan_lines_per_chunk) else {
                return Ok(None);
            };
            (1, height.div_ceil(lines), lines)
        }
    };
    let count = u64::from(columns) * u64::from(rows);
    if count > MAX_CHUNKS {
        return Ok(None);
    }
    // The table is 8 bytes an entry: one the file is too short to hold is not read (nor
    // room made for its entries, which a header of 2^24 rows and a file of a few hundred
    // bytes once had reserve 128 MiB).
    let len = r.seek(SeekFrom::End(0))?;
    if layout.header_len.saturating_add(8 * count) > len {
        return Ok(None);
    }
    r.seek(SeekFrom::Start(layout.header_len))?;
    let mut file = std::io::BufReader::new(&mut r);
    // Each entry as its place and its index in one number, sorted: the places in order.
    let mut entries = Vec::with_capacity(count as usize);
    // Where the table ends, and the first chunk may begin.
    let table_end = layout.header_len + 8 * count;
    for i in 0..count {
        let mut entry = [0u8; 8];
        if file.read_exact(&mut entry).is_err() {
            return Ok(None);
        }
        let offset = u64::from_le_bytes(entry);
        if offset < table_end {
            return Err(Placing::Refused(format!(
                "has an offset table whose entry {i} points to byte {offset}, within its \
                 header and offset table (its first {}), where no chunk lies",
                crate::text::count(table_end, "byte")
            )));
        }
        if offset >= len {
            return Err(Placing::Refused(format!(
                "has an offset table whose entry {i} points to byte {offset}, past the file's \
                 end ({})",
                crate::text::count(len, "byte")
            )));
        }
        // An offset of 2^40 or more, in a file shorter than that, is past its end above.
        if offset >= 1 << (64 - INDEX_BITS) {
            return Ok(None);
        }
        entries.push(offset << INDEX_BITS | i);
    }
    entries.sort_unstable();
    let mut at = table_end;
    // The entry of the lowest index that points to another chunk, and what that chunk says.
    let mut first_wrong: Option<(u32, [i32; 4])> = None;
    for entry in entries {
        let (offset, i) = (entry >> INDEX_BITS, (entry & (MAX_CHUNKS - 1)) as u32);
        // The chunk's coordinates (a tile's four, a block's first row) and its data's length.
        let mut said = [0u8; 20];
        let n = if layout.tiles.is_some() { 16 } else { 4 };
        file.seek_relative(offset.wrapping_sub(at) as i64)?;
        let whole = file.read_exact(&mut said[..n + 4]);
        let data = i64::from(i32::from_le_bytes([0, 1, 2, 3].map(|b| said[n + b])));
        let end = (offset + n as u64 + 4).saturating_add_signed(data);
        if whole.is_ok() && data < 0 {
            return Err(Placing::Refused(format!(
                "has an offset table whose entry {i} points to a chunk at byte {offset} whose \
                 data's length is {data} bytes, below zero"
            )));
        }
        if whole.is_err() || end > len {
            return Err(Placing::Refused(format!(
                "has an offset table whose entry {i} points to a chunk at byte {offset} that \
                 runs past the file's end ({}){}",
                crate::text::count(len, "byte"),
                if whole.is_ok() {
                    format!(
                        ": its data claims {}",
                        crate::text::count(data as u64, "byte")
                    )
                } else {
                    String::new()
                }
            )));
        }
        at = offset + n as u64 + 4;
        let said = [0, 1, 2, 3].map(|k| i32::from_le_bytes([0, 1, 2, 3].map(|b| said[4 * k + b])));
        if let Some(why) = no_chunk_of_the_image(said, columns, rows, lines, layout, height) {
            return Err(Placing::Refused(format!(
                "has an offset table whose entry {i} points to a chunk at byte {offset} {why}"
            )));
        }
        let (column, row) = (i % columns, i / columns);
        let right = match layout.tiles {
            Some(_) => said.map(i64::from) == [i64::from(column), i64::from(row), 0, 0],
            None => i64::from(said[0]) == i64::from(layout.top) + i64::from(row) * i64::from(lines),
        };
        if !right && first_wrong.is_none_or(|(j, _)| i < j) {
            first_wrong = Some((i, said));
        }
    }
    let Some((i, said)) = first_wrong else {
        return Ok(None);
    };
    let (column, row) = (i % columns, i / columns);
    let wrong = match layout.tiles {
        Some(_) => format!(
            "entry {i} of its offset table, for tile ({column}, {row}), points to the chunk of \
             tile ({}, {}) at level ({}, {})",
            said[0], said[1], said[2], said[3]
        ),
        None => format!(
            "entry {i} of its offset table, for the scan lines from {}, points to the chunk \
             of those from {}",
            i64::from(layout.top) + i64::from(row) * i64::from(lines),
            said[0]
        ),
    };
    Ok(Some(format!(
        "{wrong}: OpenEXR, and every viewer built on it, refuses such a file"
    )))
}

/// Why a chunk that says it holds `said` (a tile's column, row and levels; a block's first
/// scan line) is none of a part of `columns` x `rows` tiles, or of blocks of `lines` scan
/// lines (0 for tiles) from `layout`'s top row, `height` rows: a tile past the largest
/// level's, or of a level the part has none of; scan lines outside the data window, or not
/// where a block begins.
/// Every reader refuses such a chunk (the decoder in its own words, "invalid: tile index"),
/// where one for another of the part's chunks is read by the `exr` crate.
fn no_chunk_of_the_image(
    said: [i32; 4],
    columns: u32,
    rows: u32,
    lines: u32,
    layout: &ExrLayout,
    height: u32,
) -> Option<String> {
    if lines == 0 {
        let [x, y, level_x, level_y] = said.map(i64::from);
        let level = |l: i64| if layout.levels { l >= 0 } else { l == 0 };
        return (!(0..i64::from(columns)).contains(&x)
            || !(0..i64::from(rows)).contains(&y)
            || !level(level_x)
            || !level(level_y))
        .then(|| {
            format!(
                "of tile ({x}, {y}) at level ({level_x}, {level_y}), which the image \
                     ({columns}x{rows} tiles{}) has none of",
                if layout.levels {
                    " at its largest level"
                } else {
                    ", one level"
                }
            )
        });
    }
    let (y, top) = (i64::from(said[0]), i64::from(layout.top));
    let bottom = top + i64::from(height) - 1;
    if !(top..=bottom).contains(&y) {
        return Some(format!(
            "of the scan lines from {y}, outside the data window's rows ({top} to {bottom})"
        ));
    }
    ((y - top) % i64::from(lines) != 0).then(|| {
        format!(
            "of the scan lines from {y}, where no block begins (its compression stores \
             {} from row {top} on)",
            crate::text::count(u64::from(lines), "scan line")
        )
    })
}

#[cfg(test)]
mod tests;
