//! What a stranger makes, handed to tessera as an attacker would: EXR files of several parts,
//! other channels or half a million attributes; PNGs of a million chunks, or with chunks that
//! change what a viewer shows; recipes whose text carries terminal escapes or asks for days
//! of work; pipes and devices named as files; a symbolic link planted where tessera writes
//! its temporary file. Each is refused (exit 2) or judged (exit 1) with the reason, within
//! bounded memory, and leaves every file that is not tessera's own output as it was.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// A small figure rendered to `name` (PNG or EXR, by its extension) in `dir`.
fn rendered(dir: &Path, name: &str) -> PathBuf {
    ok(
        &[
            "render",
            scene_path("img-1.12-metal-fuzz.toml").to_str().unwrap(),
            "--width",
            "32",
            "--spp",
            "2",
            "-q",
            "-o",
            name,
        ],
        dir,
    );
    dir.join(name)
}

/// `tessera ARGS` in `dir` with its address space capped at `mib` MiB (`ulimit -v`): an
/// allocation of what a file merely claims fails there instead of succeeding on a large
/// machine.
fn run_capped(args: &[&str], dir: &Path, mib: u64) -> Output {
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {}; exec '{}' {}",
            mib << 10,
            env!("CARGO_BIN_EXE_tessera"),
            quoted.join(" ")
        ))
        .current_dir(dir)
        .env("TESSERA_DB", test_results_db())
        .output()
        .unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Asserts that `o` is a refusal (exit 2) whose message says `why`.
fn refused(o: &Output, why: &str, what: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{what}: {err}{}", stdout(o));
    assert!(err.contains(why), "{what}: expected {why:?} in: {err}");
}

// --- EXR ------------------------------------------------------------------------------------

/// An EXR header attribute: its name, its value's offset and its size.
type ExrAttribute<'a> = (&'a [u8], usize, usize);

/// The EXR header's attributes, and the end of the header (after its closing zero byte).
fn exr_walk(bytes: &[u8]) -> (Vec<ExrAttribute<'_>>, usize) {
    let mut attributes = Vec::new();
    let mut at = 8;
    while bytes[at] != 0 {
        let end = at + bytes[at..].iter().position(|&b| b == 0).unwrap();
        let kind_end = end + 1 + bytes[end + 1..].iter().position(|&b| b == 0).unwrap();
        let size = u32::from_le_bytes(bytes[kind_end + 1..kind_end + 5].try_into().unwrap());
        let value = kind_end + 5;
        attributes.push((&bytes[at..end], value, size as usize));
        at = value + size as usize;
    }
    (attributes, at + 1)
}

/// The byte offset and length of the value of the EXR header attribute `name`.
fn exr_attribute(bytes: &[u8], name: &str) -> (usize, usize) {
    let (attributes, _) = exr_walk(bytes);
    let found = attributes.iter().find(|(n, _, _)| *n == name.as_bytes());
    let &(_, value, size) = found.unwrap_or_else(|| panic!("no attribute {name}"));
    (value, size)
}

/// The end of the EXR header (after its closing zero byte).
fn exr_header_end(bytes: &[u8]) -> usize {
    exr_walk(bytes).1
}

/// One EXR header attribute's bytes.
fn exr_attr(name: &str, kind: &str, value: &[u8]) -> Vec<u8> {
    let mut a = Vec::new();
    a.extend_from_slice(name.as_bytes());
    a.push(0);
    a.extend_from_slice(kind.as_bytes());
    a.push(0);
    a.extend_from_slice(&(value.len() as u32).to_le_bytes());
    a.extend_from_slice(value);
    a
}

/// `exr` with `extra` inserted at the end of its header, and its chunk offsets moved on by
/// as much, so that the file stays a valid EXR.
fn exr_with_attributes(exr: &[u8], extra: &[u8]) -> Vec<u8> {
    let end = exr_header_end(exr) - 1;
    let (count_at, _) = exr_attribute(exr, "chunkCount");
    let chunks = u32::from_le_bytes(exr[count_at..count_at + 4].try_into().unwrap()) as usize;
    let mut out = exr[..end].to_vec();
    out.extend_from_slice(extra);
    out.push(0);
    for i in 0..chunks {
        let at = end + 1 + 8 * i;
        let offset = u64::from_le_bytes(exr[at..at + 8].try_into().unwrap());
        out.extend_from_slice(&(offset + extra.len() as u64).to_le_bytes());
    }
    out.extend_from_slice(&exr[end + 1 + 8 * chunks..]);
    out
}

/// Writes `bytes` as `file` in `dir`, beside tessera's own `a.exr`: `reproduce` says the file
/// differs (exit 1) and `compare` does not call it identical, each naming `why`.
fn differs_naming(dir: &Path, file: &str, bytes: &[u8], why: &str) {
    std::fs::write(dir.join(file), bytes).unwrap();
    let o = run(&["reproduce", file, "-q"], dir);
    assert_eq!(o.status.code(), Some(1), "{file}: {}", stderr(&o));
    let said = stdout(&o);
    assert!(
        said.starts_with("differs:") && said.contains(why),
        "{file}: {said}"
    );
    let o = run(&["compare", file, "a.exr"], dir);
    let said = stdout(&o);
    assert!(
        !said.contains("identical") && said.contains(why),
        "{file}: {said}"
    );
}

#[test]
fn exr_layouts_tessera_does_not_write_are_refused_before_anything_is_allocated() {
    let dir = temp_dir("hostile-exr");
    let exr = std::fs::read(rendered(&dir, "a.exr")).unwrap();
    let mut cases: Vec<(&str, Vec<u8>, &str)> = Vec::new();
    // The multi-part flag: a part may claim any size, and another be decoded.
    let mut multi = exr.clone();
    multi[5] |= 0x10;
    cases.push(("multi-part", multi, "multi-part OpenEXR file"));
    let mut deep = exr.clone();
    deep[5] |= 0x08;
    cases.push(("deep", deep, "deep data"));
    // An alpha channel in place of blue.
    let mut alpha = exr.clone();
    let (channels, _) = exr_attribute(&alpha, "channels");
    alpha[channels] = b'A';
    cases.push(("channels", alpha, "tessera writes R, G and B only"));
    // A data window of 2^31 x 2^31 pixels in a file of a few KiB.
    let mut huge = exr.clone();
    let (window, _) = exr_attribute(&huge, "dataWindow");
    huge[window + 8..window + 16].copy_from_slice(&[0xff, 0xff, 0xff, 0x7f].repeat(2));
    cases.push(("huge", huge, "more pixels than tessera makes"));
    // Half a million attributes, 10 MB of header.
    let many: Vec<u8> = (0..500_000)
        .flat_map(|i| exr_attr(&format!("a{i}"), "int", &[0; 4]))
        .collect();
    cases.push((
        "attributes",
        exr_with_attributes(&exr, &many),
        "more than 256 header attributes",
    ));
    // An attribute claiming 2 GiB.
    let mut claim = exr_attr("x", "string", b"");
    claim.truncate(claim.len() - 4);
    claim.extend_from_slice(&0x7fff_ffffu32.to_le_bytes());
    cases.push((
        "claim",
        exr_with_attributes(&exr, &claim),
        "more than tessera reads",
    ));
    for (name, bytes, why) in cases {
        let file = format!("{name}.exr");
        std::fs::write(dir.join(&file), &bytes).unwrap();
        for command in ["info", "reproduce"] {
            let o = run_capped(&[command, &file], &dir, 256);
            refused(&o, why, &format!("{command} {name}"));
        }
        assert_eq!(std::fs::read(dir.join(&file)).unwrap(), bytes, "{name}");
    }
}

/// An EXR another program made is read by the `exr` crate, as a texture or an image to
/// compare, which keeps every attribute of its header: 500,000 of them in a 10 MB file once
/// took 818 MB and 2 s (a 62 MB file 3.3 GB and 15 s). Its header is walked within the bounds
/// first, whatever its channels.
#[test]
fn an_exr_texture_or_compared_image_of_many_attributes_is_refused_within_bounds() {
    let dir = temp_dir("hostile-exr-others");
    let exr = std::fs::read(rendered(&dir, "a.exr")).unwrap();
    let many: Vec<u8> = (0..500_000)
        .flat_map(|i| exr_attr(&format!("a{i}"), "string", b"x"))
        .collect();
    std::fs::write(dir.join("many.exr"), exr_with_attributes(&exr, &many)).unwrap();
    std::fs::write(dir.join("scene.toml"), textured_scene("many.exr")).unwrap();
    let o = run_capped(&["render", "scene.toml", "-q", "-o", "out.png"], &dir, 256);
    refused(
        &o,
        "field `textures.t.file`: many.exr: has more than 256 header attributes",
        "texture",
    );
    assert!(!dir.join("out.png").exists());
    let o = run_capped(&["compare", "many.exr", "a.exr"], &dir, 256);
    refused(
        &o,
        "many.exr: has more than 256 header attributes",
        "compare",
    );
    // A header within the bounds is read as before, as a texture and compared.
    std::fs::write(dir.join("own.toml"), textured_scene("a.exr")).unwrap();
    ok(&["render", "own.toml", "-q", "-o", "own.png"], &dir);
    let o = run(&["compare", "a.exr", "a.exr"], &dir);
    assert!(stdout(&o).contains("identical"), "{}", stderr(&o));
}

