//! Files written whole or not at all: a temporary file beside the target, synced and renamed
//! over it, so a reader or a crash never sees half a file. Images, part files, checkpoints,
//! benchmark results and preview frames all go through here.

use crate::error::{Error, Result};
use crate::owner;
use std::io::Write;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};

/// The directory `path` is written in.
fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// The start of a temporary file's name beside `path`: `.NAME.`, to which six random
/// characters and `.tmp` are added.
fn temporary_prefix(path: &Path) -> std::io::Result<std::ffi::OsString> {
    let name = path.file_name().ok_or_else(|| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the output path has no file name",
        )
    })?;
    refuse_unnameable(path, name)?;
    // A name near the file system's limit (255 bytes) leaves no room for what the temporary
    // name adds (a dot before, a dot, six characters and `.tmp` after): its start stands for
    // it, so that every name a file may have can be written.
    const ADDED: usize = 12;
    let name = std::os::unix::ffi::OsStrExt::as_bytes(name);
    let name = &name[..name.len().min(255 - ADDED)];
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(<std::ffi::OsStr as std::os::unix::ffi::OsStrExt>::from_bytes(name));
    prefix.push(".");
    Ok(prefix)
}

/// A new temporary file beside `path`, named `.NAME.XXXXXX.tmp` with six random characters:
/// created exclusively (`O_CREAT | O_EXCL`, so nothing already there, a symbolic link that
/// another user planted included, is opened or followed), with the permissions a new file
/// gets from the umask, and removed again if it is dropped before it is persisted.
fn temporary_beside(path: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let dir = directory_of(path);
    tempfile::Builder::new()
        .prefix(&temporary_prefix(path)?)
        .suffix(".tmp")
        .permissions(std::fs::Permissions::from_mode(0o666))
        .tempfile_in(&dir)
        .map_err(|e| without_temporary_name(e, &dir))
}

/// `e`, an error of creating a temporary file in `dir`, said of the directory: tempfile
/// ends its message with the temporary file's random name (`… at path "/d/.x.png.Ab12Cd.tmp"`),
/// a file that never existed, which read as the file at fault.
fn without_temporary_name(e: std::io::Error, dir: &Path) -> std::io::Error {
    let message = e.to_string();
    let cause = message
        .rsplit_once(" at path ")
        .map_or(&*message, |(cause, _)| cause);
    std::io::Error::new(
        e.kind(),
        format!(
            "could not create a file in {}: {cause}",
            directory_named(dir)
        ),
    )
}

/// How a message names the directory `dir`: the current one in words, with its full name
/// where that can be found (a bare "." before a full stop reads as the parent).
pub fn directory_named(dir: &Path) -> String {
    if dir != Path::new(".") {
        return dir.display().to_string();
    }
    match std::env::current_dir() {
        Ok(full) => format!("the current directory ({})", full.display()),
        Err(_) => "the current directory".to_owned(),
    }
}

/// A new file in `path`'s directory with no name at all (`O_TMPFILE`), with the permissions
/// a new file gets from the umask, or None where the file system makes none or one cannot be
/// named there (`name_beside`: no `/proc`, say). A file with a name while it is written
/// outlived a process ended then: SIGTERM, Ctrl-C or a second Ctrl-C during the seconds a
/// large image takes to write left a hidden `.NAME.XXXXXX.tmp` of hundreds of megabytes
/// beside the output, one more at each stop. A file with no name goes with the process.
/// It is opened to read too, so that it can be copied to a named file where it cannot be
/// named itself once written (`copied_beside`).
fn unnamed_beside(path: &Path) -> Option<std::fs::File> {
    use rustix::fs::{CWD, Mode, OFlags, openat};
    let open = || {
        let flags = OFlags::TMPFILE | OFlags::RDWR | OFlags::CLOEXEC;
        openat(CWD, directory_of(path), flags, Mode::from(0o666)).map(std::fs::File::from)
    };
    // Another such file is named and removed first: once written, a file that cannot be
    // named would lose the work it holds.
    let trial = open().ok()?;
    drop(name_beside(path, &trial).ok()?);
    open().ok()
}

