//! Partial renders on disk — shards and checkpoints — and merging them. A part is the render
//! it belongs to (`RenderId`) and its job's state (`JobState`), sums included; sums are
//! integers, so adding parts in any order gives exactly the sums of one uninterrupted render.
//! `file` owns the byte layout and reading it safely; `merge` owns adding parts up.

mod file;
mod merge;

pub use file::{PartReader, save, save_result};
pub use merge::{merge, merge_files};

use crate::error::{Error, Result};
use crate::job::{Job, JobState};
use crate::math::PixelRect;
use crate::scene::Scene;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The version of the file layout this build writes and reads. 4: the header names the
/// build that rendered the part (`RenderId::tessera`).
const VERSION: u32 = 4;

/// Which render a part belongs to: parts merge, and checkpoints resume, only within one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderId {
    /// `Scene::fingerprint` in hex: scene contents and every setting but spp and crop.
    pub fingerprint: String,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    pub max_depth: u32,
    pub gamma: f32,
    /// The scene's window: what a merge must cover.
    pub window: PixelRect,
    /// Samples per pixel of the finished image: a merge must cover sample indices
    /// `0..target` of every pixel of `window`.
    pub target: u32,
    /// The build that rendered the part. Builds of other commits may render other sums for
    /// one scene and settings (a change of the integrator's arithmetic changes an image's
    /// bytes), and a merge or a resume of parts of two builds made an image that neither
    /// renders, its recipe naming the one that merged.
    pub tessera: crate::recipe::Maker,
    /// The scene file and settings, for the recipe of the image a merge writes; none when
    /// the render was told to leave its recipe out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recipe: Option<crate::recipe::Source>,
}

impl RenderId {
    /// The render of `scene` with `target` samples per pixel.
    pub fn of(scene: &Scene, target: u32) -> Self {
        let s = &scene.settings;
        RenderId {
            fingerprint: format!("{:016x}", scene.fingerprint()),
            seed: s.seed,
            width: s.width,
            height: s.height,
            max_depth: s.max_depth,
            gamma: s.gamma,
            window: s.window,
            target,
            tessera: crate::recipe::Maker::this_build(),
            recipe: None,
        }
    }

    /// The first thing, by name, in which `self` is another render than `other` (the
    /// target sample count aside): the setting, `self`'s value and `other`'s.
    fn mismatch(&self, other: &RenderId) -> Option<(&'static str, String, String)> {
        let pair =
            |what, a: &dyn ToString, b: &dyn ToString| Some((what, a.to_string(), b.to_string()));
        let size = |r: &RenderId| format!("{}x{}", r.width, r.height);
        let window = |r: &RenderId| {
            let w = r.window;
            format!("[{}, {}, {}, {}]", w.x0, w.y0, w.width, w.height)
        };
        if self.seed != other.seed {
            pair("seed", &self.seed, &other.seed)
        } else if (self.width, self.height) != (other.width, other.height) {
            pair("image size", &size(self), &size(other))
        } else if self.max_depth != other.max_depth {
            pair("depth", &self.max_depth, &other.max_depth)
        } else if self.window != other.window {
            pair("crop window", &window(self), &window(other))
        } else if self.fingerprint != other.fingerprint
            || self.gamma.to_bits() != other.gamma.to_bits()
        {
            pair("scene or settings", &self.fingerprint, &other.fingerprint)
        } else if self.tessera != other.tessera {
            pair("tessera build", &self.tessera, &other.tessera)
        } else {
            None
        }
    }
}

/// A partial render: the render it belongs to and how far its job has come. Its JSON header
/// is this struct; the state's sums follow it as the file's body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Part {
    pub version: u32,
    pub render: RenderId,
    pub state: JobState,
}

impl Part {
    /// The part holding `state` of `scene`, one piece of an image of `target` samples per
    /// pixel.
    pub fn of(scene: &Scene, state: JobState, target: u32) -> Part {
        Part {
            version: VERSION,
            render: RenderId::of(scene, target),
            state,
        }
    }

