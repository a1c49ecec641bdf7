//! The tests of `png_header`: chunks built here, walked, bounded and refused.

use super::*;
use std::io::{Cursor, SeekFrom};

/// A file of `len` bytes, zero but where `written` says, that counts the bytes read from
/// it: a sparse file, without the disk.
struct Sparse {
    written: Vec<(u64, Vec<u8>)>,
    len: u64,
    at: u64,
    read: u64,
}

impl Read for Sparse {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = (buf.len() as u64).min(self.len.saturating_sub(self.at)) as usize;
        buf[..n].fill(0);
        for (start, bytes) in &self.written {
            for (i, b) in bytes.iter().enumerate() {
                let p = start + i as u64;
                if p >= self.at && p < self.at + n as u64 {
                    buf[(p - self.at) as usize] = *b;
                }
            }
        }
        self.at += n as u64;
        self.read += n as u64;
        Ok(n)
    }
}

impl Seek for Sparse {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.at = match to {
            SeekFrom::Start(n) => n,
            SeekFrom::Current(d) => self.at.checked_add_signed(d).expect("in the file"),
            SeekFrom::End(d) => self.len.checked_add_signed(d).expect("in the file"),
        };
        Ok(self.at)
    }
}

fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut c = (data.len() as u32).to_be_bytes().to_vec();
    c.extend(kind);
    c.extend(data);
    c.extend(crc32fast::hash(&c[4..]).to_be_bytes());
    c
}

/// Text chunks that are not the recipe are skipped past their keyword, unread, as every
/// other chunk is: 4,096 of 1 MiB once read 4 GiB (and 65,536 of them 64 GiB, minutes).
#[test]
fn text_chunks_other_than_the_recipe_are_skipped_unread() {
    let mut written = vec![(0, PNG_SIGNATURE.to_vec())];
    let mut at = 8u64;
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    written.push((at, ihdr.clone()));
    at += ihdr.len() as u64;
    let length = MAX_BYTES as u64 + 1024;
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(b"iTXt");
    hasher.update(b"comment");
    hasher.update(&vec![0u8; length as usize - 7]);
    let crc = hasher.finalize().to_be_bytes();
    for _ in 0..4096 {
        let mut head = (length as u32).to_be_bytes().to_vec();
        head.extend(b"iTXtcomment");
        written.push((at, head));
        written.push((at + 8 + length, crc.to_vec()));
        at += 12 + length;
    }
    let end = chunk(b"IEND", &[]);
    written.push((at, end.clone()));
    at += end.len() as u64;
    let mut file = Sparse {
        written,
        len: at,
        at: 0,
        read: 0,
    };
    let header = read(&mut file, at).unwrap();
    assert_eq!((header.width, header.height, header.recipe), (4, 2, None));
    // What a buffered reader reads ahead of each chunk's head, not the chunks.
    assert!(file.read < 4096 * 16 * 1024, "{} bytes read", file.read);
    // The recipe's chunk is read whole, and its CRC checked.
    let mut recipe = format!("{KEY}\0\0\0\0\0").into_bytes();
    recipe.extend(b"{}");
    let png = [&PNG_SIGNATURE[..], &ihdr, &chunk(b"iTXt", &recipe), &end].concat();
    let header = read(Cursor::new(&png), png.len() as u64).unwrap();
    assert_eq!(header.recipe.as_deref(), Some("{}"));
    let mut damaged = png.clone();
    damaged[33 + 8 + recipe.len() - 1] ^= 1;
    let e = read(Cursor::new(&damaged), png.len() as u64).unwrap_err();
    assert!(e.contains("bad CRC"), "{e}");
}

