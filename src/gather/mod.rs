//! ⑥ The gather: G-buffer from primary rays, interleaved VPL subsets, shadow rays, and the
//! clamped contribution `L·f·G·V` (papers/002 §7.2; DESIGN §4). Reads a [`crate::vpl::VplSet`];
//! never changes it.

pub mod gbuffer;
pub mod interleave;
pub mod shade;

pub use gbuffer::GBuffer;
pub use interleave::Interleave;
pub use shade::{GatherEnergy, gather};

/// How the G-buffer and the gather trace their rays (all give the same image: packet lanes equal
/// single rays, `tests/packet_vs_scalar.rs`; the choice is speed only, `benches/gather.rs` and
/// benches/results/*-gather.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tracing {
    /// One ray at a time everywhere (the fast single-ray traversal).
    Single,
    /// 8-wide packets for the primary rays of 4×2 pixel blocks, single shadow rays: the fastest
    /// on every scene measured (shadow packets win ≤ 10 % on the Cornell box and lose up to
    /// 2.6× on the 1M-triangle sphere field, where the first occluder ends a single ray but
    /// not a packet).
    #[default]
    PrimaryPackets,
    /// Primary packets, and shadow rays in 8-wide packets grouped by shared end point — the
    /// pixels of a row that gather the same VPL subset (every n-th pixel) towards one VPL of it.
    SharedEnd,
    /// Primary packets, and shadow rays in 8-wide packets grouped by shared origin — one pixel
    /// towards the VPLs of its subset (packets are only full with ≥ 8 VPLs per subset, i.e.
    /// m ≥ 8·n·m).
    SharedOrigin,
}
