//! The partial file's bytes: the 16-byte magic `TESSERA-PARTIAL\n`, the header length (u64,
//! little endian), the header as JSON, the region's sums (three u64 per pixel, row-major,
//! little endian), and a checksum (XXH3-64, u64) of everything before it. Reading checks every size
//! the header claims before allocating anything of that size.

use super::{Part, RenderId, VERSION, part_error};
use crate::error::{Error, Result};
use crate::job::{Job, JobState};
use crate::scene::Scene;
use serde::Serialize;
use std::io::{BufReader, Read, Write};
use std::path::{Path, PathBuf};
use xxhash_rust::xxh3::Xxh3;

const MAGIC: &[u8; 16] = b"TESSERA-PARTIAL\n";
/// Bytes before the header: the magic and the header's length.
const PREAMBLE: u64 = 24;
/// Bytes of the trailing checksum.
const CHECKSUM: u64 = 8;
/// Bytes of one pixel's sums.
const PIXEL: u64 = 24;
/// Pixels read at a time when a part's sums are streamed.
const CHUNK_PIXELS: usize = 1 << 14;

/// A part file opened for reading: its header read and checked against the file's real
/// length, its sums not yet read. Every size the header claims is checked before anything
/// of that size is allocated, so a small crafted file cannot make a reader ask for gigabytes.
pub struct PartReader<R> {
    path: PathBuf,
    /// The header: the part without its sums.
    header: Part,
    reader: R,
    checksum: Xxh3,
}

impl PartReader<BufReader<std::fs::File>> {
    /// Opens the part file at `path` and reads its header.
    pub fn open(path: &Path) -> Result<Self> {
        let io = |cause| Error::Io {
            path: path.to_owned(),
            cause,
        };
        let file = crate::input_file::open_regular(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        PartReader::new(BufReader::new(file), len, path)
    }

    /// Opens the part or checkpoint at `path` to take into an image, as `open` does,
    /// refusing one that another user owns. A render takes a checkpoint's finished tiles,
    /// and a merge a part's sums, as they are, so the user who wrote the file chooses those
    /// pixels (its checksum is no secret): in a directory others may write to (`/tmp`, a
    /// shared volume), another user could leave a checkpoint of the same scene under the
    /// name a render will use, or the part of a shard that failed among a merge's, and the
    /// image would carry their pixels, recipe and all. The file's owner is read from the
    /// opened file, so nothing swapped in after the check is read; a file of root's is
    /// taken (root can write any).
    pub fn open_own(path: &Path) -> Result<Self> {
        use std::os::unix::fs::MetadataExt;
        let io = |cause| Error::Io {
            path: path.to_owned(),
            cause,
        };
        // A symbolic link is followed only where it is this user's or root's: whoever makes
        // a link chooses the file read. Where there was none, none swapped in is followed.
        let link = std::fs::symlink_metadata(path)
            .ok()
            .filter(|m| m.file_type().is_symlink());
        if let Some(link) = &link
            && crate::owner::is_another_users(link.uid(), &[])
        {
            return Err(part_error(
                path,
                format!(
                    "a symbolic link of another user's (uid {}; this is uid {}): whoever \
                     makes the link chooses the checkpoint or part read; remove it",
                    link.uid(),
                    crate::owner::this_user()
                ),
            ));
        }
        let file = if link.is_some() {
            crate::input_file::open_regular(path)
        } else {
            crate::input_file::open_regular_not_a_link(path)
        }
        .map_err(io)?;
        let meta = file.metadata().map_err(io)?;
        if crate::owner::is_another_users(meta.uid(), &[]) {
            return Err(part_error(
                path,
                format!(
                    "belongs to another user (uid {}; this is uid {}): an image takes a \
                     checkpoint or part only of its own user's, as whoever writes one chooses \
                     its pixels; remove it, or copy it to make it yours if you trust it",
                    meta.uid(),
                    crate::owner::this_user()
                ),
            ));
        }
        PartReader::new(BufReader::new(file), meta.len(), path)
    }
}

impl<R: Read> PartReader<R> {
    /// Reads and checks the header of the `len`-byte part that `reader` holds; `path` names
    /// it in errors.
    pub fn new(mut reader: R, len: u64, path: &Path) -> Result<Self> {
        let fail = |message: String| Err(part_error(path, message));
        let mut preamble = [0u8; PREAMBLE as usize];
        let got = read_up_to(&mut reader, &mut preamble, path)?;
        if got < MAGIC.len() || preamble[..MAGIC.len()] != MAGIC[..] {
            return fail("is not a tessera partial render (no TESSERA-PARTIAL header)".to_owned());
        }
        if got < preamble.len() || len < PREAMBLE + CHECKSUM {
            return fail(format!("is truncated ({len} bytes)"));
        }
        let header_len = u64::from_le_bytes(preamble[16..].try_into().expect("8 bytes"));
        if header_len > len - PREAMBLE - CHECKSUM {
            return fail(format!(
                "is truncated ({len} bytes, its header alone claims {header_len})"
            ));
        }
        // The header is parsed as it is read, never read into a buffer of the length it
        // claims: a sparse file claims any length on a few KiB of disk, and its zeros end
        // the parse at the first one. Memory follows the bytes the file really holds.
        let mut checksum = Xxh3::new();
        checksum.update(&preamble);
        let mut text = Hashing {
            inner: (&mut reader).take(header_len),
            checksum: &mut checksum,
        };
        let mut version = None;
        let parsed = {
            use serde::de::DeserializeSeed;
            let mut json = serde_json::Deserializer::from_reader(&mut text);
            (HeaderSeed {
                version: &mut version,
            })
            .deserialize(&mut json)
            .and_then(|header| json.end().map(|()| header))
        };
        let header: Part = match parsed {
            Ok(h) => h,
            // Said before anything else: the rest is another layout's.
            Err(_) if version.is_some_and(|v| v != VERSION) => {
                return fail(super::another_version(version.unwrap_or(VERSION)));
            }
            Err(e) if e.is_io() => {
                return Err(Error::Io {
                    path: path.to_owned(),
                    cause: e.into(),
                });
            }
            Err(e) if e.is_eof() => return fail(format!("is truncated ({len} bytes)")),
            Err(e) => return fail(format!("has a corrupt header: {e}")),
        };
        // The parse reads to the end of what the header claims, so bytes left unread mean
        // the file ended early (it changed while being read).
        if text.inner.limit() > 0 {
            return fail(format!("is truncated ({len} bytes)"));
        }
        header.check_claims(path)?;
        let expected = header.file_len(header_len);
        if len != expected {
            return fail(format!(
                "is truncated or padded ({len} bytes, expected {expected})"
            ));
        }
        Ok(Self {
            path: path.to_owned(),
            header,
            reader,
            checksum,
        })
    }

