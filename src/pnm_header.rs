//! A PNM file's header (PBM, PGM, PPM or PAM) read as a stranger's: it must end within
//! `MAX_HEADER_BYTES` before a decoder reads the file. The `image` crate's decoder reads each
//! line of a PAM header, comments included, into memory whatever its length, so a PAM of one
//! comment line of 4 GiB (a sparse file, a few KiB of disk) once took 4.2 GB and then ended
//! tessera on a failed allocation. Below the image textures and `compare`, which walk it so;
//! `compare` also looks for samples past the header's maxval, which the decoder takes as the
//! brightest value where Netpbm refuses the file.

use std::io::BufRead;

/// The most bytes a PNM header may take: the book's PPM header takes a dozen, a PAM's with
/// every field a hundred.
pub const MAX_HEADER_BYTES: u64 = 1 << 16;

/// Reads the PNM header `reader` starts with, no further than `MAX_HEADER_BYTES`: an error
/// says why it is not a header the decoder reads within them.
pub fn check_bounds(reader: impl BufRead) -> Result<(), String> {
    let mut limited = reader.take(MAX_HEADER_BYTES);
    let read = image::codecs::pnm::PnmDecoder::new(&mut limited).map(drop);
    match read {
        Ok(()) => Ok(()),
        // The decoder ran out of the bytes it was given: the header goes on past them.
        Err(_) if limited.limit() == 0 => Err(format!(
            "has a PNM header that does not end within its first {} KiB",
            MAX_HEADER_BYTES >> 10
        )),
        Err(e) => Err(format!("is not a PNM file tessera reads: {e}")),
    }
}

/// The fewest bytes a sample written as text takes: a digit and a separator (the last
/// sample's may be the file's end). A bitmap's (P1) digits need none between them.
pub const MIN_TEXT_SAMPLE_BYTES: u64 = 2;

/// Checks that the `len`-byte PNM file `reader` is at the start of (its header already
/// checked by `check_bounds`) is long enough for the samples its header claims, before the
/// decoder makes room for them all: a binary raster's bytes exactly, a text raster's
/// `MIN_TEXT_SAMPLE_BYTES` a sample. A file of 317 bytes whose header says `P6 4096 4096
/// 255` once had 50 MB reserved for it (and ended tessera where that allocation failed).
pub fn check_length<R: BufRead + std::io::Seek>(mut reader: R, len: u64) -> Result<(), String> {
    use image::ImageDecoder;
    use image::codecs::pnm::{PnmDecoder, PnmSubtype, SampleEncoding};
    use std::io::Read;
    let decoder = PnmDecoder::new(&mut reader)
        .map_err(|e| format!("is not a PNM file tessera reads: {e}"))?;
    let (width, height) = decoder.dimensions();
    let color = decoder.color_type();
    // What the decoder fills: each sample of one or two bytes.
    let total = u128::from(decoder.total_bytes());
    let samples = total / u128::from(color.bytes_per_pixel() / color.channel_count());
    let subtype = decoder.subtype();
    let (_, header) = decoder.into_inner();
    // A PAM of DEPTH 0 has no channels, and Netpbm refuses it; the decoder reads it as
    // 16-bit grey (two bytes a pixel, scaled by 65535 over its maxval), so `compare` gave
    // it a number against a grey image with nothing said.
    if header.as_arbitrary().is_some_and(|pam| pam.depth == 0) {
        return Err(
            "is a PAM of DEPTH 0, a pixel of no channels, which Netpbm refuses and tessera \
             does not read"
                .to_owned(),
        );
    }
    // A PAM without a TUPLTYPE line is read by the decoder one byte a sample whatever its
    // MAXVAL, scaled down by it, where Netpbm and every other reader read two bytes a sample
    // of a MAXVAL past 255: a PAM of MAXVAL 65535 whose samples are all 0x7f7f, which they
    // show mid-grey, was `identical` to a black PPM.
    if let Some(pam) = header
        .as_arbitrary()
        .filter(|pam| pam.tupltype.is_none() && pam.maxval > 255)
    {
        return Err(format!(
            "is a PAM without a TUPLTYPE line of MAXVAL {}, whose samples the decoder reads \
             as one byte each where Netpbm reads two: tessera does not read it",
            pam.maxval
        ));
    }
    let header = reader
        .stream_position()
        .map_err(|e| format!("could not be read: {e}"))?;
    // A comment that begins right after a number's digits ends the number for Netpbm (its
    // line end the one separator before a binary raster), where the decoder reads on past
    // the comment into the next bytes: `255#c` and a line end, then a space, read as the
    // maxval and a separator, so that the decoder's raster began a byte after Netpbm's and a
    // file Netpbm shows otherwise was `identical`.
    if !matches!(subtype, PnmSubtype::ArbitraryMap) {
        reader
            .seek(std::io::SeekFrom::Start(0))
            .map_err(|e| format!("could not be read: {e}"))?;
        let mut bytes = Vec::new();
        (&mut reader)
            .take(header)
            .read_to_end(&mut bytes)
            .map_err(|e| format!("could not be read: {e}"))?;
        let (mut in_comment, mut after_digit) = (false, false);
        for &b in &bytes {
            if in_comment {
                in_comment = !matches!(b, b'\n' | b'\r');
                continue;
            }
            if b == b'#' && after_digit {
                return Err(
                    "has a PNM header comment right after a number, which Netpbm and the \
                     decoder read differently (where the number ends, where the pixels \
                     begin): tessera does not read it"
                        .to_owned(),
                );
            }
            in_comment = b == b'#';
            after_digit = b.is_ascii_digit();
        }
    }
    let raster = match (subtype, subtype.sample_encoding()) {
        // Rows of bits, each row rounded up to a whole byte.
        (PnmSubtype::Bitmap(_), SampleEncoding::Binary) => {
            u128::from(width.div_ceil(8)) * u128::from(height)
        }
        (_, SampleEncoding::Binary) => total,
        (PnmSubtype::Bitmap(_), SampleEncoding::Ascii) => samples,
        (_, SampleEncoding::Ascii) => {
            (samples * u128::from(MIN_TEXT_SAMPLE_BYTES)).saturating_sub(1)
        }
    };
    let least = u128::from(header) + raster;
    if u128::from(len) < least {
        return Err(format!(
            "ends before its image does (a truncated file?): it is {len} bytes long, and its \
             header of {header} bytes claims {width}x{height} pixels, whose samples take \
             {raster} bytes at least"
        ));
    }
    Ok(())
}

