//! The tests of `exr_header`: headers built here, walked, bounded and refused.

use super::*;
use std::io::{Cursor, Seek, SeekFrom};

/// A part type given as another type than text said the type's text agreed with the
/// flags and disagreed with them in one breath ("the part type `tiledimage` where its
/// version flags say `tiledimage`"); it names the attribute's type.
#[test]
fn a_part_type_of_another_type_than_string_is_named_so() {
    let header = |kind: &[u8]| {
        let mut file = vec![0x76, 0x2f, 0x31, 0x01, 2, 2, 0, 0];
        file.extend(
            [
                &b"type\0"[..],
                kind,
                b"\0",
                &10u32.to_le_bytes(),
                b"tiledimage",
            ]
            .concat(),
        );
        file.push(0);
        file
    };
    let file = header(b"text");
    let said = read(&file[..], file.len() as u64).err();
    assert_eq!(
        said.as_deref(),
        Some("has the attribute `type` of type `text`, not the type OpenEXR gives it (string)")
    );
    // Of the right type and value, the walk goes on past it.
    let file = header(b"string");
    let said = read(&file[..], file.len() as u64).err().unwrap_or_default();
    assert!(!said.contains("`type`"), "{said}");
}

/// The bytes a data window's pixels take decoded, all channels: a header claiming more
/// than the bound is refused, whatever its display window (one pixel here), by both
/// walks; one within it is not.
#[test]
fn pixels_that_take_more_than_the_bound_decoded_are_refused() {
    let header = |width: i32, half: bool| {
        let mut channels = Vec::new();
        for name in [b"A", b"B", b"G", b"R"] {
            channels.extend(name);
            channels.push(0);
            let kind = if half && name == b"A" { 1 } else { 2 };
            channels.extend([kind, 0, 1, 1].iter().flat_map(|v: &i32| v.to_le_bytes()));
        }
        channels.push(0);
        let window = |x: i32| -> Vec<u8> {
            [0, 0, x - 1, 0]
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect()
        };
        let mut file = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        for (name, kind, value) in [
            ("channels", "chlist", channels),
            ("dataWindow", "box2i", window(width)),
            ("displayWindow", "box2i", window(1)),
        ] {
            file.extend([name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat());
            file.extend((value.len() as u32).to_le_bytes());
            file.extend(value);
        }
        file.push(0);
        file
    };
    for (width, half, within) in [(101, false, false), (100, false, true), (114, true, true)] {
        let file = header(width, half);
        let bounds = check_bounds(&file[..], file.len() as u64, 1600);
        let changes = display_changes(Cursor::new(&file), file.len() as u64, 1600);
        if within {
            assert_eq!(bounds, Ok(()), "{width}");
            assert!(changes.is_ok(), "{width}: {changes:?}");
        } else {
            let said = format!(
                "has pixels that take 1616 bytes decoded (a data window of {width}x1, 16 bytes \
                 a pixel), more than the 1600"
            );
            assert!(
                bounds.as_ref().unwrap_err().starts_with(&said),
                "{bounds:?}"
            );
            assert!(
                changes.as_ref().unwrap_err().starts_with(&said),
                "{changes:?}"
            );
        }
    }
}

/// A header of the attributes `attributes` (name, type, value), and its end.
fn header_of(attributes: &[(&str, &str, Vec<u8>)]) -> Vec<u8> {
    let mut file = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
    if attributes.iter().any(|(name, _, _)| *name == "tiles") {
        file[5] = 2;
    }
    for (name, kind, value) in attributes {
        file.extend([name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat());
        file.extend((value.len() as u32).to_le_bytes());
        file.extend(value);
    }
    file.push(0);
    file
}

/// The attributes of a `width` x `height` file of half R, G and B of the compression
/// `compression`, tiled as `tiles` says (tile width and height, level mode) where given.
fn chunked(
    width: i32,
    height: i32,
    compression: u8,
    tiles: Option<(u32, u32, u8)>,
) -> Vec<(&'static str, &'static str, Vec<u8>)> {
    let mut channels = Vec::new();
    for name in [b"B", b"G", b"R"] {
        channels.extend(name);
        channels.push(0);
        channels.extend([1, 0, 1, 1].iter().flat_map(|v: &i32| v.to_le_bytes()));
    }
    channels.push(0);
    let window: Vec<u8> = [0, 0, width - 1, height - 1]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let mut attributes = vec![
        ("channels", "chlist", channels),
        ("compression", "compression", vec![compression]),
        ("dataWindow", "box2i", window.clone()),
        ("displayWindow", "box2i", window),
    ];
    if let Some((w, h, mode)) = tiles {
        let value = [&w.to_le_bytes()[..], &h.to_le_bytes(), &[mode]].concat();
        attributes.push(("tiles", "tiledesc", value));
    }
    attributes
}

/// A channel list OpenEXR refuses, which the decoder reads: a name twice (B, G, R and a
/// second R, the first red, was `identical` to a red file), or a name of more than 31
/// bytes in a file without the long-names flag. Each is listed, naming the channel; a
/// name of 31 bytes, or a longer one with the flag, is not.
#[test]
fn a_channel_list_openexr_refuses_is_listed() {
    let listed = |names: &[&[u8]], flags: u8| {
        let mut list = Vec::new();
        for name in names {
            list.extend(*name);
            list.push(0);
            list.extend([2, 0, 1, 1].iter().flat_map(|v: &i32| v.to_le_bytes()));
        }
        list.push(0);
        let mut file = header_of(&[("channels", "chlist", list)]);
        file[5] |= flags;
        display_changes(Cursor::new(&file), file.len() as u64, 1 << 20)
            .unwrap()
            .into_iter()
            .filter(|c| c.contains("channel"))
            .collect::<Vec<_>>()
    };
    let twice = listed(&[b"B", b"G", b"R", b"R"], 0);
    assert!(
        twice.len() == 1 && twice[0].starts_with("a channel list that names `R` twice"),
        "{twice:?}"
    );
    let long = [b'X'; 32];
    let said = listed(&[b"B", b"G", b"R", &long], 0);
    assert!(
        said.len() == 1 && said[0].contains("of a name of 32 bytes in a file without"),
        "{said:?}"
    );
    assert!(listed(&[b"B", b"G", b"R", &long], 4).is_empty());
    assert!(listed(&[b"B", b"G", b"R", &long[..31]], 0).is_empty());
    assert!(listed(&[b"B", b"G", b"R"], 0).is_empty());
}

/// The chunks of a part are counted from its header as the `exr` crate counts them
/// (which reads its offset table, and places each chunk, by that count): scan lines of
/// each compression, tiles of one level, of mipmap and ripmap levels rounded down and
/// up.
#[test]
fn chunks_are_counted_as_the_decoder_counts_them() {
    use exr::meta::{BlockDescription, attribute, compute_chunk_count};
    use exr::prelude::{Compression, Vec2};
    let compressions = [
        Compression::Uncompressed,
        Compression::RLE,
        Compression::ZIP1,
        Compression::ZIP16,
        Compression::PIZ,
        Compression::PXR24,
        Compression::B44,
        Compression::B44A,
        Compression::DWAA(None),
        Compression::DWAB(None),
        Compression::HTJ2K256,
        Compression::HTJ2K32,
    ];
    for (number, compression) in compressions.into_iter().enumerate() {
        for (width, height) in [(1, 1), (7, 300), (4096, 4097), (1, 1 << 24)] {
            let theirs = compute_chunk_count(
                compression,
                Vec2(width as usize, height as usize),
                BlockDescription::ScanLines,
            );
            let ours = chunk_count(width, height, Some(number as u8), None);
            assert_eq!(
                ours,
                Some(theirs as u64),
                "{compression:?} {width}x{height}"
            );
        }
    }
    let levels = [
        attribute::LevelMode::Singular,
        attribute::LevelMode::MipMap,
        attribute::LevelMode::RipMap,
    ];
    let roundings = [exr::math::RoundingMode::Down, exr::math::RoundingMode::Up];
    for (mode, level_mode) in levels.into_iter().enumerate() {
        for (up, rounding_mode) in roundings.into_iter().enumerate() {
            for (width, height, tile) in [(1, 1, 1), (5, 300, 2), (4097, 33, 16), (600, 1, 64)] {
                let tiles = attribute::TileDescription {
                    tile_size: Vec2(tile, tile),
                    level_mode,
                    rounding_mode,
                };
                let theirs = compute_chunk_count(
                    Compression::Uncompressed,
                    Vec2(width as usize, height as usize),
                    BlockDescription::Tiles(tiles),
                );
                let tiles = Tiles {
                    width: tile as u32,
                    height: tile as u32,
                    mode: mode as u8 | (up as u8) << 4,
                };
                let ours = chunk_count(width, height, Some(0), Some(tiles));
                assert_eq!(
                    ours,
                    Some(theirs as u64),
                    "{level_mode:?} {rounding_mode:?} {width}x{height} of {tile}"
                );
            }
        }
    }
}

/// The widest data window (2^32 - 1 pixels a side) of tiles of one pixel and their
/// ripmap levels has some 2^66 chunks: counted, they wrapped to fewer where overflow
/// is not checked (and the levels of a side over 2^31 rounded up overflowed a u32),
/// and ended a build where it is. They are the most a u64 holds.
#[test]
fn a_count_of_more_chunks_than_a_u64_holds_is_its_most() {
    for mode in [0x02, 0x12, 0x01, 0x11] {
        let tiles = Tiles {
            width: 1,
            height: 1,
            mode,
        };
        let count = chunk_count(u32::MAX, u32::MAX, Some(0), Some(tiles));
        let least = u64::from(u32::MAX) * u64::from(u32::MAX);
        assert!(count.is_some_and(|c| c >= least), "{mode:x}: {count:?}");
    }
}

/// The `exr` crate takes some 72 bytes to place each chunk before it decodes a pixel:
/// a column of 14 million one-pixel scan lines, one a chunk (308 MB), took 1.0 GB to
/// compare with itself. A header claiming more than `MAX_CHUNKS_READ` chunks is refused
/// by both walks from the header alone (these files are a few hundred bytes); one of
/// that many is not.
#[test]
fn a_header_of_more_chunks_than_are_read_is_refused() {
    let most = MAX_CHUNKS_READ as i32;
    for (attributes, chunks) in [
        // A column of scan lines, one a chunk, uncompressed or ZIPS.
        (chunked(1, most + 1, 0, None), Some(most + 1)),
        (chunked(1, most + 1, 2, None), Some(most + 1)),
        (chunked(1, most, 0, None), None),
        // Scan lines 16 a chunk (ZIP).
        (chunked(1, 16 * most, 3, None), None),
        (chunked(1, 16 * most + 1, 3, None), Some(most + 1)),
        // Tiles of one pixel of 1025x1024 pixels, and 16x16 tiles of 4096x4096.
        (chunked(1025, 1024, 0, Some((1, 1, 0))), Some(1025 * 1024)),
        (chunked(4096, 4096, 0, Some((16, 16, 0))), None),
        // Mipmap levels of 1024x1024 tiles of one pixel: 1024^2 * 4/3 and more.
        (chunked(1024, 1024, 0, Some((1, 1, 1))), Some(1_398_101)),
    ] {
        let file = header_of(&attributes);
        // A file long enough to hold its chunks, as the header is all that is read.
        let len = 1 << 40;
        let bounds = check_bounds(&file[..], len, u64::MAX);
        let changes = display_changes(Cursor::new(&file), len, u64::MAX).map(drop);
        match chunks {
            None => {
                assert_eq!(bounds, Ok(()));
                assert_eq!(changes, Ok(()));
            }
            Some(chunks) => {
                let said = format!("has {chunks} chunks (blocks of scan lines or tiles");
                for refused in [bounds, changes] {
                    let refused = refused.unwrap_err();
                    assert!(refused.starts_with(&said), "{refused}");
                    assert!(refused.contains("more than the 1048576 read here"));
                }
            }
        }
    }
}

/// A file that counts the reads and seeks that reach it.
struct Counted {
    inner: Cursor<Vec<u8>>,
    calls: usize,
}

impl Read for Counted {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.calls += 1;
        self.inner.read(buf)
    }
}

impl Seek for Counted {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.calls += 1;
        self.inner.seek(to)
    }
}

