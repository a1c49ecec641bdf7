//! A PNM file's header (PBM, PGM, PPM or PAM) read as a stranger's: it must end within
//! `MAX_HEADER_BYTES` before a decoder reads the file. The `image` crate's decoder reads each
//! line of a PAM header, comments included, into memory whatever its length, so a PAM of one
//! comment line of 4 GiB (a sparse file, a few KiB of disk) once took 4.2 GB and then ended
//! tessera on a failed allocation. Below the image textures and `compare`, which walk it so.

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
