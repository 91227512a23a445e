//! Counters reported in summaries: rays by kind, samples, time per stage.

use std::ops::AddAssign;

/// Ray and sample counts of a render (summed per tile, then merged).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayStats {
    /// Closest-hit rays.
    pub closest: u64,
    /// Occlusion (shadow) rays.
    pub shadow: u64,
    /// Samples (camera paths, light paths, chain steps: whatever the mode counts).
    pub samples: u64,
    /// Samples whose value was not finite and was discarded (should stay 0).
    pub discarded: u64,
}

impl RayStats {
    /// All rays.
    pub fn rays(&self) -> u64 {
        self.closest + self.shadow
    }
}

impl AddAssign for RayStats {
    fn add_assign(&mut self, o: Self) {
        self.closest += o.closest;
        self.shadow += o.shadow;
        self.samples += o.samples;
        self.discarded += o.discarded;
    }
}