    /// The part as its header describes it, without its sums.
    pub fn header(&self) -> &Part {
        &self.header
    }

    /// The header, the sums left unread.
    pub fn into_header(self) -> Part {
        self.header
    }

    /// Reads the sums, row-major over the region, handing them to `each` a chunk at a time,
    /// then checks the checksum. What `each` was given is sound only if this returns `Ok`.
    pub fn read_sums(mut self, mut each: impl FnMut(&[[u64; 3]])) -> Result<()> {
        let mut left = self.header.state.job.region.area();
        let mut bytes = vec![0u8; CHUNK_PIXELS.min(left as usize) * PIXEL as usize];
        let mut sums = Vec::with_capacity(CHUNK_PIXELS.min(left as usize));
        while left > 0 {
            let n = CHUNK_PIXELS.min(left as usize);
            let chunk = &mut bytes[..n * PIXEL as usize];
            self.read_exact(chunk)?;
            self.checksum.update(chunk);
            sums.clear();
            sums.extend(chunk.chunks_exact(PIXEL as usize).map(|px| {
                let word = |i: usize| {
                    u64::from_le_bytes(px[i * 8..i * 8 + 8].try_into().expect("8 bytes"))
                };
                [word(0), word(1), word(2)]
            }));
            each(&sums);
            left -= n as u64;
        }
        let mut stored = [0u8; CHECKSUM as usize];
        self.read_exact(&mut stored)?;
        if self.checksum.digest() != u64::from_le_bytes(stored) {
            return Err(part_error(
                &self.path,
                "is corrupt (checksum mismatch)".to_owned(),
            ));
        }
        Ok(())
    }

    /// The whole part, sums and all.
    pub fn read_part(self) -> Result<Part> {
        let mut part = self.header.clone();
        let mut sums = Vec::with_capacity(part.state.job.region.area() as usize);
        self.read_sums(|chunk| sums.extend_from_slice(chunk))?;
        part.state.sums = sums;
        Ok(part)
    }

    fn read_exact(&mut self, buf: &mut [u8]) -> Result<()> {
        if read_up_to(&mut self.reader, buf, &self.path)? < buf.len() {
            return Err(part_error(
                &self.path,
                "is truncated (it changed while being read)".to_owned(),
            ));
        }
        Ok(())
    }
}

/// A part's JSON header, read with its format version checked first: a header of another
/// version than this build's is another layout, whose fields this one does not know, so the
/// parse stops at the version and `version` says which it was. A part of a newer tessera
/// once read "has a corrupt header: unknown field `…`", which says nothing of why. Fields
/// are taken in any order; one this layout does not know is refused once the version is
/// known to be this build's.
struct HeaderSeed<'a> {
    /// The version the header gives, once read.
    version: &'a mut Option<u32>,
}

