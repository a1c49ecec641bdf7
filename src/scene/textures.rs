//! Reading the image files of image textures: where they are looked for, and the limits that
//! keep a stranger's file (a scene, a recipe's scene) from costing more than a texture may.
//! A texture file is found by a relative name, without `..`, in the scene file's directory
//! (or the directories `TextureSource` lists), checked to be a regular file of at most
//! `MAX_TEXTURE_BYTES`, and its claimed size checked against `MAX_TEXTURE_PIXELS` before it
//! is decoded.

use super::TextureFile;
use crate::input_file::{LinkOr, open_regular_without_links};
use crate::texture::ImageTexture;
use std::fs::File;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// The largest texture file tessera reads (the book's earth map is 158 KiB).
pub const MAX_TEXTURE_BYTES: u64 = 64 << 20;
/// The most pixels a texture may have: 2²⁵, 96 MiB of RGB.
pub const MAX_TEXTURE_PIXELS: u64 = 1 << 25;
/// The most pixels all of a scene's texture files may have together: 2²⁶, 192 MiB of RGB
/// (the book's earth map has 0.5 million). A file named by many textures is read once.
pub const MAX_SCENE_TEXTURE_PIXELS: u64 = 1 << 26;

/// The most a decoder may allocate while it reads a texture file's size: what comes before
/// the pixels (a PNG's colour profile, inflated, and its text) takes a few KiB in the book's
/// files, and a 1 MB PNG of 16 pixels whose profile inflates to 1 GiB once took 532 MB here.
const MAX_HEADER_ALLOC: u64 = 16 << 20;

/// Where image textures come from.
#[derive(Clone, Debug)]
pub enum TextureSource {
    /// Files looked for in these directories, in order.
    Dirs(Vec<PathBuf>),
    /// Files compiled in, by name (the standard workloads' textures).
    Embedded(&'static [(&'static str, &'static [u8])]),
}

/// A texture file read and decoded.
pub(super) struct LoadedImage {
    pub(super) image: ImageTexture,
    pub(super) file: TextureFile,
    /// Where it was found, for messages.
    pub(super) found: String,
}

/// Reads and decodes the texture file `name`, of at most `pixels_left` pixels (what the
/// scene's other files leave of `MAX_SCENE_TEXTURE_PIXELS`); the error says what was
/// wrong, with the file.
pub(super) fn load(
    name: &str,
    source: &TextureSource,
    pixels_left: u64,
) -> Result<LoadedImage, String> {
    let relative = Path::new(name);
    if !is_plain_name(name) {
        return Err(format!(
            "`{name}` must be a relative file name without `..` (textures are found next to \
             the scene file)"
        ));
    }
    let (bytes, found) = match source {
        TextureSource::Embedded(files) => match files.iter().find(|(n, _)| *n == name) {
            Some((_, bytes)) => (bytes.to_vec(), format!("{name} (compiled in)")),
            None => return Err(format!("no texture `{name}` is compiled in")),
        },
        TextureSource::Dirs(dirs) => {
            let Some((file, path)) = open_texture(dirs, relative)? else {
                let looked: Vec<String> = dirs
                    .iter()
                    .map(|d| {
                        let shown = d.display().to_string();
                        if shown.is_empty() { ".".into() } else { shown }
                    })
                    .collect();
                return Err(format!(
                    "texture file `{name}` not found (looked in {})",
                    looked.join(", ")
                ));
            };
            (read_texture(file, &path)?, path.display().to_string())
        }
    };
    let hash = xxhash_rust::xxh3::xxh3_128(&bytes);
    let image = decode(&bytes, pixels_left).map_err(|e| format!("{found}: {e}"))?;
    Ok(LoadedImage {
        image,
        file: TextureFile {
            name: name.to_owned(),
            hash,
        },
        found,
    })
}

/// The file the texture name `name` comes from, as one key whatever the spelling
/// (`a.png`, `./a.png`): its canonical path, or its compiled-in name. None when it is not
/// found (`load` then says why).
pub(super) fn identity(name: &str, source: &TextureSource) -> Option<String> {
    if !is_plain_name(name) {
        return None;
    }
    match source {
        TextureSource::Embedded(files) => files
            .iter()
            .any(|(n, _)| *n == name)
            .then(|| format!("compiled in: {name}")),
        TextureSource::Dirs(dirs) => {
            let found = locate(dirs, Path::new(name)).ok()??;
            Some(found.real.display().to_string())
        }
    }
}

/// Whether `name` is a texture's name as a scene may give it: relative, without `..`.
pub fn is_plain_name(name: &str) -> bool {
    !name.is_empty()
        && Path::new(name)
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
}

/// A texture file found in one of the directories looked in.
struct Found {
    /// As the directory and the name make it.
    path: PathBuf,
    /// Its canonical path, when it was found.
    real: PathBuf,
    /// The canonical path of the directory it lies in.
    base: PathBuf,
}

/// The texture file `name` (a plain name) in the first of `dirs` that holds it. A file
/// that a symbolic link leads out of its directory is refused: a scene or recipe from a
/// stranger reads only what lies in the directories it is given.
fn locate(dirs: &[PathBuf], name: &Path) -> Result<Option<Found>, String> {
    for dir in dirs {
        let path = dir.join(name);
        // Not there, or a file where the name has a directory: looked for in the next
        // directory. Any other failure (a name too long, a directory it may not search) is
        // said as it is, not as "not found".
        let real = match path.canonicalize() {
            Ok(real) => real,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                continue;
            }
            Err(e) => return Err(format!("texture file {}: {e}", path.display())),
        };
        // A scene file named without a directory has "" for its own.
        let base = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir.as_path()
        };
        match base.canonicalize() {
            Ok(base) if real.starts_with(&base) => return Ok(Some(Found { path, real, base })),
            _ => return Err(leads_out(&path, base)),
        }
    }
    Ok(None)
}

