//! Sampling leaf: random numbers, the [`Sampler`] trait, warps (sample / pdf / invert),
//! discrete distributions and MIS heuristics. Imports nothing from the pipeline.

pub mod distribution;
pub mod mis;
pub mod rng;
pub mod sampler;
pub mod warp;

pub use distribution::{DiscreteSample, Distribution1D, Distribution2D, Sample2D};
pub use mis::{balance_heuristic, power_heuristic};
pub use rng::Pcg32;
pub use sampler::{IndependentSampler, PixelSampler, PixelSamplerKind, Sampler, SobolSampler};
