//! ⑤ VPL samplers: where virtual point lights come from.
//!
//! Owns the [`VplSet`] (structure of arrays read by the gather) and the [`VplSampler`] trait
//! behind which every strategy sits: SIR (Keller 1997), SIR+CDF (Wald et al. 2003), BIR (after
//! Segovia et al. 2006). Samplers only produce VPLs; they never touch the image.

pub mod bir;
pub mod cdf;
pub mod kernel;
pub mod metropolis;
pub mod mirpath;
pub mod mutation;
pub mod normalise;
pub mod screen;
pub mod set;
pub mod sir;
pub mod transfer;

use std::time::Duration;

pub use set::{ON_LIGHT, TWO_SIDED, Vpl, VplLobe, VplSet};

use crate::accel::Accel;
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;

/// What a sampler did to produce its VPL set.
#[derive(Clone, Debug, Default)]
pub struct SamplerStats {
    /// Wall-clock time.
    pub time: Duration,
    /// Candidates considered (light paths for SIR, candidate VPLs for BIR, chain states for MIR).
    pub candidates: u64,
    /// VPLs kept.
    pub kept: usize,
    /// Light (or camera) sub-paths traced.
    pub paths: u64,
    /// Accepted proposals (Metropolis samplers).
    pub accepted: u64,
    /// Proposals (Metropolis samplers).
    pub proposed: u64,
    /// Rays traced.
    pub rays: RayStats,
    /// Things the user should know (no light reaches the camera, a chain hit its bound...).
    pub warnings: Vec<String>,
}

impl SamplerStats {
    /// Acceptance rate of a Metropolis sampler, when it has one.
    pub fn acceptance_rate(&self) -> Option<f64> {
        (self.proposed > 0).then(|| self.accepted as f64 / self.proposed as f64)
    }
}

/// A strategy that places `m` VPLs for a camera.
pub trait VplSampler: Send {
    /// Short name (`sir`, `sir-cdf`, `bir`, `mh`, `mtmh`).
    fn name(&self) -> &'static str;

    /// Produces a VPL set whose gathered image is an (unbiased, for `--clamp 0`) estimate of the
    /// camera's image; `seed` selects independent sets.
    fn sample(&mut self, scene: &Scene, accel: &Accel, camera: &Camera, m: usize, seed: u64) -> (VplSet, SamplerStats);

    /// Forgets any state carried between calls (a Metropolis chain, a light CDF), so the next
    /// `sample` starts afresh. Stateless samplers ignore it.
    fn reset(&mut self) {}

    /// Tells a stateful sampler that the camera jumped (it should not reuse its chain) or moved
    /// a little (it may continue it). Stateless samplers ignore it.
    fn camera_moved(&mut self, jumped: bool) {
        let _ = jumped;
    }
}