/// A PLTE chunk whose length is not whole entries of three bytes: libpng refuses the
/// file, and the PNG decoder indexed past the chunk's end expanding a palette image's
/// pixels (`compare` of a 2x2 image with a palette of 4 bytes exited 101, "range end
/// index 3 out of range for slice of length 1"). It is refused, naming the chunk.
#[test]
fn a_palette_of_a_partial_entry_is_refused() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 2, 0, 0, 0, 2, 8, 3, 0, 0, 0]);
    let pixels = chunk(b"IDAT", &fdeflate::compress_to_vec(&[0; 6]));
    let end = chunk(b"IEND", &[]);
    let with_palette = |bytes: usize| {
        let plte = chunk(b"PLTE", &vec![255; bytes]);
        let png = [&PNG_SIGNATURE[..], &ihdr, &plte, &pixels, &end].concat();
        read(Cursor::new(&png), png.len() as u64)
    };
    for bytes in [4, 5, 7, 767] {
        let e = with_palette(bytes).unwrap_err();
        assert!(
            e.contains(&format!("a PLTE chunk of {bytes} bytes at byte 33")),
            "{e}"
        );
    }
    for bytes in [3, 6, 768] {
        assert!(with_palette(bytes).is_ok(), "{bytes}");
    }
}

/// A chunk whose type is not four letters (a control character, a digit, a byte past
/// ASCII): the PNG decoder skips it, libpng refuses the file ("invalid chunk type"), so
/// it is listed as changing how the picture is shown; a chunk of letters unknown to both
/// is not.
#[test]
fn a_chunk_whose_type_is_not_four_letters_is_listed() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let end = chunk(b"IEND", &[]);
    let listed = |kind: &[u8; 4]| {
        let png = [&PNG_SIGNATURE[..], &ihdr, &chunk(kind, b"xx"), &end].concat();
        read(Cursor::new(&png), png.len() as u64)
            .unwrap()
            .display_changes
    };
    for (kind, shown) in [
        (b"a\x01bc", "`a\\u{1}bc`"),
        (b"ab1d", "`ab1d`"),
        (b"ab\xffd", "`ab\u{fffd}d`"),
    ] {
        let said = listed(kind);
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].contains(shown), "{said:?}");
        assert!(said[0].contains("libpng refuses the file"), "{said:?}");
    }
    assert!(listed(b"abCd").is_empty());
}

/// A tRNS chunk of a length other than its colour type's: libpng ignores it (a benign
/// error, "invalid"), the PNG decoder here takes its first bytes where it is longer. A
/// greyscale image's of 4 bytes was listed only as "transparency", the same words as a
/// tRNS every viewer shows, where viewers built on libpng show the picture opaque and the
/// decoder here measured it beside an alpha channel. The disagreement is listed, and so is
/// a tRNS both ignore (shorter, or in an image of an alpha channel), in words of its own.
#[test]
fn a_trns_chunk_of_a_length_libpng_ignores_is_listed_as_such() {
    let listed = |color: u8, plte: &[u8], trns: &[u8]| {
        let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, color, 0, 0, 0]);
        let plte = if plte.is_empty() {
            Vec::new()
        } else {
            chunk(b"PLTE", plte)
        };
        let png = [
            &PNG_SIGNATURE[..],
            &ihdr,
            &plte,
            &chunk(b"tRNS", trns),
            &chunk(b"IEND", &[]),
        ]
        .concat();
        read(Cursor::new(&png), png.len() as u64)
            .unwrap()
            .display_changes
    };
    let has = |said: &[String], words: &str| said.iter().any(|c| c.contains(words));
    // Of the length libpng reads: transparency alone.
    for (color, plte, trns) in [
        (0, &[][..], &[0, 9][..]),
        (2, &[], &[0; 6]),
        (3, &[0; 6], &[0]),
    ] {
        let said = listed(color, plte, trns);
        assert_eq!(said.len(), 1, "{said:?}");
    }
    let said = listed(0, &[], &[0, 9, 0, 0]);
    assert!(
        has(
            &said,
            "a tRNS chunk of 4 bytes, where a greyscale image's holds 2"
        ) && has(&said, "libpng ignores it")
            && has(&said, "the decoder here takes its first 2 bytes"),
        "{said:?}"
    );
    let said = listed(2, &[], &[0; 8]);
    assert!(has(&said, "where an RGB image's holds 6"), "{said:?}");
    let said = listed(2, &[], &[0; 3]);
    assert!(
        has(&said, "where an RGB image's holds 6")
            && has(&said, "libpng and the decoder here ignore it"),
        "{said:?}"
    );
    // A palette's: at most its entries.
    let said = listed(3, &[0; 6], &[0; 3]);
    assert!(
        has(
            &said,
            "a tRNS chunk of 3 entries, more than the 2 of its palette"
        ),
        "{said:?}"
    );
    let said = listed(6, &[], &[0; 6]);
    assert!(has(&said, "in an image of an alpha channel"), "{said:?}");
}

