//! A pack of up to `WIDTH` constant-density media, tested a lane at a time: a medium's test
//! finds where the ray enters and leaves its boundary, then where it scatters inside.

use super::pack::beats;
use super::{Leaf, Moment, PackRay};
use crate::geometry::{Aabb, Medium, PrimitiveId};
use crate::math::Interval;
use crate::ray::Ray;
use crate::simd::Isa;

/// Up to `WIDTH` media with their ids.
#[derive(Clone, Debug)]
pub struct MediumPack {
    media: Vec<(Medium, u32)>,
}

impl Leaf for MediumPack {
    type Item = Medium;
    const ID_BASE: u32 = PrimitiveId::MEDIA;

    fn bounds(item: &Medium) -> Aabb {
        item.bounds()
    }

    fn pack(items: &[Medium], indices: &[u32]) -> Self {
        let media = indices
            .iter()
            .map(|&i| (items[i as usize].clone(), Self::ID_BASE + i))
            .collect();
        MediumPack { media }
    }

    fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.media.iter().map(|(_, id)| *id)
    }

    #[inline(always)]
    fn intersect<I: Isa>(&self, ray: &PackRay<'_, I>, closest: &mut f32, found: &mut u32) {
        for (medium, id) in &self.media {
            let interval = Interval::new(ray.t_min_scalar, f32::INFINITY);
            let hit = medium.intersect(
                ray.ray,
                ray.moment.time,
                ray.moment.medium_key,
                *id,
                interval,
            );
            if let Some(t) = hit
                && beats(t, *id, *closest, *found)
            {
                *closest = t;
                *found = *id;
            }
        }
    }

    #[inline(always)]
    fn intersect_one(
        item: &Medium,
        id: u32,
        ray: &Ray,
        moment: Moment,
        interval: Interval,
    ) -> Option<f32> {
        item.intersect(ray, moment.time, moment.medium_key, id, interval)
    }
}