/// One column of `rows` uncompressed scan lines, one a chunk, its table's first two
/// entries swapped: the table at the file's start (a header of no length), then the
/// first eight bytes of each chunk, the row it says it holds and a length of no data.
fn swapped_scan_lines(rows: u32) -> Vec<u8> {
    let chunks = 8 * u64::from(rows);
    let mut file: Vec<u8> = (0..u64::from(rows))
        .flat_map(|i| (chunks + 8 * i).to_le_bytes())
        .collect();
    file.extend((0..rows).flat_map(|row| [row.to_le_bytes(), [0; 4]].concat()));
    let (first, second) = file.split_at_mut(8);
    first.swap_with_slice(&mut second[..8]);
    file
}

/// The layout of an uncompressed file of scan lines whose header ends at byte 0.
fn uncompressed_scan_lines() -> ExrLayout {
    ExrLayout {
        header_len: 0,
        tiles: None,
        levels: false,
        compression: Some(0),
        top: 0,
    }
}

/// A header may claim 2^24 rows of a file of a few hundred bytes: room was made for
/// the table's 2^24 entries (128 MiB) before its first was read, which ended `compare`
/// where memory is bounded (`ulimit -v 100000`). A table the file is too short to
/// hold is not read at all: its length is the one thing asked of the file.
#[test]
fn a_table_longer_than_the_file_is_not_read() {
    let mut file = Counted {
        inner: Cursor::new(vec![0; 16]),
        calls: 0,
    };
    let layout = uncompressed_scan_lines();
    let said = misplaced_chunk(&mut file, 1, 1 << 24, &layout).unwrap();
    assert_eq!(said, None);
    assert_eq!(file.calls, 1);
}