/// The fields of a part's header, for messages.
const HEADER_FIELDS: &[&str] = &["version", "render", "state"];

impl<'de> serde::de::DeserializeSeed<'de> for HeaderSeed<'_> {
    type Value = Part;

    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Part, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> serde::de::Visitor<'de> for HeaderSeed<'_> {
    type Value = Part;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a part's header (an object of `version`, `render` and `state`)")
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Part, A::Error> {
        use serde::de::Error as _;
        let (mut render, mut state, mut unknown) = (None, None, None);
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "version" if self.version.is_some() => {
                    return Err(A::Error::duplicate_field("version"));
                }
                "version" => {
                    let version = map.next_value::<u32>()?;
                    *self.version = Some(version);
                    if version != VERSION {
                        return Err(A::Error::custom(super::another_version(version)));
                    }
                }
                "render" if render.is_some() => return Err(A::Error::duplicate_field("render")),
                "render" => render = Some(map.next_value::<RenderId>()?),
                "state" if state.is_some() => return Err(A::Error::duplicate_field("state")),
                "state" => state = Some(map.next_value::<JobState>()?),
                // Refused once the version is known: another version's field says nothing.
                _ => {
                    map.next_value::<serde::de::IgnoredAny>()?;
                    unknown.get_or_insert(key);
                }
            }
        }
        let version = self
            .version
            .ok_or_else(|| A::Error::missing_field("version"))?;
        if let Some(field) = unknown {
            return Err(A::Error::unknown_field(&field, HEADER_FIELDS));
        }
        Ok(Part {
            version,
            render: render.ok_or_else(|| A::Error::missing_field("render"))?,
            state: state.ok_or_else(|| A::Error::missing_field("state"))?,
        })
    }
}

/// A reader that adds what it reads to a checksum.
struct Hashing<'a, R> {
    inner: R,
    checksum: &'a mut Xxh3,
}

impl<R: Read> Read for Hashing<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.checksum.update(&buf[..n]);
        Ok(n)
    }
}

/// Fills `buf` from `reader` as far as it goes; returns the bytes read.
fn read_up_to(reader: &mut impl Read, buf: &mut [u8], path: &Path) -> Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(cause) => {
                return Err(Error::Io {
                    path: path.to_owned(),
                    cause,
                });
            }
        }
    }
    Ok(filled)
}

/// The JSON header as written: a `Part` without its sums, borrowed.
#[derive(Serialize)]
struct HeaderOut<'a> {
    version: u32,
    render: &'a RenderId,
    state: &'a JobState,
}

/// Writes the part file holding `state` of the render `render` to `out`, a chunk of sums at
/// a time, hashing as it goes.
fn write_part(out: &mut dyn Write, render: &RenderId, state: &JobState) -> std::io::Result<()> {
    let header = HeaderOut {
        version: VERSION,
        render,
        state,
    };
    let header = serde_json::to_vec(&header).map_err(std::io::Error::other)?;
    let mut checksum = Xxh3::new();
    let mut put = |bytes: &[u8]| {
        checksum.update(bytes);
        out.write_all(bytes)
    };
    put(MAGIC)?;
    put(&(header.len() as u64).to_le_bytes())?;
    put(&header)?;
    crate::film::write_sums_le(&state.sums, &mut put)?;
    out.write_all(&checksum.digest().to_le_bytes())
}

/// The bytes of a part file holding `state` of the render `render`.
fn encode(render: &RenderId, state: &JobState) -> Vec<u8> {
    let mut out = Vec::new();
    write_part(&mut out, render, state).expect("writing to memory cannot fail");
    out
}

/// Writes `state` of the render `render` to `path` as a part file, atomically.
pub fn save(path: &Path, render: &RenderId, state: &JobState) -> Result<()> {
    crate::atomic_file::write_atomically_with(path, &mut |out| write_part(out, render, state))
}

/// `save` of a render's finished part: one that cannot be renamed into place is kept
/// (`write_result_atomically_with`).
pub fn save_result(path: &Path, render: &RenderId, state: &JobState) -> Result<()> {
    crate::atomic_file::write_result_atomically_with(path, &mut |out| {
        write_part(out, render, state)
    })
}

impl Part {
    /// The length in bytes of a file with this header, once it is known to be consistent.
    fn file_len(&self, header_len: u64) -> u64 {
        PREAMBLE + header_len + self.state.job.region.area() * PIXEL + CHECKSUM
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        encode(&self.render, &self.state)
    }