/// A recipe in a tEXt or zTXt chunk beside the iTXt one checked: Python's PIL showed the
/// last of them (another scene) for an image `reproduce` called identical.
#[test]
fn a_recipe_in_a_text_chunk_tessera_does_not_write_is_refused() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let mut itxt = format!("{KEY}\0\0\0\0\0").into_bytes();
    itxt.extend(b"{}");
    let end = chunk(b"IEND", &[]);
    for kind in [b"tEXt", b"zTXt"] {
        let other = chunk(kind, format!("{KEY}\0{{\"other\": 1}}").as_bytes());
        let png = [
            &PNG_SIGNATURE[..],
            &ihdr,
            &chunk(b"iTXt", &itxt),
            &other,
            &end,
        ]
        .concat();
        let e = read(Cursor::new(&png), png.len() as u64).unwrap_err();
        assert!(e.contains("has a recipe in a"), "{e}");
        // Another keyword, or one that only begins as tessera's, is text like any other.
        for keyword in ["Comment", "tessera-recipes"] {
            let text = chunk(kind, format!("{keyword}\0x").as_bytes());
            let png = [&PNG_SIGNATURE[..], &ihdr, &text, &end].concat();
            assert!(read(Cursor::new(&png), png.len() as u64).is_ok());
        }
    }
}

/// A text chunk whose keyword is tessera's but for its first letter's case or for
/// characters that are not a tag name's (`Tessera-recipe`, `tessera-recipe!`,
/// `tessera-recipe `): exiftool drops those characters and capitalises the first letter,
/// so it named the chunk as it names the recipe's and showed the later of them, another
/// scene, for an image `reproduce` called identical. One exiftool names apart
/// (`TESSERA-RECIPE`) is text like any other.
#[test]
fn a_text_chunk_exiftool_takes_for_the_recipe_is_refused() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let mut itxt = format!("{KEY}\0\0\0\0\0").into_bytes();
    itxt.extend(b"{}");
    let end = chunk(b"IEND", &[]);
    let with = |kind: &[u8; 4], keyword: &[u8]| {
        let mut data = keyword.to_vec();
        data.extend(if kind == b"iTXt" {
            &b"\0\0\0\0\0{}"[..]
        } else {
            b"\0{}"
        });
        let png = [
            &PNG_SIGNATURE[..],
            &ihdr,
            &chunk(b"iTXt", &itxt),
            &chunk(kind, &data),
            &end,
        ]
        .concat();
        read(Cursor::new(&png), png.len() as u64)
    };
    for kind in [b"tEXt", b"zTXt", b"iTXt"] {
        for keyword in [
            &b"Tessera-recipe"[..],
            b"tessera-recipe!",
            b"tessera-recipe ",
            b" tessera-recipe",
            b"tessera -recipe",
            b"\xa0tessera\x01-recipe\xff",
            b"\ttessera-\x01 !recipe\n",
        ] {
            let e = with(kind, keyword).unwrap_err();
            assert!(e.contains("takes for tessera's"), "{e}");
            assert!(e.contains("in place of the one checked"), "{e}");
        }
        // A keyword exiftool names otherwise is text like any other.
        for keyword in [
            &b"Comment"[..],
            b"tessera_recipe",
            b"tessera-recipes",
            b"-tessera-recipe",
            b"tessera-recip",
            // exiftool keeps the case of the letters after the first (`TESSERA-RECIPE`
            // was once refused, though exiftool names it apart), and capitalises one
            // after white space (`tessera-Recipe`).
            b"TESSERA-RECIPE",
            b"tESSERA-RECIPE",
            b"tessera- recipe",
            b"tessera-\nrecipe",
        ] {
            let header = with(kind, keyword).unwrap();
            assert_eq!(header.recipe.as_deref(), Some("{}"));
        }
    }
    // A keyword past the 79 bytes PNG allows, of characters exiftool drops, is refused
    // once read so far; one of other letters is told apart at its first.
    let mut long = vec![b'!'; 2000];
    long.extend(KEY.as_bytes());
    assert!(with(b"tEXt", &long).is_err());
    assert!(with(b"tEXt", &[b'x'; 2000]).is_ok());
}