/// A file of scan lines from another program may hold millions of chunks (a column of
/// 4096x4096 pixels, one line each): the table of 2^22 + 1 entries was not checked at
/// all (a swapped pair was `identical` to `compare`), and one of 2^22 took a seek and an
/// 8 KiB read for each entry, seconds.
#[test]
fn a_table_of_millions_of_entries_is_checked_in_one_read_of_the_file() {
    let rows = (1 << 22) + 1;
    let mut file = Counted {
        inner: Cursor::new(swapped_scan_lines(rows)),
        calls: 0,
    };
    let layout = uncompressed_scan_lines();
    let said = misplaced_chunk(&mut file, 1, rows, &layout).unwrap();
    assert!(
        said.as_deref().is_some_and(|s| s.starts_with(
            "entry 0 of its offset table, for the scan lines from 0, points to the chunk of \
             those from 1"
        )),
        "{said:?}"
    );
    // 64 MiB read 8 KiB at a time: about 8,000 reads.
    assert!(file.calls < 10_000, "{} reads and seeks", file.calls);
}

/// A file of 4,396 bytes (a header of 300, and the offset table and 16 bytes a chunk of
/// the 256 ZIP blocks of 4096x4096 float RGB) passed the check of its chunks, and the
/// decoder reserved every pixel (400 MB) before it found the first chunk short. Each
/// compression's chunks must hold the fewest bytes it stores the pixels in
/// (`least_stored`); an HTJ2K file, which the decoder reads only as stored, all of them.
#[test]
fn chunks_must_hold_the_bytes_their_compression_stores_the_pixels_in() {
    let decoded = |compression| Decoded {
        data: Some([0, 0, 4095, 4095]),
        bytes_per_pixel: Some(12),
        compression: Some(compression),
        tiles: None,
    };
    let pixels: u64 = 4096 * 4096 * 12;
    let said = decoded(3).check(u64::MAX, 300, 300 + 256 * 16).unwrap_err();
    assert!(
        said.starts_with("is cut short: its header claims 256 chunks"),
        "{said}"
    );
    assert!(said.contains(&format!("at least {}", 300 + 256 * 16 + pixels / 1032)));
    let floor = 300 + 256 * 16 + pixels / 1032;
    decoded(3).check(u64::MAX, 300, floor).unwrap();
    assert!(decoded(3).check(u64::MAX, 300, floor - 1).is_err());
    // HTJ2K32: 128 chunks of 32 rows, each stored whole; one compressed is refused as
    // HTJ2K, not as cut short.
    let said = decoded(11)
        .check(u64::MAX, 300, 300 + 128 * 16)
        .unwrap_err();
    assert!(said.starts_with("is compressed with HTJ2K"), "{said}");
    decoded(11)
        .check(u64::MAX, 300, 300 + 128 * 16 + pixels)
        .unwrap();
    // RLE: one chunk a row.
    assert!(decoded(1).check(u64::MAX, 300, 300 + 4096 * 16).is_err());
    decoded(1)
        .check(u64::MAX, 300, 300 + 4096 * 16 + pixels / 64)
        .unwrap();
    // DWAB: no floor past 16 bytes a chunk.
    decoded(9).check(u64::MAX, 300, 300 + 16 * 16).unwrap();
}

