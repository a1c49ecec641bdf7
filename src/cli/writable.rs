//! Output files checked before any work is spent on them, with the reason said in words a
//! user can act on: a directory that does not exist, a directory this user may not write
//! (in a container: what to mount and which user to run as).

use super::confinement;
use anyhow::{Result, anyhow};
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use tessera::atomic_file::check_writable;

/// Checks that `path` can be written whole (`atomic_file::check_writable`), explaining a
/// failure.
pub fn check_output(path: &Path) -> Result<()> {
    let Err(e) = check_writable(path) else {
        return Ok(());
    };
    let kind = match &e {
        tessera::Error::Io { cause, .. } => Some(cause.kind()),
        _ => None,
    };
    let dir = directory_of(path);
    match kind {
        Some(ErrorKind::NotFound) if !dir.exists() => {
            let mut why = format!(
                "{}: the directory {} does not exist; create it first (mkdir -p {})",
                path.display(),
                dir.display(),
                dir.display()
            );
            if let Some(container) = confinement::this_container() {
                why.push_str(&format!(
                    ". In this {container} container, mount a directory of yours there, e.g. \
                     {}",
                    run_example(&dir)
                ));
            }
            Err(anyhow!(why))
        }
        Some(ErrorKind::PermissionDenied) => {
            let mut why = format!(
                "{}: permission denied: this user ({}) may not create files in {}",
                path.display(),
                user(),
                dir.display()
            );
            match confinement::this_container() {
                Some(container) => why.push_str(&format!(
                    ". In this {container} container, write to a mounted directory that \
                     you own, running as yourself: {}",
                    run_example(&dir)
                )),
                None => why.push_str("; choose another directory with -o"),
            }
            Err(anyhow!(why))
        }
        _ => Err(e.into()),
    }
}

/// The directory a file `path` is created in.
fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// The command line that runs the image with a writable output directory: the directory
/// `dir` when it is absolute and not the image's own, else `/out`.
fn run_example(dir: &Path) -> String {
    let mount = if dir.is_absolute() && dir != Path::new("/") && !dir.starts_with("/app") {
        dir.display().to_string()
    } else {
        "/out".to_owned()
    };
    format!(
        "mkdir -p out && podman run --rm --user \"$(id -u):$(id -g)\" -v \"$PWD/out:{mount}\" \
         IMAGE render -o {mount}/NAME.png (Docker: the same flags)"
    )
}

/// This process's user and group ids, as `uid 65532, gid 65532`.
fn user() -> String {
    use std::os::unix::fs::MetadataExt;
    match std::fs::metadata("/proc/self") {
        Ok(m) => format!("uid {}, gid {}", m.uid(), m.gid()),
        Err(_) => "this user".to_owned(),
    }
}
