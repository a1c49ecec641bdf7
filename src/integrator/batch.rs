//! Paths traced sixteen at a time, for scenes that `batches_paths` (a few quads: the Cornell
//! box): a lane per path; each segment's sixteen rays are tested at once
//! (`Scene::hit_batch`), then each path takes its hit and asks for its next segment; a lane
//! whose path ends takes the tile's next sample. The lanes' paths are independent, so the
//! processor works on all sixteen while each waits on its own long chains of arithmetic.
//!
//! Every sample's path is the one `path_trace_full` traces for it alone (the same camera
//! sample, the same hits, the same random numbers), and a pixel's sums are exact integers,
//! which add in any order: the image is the same, bit for bit.

use super::FullPath;
use super::pixel::CameraSample;
use crate::bvh::{BATCH, Moment, RayBatch};
use crate::geometry::{Hit, MaterialId, PrimitiveId};
use crate::job::SampleRange;
use crate::math::{Color, Interval, PixelRect, Vec3};
use crate::ray::Ray;
use crate::sampling::{PixelSeed, Sampler};
use crate::scene::Scene;
use crate::simd::Isa;

/// A tile's samples, pixel by pixel (rows top to bottom, each left to right), each pixel's
/// in order, as lanes ask for them.
struct Feed<'a> {
    scene: &'a Scene,
    tile: PixelRect,
    range: SampleRange,
    /// The pixel being handed out (an index into the tile, row by row) and its next
    /// sample.
    pixel: u32,
    sample: u32,
    seed: PixelSeed,
    /// Samples to hand out before the next look at the stop flag.
    until_look: u32,
}

/// What the feed hands a lane.
enum Next {
    /// A camera sample of the tile's pixel `pixel`.
    Sample {
        pixel: u32,
        camera: CameraSample,
        moment: Moment,
    },
    /// Every sample has been handed out.
    Done,
    /// The stop flag was seen set.
    Stop,
}

impl<'a> Feed<'a> {
    fn new(scene: &'a Scene, tile: PixelRect, range: SampleRange) -> Self {
        let mut feed = Feed {
            scene,
            tile,
            range,
            pixel: 0,
            sample: range.start,
            seed: PixelSeed::new(0, 0, 0),
            until_look: 0,
        };
        feed.seed = feed.pixel_seed();
        feed
    }

    /// The pixel's coordinates in the image.
    fn position(&self) -> (u32, u32) {
        let w = self.tile.width.max(1);
        (self.tile.x0 + self.pixel % w, self.tile.y0 + self.pixel / w)
    }

    fn pixel_seed(&self) -> PixelSeed {
        let (x, y) = self.position();
        PixelSeed::new(self.scene.settings.seed, x, y)
    }

    /// The next sample, looking at `stopped` at the start of each pixel and every
    /// `stop_run` samples within one.
    #[inline(always)]
    fn next(&mut self, stopped: &impl Fn() -> bool, stop_run: u32) -> Next {
        if self.sample >= self.range.end {
            if u64::from(self.pixel) + 1 >= self.tile.area() {
                return Next::Done;
            }
            self.pixel += 1;
            self.sample = self.range.start;
            self.seed = self.pixel_seed();
            self.until_look = 0;
        }
        if self.until_look == 0 {
            if stopped() {
                return Next::Stop;
            }
            self.until_look = stop_run;
        }
        self.until_look -= 1;
        let (x, y) = self.position();
        let (camera, moment) =
            CameraSample::new::<true>(self.scene, x, y, self.seed.sample(self.sample));
        self.sample += 1;
        Next::Sample {
            pixel: self.pixel,
            camera,
            moment,
        }
    }
}

/// The rounds (a ray a lane each) between two looks at the stop flag besides those the feed
/// makes: `STOP_RAYS` rays.
const LOOK_ROUNDS: u32 = (super::STOP_RAYS / BATCH as u64) as u32;

/// The hits of a camera ray count at any distance.
const CAMERA: Interval = Interval::new(0.0, f32::INFINITY);

/// The stop flag was seen set.
struct Stopped;

/// Eight lanes of paths: each one's path and generator, the segment it asks for (in the
/// batch's lanes, and alone with its moment), and its pixel.
struct Lanes {
    rays: RayBatch,
    alone: [Ray; BATCH],
    moments: [Moment; BATCH],
    paths: [FullPath; BATCH],
    rngs: [Sampler; BATCH],
    pixels: [u32; BATCH],
    /// Bit `i` set while lane `i` holds a path.
    active: u32,
}

impl Lanes {
    fn new() -> Self {
        let ray = Ray::new(Color::ZERO, Color::X);
        Lanes {
            rays: RayBatch::default(),
            alone: [ray; BATCH],
            moments: [Moment::default(); BATCH],
            paths: [FullPath::start(ray, Moment::default()); BATCH],
            rngs: std::array::from_fn(|_| Sampler::from_seed(0)),
            pixels: [0; BATCH],
            active: 0,
        }
    }