/// A recipe attribute that does not read is refused by its name and what is wrong with it:
/// its type, or the byte at which its text stops being UTF-8.
#[test]
fn a_malformed_recipe_attribute_is_refused_by_its_name() {
    for (kind, value, said) in [
        (
            "string",
            b"{\xff}".to_vec(),
            "that is not UTF-8 text (a bad byte at 1 of its value)",
        ),
        ("int", vec![0; 4], "of type `int`, not `string`"),
    ] {
        let mut attributes = chunked(1, 1, 0, None);
        attributes.push((recipe::KEY, kind, value));
        let file = header_of(&attributes);
        let e = read(&file[..], file.len() as u64).err().unwrap_or_default();
        let named = format!("has a recipe attribute (`{}`) {said}", recipe::KEY);
        assert!(e.contains(&named), "{e}");
    }
}

/// Tiles of a side of 0 pixels, or past an `int`'s, were refused in the decoder's words
/// ("Format error decoding OpenExr: invalid: tile size"); they are refused by the
/// attribute, with the sizes it gives.
#[test]
fn tiles_of_no_pixels_or_past_an_int_are_refused_by_the_attribute() {
    for (w, h) in [(0, 16), (16, 0), (1 << 31, 16)] {
        let file = header_of(&chunked(4, 4, 0, Some((w, h, 0))));
        let e = read(&file[..], file.len() as u64).err().unwrap_or_default();
        let said = format!("has a tiles attribute of tiles of {w}x{h} pixels");
        assert!(e.starts_with(&said), "{e}");
        let e = display_changes(Cursor::new(&file), file.len() as u64, 1 << 20);
        assert!(e.unwrap_err().starts_with(&said));
        // The walk a texture is read through (`check_bounds`) refuses them alike.
        let e = check_bounds(&file[..], file.len() as u64, 1 << 20);
        assert!(e.as_ref().unwrap_err().starts_with(&said), "{e:?}");
    }
    let file = header_of(&chunked(4, 4, 0, Some((16, 16, 0))));
    assert!(read(&file[..], file.len() as u64).is_ok());
}