/// The `exr` crate takes a single part whose `type` says `tiledimage` for tiles whatever the
/// version flags say, where other readers go by the flags: one file, two pictures. A part
/// type or tile description that disagrees with the flags is refused, by every reader of
/// EXR headers (`info`, `reproduce`, `compare`).
#[test]
fn an_exr_whose_part_type_disagrees_with_its_version_flags_is_refused() {
    let dir = temp_dir("hostile-exr-type");
    let exr = std::fs::read(rendered(&dir, "a.exr")).unwrap();
    let o = run(&["reproduce", "a.exr", "-q"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // tessera writes tiles: the flag (bit 9 of the version) cleared says scan lines.
    assert_eq!(exr[5] & 0x02, 0x02, "tessera's EXR is tiled");
    let mut scan_lines = exr.clone();
    scan_lines[5] &= !0x02;
    // The tile description renamed away, the flag and type still saying tiles.
    let mut untiled = exr.clone();
    let (tiles, _) = exr_attribute(&untiled, "tiles");
    let name = tiles - "tiles\0tiledesc\0".len() - 4;
    assert_eq!(&untiled[name..name + 5], b"tiles");
    untiled[name..name + 5].copy_from_slice(b"tilez");
    let cases = [
        (
            "flags.exr",
            scan_lines,
            "has the part type `tiledimage` where its version flags say `scanlineimage`",
        ),
        (
            "untiled.exr",
            untiled,
            "has no tile description where its version flags say tiles",
        ),
    ];
    for (file, bytes, why) in cases {
        std::fs::write(dir.join(file), &bytes).unwrap();
        for command in [
            &["info", file][..],
            &["reproduce", file, "-q"],
            &["compare", "a.exr", file],
        ] {
            let o = run(command, &dir);
            assert_eq!(o.status.code(), Some(2), "{command:?}: {}", stderr(&o));
            assert!(stderr(&o).contains(why), "{command:?}: {}", stderr(&o));
        }
    }
}

#[test]
fn an_exr_whose_attributes_change_its_display_differs() {
    let dir = temp_dir("hostile-exr-display");
    let exr = std::fs::read(rendered(&dir, "a.exr")).unwrap();
    let o = run(&["reproduce", "a.exr", "-q"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let mut stretched = exr.clone();
    let (ratio, _) = exr_attribute(&stretched, "pixelAspectRatio");
    stretched[ratio..ratio + 4].copy_from_slice(&2f32.to_le_bytes());
    let chromaticities = exr_attr("chromaticities", "chromaticities", &[0; 32]);
    // A thumbnail of one red pixel, which a file browser shows for the image.
    let preview = exr_attr(
        "preview",
        "preview",
        &[1, 0, 0, 0, 1, 0, 0, 0, 255, 0, 0, 255],
    );
    let cases = [
        ("stretched", stretched, "pixelAspectRatio is 2"),
        (
            "primaries",
            exr_with_attributes(&exr, &chromaticities),
            "the attribute chromaticities",
        ),
        (
            "thumbnail",
            exr_with_attributes(&exr, &preview),
            "the attribute preview",
        ),
    ];
    for (name, bytes, why) in cases {
        differs_naming(&dir, &format!("{name}.exr"), &bytes, why);
    }
}

/// An EXR without an attribute OpenEXR requires of every header (here renamed, its first
/// letter's case changed): the OpenEXR library refuses it, so every viewer built on it shows
/// nothing, but the `exr` crate reads it with defaults of its own, and it was `identical`.
#[test]
fn an_exr_lacking_an_attribute_openexr_requires_differs() {
    let dir = temp_dir("hostile-exr-required");
    let exr = std::fs::read(rendered(&dir, "a.exr")).unwrap();
    for name in [
        "lineOrder",
        "pixelAspectRatio",
        "screenWindowCenter",
        "screenWindowWidth",
    ] {
        let (attributes, _) = exr_walk(&exr);
        let found = attributes.iter().find(|a| a.0 == name.as_bytes()).unwrap();
        let start = found.0.as_ptr() as usize - exr.as_ptr() as usize;
        let mut renamed = exr.clone();
        renamed[start] ^= 0x20;
        let why = format!("no attribute {name} of type");
        differs_naming(&dir, &format!("no-{name}.exr"), &renamed, &why);
    }
}

/// An attribute whose value is not the size of its type (a float of 5 bytes, a v2f of 12, a
/// compression of 2): OpenEXR refuses the header, so every viewer built on it shows nothing,
/// but the `exr` crate reads it, and it was `identical`.
#[test]
fn an_exr_with_an_attribute_of_the_wrong_size_for_its_type_differs() {
    let dir = temp_dir("hostile-exr-attribute-size");
    let exr = std::fs::read(rendered(&dir, "a.exr")).unwrap();
    for (kind, size) in [
        ("float", 5),
        ("v2f", 12),
        ("compression", 2),
        ("floatvector", 6),
    ] {
        let grown = exr_with_attributes(&exr, &exr_attr("note", kind, &vec![0; size]));
        let why = format!("an attribute `note` of type {kind} of {size} bytes");
        differs_naming(&dir, &format!("{kind}.exr"), &grown, &why);
    }
    // Of the right size, the attribute changes nothing.
    let fits = exr_with_attributes(&exr, &exr_attr("note", "v2f", &[0; 8]));
    std::fs::write(dir.join("fits.exr"), &fits).unwrap();
    assert_eq!(
        run(&["reproduce", "fits.exr", "-q"], &dir).status.code(),
        Some(0)
    );
}

/// OpenEXR reads each tile at its offset table's entry and refuses a chunk there that says
/// it is another tile's; the `exr` crate puts each chunk where the chunk itself says. A
/// table of two entries swapped was `identical` to `reproduce` and to `compare`, though no
/// viewer built on OpenEXR shows it.
#[test]
fn an_exr_whose_offset_table_points_to_other_tiles_differs() {
    let dir = temp_dir("hostile-exr-offsets");
    let scene = scene_path("img-1.12-metal-fuzz.toml");
    let args = ["--width", "80", "--spp", "1", "-q", "-o", "a.exr"];
    ok(
        &[&["render", scene.to_str().unwrap()][..], &args].concat(),
        &dir,
    );
    assert_eq!(
        run(&["reproduce", "a.exr", "-q"], &dir).status.code(),
        Some(0)
    );
    let exr = std::fs::read(dir.join("a.exr")).unwrap();
    // Two tiles of 64x64 across: entries 0 and 1 swapped.
    let table = exr_header_end(&exr);
    let mut swapped = exr.clone();
    swapped[table..table + 8].copy_from_slice(&exr[table + 8..table + 16]);
    swapped[table + 8..table + 16].copy_from_slice(&exr[table..table + 8]);
    std::fs::write(dir.join("swapped.exr"), swapped).unwrap();
    // Said with the header, before anything is rendered.
    let o = run(&["reproduce", "swapped.exr"], &dir);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let said = stdout(&o);
    assert!(
        said.contains(
            "entry 0 of its offset table, for tile (0, 0), points to the chunk of tile (1, 0)"
        ),
        "{said}"
    );
    assert!(!stderr(&o).contains("rendering"), "{}", stderr(&o));
    // A chunk that says it is a tile the image has none of is refused by its entry, where
    // `info` showed the file as sound, `compare` quoted the decoder ("invalid: tile
    // index") and `reproduce` rendered before it said so.
    let chunk = u64::from_le_bytes(exr[table..table + 8].try_into().unwrap()) as usize;
    let mut stray = exr.clone();
    stray[chunk..chunk + 4].copy_from_slice(&5i32.to_le_bytes());
    std::fs::write(dir.join("stray.exr"), stray).unwrap();
    for args in [
        &["info", "stray.exr"][..],
        &["compare", "a.exr", "stray.exr"],
        &["reproduce", "stray.exr"],
    ] {
        let o = run(args, &dir);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!(
                "stray.exr: has an offset table whose entry 0 points to a chunk at byte \
                 {chunk} of tile (5, 0) at level (0, 0), which the image (2x1 tiles, one level) \
                 has none of"
            )),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("rendering"), "{}", stderr(&o));
    }
    // `compare` measures the same values and lists it as what changes how the file is
    // shown: it once called the two files identical.
    let o = run(&["compare", "a.exr", "swapped.exr"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let said = stdout(&o);
    assert!(
        said.contains("entry 0 of its offset table") && !said.contains("identical"),
        "{said}"
    );
    assert_eq!(
        run(&["compare", "a.exr", "a.exr"], &dir).status.code(),
        Some(0)
    );
}

/// A tiled EXR of mipmap levels (the picture again at half, quarter ... size, which a viewer
/// may show zoomed out, and a renderer samples as a texture), its first level the pixels of
/// one tessera rendered: `compare` read the first level alone and called the two identical.
#[test]
fn an_exr_of_mipmap_levels_differs() {
    use exr::math::RoundingMode;
    use exr::prelude::*;
    let dir = temp_dir("hostile-exr-mipmap");
    let a = rendered(&dir, "a.exr");
    let first = read_first_rgba_layer_from_file(
        &a,
        |size, _| (size.width(), vec![[0f32; 3]; size.area()]),
        |(width, pixels): &mut (usize, Vec<[f32; 3]>),
         p: Vec2<usize>,
         (r, g, b, _): (f32, f32, f32, f32)| {
            pixels[p.y() * *width + p.x()] = [r, g, b];
        },
    )
    .unwrap();
    let (_, pixels) = first.layer_data.channel_data.pixels;
    let size = first.layer_data.size;
    let levels: Vec<_> = exr::meta::mip_map_levels(RoundingMode::Down, size).collect();
    let channel = |name: &str, c: usize| {
        let level_data = (levels.iter())
            .map(|(i, level)| match i {
                0 => FlatSamples::F32(pixels.iter().map(|p| p[c]).collect()),
                _ => FlatSamples::F32(vec![1.0; level.area()]),
            })
            .collect();
        AnyChannel::new(
            name,
            Levels::Mip {
                level_data,
                rounding_mode: RoundingMode::Down,
            },
        )
    };
    let channels = AnyChannels::sort(SmallVec::from_iter([
        channel("R", 0),
        channel("G", 1),
        channel("B", 2),
    ]));
    let encoding = Encoding {
        compression: Compression::Uncompressed,
        blocks: Blocks::Tiles(Vec2(16, 16)),
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(size, LayerAttributes::default(), encoding, channels);
    Image::from_layer(layer)
        .write()
        .to_file(dir.join("mip.exr"))
        .unwrap();
    let o = run(&["compare", "a.exr", "mip.exr"], &dir);
    let said = stdout(&o);
    assert!(
        said.contains("mipmap") && !said.contains("identical"),
        "{said}{}",
        stderr(&o)
    );
}

// --- PNG ------------------------------------------------------------------------------------

/// A PNG chunk's bytes.
fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut c = (data.len() as u32).to_be_bytes().to_vec();
    c.extend_from_slice(kind);
    c.extend_from_slice(data);
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    c.extend_from_slice(&crc.finalize().to_be_bytes());
    c
}

/// `png` with `chunks` inserted right after its IHDR chunk.
fn png_with_chunks(png: &[u8], chunks: &[u8]) -> Vec<u8> {
    let after_ihdr = 8 + 12 + 13;
    [&png[..after_ihdr], chunks, &png[after_ihdr..]].concat()
}

/// `png` with the size its IHDR claims replaced (its pixel data left as it is).
fn png_claiming(png: &[u8], width: u32, height: u32) -> Vec<u8> {
    let mut ihdr = png[16..29].to_vec();
    ihdr[..4].copy_from_slice(&width.to_be_bytes());
    ihdr[4..8].copy_from_slice(&height.to_be_bytes());
    [&png[..8], &png_chunk(b"IHDR", &ihdr)[..], &png[33..]].concat()
}

/// `compare` of two images that claim 16000x16000 pixels once took 6.3 GB (three floats a
/// pixel, twice, and the decoder's own buffers), and two 16-bit RGBA PNGs of 2^25 pixels
/// 1 GB: the size each header claims is checked before anything is decoded (at most 2^24
/// pixels), and two sizes that differ are an error before either is.
#[test]
fn compare_checks_the_sizes_images_claim_before_decoding_them() {
    let dir = temp_dir("hostile-compare-size");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    std::fs::write(dir.join("huge.png"), png_claiming(&png, 16000, 16000)).unwrap();
    let o = run_capped(&["compare", "huge.png", "huge.png"], &dir, 256);
    refused(
        &o,
        "huge.png: 16000x16000 is more than the 16777216 pixels (4096x4096) an image may have",
        "huge",
    );
    // Within the bound, its pixels' stream far shorter than the rows it claims: refused
    // before the decoder is given room for them (libpng refuses it too).
    std::fs::write(dir.join("wide.png"), png_claiming(&png, 4096, 4096)).unwrap();
    let o = run_capped(&["compare", "a.png", "wide.png"], &dir, 256);
    refused(
        &o,
        "wide.png: has pixels that do not decode: a zlib stream that inflates to 1746 bytes, \
         fewer than the 50335744 its image's rows take",
        "wide",
    );
    let o = run(&["compare", "a.png", "a.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("inf dB (identical)"), "{}", stdout(&o));
}

/// `compare` of a real 4096x4096 PNG (within every bound) under 300 MiB of address space
/// ended in a panic within the image crate's `to_rgb32f` (exit 101; with `RUST_BACKTRACE`
/// set, its backtrace then waited forever on a lock): the memory its pixels take to compare is
/// asked of the system first, and a refusal is an error that says how much (exit 2). With
/// room enough the same files compare `identical`.
#[test]
fn compare_refuses_an_image_whose_memory_the_system_refuses() {
    let dir = temp_dir("hostile-compare-memory");
    image::RgbImage::new(4096, 4096)
        .save(dir.join("big.png"))
        .unwrap();
    let o = run_capped(&["compare", "big.png", "big.png"], &dir, 300);
    refused(
        &o,
        "big.png: could not be compared: its 4096x4096 pixels take 251658240 bytes of memory \
         to compare",
        "capped",
    );
    let o = run_capped(&["compare", "big.png", "big.png"], &dir, 1024);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("inf dB (identical)"), "{}", stdout(&o));
}

/// A file far longer than any image of `compare`'s 2^24 pixels takes: a JPEG followed by 4 GiB
/// (its decoder reads the whole file: 4.2 GB and 22 s before), a PPM whose header is a comment
/// of 100 GiB (12 minutes of reading), each sparse, on a few KiB of disk; and a PAM within that
/// length whose header is one line of 300 MiB (the decoder kept the line: an allocation failed
/// under the cap and ended tessera). Each is refused before its pixels, or the line, are read.
#[test]
fn compare_refuses_a_file_longer_than_its_images_take_and_a_pnm_header_without_end() {
    let dir = temp_dir("hostile-compare-length");
    let jpeg = std::fs::read(scene_path("earthmap.jpg")).unwrap();
    std::fs::write(dir.join("a.jpg"), &jpeg).unwrap();
    let sparse = |name: &str, start: &[u8], len: u64| {
        let mut file = std::fs::File::create(dir.join(name)).unwrap();
        std::io::Write::write_all(&mut file, start).unwrap();
        file.set_len(len).unwrap();
    };
    sparse("long.jpg", &jpeg, 4 << 30);
    sparse("comment.ppm", b"P6\n#", 100 << 30);
    sparse("line.pam", b"P7\n#", 300 << 20);
    let o = run_capped(&["compare", "a.jpg", "long.jpg"], &dir, 256);
    refused(
        &o,
        "long.jpg: is 4294967296 bytes long, more than the",
        "jpeg",
    );
    let started = std::time::Instant::now();
    let o = run_capped(&["compare", "a.jpg", "comment.ppm"], &dir, 256);
    refused(&o, "comment.ppm: is 107374182400 bytes long", "ppm");
    assert!(started.elapsed().as_secs() < 10, "{:?}", started.elapsed());
    let o = run_capped(&["compare", "a.jpg", "line.pam"], &dir, 256);
    refused(
        &o,
        "line.pam: has a PNM header that does not end within its first 64 KiB",
        "pam",
    );
    let o = run(&["compare", "a.jpg", "a.jpg"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("inf dB (identical)"), "{}", stdout(&o));
    // A file that ends within its pixels says so, not the decoder's "failed to fill whole
    // buffer".
    let pixels = [7u8; 4 * 4 * 3];
    let pam = b"P7\nWIDTH 4\nHEIGHT 4\nDEPTH 3\nMAXVAL 255\nTUPLTYPE RGB\nENDHDR\n";
    std::fs::write(dir.join("whole.pam"), [&pam[..], &pixels].concat()).unwrap();
    std::fs::write(dir.join("cut.pam"), [&pam[..], &pixels[..20]].concat()).unwrap();
    std::fs::write(
        dir.join("cut.ppm"),
        [&b"P6\n4 4\n255\n"[..], &pixels[..20]].concat(),
    )
    .unwrap();
    for cut in ["cut.pam", "cut.ppm"] {
        let o = run(&["compare", "whole.pam", cut], &dir);
        refused(
            &o,
            &format!("{cut}: ends before its image does (a truncated file?)"),
            cut,
        );
    }
    // Files of 100 GiB, if only in name, are not left for whoever sums the sizes of /tmp.
    for name in ["long.jpg", "comment.ppm", "line.pam"] {
        std::fs::remove_file(dir.join(name)).unwrap();
    }
}

/// A baseline JPEG of `side`x`side` pixels in three components whose one scan holds
/// `coded` bytes of data (each table one code of one bit: two bits a block).
fn thin_jpeg(side: u16, coded: usize) -> Vec<u8> {
    let segment = |marker: u8, body: &[u8]| {
        let length = (body.len() as u16 + 2).to_be_bytes();
        [&[0xff, marker][..], &length, body].concat()
    };
    let side = side.to_be_bytes();
    let frame = [
        &[8][..],
        &side,
        &side,
        &[3, 1, 0x11, 0, 2, 0x11, 0, 3, 0x11, 0],
    ]
    .concat();
    let one_code = |class: u8| [&[class, 1][..], &[0; 15], &[0]].concat();
    [
        &[0xff, 0xd8][..],
        &segment(0xdb, &[&[0][..], &[1; 64]].concat()),
        &segment(0xc0, &frame),
        &segment(0xc4, &one_code(0x00)),
        &segment(0xc4, &one_code(0x10)),
        &segment(0xda, &[3, 1, 0, 2, 0, 3, 0, 0, 63, 0]),
        &vec![0; coded],
        &[0xff, 0xd9],
    ]
    .concat()
}

/// The JPEG decoder fills what a scan lacks rather than failing: a JPEG of 214 bytes whose
/// frame claims 4096x4096 pixels and whose scan holds 64 bytes was compared `identical` with
/// itself (448 MB, 0.77 s; under 256 MiB of address space, a panic of the colour conversion's
/// allocation, exit 101), and rendered as a texture of grey. Coded data fewer than two bits a
/// block is refused from the file's bytes, before anything of its size is allocated; the
/// same frame with that many bytes (a flat picture) is read.
#[test]
fn a_jpeg_of_less_coded_data_than_its_frame_s_blocks_take_is_refused_undecoded() {
    let dir = temp_dir("hostile-jpeg-thin");
    std::fs::write(dir.join("thin.jpg"), thin_jpeg(4096, 64)).unwrap();
    let o = run_capped(&["compare", "thin.jpg", "thin.jpg"], &dir, 256);
    refused(
        &o,
        "thin.jpg: claims 4096x4096 pixels in 3 components, 786432 blocks of 8x8, but its \
         scans hold 64 bytes of coded data, fewer than the 196608",
        "compare",
    );
    std::fs::write(dir.join("thin.toml"), textured_scene("thin.jpg")).unwrap();
    let o = run_capped(&["render", "thin.toml", "-o", "out.png"], &dir, 1024);
    refused(
        &o,
        "thin.jpg: is a JPEG that claims 4096x4096 pixels",
        "texture",
    );
    assert!(!dir.join("out.png").exists());
    std::fs::write(dir.join("flat.jpg"), thin_jpeg(64, 3 * 64 / 4)).unwrap();
    let o = run(&["compare", "flat.jpg", "flat.jpg"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(dir.join("flat.toml"), textured_scene("flat.jpg")).unwrap();
    let o = run(&["render", "flat.toml", "-q", "-o", "out.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A PPM of 317 bytes whose header says `P6 4096 4096 255`, and a plain one of as many, had
/// 50 MB (100 MB) reserved for their samples before they were found short: under 40 MiB of
/// address space tessera ended on the failed allocation (exit 134). Each is refused by its
/// length against its header, before anything of its size is allocated; as a texture too.
#[test]
fn a_pnm_shorter_than_its_header_s_samples_is_refused_before_they_are_allocated() {
    let dir = temp_dir("hostile-pnm-short");
    for (name, magic, fill) in [("short.ppm", "P6", 0u8), ("plain.ppm", "P3", b' ')] {
        let bytes = [
            format!("{magic}\n4096 4096\n255\n").as_bytes(),
            &[fill; 300],
        ]
        .concat();
        std::fs::write(dir.join(name), bytes).unwrap();
        let o = run_capped(&["compare", name, name], &dir, 40);
        refused(
            &o,
            &format!(
                "{name}: ends before its image does (a truncated file?): it is 317 bytes long, \
                 and its header of 17 bytes claims 4096x4096 pixels"
            ),
            name,
        );
        let scene = format!("{name}.toml");
        std::fs::write(dir.join(&scene), textured_scene(name)).unwrap();
        let o = run_capped(&["render", &scene, "-o", "out.png"], &dir, 1024);
        refused(&o, &format!("{name}: ends before its image does"), &scene);
        assert!(!dir.join("out.png").exists());
    }
}

#[test]
fn a_png_whose_chunks_change_its_display_differs_naming_the_chunk() {
    let dir = temp_dir("hostile-png-display");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let o = run(&["reproduce", "a.png", "-q"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let animation = [
        png_chunk(b"acTL", &[0, 0, 0, 1, 0, 0, 0, 0]),
        png_chunk(b"fcTL", &[0; 26]),
    ]
    .concat();
    let cases: [(&str, Vec<u8>, &str); 6] = [
        ("apng", animation, "acTL chunk"),
        (
            "trns",
            png_chunk(b"tRNS", &[0, 0, 0, 0, 0, 0]),
            "tRNS chunk",
        ),
        (
            "gama",
            png_chunk(b"gAMA", &100_000u32.to_be_bytes()),
            "gAMA chunk",
        ),
        ("iccp", png_chunk(b"iCCP", b"p\0\0x"), "iCCP chunk"),
        (
            "exif",
            png_chunk(b"eXIf", b"MM\0*\0\0\0\x08\0\0"),
            "eXIf chunk",
        ),
        // Apple's decoders decode the rows from the IDAT chunk it points to as a stream of
        // their own: an "ambiguous PNG" shows other pixels on macOS and iOS only.
        ("idot", png_chunk(b"iDOT", &[0; 28]), "iDOT chunk"),
    ];
    for (name, chunks, why) in cases {
        let file = format!("{name}.png");
        std::fs::write(dir.join(&file), png_with_chunks(&png, &chunks)).unwrap();
        let o = run(&["reproduce", &file, "-q"], &dir);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stderr(&o));
        let said = stdout(&o);
        assert!(
            said.starts_with("differs:") && said.contains(why),
            "{name}: {said}"
        );
        // compare measures the same values, but does not call them identical: it lists
        // what changes how the file is shown. (The animation's frame control of zeros is
        // one the decoder refuses.)
        if name == "apng" {
            continue;
        }
        let o = run(&["compare", "a.png", &file], &dir);
        assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        let said = stdout(&o);
        assert!(
            said.contains("RMSE 0 ")
                && !said.contains("identical")
                && said.contains(&format!("\n{file}: ")),
            "{name}: {said}"
        );
        assert!(said.contains(why), "{name}: {said}");
    }
    // Text that changes nothing a viewer shows leaves it identical.
    let text = png_chunk(b"tEXt", b"Comment\0made by a friend");
    std::fs::write(dir.join("text.png"), png_with_chunks(&png, &text)).unwrap();
    let o = run(&["reproduce", "text.png", "-q"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let o = run(&["compare", "text.png", "a.png"], &dir);
    assert!(stdout(&o).contains("inf dB (identical)"), "{}", stdout(&o));
}

/// Text chunks are skipped unread by the header's reader, but the pixels' decoder reads all
/// that comes before the pixels: a sparse file of 65,536 text chunks of 1 MiB (64 GiB on
/// 256 MiB of disk) took minutes. A file longer than an image of its size takes (16 bytes a
/// pixel, 32 a row and 64 MiB) has its pixels left unread: an error, not a verdict.
#[test]
fn a_png_longer_than_its_image_takes_has_its_pixels_left_unread() {
    use std::io::{Seek, SeekFrom, Write};
    let dir = temp_dir("hostile-png-long");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    // One tEXt chunk of 80 MiB of zeros before the pixels, sparse.
    let length = 80u32 << 20;
    let mut crc = crc32fast::Hasher::new();
    crc.update(b"tEXt");
    crc.update(&vec![0u8; length as usize]);
    let mut file = std::fs::File::create(dir.join("long.png")).unwrap();
    file.write_all(&png[..33]).unwrap();
    file.write_all(&length.to_be_bytes()).unwrap();
    file.write_all(b"tEXt").unwrap();
    file.seek(SeekFrom::Current(i64::from(length))).unwrap();
    file.write_all(&crc.finalize().to_be_bytes()).unwrap();
    file.write_all(&png[33..]).unwrap();
    drop(file);
    let o = run(&["info", "long.png"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = run(&["reproduce", "long.png", "-q"], &dir);
    refused(&o, "bytes long, more than the", "a PNG of 80 MiB of text");
}

/// A PNG has one IHDR chunk, first, of 13 bytes: another layout would let the size a header
/// reader reports be another than the pixels' (a decoder takes the first).
#[test]
fn a_png_s_size_comes_from_its_one_first_ihdr_chunk() {
    let dir = temp_dir("hostile-png-ihdr");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let ihdr = &png[8..8 + 12 + 13];
    let huge = png_chunk(b"IHDR", &[0, 0, 0x40, 0, 0, 0, 0x40, 0, 8, 2, 0, 0, 0]);
    let long = png_chunk(b"IHDR", &[0; 14]);
    let cases = [
        (
            "second",
            png_with_chunks(&png, &huge),
            "has a second IHDR chunk at byte 33",
        ),
        (
            "late",
            [&png[..8], &png_chunk(b"tEXt", b"a\0b"), &png[8..]].concat(),
            "does not begin with its IHDR chunk (a tEXt chunk at byte 8)",
        ),
        (
            "long",
            [&png[..8], &long[..], &png[8 + ihdr.len()..]].concat(),
            "has an IHDR chunk of 14 bytes",
        ),
    ];
    for (name, bytes, why) in cases {
        let file = format!("{name}.png");
        std::fs::write(dir.join(&file), bytes).unwrap();
        for command in ["info", "reproduce"] {
            refused(
                &run(&[command, &file], &dir),
                why,
                &format!("{name} {command}"),
            );
        }
    }
}

#[test]
fn a_png_of_a_million_chunks_is_refused_within_bounds() {
    let dir = temp_dir("hostile-png-chunks");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let empty = png_chunk(b"zzZz", &[]);
    let many = empty.repeat(1_000_000);
    std::fs::write(dir.join("many.png"), png_with_chunks(&png, &many)).unwrap();
    for command in ["info", "reproduce"] {
        let o = run_capped(&[command, "many.png"], &dir, 256);
        refused(&o, "more than 65536 chunks", command);
    }
}

/// `png` with its one IDAT chunk's zlib stream made `change(stream)`.
fn png_with_stream(png: &[u8], change: impl Fn(&mut Vec<u8>)) -> Vec<u8> {
    let mut at = 8;
    loop {
        let length = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
        if &png[at + 4..at + 8] == b"IDAT" {
            let mut stream = png[at + 8..at + 8 + length].to_vec();
            change(&mut stream);
            let chunk = png_chunk(b"IDAT", &stream);
            return [&png[..at], &chunk[..], &png[at + 12 + length..]].concat();
        }
        at += 12 + length;
    }
}

/// The pixels' zlib stream as libpng (Firefox, GIMP) reads it: with the window its header
/// declares, and its checksum checked. A stream declaring a window of 256 bytes that reaches
/// 32 KiB back, or one whose checksum is wrong, is a broken picture there; the PNG decoder
/// tessera uses takes no notice of either, and both were called `identical`.
#[test]
fn a_png_whose_zlib_stream_libpng_refuses_is_not_identical() {
    let dir = temp_dir("hostile-png-zlib");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    assert_eq!(
        run(&["reproduce", "a.png", "-q"], &dir).status.code(),
        Some(0)
    );
    // The window of 256 bytes (its check bits made right again), or a preset dictionary.
    let small_window = png_with_stream(&png, |s| {
        s[0] = 0x08;
        s[1] = (s[1] & 0xe0) + (31 - (0x0800 + u16::from(s[1] & 0xe0)) % 31) as u8 % 31;
    });
    std::fs::write(dir.join("window.png"), small_window).unwrap();
    let o = run(&["reproduce", "window.png", "-q"], &dir);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("a zlib stream declaring a window of 256 bytes"),
        "{}",
        stdout(&o)
    );
    let checksum = png_with_stream(&png, |s| *s.last_mut().unwrap() ^= 1);
    std::fs::write(dir.join("checksum.png"), checksum).unwrap();
    let o = run(&["reproduce", "checksum.png", "-q"], &dir);
    refused(&o, "has pixels that do not decode", "checksum");
}

/// `compare` of a PNG whose pixels' stream declares a window of 256 bytes and inflates to
/// more (libpng inflates with the window declared, and refuses the file where the stream
/// reaches further back: a broken picture in Firefox and GIMP) beside the file it was made
/// from said `RMSE 0  PSNR inf dB (identical)`, exit 0: the decoder here takes no notice of
/// the window. The window is listed, and the two are not called identical.
#[test]
fn compare_lists_a_png_whose_zlib_stream_declares_a_window_smaller_than_it() {
    let dir = temp_dir("hostile-png-window-compare");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let small_window = png_with_stream(&png, |s| {
        s[0] = 0x08;
        s[1] = (s[1] & 0xe0) + (31 - (0x0800 + u16::from(s[1] & 0xe0)) % 31) as u8 % 31;
    });
    std::fs::write(dir.join("window.png"), small_window).unwrap();
    let o = run(&["compare", "a.png", "window.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(!out.contains("(identical)"), "{out}");
    assert!(
        out.contains("window.png: a zlib stream declaring a window of 256 bytes that inflates to"),
        "{out}"
    );
    let o = run(&["compare", "a.png", "a.png"], &dir);
    assert!(stdout(&o).contains("(identical)"), "{}", stdout(&o));
}

/// A zlib stream cut after its last row, without its end or without its Adler-32 checksum:
/// the PNG decoder stops once it has every row and took it whole (`identical`, exit 0),
/// where libpng refuses it ("Not enough image data": Firefox, GIMP, pngfix).
#[test]
fn a_png_whose_zlib_stream_ends_without_its_checksum_is_not_identical() {
    let dir = temp_dir("hostile-png-zlib-end");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    for cut in [4, 2] {
        let name = format!("cut{cut}.png");
        let cut_png = png_with_stream(&png, |s| s.truncate(s.len() - cut));
        std::fs::write(dir.join(&name), cut_png).unwrap();
        let o = run(&["reproduce", &name, "-q"], &dir);
        refused(
            &o,
            "a zlib stream that ends without its end and checksum",
            &name,
        );
    }
}

/// Where the chunk of type `kind` begins in `png`, and its data's length.
fn png_chunk_at(png: &[u8], kind: &[u8; 4]) -> (usize, usize) {
    let mut at = 8;
    loop {
        let length = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
        if &png[at + 4..at + 8] == kind {
            return (at, length);
        }
        at += 12 + length;
    }
}

/// `compare` read a PNG's zlib stream as its decoder does, to the last row and without its
/// checksum: a stream cut there, or of a wrong checksum, both of which libpng refuses, was
/// `inf dB (identical)` beside the file it was made from.
#[test]
fn compare_refuses_a_png_whose_zlib_stream_libpng_refuses() {
    let dir = temp_dir("hostile-png-zlib-compare");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let cut = png_with_stream(&png, |s| s.truncate(s.len() - 4));
    let checksum = png_with_stream(&png, |s| *s.last_mut().unwrap() ^= 1);
    for (name, bytes, why) in [
        ("cut.png", cut, "ends without its end and checksum"),
        ("checksum.png", checksum, "checksum is wrong"),
    ] {
        std::fs::write(dir.join(name), bytes).unwrap();
        let o = run(&["compare", "a.png", name], &dir);
        refused(&o, why, name);
        assert!(!stdout(&o).contains("identical"), "{name}: {}", stdout(&o));
    }
    // A PNG without pixels says so, not that the file ended.
    let (at, length) = png_chunk_at(&png, b"IDAT");
    let no_idat = [&png[..at], &png[at + 12 + length..]].concat();
    std::fs::write(dir.join("none.png"), no_idat).unwrap();
    let o = run(&["compare", "a.png", "none.png"], &dir);
    refused(&o, "no IDAT chunk", "none.png");
    assert_eq!(
        run(&["compare", "a.png", "a.png"], &dir).status.code(),
        Some(0)
    );
}
// --- recipes ----------------------------------------------------------------------------------

/// The recipe JSON of the image at `path`.
fn recipe_json(dir: &Path, path: &str) -> serde_json::Value {
    let o = run(&["info", "--json", path], dir);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// A PNG of `png`'s pixels carrying `recipe` (uncompressed iTXt) in place of its own.
fn png_with_recipe(png: &[u8], recipe: &serde_json::Value) -> Vec<u8> {
    // Only IHDR, IDAT and IEND of the original, then the new recipe after IHDR.
    let mut kept = png[..8].to_vec();
    let mut at = 8;
    while at < png.len() {
        let len = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
        if &png[at + 4..at + 8] != b"iTXt" {
            kept.extend_from_slice(&png[at..at + 12 + len]);
        }
        at += 12 + len;
    }
    let mut data = b"tessera-recipe\0\0\0\0\0".to_vec();
    data.extend_from_slice(serde_json::to_string(recipe).unwrap().as_bytes());
    png_with_chunks(&kept, &png_chunk(b"iTXt", &data))
}

/// A recipe may list 256 texture files, each read whole and hashed before its scene is
/// built: 256 spellings of one 48 MB file (`big.png`, `./big.png`, `.//big.png`, …) once read
/// 12 GB, 17 s. A file is read once however it is spelt: the bytes the process reads (the
/// kernel's count, not a time) are about one file's.
#[test]
fn a_recipe_naming_one_texture_file_many_ways_reads_it_once() {
    let dir = temp_dir("hostile-recipe-spellings");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let big = vec![7u8; 32 << 20];
    std::fs::write(dir.join("big.png"), &big).unwrap();
    let hash = format!("xxh3-128:{:032x}", xxhash_rust::xxh3::xxh3_128(&big));
    let mut recipe = recipe_json(&dir, "a.png");
    // `.` or `./.`, one to 128 slashes, the name: 256 names within a name's 255 bytes.
    let spellings: Vec<String> = (0..256)
        .map(|k| {
            let dot = if k < 128 { "." } else { "./." };
            format!("{dot}{}big.png", "/".repeat(k % 128 + 1))
        })
        .collect();
    recipe["textures"] = spellings
        .iter()
        .map(|n| serde_json::json!({"name": n, "hash": hash}))
        .collect();
    std::fs::write(dir.join("many.png"), png_with_recipe(&png, &recipe)).unwrap();
    let o = run(&["reproduce", "many.png", "-q"], &dir);
    // The image's scene names no texture: refused once every file is checked.
    refused(
        &o,
        "its recipe's texture files are not those its scene reads",
        "many.png",
    );
    // A shell that runs the same command, then reads its own I/O count, which holds its
    // finished children's: the bytes they read.
    let counted = Command::new("sh")
        .arg("-c")
        .arg("\"$0\" reproduce many.png -q >/dev/null 2>&1; cat /proc/$$/io")
        .arg(env!("CARGO_BIN_EXE_tessera"))
        .env("TESSERA_DB", test_results_db())
        .current_dir(&dir)
        .output()
        .unwrap();
    let io = String::from_utf8_lossy(&counted.stdout);
    let read: u64 = (io.lines())
        .find_map(|l| l.strip_prefix("rchar: "))
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no rchar in {io:?}"));
    assert!(
        read < 2 * big.len() as u64,
        "256 names of one {} byte file: {read} bytes read",
        big.len()
    );
}

/// Characters that rewrite a terminal or hide text.
const INVISIBLE: [char; 7] = [
    '\u{1b}', '\u{7}', '\u{9b}', '\u{61c}', '\u{2028}', '\u{2029}', '\u{feff}',
];

#[test]
fn escapes_in_a_recipe_never_reach_the_terminal() {
    let dir = temp_dir("hostile-escapes");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let mut recipe = recipe_json(&dir, "a.png");
    let evil = "\u{1b}]0;owned\u{7}\u{1b}[2J\u{9b}31m\u{61c}\u{2028}\u{2029}\u{feff}";
    // The same as TOML escapes, which the scene's parser decodes into the characters.
    let escaped: String = evil
        .chars()
        .map(|c| format!("\\u{:04x}", c as u32))
        .collect();
    // Errors that quote the scene's own text: an unknown key, a bad material name, a TOML
    // syntax error; and the scene's name.
    let scenes = [
        format!("\"{escaped}\" = 1\n"),
        format!(
            "{}\n[[sphere]]\ncenter = [0, 0, -1]\nradius = 0.5\nmaterial = \"{escaped}\"\n",
            recipe["scene"]["text"].as_str().unwrap()
        ),
        format!("[camera\n{evil}"),
    ];
    for (i, text) in scenes.iter().enumerate() {
        recipe["scene"]["text"] = text.as_str().into();
        recipe["scene"]["name"] = format!("{evil}.toml").into();
        let file = format!("evil{i}.png");
        std::fs::write(dir.join(&file), png_with_recipe(&png, &recipe)).unwrap();
        for args in [
            &["reproduce", &file][..],
            &["info", &file],
            &["reproduce", &file, "--extract-scene", "x.toml"],
        ] {
            let o = run(args, &dir);
            let all = format!("{}{}", stdout(&o), stderr(&o));
            for c in INVISIBLE {
                assert!(
                    !all.contains(c),
                    "{args:?}: {c:?} reached the terminal: {all:?}"
                );
            }
        }
        let o = run(&["reproduce", &file], &dir);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("\\u{1b}"), "{}", stderr(&o));
    }
    // A newline in a key a message quotes (the recipe's own, or its scene's) stays in the
    // error's one line: it cannot start a line that looks like a verdict.
    let forged = "x\nidentical: a.png is bit for bit what its recipe makes";
    let mut keyed = recipe_json(&dir, "a.png");
    keyed[forged] = 1.into();
    std::fs::write(dir.join("key.png"), png_with_recipe(&png, &keyed)).unwrap();
    let mut scene_keyed = recipe_json(&dir, "a.png");
    let text = scene_keyed["scene"]["text"]
        .as_str()
        .unwrap()
        .replace("[image]\n", "[image]\n\"evil\\nidentical: spoofed\" = 3\n");
    scene_keyed["scene"]["text"] = text.into();
    std::fs::write(
        dir.join("scene-key.png"),
        png_with_recipe(&png, &scene_keyed),
    )
    .unwrap();
    for file in ["key.png", "scene-key.png"] {
        let o = run(&["reproduce", file], &dir);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", stderr(&o));
        let err = stderr(&o);
        assert_eq!(err.lines().count(), 1, "{file}: {err}");
        assert!(
            err.starts_with("tessera: error: ") && err.contains("\\u{a}identical"),
            "{file}: {err}"
        );
    }
}

/// A file name a stranger chose, with a newline and a verdict in it, once printed as it is
/// in the verdict's line: `differs: a` and then a line of its own, `identical: b.png is bit
/// for bit what its recipe makes`. The name is one line wherever a verdict or `info` shows
/// it.
#[test]
fn a_file_name_with_a_newline_cannot_forge_a_verdict_line() {
    let dir = temp_dir("hostile-name-newline");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let name = "a\nidentical: b.png is bit for bit what its recipe makes\u{1b}[2J\nx.png";
    let gamma = png_chunk(b"gAMA", &100_000u32.to_be_bytes());
    std::fs::write(dir.join(name), png_with_chunks(&png, &gamma)).unwrap();
    let o = run(&["reproduce", name, "-q"], &dir);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let said = stdout(&o);
    assert!(
        said.lines()
            .next()
            .is_some_and(|l| l.starts_with("differs: a\\u{a}identical")),
        "{said}"
    );
    assert!(!said.lines().any(|l| l.starts_with("identical")), "{said}");
    // The same pixels without the chunk: identical, the name still on one line.
    std::fs::write(dir.join(name), &png).unwrap();
    let o = run(&["reproduce", name, "-q"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 1, "{}", stdout(&o));
    let o = run(&["info", name], &dir);
    let said = stdout(&o);
    assert!(said.starts_with("a\\u{a}identical"), "{said}");
    assert!(!said.contains('\u{1b}'), "{said}");
    assert!(!said.lines().any(|l| l.starts_with("identical")), "{said}");
}

#[test]
fn a_recipe_asking_for_days_of_work_is_refused_unless_asked() {
    let dir = temp_dir("hostile-cost");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let mut recipe = recipe_json(&dir, "a.png");
    recipe["image"]["width"] = 8192.into();
    recipe["image"]["height"] = 8192.into();
    recipe["image"]["window"] = serde_json::json!([0, 0, 8192, 8192]);
    recipe["image"]["samples_per_pixel"] = 1_000_000.into();
    std::fs::write(dir.join("costly.png"), png_with_recipe(&png, &recipe)).unwrap();
    let o = run(&["reproduce", "costly.png"], &dir);
    refused(&o, "pass --any-cost to render it anyway", "reproduce");
    let err = stderr(&o);
    assert!(
        err.contains("8192x8192 pixels at 1000000 samples per pixel")
            && err.contains("more than the 4 book covers' work that reproduce renders"),
        "{err}"
    );
    // Little work, but a film of 6.4 GB: the most pixels a recipe may claim, at one sample.
    recipe["image"]["width"] = 16384.into();
    recipe["image"]["height"] = 16384.into();
    recipe["image"]["window"] = serde_json::json!([0, 0, 16384, 16384]);
    recipe["image"]["samples_per_pixel"] = 1.into();
    recipe["image"]["max_depth"] = 1.into();
    std::fs::write(dir.join("large.png"), png_with_recipe(&png, &recipe)).unwrap();
    let o = run_capped(&["reproduce", "large.png"], &dir, 256);
    refused(
        &o,
        "more than the 33554432 pixels that reproduce renders unasked",
        "large",
    );
    // Asked for, the work is allowed; here the recipe's scene then does not give what it
    // claims, which stops it before anything is rendered.
    let o = run(&["reproduce", "costly.png", "--any-cost"], &dir);
    refused(
        &o,
        "are not what its scene and overrides give",
        "--any-cost",
    );
}

/// What a recipe claims (pixels, samples, depth) cannot say what one of its rays costs: a
/// ray into 4,000 nested glass shells meets every one of them. `reproduce` traces a few of
/// the scene's paths against as many of the cover's and judges the work by what they cost.
#[test]
fn a_recipe_whose_paths_cost_more_than_it_claims_is_refused_once_they_are_traced() {
    let dir = temp_dir("hostile-path-cost");
    let mut scene = String::from(
        "[image]\nwidth = 320\nheight = 180\nsamples_per_pixel = 20000\nmax_depth = 50\n\
         seed = 1\n\n[render]\nshading = \"path\"\ndiffuse = \"lambertian\"\n\n\
         [materials.glass]\ntype = \"dielectric\"\nir = 1.5\n",
    );
    for i in 0..4000 {
        let radius = 0.3 + 0.2 * f64::from(i) / 4000.0;
        scene += &format!(
            "\n[[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = {radius:.6}\nmaterial = \"glass\"\n"
        );
    }
    std::fs::write(dir.join("shells.toml"), scene).unwrap();
    // A real image of the scene at one sample; its recipe then claims the scene's own 20,000.
    ok(
        &["render", "shells.toml", "--spp", "1", "-q", "-o", "one.png"],
        &dir,
    );
    let png = std::fs::read(dir.join("one.png")).unwrap();
    let mut recipe = recipe_json(&dir, "one.png");
    recipe["overrides"] = serde_json::json!({});
    recipe["image"]["samples_per_pixel"] = 20_000.into();
    std::fs::write(dir.join("shells.png"), png_with_recipe(&png, &recipe)).unwrap();
    let o = run(&["reproduce", "shells.png"], &dir);
    refused(&o, "pass --any-cost to render it anyway", "shells");
    let err = stderr(&o);
    // Claimed, it is under the limit (every ray a cover's: 2.4 covers); traced, the paths
    // cost some tens of times the cover's (26 to 28 on an AMD Zen 5).
    assert!(
        err.contains("320x180 pixels at 20000 samples per pixel, paths of up to 50 bounces: about")
            && err.contains("times the cover's), more than the 4 book covers' work"),
        "{err}"
    );
    // The image at one sample, as rendered, is reproduced: its work is a small part of one.
    let o = run(&["reproduce", "one.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).starts_with("identical:"), "{}", stdout(&o));
    // What the probe misses, the time budget stops (here set low by its variable; unset,
    // twice four covers' time on this machine), between pixels, writing nothing.
    ok(
        &[
            "render",
            "shells.toml",
            "--width",
            "240",
            "--spp",
            "16",
            "-q",
            "-o",
            "sixteen.png",
        ],
        &dir,
    );
    let budget = [("TESSERA_REPRODUCE_SECONDS", "0.01")];
    let o = run_in_env(
        &["reproduce", "sixteen.png", "-q", "-o", "again.png"],
        &budget,
        &dir,
    );
    refused(
        &o,
        "the time reproduce gives a recipe unasked (TESSERA_REPRODUCE_SECONDS, or twice what \
         four book covers take on this machine)",
        "budget",
    );
    assert!(!dir.join("again.png").exists());
    let o = run_in_env(&["reproduce", "one.png", "-q", "--any-cost"], &budget, &dir);
    assert!(
        stdout(&o).starts_with("identical:"),
        "{}{}",
        stdout(&o),
        stderr(&o)
    );
    // One pixel of 400 million samples: the probe draws its samples' indices, and the
    // budget stops a pixel within 4,096 of them. (At one cover path's cost a sample it is
    // 0.83 covers' work, under the 4 reproduce renders unasked with room to spare: four
    // billion samples were once refused up front in CI, when the probe timed paths by the
    // wall clock and a busy machine had them at 3.0 times the cover's.)
    std::fs::write(
        dir.join("dot.toml"),
        "[image]\nwidth = 1\nheight = 1\nsamples_per_pixel = 400000000\nmax_depth = 1\n",
    )
    .unwrap();
    ok(
        &["render", "dot.toml", "--spp", "1", "-q", "-o", "dot1.png"],
        &dir,
    );
    let mut recipe = recipe_json(&dir, "dot1.png");
    recipe["overrides"] = serde_json::json!({});
    recipe["image"]["samples_per_pixel"] = 400_000_000u64.into();
    let dot = std::fs::read(dir.join("dot1.png")).unwrap();
    std::fs::write(dir.join("dot.png"), png_with_recipe(&dot, &recipe)).unwrap();
    let started = std::time::Instant::now();
    let half = [("TESSERA_REPRODUCE_SECONDS", "0.5")];
    let o = run_in_env(&["reproduce", "dot.png", "-q"], &half, &dir);
    refused(&o, "stopped after", "one pixel of many samples");
    assert!(started.elapsed().as_secs() < 30, "{:?}", started.elapsed());
    // Zero is refused as no budget at all, and said so ("between 0 and 10⁹" once).
    for bad in ["soon", "0", "-1", "nan", "1e10"] {
        let o = run_in_env(
            &["reproduce", "sixteen.png", "-q"],
            &[("TESSERA_REPRODUCE_SECONDS", bad)],
            &dir,
        );
        refused(
            &o,
            "`TESSERA_REPRODUCE_SECONDS`: must be a number of seconds above 0, at most 10⁹",
            bad,
        );
    }
}

/// A scene's generators skip draws one at a time: a 2 KB scene (or recipe) of textures each
/// skipping 2³² draws once took a CPU-minute per four of them. Each skip and their sum are
/// bounded, and the refusal names the texture that goes over, before its draws are made.
#[test]
fn a_scene_of_many_long_skips_is_refused_at_the_one_over_the_limit() {
    let dir = temp_dir("hostile-skip");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    let base = std::fs::read_to_string(scene_path("img-1.12-metal-fuzz.toml")).unwrap();
    let noise = |i: usize, skip: u64| {
        format!(
            "\n[textures.n{i:02}]\ntype = \"noise\"\nnoise = \"perlin\"\nscale = 4.0\nskip = {skip}\n"
        )
    };
    let one_too_far = format!("{base}{}", noise(0, (1 << 24) + 1));
    std::fs::write(dir.join("far.toml"), &one_too_far).unwrap();
    let o = run(
        &["render", "far.toml", "--width", "8", "-q", "-o", "far.png"],
        &dir,
    );
    refused(
        &o,
        "textures.n00.skip`: must be between 0 and 16777216, got 16777217",
        "one skip",
    );
    let many: String = (0..50).map(|i| noise(i, 1 << 23)).collect();
    let many = format!("{base}{many}");
    std::fs::write(dir.join("many.toml"), &many).unwrap();
    let o = run(
        &[
            "render",
            "many.toml",
            "--width",
            "8",
            "-q",
            "-o",
            "many.png",
        ],
        &dir,
    );
    refused(
        &o,
        "field `textures.n02.skip`: the scene's generators would skip 25165824 draws in all, \
         at most 16777216",
        "fifty skips",
    );
    let line = many.lines().position(|l| l == "[textures.n02]").unwrap() + 5;
    assert!(
        stderr(&o).contains(&format!("many.toml:{line}:")),
        "{}",
        stderr(&o)
    );
    // The same scene in a recipe is refused the same way by `reproduce`.
    let mut recipe = recipe_json(&dir, "a.png");
    recipe["scene"]["text"] = many.as_str().into();
    std::fs::write(dir.join("skips.png"), png_with_recipe(&png, &recipe)).unwrap();
    let o = run(&["reproduce", "skips.png"], &dir);
    refused(&o, "would skip 25165824 draws in all", "reproduce");
    assert!(!dir.join("far.png").exists() && !dir.join("many.png").exists());
}

// --- files that are not files -------------------------------------------------------------

#[test]
fn pipes_and_devices_named_as_inputs_are_refused_not_waited_on() {
    let dir = temp_dir("hostile-fifo");
    rendered(&dir, "a.png");
    let made = Command::new("mkfifo").arg(dir.join("fifo.png")).status();
    if !made.is_ok_and(|s| s.success()) {
        return skip("pipes_and_devices_named_as_inputs", "mkfifo is missing");
    }
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.png")).unwrap();
    for (name, why) in [
        ("fifo.png", "is a pipe (FIFO)"),
        ("zero.png", "is a device"),
    ] {
        for args in [
            &["info", name][..],
            &["reproduce", name],
            &["merge", name, "-o", "m.png"],
            &["compare", "a.png", name],
            &["render", name, "-o", "r.png"],
            &["bench", name, "--no-save"],
        ] {
            // A FIFO with no writer: opened for reading the usual way, it waits forever.
            let o = output_within_a_minute(
                tessera().args(args).current_dir(&dir),
                &format!("{args:?} (on the pipe)"),
            );
            refused(&o, why, &format!("{args:?}"));
        }
    }
}

#[cfg(feature = "results")]
#[test]
fn a_pipe_named_as_a_result_to_import_is_refused() {
    let dir = temp_dir("hostile-fifo-import");
    let made = Command::new("mkfifo").arg(dir.join("r.json")).status();
    if !made.is_ok_and(|s| s.success()) {
        return skip("a_pipe_named_as_a_result_to_import", "mkfifo is missing");
    }
    let o = run(&["results", "import", "r.json", "--db", "r.db"], &dir);
    refused(&o, "is a pipe (FIFO)", "results import");
}

// --- output --------------------------------------------------------------------------------

#[test]
fn a_link_planted_where_the_temporary_file_goes_is_never_followed() {
    let dir = temp_dir("hostile-planted");
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, "precious").unwrap();
    // The names of the temporary files the old scheme used (`.NAME.tmp-PID`) for the next
    // few hundred process ids, each a link to the victim; and the output's own name too.
    let mut next = Command::new("true").spawn().unwrap();
    let pid = next.id();
    next.wait().unwrap();
    let out_dir = dir.join("shared");
    std::fs::create_dir(&out_dir).unwrap();
    for p in pid..pid + 400 {
        for name in ["out.png", "out.exr"] {
            let _ = std::os::unix::fs::symlink(&victim, out_dir.join(format!(".{name}.tmp-{p}")));
        }
    }
    std::os::unix::fs::symlink(&victim, out_dir.join("out.png")).unwrap();
    for name in ["out.png", "out.exr"] {
        ok(
            &[
                "render",
                scene_path("img-1.12-metal-fuzz.toml").to_str().unwrap(),
                "--width",
                "16",
                "--spp",
                "1",
                "-q",
                "-o",
                &format!("shared/{name}"),
            ],
            &dir,
        );
    }
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
    // The output replaced the link with a file of its own.
    let out = out_dir.join("out.png");
    assert!(std::fs::symlink_metadata(&out).unwrap().is_file());
    assert!(std::fs::read(&out).unwrap().starts_with(b"\x89PNG"));
    // No temporary file is left behind.
    let leftover: Vec<_> = std::fs::read_dir(&out_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftover.is_empty(), "{leftover:?}");
}

#[test]
fn info_and_reproduce_end_quietly_on_a_closed_pipe_and_fail_on_a_full_disk() {
    let dir = temp_dir("hostile-pipe");
    rendered(&dir, "a.png");
    for args in [
        &["info", "a.png"][..],
        &["info", "--json", "a.png"],
        &["reproduce", "a.png", "-q"],
    ] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = tessera()
            .args(args)
            .current_dir(&dir)
            .stdout(Stdio::from(writer))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert!(o.stderr.is_empty(), "{args:?}: {}", stderr(&o));
        let full = std::fs::File::create("/dev/full").unwrap();
        let o = tessera()
            .args(args)
            .current_dir(&dir)
            .stdout(Stdio::from(full))
            .output()
            .unwrap();
        refused(
            &o,
            "could not write to standard output",
            &format!("{args:?}"),
        );
    }
}

// --- imported results -----------------------------------------------------------------------

/// A quick benchmark result of the cover, written to `dir/r.json` and read back.
#[cfg(feature = "results")]
fn bench_result(dir: &Path) -> serde_json::Value {
    ok(
        &[
            "bench",
            &cover(),
            "--width",
            "48",
            "--spp",
            "1",
            "--repeat",
            "1",
            "--warmup",
            "0",
            "--no-scaling",
            "--no-save",
            "--out",
            "r.json",
        ],
        dir,
    );
    serde_json::from_slice(&std::fs::read(dir.join("r.json")).unwrap()).unwrap()
}

#[cfg(feature = "results")]
#[test]
fn unknown_fields_inside_host_and_build_are_refused() {
    let dir = temp_dir("hostile-result-fields");
    let good = bench_result(&dir);
    for part in ["host", "build"] {
        let mut v = good.clone();
        v[part]["surprise"] = 1.into();
        let file = format!("{part}.json");
        std::fs::write(dir.join(&file), serde_json::to_vec(&v).unwrap()).unwrap();
        let o = run(&["results", "import", &file, "--db", "r.db"], &dir);
        refused(&o, "unknown field `surprise`", part);
    }
    assert!(
        !dir.join("r.db").exists() || {
            let o = run(&["results", "list", "--db", "r.db"], &dir);
            stdout(&o).trim() == "no results"
        }
    );
}

#[cfg(feature = "results")]
#[test]
fn the_report_shows_bidirectional_and_invisible_characters_escaped() {
    let dir = temp_dir("hostile-result-bidi");
    let mut v = bench_result(&dir);
    // Read right to left, "Intel\u{202e}9 noziR DMA" shows as another CPU's name.
    v["host"]["cpu_model"] = "Intel\u{202e}9 noziR DMA\u{2066}\u{200b}\u{feff}\u{61c}".into();
    std::fs::write(dir.join("evil.json"), serde_json::to_vec(&v).unwrap()).unwrap();
    let o = run(&["results", "import", "evil.json", "--db", "r.db"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    for args in [
        &[
            "results",
            "report",
            "--all",
            "--db",
            "r.db",
            "-o",
            "report.html",
        ][..],
        &["results", "list", "--db", "r.db"],
        &["results", "rank", "--all", "--db", "r.db"],
    ] {
        let o = run(args, &dir);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        let shown = format!("{}{}", stdout(&o), stderr(&o));
        let page = std::fs::read_to_string(dir.join("report.html")).unwrap_or_default();
        for c in ['\u{202e}', '\u{2066}', '\u{200b}', '\u{feff}', '\u{61c}'] {
            assert!(!shown.contains(c), "{args:?} shows {c:?} raw: {shown}");
            assert!(!page.contains(c), "the report shows {c:?} raw");
        }
    }
    let page = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(
        page.contains("Intel\\u{202e}9 noziR DMA"),
        "the CPU is not named"
    );
}

// --- Image textures ---------------------------------------------------------------------------

/// A scene with one image texture, `file`, on a sphere.
fn textured_scene(file: &str) -> String {
    format!(
        "[image]\nwidth = 16\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 4\n\
         [textures.t]\ntype = \"image\"\nfile = \"{file}\"\n\
         [materials.m]\ntype = \"lambertian\"\nalbedo = \"t\"\n\
         [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"m\"\n"
    )
}

/// Each texture may have 2^25 pixels (96 MiB of RGB), and one 98 KB PNG of that size named
/// by forty textures once took forty decodes and aborted out of memory. A file named again
/// is read once, and all of a scene's files together have at most 2^26 pixels.
#[test]
fn many_textures_of_one_large_file_decode_it_once_and_all_files_share_a_bound() {
    let dir = temp_dir("hostile-texture-total");
    image::RgbImage::new(8192, 4096)
        .save(dir.join("big.png"))
        .unwrap();
    for copy in ["big2.png", "big3.png"] {
        std::fs::copy(dir.join("big.png"), dir.join(copy)).unwrap();
    }
    let scene = |files: &[&str]| {
        let mut s =
            String::from("[image]\nwidth = 16\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 4\n");
        for (i, file) in files.iter().enumerate() {
            s += &format!(
                "[textures.t{i}]\ntype = \"image\"\nfile = \"{file}\"\n\
                 [materials.m{i}]\ntype = \"lambertian\"\nalbedo = \"t{i}\"\n\
                 [[spheres]]\ncenter = [{i}.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"m{i}\"\n"
            );
        }
        s
    };
    // Renders the scene of `files` as `name`.toml to `name`.png, under a 1 GiB cap.
    let render = |name: &str, files: &[&str]| {
        std::fs::write(dir.join(format!("{name}.toml")), scene(files)).unwrap();
        let (toml, png) = (format!("{name}.toml"), format!("{name}.png"));
        run_capped(&["render", &toml, "-q", "-o", &png], &dir, 1024)
    };
    let o = render("forty", &["big.png"; 40]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The same file however spelt is one file: two of 2^25 pixels fill the 2^26.
    let o = render("spelt", &["big.png", "./big.png", "big2.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = render("three", &["big.png", "big2.png", "big3.png"]);
    refused(
        &o,
        "field `textures.t2.file`: ",
        "a third file of 2^25 pixels",
    );
    assert!(
        stderr(&o).contains(
            "big3.png: is 8192x4096: more than the 0 pixels the scene's other \
                             texture files leave of the 67108864"
        ),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("three.png").exists());
}

/// What a PNG holds before its pixels is read before its size is: a 1 MB PNG of 16 pixels
/// whose colour profile inflates to 1 GiB took 532 MB as a texture, and a 200 MB PNG of 16
/// pixels and 17 million text chunks 1.6 GB in `compare`. A texture's header is read within
/// 16 MiB, and a PNG of more chunks than a PNG tessera reads may have is refused.
#[test]
fn a_png_s_profile_and_text_before_its_pixels_are_read_within_bounds() {
    let dir = temp_dir("hostile-png-metadata");
    let small = dir.join("small.png");
    image::RgbImage::from_pixel(4, 4, image::Rgb([128, 128, 128]))
        .save(&small)
        .unwrap();
    let png = std::fs::read(&small).unwrap();
    let mut profile = b"p\0\0".to_vec();
    profile.extend(fdeflate::compress_to_vec(&vec![0u8; 256 << 20]));
    std::fs::write(
        dir.join("profile.png"),
        png_with_chunks(&png, &png_chunk(b"iCCP", &profile)),
    )
    .unwrap();
    let text = png_chunk(b"tEXt", b"k\0v").repeat(70_000);
    std::fs::write(dir.join("text.png"), png_with_chunks(&png, &text)).unwrap();
    std::fs::write(dir.join("profile.toml"), textured_scene("profile.png")).unwrap();
    let o = run_capped(&["render", "profile.toml", "-q", "-o", "p.png"], &dir, 256);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(dir.join("text.toml"), textured_scene("text.png")).unwrap();
    let o = run_capped(&["render", "text.toml", "-q", "-o", "t.png"], &dir, 256);
    refused(
        &o,
        "field `textures.t.file`: text.png: has more than 65536 chunks",
        "texture",
    );
    assert!(!dir.join("t.png").exists());
    let o = run_capped(&["compare", "text.png", "small.png"], &dir, 256);
    refused(&o, "text.png: has more than 65536 chunks", "compare");
}

/// A PNG texture of 170 bytes whose IHDR claims 5792x5792 16-bit RGBA pixels (within the
/// 2^25 a texture may have) and whose pixels' stream holds two rows: its decoder was handed
/// 268 MB for the rows claimed before it found them missing, and under a cap of 256 MiB
/// tessera ended there ("memory allocation of 268378112 bytes failed", exit 134). The stream
/// is inflated first, and one that ends before its rows is refused (exit 2), as `compare`
/// refuses it.
#[test]
fn a_png_texture_claiming_more_rows_than_its_stream_holds_is_refused_undecoded() {
    let dir = temp_dir("hostile-png-texture-rows");
    let side = 5792u32;
    let mut ihdr = side.to_be_bytes().to_vec();
    ihdr.extend(side.to_be_bytes());
    ihdr.extend([16, 6, 0, 0, 0]);
    let rows = vec![0u8; 2 * (1 + side as usize * 8)];
    let png = [
        &b"\x89PNG\r\n\x1a\n"[..],
        &png_chunk(b"IHDR", &ihdr),
        &png_chunk(b"IDAT", &fdeflate::compress_to_vec(&rows)),
        &png_chunk(b"IEND", b""),
    ]
    .concat();
    std::fs::write(dir.join("claims.png"), png).unwrap();
    std::fs::write(dir.join("claims.toml"), textured_scene("claims.png")).unwrap();
    let o = run_capped(&["render", "claims.toml", "-q", "-o", "out.png"], &dir, 256);
    refused(
        &o,
        "field `textures.t.file`: claims.png: has pixels that do not decode: a zlib stream \
         that inflates to 92674 bytes, fewer than the 268383904 its image's rows take",
        "claims.png",
    );
    assert!(!dir.join("out.png").exists());
}

#[test]
fn texture_files_a_stranger_names_are_refused_with_the_reason_within_bounds() {
    let dir = temp_dir("hostile-textures");
    let earth = std::fs::read(root().join("scenes/earthmap.jpg")).unwrap();
    // Cut where its scan begins: headers and no pixels. (A JPEG cut inside its scan is refused
    // too, by `textures`' own test: it has no end marker.)
    let scan = (0..earth.len() - 1)
        .find(|&i| earth[i] == 0xFF && earth[i + 1] == 0xDA)
        .expect("a scan");
    std::fs::write(dir.join("truncated.jpg"), &earth[..scan]).unwrap();
    // A JPEG whose frame header claims 65535 x 65535 pixels (4 G pixels): refused from the
    // header, before anything of that size is allocated.
    let mut huge = earth.clone();
    let sof = (0..huge.len() - 1)
        .find(|&i| huge[i] == 0xFF && (huge[i + 1] == 0xC0 || huge[i + 1] == 0xC2))
        .expect("a frame header");
    huge[sof + 5..sof + 9].copy_from_slice(&[0xFF, 0xFF, 0xFF, 0xFF]);
    std::fs::write(dir.join("huge.jpg"), &huge).unwrap();
    std::fs::write(dir.join("text.jpg"), b"not an image at all").unwrap();
    std::fs::create_dir_all(dir.join("folder.jpg")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.jpg")).unwrap();
    let fifo = Command::new("mkfifo")
        .arg(dir.join("fifo.jpg"))
        .status()
        .is_ok_and(|s| s.success());
    let mut cases = vec![
        (
            "truncated.jpg",
            "truncated.jpg: is a JPEG that ends before its image does",
        ),
        ("huge.jpg", "65535x65535: a texture must have between 1 and"),
        ("text.jpg", "is not an image tessera reads"),
        ("folder.jpg", "folder.jpg"),
        // A link to a device: it leads out of the scene's directory, refused before it is opened.
        (
            "zero.jpg",
            "zero.jpg leads out of . (a symbolic link): refused",
        ),
        (
            "../earthmap.jpg",
            "must be a relative file name without `..`",
        ),
        ("/etc/passwd", "must be a relative file name without `..`"),
        ("missing.jpg", "texture file `missing.jpg` not found"),
    ];
    if fifo {
        cases.push(("fifo.jpg", "is a pipe (FIFO)"));
    }
    for (file, why) in cases {
        let scene = format!("{}.toml", file.replace(['/', '.'], "_"));
        std::fs::write(dir.join(&scene), textured_scene(file)).unwrap();
        // In 1 GiB of address space: what the huge header claims would need 12 GiB.
        let o = run_capped(&["render", &scene, "-o", "out.png"], &dir, 1024);
        refused(&o, why, file);
        assert!(
            stderr(&o).contains(&scene),
            "{file}: the message names the scene: {}",
            stderr(&o)
        );
        assert!(!dir.join("out.png").exists(), "{file}: no output");
    }
}

#[test]
fn a_stranger_s_scene_or_recipe_reads_nothing_outside_and_holds_its_size() {
    let dir = temp_dir("hostile-reach");
    let png = std::fs::read(rendered(&dir, "a.png")).unwrap();
    // A recipe naming texture files outside every directory it is given.
    let mut recipe = recipe_json(&dir, "a.png");
    for name in ["/etc/passwd", "../../../../etc/hostname"] {
        recipe["textures"] = serde_json::json!([{
            "name": name,
            "hash": "xxh3-128:00000000000000000000000000000000"
        }]);
        std::fs::write(dir.join("reach.png"), png_with_recipe(&png, &recipe)).unwrap();
        refused(
            &run(&["reproduce", "reach.png"], &dir),
            "which is not a relative name without `..`: refused",
            name,
        );
    }
    // A texture that a symbolic link leads out of the scene's directory.
    let outside = temp_dir("hostile-reach-outside");
    std::fs::copy(
        root().join("scenes/earthmap.jpg"),
        outside.join("earth.jpg"),
    )
    .unwrap();
    std::os::unix::fs::symlink(outside.join("earth.jpg"), dir.join("earth.jpg")).unwrap();
    std::fs::write(dir.join("linked.toml"), textured_scene("earth.jpg")).unwrap();
    refused(
        &run(&["render", "linked.toml", "-o", "linked.png"], &dir),
        "leads out of",
        "a linked texture",
    );
    assert!(!dir.join("linked.png").exists());
    // Clouds whose spheres would be more than a scene may hold: refused before any is drawn.
    let cloud = "[[random_sphere_clouds]]\ncount = 1048576\nmin = [0, 0, 0]\nmax = [1, 1, 1]\n\
                 radius = 0.01\nmaterial = \"m\"\n";
    let clouds = format!(
        "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 1\n\
         [materials.m]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n{}",
        cloud.repeat(40)
    );
    std::fs::write(dir.join("clouds.toml"), &clouds).unwrap();
    let o = run_capped(&["render", "clouds.toml", "-o", "c.png"], &dir, 1024);
    refused(
        &o,
        "random_sphere_clouds[1].count`: would make the scene's primitives (spheres and quads; \
         a box is six) 2097152",
        "clouds",
    );
    // The cover's grid at its largest (four million spheres, each with its own material,
    // took 1 GB from 1.3 KB), and quads beside a full cloud, are weighed the same way.
    let cover = std::fs::read_to_string(scene_path("cover.toml")).unwrap();
    let grid = cover.replace("grid = 11", "grid = 1000");
    assert_ne!(grid, cover);
    std::fs::write(dir.join("grid.toml"), &grid).unwrap();
    let o = run_capped(&["render", "grid.toml", "-o", "g.png"], &dir, 1024);
    refused(
        &o,
        "field `random_spheres.grid`: would make the scene's primitives (spheres and quads; a \
         box is six) 4000004",
        "grid",
    );
    let boxes = format!(
        "{}[[random_boxes]]\ncorner = [0.0, 0.0, 0.0]\ncount = [1000, 100]\nsize = 1.0\n\
         top = [1.0, 2.0]\nmaterial = \"m\"\n",
        cloud.replace("count = 1048576", "count = 1000000")
    );
    let boxes = format!(
        "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 1\n\
         [materials.m]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n{boxes}"
    );
    std::fs::write(dir.join("boxes.toml"), &boxes).unwrap();
    let o = run_capped(&["render", "boxes.toml", "-o", "b.png"], &dir, 1024);
    refused(
        &o,
        "more than the 1048576 a scene may hold",
        "boxes and a cloud",
    );
    // -o naming the image being checked: refused, the image left as it was.
    refused(
        &run(&["reproduce", "a.png", "-o", "./a.png"], &dir),
        "names the image being checked",
        "reproduce -o itself",
    );
    // So is --extract-scene naming it, which once wrote the scene's text over the image.
    refused(
        &run(&["reproduce", "a.png", "--extract-scene", "./a.png"], &dir),
        "--extract-scene ./a.png names the image being checked",
        "reproduce --extract-scene itself",
    );
    assert_eq!(std::fs::read(dir.join("a.png")).unwrap(), png);
}

/// The TOML parser keeps 150 to 500 bytes for each value, table and array with its place:
/// a 12 MB array of numbers took 900 MB, 3 MB of inline tables 700 MB, before any check of
/// ours. Their count is bounded before the parser sees the text (a recipe's scene, at most
/// 1 MiB, is within it), and the refusal points at where the count goes over.
#[test]
fn a_scene_of_millions_of_small_values_is_refused_before_it_is_parsed() {
    let dir = temp_dir("hostile-values");
    let head = "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 1\n\
                [materials.m]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n";
    let numbers = format!("{head}junk = [{}]\n", vec!["1"; 6_000_000].join(","));
    std::fs::write(dir.join("numbers.toml"), &numbers).unwrap();
    let o = run_capped(&["render", "numbers.toml", "-o", "n.png"], &dir, 200);
    refused(
        &o,
        "numbers.toml:9:2097128: more than 1048576 values, tables and arrays",
        "numbers",
    );
    let tables = format!("{head}junk = [{}]\n", vec!["{a=1}"; 600_000].join(","));
    std::fs::write(dir.join("tables.toml"), &tables).unwrap();
    let o = run_capped(&["render", "tables.toml", "-o", "t.png"], &dir, 200);
    refused(&o, "tables.toml:9:", "inline tables");
    assert!(
        stderr(&o).contains("more than 1048576 values"),
        "{}",
        stderr(&o)
    );
    // Commas in a string are not values: a long string is only its bytes.
    let string = format!("# {}\n{head}", ",".repeat(3_000_000));
    std::fs::write(dir.join("string.toml"), &string).unwrap();
    ok(&["render", "string.toml", "-q", "-o", "s.png"], &dir);
    assert!(!dir.join("n.png").exists() && !dir.join("t.png").exists());
}

/// The TOML parser lexes the whole text before it parses any of it, keeping 48 bytes for
/// each token: 60 MB of empty lines took 2.9 GB and rendered, 60 MB of bare carriage
/// returns 2.9 GB before the error on the first. Line ends, words, strings, comments and
/// runs of blanks are counted with the values, and refused past 2^22 where they go over.
#[test]
fn a_scene_of_millions_of_empty_lines_or_words_is_refused_before_it_is_parsed() {
    let dir = temp_dir("hostile-tokens");
    let head = "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 1\n";
    let cases = [
        ("lines", "\n".repeat(20_000_000), "lines.toml:4194287:1: "),
        (
            "returns",
            "\r".repeat(20_000_000),
            "returns.toml:6:4194282: ",
        ),
        ("words", "a ".repeat(10_000_000), "words.toml:6:4194282: "),
        (
            "comments",
            "#\n".repeat(10_000_000),
            "comments.toml:2097146:2: ",
        ),
    ];
    for (name, tail, at) in cases {
        let file = format!("{name}.toml");
        std::fs::write(dir.join(&file), format!("{head}{tail}")).unwrap();
        let o = run_capped(&["render", &file, "-o", "out.png"], &dir, 512);
        refused(
            &o,
            &format!("{at}more than 4194304 words, strings, comments, line ends, runs"),
            name,
        );
    }
    assert!(!dir.join("out.png").exists());
    // Within the bound, blank lines are only blank lines.
    let blank = format!("{head}{}", "\n".repeat(4_000_000));
    std::fs::write(dir.join("blank.toml"), blank).unwrap();
    ok(&["render", "blank.toml", "-q", "-o", "blank.png"], &dir);
}

/// The count once read a string on one line on to the next quote, lines later, a comment
/// on past a carriage return, a quote inside a word as a string's start and a run of `]`
/// as one word, where the TOML lexer, which lexes the whole text first, reads a token each:
/// 16 MB hidden so took 1.2 GB, 60 MB of `]` 2.9 GB.
#[test]
fn what_the_lexer_reads_as_tokens_the_count_reads_as_tokens() {
    let dir = temp_dir("hostile-hidden-tokens");
    let head = "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 1\n";
    let values = format!("v = [{}]\n", "1,".repeat(3_000_000));
    let cases = [
        (
            "string",
            format!("a = \"\n{values}# \"\n"),
            "1048576 values",
        ),
        ("literal", format!("a = '\n{values}# '\n"), "1048576 values"),
        ("word", format!("a = b\"\n{values}# \"\n"), "1048576 values"),
        ("comment", format!("# \r{values}"), "1048576 values"),
        (
            "brackets",
            format!("a = {}\n", "]".repeat(20_000_000)),
            "4194304 words",
        ),
    ];
    for (name, tail, what) in cases {
        let file = format!("{name}.toml");
        std::fs::write(dir.join(&file), format!("{head}{tail}")).unwrap();
        let o = run_capped(&["render", &file, "-o", "out.png"], &dir, 512);
        refused(&o, &format!("more than {what}"), name);
    }
    assert!(!dir.join("out.png").exists());
}

#[test]
fn a_long_chain_of_checkers_is_checked_in_linear_time_and_a_long_cycle_found() {
    let dir = temp_dir("hostile-chain");
    // t0000 -> t0001 -> ... -> t4999; with `cycle`, the last leads back to the first.
    let chain = |n: usize, cycle: bool| {
        let mut t = String::from(
            "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 2\n\
             [materials.m]\ntype = \"lambertian\"\nalbedo = \"t0000\"\n\
             [[spheres]]\ncenter = [0, 0, -1]\nradius = 0.5\nmaterial = \"m\"\n",
        );
        for i in 0..n {
            let next = if i + 1 < n {
                format!("\"t{:04}\"", i + 1)
            } else if cycle {
                "\"t0000\"".to_owned()
            } else {
                "[1, 1, 1]".to_owned()
            };
            t.push_str(&format!(
                "[textures.t{i:04}]\ntype = \"checker\"\neven = {next}\n\
                 odd = [0, 0, 0]\n"
            ));
        }
        t
    };
    // Cubic before: 5000 textures took hours; now a fraction of a second, and refused as
    // deeper than a hit may walk (`MAX_CHECKER_DEPTH`), a check linear in the textures too.
    std::fs::write(dir.join("chain.toml"), chain(5000, false)).unwrap();
    refused(
        &run(&["render", "chain.toml", "-o", "chain.png"], &dir),
        "field `textures.t0000`: its squares lead through 5000 checkers, more than the 16",
        "a chain of 5000",
    );
    // As deep as a hit may walk, a chain renders.
    std::fs::write(dir.join("chain.toml"), chain(16, false)).unwrap();
    ok(&["render", "chain.toml", "-o", "chain.png", "-q"], &dir);
    std::fs::write(dir.join("cycle.toml"), chain(3000, true)).unwrap();
    refused(
        &run(&["render", "cycle.toml", "-o", "cycle.png"], &dir),
        "field `textures.t0000`: a checker's squares lead back to itself",
        "a cycle of 3000",
    );
}

/// A checker's square may be another checker, and every hit walks the chain to its colour:
/// a 9 MB chain of 150,000 checkers took 19 s for a 32×32 image of 2 samples a pixel (the
/// same scene with one checker: milliseconds), some 42 hours at 400×400 and 100 samples. A
/// hit passes through at most `MAX_CHECKER_DEPTH` (16) checkers; the first texture of the
/// file that leads through more is refused by name. What counts is the depth, not the
/// count: a tree of many checkers, 16 deep, renders.
#[test]
fn a_chain_of_checkers_deeper_than_a_hit_may_walk_is_refused() {
    let dir = temp_dir("hostile-checker-depth");
    let head = "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 2\n\
                [materials.m]\ntype = \"lambertian\"\nalbedo = \"a00\"\n\
                [[spheres]]\ncenter = [0, 0, -1]\nradius = 0.5\nmaterial = \"m\"\n";
    // a00 -> a01 -> ... -> a{depth-1}, each checker's odd square a second chain b{i} ->
    // b{i+1} of the same length from there, so that the deepest path is `depth` long and the
    // textures about twice as many.
    let tree = |depth: usize| {
        let mut t = head.to_owned();
        for i in 0..depth {
            let next = |p: &str| {
                if i + 1 < depth {
                    format!("\"{p}{:02}\"", i + 1)
                } else {
                    "[1, 1, 1]".to_owned()
                }
            };
            t.push_str(&format!(
                "[textures.a{i:02}]\ntype = \"checker\"\neven = {}\nodd = {}\n\
                 [textures.b{i:02}]\ntype = \"checker\"\neven = {}\nodd = [0, 0, 0]\n",
                next("a"),
                next("b"),
                next("b")
            ));
        }
        t
    };
    std::fs::write(dir.join("within.toml"), tree(16)).unwrap();
    ok(&["render", "within.toml", "-o", "within.png", "-q"], &dir);
    std::fs::write(dir.join("over.toml"), tree(17)).unwrap();
    refused(
        &run(&["render", "over.toml", "-o", "over.png"], &dir),
        "field `textures.a00`: its squares lead through 17 checkers, more than \
         the 16 a texture may nest",
        "a tree 17 deep",
    );
    assert!(!dir.join("over.png").exists());
}

/// Two generators of 100,000 boxes each (1.2 million quads, past the 2^20 a scene holds):
/// the second was refused only after its 600,000 quads were built (1.3 s, 204 MB, its table
/// named). Every generator's count is weighed before any box is drawn, and the one that goes
/// over is refused at its count, as a cloud's is.
#[test]
fn box_generators_are_weighed_before_any_box_is_drawn() {
    let dir = temp_dir("hostile-random-boxes");
    let mut text = String::from(
        "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 2\n\
         [materials.m]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n",
    );
    for _ in 0..2 {
        text.push_str(
            "[[random_boxes]]\ncorner = [-1000.0, -101.0, -1000.0]\ncount = [1000, 100]\n\
             size = 1.0\ntop = [-100.0, -99.0]\nmaterial = \"m\"\n",
        );
    }
    std::fs::write(dir.join("boxes.toml"), text).unwrap();
    // The second generator's count, on line 17: refused there, before the first is drawn
    // (within 64 MiB of address space, where the first's quads alone take about 100 MB).
    refused(
        &run_capped(&["render", "boxes.toml", "-o", "boxes.png"], &dir, 64),
        "boxes.toml:17:9: field `random_boxes[1].count`: would make the scene's primitives \
         (spheres and quads; a box is six) 1200000",
        "two generators of 100,000 boxes",
    );
    assert!(!dir.join("boxes.png").exists());
}

/// Each noise texture draws its own 4.8 KB of tables: 250,000 of them, 12 MB of scene within
/// its bound on values, once took 1.5 GB. A scene has at most 4,096, and the one over is
/// refused by name before its tables are drawn.
#[test]
fn a_scene_of_many_noise_textures_is_refused_at_the_one_over_the_bound() {
    let dir = temp_dir("hostile-noises");
    let noises = |n: usize| {
        let mut t = String::from(
            "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 2\n\
             [materials.m]\ntype = \"lambertian\"\nalbedo = \"t0000\"\n\
             [[spheres]]\ncenter = [0, 0, -1]\nradius = 0.5\nmaterial = \"m\"\n",
        );
        for i in 0..n {
            t.push_str(&format!(
                "[textures.t{i:04}]\ntype = \"noise\"\nnoise = \"perlin\"\nseed = {i}\n"
            ));
        }
        t
    };
    std::fs::write(dir.join("within.toml"), noises(4096)).unwrap();
    ok(&["render", "within.toml", "-o", "within.png", "-q"], &dir);
    std::fs::write(dir.join("over.toml"), noises(4097)).unwrap();
    refused(
        &run(&["render", "over.toml", "-o", "over.png"], &dir),
        "field `textures.t4096`: is one noise texture more than the 4096 a scene may have",
        "4097 noise textures",
    );
    assert!(!dir.join("over.png").exists());
}

/// A part file is read by `merge` and by a resumed checkpoint. A sparse one takes a few KiB
/// of disk whatever length it has, so its header may claim a terabyte: a reader that sized a
/// buffer by the claim once aborted (the allocation failed). The header is parsed as it is
/// read, and the hole's zeros end the parse at once.
#[test]
fn a_sparse_part_whose_header_claims_a_terabyte_is_refused_without_reading_it() {
    use std::io::Write;
    let dir = temp_dir("hostile-sparse-part");
    let len: u64 = 1 << 40;
    let mut file = std::fs::File::create(dir.join("sparse.part")).unwrap();
    file.write_all(b"TESSERA-PARTIAL\n").unwrap();
    file.write_all(&(len - 64).to_le_bytes()).unwrap();
    file.set_len(len).unwrap();
    std::fs::write(dir.join("out.png"), b"precious").unwrap();
    let cover = cover();
    for args in [
        vec!["merge", "sparse.part", "-o", "out.png"],
        vec![
            "render",
            &cover,
            "-q",
            "--width",
            "40",
            "--spp",
            "1",
            "--checkpoint",
            "sparse.part",
            "-o",
            "out.png",
        ],
    ] {
        refused(
            &run_capped(&args, &dir, 1024),
            "sparse.part: has a corrupt header",
            &args.join(" "),
        );
    }
    assert_eq!(std::fs::read(dir.join("out.png")).unwrap(), b"precious");
}

/// An error message quotes what a stranger wrote whole: a scene's unknown key of 60 MiB made
/// a message of 120 MB, one line on the terminal. A message keeps its start (the file, line
/// and field) and its end (why), and says how much between them it leaves out.
#[test]
fn a_message_quoting_a_long_key_or_name_keeps_its_start_and_end() {
    let dir = temp_dir("hostile-long-message");
    let key = "k".repeat(1 << 20);
    let scene = format!(
        "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 1\n{key} = 1\n"
    );
    std::fs::write(dir.join("key.toml"), scene).unwrap();
    let o = run(&["render", "key.toml", "-o", "k.png"], &dir);
    refused(&o, "key.toml:6:1: field `image.kkkk", "long key");
    let err = stderr(&o);
    assert!(err.len() < 5000, "a message of {} bytes", err.len());
    assert!(err.contains("characters left out) … kkkk"), "{err}");
    assert!(err.trim_end().ends_with("`seed`, `crop`"), "{err}");
    let name = "m".repeat(1 << 20);
    let cover = std::fs::read_to_string(scene_path("cover.toml")).unwrap();
    let named = cover.replacen(
        "material = \"ground\"",
        &format!("material = \"{name}\""),
        1,
    );
    assert_ne!(named, cover);
    std::fs::write(dir.join("name.toml"), named).unwrap();
    let o = run(&["render", "name.toml", "-o", "n.png"], &dir);
    refused(
        &o,
        "field `spheres[0].material`: unknown material `mmmm",
        "long name",
    );
    assert!(
        stderr(&o).len() < 5000,
        "a message of {} bytes",
        stderr(&o).len()
    );
}

/// A scene file that does not exist has the nearest names beside it suggested, by an edit
/// distance that takes the product of the lengths: a name of 100,000 characters (a script's
/// argument) beside 2,000 scene files of 250 took minutes. Names too unlike in length to be
/// near are not measured.
#[test]
fn a_long_missing_scene_name_beside_many_scene_files_is_answered_at_once() {
    let dir = temp_dir("hostile-missing-scene");
    for i in 0..2000 {
        let name = format!("{i:05}{}.toml", "x".repeat(240));
        std::fs::write(dir.join(name), "").unwrap();
    }
    let long = format!("{}.toml", "y".repeat(100_000));
    let started = std::time::Instant::now();
    let o = run(&["render", &long], &dir);
    refused(&o, "yyyy.toml: no such scene file", "long name");
    assert!(started.elapsed().as_secs() < 10, "{:?}", started.elapsed());
    // A name near one of them is still suggested.
    let near = format!("00007{}.toml", "x".repeat(239));
    let o = run(&["render", &near], &dir);
    refused(&o, "did you mean 00007xxx", "near name");
}

/// A part whose recipe's scene (a stranger's text, within the part's checksum) holds a key of
/// 1 MiB: `merge` warns that its image carries no recipe, saying why in a bounded line, not
/// in 2 MB quoting the key twice.
#[test]
fn merge_s_warning_on_a_stranger_s_recipe_is_of_bounded_length() {
    let dir = temp_dir("hostile-merge-warning");
    let scene = scene_path("img-1.12-metal-fuzz.toml");
    let scene = scene.to_str().unwrap();
    let args = ["render", scene, "--width", "16", "--spp", "2", "-q"];
    ok(
        &[&args[..], &["--samples", "0..2", "-o", "a.part"]].concat(),
        &dir,
    );
    part_edited(&dir, "a.part", "b.part", |header| {
        let text = &mut header["render"]["recipe"]["scene"]["text"];
        *text = format!("{}\n{} = 1\n", text.as_str().unwrap(), "k".repeat(1 << 20)).into();
    });
    let o = run(&["merge", "b.part", "-o", "m.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.len() < 5000, "a warning of {} bytes", err.len());
    assert!(err.contains("characters left out"), "{err}");
    assert!(err.contains("m.png carries no recipe"), "{err}");
}

/// Writes `from`'s part in `dir` again as `to`, its header's gamma set to `gamma` (its
/// checksum made anew: it is no secret).
fn part_with_gamma(dir: &Path, from: &str, to: &str, gamma: f64) {
    part_edited(dir, from, to, |header| {
        header["render"]["gamma"] = gamma.into()
    });
}

/// The part `from` in `dir` with its JSON header changed by `edit`, its checksum made again,
/// written as `to`: what anyone can make, the checksum being no secret.
fn part_edited(dir: &Path, from: &str, to: &str, edit: impl Fn(&mut serde_json::Value)) {
    let bytes = std::fs::read(dir.join(from)).unwrap();
    let part = with_part_header(&bytes, |header| {
        let mut header: serde_json::Value = serde_json::from_slice(header).unwrap();
        edit(&mut header);
        serde_json::to_vec(&header).unwrap()
    });
    std::fs::write(dir.join(to), part).unwrap();
}

/// A part's header gives the gamma its image is written with beside the fingerprint its
/// recipe is checked against, and nothing checked the one against the other: a stranger's
/// part of an honest recipe and sums but gamma 0.25 merged into an image written at 0.25
/// that carried the recipe of gamma 2 (`info` said gamma 2; `reproduce` found all 144 pixels
/// differing), and gamma 0 or -1 merged too. A recipe that does not give every setting of
/// the header is now left out with the warning, and a gamma no scene takes is refused.
#[test]
fn a_part_whose_gamma_is_not_its_recipe_s_merges_without_the_recipe() {
    let dir = temp_dir("hostile-merge-gamma");
    let scene = scene_path("img-1.12-metal-fuzz.toml");
    let scene = scene.to_str().unwrap();
    let args = ["render", scene, "--width", "16", "--spp", "2", "-q"];
    ok(
        &[&args[..], &["--samples", "0..2", "-o", "a.part"]].concat(),
        &dir,
    );
    part_with_gamma(&dir, "a.part", "quarter.part", 0.25);
    let o = run(&["merge", "quarter.part", "-o", "q.png"], &dir);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("does not describe them"), "{err}");
    assert!(err.contains("q.png carries no recipe"), "{err}");
    for (gamma, says) in [(0.0, "gamma 0 "), (-1.0, "gamma -1 ")] {
        part_with_gamma(&dir, "a.part", "bad.part", gamma);
        let o = run(&["merge", "bad.part", "-o", "bad.png"], &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{gamma}: {err}");
        assert!(
            err.contains("bad.part") && err.contains(says),
            "{gamma}: {err}"
        );
        assert!(!dir.join("bad.png").exists(), "{gamma}");
    }
    let o = run(&["merge", "a.part", "-o", "a.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("carries no recipe"), "{}", stderr(&o));
}

/// A hand-made part whose samples are an empty range (0..0) merged into an image said to be
/// of 0 samples per pixel, exit 0; one whose range goes past the image's samples per pixel
/// likewise claimed more than the image has. Both are refused as inconsistent.
#[test]
fn a_part_of_no_samples_or_more_than_its_image_has_is_refused() {
    let dir = temp_dir("hostile-merge-samples");
    let scene = scene_path("img-1.12-metal-fuzz.toml");
    let scene = scene.to_str().unwrap();
    let args = ["render", scene, "--width", "16", "--spp", "2", "-q"];
    ok(
        &[&args[..], &["--samples", "0..2", "-o", "a.part"]].concat(),
        &dir,
    );
    for (name, end) in [("empty.part", 0), ("beyond.part", 3)] {
        part_edited(&dir, "a.part", name, |h| {
            h["state"]["job"]["samples"]["end"] = end.into();
        });
        let o = run(&["merge", name, "-o", "m.png"], &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains("inconsistent header"),
            "{name}: {err}"
        );
        assert!(!dir.join("m.png").exists(), "{name}");
    }
    let o = run(&["merge", "a.part", "-o", "a.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A checkpoint's header is checked against the render before its sums are read: a header
/// may claim an image of up to 2^28 pixels (6 GiB of sums) on a sparse file of a few KiB, and
/// one of another render was read whole first, then refused (a sparse 1.6 GB checkpoint
/// claiming 8192x8192 pixels, given to a 32x18 render: 9 s and 1.5 GB of memory). Here the
/// sums of a checkpoint of a render 24 pixels wide are corrupt: a render 32 wide is refused
/// for its size, which the header says, not for its sums, which only reading them finds.
#[test]
fn a_checkpoint_of_another_render_is_refused_before_its_sums_are_read() {
    let dir = temp_dir("hostile-checkpoint-header-first");
    let cover = cover();
    let render = |width: &str| {
        let args = ["--spp", "2", "--checkpoint", "ck.part", "-o", "out.png"];
        run(
            &[&["render", &cover, "-q", "--width", width][..], &args].concat(),
            &dir,
        )
    };
    let o = render("24");
    assert!(o.status.success(), "{}", stderr(&o));
    let ck = dir.join("ck.part");
    let mut bytes = std::fs::read(&ck).unwrap();
    // The last sum's last byte: the checksum after it no longer holds.
    let last = bytes.len() - 9;
    bytes[last] ^= 0xff;
    std::fs::write(&ck, &bytes).unwrap();
    refused(
        &render("32"),
        "ck.part: was rendered with a different image size",
        "a checkpoint of another size, its sums corrupt",
    );
    assert_eq!(
        std::fs::read(&ck).unwrap(),
        bytes,
        "the checkpoint was changed"
    );
}

/// A render takes a checkpoint's finished tiles as they are, so whoever wrote the file chose
/// those pixels. In a directory others may write to (`/tmp`), another user could leave a
/// checkpoint of the same scene, with sums of their choosing, under the name a render uses:
/// the render resumed from it ("resuming ... (50.0% done)") and its image carried the
/// stranger's pixels under its own recipe. A checkpoint of another user's is refused; the
/// same file, the user's own again, resumes. Changing a file's owner needs root: elsewhere
/// the test is skipped.
#[test]
fn a_checkpoint_another_user_owns_is_not_resumed() {
    let dir = temp_dir("hostile-strangers-checkpoint");
    let cover = cover();
    let render = |spp: &str| {
        run(
            &[
                "render",
                &cover,
                "-q",
                "--width",
                "24",
                "--spp",
                spp,
                "--checkpoint",
                "ck.part",
                "-o",
                "out.png",
            ],
            &dir,
        )
    };
    let o = render("2");
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::remove_file(dir.join("out.png")).unwrap();
    let me = std::fs::metadata("/proc/self").map(|m| std::os::unix::fs::MetadataExt::uid(&m));
    let ck = dir.join("ck.part");
    if std::os::unix::fs::chown(&ck, Some(65534), Some(65534)).is_err() {
        return skip(
            "a_checkpoint_another_user_owns_is_not_resumed",
            "changing a file's owner needs root",
        );
    }
    refused(
        &render("4"),
        "ck.part: belongs to another user (uid 65534",
        "another user's checkpoint",
    );
    assert!(!dir.join("out.png").exists(), "an image was written");
    std::os::unix::fs::chown(&ck, me.as_ref().ok().copied(), None).unwrap();
    let o = render("4");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("out.png").exists());
    // Another user's link under the name, to a checkpoint that is this user's (or root's):
    // whoever made the link chose which file is resumed. Refused; this user's own link is
    // followed.
    std::fs::remove_file(dir.join("out.png")).unwrap();
    std::fs::rename(&ck, dir.join("kept.part")).unwrap();
    std::os::unix::fs::symlink("kept.part", &ck).unwrap();
    std::os::unix::fs::lchown(&ck, Some(65534), Some(65534)).unwrap();
    refused(
        &render("8"),
        "ck.part: a symbolic link of another user's (uid 65534",
        "another user's link to a checkpoint",
    );
    assert!(!dir.join("out.png").exists(), "an image was written");
    std::os::unix::fs::lchown(&ck, me.ok(), None).unwrap();
    let o = render("8");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("out.png").exists());
}

/// `merge DIR` took every part in the directory, whoever owned it: where a shard failed,
/// another user's part of the same scene left in a shared directory filled the gap (its
/// sums of their choosing, its checksum no secret), and the image was written, "merged 2
/// parts", under the user's recipe. A part another user owns is refused, named or found in
/// a directory, and the image is not written; the same file, the user's own again, merges.
/// Changing a file's owner needs root: elsewhere the test is skipped.
#[test]
fn a_part_another_user_owns_is_not_merged() {
    let dir = temp_dir("hostile-strangers-part");
    std::fs::create_dir_all(dir.join("parts")).unwrap();
    let cover = cover();
    for shard in ["0/2", "1/2"] {
        let name = format!("parts/p{}.part", &shard[..1]);
        let o = run(
            &["render", &cover, "-q", "--width", "24", "--spp", "2"]
                .into_iter()
                .chain(["--shard", shard, "-o", &name])
                .collect::<Vec<_>>(),
            &dir,
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let me = std::fs::metadata("/proc/self").map(|m| std::os::unix::fs::MetadataExt::uid(&m));
    let theirs = dir.join("parts/p1.part");
    if std::os::unix::fs::chown(&theirs, Some(65534), Some(65534)).is_err() {
        return skip(
            "a_part_another_user_owns_is_not_merged",
            "changing a file's owner needs root",
        );
    }
    for named in [&["parts"][..], &["parts/p0.part", "parts/p1.part"]] {
        let args = [&["merge"][..], named, &["-o", "out.png"]].concat();
        refused(
            &run(&args, &dir),
            "p1.part: belongs to another user (uid 65534",
            "another user's part",
        );
        assert!(!dir.join("out.png").exists(), "an image was written");
    }
    std::os::unix::fs::chown(&theirs, me.ok(), None).unwrap();
    let o = run(&["merge", "parts", "-o", "out.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.join("out.png").exists());
}

/// A device is written in place, but a symbolic link another user left under an output's
/// name in a shared directory is not followed to one: a link to a terminal of theirs took
/// the image and its recipe (they read all 6,217 bytes of the PNG from it), the render said
/// it wrote the file, exit 0, and no file was made. Such a link is replaced by the file, as
/// a link to a file is; the device is left as it was. Here the links point at `/dev/null`
/// and `/dev/zero` (where the image vanished). Changing a link's owner needs root: elsewhere the test is
/// skipped.
#[test]
fn an_output_name_that_is_another_users_link_to_a_device_is_not_followed() {
    let dir = temp_dir("hostile-strangers-device-link");
    for (name, device) in [("out.png", "/dev/null"), ("preview.png", "/dev/zero")] {
        let link = dir.join(name);
        std::os::unix::fs::symlink(device, &link).unwrap();
        if std::os::unix::fs::lchown(&link, Some(65534), Some(65534)).is_err() {
            return skip(
                "an_output_name_that_is_another_users_link_to_a_device",
                "changing a link's owner needs root",
            );
        }
    }
    let cover = cover();
    let o = output_within_a_minute(
        tessera()
            .args([
                "render",
                &cover,
                "-q",
                "--width",
                "16",
                "--spp",
                "1",
                "-o",
                "out.png",
                "--preview-file",
                "preview.png",
            ])
            .current_dir(&dir),
        "the render (on another user's links to a device)",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for name in ["out.png", "preview.png"] {
        let meta = std::fs::symlink_metadata(dir.join(name)).unwrap();
        assert!(
            meta.is_file(),
            "{name} is still another user's link: the image went where it points"
        );
        let bytes = std::fs::read(dir.join(name)).unwrap();
        assert!(
            bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{name} holds no PNG"
        );
    }
    use std::os::unix::fs::FileTypeExt;
    for device in ["/dev/null", "/dev/zero"] {
        let meta = std::fs::metadata(device).unwrap();
        assert!(meta.file_type().is_char_device(), "{device} was replaced");
    }
}

/// In a directory where only a file's owner may replace it (sticky, as `/tmp`), another
/// user's file under an output's name cannot be replaced by a user other than root: the
/// render ran to its end and then failed, "out.png: Operation not permitted", its work lost.
/// Refused before the render starts, naming the owner; the file is left as it was. Acting
/// as a second user needs root: elsewhere the test is skipped.
#[test]
fn an_output_name_another_user_holds_in_a_sticky_directory_is_refused_before_the_render() {
    use std::os::unix::fs::PermissionsExt;
    use std::os::unix::process::CommandExt;
    let test = "an_output_name_another_user_holds_in_a_sticky_directory";
    let dir = temp_dir("hostile-strangers-sticky");
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o1777)).unwrap();
    std::fs::write(dir.join("scene.toml"), GOOD).unwrap();
    std::fs::write(dir.join("out.png"), "another user's").unwrap();
    if std::os::unix::fs::chown(dir.join("out.png"), Some(65533), Some(65533)).is_err() {
        return skip(test, "changing a file's owner needs root");
    }
    // The binary, where the second user (65534) may run it.
    let binary = dir.join("tessera");
    std::fs::copy(env!("CARGO_BIN_EXE_tessera"), &binary).unwrap();
    let o = output_within_a_minute(
        Command::new(&binary)
            .args(["render", "scene.toml", "-q", "--spp", "64", "-o", "out.png"])
            .current_dir(&dir)
            .uid(65534)
            .gid(65534),
        "the render (onto another user's file in a sticky directory)",
    );
    refused(
        &o,
        "out.png: belongs to another user (uid 65533",
        "another user's file in a sticky directory",
    );
    assert_eq!(
        std::fs::read(dir.join("out.png")).unwrap(),
        b"another user's"
    );
}

/// An output written in place because it is a pipe (`-o /dev/stdout`, a FIFO) may be a pipe
/// another user made under the name in a shared directory (`/tmp`): the render then waited
/// forever for a reader (killed after 20 s), or, with the other user reading, sent them the
/// image and exited 0 with no file made. Another user's pipe is refused before the render
/// starts. Changing a pipe's owner needs root: elsewhere the test is skipped.
#[test]
fn an_output_name_that_is_another_users_pipe_is_refused() {
    let dir = temp_dir("hostile-strangers-fifo");
    let made = Command::new("mkfifo").arg(dir.join("out.png")).status();
    if !made.is_ok_and(|s| s.success()) {
        return skip(
            "an_output_name_that_is_another_users_pipe",
            "mkfifo is missing",
        );
    }
    if std::os::unix::fs::chown(dir.join("out.png"), Some(65534), Some(65534)).is_err() {
        return skip(
            "an_output_name_that_is_another_users_pipe",
            "changing a file's owner needs root",
        );
    }
    let cover = cover();
    let o = output_within_a_minute(
        tessera()
            .args([
                "render", &cover, "-q", "--width", "16", "--spp", "1", "-o", "out.png",
            ])
            .current_dir(&dir),
        "the render (on another user's pipe)",
    );
    refused(
        &o,
        "out.png: is a pipe (FIFO) of another user's (uid 65534",
        "another user's pipe",
    );
}

/// A medium's boundary is primitives too (a box medium six quads, each tested by a ray that
/// reaches it), and was not counted: a cloud of the most spheres a scene may hold, less
/// three, beside one box of smoke was built whole. The boundary counts, and the cloud that
/// goes over with it is refused at its count, before it is drawn.
#[test]
fn a_medium_s_boundary_counts_among_the_scene_s_primitives() {
    let dir = temp_dir("hostile-media-counted");
    let most = 1 << 20;
    let text = format!(
        "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 2\n\
         [materials.m]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [materials.smoke]\ntype = \"isotropic\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[media]]\ndensity = 0.01\nmaterial = \"smoke\"\n\
         box = {{ min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 1.0] }}\n\
         [[random_sphere_clouds]]\ncount = {}\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\n\
         radius = 0.1\nmaterial = \"m\"\n",
        most - 3
    );
    std::fs::write(dir.join("media.toml"), text).unwrap();
    refused(
        &run_capped(&["render", "media.toml", "-o", "media.png"], &dir, 64),
        &format!(
            "media.toml:17:9: field `random_sphere_clouds[0].count`: would make the scene's \
             primitives (spheres and quads; a box is six) {}",
            most + 3
        ),
        "a cloud of the most spheres less three beside a box of smoke",
    );
    assert!(!dir.join("media.png").exists());
}

/// The recipe lists every name a scene gives a texture file, each once: the names were
/// looked for among every name before, so 160,000 spellings of one 2×2 PNG (`./a.png`,
/// `.//a.png`, `././a.png`, …: 11 MB of inline textures, within the file's bounds) took
/// 90 s before a 32×32 render; looked up in a set, 3.5 s. What the set must keep is checked
/// here on 200 spellings, each given twice (a test bounds no time). More names than the
/// 256 a recipe may list (`info` refused the image's recipe for it, though `render` wrote
/// it) leave the recipe out, with a warning.
#[test]
fn a_scene_spelling_one_texture_file_many_ways_lists_each_name_once() {
    let dir = temp_dir("hostile-texture-spellings");
    image::RgbImage::new(2, 2).save(dir.join("a.png")).unwrap();
    // The `i`th spelling: `./`, then one `./` or `/` for each bit of `i`.
    let spelling = |mut i: usize| {
        let mut s = String::from("./");
        while i > 0 {
            s += if i & 1 == 1 { "./" } else { "/" };
            i >>= 1;
        }
        s + "/a.png"
    };
    let scene = |n: usize| {
        let mut text = String::from(
            "[image]\nwidth = 8\nheight = 8\nsamples_per_pixel = 1\nmax_depth = 2\n\
             [materials.m]\ntype = \"lambertian\"\nalbedo = \"t0\"\n\
             [[spheres]]\ncenter = [0.0, 0.0, -1.0]\nradius = 0.5\nmaterial = \"m\"\n\
             [textures]\n",
        );
        for i in 0..2 * n {
            text += &format!(
                "t{i} = {{ type = \"image\", file = \"{}\" }}\n",
                spelling(i % n)
            );
        }
        text
    };
    std::fs::write(dir.join("spelt.toml"), scene(200)).unwrap();
    ok(&["render", "spelt.toml", "-q", "-o", "spelt.png"], &dir);
    let o = run(&["info", "--json", "spelt.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let recipe: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let mut names: Vec<&str> = (recipe["textures"].as_array().unwrap().iter())
        .map(|t| t["name"].as_str().unwrap())
        .collect();
    names.sort_unstable();
    let mut expected: Vec<String> = (0..200).map(spelling).collect();
    expected.sort_unstable();
    assert_eq!(names, expected);

    std::fs::write(dir.join("many.toml"), scene(300)).unwrap();
    let o = run(&["render", "many.toml", "-o", "many.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("its recipe lists 300 texture files, more than the 256")
            && stderr(&o).contains("so many.png carries none"),
        "{}",
        stderr(&o)
    );
    let o = run(&["info", "many.png"], &dir);
    assert!(stderr(&o).contains("no recipe"), "{}", stderr(&o));
}

/// A scene's size is the scene file's to choose: 16384x16384 pixels claim 6 GiB of sums,
/// and where the system could not give them (a cap on memory) the allocation aborted
/// tessera ("memory allocation of 6442450944 bytes failed", signal 6). It is refused in
/// words, exit 2, before a ray is traced.
#[test]
fn a_scene_whose_sums_memory_cannot_hold_is_refused_in_words() {
    let dir = dir_with_scene(
        "hostile-huge-sums",
        "[image]\nwidth = 16384\nheight = 16384\nsamples_per_pixel = 1\nmax_depth = 1\n",
    );
    let o = run_capped(&["render", "scene.toml", "-q", "-o", "a.png"], &dir, 1024);
    refused(
        &o,
        "the image's 16384x16384 pixels need 6442450944 bytes for their sums, which this \
         process could not have",
        "16384x16384 under 1 GiB",
    );
    assert!(!dir.join("a.png").exists());
}