/// A recipe in a text chunk after the IEND chunk, where a PNG ends and no decoder
/// reads: exiftool walks the chunks there too, and showed that one, another scene, in
/// place of the one checked, for an image `reproduce` called identical. Other bytes
/// there are let be.
#[test]
fn a_recipe_after_the_iend_chunk_is_refused() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let mut itxt = format!("{KEY}\0\0\0\0\0").into_bytes();
    itxt.extend(b"{}");
    let end = chunk(b"IEND", &[]);
    let followed_by = |trailer: &[u8]| {
        let png = [
            &PNG_SIGNATURE[..],
            &ihdr,
            &chunk(b"iTXt", &itxt),
            &end,
            trailer,
        ]
        .concat();
        read(Cursor::new(&png), png.len() as u64)
    };
    let comment = chunk(b"tEXt", b"Comment\0x");
    for trailer in [
        chunk(b"iTXt", &itxt),
        chunk(b"tEXt", format!("{KEY}\0{{}}").as_bytes()),
        chunk(b"zTXt", b"Tessera-recipe\0\0x"),
        // After another chunk, and after a second IEND.
        [
            &comment[..],
            &end,
            &chunk(b"tEXt", format!("{KEY}\0x").as_bytes()),
        ]
        .concat(),
    ] {
        let e = followed_by(&trailer).unwrap_err();
        assert!(e.contains("after its IEND chunk"), "{e}");
    }
    for trailer in [
        comment.clone(),
        b"PK\x03\x04 any bytes".to_vec(),
        // A chunk that does not fit in the file ends the walk, as it ends exiftool's.
        [
            &comment[..],
            &chunk(b"tEXt", format!("{KEY}\0x").as_bytes())[..20],
        ]
        .concat(),
    ] {
        let header = followed_by(&trailer).unwrap();
        assert_eq!(header.recipe.as_deref(), Some("{}"));
    }
}

/// The zlib stream's header is taken from the first IDAT chunk only: where that chunk
/// holds less than both bytes, none is taken (two bytes of the stream's middle, in the
/// next chunk, once stood for it).
#[test]
fn the_zlib_header_is_the_first_idat_chunk_s_start() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let end = chunk(b"IEND", &[]);
    let header_of = |idats: &[&[u8]]| {
        let mut png = [&PNG_SIGNATURE[..], &ihdr].concat();
        for data in idats {
            png.extend(chunk(b"IDAT", data));
        }
        png.extend(&end);
        read(Cursor::new(&png), png.len() as u64)
            .unwrap()
            .zlib_header
    };
    assert_eq!(header_of(&[&[0x78, 0x9c, 1], &[2, 3]]), Some([0x78, 0x9c]));
    assert_eq!(header_of(&[&[0x08], &[0x78, 0x9c, 1]]), None);
    assert_eq!(header_of(&[&[], &[0x78, 0x9c, 1]]), None);
    assert_eq!(header_of(&[]), None);
}

