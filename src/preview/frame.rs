//! The preview's picture of a job: its region tone-mapped to 8 bits as the state grows,
//! shrunk by a whole factor when it is large, and updated tile by tile as tiles are folded,
//! so keeping it costs work in proportion to the folding, never a pass over the whole image.

use crate::job::JobState;
use crate::math::PixelRect;
use crate::tonemap::{encode_8bit, mean, mean_scale};

/// The longest edge of a preview frame, in pixels: a larger region is shown shrunk by the
/// smallest whole factor that fits (the mean of each block of pixels), so a poster-sized
/// render costs its viewer no more than a screenful.
pub const MAX_EDGE: u32 = 2048;

/// The colour of pixels that have no sample yet: the viewer's own dark grey.
pub const UNRENDERED: [u8; 3] = [30, 31, 34];

/// A finished picture of the job at one moment, as sent to viewers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// Counts the frames of a render: a new number means new pixels.
    pub version: u64,
    pub width: u32,
    pub height: u32,
    /// Region pixels per frame pixel along each axis (1: full size).
    pub scale: u32,
    /// Row-major RGB, 8 bits per channel, as the image file would hold them.
    pub rgb: Vec<u8>,
    /// The only rows that differ from frame `version - 1`, as `[start, end)` ranges in
    /// order (`None`: any may), so that a viewer holding that frame needs only these rows.
    /// Tiles finish along rows, a band per worker, so a second's changes are a few bands.
    pub changed: Option<Vec<[u32; 2]>>,
}

impl Frame {
    /// The frame as a PNG.
    pub fn png(&self) -> Vec<u8> {
        self.png_of_rows(&[[0, self.height]])
    }

    /// The rows `rows` (`[start, end)` ranges inside the frame) stacked in order into one
    /// PNG, compressed for speed rather than size: it is made about once a second and
    /// thrown away.
    pub fn png_of_rows(&self, rows: &[[u32; 2]]) -> Vec<u8> {
        use image::ImageEncoder;
        use image::codecs::png::{CompressionType, FilterType, PngEncoder};
        let row = self.width as usize * 3;
        let mut pixels = Vec::new();
        let mut height = 0;
        for &[start, end] in rows {
            let (start, end) = (start.min(self.height), end.min(self.height));
            if start < end {
                pixels.extend_from_slice(&self.rgb[start as usize * row..end as usize * row]);
                height += end - start;
            }
        }
        let mut out = Vec::with_capacity(pixels.len() / 2 + 1024);
        PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Adaptive)
            .write_image(&pixels, self.width, height, image::ExtendedColorType::Rgb8)
            .expect("the rows' buffer matches their size and a Vec takes any length");
        out
    }
}

/// Keeps the 8-bit picture of a job's region up to date as tiles are folded.
pub struct FrameBuilder {
    region: PixelRect,
    tile: u32,
    tiles_across: u32,
    scale: u32,
    width: u32,
    height: u32,
    gamma: f32,
    rgb: Vec<u8>,
    /// The frame rows redrawn since the last `frame`.
    dirty: Vec<bool>,
}

