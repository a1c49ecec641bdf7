//! A watched render's companions: the web viewer's server and the preview file's writer,
//! started before the render and ended after it (held open until Ctrl-C with
//! `--preview-hold`). Both read the previewer's hub; neither is ever waited for by a worker.

use super::plan::PreviewSettings;
use crate::cli::output::note;
use anyhow::Result;
use indicatif::ProgressBar;
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;
use tessera::atomic_file::write_atomically;
use tessera::job::JobState;
use tessera::preview::{About, Hub, Previewer, RunState};

/// The preview of one render.
pub struct Session {
    pub previewer: Previewer,
    viewer: Option<Viewer>,
    file: Option<FileWriter>,
    run: RunState,
}

impl Session {
    /// Starts the viewer (its address printed) and the preview file's writer for `state`.
    pub fn start(
        settings: PreviewSettings,
        about: About,
        state: &JobState,
        gamma: f32,
        bar: &ProgressBar,
    ) -> Result<Session> {
        let previewer = Previewer::new(about, state, gamma);
        let viewer = match settings.listener {
            Some(listener) => Some(Viewer::start(listener, &previewer, settings.hold)?),
            None => None,
        };
        let file = (settings.file)
            .map(|(path, every)| FileWriter::start(path, every, previewer.hub(), bar.clone()));
        Ok(Session {
            previewer,
            viewer,
            file,
            run: RunState::Rendering,
        })
    }

    /// Publishes the end of the render, `Finished`, `Interrupted` or `Failed`, and writes the final
    /// preview file.
    pub fn end(mut self, state: &JobState, run: RunState) -> Self {
        self.previewer.finish(state, run);
        self.run = run;
        if let Some(file) = self.file.take() {
            file.finish();
        }
        self
    }

    /// Whether a live viewer is watching (it offers the finished image for download).
    pub fn has_viewer(&self) -> bool {
        self.viewer.is_some()
    }

    /// Ends the viewer (see `Viewer::close`).
    pub fn close(self) {
        if let Some(viewer) = self.viewer {
            viewer.close(&self.previewer, self.run);
        }
    }
}

#[cfg(feature = "preview")]
use viewer::Viewer;

/// The live viewer: the web server and how it ends.
#[cfg(feature = "preview")]
mod viewer {
    use crate::cli::output::note;
    use anyhow::{Context, Result};
    use std::net::TcpListener;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::time::{Duration, Instant};
    use tessera::preview::server::{self, Server};
    use tessera::preview::{Previewer, RunState};

    /// How long a render that ends, without `--preview-hold`, waits for a connected viewer
    /// to fetch the final frame before the server goes.
    const LINGER: Duration = Duration::from_secs(2);

    pub struct Viewer {
        server: Server,
        /// Serve the final image after the render until Ctrl-C.
        hold: bool,
    }

    impl Viewer {
        /// Starts the server on `listener` and prints its address.
        pub fn start(listener: TcpListener, previewer: &Previewer, hold: bool) -> Result<Self> {
            let server = Server::start(listener, previewer.hub())
                .context("could not start the preview server")?;
            let addr = server.addr();
            if server::is_public(&addr) {
                note(format_args!(
                    "tessera: warning: the preview listens on {addr}: anyone who can reach \
                     this machine on that address can see the render"
                ));
            }
            note(format_args!("tessera: preview at {}", server.url()));
            Ok(Self { server, hold })
        }