/// The name `/proc` gives the open `file`: `/proc/self/fd/N`.
fn proc_path(file: &std::fs::File) -> PathBuf {
    use std::os::fd::AsRawFd;
    PathBuf::from(format!("/proc/self/fd/{}", file.as_raw_fd()))
}

/// Gives `file`, made by `unnamed_beside(path)` and written whole, a temporary name beside
/// `path` (`.NAME.XXXXXX.tmp`, as `temporary_beside`), to be renamed over `path` at once:
/// the link is made only where no file is (a link planted there is not followed), and it
/// is removed again if the name is dropped before it is persisted.
fn name_beside(path: &Path, file: &std::fs::File) -> std::io::Result<tempfile::TempPath> {
    use rustix::fs::{AtFlags, CWD, linkat};
    let (from, dir) = (proc_path(file), directory_of(path));
    let named = tempfile::Builder::new()
        .prefix(&temporary_prefix(path)?)
        .suffix(".tmp")
        .make_in(&dir, |name| {
            linkat(CWD, &from, CWD, name, AtFlags::SYMLINK_FOLLOW).map_err(std::io::Error::from)
        })
        .map_err(|e| without_temporary_name(e, &dir))?;
    Ok(named.into_temp_path())
}

/// `file`, made by `unnamed_beside(path)` and written whole, copied to a new temporary file
/// beside `path` (`temporary_beside`) and synced: the second way to a name where the link
/// (`name_beside`) fails once the file is written. The link once was the only way: where it
/// failed (the directory moved to another file system while the file was written, "Invalid
/// cross-device link", or a link count or quota reached), the finished image went with the
/// unnamed file, a render of minutes lost for a failure a new file survives.
fn copied_beside(path: &Path, file: &mut std::fs::File) -> std::io::Result<tempfile::TempPath> {
    use std::io::Seek;
    file.seek(std::io::SeekFrom::Start(0))?;
    let mut copy = temporary_beside(path)?;
    std::io::copy(file, copy.as_file_mut())?;
    copy.as_file().sync_all()?;
    Ok(copy.into_temp_path())
}

/// How a file made by `unnamed_beside` is given its temporary name: `name_beside`, but for
/// tests that make the link fail.
type Link = fn(&Path, &std::fs::File) -> std::io::Result<tempfile::TempPath>;

/// Refuses a path no file can be renamed to, before anything is written: one that ends in
/// `/` or `/.` (a directory's form: `Path::file_name` reads `x.png/` as `x.png`, and the
/// rename at the end failed, "Not a directory"), or whose name is longer than a file
/// system's 255 bytes ("File name too long"). Both once failed only once the file was
/// written, after the render, a hidden temporary file of it left behind at each try.
fn refuse_unnameable(path: &Path, name: &std::ffi::OsStr) -> std::io::Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let bytes = path.as_os_str().as_bytes();
    if bytes.ends_with(b"/") || bytes.ends_with(b"/.") {
        return Err(std::io::Error::new(
            std::io::ErrorKind::NotADirectory,
            "ends in `/`, as a directory's name does, not a file's",
        ));
    }
    if name.as_bytes().len() > 255 {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidFilename,
            format!(
                "its name is {} bytes long, more than the 255 a file system takes",
                name.as_bytes().len()
            ),
        ));
    }
    Ok(())
}

/// True when `path` exists and is neither a file nor a directory: a device such as
/// `/dev/null`, or a pipe, named itself or by a symbolic link of this user's or root's
/// (`/dev/stdout`). A link of another user's is not followed: in a directory others may
/// write to (`/tmp`), another user can leave one under the name an output will have,
/// pointing at a device of theirs (their own terminal), which then received the image, recipe
/// and all, with no file made and exit 0. Such a link is replaced by the file, as a link to
/// a file is. So is, written in place, a file that `path` names as one of this process's
/// open files (`open_file_named`: `/dev/stdout` redirected to a file).
fn is_special(path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match std::fs::symlink_metadata(path) {
        Ok(link) if link.file_type().is_symlink() && owner::is_another_users(link.uid(), &[]) => {
            false
        }
        Ok(_) => std::fs::metadata(path)
            .is_ok_and(|m| !m.is_dir() && (!m.is_file() || open_file_named(path).is_some())),
        Err(_) => false,
    }
}

