//! Ray packets: `LANES` rays in structure-of-arrays form with an active mask.

use glam::Vec3;

use super::{Lanes, Vec3x};

/// One ray of a packet as a scalar value: `origin + t·dir` for t in (t_min, t_max].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaneRay {
    /// Origin.
    pub origin: Vec3,
    /// Direction (not necessarily normalised).
    pub dir: Vec3,
    /// Start of the ray interval.
    pub t_min: f32,
    /// End of the ray interval.
    pub t_max: f32,
}

impl LaneRay {
    /// A ray over (0, t_max].
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3, t_max: f32) -> Self {
        LaneRay { origin, dir, t_min: 0.0, t_max }
    }
}

/// `LANES` rays: origins, directions, reciprocal directions (IEEE: ±∞ for zero components),
/// intervals and the mask of lanes that carry a ray. Inactive lanes hold a harmless ray
/// (origin 0, direction +x, empty interval) so that kernels may compute on them freely.
#[derive(Clone, Copy, Debug)]
pub struct RayPacket<F: Lanes> {
    /// Origins.
    pub origin: Vec3x<F>,
    /// Directions.
    pub dir: Vec3x<F>,
    /// Reciprocal directions.
    pub rdir: Vec3x<F>,
    /// Interval starts.
    pub t_min: F,
    /// Interval ends (−∞ in inactive lanes).
    pub t_max: F,
    /// Bit i set when lane i carries a ray.
    pub active: u32,
}

impl<F: Lanes> RayPacket<F> {
    /// The packet whose lane i is `f(i)` (`None`: inactive lane).
    #[inline]
    pub fn from_fn(mut f: impl FnMut(usize) -> Option<LaneRay>) -> Self {
        let idle = LaneRay { origin: Vec3::ZERO, dir: Vec3::X, t_min: 0.0, t_max: f32::NEG_INFINITY };
        let mut rays = [idle; 16];
        let mut active = 0;
        for (i, r) in rays.iter_mut().enumerate().take(F::LANES) {
            if let Some(ray) = f(i) {
                *r = ray;
                active |= 1 << i;
            }
        }
        RayPacket {
            origin: Vec3x::from_fn(|i| rays[i].origin),
            dir: Vec3x::from_fn(|i| rays[i].dir),
            rdir: Vec3x::from_fn(|i| {
                let d = rays[i].dir;
                Vec3::ONE / d
            }),
            t_min: F::from_fn(|i| rays[i].t_min),
            t_max: F::from_fn(|i| rays[i].t_max),
            active,
        }
    }

    /// The packet of `rays` (at most `LANES`; missing lanes are inactive).
    #[inline]
    pub fn from_rays(rays: &[LaneRay]) -> Self {
        debug_assert!(rays.len() <= F::LANES);
        Self::from_fn(|i| rays.get(i).copied())
    }

    /// Lane `i` as a single ray, `None` when inactive.
    #[inline]
    pub fn lane(&self, i: usize) -> Option<LaneRay> {
        if i >= F::LANES || self.active >> i & 1 == 0 {
            return None;
        }
        Some(LaneRay {
            origin: self.origin.lane(i),
            dir: self.dir.lane(i),
            t_min: self.t_min.lane(i),
            t_max: self.t_max.lane(i),
        })
    }

    /// The active rays, in lane order.
    pub fn rays(&self) -> impl Iterator<Item = (usize, LaneRay)> + '_ {
        (0..F::LANES).filter_map(|i| self.lane(i).map(|r| (i, r)))
    }

    /// Number of active lanes.
    #[inline]
    pub fn count(&self) -> u32 {
        self.active.count_ones()
    }

    /// The active mask as a lane mask.
    #[inline]
    pub fn active_mask(&self) -> F {
        F::mask_from_bits(self.active)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{F4, F8};

    fn round_trip<F: Lanes>() {
        let rays: Vec<LaneRay> = (0..F::LANES - 1)
            .map(|i| LaneRay::new(Vec3::new(i as f32, 0.5, -1.0), Vec3::new(0.0, 1.0, i as f32), 2.0 + i as f32))
            .collect();
        let p = RayPacket::<F>::from_rays(&rays);
        assert_eq!(p.count() as usize, F::LANES - 1);
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(p.lane(i), Some(*r));
            assert_eq!(p.rdir.lane(i).y, 1.0);
            assert_eq!(p.rdir.lane(i).x, 1.0 / rays[i].dir.x);
        }
        assert_eq!(p.lane(F::LANES - 1), None);
        assert_eq!(p.rays().count(), F::LANES - 1);
        assert_eq!(p.active_mask().bitmask(), p.active);
    }

    #[test]
    fn packets_round_trip_single_rays() {
        round_trip::<F4>();
        round_trip::<F8>();
    }
}
