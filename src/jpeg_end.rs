//! Whether a JPEG file ends: its end-of-image marker after its last scan, which the JPEG
//! decoder does not ask for (it fills what a file cut short lacks with grey), the Adobe
//! segments between its scans, which the decoder reads and libjpeg reads past, and whether
//! its scans hold enough coded data for the blocks its frame header claims (the decoder
//! fills what they lack too: a file of 214 bytes claiming 4096x4096 pixels once decoded,
//! taking 448 MB).

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
    /// The bytes of coded data of its scans before its first end marker: those outside
    /// segments, an FF stuffed as FF 00 counted once, markers (restarts) and fill bytes not.
    pub coded_bytes: u64,
    /// Its first frame header before its first scan, where the walk starts before it (the
    /// decoder refuses a second one).
    pub frame: Option<Frame>,
    /// The marker of its first frame header of any kind (`is_frame`) before its first scan,
    /// where the walk starts before it.
    pub frame_marker: Option<u8>,
}

/// Whether `marker` begins a frame header (SOF0 to SOF15), of any kind: not DHT (C4), JPG
/// (C8) or DAC (CC), which share the range.
pub fn is_frame(marker: u8) -> bool {
    (0xc0..=0xcf).contains(&marker) && !matches!(marker, 0xc4 | 0xc8 | 0xcc)
}

/// What is said of a JPEG whose first frame header has the marker `marker`, if the decoder
/// does not read that kind of frame: it reads those of Huffman coding, baseline, extended
/// and progressive (SOF0 to SOF2), and skips a frame header of another kind as an unknown
/// segment, so that it then fails with words of a fault the file does not have ("Number of
/// components cannot be zero").
pub fn unread_frame(marker: u8) -> Option<String> {
    let kind = match marker {
        0xc3 => "lossless (SOF3)",
        0xc5 => "differential sequential, hierarchical (SOF5)",
        0xc6 => "differential progressive, hierarchical (SOF6)",
        0xc7 => "differential lossless, hierarchical (SOF7)",
        0xc9 => "extended sequential, arithmetic coding (SOF9)",
        0xca => "progressive, arithmetic coding (SOF10)",
        0xcb => "lossless, arithmetic coding (SOF11)",
        0xcd => "differential sequential, arithmetic coding (SOF13)",
        0xce => "differential progressive, arithmetic coding (SOF14)",
        0xcf => "differential lossless, arithmetic coding (SOF15)",
        _ => return None,
    };
    Some(format!(
        "has a frame header of {kind}, a kind the decoder does not read: it reads baseline, \
         extended and progressive JPEGs of Huffman coding (SOF0 to SOF2)"
    ))
}

/// The fewest bits of coded data a block of 8x8 samples of one component takes in a
/// sequential (baseline or extended) JPEG of Huffman coding: a code for its DC difference and
/// an end-of-block code (or a code for its 63rd coefficient), and no Huffman code is shorter
/// than one bit. An encoder's flat picture, its tables optimized, takes exactly this.
pub const MIN_SEQUENTIAL_BITS_PER_BLOCK: u64 = 2;

/// The fewest bits a block of one component takes over all the scans of a progressive JPEG:
/// its first DC scan codes each block's DC difference in a Huffman code of one bit at least
/// (its AC scans may code a run of 32,767 empty blocks in one code).
pub const MIN_PROGRESSIVE_BITS_PER_BLOCK: u64 = 1;

/// A JPEG's frame header (SOF0, SOF1 or SOF2, the ones the decoder reads): the size it
/// claims and its components' sampling factors.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub progressive: bool,
    pub width: u16,
    pub height: u16,
    /// Each component's horizontal and vertical sampling factors.
    pub sampling: Vec<(u8, u8)>,
}

/// The most bytes of a frame header's segment that are read: its 6 bytes and 255
/// components of 3.
pub const MAX_FRAME_BYTES: usize = 6 + 3 * 255;