/// Whether `write_atomically` writes `path` in place rather than replacing it with a new
/// file: a device, a pipe, or one of this process's open files (`/dev/stdout` redirected to
/// a file), as `is_special` says.
pub fn written_in_place(path: &Path) -> bool {
    is_special(path)
}

/// Symbolic links followed, at most, to see where a path leads (the kernel's own limit).
const MAX_LINKS: usize = 40;

/// The file descriptor N when `path` is, or leads by symbolic links to, one of this
/// process's open files as `/proc` names them (`/proc/self/fd/N`, `/dev/fd/N`): `/dev/stdout`
/// with the output redirected to a file (`-o /dev/stdout > out.json`), the file the shell
/// opened for the redirect. Renaming over the path replaced the link itself (`/dev/stdout` of
/// the whole machine, where tessera ran as root) and left the redirected file empty, exit 0.
fn open_file_named(path: &Path) -> Option<u32> {
    let mut at = path.to_owned();
    for _ in 0..MAX_LINKS {
        if let Some(fd) = open_file_s_number(&at) {
            return Some(fd);
        }
        // The link is read, not followed: `/proc/self/fd/N` itself reads as the file's name.
        let target = std::fs::read_link(&at).ok()?;
        at = directory_of(&at).join(target);
    }
    None
}

/// N, where `path` is a name `/proc` gives the open file N of this process:
/// `/proc/self/fd/N`, `/proc/thread-self/fd/N`, `/proc/PID/fd/N` with this process's id, or
/// `/dev/fd/N`.
fn open_file_s_number(path: &Path) -> Option<u32> {
    use std::path::Component;
    let parts: Vec<Component> = path.components().collect();
    let named = |c: &Component, name: &str| c.as_os_str() == name;
    let number = |c: &Component| (c.as_os_str().to_str()).and_then(|n| n.parse::<u32>().ok());
    let this_process = std::process::id().to_string();
    match parts.as_slice() {
        [Component::RootDir, proc, whose, fd, n]
            if named(proc, "proc")
                && (named(whose, "self")
                    || named(whose, "thread-self")
                    || named(whose, &this_process))
                && named(fd, "fd") =>
        {
            number(n)
        }
        [Component::RootDir, dev, fd, n] if named(dev, "dev") && named(fd, "fd") => number(n),
        _ => None,
    }
}

/// Whether this process has its file descriptor `fd` open for writing, as
/// `/proc/self/fdinfo/N` says (the access mode of its `flags`, in octal); None where that
/// cannot be read.
fn open_for_writing(fd: u32) -> Option<bool> {
    let info = std::fs::read_to_string(format!("/proc/self/fdinfo/{fd}")).ok()?;
    let flags = info.lines().find_map(|l| l.strip_prefix("flags:"))?;
    let flags = u32::from_str_radix(flags.trim(), 8).ok()?;
    let mode = flags & libc::O_ACCMODE as u32;
    Some(
        flags & libc::O_PATH as u32 == 0
            && (mode == libc::O_WRONLY as u32 || mode == libc::O_RDWR as u32),
    )
}

/// Refuses a `path` that leads to one of this process's open files (`open_file_named`)
/// that the process does not hold open for writing: standard input (`-o /dev/stdin <
/// scene.toml`), or any descriptor opened only to read. Written through, the output was
/// appended to the very file the shell gave as input (a 12-byte file grew to 3,393 bytes,
/// exit 0), or, where the input is a pipe, written into the pipe the process itself reads,
/// which waits forever once its buffer is full. Only what the shell opened for writing
/// (`>`, `>>`, `<>`) is written through.
fn refuse_read_only_descriptor(path: &Path) -> std::io::Result<()> {
    let Some(fd) = open_file_named(path) else {
        return Ok(());
    };
    let which = match fd {
        0 => "standard input (file descriptor 0)".to_owned(),
        n => format!("file descriptor {n}"),
    };
    let why = match open_for_writing(fd) {
        Some(true) => return Ok(()),
        Some(false) => "which this process has open only for reading",
        None => "which this process cannot tell is open for writing (no /proc/self/fdinfo)",
    };
    // Not "permission denied": that reads as the directory's, which is not at fault.
    Err(std::io::Error::other(format!(
        "leads to {which}, {why}: the output would go into what this command reads; name \
         a file, or redirect standard output with `>` and write to /dev/stdout"
    )))
}

