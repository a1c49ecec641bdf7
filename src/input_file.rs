//! Files a stranger may hand tessera (images, part files, results), opened to read: regular
//! files only, so a pipe or a device named as an input is refused with the reason instead of
//! blocking the command forever or reading without end.

use std::fs::File;
use std::io;
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// Opens `path` to read, refusing what is not a regular file. The file is opened without
/// blocking (a FIFO with no writer would wait for one) and then checked by its handle, so
/// nothing swapped in between a check and the open gets through.
pub fn open_regular(path: &Path) -> io::Result<File> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    let kind = file.metadata()?.file_type();
    if kind.is_file() {
        return Ok(file);
    }
    let what = if kind.is_dir() {
        "a directory"
    } else if std::os::unix::fs::FileTypeExt::is_fifo(&kind) {
        "a pipe (FIFO)"
    } else if std::os::unix::fs::FileTypeExt::is_socket(&kind) {
        "a socket"
    } else {
        "a device"
    };
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        format!("is {what}, not a regular file: tessera reads only files here"),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_directories_are_refused_files_read() {
        let device = open_regular(Path::new("/dev/zero")).unwrap_err();
        assert!(device.to_string().contains("is a device"), "{device}");
        let dir = open_regular(Path::new("/")).unwrap_err();
        assert!(dir.to_string().contains("is a directory"), "{dir}");
        assert!(open_regular(Path::new("Cargo.toml")).is_ok());
    }
}
