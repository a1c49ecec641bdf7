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
    regular(file)
}

/// Opens `path` as `open_regular` does, where its last component is not a symbolic link:
/// one there (swapped in since a caller looked) is not followed, and the error is ELOOP.
pub fn open_regular_not_a_link(path: &Path) -> io::Result<File> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW)
        .open(path)?;
    regular(file)
}

/// Opens `path`, a canonical path (no symbolic link anywhere along it), as `open_regular`
/// does; where a link has since been swapped in anywhere along it, nothing is opened and
/// the error is `LinkFound`. With Linux's `openat2` (5.6 and later) no link is followed at
/// any step; where it is missing or a sandbox forbids it, only the last step is guarded
/// (`O_NOFOLLOW`), and the caller checks what it opened.
pub fn open_regular_without_links(path: &Path) -> Result<File, LinkOr> {
    use rustix::fs::{Mode, OFlags, ResolveFlags};
    let flags = OFlags::RDONLY | OFlags::NONBLOCK | OFlags::CLOEXEC;
    let resolve = ResolveFlags::NO_SYMLINKS | ResolveFlags::NO_MAGICLINKS;
    let opened = match rustix::fs::openat2(rustix::fs::CWD, path, flags, Mode::empty(), resolve) {
        Err(rustix::io::Errno::NOSYS | rustix::io::Errno::PERM) => std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW)
            .open(path),
        opened => opened.map(File::from).map_err(io::Error::from),
    };
    match opened {
        Ok(file) => regular(file).map_err(LinkOr::Other),
        Err(e) if e.raw_os_error() == Some(libc::ELOOP) => Err(LinkOr::LinkFound),
        Err(e) => Err(LinkOr::Other(e)),
    }
}

/// Why `open_regular_without_links` opened nothing.
#[derive(Debug)]
pub enum LinkOr {
    /// A symbolic link lies along the path.
    LinkFound,
    Other(io::Error),
}

/// `file`, if it is a regular file; else why not.
fn regular(file: File) -> io::Result<File> {
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

    #[test]
    fn a_path_with_a_link_anywhere_along_it_is_not_opened() {
        let root = std::env::temp_dir().join(format!("tessera-links-{}", std::process::id()));
        let inside = root.join("real");
        std::fs::create_dir_all(&inside).unwrap();
        std::fs::write(inside.join("a.png"), b"a").unwrap();
        std::os::unix::fs::symlink(&inside, root.join("dir-link")).unwrap();
        std::os::unix::fs::symlink(inside.join("a.png"), inside.join("file-link")).unwrap();
        let root = root.canonicalize().unwrap();
        assert!(open_regular_without_links(&root.join("real/a.png")).is_ok());
        // A link at the last step is refused wherever this runs; one at an earlier step
        // where the kernel has openat2 (where it has not, the caller's check of what was
        // opened is the guard).
        assert!(matches!(
            open_regular_without_links(&root.join("real/file-link")),
            Err(LinkOr::LinkFound)
        ));
        let through_dir = open_regular_without_links(&root.join("dir-link/a.png"));
        let has_openat2 = !matches!(
            rustix::fs::openat2(
                rustix::fs::CWD,
                "/",
                rustix::fs::OFlags::RDONLY,
                rustix::fs::Mode::empty(),
                rustix::fs::ResolveFlags::empty()
            ),
            Err(rustix::io::Errno::NOSYS | rustix::io::Errno::PERM)
        );
        if has_openat2 {
            assert!(
                matches!(through_dir, Err(LinkOr::LinkFound)),
                "{through_dir:?}"
            );
        }
        assert!(matches!(
            open_regular_without_links(Path::new("/dev/zero")),
            Err(LinkOr::Other(_))
        ));
        std::fs::remove_dir_all(&root).unwrap();
    }
}