/// Opens the device or pipe at `path` (`is_special`) to write in place. A symbolic link is
/// followed only where there was one when `is_special` took it (this user's or root's):
/// one swapped in since for a device named itself is refused (`O_NOFOLLOW`), not followed.
/// A file (one of this process's open files, `open_file_named`) is written at its end,
/// as the shell's `>` (which left it empty) or `>>` asked: opened again by its name, it
/// would be written from its start, over what it held.
fn open_in_place(path: &Path) -> std::io::Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    let link = std::fs::symlink_metadata(path)?.file_type().is_symlink();
    let mut options = std::fs::OpenOptions::new();
    options.write(true);
    if std::fs::metadata(path)?.is_file() {
        options.append(true);
    }
    if !link {
        options.custom_flags(libc::O_NOFOLLOW);
    }
    options.open(path)
}

/// Refuses to write in place what is at `path` (`is_special`) where that cannot end in a
/// file written: a pipe (FIFO) that another user owns (neither this user nor root), or a
/// socket. In a directory others may write to (`/tmp`), another user can make one under the
/// name an output will have: writing their pipe in place sent the image to whoever reads it,
/// with no file made and exit 0, or, with nobody reading, waited forever; a socket cannot be
/// opened at all ("No such device or address"). The kernel's `fs.protected_fifos` guards only
/// opens that may create the file, which this is not. So too one of this process's open
/// files that it does not hold open for writing (`refuse_read_only_descriptor`).
fn refuse_in_place(path: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    refuse_read_only_descriptor(path)?;
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    if meta.file_type().is_socket() {
        return Err(std::io::Error::other(format!(
            "is a socket (uid {}): no file can be written there; remove it or choose another \
             name",
            meta.uid()
        )));
    }
    if meta.file_type().is_fifo() && owner::is_another_users(meta.uid(), &[]) {
        return Err(std::io::Error::other(format!(
            "is a pipe (FIFO) of another user's (uid {}; this is uid {}): what is written \
             there goes to whoever reads it, not to a file; remove it or choose another name",
            meta.uid(),
            owner::this_user()
        )));
    }
    Ok(())
}

/// Refuses a file at `path` that this user may create a file beside but not replace: one of
/// another user's (root's included) in a sticky directory (`/tmp`) of another user's, where
/// only a file's owner may remove or rename over it. The rename that puts the output in
/// place then failed at the very end, "Operation not permitted", the render's work lost.
/// Root may replace any file.
fn refuse_unreplaceable(path: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::MetadataExt;
    let me = owner::this_user();
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    if me == 0 || meta.uid() == me {
        return Ok(());
    }
    let Ok(dir) = std::fs::metadata(directory_of(path)) else {
        return Ok(());
    };
    if dir.mode() & 0o1000 == 0 || dir.uid() == me {
        return Ok(());
    }
    Err(std::io::Error::other(format!(
        "belongs to another user (uid {}; this is uid {me}), in a directory where only a \
         file's owner may replace it (sticky, as /tmp): the output could not be put in its \
         place; remove it or choose another name",
        meta.uid()
    )))
}

/// What is wrong with the output `path`, a directory: the name itself, or a symbolic link to
/// one. A link said only "is a directory", which the name (`out.png`, a link) is not.
fn a_directory(path: &Path) -> String {
    match std::fs::read_link(path) {
        Ok(target) => format!(
            "is a symbolic link to a directory ({}), not a file name; name a file in that \
             directory, or another name",
            crate::text::path_safe(&target)
        ),
        Err(_) => "is a directory, not a file name".to_owned(),
    }
}

/// Checks, before any work is spent on it, that `write_atomically` can write `path`: its
/// directory exists and takes a new file, and `path` is not a directory (nor another user's
/// pipe, nor a socket, nor a file this user may not replace).
pub fn check_writable(path: &Path) -> Result<()> {
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    if path.is_dir() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            a_directory(path),
        )));
    }
    if is_special(path) {
        // Written in place; opening a pipe now would wait for its reader.
        return refuse_in_place(path).map_err(io);
    }
    refuse_unreplaceable(path).map_err(io)?;
    // Created and removed again: the directory takes a new file.
    temporary_beside(path)
        .and_then(|tmp| tmp.close())
        .map_err(io)
}

