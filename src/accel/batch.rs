//! Shadow rays queued eight at a time: set up on SIMD lanes and traced with the shadow cache
//! (the gather's and MIR's probe normalisation's visibility tests).

use glam::Vec3;

use super::single::NO_OCCLUDER;
use super::{Accel, SHADOW_T_MAX};
use crate::simd::{F4, F8, LaneRay, Lanes, RayPacket};
use crate::stats::RayStats;

/// Shadow rays waiting to be traced, each with its shadow-cache slot (its VPL) and a payload:
/// set up on eight lanes at once ([`Accel::occluded_lanes_cached`]) and traced one by one,
/// whichever receivers they come from (a pixel's subset of four VPLs would leave half of the
/// set-up lanes idle; MIR's probes each send one ray to the same VPL).
pub(crate) struct ShadowBatch<T: Copy + Default> {
    rays: [LaneRay; 8],
    slot: [u32; 8],
    item: [T; 8],
    len: usize,
}

impl<T: Copy + Default> ShadowBatch<T> {
    pub(crate) fn new() -> Self {
        let idle = LaneRay::new(Vec3::ZERO, Vec3::X, 0.0);
        ShadowBatch { rays: [idle; 8], slot: [0; 8], item: [T::default(); 8], len: 0 }
    }

    /// Queues the segment from `o` to `target` (tested up to [`SHADOW_T_MAX`]) with cache slot
    /// `slot`, tracing the batch (see [`ShadowBatch::trace`]) when it is full.
    #[inline(always)]
    pub(crate) fn push(
        &mut self,
        o: Vec3,
        target: Vec3,
        slot: u32,
        item: T,
        accel: &Accel,
        cache: &mut [u32],
        st: &mut RayStats,
        visible: impl FnMut(u32, T),
    ) {
        let k = self.len;
        (self.rays[k], self.slot[k], self.item[k]) = (LaneRay::new(o, target - o, SHADOW_T_MAX), slot, item);
        self.len += 1;
        if self.len == F8::LANES {
            self.trace(accel, cache, st, visible);
        }
    }

    /// Traces the queued rays and calls `visible` with the cache slot and payload of each
    /// unblocked ray, in queue order. Ray k starts from the shadow cache `cache[slot k]` as it was when the batch
    /// was traced (rays of one batch do not see each other's occluders); a blocked ray then
    /// leaves its occluder there, in queue order. The answers do not depend on the cache.
    pub(crate) fn trace(
        &mut self,
        accel: &Accel,
        cache: &mut [u32],
        st: &mut RayStats,
        mut visible: impl FnMut(u32, T),
    ) {
        let n = self.len;
        if n == 0 {
            return;
        }
        let mut hints = [NO_OCCLUDER; 8];
        for k in 0..n {
            hints[k] = cache[self.slot[k] as usize];
        }
        let ray = |k: usize| (k < n).then(|| self.rays[k]);
        let blocked = if n <= 4 {
            accel.occluded_lanes_cached(&RayPacket::<F4>::from_fn(ray), &mut hints)
        } else {
            accel.occluded_lanes_cached(&RayPacket::<F8>::from_fn(ray), &mut hints)
        };
        st.shadow += n as u64;
        for k in 0..n {
            if blocked >> k & 1 != 0 {
                cache[self.slot[k] as usize] = hints[k];
            } else {
                visible(self.slot[k], self.item[k]);
            }
        }
        self.len = 0;
    }
}