    /// Parses and checks a part; `path` names it in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Part> {
        PartReader::new(bytes, bytes.len() as u64, path)?.read_part()
    }

    pub fn load(path: &Path) -> Result<Part> {
        PartReader::open(path)?.read_part()
    }

    /// The state to go on rendering `job` of `scene` from, the checkpoint at `path` (a file
    /// of this user's, `PartReader::open_own`; then `resume`). Its header is checked against
    /// the render before its sums are read: a checkpoint's header may claim any image up to
    /// `scene::MAX_PIXELS` (6 GiB of sums, a sparse file of a few KiB on disk), and one of
    /// another render was read whole first and refused only after. A 1.6 GB sparse
    /// checkpoint claiming 8192x8192 pixels, given to a 32x18 render, took 9 s and 1.5 GB of
    /// memory before it was refused.
    pub fn load_checkpoint(path: &Path, scene: &Scene, job: Job) -> Result<JobState> {
        let reader = PartReader::open_own(path)?;
        reader.header().check_resumes(scene, job, path)?;
        reader.read_part()?.resume(scene, job, path)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::part;
    use super::*;
    use crate::math::PixelRect;

    #[test]
    fn bytes_round_trip() {
        let p = part(
            PixelRect {
                x0: 2,
                y0: 1,
                width: 5,
                height: 4,
            },
            [3, 9],
        );
        let bytes = p.to_bytes();
        assert_eq!(Part::from_bytes(&bytes, Path::new("p")).unwrap(), p);
    }

    /// `bytes`, a part file, with its JSON header replaced by `header` and its checksum made
    /// again.
    fn with_header(bytes: &[u8], header: &str) -> Vec<u8> {
        let old = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
        let body = &bytes[24 + old..bytes.len() - 8];
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&(header.len() as u64).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(body);
        let sum = xxhash_rust::xxh3::xxh3_64(&out);
        out.extend_from_slice(&sum.to_le_bytes());
        out
    }

    /// A part of another format version is refused as that, whatever else its header holds
    /// and wherever its version stands: one of a newer tessera with a field this one does
    /// not know read "has a corrupt header: unknown field `…`".
    #[test]
    fn a_part_of_another_format_version_is_refused_as_that_first() {
        let bytes = part(PixelRect::full(3, 2), [0, 4]).to_bytes();
        let len = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
        let header = std::str::from_utf8(&bytes[24..24 + len]).unwrap();
        let (version, rest) = header.split_once(',').unwrap();
        assert_eq!(version, format!("{{\"version\":{VERSION}"));
        let refused = |header: &str| {
            let e = Part::from_bytes(&with_header(&bytes, header), Path::new("p.part"));
            e.unwrap_err().to_string()
        };
        let newer = VERSION + 1;
        for header in [
            format!("{{\"version\":{newer},\"tiles\":[[0,0,3,2]],{rest}"),
            format!("{{\"version\":{newer},\"render\":{{\"camera\":1}}}}"),
            format!("{{\"tiles\":[],\"version\":{newer},{rest}"),
            format!("{{\"version\":{newer}"),
        ] {
            let said = refused(&header);
            assert!(
                said.starts_with(&format!(
                    "p.part: is a part of format version {newer}; this tessera reads version \
                     {VERSION}: it was written by a newer tessera"
                )),
                "{header}: {said}"
            );
        }
        let said = refused(&format!("{{\"version\":1,{rest}"));
        assert!(
            said.contains("version 1;") && said.contains("an older"),
            "{said}"
        );
        // This version's header, its fields in another order, is read; a field it does not
        // know is refused as one.
        let reordered = format!("{{{},\"version\":{VERSION}}}", &rest[..rest.len() - 1]);
        let read = Part::from_bytes(&with_header(&bytes, &reordered), Path::new("p"));
        assert_eq!(read.unwrap().to_bytes(), bytes);
        let said = refused(&format!("{version},\"tiles\":[],{rest}"));
        assert!(said.contains("unknown field `tiles`"), "{said}");
        let twice = format!("{version},\"version\":{VERSION},{rest}");
        assert!(refused(&twice).contains("duplicate field `version`"));
        assert!(refused(&format!("{{{rest}")).contains("missing field `version`"));
    }

    #[test]
    fn every_truncation_and_every_flipped_byte_is_caught() {
        let bytes = part(
            PixelRect {
                x0: 0,
                y0: 0,
                width: 3,
                height: 2,
            },
            [0, 4],
        )
        .to_bytes();
        for len in 0..bytes.len() {
            assert!(
                Part::from_bytes(&bytes[..len], Path::new("p")).is_err(),
                "truncated to {len}"
            );
        }
        for i in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[i] ^= 0x10;
            assert!(
                Part::from_bytes(&bad, Path::new("p")).is_err(),
                "byte {i} flipped"
            );
        }
    }
}
