//! Output files checked before any work is spent on them, with the reason said in words a
//! user can act on: a directory that does not exist, a directory this user may not write
//! (in a container: what to mount and which user to run as).

use anyhow::{Result, anyhow};
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use tessera::atomic_file::{check_writable, directory_named};
use tessera::confinement;

/// Checks that `path`, given with the flag `flag` (`-o`, `--checkpoint`), can be written
/// whole (`atomic_file::check_writable`), explaining a failure: the advice names the flag
/// that gave the path, not always `-o`.
pub fn check_output(flag: &str, path: &Path) -> Result<()> {
    let Err(e) = check_writable(path) else {
        return Ok(());
    };
    let kind = match &e {
        tessera::Error::Io { cause, .. } => Some(cause.kind()),
        _ => None,
    };
    let dir = directory_of(path);
    let container = confinement::entry_point_of_container();
    let why = match kind {
        Some(ErrorKind::NotFound) if !dir.exists() => match &container {
            Some(c) => format!(
                "{}: the directory {} does not exist in this {c} container: mount a \
                 directory of yours there; {}",
                path.display(),
                dir.display(),
                mount_advice(c, &dir, flag, path)
            ),
            None => format!(
                "{}: the directory {} does not exist; create it first (mkdir -p {})",
                path.display(),
                dir.display(),
                dir.display()
            ),
        },
        Some(kind @ (ErrorKind::PermissionDenied | ErrorKind::ReadOnlyFilesystem)) => {
            let what = if kind == ErrorKind::ReadOnlyFilesystem {
                format!("{} is on a read-only file system", directory_named(&dir))
            } else {
                format!(
                    "permission denied: this user ({}) may not create files in {}",
                    user(),
                    directory_named(&dir)
                )
            };
            match &container {
                Some(c) => format!(
                    "{}: {what}. In this {c} container, write to a mounted directory that \
                     you own, running as yourself; {}",
                    path.display(),
                    mount_advice(c, &dir, flag, path)
                ),
                None => format!(
                    "{}: {what}; choose another directory with {flag}",
                    path.display()
                ),
            }
        }
        _ => return Err(e.into()),
    };
    Err(anyhow!(why))
}

/// How to give a container a writable directory for its output `path`, given with `flag`,
/// for the runtime `container` names.
fn mount_advice(container: &str, dir: &Path, flag: &str, path: &Path) -> String {
    if container == "kubernetes" {
        return format!(
            "mount a volume at {} (deploy/k8s/render-job.yaml shows one, with the pod's fsGroup \
             so that its user can write there)",
            mount_point(dir)
        );
    }
    run_example(&command_typed(), dir, flag, path)
}

/// The subcommand this process runs (`render`, `merge`, …), as the example command line
/// names it.
fn command_typed() -> String {
    const COMMANDS: [&str; 5] = ["render", "merge", "reproduce", "results", "bench"];
    std::env::args()
        .nth(1)
        .filter(|c| COMMANDS.contains(&c.as_str()))
        .unwrap_or_else(|| "render".to_owned())
}

/// Where the example mounts the output directory: `dir` when it is absolute and not the
/// image's own, else `/out`.
fn mount_point(dir: &Path) -> String {
    if dir.is_absolute() && dir != Path::new("/") && !dir.starts_with("/app") {
        dir.display().to_string()
    } else {
        "/out".to_owned()
    }
}

/// The directory a file `path` is created in.
fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// The command lines that run the image's `command` with a writable output directory
/// mounted, the output `path` given with `flag` there: the flag that gave the path, with
/// its file name (`--checkpoint /out/c.ckpt`), not always `-o` and an image's name.
fn run_example(command: &str, dir: &Path, flag: &str, path: &Path) -> String {
    let mount = mount_point(dir);
    let name = path
        .file_name()
        .map_or("NAME".into(), |n| tessera::text::path_safe(Path::new(n)));
    format!(
        "mkdir -p out && podman run --rm --network none --userns=keep-id --user \"$(id -u):$(id -g)\" -v \
         \"$PWD/out:{mount}\" IMAGE {command} … {flag} {mount}/{name} (Docker, or Podman as \
         root: the same without --userns=keep-id)"
    )
}

/// This process's user and group ids, as `uid 65532, gid 65532`.
fn user() -> String {
    format!(
        "uid {}, gid {}",
        tessera::owner::this_user(),
        rustix::process::getegid().as_raw()
    )
}

/// Whether `a` and `b` name one file, whether or not it exists yet: the same name in the
/// same directory, however the directory is spelt, or, where both exist, one file by two
/// names (a link).
pub fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    let place = |p: &Path| {
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        Some((dir.canonicalize().ok()?, p.file_name()?.to_owned()))
    };
    let inode = |p: &Path| std::fs::metadata(p).ok().map(|m| (m.dev(), m.ino()));
    matches!((place(a), place(b)), (Some(a), Some(b)) if a == b)
        || matches!((inode(a), inode(b)), (Some(a), Some(b)) if a == b)
}

/// What of the results database at `db` the output `output` names, if any: the database
/// itself, or the write-ahead log, shared memory or rollback journal beside it, whose loss
/// takes the runs not yet in the database with it.
///
/// A database named through a link has its companion files beside the link's target, where
/// SQLite puts them, and they are checked there too.
pub fn names_database_file(output: &Path, db: &Path) -> Option<String> {
    let real = db.canonicalize().ok();
    let names = std::iter::once(db).chain(real.as_deref());
    names.into_iter().find_map(|db| {
        ["", "-wal", "-shm", "-journal"]
            .into_iter()
            .find_map(|suffix| {
                let mut companion = db.as_os_str().to_owned();
                companion.push(suffix);
                same_file(output, Path::new(&companion)).then(|| match suffix {
                    "" => "the results database".to_owned(),
                    _ => format!("the results database's {} file", &suffix[1..]),
                })
            })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The container's advice named `render -o …/NAME.png` whatever flag gave the path: a
    /// checkpoint that could not be written was to be fixed with `-o`, which moves the image.
    #[test]
    fn the_container_s_advice_names_the_flag_that_gave_the_path() {
        let said = run_example(
            "render",
            Path::new("/app"),
            "--checkpoint",
            Path::new("/app/c.ckpt"),
        );
        assert!(
            said.contains("IMAGE render … --checkpoint /out/c.ckpt"),
            "{said}"
        );
        assert!(!said.contains("-o "), "{said}");
        let said = run_example("merge", Path::new("/data"), "-o", Path::new("/data/x.png"));
        assert!(said.contains("IMAGE merge … -o /data/x.png"), "{said}");
    }
}
