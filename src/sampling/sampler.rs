//! The one interface every stochastic stage draws its random numbers through.

use glam::{Vec2, vec2};

use super::rng::Pcg32;

/// A source of uniform samples in [0, 1).
///
/// Estimators take `&mut impl Sampler` and never own their randomness, so the same estimator can
/// be driven by independent streams (path tracing, VPL sampling) or by a primary-sample-space
/// Markov chain that replays and perturbs the numbers (Kelemen et al. 2002).
pub trait Sampler {
    /// The next uniform number in [0, 1).
    fn next_1d(&mut self) -> f32;

    /// The next two uniform numbers in [0, 1)².
    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        let y = self.next_1d();
        vec2(x, y)
    }
}

/// Independent uniform samples from a hash-seeded PCG32 stream.
#[derive(Clone, Debug)]
pub struct IndependentSampler {
    rng: Pcg32,
}

impl IndependentSampler {
    /// A stream fully determined by `seed`.
    pub fn new(seed: u64) -> Self {
        IndependentSampler { rng: Pcg32::new(seed) }
    }

    /// The stream of one pixel sample: a hash of (seed, pixel index, sample index), so images do
    /// not depend on the order in which threads visit pixels.
    pub fn for_pixel_sample(seed: u64, pixel: u64, sample: u64) -> Self {
        IndependentSampler { rng: Pcg32::from_words(&[seed, 0x0050_4958_454c, pixel, sample]) }
    }

    /// A stream for any other purpose, keyed by a tag and indices (chain, step, light path...).
    pub fn for_stream(seed: u64, tag: u64, index: u64) -> Self {
        IndependentSampler { rng: Pcg32::from_words(&[seed, tag, index]) }
    }

    /// The underlying generator, for integer draws.
    pub fn rng(&mut self) -> &mut Pcg32 {
        &mut self.rng
    }
}

impl Sampler for IndependentSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        self.rng.next_f32()
    }
}
