//! Watching a render as it happens: the folding thread keeps a picture of the job
//! ([`frame`]) and publishes it with the run's status about once a second to a [`Hub`],
//! from which the web viewer ([`server`]) and the preview file take the latest snapshot.
//! Nothing here is on a worker's path, and nothing here changes the image.

pub mod frame;
#[cfg(feature = "preview")]
pub mod server;

use crate::job::JobState;
use crate::render::{Progress, Watch};
use bytes::Bytes;
use frame::{Frame, FrameBuilder};
use serde::Serialize;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The longest time between two snapshots while a render runs. A pass that ends publishes
/// at once, so the first pass's image appears as soon as it is done.
pub const PUBLISH_EVERY: Duration = Duration::from_millis(1000);

/// Where a render stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RunState {
    Rendering,
    Finished,
    Interrupted,
    /// Its output could not be written: a finished render's image, part or checkpoint, or
    /// an interrupted one's checkpoint (its progress lost).
    Failed,
}

/// What a render is, as the viewer shows it: fixed for the run.
#[derive(Clone, Debug, Serialize)]
pub struct About {
    /// The scene's name (its file's stem) and file as given.
    pub scene: String,
    pub scene_file: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
    pub shading: String,
    pub threads: usize,
    pub tile: u32,
    pub simd: String,
    /// The job's pixels `[x, y, width, height]` and sample indices `[start, end]`.
    pub region: [u32; 4],
    pub samples: [u32; 2],
    /// What this process renders: the whole image, a crop, a shard or a sample range.
    pub job: String,
    /// Where the result goes.
    pub output: String,
    /// Whether the viewer keeps serving after the render ends (`--preview-hold`); without,
    /// a page keeps what it offers to download itself, as the server goes.
    pub held: bool,
}

/// The image file a finished render offers to download: the very bytes of its PNG (recipe
/// included), under the output's name.
#[derive(Debug)]
pub struct Download {
    pub name: String,
    pub png: Bytes,
}

/// What the status says of the download.
#[derive(Clone, Debug, Serialize)]
pub struct DownloadInfo {
    pub name: String,
    pub bytes: usize,
}

/// The run's status at one moment, as `/status` and the event stream send it.
#[derive(Clone, Debug, Serialize)]
pub struct Status {
    pub state: RunState,
    pub about: Arc<About>,
    /// Samples per pixel that every pixel of the job has, the most any has, and the job's
    /// total, all counted from the job's first sample index.
    pub spp_done: u32,
    pub spp_max: u32,
    pub spp_total: u32,
    /// The pass being rendered (1-based; `passes` when finished) and its end in samples.
    pub pass: usize,
    pub passes: usize,
    pub pass_spp: u32,
    /// Percent of the job done, by estimated work (a tile of ground weighs more than sky).
    pub percent: f64,
    pub elapsed_s: f64,
    /// Seconds left at the rate so far, by estimated work; `None` before any tile is done.
    pub eta_s: Option<f64>,
    pub samples_per_sec: f64,
    pub mrays_per_sec: f64,
    pub frame: FrameInfo,
    /// The tiles being rendered now, `[x, y, width, height]` in the job's pixels.
    pub tiles: Vec<[u32; 4]>,
    /// The finished image to download, once there is one.
    pub download: Option<DownloadInfo>,
}

/// The frame a status goes with.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FrameInfo {
    pub version: u64,
    pub width: u32,
    pub height: u32,
    pub scale: u32,
}

/// One published moment: the status (and its JSON, made once for every viewer), the frame
/// and, at the end, the image to download.
#[derive(Debug)]
pub struct Snapshot {
    pub status: Status,
    pub status_json: Bytes,
    pub frame: Arc<Frame>,
    pub download: Option<Arc<Download>>,
}

/// The latest snapshot, for any number of readers on any threads. Publishing replaces it
/// and never waits for a reader: readers hold it only to clone its `Arc`.
pub struct Hub {
    latest: tokio::sync::watch::Sender<Arc<Snapshot>>,
}

impl Hub {
    fn new(first: Snapshot) -> Self {
        Self {
            latest: tokio::sync::watch::Sender::new(Arc::new(first)),
        }
    }