fn leads_out(path: &Path, base: &Path) -> String {
    format!(
        "texture file {} leads out of {} (a symbolic link): refused",
        path.display(),
        base.display()
    )
}

/// The texture file `name` in the first of `dirs` that holds it (`locate`), opened:
/// None when no directory holds it. Checked before it is opened (a link out of the
/// directory, to a device say, is not opened), and the file opened checked again: whoever
/// can write in the directory could otherwise swap a link in between the check and the
/// opening, and have tessera read a file outside.
pub fn open_texture(dirs: &[PathBuf], name: &Path) -> Result<Option<(File, PathBuf)>, String> {
    let Some(found) = locate(dirs, name)? else {
        return Ok(None);
    };
    let file = open_found(&found)?;
    Ok(Some((file, found.path)))
}

/// The file `found`, opened by its canonical path with no link followed at any step
/// (`open_regular_without_links`): a link swapped in since the check is refused unopened.
/// What was opened is checked again, for systems where only the last step is guarded.
fn open_found(found: &Found) -> Result<File, String> {
    let file = match open_regular_without_links(&found.real) {
        Ok(file) => file,
        Err(LinkOr::LinkFound) => {
            return Err(format!(
                "texture file {} became a symbolic link as it was opened: refused, not followed",
                found.path.display()
            ));
        }
        Err(LinkOr::Other(e)) => return Err(format!("{}: {e}", found.path.display())),
    };
    if !opened_inside(&file, found) {
        return Err(leads_out(&found.path, &found.base));
    }
    Ok(file)
}

/// Whether the file `file`, opened after `found` was checked, lies in `found`'s directory:
/// as the kernel knows the file opened (its `/proc/self/fd` link), not by a path that may
/// since lead elsewhere. Without `/proc`, the file at the canonical path checked must be the
/// one opened (the same device and inode, a link there not followed).
fn opened_inside(file: &File, found: &Found) -> bool {
    use std::os::unix::fs::MetadataExt;
    use std::os::unix::io::AsRawFd;
    if let Ok(opened) = std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd())) {
        return opened.starts_with(&found.base);
    }
    match (file.metadata(), std::fs::symlink_metadata(&found.real)) {
        (Ok(opened), Ok(checked)) => (opened.dev(), opened.ino()) == (checked.dev(), checked.ino()),
        _ => false,
    }
}