impl Frame {
    /// The frame header of the segment of marker `marker` whose bytes past its length are
    /// `body`: `None` for another marker, or a header cut short (the decoder's to refuse).
    pub fn parse(marker: u8, body: &[u8]) -> Option<Frame> {
        if !(0xc0..=0xc2).contains(&marker) {
            return None;
        }
        let count = usize::from(*body.get(5)?);
        let sampling = body
            .get(6..6 + 3 * count)?
            .chunks_exact(3)
            .map(|c| (c[1] >> 4, c[1] & 0x0f))
            .collect();
        Some(Frame {
            progressive: marker == 0xc2,
            height: u16::from_be_bytes([body[1], body[2]]),
            width: u16::from_be_bytes([body[3], body[4]]),
            sampling,
        })
    }

    /// The blocks of 8x8 samples of all its components: each component's samples are its
    /// share (its factors over the largest) of the pixels, rounded up, in blocks rounded up.
    pub fn blocks(&self) -> u64 {
        let most = |f: fn(&(u8, u8)) -> u8| {
            u64::from(self.sampling.iter().map(f).max().unwrap_or(1).max(1))
        };
        let (h_most, v_most) = (most(|s| s.0), most(|s| s.1));
        let (w, h) = (u64::from(self.width), u64::from(self.height));
        self.sampling
            .iter()
            .map(|&(hs, vs)| {
                let cols = (w * u64::from(hs)).div_ceil(h_most).div_ceil(8);
                let rows = (h * u64::from(vs)).div_ceil(v_most).div_ceil(8);
                cols * rows
            })
            .sum()
    }

