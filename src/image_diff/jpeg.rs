//! What a JPEG's segments before its first scan say of how it is shown, where viewers
//! built on libjpeg (and libexif) read them otherwise than the decoder: EXIF orientation,
//! colour profiles, JFIF and Adobe colour transforms.

use std::io::Seek;

/// The most segments of a JPEG walked for its EXIF ones: the book's earth map has a dozen.
pub(super) const MAX_JPEG_SEGMENTS: usize = 1 << 16;

/// What compare lists of a JPEG with a colour profile.
pub(super) const JPEG_ICC_PROFILE: &str = "an ICC colour profile (an APP2 segment)";

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
pub(super) fn jpeg_display_changes<R: std::io::Read + Seek>(
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
pub(super) fn late_adobe_change(
    seen: &JpegSegments,
    late: &std::collections::BTreeSet<u8>,
) -> Option<String> {
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
pub(super) struct JpegSegments {
    /// Its EXIF segments (APP1).
    exif: usize,
    /// What its first EXIF segment that does not read says of it: an IFD or a value past
    /// its end, or no TIFF header.
    exif_fault: Option<String>,
    /// An orientation of its EXIF segments that libexif reads otherwise than the decoder and
    /// that does not say upright, described.
    odd_orientation: Option<String>,
    /// Whether the walk stopped just past the first scan's marker.
    pub(super) at_scan: bool,
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
    pub(super) frame: Option<crate::jpeg_end::Frame>,
    /// The marker of its first frame header of any kind, if it comes before the first scan.
    pub(super) frame_marker: Option<u8>,
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
        if crate::jpeg_end::is_frame(byte[0]) {
            seen.frame_marker.get_or_insert(byte[0]);
        }
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
    let past = |what: String| {
        let len = crate::text::count(tiff.len() as u64, "byte");
        format!("it ends ({len}) before {what}")
    };
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
                "the {entries} {} of its IFD{ifd} (from byte {table})",
                if entries == 1 { "entry" } else { "entries" }
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
                        "the {} of its IFD{ifd}'s orientation (at byte {from})",
                        crate::text::count(count, "value")
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