/// The bytes of the regular file `file` (`shown` in messages), at most `MAX_TEXTURE_BYTES`.
pub fn read_texture(file: File, shown: &Path) -> Result<Vec<u8>, String> {
    let shown = shown.display();
    let mut bytes = Vec::new();
    file.take(MAX_TEXTURE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("{shown}: {e}"))?;
    if bytes.len() as u64 > MAX_TEXTURE_BYTES {
        return Err(format!(
            "{shown}: is larger than the {} MiB a texture file may be",
            MAX_TEXTURE_BYTES >> 20
        ));
    }
    Ok(bytes)
}

/// Decodes a PNG, JPEG or other image the `image` crate reads into 8-bit RGB, its size
/// checked before its pixels are: at most `MAX_TEXTURE_PIXELS`, and at most `pixels_left`.
pub fn decode(bytes: &[u8], pixels_left: u64) -> Result<ImageTexture, String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    // A JPEG's frame header and coded data, checked against each other once its size is,
    // as a PNM's header and length are.
    let mut jpeg = None;
    let (mut pnm, mut png) = (false, false);
    match reader.format() {
        None => return Err("is not an image tessera reads (PNG, JPEG, PPM or EXR)".into()),
        Some(image::ImageFormat::Jpeg) => {
            let after = jpeg_after_scan(bytes)?;
            // A frame of a kind the decoder does not read, refused by its kind.
            if let Some(why) = after.frame_marker.and_then(crate::jpeg_end::unread_frame) {
                return Err(format!("is a JPEG that {why}"));
            }
            jpeg = Some(after);
        }
        // The PNG decoder keeps every text chunk before the pixels, whatever their count.
        Some(image::ImageFormat::Png) => {
            crate::png_header::read(std::io::Cursor::new(bytes), bytes.len() as u64)?;
            png = true;
        }
        // The `exr` crate keeps every attribute of a header, whatever its count, and
        // inflates the pixels of its data window, whatever the size read below (its display
        // window's): at most four floats a pixel of the most a texture has.
        Some(image::ImageFormat::OpenExr) => {
            crate::exr_header::check_bounds(bytes, bytes.len() as u64, 16 * MAX_TEXTURE_PIXELS)?;
        }
        // The PNM decoder keeps each line of a PAM header, whatever its length.
        Some(image::ImageFormat::Pnm) => {
            crate::pnm_header::check_bounds(std::io::Cursor::new(bytes))?;
            pnm = true;
        }
        Some(_) => {}
    }
    // What a decoder keeps of the file before its pixels (a PNG's colour profile, inflated):
    // at most `MAX_HEADER_ALLOC`.
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_HEADER_ALLOC);
    reader.limits(limits);
    let (width, height) = reader
        .into_dimensions()
        .map_err(|e| format!("cannot read the image's size: {e}"))?;
    let pixels = u64::from(width) * u64::from(height);
    if pixels == 0 || pixels > MAX_TEXTURE_PIXELS {
        return Err(format!(
            "is {width}x{height}: a texture must have between 1 and {MAX_TEXTURE_PIXELS} pixels"
        ));
    }
    if pixels > pixels_left {
        return Err(format!(
            "is {width}x{height}: more than the {pixels_left} pixels the scene's other texture \
             files leave of the {MAX_SCENE_TEXTURE_PIXELS} all of them may have"
        ));
    }
    let is_jpeg = jpeg.is_some();
    // The decoder fills what the scans lack, as large as the frame claims.
    if let Some(why) = jpeg.and_then(|a| a.frame.and_then(|f| f.too_short(a.coded_bytes))) {
        return Err(format!("is a JPEG that {why}"));
    }
    // And so it fills a scan cut short whose end marker is put back, with grey: its codes
    // are followed to each block (the file held whole in memory already, read once more).
    if is_jpeg {
        match crate::jpeg_end::sequential_fault(bytes) {
            Ok(Some(why)) => return Err(format!("is a JPEG that {why}")),
            Ok(None) => {}
            Err(e) => return Err(format!("could not be read: {e}")),
        }
    }
    // A PNG's decoder is handed room for every row IHDR claims before it finds them
    // missing: the pixels' stream is inflated to its end first (at most 8 bytes a pixel
    // and a filter byte a row of each pass, of the most a texture has), and one that
    // ends before its rows, or without its end, is refused. A file of 170 bytes claiming
    // 5792x5792 16-bit RGBA pixels had 268 MB asked for them, and ended tessera
    // ("memory allocation failed") where the system refused it.
    if png {
        crate::png_header::check_zlib_stream_ends(bytes, MAX_TEXTURE_PIXELS * 10)
            .map_err(|why| format!("has pixels that do not decode: {why}"))?;
    }
    // The decoder makes room for every sample a PNM's header claims before it reads one.
    if pnm {
        crate::pnm_header::check_length(std::io::Cursor::new(bytes), bytes.len() as u64)?;
    }
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // The decoded image and the decoder's own buffers: a few times the RGBA pixels.
    limits.max_alloc = Some(16 * pixels + (16 << 20));
    reader.limits(limits);
    let decoded = reader
        .decode()
        .map_err(|e| format!("cannot decode the image: {e}"))?;
    let rgb = decoded.into_rgb8();
    ImageTexture::new(rgb.width(), rgb.height(), rgb.into_raw())
        .ok_or_else(|| "the decoded image has no pixels".to_owned())
}