    /// Gives `lane` the feed's next sample, or leaves it empty when there is none.
    #[inline(always)]
    fn fill(
        &mut self,
        lane: usize,
        feed: &mut Feed<'_>,
        stopped: &impl Fn() -> bool,
        stop_run: u32,
    ) -> Result<(), Stopped> {
        match feed.next(stopped, stop_run) {
            Next::Sample {
                pixel,
                camera,
                moment,
            } => {
                self.paths[lane] = FullPath::start(camera.ray, moment);
                self.rngs[lane] = camera.rng;
                self.alone[lane] = camera.ray;
                self.moments[lane] = moment;
                self.pixels[lane] = pixel;
                self.rays.set(lane, &camera.ray, CAMERA, crate::bvh::NO_HIT);
                self.active |= 1 << lane;
            }
            Next::Done => {
                self.rays.clear(lane);
                self.active &= !(1 << lane);
            }
            Next::Stop => return Err(Stopped),
        }
        Ok(())
    }
}

/// Traces samples `range` of every pixel of `tile` (the scene must `batches_paths`, shade by
/// path tracing and allow a segment), handing each sample's radiance and ray segments to
/// `add` with its pixel's index in the tile (row by row). False when `stopped` said to
/// stop (looked at before each pixel, every `stop_run` samples within one and every
/// `LOOK_ROUNDS` rounds) before the last sample.
#[inline(always)]
pub fn trace_tile<I: Isa>(
    isa: I,
    scene: &Scene,
    tile: &PixelRect,
    range: SampleRange,
    stopped: impl Fn() -> bool,
    stop_run: u32,
    mut add: impl FnMut(usize, Color, u32),
) -> bool {
    if range.is_empty() || tile.area() == 0 {
        return true;
    }
    let mut feed = Feed::new(scene, *tile, range);
    let mut l = Lanes::new();
    for lane in 0..BATCH {
        if l.fill(lane, &mut feed, &stopped, stop_run).is_err() {
            return false;
        }
    }
    // Each round: the lanes' rays tested at once; then each path scatters where its ray
    // hit; then the paths that go on leave, and the lanes whose paths ended take new
    // samples. In separate loops, so that the processor overlaps the lanes' long chains
    // (the hits' records and the scattering, then the new directions' square roots and
    // divisions) rather than waiting on each lane's in turn.
    // Each going-on lane's hit and scattered direction.
    let nowhere = Hit {
        t: 0.0,
        p: Vec3::ZERO,
        normal: Vec3::X,
        front_face: true,
        normal_points_out: true,
        material: MaterialId(0),
        primitive: PrimitiveId(0),
    };
    let mut heres = [nowhere; BATCH];
    let mut raws = [Vec3::ZERO; BATCH];
    // Rounds to the next look at `stopped`: sixteen paths of thousands of bounces each may
    // hand out no sample for as many rounds.
    let mut until_look = LOOK_ROUNDS;
    while l.active != 0 {
        until_look -= 1;
        if until_look == 0 {
            if stopped() {
                return false;
            }
            until_look = LOOK_ROUNDS;
        }
        let (t, ids) = scene.hit_batch(isa, &l.rays, &l.alone, &l.moments, l.active);
        let mut ended = 0u32;
        let mut lanes = l.active;
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize & (BATCH - 1);
            lanes &= lanes - 1;
            let path = &mut l.paths[lane];
            // The hit record is made where it is kept, and scattered from there: a record
            // handed back with the direction was copied through the stack in pieces whose
            // reload missed store forwarding, a stall of a tenth of the Cornell box's time.
            let here = match scene.surface_of(&l.alone[lane], path.moment, t[lane], ids[lane]) {
                Some(hit) => {
                    heres[lane] = hit;
                    Some(&heres[lane])
                }
                None => None,
            };
            match path.scatter(scene, here, &mut l.rngs[lane]) {
                Some(raw) => raws[lane] = raw,
                None => ended |= 1 << lane,
            }
        }
        let mut lanes = l.active & !ended;
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize & (BATCH - 1);
            lanes &= lanes - 1;
            let path = &mut l.paths[lane];
            let (next, interval, hints) = path.leave(scene, &heres[lane], raws[lane]);
            l.alone[lane] = next;
            l.moments[lane] = path.moment;
            l.rays.set(lane, &next, interval, hints.leaving.id());
        }
        while ended != 0 {
            let lane = ended.trailing_zeros() as usize & (BATCH - 1);
            ended &= ended - 1;
            let r = l.paths[lane].radiance();
            add(l.pixels[lane] as usize, r.color, r.rays);
            if l.fill(lane, &mut feed, &stopped, stop_run).is_err() {
                return false;
            }
        }
    }
    true
}
