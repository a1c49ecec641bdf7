//! Whether a JPEG file ends: its end-of-image marker after its last scan, which the JPEG
//! decoder does not ask for (it fills what a file cut short lacks with grey).

/// Whether the JPEG `r` is at the start of (or, `scanned`, just past its first start of
/// scan) has an end-of-image marker (FF D9) after its last start of scan (FF DA), read
/// through once: as `compare` and `scene::textures` ask of a JPEG. A segment's bytes (a
/// comment between two scans of a progressive file, a scan's header) are skipped by its
/// length, as libjpeg skips them: an FF D9 within them ends nothing.
pub fn ends<R: std::io::Read>(
    r: &mut std::io::BufReader<R>,
    scanned: bool,
) -> std::io::Result<bool> {
    use std::io::BufRead;
    let (mut scanned, mut ended, mut after_ff) = (scanned, false, false);
    // A segment's length comes in two bytes: `length` is `Some` while they are read, holding
    // the high one once it is in. Where `scanned`, the scan's header (its length first) is next.
    let (mut length, mut skip) = (if scanned { Some(None) } else { None }, 0usize);
    loop {
        let buf = r.fill_buf()?;
        if buf.is_empty() {
            return Ok(scanned && ended);
        }
        for &b in buf {
            if skip > 0 {
                skip -= 1;
                continue;
            }
            if let Some(high) = length {
                match high {
                    None => length = Some(Some(b)),
                    Some(high) => {
                        skip = usize::from(u16::from_be_bytes([high, b])).saturating_sub(2);
                        length = None;
                    }
                }
                continue;
            }
            match (after_ff, b) {
                // Fill bytes, stuffed data, restarts, TEM and the start of the image.
                (true, 0xff | 0x00 | 0x01 | 0xd0..=0xd8) | (false, _) => {}
                (true, 0xd9) => ended = scanned,
                (true, marker) => {
                    if marker == 0xda {
                        (scanned, ended) = (true, false);
                    }
                    length = Some(None);
                }
            }
            after_ff = b == 0xff && length.is_none();
        }
        let n = buf.len();
        r.consume(n);
    }
}
