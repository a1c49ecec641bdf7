//! Whether a JPEG file ends: its end-of-image marker after its last scan, which the JPEG
//! decoder does not ask for (it fills what a file cut short lacks with grey), and the Adobe
//! segments between its scans, which the decoder reads and libjpeg reads past.

use std::collections::BTreeSet;

/// What a JPEG's bytes from its first scan on hold, read through once.
#[derive(Debug, Default, PartialEq)]
pub struct AfterScan {
    /// Whether an end-of-image marker (FF D9) follows its last start of scan (FF DA).
    pub ends: bool,
    /// The colour transforms (each once, so at most 256) of the Adobe segments (APP14 of
    /// "Adobe" and 12 bytes or more, as the decoder reads one) after its first scan and
    /// before its first end marker: libjpeg takes a JPEG's colours from the segments before
    /// its first scan, the decoder takes each Adobe segment as it comes, up to its end.
    pub late_adobe: BTreeSet<u8>,
    /// Its scans (FF DA) before its first end marker: the decoder converts the colours of a
    /// file of one scan as it reads that scan, of more at their end.
    pub scans: usize,
}

/// Whether the JPEG `r` is at the start of (or, `scanned`, just past its first start of
/// scan) has an end-of-image marker (FF D9) after its last start of scan (FF DA), read
/// through once: as `compare` and `scene::textures` ask of a JPEG.
pub fn ends<R: std::io::Read>(
    r: &mut std::io::BufReader<R>,
    scanned: bool,
) -> std::io::Result<bool> {
    after_scan(r, scanned).map(|after| after.ends)
}

/// What the JPEG `r` is at the start of (or, `scanned`, just past its first start of scan)
/// holds from its first scan on, read through once. A segment's bytes (a comment between two
/// scans of a progressive file, a scan's header) are skipped by its length, as libjpeg skips
/// them: an FF D9 within them ends nothing.
pub fn after_scan<R: std::io::Read>(
    r: &mut std::io::BufReader<R>,
    scanned: bool,
) -> std::io::Result<AfterScan> {
    use std::io::BufRead;
    let mut after = AfterScan {
        scans: usize::from(scanned),
        ..AfterScan::default()
    };
    let (mut scanned, mut ended, mut after_ff) = (scanned, false, false);
    // Whether an end marker has followed the first scan: the decoder reads nothing past it.
    let mut past_end = false;
    // A segment's length comes in two bytes: `length` is `Some` while they are read, holding
    // the high one once it is in. Where `scanned`, the scan's header (its length first) is next.
    let (mut length, mut skip) = (if scanned { Some(None) } else { None }, 0usize);
    // The marker whose segment's length is being read, and the first 12 bytes of an Adobe
    // segment after the first scan, as they come in (its colour transform is the 12th).
    let mut marker = 0u8;
    let mut adobe: Option<([u8; 12], usize)> = None;
    loop {
        let buf = r.fill_buf()?;
        if buf.is_empty() {
            after.ends = scanned && ended;
            return Ok(after);
        }
        for &b in buf {
            if skip > 0 {
                skip -= 1;
                if let Some((head, n)) = &mut adobe {
                    head[*n] = b;
                    *n += 1;
                    if *n == head.len() {
                        if head.starts_with(b"Adobe") {
                            after.late_adobe.insert(head[11]);
                        }
                        adobe = None;
                    }
                }
                continue;
            }
            if let Some(high) = length {
                match high {
                    None => length = Some(Some(b)),
                    Some(high) => {
                        skip = usize::from(u16::from_be_bytes([high, b])).saturating_sub(2);
                        length = None;
                        adobe = (marker == 0xee && scanned && !past_end && skip >= 12)
                            .then_some(([0; 12], 0));
                    }
                }
                continue;
            }
            match (after_ff, b) {
                // Fill bytes, stuffed data, restarts, TEM and the start of the image.
                (true, 0xff | 0x00 | 0x01 | 0xd0..=0xd8) | (false, _) => {}
                (true, 0xd9) => {
                    ended = scanned;
                    past_end |= scanned;
                }
                (true, m) => {
                    if m == 0xda {
                        (scanned, ended) = (true, false);
                        if !past_end {
                            after.scans = after.scans.saturating_add(1);
                        }
                    }
                    marker = m;
                    length = Some(None);
                }
            }
            after_ff = b == 0xff && length.is_none();
        }
        let n = buf.len();
        r.consume(n);
    }
}