impl FrameBuilder {
    /// A builder for the region of `state`'s job, blank until `update_all` or `update_tile`.
    pub fn new(state: &JobState, gamma: f32) -> Self {
        let region = state.job.region;
        let longest = region.width.max(region.height).max(1);
        let scale = longest.div_ceil(MAX_EDGE).max(1);
        let (width, height) = (region.width.div_ceil(scale), region.height.div_ceil(scale));
        let tile = state.tile.max(1);
        let mut rgb = Vec::with_capacity(width as usize * height as usize * 3);
        for _ in 0..width as usize * height as usize {
            rgb.extend(UNRENDERED);
        }
        Self {
            region,
            tile,
            tiles_across: region.width.div_ceil(tile),
            scale,
            width,
            height,
            gamma,
            rgb,
            dirty: vec![false; height as usize],
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn scale(&self) -> u32 {
        self.scale
    }

    /// Redraws every pixel from `state` (a job resumed from a checkpoint starts with some).
    pub fn update_all(&mut self, state: &JobState) {
        for index in 0..state.done.len() {
            self.update_tile(state, index);
        }
    }

    /// Redraws the frame pixels that tile `index` of the region touches.
    pub fn update_tile(&mut self, state: &JobState, index: usize) {
        let Some(tile) = self.region.tile(self.tile, index) else {
            return;
        };
        let ry = tile.y0 - self.region.y0;
        let rows = ry / self.scale..(ry + tile.height).div_ceil(self.scale);
        self.dirty[rows.start as usize..rows.end as usize].fill(true);
        if self.scale == 1 {
            self.update_full_size(state, index, tile);
        } else {
            self.update_shrunk(state, tile);
        }
    }

    /// At full size a frame pixel is one pixel of the tile, with the tile's sample count:
    /// the same arithmetic as the image file, so a finished pixel has the file's bytes.
    fn update_full_size(&mut self, state: &JobState, index: usize, tile: PixelRect) {
        let samples = state.done[index];
        let scale = mean_scale(samples);
        let (rx, ry) = (tile.x0 - self.region.x0, tile.y0 - self.region.y0);
        for y in ry..ry + tile.height {
            let row = y as usize * self.region.width as usize;
            for x in rx..rx + tile.width {
                let at = row + x as usize;
                let pixel = if samples == 0 {
                    UNRENDERED
                } else {
                    state.sums[at].map(|c| encode_8bit(mean(c, scale), self.gamma))
                };
                self.rgb[at * 3..at * 3 + 3].copy_from_slice(&pixel);
            }
        }
    }

    /// Shrunk, a frame pixel is the mean radiance of its block's pixels that have samples,
    /// each pixel's mean taken over its own tile's count.
    fn update_shrunk(&mut self, state: &JobState, tile: PixelRect) {
        let s = self.scale;
        let (rx, ry) = (tile.x0 - self.region.x0, tile.y0 - self.region.y0);
        let (fx0, fy0) = (rx / s, ry / s);
        let (fx1, fy1) = ((rx + tile.width - 1) / s, (ry + tile.height - 1) / s);
        for fy in fy0..=fy1 {
            for fx in fx0..=fx1 {
                let mut total = [0.0f32; 3];
                let mut count = 0u32;
                for y in fy * s..((fy + 1) * s).min(self.region.height) {
                    for x in fx * s..((fx + 1) * s).min(self.region.width) {
                        let t = (y / self.tile) * self.tiles_across + x / self.tile;
                        let samples = state.done[t as usize];
                        if samples == 0 {
                            continue;
                        }
                        let scale = mean_scale(samples);
                        let sum = state.sums[y as usize * self.region.width as usize + x as usize];
                        for c in 0..3 {
                            total[c] += mean(sum[c], scale);
                        }
                        count += 1;
                    }
                }
                let pixel = if count == 0 {
                    UNRENDERED
                } else {
                    total.map(|c| encode_8bit(c / count as f32, self.gamma))
                };
                let at = (fy as usize * self.width as usize + fx as usize) * 3;
                self.rgb[at..at + 3].copy_from_slice(&pixel);
            }
        }
    }

    /// The frame as it is now, numbered `version`, with the rows redrawn since the frame
    /// before (the last call) as its `changed`.
    pub fn frame(&mut self, version: u64) -> Frame {
        let mut changed: Vec<[u32; 2]> = Vec::new();
        for (y, dirty) in (0u32..).zip(&mut self.dirty) {
            if std::mem::take(dirty) {
                match changed.last_mut() {
                    Some(last) if last[1] == y => last[1] = y + 1,
                    _ => changed.push([y, y + 1]),
                }
            }
        }
        Frame {
            version,
            width: self.width,
            height: self.height,
            scale: self.scale,
            rgb: self.rgb.clone(),
            changed: Some(changed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::to_fixed;
    use crate::job::{Job, SampleRange};

    fn state(width: u32, height: u32, tile: u32, spp: u32) -> JobState {
        let job = Job {
            region: PixelRect::full(width, height),
            samples: SampleRange { start: 0, end: spp },
        };
        JobState::new(job, tile)
    }

    #[test]
    fn a_finished_frame_holds_the_image_files_bytes() {
        let mut s = state(5, 3, 2, 4);
        for (i, sum) in s.sums.iter_mut().enumerate() {
            *sum = [to_fixed(0.1 * i as f32), to_fixed(0.5), to_fixed(3.0)].map(|c| c * 4);
        }
        s.done.iter_mut().for_each(|d| *d = 4);
        let mut b = FrameBuilder::new(&s, 2.0);
        b.update_all(&s);
        let film = s.clone().into_film();
        assert_eq!(b.frame(1).rgb, film.to_rgb8(2.0));
    }

    #[test]
    fn pixels_without_samples_are_blank_and_each_tile_has_its_own_count() {
        let mut s = state(4, 2, 2, 8);
        s.sums
            .iter_mut()
            .for_each(|sum| *sum = [to_fixed(0.25) * 2; 3]);
        s.done[0] = 2; // tile 0: x 0..2 with 2 samples; tile 1 (x 2..4) has none
        let mut b = FrameBuilder::new(&s, 2.0);
        b.update_tile(&s, 0);
        let rgb = b.frame(1).rgb;
        assert_eq!(&rgb[0..3], &[128; 3]);
        assert_eq!(&rgb[6..9], &UNRENDERED);
        // An index past the tiles changes nothing.
        b.update_tile(&s, 99);
        assert_eq!(b.frame(1).rgb, rgb);
    }

    #[test]
    fn each_frame_names_the_pixels_it_changed() {
        let mut s = state(40, 20, 8, 4);
        s.sums
            .iter_mut()
            .for_each(|sum| *sum = [to_fixed(0.5) * 4; 3]);
        let mut b = FrameBuilder::new(&s, 2.0);
        let blank = b.frame(1);
        s.done[1] = 4; // x 8..16, y 0..8
        s.done[7] = 4; // x 16..24, y 8..16
        b.update_tile(&s, 1);
        b.update_tile(&s, 7);
        s.done[10] = 4; // x 0..8, y 16..20
        b.update_tile(&s, 10);
        let next = b.frame(2);
        let rows = next.changed.clone().unwrap();
        assert_eq!(rows, vec![[0, 20]], "touching bands merge");
        // The patch on the frame before gives the frame.
        let patch = image::load_from_memory(&next.png_of_rows(&rows))
            .unwrap()
            .to_rgb8();
        let mut rebuilt = image::RgbImage::from_raw(40, 20, blank.rgb.clone()).unwrap();
        image::imageops::replace(&mut rebuilt, &patch, 0, 0);
        assert_eq!(rebuilt.as_raw(), &next.rgb);
        // Nothing redrawn: no rows.
        assert_eq!(b.frame(3).changed.unwrap(), Vec::<[u32; 2]>::new());
        // Two bands apart: two ranges, stacked in the patch.
        s.done[0] = 4; // y 0..8
        s.done[14] = 4; // y 16..20
        b.update_tile(&s, 0);
        b.update_tile(&s, 14);
        let last = b.frame(4);
        let rows = last.changed.clone().unwrap();
        assert_eq!(rows, vec![[0, 8], [16, 20]]);
        let patch = image::load_from_memory(&last.png_of_rows(&rows))
            .unwrap()
            .to_rgb8();
        assert_eq!(patch.dimensions(), (40, 12));
        let mut rebuilt = image::RgbImage::from_raw(40, 20, next.rgb).unwrap();
        image::imageops::replace(
            &mut rebuilt,
            &image::imageops::crop_imm(&patch, 0, 0, 40, 8).to_image(),
            0,
            0,
        );
        image::imageops::replace(
            &mut rebuilt,
            &image::imageops::crop_imm(&patch, 0, 8, 40, 4).to_image(),
            0,
            16,
        );
        assert_eq!(rebuilt.as_raw(), &last.rgb);
    }

    #[test]
    fn large_regions_are_shrunk_by_a_whole_factor() {
        let mut s = state(MAX_EDGE * 2 + 1, 3, 16, 1);
        s.sums
            .iter_mut()
            .for_each(|sum| *sum = [to_fixed(1.0), 0, 0]);
        let mut b = FrameBuilder::new(&s, 1.0);
        assert_eq!((b.scale(), b.width(), b.height()), (3, 1366, 1));
        s.done[0] = 1; // the first tile: pixels 0..16 of rows 0..3
        b.update_tile(&s, 0);
        let rgb = b.frame(1).rgb;
        // Frame pixels 0..5 lie in the tile; pixel 5 (columns 15..18) is one third in it and
        // shows only its rendered column.
        assert_eq!(&rgb[0..3], &[255, 0, 0]);
        assert_eq!(&rgb[15..18], &[255, 0, 0]);
        assert_eq!(&rgb[18..21], &UNRENDERED);
        let png = b.frame(1).png();
        let decoded = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(decoded.as_raw(), &rgb);
    }
}
