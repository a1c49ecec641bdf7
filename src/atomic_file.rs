//! Files written whole or not at all: a temporary file beside the target, synced and renamed
//! over it, so a reader or a crash never sees half a file. Images, part files, checkpoints,
//! benchmark results and preview frames all go through here.

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The temporary file beside `path` that `write_atomically` writes first.
fn temporary_beside(path: &Path) -> Result<PathBuf> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().ok_or_else(|| Error::Image {
        path: path.to_owned(),
        message: "output path has no file name".to_owned(),
    })?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    Ok(dir.join(tmp_name))
}

/// True when `path` exists and is neither a file nor a directory: a device such as
/// `/dev/null`, or a pipe.
fn is_special(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Checks, before any work is spent on it, that `write_atomically` can write `path`: its
/// directory exists and takes a new file, and `path` is not a directory.
pub fn check_writable(path: &Path) -> Result<()> {
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    if path.is_dir() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a directory, not a file name",
        )));
    }
    if is_special(path) {
        // Written in place; opening a pipe now would wait for its reader.
        return Ok(());
    }
    let tmp = temporary_beside(path)?;
    std::fs::File::create(&tmp).map_err(io)?;
    std::fs::remove_file(&tmp).map_err(io)
}

/// Writes `bytes` to a temporary file beside `path`, syncs it and renames it over `path`, so
/// a reader (or a crash) never sees a half-written file and an old file survives a failure.
/// A device or a pipe (`-o /dev/null`) is written in place: renaming a file over it would
/// replace the device itself.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically_with(path, &mut |out| out.write_all(bytes))
}

/// `write_atomically` of what `write` writes, streamed through a buffer rather than made
/// whole in memory first.
pub fn write_atomically_with(
    path: &Path,
    write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    let buffered =
        |file: std::fs::File, write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>| {
            let mut out = std::io::BufWriter::with_capacity(1 << 16, file);
            write(&mut out)?;
            out.into_inner()
                .map_err(std::io::IntoInnerError::into_error)
        };
    if is_special(path) {
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io)?;
        return buffered(f, write).map(drop).map_err(io);
    }
    let tmp = temporary_beside(path)?;
    let result = (|| {
        let f = buffered(std::fs::File::create(&tmp)?, write)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_are_written_in_place_not_replaced() {
        let null = Path::new("/dev/null");
        if !is_special(null) {
            return; // not a Unix machine
        }
        check_writable(null).unwrap();
        write_atomically(null, b"into the void").unwrap();
        assert!(is_special(null), "/dev/null was replaced by a file");
        let full = write_atomically(Path::new("/dev/full"), b"x");
        assert!(full.is_err_and(|e| e.to_string().contains("/dev/full")));
    }

    #[test]
    fn atomic_write_replaces_whole_file() {
        let dir = std::env::temp_dir().join(format!("tessera-film-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.ppm");
        write_atomically(&p, b"first").unwrap();
        write_atomically(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        let leftovers = std::fs::read_dir(&dir).unwrap().count();
        assert_eq!(leftovers, 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