/// What a 4x2 PNG whose pixels (one IDAT chunk) are followed by the bytes `after`, then
/// its IEND, holds that changes how it is shown.
fn changes_with_after_the_pixels(after: &[u8]) -> Vec<String> {
    let png = [
        &PNG_SIGNATURE[..],
        &chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]),
        &chunk(b"IDAT", &[0x78, 0x9c, 1]),
        after,
        &chunk(b"IEND", &[]),
    ]
    .concat();
    read(Cursor::new(&png), png.len() as u64)
        .unwrap()
        .display_changes
}

/// A critical chunk after the pixels (a palette, or one libpng does not know) makes
/// libpng refuse the file, where the decoder here stops at the last row: it was called
/// identical. It is listed; an ancillary one there is not.
#[test]
fn a_critical_chunk_after_the_pixels_is_listed() {
    let changes_with = changes_with_after_the_pixels;
    for kind in [b"PLTE", b"ABCD"] {
        let changes = changes_with(&chunk(kind, &[0; 3]));
        assert!(
            changes.len() == 1 && changes[0].contains("chunk after the pixels, a critical"),
            "{changes:?}"
        );
    }
    assert!(changes_with(&chunk(b"abCD", &[0; 3])).is_empty());
    assert!(changes_with(&chunk(b"IDAT", &[0; 3])).is_empty());
    assert!(changes_with(&[]).is_empty());
}

/// An IDAT chunk after another chunk that follows the pixels (a second run of them):
/// the decoder here stops after the first, libpng reads it at the end and refuses the
/// file where its CRC is wrong. Such a file, its late IDAT's CRC wrong, was called
/// identical. It is listed, once for each; IDAT chunks of one run are not.
#[test]
fn an_idat_chunk_after_the_pixels_run_is_listed() {
    let changes_with = changes_with_after_the_pixels;
    let mut damaged = chunk(b"IDAT", &[]);
    damaged[11] ^= 1;
    let text = chunk(b"tEXt", b"Comment\0x");
    let changes = changes_with(&[&text[..], &damaged].concat());
    assert!(
        changes.len() == 1 && changes[0].starts_with("an IDAT chunk at byte 69 after"),
        "{changes:?}"
    );
    let changes = changes_with(&[&text[..], &damaged, &damaged].concat());
    assert_eq!(changes.len(), 2, "{changes:?}");
    let idat = chunk(b"IDAT", &[0x78, 0x9c, 1]);
    assert!(changes_with(&[&idat[..], &text].concat()).is_empty());
}

/// An IEND chunk whose CRC is wrong: libpng refuses the file at its end ("IEND: CRC
/// error"), where the decoder here never reads it, and `compare` and `reproduce` called
/// such a file identical to tessera's own. It is listed, and so is an IEND that holds
/// data; a second IEND after the end, which no decoder reads, is not.
#[test]
fn an_iend_chunk_of_a_wrong_crc_is_listed() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let idat = chunk(b"IDAT", &[0x78, 0x9c, 1]);
    let changes_with = |end: &[u8]| {
        let png = [&PNG_SIGNATURE[..], &ihdr, &idat, end].concat();
        read(Cursor::new(&png), png.len() as u64)
            .unwrap()
            .display_changes
    };
    let mut damaged = chunk(b"IEND", &[]);
    damaged[11] ^= 1;
    let changes = changes_with(&damaged);
    assert!(
        changes.len() == 1 && changes[0].contains("IEND chunk at byte 48 whose CRC is wrong"),
        "{changes:?}"
    );
    let changes = changes_with(&chunk(b"IEND", b"xy"));
    assert!(
        changes.len() == 1 && changes[0].contains("IEND chunk at byte 48 of 2 bytes"),
        "{changes:?}"
    );
    assert!(changes_with(&chunk(b"IEND", &[])).is_empty());
    assert!(changes_with(&[&chunk(b"IEND", &[])[..], &damaged].concat()).is_empty());
}