/// Writes `bytes` to a temporary file beside `path`, syncs it and renames it over `path`, so
/// a reader (or a crash) never sees a half-written file and an old file survives a failure.
/// A device or a pipe (`-o /dev/null`) is written in place: renaming a file over it would
/// replace the device itself.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically_with(path, &mut |out| out.write_all(bytes))
}

/// `write_atomically` of what `write` writes, streamed through a buffer rather than made
/// whole in memory first. The rename replaces `path` itself: where `path` is a symbolic
/// link (to a file, or another user's to anything), the link is replaced, and what it
/// pointed to is left as it was.
pub fn write_atomically_with(
    path: &Path,
    write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    write_whole(path, write, false, name_beside)
}

/// `write_atomically_with` of a result that took work to make (a render's image or part):
/// where the finished file cannot be renamed into place, it is kept under its temporary
/// name, which the error gives, rather than removed. In a sticky directory (`/tmp`) another
/// user can leave a file under the output's name while the render runs, after the check
/// before it (`check_writable`); the rename then failed and the render's work was lost. So
/// too where a pipe of another user's, or a socket, took the name: nothing is written in it.
pub fn write_result_atomically_with(
    path: &Path,
    write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    write_whole(path, write, true, name_beside)
}

/// `write_atomically_with`, keeping the finished temporary file where the rename fails if
/// `keep`; a file written with no name is named by `link` (`name_beside`), or else copied to
/// a named one (`copied_beside`).
fn write_whole(
    path: &Path,
    write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>,
    keep: bool,
    link: Link,
) -> Result<()> {
    let io = |cause| Error::Io {
        path: path.to_owned(),
        cause,
    };
    // Where a pipe or socket that cannot be written in place took the output's name since
    // `check_writable` (another user's, in `/tmp`), a result is still written, to be kept.
    let mut refused = None;
    if is_special(path) {
        match refuse_in_place(path) {
            Ok(()) => {
                let file = open_in_place(path).map_err(io)?;
                let mut out = std::io::BufWriter::with_capacity(1 << 16, file);
                return write(&mut out).and_then(|()| out.flush()).map_err(io);
            }
            Err(why) if keep => refused = Some(why),
            Err(why) => return Err(io(why)),
        }
    }
    // Written with no name where the system allows (`unnamed_beside`), named only once
    // whole; else under its temporary name from the start.
    let (file, named) = match unnamed_beside(path) {
        Some(file) => (file, None),
        None => {
            let (file, name) = temporary_beside(path).map_err(io)?.into_parts();
            (file, Some(name))
        }
    };
    let mut out = std::io::BufWriter::with_capacity(1 << 16, file);
    // On any error from here on, dropping the temporary file (or its name) removes it.
    write(&mut out).map_err(io)?;
    let mut file = out
        .into_inner()
        .map_err(|e| io(std::io::IntoInnerError::into_error(e)))?;
    file.sync_all().map_err(io)?;
    let tmp = match named {
        Some(name) => name,
        None => match link(path, &file) {
            Ok(name) => name,
            Err(unlinked) => copied_beside(path, &mut file).map_err(|e| {
                io(std::io::Error::new(
                    e.kind(),
                    format!("{e}; the finished file could not be named either: {unlinked}"),
                ))
            })?,
        },
    };
    let (why, tmp) = match refused {
        Some(why) => (why, tmp),
        None => match tmp.persist(path) {
            Ok(()) => return Ok(()),
            // Why: a file another user holds says so, rather than "Operation not permitted".
            Err(failed) => (
                refuse_unreplaceable(path).err().unwrap_or(failed.error),
                failed.path,
            ),
        },
    };
    if !keep {
        return Err(io(why));
    }
    let Ok(kept) = tmp.keep() else {
        return Err(io(why));
    };
    Err(io(std::io::Error::new(
        why.kind(),
        format!(
            "{why}; the finished file is kept as {}",
            crate::text::path_safe(&kept)
        ),
    )))
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

    /// A link to one of the process's own open files (`/dev/stdout`, a link to
    /// `/proc/self/fd/1`) is written through, as the shell opened that file (`>` or `>>`),
    /// and the link is left as it was: renaming over it replaced the link itself (as root,
    /// `/dev/stdout` of the whole machine) and wrote nothing to the redirected file.
    #[test]
    fn a_link_to_an_open_file_of_the_process_is_written_through_not_replaced() {
        use std::os::fd::AsRawFd;
        if !Path::new("/proc/self/fd").is_dir() {
            return; // no /proc
        }
        let dir = std::env::temp_dir().join(format!("tessera-fdlink-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (append, before, after) in [
            (false, &b""[..], &b"the image"[..]),
            (true, &b"kept\n"[..], &b"kept\nthe image"[..]),
        ] {
            let sink = dir.join("sink");
            std::fs::write(&sink, before).unwrap();
            let open = std::fs::OpenOptions::new()
                .write(true)
                .append(append)
                .open(&sink)
                .unwrap();
            let link = dir.join("stdout");
            let _ = std::fs::remove_file(&link);
            let fd = format!("/proc/self/fd/{}", open.as_raw_fd());
            std::os::unix::fs::symlink(&fd, &link).unwrap();
            check_writable(&link).unwrap();
            write_atomically(&link, b"the image").unwrap();
            let kept = std::fs::symlink_metadata(&link).unwrap();
            assert!(kept.file_type().is_symlink(), "the link was replaced");
            assert_eq!(std::fs::read(&sink).unwrap(), after, "append: {append}");
            drop(open);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A link to one of the process's open files that it holds only for reading (standard
    /// input: `-o /dev/stdin < scene.toml`) is refused, the file left as it was: written
    /// through, the image was appended to the input file (12 bytes grew to 3,393, exit 0).
    /// One held for reading and writing (`<>`) is written through.
    #[test]
    fn a_link_to_an_open_file_held_only_for_reading_is_refused_and_the_file_untouched() {
        use std::os::fd::AsRawFd;
        if !Path::new("/proc/self/fdinfo").is_dir() {
            return; // no /proc
        }
        let dir = std::env::temp_dir().join(format!("tessera-fdread-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let input = dir.join("scene.toml");
        std::fs::write(&input, b"the input").unwrap();
        let link = dir.join("stdin.png");
        for (write, after) in [
            (false, &b"the input"[..]),
            (true, &b"the inputthe image"[..]),
        ] {
            let open = std::fs::OpenOptions::new()
                .read(true)
                .write(write)
                .open(&input)
                .unwrap();
            let _ = std::fs::remove_file(&link);
            let fd = format!("/proc/self/fd/{}", open.as_raw_fd());
            std::os::unix::fs::symlink(&fd, &link).unwrap();
            let checked = check_writable(&link);
            let written =
                write_result_atomically_with(&link, &mut |out| out.write_all(b"the image"));
            if write {
                checked.unwrap();
                written.unwrap();
            } else {
                let said = checked.unwrap_err().to_string();
                assert!(said.contains("open only for reading"), "{said}");
                assert!(said.contains("stdin.png"), "{said}");
                assert!(written.is_err());
            }
            assert_eq!(std::fs::read(&input).unwrap(), after, "write: {write}");
            assert!(
                std::fs::symlink_metadata(&link)
                    .unwrap()
                    .file_type()
                    .is_symlink()
            );
            drop(open);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A directory that cannot take the output is named, not the temporary file that was
    /// never made there (the message once ended `at path "/…/.x.png.Ab12Cd.tmp"`).
    #[test]
    fn a_directory_that_takes_no_file_is_named_not_the_temporary_file() {
        let missing = std::env::temp_dir().join(format!("tessera-gone-{}", std::process::id()));
        let e = write_atomically(&missing.join("x.png"), b"x").unwrap_err();
        assert!(
            matches!(&e, Error::Io { cause, .. } if cause.kind() == std::io::ErrorKind::NotFound),
            "{e}"
        );
        let said = e.to_string();
        assert!(
            said.contains(&format!(
                "could not create a file in {}: ",
                missing.display()
            )) && !said.contains(".tmp")
                && !said.contains(".x.png"),
            "{said}"
        );
    }

    /// The current directory is named in words with its full name, as `render`'s check of
    /// the output directory names it: a bare "." before a full stop reads as the parent.
    #[test]
    fn the_current_directory_is_named_in_words_and_in_full() {
        let full = std::env::current_dir().unwrap();
        assert_eq!(
            directory_named(Path::new(".")),
            format!("the current directory ({})", full.display())
        );
        assert_eq!(directory_named(Path::new("/tmp/x")), "/tmp/x");
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

    #[test]
    fn a_finished_result_that_cannot_be_put_in_place_is_kept() {
        let dir = std::env::temp_dir().join(format!("tessera-result-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.png");
        // While the result is written, something the rename cannot replace takes its name:
        // here a directory; in a sticky directory, another user's file.
        let failed = write_result_atomically_with(&p, &mut |out| {
            std::fs::create_dir_all(p.join("in the way"))?;
            out.write_all(b"finished")
        })
        .unwrap_err()
        .to_string();
        let (_, kept) = failed.rsplit_once("the finished file is kept as ").unwrap();
        assert_eq!(std::fs::read(kept).unwrap(), b"finished", "{failed}");
        // A preview's or a checkpoint's file is written again soon: nothing is kept.
        let lost = write_atomically(&p, b"a preview");
        assert!(lost.is_err_and(|e| !e.to_string().contains("is kept as")));
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_socket_or_another_user_s_pipe_at_the_output_is_refused_and_a_result_kept() {
        let dir = std::env::temp_dir().join(format!("tessera-socket-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.png");
        // A socket (in `/tmp`, another user's) where the output goes: no file can be opened
        // there, so the check before the work says so.
        let socket = std::os::unix::net::UnixListener::bind(&p).unwrap();
        let refused = check_writable(&p).unwrap_err().to_string();
        assert!(refused.contains("is a socket"), "{refused}");
        // One made after the check, while the result was made: the result is kept.
        let kept_of = |failed: String| {
            let (_, kept) = failed.rsplit_once("the finished file is kept as ").unwrap();
            assert_eq!(std::fs::read(kept).unwrap(), b"finished", "{failed}");
            std::fs::remove_file(kept).unwrap();
        };
        let failed = write_result_atomically_with(&p, &mut |out| out.write_all(b"finished"));
        kept_of(failed.unwrap_err().to_string());
        drop(socket);
        std::fs::remove_file(&p).unwrap();
        // Another user's pipe, made during the work (root can give it away).
        rustix::fs::mkfifoat(rustix::fs::CWD, &p, rustix::fs::Mode::from(0o644)).unwrap();
        if std::os::unix::fs::chown(&p, Some(65534), Some(65534)).is_ok() {
            let failed = write_result_atomically_with(&p, &mut |out| out.write_all(b"finished"));
            let failed = failed.unwrap_err().to_string();
            assert!(failed.contains("pipe (FIFO) of another user's"), "{failed}");
            kept_of(failed);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_name_at_the_file_system_s_limit_is_written() {
        let dir = std::env::temp_dir().join(format!("tessera-long-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(format!("{}.png", "a".repeat(251)));
        check_writable(&p).unwrap();
        write_atomically(&p, b"whole").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"whole");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_name_no_file_can_take_is_refused_before_anything_is_written() {
        let dir = std::env::temp_dir().join(format!("tessera-unnameable-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let slash = PathBuf::from(format!("{}/out.png/", dir.display()));
        let dot = PathBuf::from(format!("{}/out.png/.", dir.display()));
        let long = dir.join(format!("{}.png", "a".repeat(252)));
        for p in [&slash, &dot, &long] {
            assert!(check_writable(p).is_err(), "{}", p.display());
            let written = write_result_atomically_with(p, &mut |out| out.write_all(b"finished"));
            let e = written.unwrap_err().to_string();
            assert!(!e.contains("is kept as"), "{e}");
        }
        // Nothing was made: no file, no temporary one kept.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = std::env::temp_dir().join(format!("tessera-failed-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.png");
        write_atomically(&p, b"old").unwrap();
        let failed = write_atomically_with(&p, &mut |out| {
            out.write_all(b"half")?;
            Err(std::io::Error::other("the disk is full"))
        });
        assert!(failed.is_err_and(|e| e.to_string().contains("the disk is full")));
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A file is written with no name: what ends the process while it is written (SIGTERM,
    /// Ctrl-C, SIGKILL) leaves nothing behind. It once had its temporary name from the start:
    /// `kill -TERM` three seconds into the write of an 8192x4096 PPM left a hidden
    /// `.big.ppm.XXXXXX.tmp` of 59 MB beside it.
    #[test]
    fn nothing_has_a_name_beside_the_output_while_it_is_written() {
        let dir = std::env::temp_dir().join(format!("tessera-unnamed-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let names = || -> Vec<String> {
            std::fs::read_dir(&dir)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        };
        // Where the file system makes no file without a name, a named one is all there is.
        let flags = rustix::fs::OFlags::TMPFILE | rustix::fs::OFlags::WRONLY;
        let mode = rustix::fs::Mode::from(0o600);
        if rustix::fs::openat(rustix::fs::CWD, &dir, flags, mode).is_err()
            || !Path::new("/proc/self/fd").is_dir()
        {
            std::fs::remove_dir_all(&dir).unwrap();
            return;
        }
        let p = dir.join("out.png");
        write_atomically(&p, b"old").unwrap();
        for keep in [false, true] {
            let mut seen = Vec::new();
            write_whole(
                &p,
                &mut |out| {
                    out.write_all(b"half")?;
                    seen = names();
                    out.write_all(b" and the rest")
                },
                keep,
                name_beside,
            )
            .unwrap();
            assert_eq!(seen, ["out.png"], "while written");
            assert_eq!(std::fs::read(&p).unwrap(), b"half and the rest");
            assert_eq!(names(), ["out.png"], "once written");
            use std::os::unix::fs::MetadataExt;
            let mode = std::fs::metadata(&p).unwrap().mode() & 0o777;
            // The umask as `/proc` says it (setting it to read it would race other tests).
            let status = std::fs::read_to_string("/proc/self/status").unwrap();
            let umask = status.lines().find_map(|l| l.strip_prefix("Umask:"));
            let umask = u32::from_str_radix(umask.unwrap().trim(), 8).unwrap();
            assert_eq!(mode, 0o666 & !umask, "the umask's permissions");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Where the file written with no name cannot be named once whole (the link fails:
    /// "Invalid cross-device link" where the directory moved to another file system, a link
    /// count or quota reached), it is copied to a named file and put in place. The work once
    /// went with the unnamed file: `strace -e inject=linkat:error=EXDEV:when=2 tessera render
    /// … -o out.png` ended in exit 2 and no file.
    #[test]
    fn a_written_file_that_cannot_be_linked_is_copied_into_place() {
        let dir = std::env::temp_dir().join(format!("tessera-unlinked-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.png");
        let fail: Link = |_, _| Err(std::io::Error::from_raw_os_error(libc::EXDEV));
        for keep in [false, true] {
            write_whole(&p, &mut |out| out.write_all(b"finished"), keep, fail).unwrap();
            assert_eq!(std::fs::read(&p).unwrap(), b"finished");
            assert_eq!(
                std::fs::read_dir(&dir).unwrap().count(),
                1,
                "no temporary left"
            );
            std::fs::remove_file(&p).unwrap();
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// An output named by a symbolic link to a directory is refused as that, not as "a
    /// directory": `ln -s real.png link.png; tessera render -o link.png` said "link.png: is a
    /// directory, not a file name".
    #[test]
    fn a_link_to_a_directory_at_the_output_is_said_to_be_one() {
        let dir = std::env::temp_dir().join(format!("tessera-dirlink-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("real.png")).unwrap();
        std::os::unix::fs::symlink("real.png", dir.join("link.png")).unwrap();
        let said = check_writable(&dir.join("link.png"))
            .unwrap_err()
            .to_string();
        assert!(
            said.contains("is a symbolic link to a directory (real.png)"),
            "{said}"
        );
        let said = check_writable(&dir.join("real.png"))
            .unwrap_err()
            .to_string();
        assert!(said.contains(": is a directory, not a file name"), "{said}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