/// Counts of one were said as many ("its header claims 1 chunks", "its attribute name needs
/// 1 bytes, 0 are left"); they are said in the singular.
#[test]
fn counts_of_one_are_said_in_the_singular() {
    let file = header_of(&chunked(4, 1, 0, None));
    let e = check_bounds(&file[..], file.len() as u64, 1 << 20).unwrap_err();
    assert!(
        e.starts_with("is cut short: its header claims 1 chunk (blocks"),
        "{e}"
    );
    // Cut within the end of the attribute names.
    let e = read(&file[..file.len() - 1], file.len() as u64 - 1).unwrap_err();
    assert_eq!(
        e,
        "is truncated: its attribute name needs 1 byte, and the file has 0 bytes left"
    );
    let e = box2i(&[0], "dataWindow").unwrap_err();
    assert_eq!(e, "has a dataWindow of 1 byte, not 16");
}

/// An offset table entry that points into the header or the table, past the file's end,
/// or to a chunk whose data runs past it, or is of a length below zero, reached the decoder,
/// which said "invalid: scan line block sample count" or "reference to missing bytes"; each
/// is refused naming the entry and the byte it points to.
#[test]
fn an_offset_table_entry_where_no_chunk_can_be_is_refused_by_its_entry() {
    // Three rows of one pixel, uncompressed: a chunk a row of 12 bytes of data.
    let header = header_of(&chunked(1, 3, 0, None));
    let table_end = header.len() as u64 + 24;
    let file = |offsets: [u64; 3], last_len: i32| {
        let mut file = header.clone();
        file.extend(offsets.iter().flat_map(|o| o.to_le_bytes()));
        for y in 0..3i32 {
            file.extend(y.to_le_bytes());
            file.extend(if y == 2 { last_len } else { 6 }.to_le_bytes());
            file.extend([0; 6]);
        }
        file
    };
    let placed = [table_end, table_end + 14, table_end + 28];
    let layout = ExrLayout {
        header_len: header.len() as u64,
        tiles: None,
        levels: false,
        compression: Some(0),
        top: 0,
    };
    let judged =
        |offsets, last_len| misplaced_chunk(Cursor::new(file(offsets, last_len)), 1, 3, &layout);
    assert_eq!(judged(placed, 6), Ok(None));
    let e = judged([20, placed[1], placed[2]], 6).unwrap_err();
    let within = format!(
        "has an offset table whose entry 0 points to byte 20, within its header and offset \
         table (its first {table_end} bytes)"
    );
    assert!(e.starts_with(&within), "{e}");
    let e = judged([placed[0], 1 << 30, placed[2]], 6).unwrap_err();
    assert!(
        e.starts_with(
            "has an offset table whose entry 1 points to byte 1073741824, past the file's end"
        ),
        "{e}"
    );
    let e = judged(placed, 1000).unwrap_err();
    let past = format!(
        "entry 2 points to a chunk at byte {} that runs past the file's end ({} bytes): its \
         data claims 1000 bytes",
        placed[2],
        table_end + 42
    );
    assert!(e.ends_with(&past), "{e}");
    let e = judged(placed, -5).unwrap_err();
    assert!(
        e.ends_with("whose data's length is -5 bytes, below zero"),
        "{e}"
    );
}