    /// The latest snapshot.
    pub fn latest(&self) -> Arc<Snapshot> {
        Arc::clone(&self.latest.borrow())
    }

    /// A receiver that wakes when a new snapshot is published.
    pub fn subscribe(&self) -> tokio::sync::watch::Receiver<Arc<Snapshot>> {
        self.latest.subscribe()
    }

    fn publish(&self, snapshot: Snapshot) {
        self.latest.send_replace(Arc::new(snapshot));
    }
}

/// Watches a job for the preview: keeps its frame up to date as tiles are folded and
/// publishes snapshots to its hub.
pub struct Previewer {
    hub: Arc<Hub>,
    about: Arc<About>,
    builder: FrameBuilder,
    frame: Arc<Frame>,
    dirty: bool,
    last_publish: Instant,
    last_pass: usize,
    /// The fraction of the job's samples already done when this run started (a resume).
    done_before: f64,
    status: Option<Status>,
    download: Option<Arc<Download>>,
}

impl Previewer {
    /// A previewer of a small blank job (16x9, 4 samples a pixel, none done yet), its
    /// scene, files and output named after `name`: a server to ask, for the tests and the
    /// request fuzzer.
    #[doc(hidden)]
    pub fn blank(name: &str) -> Self {
        use crate::job::{Job, SampleRange};
        let job = Job {
            region: crate::math::PixelRect::full(16, 9),
            samples: SampleRange { start: 0, end: 4 },
        };
        let about = About {
            scene: name.into(),
            scene_file: format!("{name}.toml"),
            width: 16,
            height: 9,
            spp: 4,
            max_depth: 5,
            seed: 0,
            shading: "path".into(),
            threads: 1,
            tile: 4,
            simd: "portable".into(),
            region: [0, 0, 16, 9],
            samples: [0, 4],
            job: "whole image".into(),
            output: format!("{name}.png"),
            held: false,
        };
        Self::new(about, &JobState::new(job, 4), 2.0)
    }

    /// A previewer of `state`'s job, its picture tone-mapped with `gamma`.
    pub fn new(about: About, state: &JobState, gamma: f32) -> Self {
        // The names are a stranger's text (a scene file handed over under its name): the
        // page shows them as the terminal does, a bidirectional override or an escape in
        // them as `\u{…}`, never raw.
        let about = About {
            scene: shown(&about.scene),
            scene_file: shown(&about.scene_file),
            job: shown(&about.job),
            output: shown(&about.output),
            ..about
        };
        let mut builder = FrameBuilder::new(state, gamma);
        builder.update_all(state);
        // The first frame is all new: there is no frame before it to patch.
        let frame = Arc::new(Frame {
            changed: None,
            ..builder.frame(1)
        });
        let about = Arc::new(about);
        let done_before = state.finished_samples() as f64 / state.total_samples().max(1) as f64;
        let status = status_of(
            &about,
            state,
            &frame,
            None,
            done_before,
            RunState::Rendering,
        );
        let hub = Arc::new(Hub::new(snapshot(status, Arc::clone(&frame), None)));
        Self {
            hub,
            about,
            builder,
            frame,
            dirty: false,
            last_publish: Instant::now(),
            last_pass: 0,
            done_before,
            status: None,
            download: None,
        }
    }

    /// The hub the previewer publishes to.
    pub fn hub(&self) -> Arc<Hub> {
        Arc::clone(&self.hub)
    }

    fn publish(&mut self, state: &JobState, progress: Option<&Progress>, run: RunState) {
        if self.dirty {
            self.frame = Arc::new(self.builder.frame(self.frame.version + 1));
            self.dirty = false;
        }
        let mut status = status_of(
            &self.about,
            state,
            &self.frame,
            progress,
            self.done_before,
            run,
        );
        if progress.is_none()
            && let Some(last) = &self.status
        {
            // The end keeps the run's own figures; only the state and the frame are new.
            status = Status {
                state: run,
                frame: status.frame,
                spp_done: status.spp_done,
                spp_max: status.spp_max,
                percent: if run == RunState::Finished {
                    100.0
                } else {
                    last.percent
                },
                eta_s: (run == RunState::Finished).then_some(0.0),
                tiles: Vec::new(),
                ..last.clone()
            };
        }
        status.download = (self.download.as_ref()).map(|d| DownloadInfo {
            name: shown(&d.name),
            bytes: d.png.len(),
        });
        self.status = Some(status.clone());
        let download = self.download.clone();
        self.hub
            .publish(snapshot(status, Arc::clone(&self.frame), download));
        self.last_publish = Instant::now();
    }