/// What a JPEG holds from its first scan on (`jpeg_end::after_scan`), once its last scan
/// is found followed by its end-of-image marker (FF D9): the JPEG decoder fills what a
/// truncated file lacks with grey rather than failing, so a cut-off texture would render
/// as a grey band. Read as `compare` reads a JPEG: the segments between scans (a comment, a
/// table) are skipped by their length, so an FF D9 within one (a progressive file cut
/// within a comment before its last scans) ends nothing.
fn jpeg_after_scan(bytes: &[u8]) -> Result<crate::jpeg_end::AfterScan, String> {
    let mut r = std::io::BufReader::new(std::io::Cursor::new(bytes));
    match crate::jpeg_end::after_scan(&mut r, false) {
        Ok(after) if after.ends => Ok(after),
        _ => Err("is a JPEG that ends before its image does (a truncated file?)".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input_file::open_regular;

    /// A link swapped in between the check of a texture's path and its opening: the file
    /// opened is checked again, by what was opened, and refused when it lies outside.
    #[test]
    fn a_texture_opened_is_checked_again_by_what_was_opened() {
        let root = std::env::temp_dir().join(format!("tessera-swap-{}", std::process::id()));
        let (dir, outside) = (root.join("scenes"), root.join("secret"));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::create_dir_all(&outside).unwrap();
        std::fs::write(dir.join("earth.jpg"), b"inside").unwrap();
        std::fs::write(outside.join("key"), b"outside").unwrap();
        let dirs = [dir.clone()];
        // The path as checked: inside.
        let found = locate(&dirs, Path::new("earth.jpg")).unwrap().unwrap();
        let inside = open_regular(&found.path).unwrap();
        assert!(opened_inside(&inside, &found));
        // What an attacker's swap would have opened in its place: refused.
        let swapped = open_regular(&outside.join("key")).unwrap();
        assert!(!opened_inside(&swapped, &found));
        // Opened whole, a file that lies inside reads; a link out is refused unopened.
        let (file, path) = open_texture(&dirs, Path::new("earth.jpg"))
            .unwrap()
            .unwrap();
        assert_eq!(read_texture(file, &path).unwrap(), b"inside");
        std::os::unix::fs::symlink(outside.join("key"), dir.join("key.jpg")).unwrap();
        let e = open_texture(&dirs, Path::new("key.jpg")).err().unwrap();
        assert!(e.contains("leads out of"), "{e}");
        // The race's other half: checked while it was a file, a link put in its place
        // before the opening is refused, not followed.
        let checked = locate(&dirs, Path::new("earth.jpg")).unwrap().unwrap();
        std::fs::remove_file(dir.join("earth.jpg")).unwrap();
        std::os::unix::fs::symlink(outside.join("key"), dir.join("earth.jpg")).unwrap();
        let e = open_found(&checked).err().unwrap();
        assert!(e.contains("became a symbolic link as it was opened"), "{e}");
        assert!(
            open_texture(&dirs, Path::new("none.jpg"))
                .unwrap()
                .is_none()
        );
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_truncated_jpeg_is_refused_and_the_whole_one_decodes() {
        let whole = include_bytes!("../../scenes/earthmap.jpg");
        let texture = decode(whole, MAX_TEXTURE_PIXELS).unwrap();
        assert_eq!((texture.width, texture.height), (1024, 512));
        for cut in [whole.len() - 2, whole.len() / 2, 2000] {
            let e = decode(&whole[..cut], MAX_TEXTURE_PIXELS).err().unwrap();
            assert!(e.contains("ends before its image does"), "{cut}: {e}");
        }
        // Cut within a comment after the scan that holds the bytes FF D9: no end, as a
        // progressive file cut within a comment before its last scans has none; the comment
        // whole and the end after it are one.
        let (pixels, end) = whole.split_at(whole.len() - 2);
        let comment = b"\xff\xfe\x00\x0fhello\xff\xd9 there";
        let cut = decode(&[pixels, &comment[..11]].concat(), MAX_TEXTURE_PIXELS).err();
        assert!(cut.is_some_and(|e| e.contains("ends before its image does")));
        assert!(decode(&[pixels, comment, end].concat(), MAX_TEXTURE_PIXELS).is_ok());
        // Bytes after the end marker (a file with something appended) are not a truncation.
        let mut appended = whole.to_vec();
        appended.extend(b"appended");
        assert!(decode(&appended, MAX_TEXTURE_PIXELS).is_ok());
    }

    /// The earth map cut at half its coded data and its end marker put back decoded, its
    /// lower half grey, without a word (it holds more coded data than `too_short` asks); a
    /// second scan of a component, or a component no scan codes, went unchecked. Each is
    /// refused by what its scans lack.
    #[test]
    fn a_jpeg_whose_scans_do_not_code_each_block_once_is_refused() {
        let whole = include_bytes!("../../scenes/earthmap.jpg");
        let scan = whole.windows(2).position(|w| w == [0xff, 0xda]).unwrap();
        let cut = [&whole[..scan + (whole.len() - scan) / 2], &[0xff, 0xd9]].concat();
        let e = decode(&cut, MAX_TEXTURE_PIXELS).err().unwrap_or_default();
        assert!(
            e.starts_with("is a JPEG that has a scan (scan 1) whose coded data ends at its block"),
            "{e}"
        );
        // The scan again, after the first: its three components coded twice.
        let (pixels, end) = whole.split_at(whole.len() - 2);
        let twice = [pixels, &whole[scan..whole.len() - 2], end].concat();
        let e = decode(&twice, MAX_TEXTURE_PIXELS).err().unwrap_or_default();
        assert!(
            e.starts_with("is a JPEG that codes its component 1 in scan 1 and again in scan 2"),
            "{e}"
        );
    }

    /// A frame header of a kind the decoder does not read (arithmetic coding, SOF9) was
    /// refused as "Number of components cannot be zero"; it is refused by its kind.
    #[test]
    fn a_jpeg_of_a_frame_kind_the_decoder_does_not_read_is_refused_by_its_kind() {
        let mut jpeg = include_bytes!("../../scenes/earthmap.jpg").to_vec();
        let sof = jpeg.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
        jpeg[sof + 1] = 0xc9;
        let e = decode(&jpeg, MAX_TEXTURE_PIXELS).err().unwrap_or_default();
        assert!(e.contains("arithmetic coding (SOF9)"), "{e}");
    }

    #[test]
    fn a_pam_whose_header_does_not_end_within_its_bound_is_refused() {
        let pam = |comment: usize| {
            let mut bytes = b"P7\n#".to_vec();
            bytes.extend(vec![b'a'; comment]);
            bytes.extend(
                b"\nWIDTH 1\nHEIGHT 1\nDEPTH 3\nMAXVAL 255\nTUPLTYPE RGB\nENDHDR\n\x01\x02\x03",
            );
            bytes
        };
        let texture = decode(&pam(10), MAX_TEXTURE_PIXELS).unwrap();
        assert_eq!((texture.width, texture.height), (1, 1));
        let e = decode(&pam(1 << 16), MAX_TEXTURE_PIXELS).err().unwrap();
        assert!(e.contains("does not end within its first 64 KiB"), "{e}");
    }

    #[test]
    fn names_that_leave_the_scene_directory_are_refused() {
        let source = TextureSource::Dirs(vec![PathBuf::from(".")]);
        for name in ["/etc/passwd", "../x.jpg", "a/../../b.png", ""] {
            let e = load(name, &source, MAX_SCENE_TEXTURE_PIXELS).err().unwrap();
            assert!(e.contains("relative file name"), "{name}: {e}");
        }
        let missing = load("no-such.jpg", &source, MAX_SCENE_TEXTURE_PIXELS)
            .err()
            .unwrap();
        assert!(missing.contains("not found (looked in ."), "{missing}");
        // A failure other than absence is said as it is: every one was "not found".
        let long = format!("{}.png", "a".repeat(300));
        let e = load(&long, &source, MAX_SCENE_TEXTURE_PIXELS)
            .err()
            .unwrap();
        assert!(
            e.contains("name too long") && !e.contains("not found"),
            "{e}"
        );
        let e = load("a\0b.png", &source, MAX_SCENE_TEXTURE_PIXELS)
            .err()
            .unwrap();
        assert!(!e.contains("not found"), "{e}");
    }

    #[test]
    fn what_is_not_an_image_or_too_large_is_refused_before_decoding() {
        assert!(
            decode(b"hello", MAX_TEXTURE_PIXELS)
                .unwrap_err()
                .contains("not an image")
        );
        // A PNG header claiming 100000 x 100000 pixels, and nothing else.
        let mut png = b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR".to_vec();
        png.extend(100_000u32.to_be_bytes());
        png.extend(100_000u32.to_be_bytes());
        png.extend([8, 2, 0, 0, 0]);
        let crc = crc32fast::hash(&png[12..29]);
        png.extend(crc.to_be_bytes());
        // An empty IDAT, where the header ends, and the end.
        for kind in [b"IDAT", b"IEND"] {
            png.extend(b"\0\0\0\0");
            png.extend(kind);
            png.extend(crc32fast::hash(kind).to_be_bytes());
        }
        let e = decode(&png, MAX_TEXTURE_PIXELS).unwrap_err();
        assert!(e.contains("100000x100000"), "{e}");
    }

    /// A tiled EXR of tiles 0 pixels wide reached the decoder, which refused it in its own
    /// words ("cannot read the image's size: Format error decoding OpenExr: invalid: tile
    /// size"); it is refused by the attribute, as `compare` and `info` refuse it.
    #[test]
    fn an_exr_texture_of_tiles_of_no_pixels_is_refused_by_the_attribute() {
        let attribute = |name: &str, kind: &str, value: &[u8]| {
            let mut a = [name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat();
            a.extend((value.len() as u32).to_le_bytes());
            a.extend(value);
            a
        };
        let ints = |v: &[i32]| v.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<u8>>();
        let mut channels = Vec::new();
        for name in [b"B", b"G", b"R"] {
            channels.extend([&name[..], b"\0", &ints(&[2, 0, 1, 1])].concat());
        }
        channels.push(0);
        let mut exr = vec![0x76, 0x2f, 0x31, 0x01, 2, 2, 0, 0];
        exr.extend(attribute("channels", "chlist", &channels));
        exr.extend(attribute("compression", "compression", &[0]));
        exr.extend(attribute("dataWindow", "box2i", &ints(&[0, 0, 3, 3])));
        exr.extend(attribute("displayWindow", "box2i", &ints(&[0, 0, 3, 3])));
        exr.extend(attribute(
            "tiles",
            "tiledesc",
            &[ints(&[0, 16]), vec![0]].concat(),
        ));
        exr.push(0);
        // One tile's offset, and the tile: its coordinates, its length and its pixels.
        exr.extend((exr.len() as u64 + 8).to_le_bytes());
        exr.extend(ints(&[0, 0, 0, 0, 4 * 4 * 12]));
        exr.extend([0; 4 * 4 * 12]);
        let e = decode(&exr, MAX_TEXTURE_PIXELS).err().unwrap_or_default();
        assert!(
            e.starts_with("has a tiles attribute of tiles of 0x16 pixels"),
            "{e}"
        );
    }
}