    /// Why `coded_bytes` of coded data cannot hold the blocks it claims, said in words, if
    /// they cannot: fewer than `MIN_SEQUENTIAL_BITS_PER_BLOCK` (or, progressive,
    /// `MIN_PROGRESSIVE_BITS_PER_BLOCK`) a block. The decoder fills what the scans lack
    /// (with grey), as large as the header claims, rather than failing.
    pub fn too_short(&self, coded_bytes: u64) -> Option<String> {
        let (bits, kind) = if self.progressive {
            (MIN_PROGRESSIVE_BITS_PER_BLOCK, "progressive")
        } else {
            (MIN_SEQUENTIAL_BITS_PER_BLOCK, "sequential")
        };
        let blocks = self.blocks();
        let least = (blocks * bits).div_ceil(8);
        (coded_bytes < least).then(|| {
            format!(
                "claims {}x{} pixels in {}, {} of 8x8, but its scans hold {} of coded \
                 data, fewer than the {least} any {kind} JPEG of that size takes ({} a block \
                 at least): its pixels are not decoded (a truncated or made-up file?)",
                self.width,
                self.height,
                crate::text::count(self.sampling.len() as u64, "component"),
                crate::text::count(blocks, "block"),
                crate::text::count(coded_bytes, "byte"),
                crate::text::count(bits, "bit")
            )
        })
    }
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
    // The bytes of a frame header before the first scan, as they come in, and the bytes
    // of its segment left to come.
    let mut frame: Option<(Vec<u8>, usize)> = None;
    loop {
        let buf = r.fill_buf()?;
        if buf.is_empty() {
            after.ends = scanned && ended;
            return Ok(after);
        }
        for &b in buf {
            if skip > 0 {
                skip -= 1;
                if let Some((body, left)) = &mut frame {
                    if body.len() < MAX_FRAME_BYTES {
                        body.push(b);
                    }
                    *left -= 1;
                    if *left == 0 {
                        after.frame = Frame::parse(marker, body);
                        frame = None;
                    }
                }
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
                        let first_frame = !scanned && after.frame.is_none();
                        frame = (first_frame && (0xc0..=0xc2).contains(&marker) && skip > 0)
                            .then(|| (Vec::new(), skip));
                    }
                }
                continue;
            }
            // Coded data: a byte other than FF, or an FF stuffed as FF 00.
            if scanned && !past_end && matches!((after_ff, b), (false, 0..=0xfe) | (true, 0)) {
                after.coded_bytes += 1;
            }
            match (after_ff, b) {
                // Fill bytes, stuffed data, restarts, TEM and the start of the image.
                (true, 0xff | 0x00 | 0x01 | 0xd0..=0xd8) | (false, _) => {}
                (true, 0xd9) => {
                    ended = scanned;
                    past_end |= scanned;
                }
                (true, m) => {
                    if !scanned && after.frame_marker.is_none() && is_frame(m) {
                        after.frame_marker = Some(m);
                    }
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

/// A Huffman table of a JPEG (DHT), as F.2.2.3 of the standard decodes with it: for each
/// code length, the largest code of that length (-1 for none), and where its codes' symbols
/// begin among `symbols`, less its smallest code.
#[derive(Clone)]
struct Huffman {
    max_code: [i32; 17],
    offset: [i32; 17],
    symbols: Vec<u8>,
}

impl Huffman {
    /// The table of a DHT segment's 16 counts and the symbols after them, `None` where they
    /// are more than a table holds (256) or more than its codes of each length can be.
    fn new(counts: &[u8; 16], symbols: Vec<u8>) -> Option<Huffman> {
        let (mut max_code, mut offset) = ([-1i32; 17], [0i32; 17]);
        let (mut code, mut k) = (0i32, 0i32);
        for len in 1..=16 {
            let n = i32::from(counts[len - 1]);
            offset[len] = k - code;
            code += n;
            k += n;
            if n > 0 {
                max_code[len] = code - 1;
            }
            if code > 1 << len {
                return None;
            }
            code <<= 1;
        }
        (k as usize == symbols.len() && k <= 256).then_some(Huffman {
            max_code,
            offset,
            symbols,
        })
    }
}

/// The bits of a scan's coded data, read from the bytes after its header: an FF stuffed as
/// FF 00 is data, fill bytes before a marker are none, and a marker ends the data (kept in
/// `marker`; FF D9 where the file ends).
struct Bits<I: Iterator<Item = std::io::Result<u8>>> {
    bytes: std::iter::Peekable<I>,
    byte: u8,
    left: u32,
    marker: Option<u8>,
}

impl<I: Iterator<Item = std::io::Result<u8>>> Bits<I> {
    /// The next byte of the file, `None` at its end.
    fn next_byte(&mut self) -> std::io::Result<Option<u8>> {
        self.bytes.next().transpose()
    }

    /// The byte after an FF, the fill bytes (more FFs) passed over: 0 where the FF is data
    /// (stuffed), else a marker's code (D9 where the file ends).
    fn after_ff(&mut self) -> std::io::Result<u8> {
        let mut m = 0xff;
        while m == 0xff {
            m = self.next_byte()?.unwrap_or(0xd9);
        }
        Ok(m)
    }

    /// The next bit of coded data, `None` once the data has met a marker.
    fn bit(&mut self) -> std::io::Result<Option<u32>> {
        if self.left == 0 {
            if self.marker.is_some() {
                return Ok(None);
            }
            let Some(b) = self.next_byte()? else {
                self.marker = Some(0xd9);
                return Ok(None);
            };
            if b == 0xff {
                let m = self.after_ff()?;
                if m != 0 {
                    self.marker = Some(m);
                    return Ok(None);
                }
            }
            (self.byte, self.left) = (b, 8);
        }
        self.left -= 1;
        Ok(Some(u32::from(self.byte >> self.left) & 1))
    }

    /// The next `n` bits, `None` once the data has met a marker.
    fn skip(&mut self, n: u8) -> std::io::Result<Option<()>> {
        for _ in 0..n {
            if self.bit()?.is_none() {
                return Ok(None);
            }
        }
        Ok(Some(()))
    }

    /// The symbol of the next code of `table`, `None` once the data has met a marker;
    /// `Some(None)` for bits that are no code of it.
    fn symbol(&mut self, table: &Huffman) -> std::io::Result<Option<Option<u8>>> {
        let mut code = 0i32;
        for len in 1..=16 {
            let Some(bit) = self.bit()? else {
                return Ok(None);
            };
            code = code << 1 | bit as i32;
            if code <= table.max_code[len] {
                let at = usize::try_from(code + table.offset[len]).ok();
                return Ok(Some(at.and_then(|at| table.symbols.get(at).copied())));
            }
        }
        Ok(Some(None))
    }

    /// Past what is left of the data to the next marker, which is taken (`None` at the end
    /// of the file).
    fn next_marker(&mut self) -> std::io::Result<Option<u8>> {
        self.left = 0;
        while self.marker.is_none() {
            let Some(b) = self.next_byte()? else {
                return Ok(None);
            };
            if b == 0xff {
                let m = self.after_ff()?;
                if m != 0 {
                    self.marker = Some(m);
                }
            }
        }
        Ok(self.marker.take())
    }
}

/// A frame's component: its name and its horizontal and vertical sampling factors.
type Sampled = (u8, u8, u8);

/// Why the scans of the sequential JPEG (baseline or extended, of Huffman coding: SOF0 or
/// SOF1) `r` is at the start of do not code each block of its frame once, if they do not:
/// a scan whose coded data ends (at a marker, or the file's end) before its last block,
/// which the decoder and libjpeg fill with grey without failing (the file cut short, and an
/// end marker put back: a texture with a grey band); a component coded by a second scan,
/// whose blocks libjpeg takes from the last and the decoder (past a scan of every
/// component) from the first; or a component no scan codes, grey. Their codes are followed
/// through each block, the work bounded by the file's bits. A file of another kind, or
/// whose tables or scans the walk cannot follow (a table it names missing, bits that are
/// no code), is not judged here: the decoder's to read or refuse.
pub fn sequential_fault<R: std::io::Read>(r: R) -> std::io::Result<Option<String>> {
    use std::io::Read;
    let mut bits = Bits {
        bytes: std::io::BufReader::new(r).bytes().peekable(),
        byte: 0,
        left: 0,
        marker: None,
    };
    // The frame's size and its components (name, sampling), its tables (DC 0-3, AC 4-7),
    // its restart interval, and which scan coded each component.
    let mut frame: Option<(u32, u32, Vec<Sampled>)> = None;
    let mut tables: [Option<Huffman>; 8] = Default::default();
    let mut interval = 0u32;
    let mut coded: Vec<Option<usize>> = Vec::new();
    let mut scans = 0usize;
    let mut marker = bits.next_marker()?;
    loop {
        let Some(m) = marker else {
            return Ok(None);
        };
        if matches!(m, 0xd0..=0xd8 | 0x01) {
            marker = bits.next_marker()?;
            continue;
        }
        if m == 0xd9 {
            break;
        }
        // A segment: its length, then its body (at most 64 KiB).
        let (Some(hi), Some(lo)) = (bits.next_byte()?, bits.next_byte()?) else {
            return Ok(None);
        };
        let length = usize::from(u16::from_be_bytes([hi, lo])).saturating_sub(2);
        let mut body = Vec::with_capacity(length);
        for _ in 0..length {
            let Some(b) = bits.next_byte()? else {
                return Ok(None);
            };
            body.push(b);
        }
        match m {
            0xc0 | 0xc1 if frame.is_none() => {
                let (Some(&count), Some(h), Some(w)) =
                    (body.get(5), body.get(1..3), body.get(3..5))
                else {
                    return Ok(None);
                };
                let Some(list) = body.get(6..6 + 3 * usize::from(count)) else {
                    return Ok(None);
                };
                let components: Vec<Sampled> = list
                    .chunks_exact(3)
                    .map(|c| (c[0], (c[1] >> 4).max(1), (c[1] & 0xf).max(1)))
                    .collect();
                let (h, w) = (
                    u16::from_be_bytes([h[0], h[1]]),
                    u16::from_be_bytes([w[0], w[1]]),
                );
                if h == 0 || w == 0 || components.is_empty() {
                    return Ok(None);
                }
                coded = vec![None; components.len()];
                frame = Some((u32::from(w), u32::from(h), components));
            }
            // Another kind of frame: not judged here.
            m if is_frame(m) => return Ok(None),
            0xc4 => {
                let mut rest = &body[..];
                while let Some((&class_id, after)) = rest.split_first() {
                    let Some(counts) = after.get(..16) else {
                        return Ok(None);
                    };
                    let counts: [u8; 16] = counts.try_into().expect("16 bytes");
                    let n: usize = counts.iter().map(|&c| usize::from(c)).sum();
                    let Some(symbols) = after.get(16..16 + n) else {
                        return Ok(None);
                    };
                    let slot = usize::from(class_id >> 4 & 1) * 4 + usize::from(class_id & 3);
                    tables[slot] = Huffman::new(&counts, symbols.to_vec());
                    rest = &after[16 + n..];
                }
            }
            0xdd => {
                let Some(i) = body.get(..2) else {
                    return Ok(None);
                };
                interval = u32::from(u16::from_be_bytes([i[0], i[1]]));
            }
            0xda => {
                let Some((w, h, components)) = &frame else {
                    return Ok(None);
                };
                scans += 1;
                let count = usize::from(*body.first().unwrap_or(&0));
                let Some(list) = body.get(1..1 + 2 * count) else {
                    return Ok(None);
                };
                // Each of the scan's components: its place in the frame and its tables.
                let mut in_scan = Vec::new();
                for c in list.chunks_exact(2) {
                    let Some(i) = components.iter().position(|f| f.0 == c[0]) else {
                        return Ok(None);
                    };
                    let (Some(dc), Some(ac)) = (
                        tables[usize::from(c[1] >> 4 & 3)].clone(),
                        tables[4 + usize::from(c[1] & 3)].clone(),
                    ) else {
                        return Ok(None);
                    };
                    if let Some(first) = coded[i] {
                        return Ok(Some(format!(
                            "codes its component {} in scan {first} and again in scan \
                             {scans}: libjpeg takes its blocks from the last, the decoder from \
                             the first where that scan held every component",
                            c[0]
                        )));
                    }
                    coded[i] = Some(scans);
                    in_scan.push((i, dc, ac));
                }
                if in_scan.is_empty() {
                    return Ok(None);
                }
                let h_most = u32::from(components.iter().map(|c| c.1).max().unwrap_or(1));
                let v_most = u32::from(components.iter().map(|c| c.2).max().unwrap_or(1));
                // An interleaved scan's MCUs hold each component's blocks of its sampling; a
                // scan of one component codes each of its blocks alone.
                let (mcus, per_mcu): (u64, Vec<u32>) = if in_scan.len() == 1 {
                    let (_, hs, vs) = components[in_scan[0].0];
                    let cols = (w * u32::from(hs)).div_ceil(h_most).div_ceil(8);
                    let rows = (h * u32::from(vs)).div_ceil(v_most).div_ceil(8);
                    (u64::from(cols) * u64::from(rows), vec![1])
                } else {
                    let cols = w.div_ceil(8 * h_most);
                    let rows = h.div_ceil(8 * v_most);
                    let per = in_scan
                        .iter()
                        .map(|&(i, _, _)| u32::from(components[i].1) * u32::from(components[i].2))
                        .collect();
                    (u64::from(cols) * u64::from(rows), per)
                };
                let blocks_per_mcu: u64 = per_mcu.iter().map(|&n| u64::from(n)).sum();
                let mut block = 0u64;
                for mcu in 0..mcus {
                    if interval > 0 && mcu > 0 && mcu % u64::from(interval) == 0 {
                        match bits.next_marker()? {
                            Some(0xd0..=0xd7) => {}
                            _ => return Ok(Some(ends_early(scans, block, mcus * blocks_per_mcu))),
                        }
                    }
                    for ((_, dc, ac), &n) in in_scan.iter().zip(&per_mcu) {
                        for _ in 0..n {
                            let ended =
                                || Ok(Some(ends_early(scans, block, mcus * blocks_per_mcu)));
                            let Some(s) = bits.symbol(dc)? else {
                                return ended();
                            };
                            let Some(s) = s else { return Ok(None) };
                            if bits.skip(s & 15)?.is_none() {
                                return ended();
                            }
                            let mut k = 1;
                            while k < 64 {
                                let Some(rs) = bits.symbol(ac)? else {
                                    return ended();
                                };
                                let Some(rs) = rs else { return Ok(None) };
                                let (run, size) = (rs >> 4, rs & 15);
                                if size == 0 && run != 15 {
                                    break;
                                }
                                k += usize::from(run) + 1;
                                if bits.skip(size)?.is_none() {
                                    return ended();
                                }
                            }
                            block += 1;
                        }
                    }
                }
                marker = bits.next_marker()?;
                continue;
            }
            _ => {}
        }
        marker = bits.next_marker()?;
    }
    if let Some(i) = coded.iter().position(Option::is_none) {
        let name = frame.map_or(0, |f| f.2[i].0);
        return Ok(Some(format!(
            "codes its component {name} in none of its {scans} scan(s): the decoder and \
             libjpeg show it grey (a truncated file?)"
        )));
    }
    Ok(None)
}

/// What is said of a scan (the `scan`th) whose coded data ends at its block `block` of
/// `blocks`.
fn ends_early(scan: usize, block: u64, blocks: u64) -> String {
    format!(
        "has a scan (scan {scan}) whose coded data ends at its block {block} of {blocks}: the \
         decoder and libjpeg fill the rest with grey (a truncated file, its end marker put \
         back?)"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A baseline JPEG of `width`x`height` pixels and `components` components (the first
    /// sampled `sampling`, the others 1x1), whose one scan holds `coded` bytes of data: one
    /// Huffman code of one bit in each table, so that each block takes two bits.
    fn thin_jpeg(width: u16, height: u16, components: u8, sampling: u8, coded: &[u8]) -> Vec<u8> {
        let segment = |marker: u8, body: &[u8]| {
            let length = (body.len() as u16 + 2).to_be_bytes();
            [&[0xff, marker][..], &length, body].concat()
        };
        let mut frame = vec![8];
        frame.extend(height.to_be_bytes());
        frame.extend(width.to_be_bytes());
        frame.push(components);
        let mut scan = vec![components];
        for c in 1..=components {
            frame.extend([c, if c == 1 { sampling } else { 0x11 }, 0]);
            scan.extend([c, 0]);
        }
        scan.extend([0, 63, 0]);
        let one_code = |class: u8| [&[class, 1][..], &[0; 15], &[0]].concat();
        [
            &[0xff, 0xd8][..],
            &segment(0xdb, &[&[0][..], &[1; 64]].concat()),
            &segment(0xc0, &frame),
            &segment(0xc4, &one_code(0x00)),
            &segment(0xc4, &one_code(0x10)),
            &segment(0xda, &scan),
            coded,
            &[0xff, 0xd9],
        ]
        .concat()
    }

    fn after(bytes: &[u8]) -> AfterScan {
        after_scan(&mut std::io::BufReader::new(bytes), false).unwrap()
    }

    /// A JPEG of 214 bytes claiming 4096x4096 pixels, its scan of 64 bytes, was decoded
    /// whole (the decoder filled the rest with grey: 448 MB and 0.77 s for `compare`). Its
    /// frame's blocks and its coded bytes are read on the way to its end, and it is refused
    /// by them; a flat picture of as many bytes as its blocks take at least is not.
    #[test]
    fn coded_data_too_short_for_the_frame_s_blocks_is_refused() {
        let thin = thin_jpeg(4096, 4096, 3, 0x11, &[0; 64]);
        assert_eq!(thin.len(), 214);
        let a = after(&thin);
        assert!(a.ends);
        assert_eq!(a.coded_bytes, 64);
        let frame = a.frame.unwrap();
        assert_eq!(frame.blocks(), 3 * 512 * 512);
        let why = frame.too_short(a.coded_bytes).unwrap();
        assert!(
            why.starts_with(
                "claims 4096x4096 pixels in 3 components, 786432 blocks of 8x8, but its \
                 scans hold 64 bytes of coded data, fewer than the 196608"
            ),
            "{why}"
        );
        // Two bits a block, exactly: a flat picture as an optimizing encoder makes it.
        let flat = thin_jpeg(4096, 4096, 3, 0x11, &vec![0; 196_608]);
        let a = after(&flat);
        assert_eq!(a.frame.unwrap().too_short(a.coded_bytes), None);
        // 4:2:0 of 17x9 pixels: 3x2 blocks of luma, 2x1 of each chroma; sizes rounded up.
        let a = after(&thin_jpeg(17, 9, 3, 0x22, &[0; 2]));
        assert_eq!(a.frame.as_ref().unwrap().blocks(), 6 + 2 + 2);
        assert!(a.frame.unwrap().too_short(2).is_some());
        // An FF stuffed as FF 00 is one byte of data; restarts and the fill bytes before one
        // are none.
        let a = after(&thin_jpeg(
            8,
            8,
            1,
            0x11,
            &[0xff, 0, 0xff, 0xd0, 0xff, 0xff, 0xd1, 7],
        ));
        assert_eq!(a.coded_bytes, 2);
        // A progressive frame takes one bit a block at least.
        let mut progressive = Frame::parse(0xc2, &[8, 0, 64, 0, 64, 1, 1, 0x11, 0]).unwrap();
        assert_eq!(progressive.blocks(), 64);
        assert_eq!(progressive.too_short(8), None);
        assert!(progressive.too_short(7).is_some());
        progressive.progressive = false;
        assert!(progressive.too_short(8).is_some());
        // A frame the decoder does not read, or cut short, is none.
        assert_eq!(Frame::parse(0xc3, &[8, 0, 64, 0, 64, 1, 1, 0x11, 0]), None);
        assert_eq!(Frame::parse(0xc0, &[8, 0, 64, 0, 64, 2, 1, 0x11, 0]), None);
    }
    /// A baseline JPEG of `width`x`height` pixels and `components` components sampled 1x1,
    /// of the scans `scans` (the components each codes, its coded data), its tables those of
    /// `thin_jpeg`: each block takes two bits.
    fn scanned_jpeg(width: u16, height: u16, components: u8, scans: &[(&[u8], &[u8])]) -> Vec<u8> {
        let segment = |marker: u8, body: &[u8]| {
            let length = (body.len() as u16 + 2).to_be_bytes();
            [&[0xff, marker][..], &length, body].concat()
        };
        let mut frame = vec![8];
        frame.extend(height.to_be_bytes());
        frame.extend(width.to_be_bytes());
        frame.push(components);
        for c in 1..=components {
            frame.extend([c, 0x11, 0]);
        }
        let one_code = |class: u8| [&[class, 1][..], &[0; 15], &[0]].concat();
        let mut jpeg = [
            &[0xff, 0xd8][..],
            &segment(0xdb, &[&[0][..], &[1; 64]].concat()),
            &segment(0xc0, &frame),
            &segment(0xc4, &one_code(0x00)),
            &segment(0xc4, &one_code(0x10)),
        ]
        .concat();
        for (coded, data) in scans {
            let mut scan = vec![coded.len() as u8];
            for &c in *coded {
                scan.extend([c, 0]);
            }
            scan.extend([0, 63, 0]);
            jpeg.extend(segment(0xda, &scan));
            jpeg.extend(*data);
        }
        jpeg.extend([0xff, 0xd9]);
        jpeg
    }

    fn fault(jpeg: &[u8]) -> Option<String> {
        sequential_fault(jpeg).unwrap()
    }

    /// A baseline JPEG cut within its scan and its end marker put back was decoded with the
    /// rest grey, as a texture and by `compare`, without a word: the earth map cut at half
    /// its coded data holds more than `too_short` asks. Its codes are followed through each
    /// block, and the scan found to end at block 20,164 of 49,152 (of 4:2:0, six blocks an
    /// MCU); the whole file codes them all.
    #[test]
    fn a_scan_whose_coded_data_ends_before_its_blocks_is_found() {
        let whole = include_bytes!("../scenes/earthmap.jpg");
        assert_eq!(fault(whole), None);
        let scan = whole.windows(2).position(|w| w == [0xff, 0xda]).unwrap();
        let cut = [&whole[..scan + (whole.len() - scan) / 2], &[0xff, 0xd9]].concat();
        let why = fault(&cut).unwrap_or_default();
        assert!(
            why.starts_with("has a scan (scan 1) whose coded data ends at its block "),
            "{why}"
        );
        // Two bits a block: 32 blocks of 8x8 want 8 bytes, 7 end at block 28.
        assert_eq!(fault(&scanned_jpeg(64, 32, 1, &[(&[1], &[0; 8])])), None);
        let why = fault(&scanned_jpeg(64, 32, 1, &[(&[1], &[0; 7])])).unwrap_or_default();
        assert!(why.contains("ends at its block 28 of 32"), "{why}");
        // A restart where the interval is not over ends the data too.
        // Intervals of 4 blocks, a byte each, 8 of them: 7 restarts.
        let data: Vec<u8> = (0..8u8)
            .flat_map(|i| {
                if i == 0 {
                    vec![0]
                } else {
                    vec![0xff, 0xcf + i, 0]
                }
            })
            .collect();
        let mut restarted = scanned_jpeg(64, 32, 1, &[(&[1], &data)]);
        let sos = restarted
            .windows(2)
            .position(|w| w == [0xff, 0xda])
            .unwrap();
        restarted.splice(sos..sos, [0xff, 0xdd, 0, 4, 0, 4]);
        assert_eq!(fault(&restarted), None);
        let mut early = scanned_jpeg(64, 32, 1, &[(&[1], &data[1..])]);
        early.splice(sos..sos, [0xff, 0xdd, 0, 4, 0, 8]);
        let why = fault(&early).unwrap_or_default();
        assert!(why.contains("ends at its block 0 of 32"), "{why}");
    }

    /// Sequential scans of one component each are followed; a component coded by a second
    /// scan (libjpeg takes the last, the decoder the first past a scan of all of them), or by
    /// none, is found.
    #[test]
    fn a_component_coded_twice_or_never_is_found() {
        let one = &[0u8][..];
        let apart = scanned_jpeg(8, 8, 3, &[(&[1], one), (&[2], one), (&[3], one)]);
        assert_eq!(fault(&apart), None);
        assert_eq!(fault(&scanned_jpeg(8, 8, 3, &[(&[1, 2, 3], one)])), None);
        let twice = scanned_jpeg(8, 8, 3, &[(&[1, 2, 3], one), (&[1], one)]);
        let why = fault(&twice).unwrap_or_default();
        assert!(
            why.starts_with("codes its component 1 in scan 1 and again in scan 2"),
            "{why}"
        );
        let never = scanned_jpeg(8, 8, 3, &[(&[1], one), (&[2], one)]);
        let why = fault(&never).unwrap_or_default();
        assert!(
            why.starts_with("codes its component 3 in none of its 2 scan(s)"),
            "{why}"
        );
        // A progressive file is not judged here.
        let progressive = include_bytes!("../tests/data/progressive-8x8.jpg");
        assert_eq!(fault(progressive), None);
    }
}