    /// Publishes the end of the run: `Finished`, `Interrupted` or `Failed`, with the final frame (and
    /// the image to download, if one was offered).
    pub fn finish(&mut self, state: &JobState, run: RunState) {
        self.publish(state, None, run);
    }

    /// Offers the finished image file for download: `png` is the PNG the render wrote (or
    /// would write), `name` its file name. Published with the end of the run.
    pub fn offer_download(&mut self, name: String, png: Vec<u8>) {
        self.download = Some(Arc::new(Download {
            name,
            png: Bytes::from(png),
        }));
    }
}

impl Watch for Previewer {
    fn started(&mut self, state: &JobState, progress: &Progress) {
        self.publish(state, Some(progress), RunState::Rendering);
    }

    fn folded(&mut self, state: &JobState, folded: &[usize], progress: &Progress) {
        for &index in folded {
            self.builder.update_tile(state, index);
        }
        self.dirty |= !folded.is_empty();
        if progress.pass != self.last_pass || self.last_publish.elapsed() >= PUBLISH_EVERY {
            self.last_pass = progress.pass;
            self.publish(state, Some(progress), RunState::Rendering);
        }
    }
}

/// Text for the page: one line, every character that could reorder or hide what is around it
/// (`text::is_unsafe`) written as a `\u{…}` escape.
fn shown(text: &str) -> String {
    crate::text::terminal_safe(text, usize::MAX)
}

fn snapshot(status: Status, frame: Arc<Frame>, download: Option<Arc<Download>>) -> Snapshot {
    let json = serde_json::to_vec(&status).expect("a status serializes");
    Snapshot {
        status,
        status_json: Bytes::from(json),
        frame,
        download,
    }
}

fn status_of(
    about: &Arc<About>,
    state: &JobState,
    frame: &Frame,
    progress: Option<&Progress>,
    done_before: f64,
    run: RunState,
) -> Status {
    let spp_total = state.job.samples.len();
    let mut status = Status {
        state: run,
        about: Arc::clone(about),
        spp_done: state.min_done().min(spp_total),
        spp_max: state.done.iter().copied().max().unwrap_or(0).min(spp_total),
        spp_total,
        pass: 1,
        passes: 1,
        pass_spp: spp_total,
        percent: 100.0 * done_before,
        elapsed_s: 0.0,
        eta_s: None,
        samples_per_sec: 0.0,
        mrays_per_sec: 0.0,
        frame: FrameInfo {
            version: frame.version,
            width: frame.width,
            height: frame.height,
            scale: frame.scale,
        },
        tiles: Vec::new(),
        download: None,
    };
    let Some(p) = progress else {
        return status;
    };
    let secs = p.elapsed.as_secs_f64();
    let fraction = p.work_done as f64 / p.work_total.max(1) as f64;
    status.pass = (p.pass + 1).min(p.passes.len());
    status.passes = p.passes.len();
    status.pass_spp = p.passes.get(p.pass).copied().unwrap_or(spp_total);
    status.percent = 100.0 * (done_before + (1.0 - done_before) * fraction);
    status.elapsed_s = secs;
    status.eta_s = (p.work_done > 0).then(|| secs * (1.0 - fraction) / fraction);
    if secs > 0.0 {
        status.samples_per_sec = p.samples as f64 / secs;
        status.mrays_per_sec = p.rays as f64 / secs / 1e6;
    }
    let region = state.job.region;
    status.tiles = (p.active.tiles().into_iter())
        .filter_map(|i| region.tile(state.tile, i))
        .map(|t| [t.x0 - region.x0, t.y0 - region.y0, t.width, t.height])
        .collect();
    status
}