/// The first sample past its maxval of the PNM file `reader` is at the start of (its header
/// already checked by `check_bounds`), said in words: the decoder scales such a sample to
/// the brightest value, where Netpbm refuses the file ("exceeds maxval") and other readers
/// scale it past the brightest (GIMP's wraps round). `None` when every sample is within
/// it, the file is a bitmap, its maxval is the largest its samples can hold (255, 65535),
/// or a sample is not one the decoder reads (its error then says so).
pub fn sample_past_maxval(reader: impl BufRead) -> Option<String> {
    use image::codecs::pnm::{PnmDecoder, SampleEncoding};
    let (mut reader, header) = PnmDecoder::new(reader).ok()?.into_inner();
    let maxval = header.maximal_sample();
    if header.as_bitmap().is_some() || maxval == 255 || maxval == 65535 {
        return None;
    }
    let said = |value: u32, at: u64| {
        Some(format!(
            "sample {} of its pixels' values is {value}, past its maxval of {maxval}: Netpbm \
             refuses the file, and viewers differ in what they show for it (compare measured \
             it as the brightest)",
            at + 1
        ))
    };
    // The raster's samples only: what follows it is no sample of the picture.
    let components = header
        .as_arbitrary()
        .map_or(if header.as_pixmap().is_some() { 3 } else { 1 }, |a| {
            u64::from(a.depth)
        });
    let count = u64::from(header.width()) * u64::from(header.height()) * components;
    let mut at = 0u64;
    match header.subtype().sample_encoding() {
        SampleEncoding::Binary => {
            let wide = maxval > 255;
            let mut high = None;
            while at < count {
                let buf = reader.fill_buf().ok()?;
                if buf.is_empty() {
                    break;
                }
                let n = buf.len();
                for &b in buf {
                    let value = match (wide, high.take()) {
                        (false, _) => u32::from(b),
                        (true, None) => {
                            high = Some(b);
                            continue;
                        }
                        (true, Some(h)) => u32::from(u16::from_be_bytes([h, b])),
                    };
                    if value > maxval {
                        return said(value, at);
                    }
                    at += 1;
                    if at == count {
                        break;
                    }
                }
                reader.consume(n);
            }
        }
        SampleEncoding::Ascii => {
            let mut digits = Vec::new();
            for byte in reader.bytes() {
                if at == count {
                    break;
                }
                let b = byte.ok()?;
                if b.is_ascii_digit() {
                    digits.push(b);
                    continue;
                }
                if !b.is_ascii_whitespace() {
                    return None;
                }
                if !digits.is_empty() {
                    let value = std::str::from_utf8(&digits).ok()?.parse::<u32>().ok()?;
                    if value > maxval {
                        return said(value, at);
                    }
                    at += 1;
                    digits.clear();
                }
            }
            let value = std::str::from_utf8(&digits).ok()?.parse::<u32>().ok();
            if let Some(value) = value.filter(|&v| v > maxval && at < count) {
                return said(value, at);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// A PAM header of one 1x1 RGB pixel, with `comment` on a line of its own first.
    fn pam(comment: &[u8]) -> Vec<u8> {
        let mut bytes = b"P7\n#".to_vec();
        bytes.extend(comment);
        bytes.extend(
            b"\nWIDTH 1\nHEIGHT 1\nDEPTH 3\nMAXVAL 255\nTUPLTYPE RGB\nENDHDR\n\x01\x02\x03",
        );
        bytes
    }

    /// A sample past the maxval (200 where it is 100), binary, plain or 16-bit: the decoder
    /// took it as the brightest, so that `compare` called such a file identical with a white
    /// one, which Netpbm refuses. Samples within it, and files whose maxval is the largest
    /// their samples hold, are not listed.
    #[test]
    fn a_sample_past_the_maxval_is_said() {
        let past = |bytes: &[u8]| sample_past_maxval(Cursor::new(bytes.to_vec()));
        let said = past(b"P6\n2 1\n100\n\x64\x64\x64\x64\xc8\x64").unwrap();
        assert!(
            said.starts_with("sample 5 of its pixels' values is 200, past its maxval of 100"),
            "{said}"
        );
        let said = past(b"P3\n2 1\n100\n100 100 100\n100 100 200\n").unwrap();
        assert!(
            said.starts_with("sample 6 of its pixels' values is 200,"),
            "{said}"
        );
        let said = past(b"P5\n1 1\n1000\n\x03\xe9").unwrap();
        assert!(
            said.starts_with("sample 1 of its pixels' values is 1001,"),
            "{said}"
        );
        let pam = b"P7\nWIDTH 1\nHEIGHT 1\nDEPTH 3\nMAXVAL 7\nTUPLTYPE RGB\nENDHDR\n\x07\x08\x00";
        let said = past(pam).unwrap();
        assert!(
            said.starts_with("sample 2 of its pixels' values is 8,"),
            "{said}"
        );
        for within in [
            &b"P6\n2 1\n100\n\x64\x64\x64\x00\x00\x00"[..],
            b"P3\n2 1\n100\n100 0 100 0 0 99",
            b"P6\n1 1\n255\n\xff\xff\xff",
            b"P5\n1 1\n1000\n\x03\xe8",
            b"P1\n2 1\n1 0\n",
            // What follows the raster is no sample.
            b"P6\n1 1\n100\n\x64\x64\x64\xc8",
            b"P3\n1 1\n100\n1 2 3 200\n",
        ] {
            assert_eq!(past(within), None, "{}", String::from_utf8_lossy(within));
        }
    }

    /// A PPM of 317 bytes whose header says `P6 4096 4096 255` had 50 MB reserved for its
    /// samples before it was found short (and ended tessera where the allocation failed):
    /// its length is checked against its header first, a binary raster's bytes exactly, a
    /// text raster's two bytes a sample (a bitmap's one), 16-bit samples two bytes each.
    /// A PAM of DEPTH 0 (no channels: Netpbm refuses it) was read by the decoder as 16-bit
    /// grey, and `compare` of it against a grey PGM gave 1.14 dB with nothing listed.
    #[test]
    fn a_pam_of_no_channels_is_refused() {
        let pam = b"P7\nWIDTH 2\nHEIGHT 1\nDEPTH 0\nMAXVAL 255\nTUPLTYPE GRAYSCALE\nENDHDR\n\
                    \x10\x20\x30\x40";
        let e = check_length(Cursor::new(&pam[..]), pam.len() as u64).unwrap_err();
        assert!(e.contains("DEPTH 0"), "{e}");
        let one = b"P7\nWIDTH 2\nHEIGHT 1\nDEPTH 1\nMAXVAL 255\nTUPLTYPE GRAYSCALE\nENDHDR\n\
                    \x10\x20";
        assert_eq!(
            check_length(Cursor::new(&one[..]), one.len() as u64),
            Ok(())
        );
    }

    /// The decoder reads a PAM without a TUPLTYPE line one byte a sample whatever its
    /// MAXVAL, scaling each by 255 over it: a PAM of MAXVAL 65535 whose samples are all
    /// 0x7f7f (mid-grey to Netpbm, which reads two bytes a sample) decoded black, and
    /// `compare` called it identical to a black PPM. Such a PAM is refused; one of a
    /// MAXVAL of at most 255, or with a TUPLTYPE, is read as before.
    #[test]
    fn a_pam_without_a_tuple_type_of_two_byte_samples_is_refused() {
        let check = |bytes: &[u8]| check_length(Cursor::new(bytes), bytes.len() as u64);
        let pam = |maxval: &str, tupltype: &str| {
            let head =
                format!("P7\nWIDTH 2\nHEIGHT 2\nDEPTH 3\nMAXVAL {maxval}\n{tupltype}ENDHDR\n");
            [head.as_bytes(), &[0x7f; 24]].concat()
        };
        for maxval in ["65535", "256"] {
            let e = check(&pam(maxval, "")).unwrap_err();
            assert!(
                e.starts_with(&format!(
                    "is a PAM without a TUPLTYPE line of MAXVAL {maxval}"
                )),
                "{e}"
            );
        }
        assert_eq!(check(&pam("255", "")), Ok(()));
        assert_eq!(check(&pam("65535", "TUPLTYPE RGB\n")), Ok(()));
    }

    /// Netpbm ends a number where a comment begins, and takes the comment's line end as the
    /// one separator before a binary raster; the decoder read on past the comment, so that
    /// `P5 2 1 255#c`, a line end and the bytes 20 20 80 was `identical` to a PGM of the
    /// bytes 20 80 (Netpbm reads 20 20). A comment right after a number is refused; one
    /// after a separator, or holding digits and `#`, is not.
    #[test]
    fn a_comment_right_after_a_number_is_refused() {
        let check = |bytes: &[u8]| check_length(Cursor::new(bytes), bytes.len() as u64);
        for after in [
            &b"P5\n2 1\n255#c\n\x20\x20\x80"[..],
            b"P5\n2#c\n0 1\n255\n\x20\x80",
        ] {
            let e = check(after).unwrap_err();
            assert!(e.contains("comment right after a number"), "{e}");
        }
        for fine in [
            &b"P5\n2 1\n255\n\x20\x80"[..],
            b"P5\n# made by v1#2\n2 1 #c\n255\n\x20\x80",
            b"P3\n1 1\n255\n1 2 3\n",
        ] {
            assert_eq!(check(fine), Ok(()), "{}", String::from_utf8_lossy(fine));
        }
    }

    #[test]
    fn a_file_shorter_than_its_header_s_samples_is_refused_before_they_are_read() {
        let check = |bytes: &[u8]| check_length(Cursor::new(bytes), bytes.len() as u64);
        let short = [&b"P6\n4096 4096\n255\n"[..], &[0; 300]].concat();
        assert_eq!(short.len(), 317);
        let e = check(&short).unwrap_err();
        assert!(
            e.starts_with(
                "ends before its image does (a truncated file?): it is 317 bytes long, and its \
                 header of 17 bytes claims 4096x4096 pixels, whose samples take 50331648 bytes"
            ),
            "{e}"
        );
        for (whole, cut) in [
            (&b"P6\n2 1\n255\n\x01\x02\x03\x04\x05\x06"[..], 1),
            (b"P5\n1 1\n1000\n\x03\xe8", 1),
            (b"P3\n2 1\n255\n1 2 3 4 5 6", 2),
            (b"P1\n2 2\n1001", 1),
            (b"P4\n9 2\n\x00\x00\x00\x00", 1),
            (
                b"P7\nWIDTH 1\nHEIGHT 1\nDEPTH 4\nMAXVAL 65535\nTUPLTYPE RGB_ALPHA\nENDHDR\n\
                  \x00\x01\x00\x02\x00\x03\x00\x04",
                1,
            ),
        ] {
            let shown = String::from_utf8_lossy(whole);
            assert_eq!(check(whole), Ok(()), "{shown}");
            let e = check(&whole[..whole.len() - cut]).unwrap_err();
            assert!(e.starts_with("ends before its image does"), "{shown}: {e}");
        }
    }

    #[test]
    fn a_header_that_does_not_end_within_the_bound_is_refused() {
        assert_eq!(check_bounds(Cursor::new(pam(b"a short comment"))), Ok(()));
        assert_eq!(
            check_bounds(Cursor::new(b"P3\n2 1\n255\n255 0 64\n0 0 0\n")),
            Ok(())
        );
        let long = pam(&vec![b'a'; MAX_HEADER_BYTES as usize]);
        let e = check_bounds(Cursor::new(long)).unwrap_err();
        assert!(e.contains("does not end within its first 64 KiB"), "{e}");
        // A header cut short within the bound is the decoder's error, said as such.
        let e = check_bounds(Cursor::new(b"P7\nWIDTH 1\n")).unwrap_err();
        assert!(e.starts_with("is not a PNM file tessera reads"), "{e}");
    }
}
