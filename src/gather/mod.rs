//! ⑥ The gather: G-buffer from primary rays, interleaved VPL subsets, shadow rays, and the
//! clamped contribution `L·f·G·V` (papers/002 §7.2; DESIGN §4). Reads a [`crate::vpl::VplSet`];
//! never changes it.

pub mod gbuffer;
pub mod interleave;
pub mod shade;

pub use gbuffer::GBuffer;
pub use interleave::Interleave;
pub use shade::{GatherEnergy, gather};
