//! The job model: which pixels over which sample indices a render (or one part of it) covers,
//! and how far it has come, tile by tile. No threads; `render` runs jobs, `partial` stores
//! their state.

use crate::film::{Film, add_sums};
use crate::math::PixelRect;
use crate::scene::Scene;
use serde::{Deserialize, Serialize};

/// A range of sample indices `start..end`, rendered for every pixel of a region.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SampleRange {
    pub start: u32,
    pub end: u32,
}

impl SampleRange {
    pub fn len(&self) -> u32 {
        self.end.saturating_sub(self.start)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A unit of rendering: the pixels of `region` (inside the scene's window) over the sample
/// indices `samples`. A whole render is the window over `0..samples_per_pixel`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Job {
    pub region: PixelRect,
    pub samples: SampleRange,
}

impl Job {
    /// The whole image the scene describes.
    pub fn whole(scene: &Scene) -> Self {
        Job {
            region: scene.settings.window,
            samples: SampleRange {
                start: 0,
                end: scene.settings.samples_per_pixel,
            },
        }
    }
}

/// A job's accumulated state: the sums so far and how many samples of the job's range each
/// tile has finished. Tiles finish whole, so the state is exact at every point, and adding the
/// rest of the samples later gives the same integers as rendering them in one go.
///
/// Partial files store it as it is: the fields in their JSON header, the sums as their body.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobState {
    pub job: Job,
    /// Tile edge in pixels; `done` follows `job.region.tiles(tile)`.
    pub tile: u32,
    /// Samples finished per tile, counted from `job.samples.start`.
    pub done: Vec<u32>,
    /// Fixed-point sums over the region, row-major.
    #[serde(skip)]
    pub sums: Vec<[u64; 3]>,
}

impl JobState {
    /// The state of `job` before anything is rendered, in tiles of edge `tile`; for jobs
    /// whose size is this program's own (tests, a part's few tiles). A stranger's job is
    /// `try_new`.
    pub fn new(job: Job, tile: u32) -> Self {
        Self::try_new(job, tile).unwrap_or_else(|why| panic!("{why}"))
    }

    /// The state of `job` before anything is rendered, its sums reserved first and a failure
    /// to have them said in words: a scene's size is a stranger's to choose (2^28 pixels
    /// claim 6 GiB of sums), and a failed allocation otherwise ends the process (an abort,
    /// "memory allocation failed"), the interpreter and all where tessera is a Python
    /// module.
    pub fn try_new(job: Job, tile: u32) -> Result<Self, String> {
        let tile = tile.max(1);
        let area = job.region.area() as usize;
        let tiles = job.region.tiles(tile).len();
        let refused = |e: std::collections::TryReserveError| {
            let (width, height) = (job.region.width, job.region.height);
            let bytes = area as u64 * std::mem::size_of::<[u64; 3]>() as u64;
            format!(
                "the image's {width}x{height} pixels need {bytes} bytes for their sums, which \
                 this process could not have ({e})"
            )
        };
        // Zeroed as `film::zeroed_sums` zeroes them: written now, not left to zero pages.
        let mut sums = Vec::new();
        sums.try_reserve_exact(area).map_err(refused)?;
        sums.resize(area, [0; 3]);
        let mut done = Vec::new();
        done.try_reserve_exact(tiles).map_err(refused)?;
        done.resize(tiles, 0);
        Ok(JobState {
            done,
            sums,
            job,
            tile,
        })
    }

    pub fn is_complete(&self) -> bool {
        self.done.iter().all(|&d| d >= self.job.samples.len())
    }

    /// Samples of the whole job, over all pixels.
    pub fn total_samples(&self) -> u64 {
        self.job.region.area() * u64::from(self.job.samples.len())
    }

    /// Samples finished, over all pixels.
    pub fn finished_samples(&self) -> u64 {
        let len = self.job.samples.len();
        (self.job.region.tiles(self.tile).iter())
            .zip(&self.done)
            .map(|(t, &d)| t.area() * u64::from(d.min(len)))
            .sum()
    }

    /// Samples still to render.
    pub fn remaining_samples(&self) -> u64 {
        self.total_samples() - self.finished_samples()
    }

    /// How much of the job is done, in percent (0 of nothing is 0%).
    pub fn percent_done(&self) -> f64 {
        100.0 * self.finished_samples() as f64 / self.total_samples().max(1) as f64
    }

    /// The tiles that still lack samples: each one's index, its pixels, and the sample
    /// indices it lacks.
    pub fn unfinished_tiles(&self) -> Vec<(usize, PixelRect, SampleRange)> {
        let samples = self.job.samples;
        (self.job.region.tiles(self.tile).into_iter().enumerate())
            .filter(|&(i, _)| self.done[i] < samples.len())
            .map(|(i, tile)| {
                let start = samples.start + self.done[i];
                (i, tile, SampleRange { start, ..samples })
            })
            .collect()
    }

    /// Extends the job to more samples (progressive rendering): finished tiles keep their sums.
    pub fn extend_to(&mut self, end: u32) {
        self.job.samples.end = self.job.samples.end.max(end);
    }

    /// Adds the sums of tile `index` (the pixels `tile`), which now has every sample.
    pub fn add_tile(&mut self, index: usize, tile: &PixelRect, sums: &[[u64; 3]]) {
        self.add_samples(index, tile, sums, self.job.samples.len());
    }

    /// Adds the sums of tile `index` (the pixels `tile`) over the samples that follow its
    /// `done` ones, after which it has `done_after` of the job's samples.
    pub fn add_samples(
        &mut self,
        index: usize,
        tile: &PixelRect,
        sums: &[[u64; 3]],
        done_after: u32,
    ) {
        debug_assert!(done_after >= self.done[index] && done_after <= self.job.samples.len());
        add_sums(&mut self.sums, self.job.region, sums, *tile);
        self.done[index] = done_after;
    }

    /// The fewest samples any tile has: every pixel of the region has at least this many.
    pub fn min_done(&self) -> u32 {
        self.done.iter().copied().min().unwrap_or(0)
    }

    /// The finished image of the region. Panics if the job is not complete.
    pub fn into_film(self) -> Film {
        assert!(self.is_complete(), "film of an unfinished job");
        Film {
            width: self.job.region.width,
            height: self.job.region.height,
            samples_per_pixel: self.job.samples.len(),
            sums: self.sums,
        }
    }
}