/// A lineOrder past 2 or a compression past HTJ2K32 was refused in the decoder's words
/// ("invalid: line order attribute value", "not supported: unknown compression method"),
/// and `info`, which decodes no pixels, showed the file as sound. Each is refused by its
/// attribute, by every walk of the header; the values OpenEXR defines are read.
#[test]
fn a_line_order_or_compression_openexr_does_not_define_is_refused_by_its_attribute() {
    let with = |name, kind, value: u8| {
        let mut attributes = chunked(4, 4, 0, None);
        attributes.retain(|(n, _, _)| *n != name);
        attributes.push((name, kind, vec![value]));
        header_of(&attributes)
    };
    for (name, value, said) in [
        (
            "lineOrder",
            3,
            "has a lineOrder attribute of 3: OpenEXR defines 0 (increasing y)",
        ),
        ("lineOrder", 255, "has a lineOrder attribute of 255"),
        (
            "compression",
            12,
            "has a compression attribute of 12: OpenEXR defines 0 (none) to 11",
        ),
        ("compression", 255, "has a compression attribute of 255"),
    ] {
        let file = with(name, name, value);
        let e = read(&file[..], file.len() as u64).unwrap_err();
        assert!(e.starts_with(said), "{e}");
        let e = display_changes(Cursor::new(&file), file.len() as u64, 1 << 20).unwrap_err();
        assert!(e.starts_with(said), "{e}");
        let e = check_bounds(&file[..], file.len() as u64, 1 << 20).unwrap_err();
        assert!(e.starts_with(said), "{e}");
    }
    for (name, value) in [("lineOrder", 2), ("compression", 11)] {
        let file = with(name, name, value);
        assert!(read(&file[..], file.len() as u64).is_ok(), "{name} {value}");
    }
}

/// A chunk that says it holds scan lines outside the data window, or from a row where no
/// block of its compression begins, is none of the image's: the decoder refused it in its
/// own words ("invalid: tile index"). It is refused by its entry; one that says it is
/// another block of the image is what changes how the file is shown, as before.
#[test]
fn a_chunk_of_none_of_the_image_s_scan_lines_is_refused_by_its_entry() {
    // ZIP: blocks of 16 scan lines, 40 rows from row 100: blocks from 100, 116 and 132.
    let header = header_of(&chunked(1, 40, 3, None));
    let table_end = header.len() as u64 + 24;
    let file = |firsts: [i32; 3]| {
        let mut file = header.clone();
        file.extend((0..3).flat_map(|i| (table_end + 8 * i).to_le_bytes()));
        file.extend(
            firsts
                .iter()
                .flat_map(|y| [y.to_le_bytes(), [0; 4]].concat()),
        );
        file
    };
    let layout = ExrLayout {
        header_len: header.len() as u64,
        tiles: None,
        levels: false,
        compression: Some(3),
        top: 100,
    };
    let judged = |firsts| misplaced_chunk(Cursor::new(file(firsts)), 1, 40, &layout);
    assert_eq!(judged([100, 116, 132]), Ok(None));
    let swapped = judged([116, 100, 132]).unwrap().unwrap();
    assert!(swapped.starts_with("entry 0 of its offset table, for the scan lines from 100"));
    let at = |i: u64| table_end + 8 * i;
    for (firsts, said) in [
        (
            [100, 116, 148],
            format!(
                "entry 2 points to a chunk at byte {} of the scan lines from 148, outside the \
                 data window's rows (100 to 139)",
                at(2)
            ),
        ),
        (
            [99, 116, 132],
            format!(
                "entry 0 points to a chunk at byte {} of the scan lines from 99",
                at(0)
            ),
        ),
        (
            [100, 117, 132],
            format!(
                "entry 1 points to a chunk at byte {} of the scan lines from 117, where no \
                 block begins (its compression stores 16 scan lines from row 100 on)",
                at(1)
            ),
        ),
    ] {
        let e = judged(firsts).unwrap_err();
        assert!(e.ends_with(&said) || e.contains(&said), "{e}");
    }
}
