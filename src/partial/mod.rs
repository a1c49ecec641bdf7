//! Partial renders on disk — shards and checkpoints — and merging them: a self-describing
//! binary file of exact fixed-point sums, so merged parts give the bytes of a single render.
//! Sums are integers, so adding parts in any order gives exactly the sums of one
//! uninterrupted render. `file` owns the byte layout and reading it safely; `merge` owns
//! adding parts up.

mod file;
mod merge;

pub use file::PartReader;
pub use merge::{merge, merge_files};

use crate::error::{Error, Result};
use crate::math::PixelRect;
use crate::render::{Job, Progress, SampleRange};
use crate::scene::Scene;
use serde::{Deserialize, Serialize};
use std::path::Path;

const VERSION: u32 = 1;

/// What a part is a part of, and which part it is.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    pub version: u32,
    /// `Scene::fingerprint` in hex: scene contents and every setting but spp and crop.
    pub fingerprint: String,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    pub max_depth: u32,
    pub gamma: f32,
    /// The scene's window `[x, y, width, height]`: what a merge must cover.
    pub window: [u32; 4],
    /// The pixels this part holds, `[x, y, width, height]`.
    pub region: [u32; 4],
    /// The sample indices this part is for, `[start, end)`.
    pub samples: [u32; 2],
    /// Samples per pixel of the finished image: a merge must cover sample indices
    /// `0..target` of every pixel of `window`.
    pub target: u32,
    /// Tile edge; `done` has one entry per tile of `region`.
    pub tile: u32,
    /// Samples finished per tile, from `samples[0]`; all equal to the range length once the
    /// part is complete.
    pub done: Vec<u32>,
}

impl Header {
    pub fn region(&self) -> PixelRect {
        unrect(self.region)
    }

    pub fn samples(&self) -> SampleRange {
        SampleRange {
            start: self.samples[0],
            end: self.samples[1],
        }
    }

    pub fn is_complete(&self) -> bool {
        let len = self.samples().len();
        self.done.iter().all(|&d| d >= len)
    }

    /// Checks the header's claims against each other, so nothing sized by them is
    /// allocated before they are known to be sane.
    fn check(&self, path: &Path) -> Result<()> {
        let fail = |message: String| Err(part_error(path, message));
        if self.version != VERSION {
            return fail(format!(
                "has format version {}, this tessera reads {VERSION}",
                self.version
            ));
        }
        let region = self.region();
        let window = unrect(self.window);
        let image = PixelRect::full(self.width, self.height);
        if image.area() > crate::scene::MAX_PIXELS
            || !image.contains(&window)
            || !window.contains(&region)
            || region.area() == 0
        {
            return fail(format!(
                "has an impossible region {:?} for window {:?} of a {}x{} image",
                self.region, self.window, self.width, self.height
            ));
        }
        let len = self.samples().len();
        if self.samples[1] < self.samples[0]
            || self.tile == 0
            || self.done.len() as u64 != region.tile_count(self.tile)
            || self.done.iter().any(|&d| d > len)
        {
            return fail("has an inconsistent header (samples, tiles or progress)".to_owned());
        }
        Ok(())
    }
}

/// A partial render: its header and its sums.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    pub header: Header,
    pub sums: Vec<[u64; 3]>,
}

fn rect(r: PixelRect) -> [u32; 4] {
    [r.x0, r.y0, r.width, r.height]
}

fn unrect(r: [u32; 4]) -> PixelRect {
    PixelRect {
        x0: r[0],
        y0: r[1],
        width: r[2],
        height: r[3],
    }
}

impl Part {
    /// The part holding `progress` of `scene`, one piece of an image of `target` samples
    /// per pixel.
    pub fn from_progress(scene: &Scene, progress: &Progress, target: u32) -> Part {
        let s = &scene.settings;
        Part {
            header: Header {
                version: VERSION,
                fingerprint: format!("{:016x}", scene.fingerprint()),
                seed: s.seed,
                width: s.width,
                height: s.height,
                max_depth: s.max_depth,
                gamma: s.gamma,
                window: rect(s.window),
                region: rect(progress.job.region),
                samples: [progress.job.samples.start, progress.job.samples.end],
                target,
                tile: progress.tile,
                done: progress.done.clone(),
            },
            sums: progress.sums.clone(),
        }
    }

    pub fn region(&self) -> PixelRect {
        self.header.region()
    }

    pub fn samples(&self) -> SampleRange {
        self.header.samples()
    }

    pub fn is_complete(&self) -> bool {
        self.header.is_complete()
    }

    /// The render state this part records, to resume or extend it.
    pub fn progress(&self) -> Progress {
        Progress {
            job: Job {
                region: self.region(),
                samples: self.samples(),
            },
            tile: self.header.tile,
            done: self.header.done.clone(),
            sums: self.sums.clone(),
        }
    }

    /// Refuses a part made from another scene or other settings than `scene`'s.
    pub fn check_scene(&self, scene: &Scene, path: &Path) -> Result<()> {
        let expected = &scene.settings;
        let fingerprint = format!("{:016x}", scene.fingerprint());
        let h = &self.header;
        let mismatch = |what: &str, theirs: String, ours: String| {
            Err(part_error(
                path,
                format!("was rendered with a different {what} ({theirs}, this render has {ours})"),
            ))
        };
        if h.fingerprint != fingerprint {
            if (h.width, h.height) != (expected.width, expected.height) {
                return mismatch(
                    "image size",
                    format!("{}x{}", h.width, h.height),
                    format!("{}x{}", expected.width, expected.height),
                );
            }
            if h.seed != expected.seed {
                return mismatch("seed", h.seed.to_string(), expected.seed.to_string());
            }
            if h.max_depth != expected.max_depth {
                return mismatch(
                    "depth",
                    h.max_depth.to_string(),
                    expected.max_depth.to_string(),
                );
            }
            return mismatch("scene", h.fingerprint.clone(), fingerprint);
        }
        if h.window != rect(expected.window) {
            return mismatch(
                "crop window",
                format!("{:?}", h.window),
                format!("{:?}", rect(expected.window)),
            );
        }
        Ok(())
    }
}

fn part_error(path: &Path, message: String) -> Error {
    Error::Partial {
        path: path.to_owned(),
        message,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A complete part of an 8×6 image of 9 samples per pixel: `region` over `samples`.
    pub(crate) fn part(region: PixelRect, samples: [u32; 2]) -> Part {
        let job = Job {
            region,
            samples: SampleRange {
                start: samples[0],
                end: samples[1],
            },
        };
        let mut progress = Progress::new(job, 4);
        progress
            .done
            .iter_mut()
            .for_each(|d| *d = job.samples.len());
        progress
            .sums
            .iter_mut()
            .enumerate()
            .for_each(|(i, s)| *s = [i as u64, 1, 2]);
        Part {
            header: Header {
                version: VERSION,
                fingerprint: "00".to_owned(),
                seed: 1,
                width: 8,
                height: 6,
                max_depth: 5,
                gamma: 2.0,
                window: [0, 0, 8, 6],
                region: rect(region),
                samples,
                target: 9,
                tile: 4,
                done: progress.done.clone(),
            },
            sums: progress.sums,
        }
    }
}