/// EXIF in a chunk exiftool reads as eXIf though its name is not (`exIf`, `EXIF`, a
/// `zxIf` of compressed EXIF): exiftool shows its orientation, which turns or flips the
/// picture, and such a file was called identical. It is listed; eXIf is listed as before,
/// and a chunk of another name is not.
#[test]
fn exif_in_a_chunk_exiftool_reads_as_exif_is_listed() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let changes_with = |kind: &[u8; 4]| {
        let png = [
            &PNG_SIGNATURE[..],
            &ihdr,
            &chunk(kind, b"MM\0\x2a\0\0\0\x08"),
            &chunk(b"IDAT", &[0x78, 0x9c, 1]),
            &chunk(b"IEND", &[]),
        ]
        .concat();
        read(Cursor::new(&png), png.len() as u64)
            .unwrap()
            .display_changes
    };
    for kind in [b"exIf", b"eXIf", b"zxIf", b"zXIf"] {
        let changes = changes_with(kind);
        assert!(
            changes.len() == 1 && changes[0].contains("turn or flip the picture"),
            "{changes:?}"
        );
    }
    assert!(changes_with(b"exIg").is_empty());
}

/// A chunk named in a message takes the article its name is said with: "a exIf chunk"
/// and "a iCCP chunk" were written, where the project writes "an IDAT chunk".
#[test]
fn a_chunk_is_named_with_its_article() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let changes_with = |kind: &[u8; 4]| {
        let png = [
            &PNG_SIGNATURE[..],
            &ihdr,
            &chunk(kind, b"MM\0\x2a\0\0\0\x08"),
            &chunk(b"IDAT", &[0x78, 0x9c, 1]),
            &chunk(b"IEND", &[]),
        ]
        .concat();
        read(Cursor::new(&png), png.len() as u64)
            .unwrap()
            .display_changes
    };
    for (kind, said) in [
        (b"exIf", "an exIf chunk,"),
        (b"eXIf", "an eXIf chunk,"),
        (b"iCCP", "an iCCP chunk,"),
        (b"acTL", "an acTL chunk,"),
        (b"iDOT", "an iDOT chunk,"),
        (b"tRNS", "a tRNS chunk,"),
        (b"zxIf", "a zxIf chunk,"),
    ] {
        let changes = changes_with(kind);
        assert!(changes[0].starts_with(said), "{changes:?}");
    }
    assert_eq!(a_chunk(b"uNKN"), "a uNKN chunk");
    assert_eq!(a_chunk(b"O\x1b[m"), "an O\\u{1b}[m chunk");
}

/// A palette PNG whose pixels are interlaced: its rows come pass by pass, each of its
/// pass's pixels only, and indexing one as a row of the whole width panicked (`compare`
/// of a 16x1 one exited 101, "index out of bounds: the len is 2 but the index is 2").
/// An index past the palette is found where it lies in the picture.
#[test]
fn an_interlaced_palette_png_is_walked_pass_by_pass() {
    // 16x1: passes 1, 2, 4 and 6 hold 2, 2, 4 and 8 pixels of the row, at x = 0 and 8,
    // 4 and 12, 2 + 4k, 1 + 2k.
    let interlaced = |rows: &[&[u8]], entries: usize| {
        let ihdr = chunk(b"IHDR", &[0, 0, 0, 16, 0, 0, 0, 1, 8, 3, 0, 0, 1]);
        let mut raw = Vec::new();
        for row in rows {
            raw.push(0);
            raw.extend(*row);
        }
        let png = [
            &PNG_SIGNATURE[..],
            &ihdr,
            &chunk(b"PLTE", &vec![255; 3 * entries]),
            &chunk(b"IDAT", &fdeflate::compress_to_vec(&raw)),
            &chunk(b"IEND", &[]),
        ]
        .concat();
        palette_index_past_its_entries(Cursor::new(png), 1 << 20)
    };
    assert_eq!(interlaced(&[&[0; 2], &[0; 2], &[0; 4], &[0; 8]], 1), None);
    let past = interlaced(&[&[0; 2], &[0; 2], &[0; 4], &[0, 0, 0, 1, 0, 0, 0, 0]], 1);
    assert!(
        past.as_deref()
            .is_some_and(|p| p.starts_with("a pixel (7, 0) of palette index 1")),
        "{past:?}"
    );
}