        /// After a finished render with `--preview-hold`, serves the final frame until
        /// Ctrl-C or SIGTERM; otherwise stops once a connected viewer has had the final frame
        /// and kept the image offered for download (waiting at most `LINGER`).
        pub fn close(self, previewer: &Previewer, run: RunState) {
            let server = self.server;
            let latest = previewer.hub().latest();
            let last = latest.frame.version;
            let offered = latest.download.is_some();
            if self.hold && run == RunState::Finished {
                // Caught before it is announced: a Ctrl-C after the message always ends it
                // cleanly (and is never lost where a parent made SIGINT ignored).
                let stop = Arc::new(AtomicBool::new(false));
                for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
                    if signal_hook::flag::register(signal, Arc::clone(&stop)).is_err() {
                        server.stop();
                        return;
                    }
                }
                note(format_args!(
                    "tessera: serving the final image at {} until Ctrl-C",
                    server.url()
                ));
                while !stop.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(100));
                }
            } else {
                let until = Instant::now() + LINGER;
                let stats = server.stats();
                let waiting = || {
                    stats.frame_served.load(Ordering::Relaxed) < last
                        || (offered && stats.downloads.load(Ordering::Relaxed) == 0)
                };
                while stats.keyed.load(Ordering::Relaxed) > 0 && waiting() && Instant::now() < until
                {
                    std::thread::sleep(Duration::from_millis(20));
                }
            }
            server.stop();
        }
    }
}

/// Without the live viewer compiled in there is none: `--preview` is refused before a
/// render starts.
#[cfg(not(feature = "preview"))]
enum Viewer {}

#[cfg(not(feature = "preview"))]
impl Viewer {
    fn start(_: std::net::TcpListener, _: &Previewer, _: bool) -> Result<Self> {
        anyhow::bail!("this tessera was built without the live viewer")
    }

    fn close(self, _: &Previewer, _: RunState) {
        match self {}
    }
}

/// Writes the latest frame to the preview file every so often, on a thread of its own.
struct FileWriter {
    wake: Arc<(Mutex<bool>, Condvar)>,
    thread: std::thread::JoinHandle<()>,
}

impl FileWriter {
    fn start(path: PathBuf, every: Duration, hub: Arc<Hub>, bar: ProgressBar) -> Self {
        let wake = Arc::new((Mutex::new(false), Condvar::new()));
        let thread = {
            let wake = Arc::clone(&wake);
            std::thread::spawn(move || {
                let mut writer = PreviewFile {
                    path,
                    written: 0,
                    failures: 0,
                };
                let (lock, signal) = &*wake;
                let mut done = lock.lock().unwrap_or_else(|e| e.into_inner());
                loop {
                    let (guard, _) = signal
                        .wait_timeout_while(done, every, |done| !*done)
                        .unwrap_or_else(|e| e.into_inner());
                    done = guard;
                    let finished = *done;
                    drop(done);
                    writer.write(&hub, &bar);
                    if finished {
                        writer.report();
                        return;
                    }
                    done = lock.lock().unwrap_or_else(|e| e.into_inner());
                }
            })
        };
        Self { wake, thread }
    }

    /// Writes the final frame and ends the thread.
    fn finish(self) {
        let (lock, signal) = &*self.wake;
        *lock.lock().unwrap_or_else(|e| e.into_inner()) = true;
        signal.notify_all();
        let _ = self.thread.join();
    }
}

/// The preview file and what was written to it.
struct PreviewFile {
    path: PathBuf,
    /// The frame version in the file (0: none yet).
    written: u64,
    failures: u32,
}

impl PreviewFile {
    /// Writes the hub's frame if it is newer than the file's. A failure (a full disk) is
    /// reported once; the render goes on.
    fn write(&mut self, hub: &Hub, bar: &ProgressBar) {
        let frame = Arc::clone(&hub.latest().frame);
        if frame.version == self.written {
            return;
        }
        match write_atomically(&self.path, &frame.png()) {
            Ok(()) => self.written = frame.version,
            Err(e) => {
                if self.failures == 0 {
                    bar.suspend(|| {
                        note(format_args!(
                            "tessera: warning: could not write the preview file: {}; rendering goes on",
                            tessera::text::message_safe(&e.to_string())
                        ))
                    });
                }
                self.failures += 1;
            }
        }
    }

    fn report(&self) {
        if self.failures > 1 {
            note(format_args!(
                "tessera: warning: {} preview file writes failed in all",
                self.failures
            ));
        }
    }
}