    pub fn is_complete(&self) -> bool {
        self.state.is_complete()
    }

    /// Checks the header's claims against each other, so nothing sized by them is
    /// allocated before they are known to be sane.
    fn check_claims(&self, path: &Path) -> Result<()> {
        let fail = |message: String| Err(part_error(path, message));
        if self.version != VERSION {
            return fail(another_version(self.version));
        }
        let (r, job) = (&self.render, &self.state.job);
        let image = PixelRect::full(r.width, r.height);
        if image.area() > crate::scene::MAX_PIXELS
            || !image.contains(&r.window)
            || !r.window.contains(&job.region)
            || job.region.area() == 0
        {
            return fail(format!(
                "has an impossible region: state.job.region {} in render.window {} of a {}x{} \
                 image",
                pixels(job.region),
                pixels(r.window),
                r.width,
                r.height
            ));
        }
        // The film is written with the header's gamma, so it must be one a scene takes.
        if !(r.gamma.is_finite() && r.gamma > 0.0) {
            return fail(format!(
                "has an impossible gamma {} (a scene's is positive)",
                r.gamma
            ));
        }
        let s = &self.state;
        let (start, end) = (job.samples.start, job.samples.end);
        // A part holds at least one sample of each pixel of its region, within the image's
        // samples per pixel: an empty range once merged into a "0 spp" image. Each refusal
        // names the field at fault: one message for all five said nothing of which.
        let inconsistent = if end <= start {
            format!("state.job.samples {start}..{end} holds no sample")
        } else if end > r.target {
            format!(
                "state.job.samples {start}..{end} goes past render.target, the image's {} \
                 samples per pixel",
                r.target
            )
        } else if s.tile == 0 {
            "state.tile is 0".to_owned()
        } else if s.done.len() as u64 != job.region.tile_count(s.tile) {
            format!(
                "state.done lists {} tiles, where state.job.region in tiles of {} has {}",
                s.done.len(),
                s.tile,
                job.region.tile_count(s.tile)
            )
        } else if let Some((i, d)) = (s.done.iter().enumerate()).find(|&(_, &d)| d > end - start) {
            format!(
                "state.done[{i}] is {d} samples, more than the {} of state.job.samples",
                end - start
            )
        } else {
            return Ok(());
        };
        fail(format!("has an inconsistent header: {inconsistent}"))
    }

    /// Refuses a part made from another scene or other settings than `scene`'s.
    pub fn check_scene(&self, scene: &Scene, path: &Path) -> Result<()> {
        let ours = RenderId::of(scene, self.render.target);
        match self.render.mismatch(&ours) {
            Some((what, theirs, ours)) => Err(part_error(
                path,
                format!("was rendered with a different {what} ({theirs}, this render has {ours})"),
            )),
            None => Ok(()),
        }
    }

    /// The state to go on rendering `job` of `scene` from, this part being its checkpoint:
    /// the same scene and settings, the same pixels from the same first sample, and no more
    /// samples than `job` asks for (which may be more than the part has: progressive
    /// rendering).
    pub fn resume(self, scene: &Scene, job: Job, path: &Path) -> Result<JobState> {
        self.check_resumes(scene, job, path)?;
        let mut state = self.state;
        state.extend_to(job.samples.end);
        Ok(state)
    }