/// A stream that ends, checksum and all, before the rows its IHDR chunk claims is refused
/// before the decoder is handed room for them: a file of 65 bytes claiming 4096x4096 16-bit
/// RGBA pixels once had 137 MB filled for them in `compare` before the decoder found its
/// one empty stream short. A stream of every row, interlaced or not, of whole bytes or not,
/// is not.
#[test]
fn a_stream_shorter_than_the_rows_it_claims_is_refused() {
    let png = |ihdr: &[u8], raw: &[u8]| {
        [
            &PNG_SIGNATURE[..],
            &chunk(b"IHDR", ihdr),
            &chunk(b"IDAT", &fdeflate::compress_to_vec(raw)),
            &chunk(b"IEND", &[]),
        ]
        .concat()
    };
    let ends = |bytes: Vec<u8>| check_zlib_stream_ends(Cursor::new(bytes), 1 << 30);
    let huge = [0, 0, 16, 0, 0, 0, 16, 0, 16, 6, 0, 0, 0];
    let e = ends(png(&huge, &[])).unwrap_err();
    assert!(
        e.starts_with("a zlib stream that inflates to 0 bytes, fewer than the 134221824 its"),
        "{e}"
    );
    // 9x2 pixels of one bit: two rows of a filter byte and two bytes.
    let bits = [0, 0, 0, 9, 0, 0, 0, 2, 1, 0, 0, 0, 0];
    assert_eq!(ends(png(&bits, &[0; 6])), Ok(6));
    assert!(ends(png(&bits, &[0; 5])).is_err());
    // 16x1 interlaced, one byte a pixel: passes 1, 2, 4 and 6 hold 2, 2, 4 and 8 pixels.
    let interlaced = [0, 0, 0, 16, 0, 0, 0, 1, 8, 0, 0, 0, 1];
    assert_eq!(ends(png(&interlaced, &[0; 20])), Ok(20));
    assert!(ends(png(&interlaced, &[0; 19])).is_err());
}

/// A recipe chunk that does not read is refused by the field that is wrong, at the chunk's
/// byte: its compression flag or method, the zero bytes ending its language tag and
/// translated keyword, a text that does not inflate or is not UTF-8. Each was once "has a
/// malformed recipe chunk", or a reason that named no chunk.
#[test]
fn a_malformed_recipe_chunk_is_refused_by_its_field() {
    let ihdr = chunk(b"IHDR", &[0, 0, 0, 4, 0, 0, 0, 2, 8, 2, 0, 0, 0]);
    let end = chunk(b"IEND", &[]);
    let refused = |after_key: &[u8]| {
        let itxt = [format!("{KEY}\0").as_bytes(), after_key].concat();
        let png = [&PNG_SIGNATURE[..], &ihdr, &chunk(b"iTXt", &itxt), &end].concat();
        read(Cursor::new(&png), png.len() as u64).unwrap_err()
    };
    let chunk_at = format!("recipe chunk (iTXt '{KEY}' at byte 33)");
    for (after_key, field) in [
        (
            &b"\x02\0\0\0{}"[..],
            "compression flag 2: 0 (none) or 1 (zlib)",
        ),
        (b"\x01\x05\0\0x", "compression method 5: 0 (zlib)"),
        (b"", "no compression flag"),
        (b"\0", "no compression method"),
        (b"\0\0en", "no zero byte after its language tag"),
        (b"\0\0en\0x", "no zero byte after its translated keyword"),
        (
            b"\x01\0\0\0\x78\x9c\xff",
            "compressed text that does not inflate",
        ),
        (
            b"\0\0\0\0{\xff}",
            "text that is not UTF-8 (a bad byte at 1 of its text)",
        ),
    ] {
        let e = refused(after_key);
        assert!(e.contains(&chunk_at), "{e}");
        assert!(e.contains(field), "{field}: {e}");
    }
}