    /// Refuses this part, a checkpoint's header, as the state to go on rendering `job` of
    /// `scene` from (`resume`); the header alone says, so a checkpoint of another render is
    /// refused before its sums are read (`Part::load_checkpoint`).
    pub fn check_resumes(&self, scene: &Scene, job: Job, path: &Path) -> Result<()> {
        self.check_scene(scene, path)?;
        let had = self.state.job;
        let describe = |j: Job| {
            let r = j.region;
            format!(
                "pixels {}x{} at ({}, {}) from sample {}",
                r.width, r.height, r.x0, r.y0, j.samples.start
            )
        };
        if had.region != job.region || had.samples.start != job.samples.start {
            return Err(part_error(
                path,
                format!(
                    "the checkpoint holds {}, but this render is {}; use another checkpoint file",
                    describe(had),
                    describe(job)
                ),
            ));
        }
        if had.samples.end > job.samples.end {
            return Err(part_error(
                path,
                format!(
                    "the checkpoint already goes to sample {}, past the {} this render asks for",
                    had.samples.end, job.samples.end
                ),
            ));
        }
        Ok(())
    }
}

/// A rectangle of pixels as messages give one: `pixels 16x9 at (0, 0)`.
fn pixels(r: PixelRect) -> String {
    format!("pixels {}x{} at ({}, {})", r.width, r.height, r.x0, r.y0)
}

/// Why a part of format `version`, another than this build's, is refused.
fn another_version(version: u32) -> String {
    let whose = if version < VERSION {
        "an older"
    } else {
        "a newer"
    };
    format!(
        "is a part of format version {version}; this tessera reads version {VERSION}: it was \
         written by {whose} tessera, which can merge or resume it; or render it again with \
         this one"
    )
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
    use crate::job::SampleRange;

    /// A complete part of an 8×6 image of 9 samples per pixel: `region` over `samples`.
    pub(crate) fn part(region: PixelRect, samples: [u32; 2]) -> Part {
        let job = Job {
            region,
            samples: SampleRange {
                start: samples[0],
                end: samples[1],
            },
        };
        let mut state = JobState::new(job, 4);
        state.done.iter_mut().for_each(|d| *d = job.samples.len());
        (state.sums.iter_mut().enumerate()).for_each(|(i, s)| *s = [i as u64, 1, 2]);
        Part {
            version: VERSION,
            render: RenderId {
                fingerprint: "00".to_owned(),
                seed: 1,
                width: 8,
                height: 6,
                max_depth: 5,
                gamma: 2.0,
                window: PixelRect::full(8, 6),
                target: 9,
                tessera: crate::recipe::Maker::this_build(),
                recipe: None,
            },
            state,
        }
    }

    /// A header's inconsistent claims were refused all in one message, "has an inconsistent
    /// header (samples, tiles or progress)", and its impossible region in Rust's debug form
    /// (`PixelRect { x0: 4294967295, … }`): each refusal now names its field, in words.
    #[test]
    fn an_inconsistent_header_names_the_field_at_fault() {
        let path = Path::new("p.part");
        type Edit = dyn Fn(&mut Part);
        let refused = |edit: &Edit| {
            let mut p = part(PixelRect::full(8, 6), [0, 9]);
            edit(&mut p);
            p.check_claims(path).unwrap_err().to_string()
        };
        let cases: [(&Edit, &str); 6] = [
            (
                &|p| p.state.job.samples.end = 0,
                "state.job.samples 0..0 holds no sample",
            ),
            (
                &|p| p.state.job.samples.end = 10,
                "state.job.samples 0..10 goes past render.target, the image's 9",
            ),
            (&|p| p.state.tile = 0, "state.tile is 0"),
            (
                &|p| p.state.done.push(0),
                "state.done lists 5 tiles, where state.job.region in tiles of 4 has 4",
            ),
            (
                &|p| p.state.done[2] = 10,
                "state.done[2] is 10 samples, more than the 9 of state.job.samples",
            ),
            (
                &|p| p.state.job.region.x0 = u32::MAX,
                "state.job.region pixels 8x6 at (4294967295, 0) in render.window pixels 8x6 \
                 at (0, 0) of a 8x6 image",
            ),
        ];
        for (edit, says) in cases {
            let said = refused(edit);
            assert!(said.starts_with("p.part: has a"), "{said}");
            assert!(said.contains(says), "{said}");
        }
    }
}
