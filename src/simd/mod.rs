//! SIMD leaf: the only importer of `wide`. Lane types of 4, 8 and 16 `f32` lanes behind one
//! trait ([`Lanes`], with [`LANES_4`] / [`LANES_8`]), the structure-of-arrays vector [`Vec3x`],
//! the ray packet [`RayPacket`] with its conversions to and from single rays, and [`prefetch`]
//! (the code base's one `unsafe` block: a cache hint).
//!
//! Kernels elsewhere are generic over `F: Lanes` and instantiated for [`F4`] and [`F8`] (the
//! ray kernels) or [`F16`] (the image filter); with `-C target-cpu=native` on an AVX-512 machine
//! `F8` compiles to 256-bit AVX instructions with mask registers for comparisons and `F16` to one
//! 512-bit register. Imports nothing from the pipeline.

pub mod lanes;
pub mod packet;
pub mod vec3x;

pub use lanes::{F4, F8, F16, LANES_4, LANES_8, Lanes};
pub use packet::{LaneRay, RayPacket};
pub use vec3x::Vec3x;

/// Asks the CPU to start loading the 64-byte cache lines `value` spans (at most `lines` of them)
/// into L1. A hint only: no effect on results, and no fault whatever the address (x86-64
/// `prefetcht0`; a no-op on other targets).
#[inline(always)]
#[allow(unsafe_code)]
pub fn prefetch<T>(value: &T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let base = (value as *const T).cast::<i8>();
        // A value need not start on a line: count the lines from its first byte to its last.
        let offset = base as usize % 64;
        let spans = (offset + std::mem::size_of::<T>()).div_ceil(64);
        for k in 0..lines.min(spans) {
            // SAFETY: prefetch instructions never fault and do not change memory; the address
            // (the value's start, then the starts of the following lines it spans) stays inside
            // the live value `value`, since line k > 0 begins before its end.
            let line = if k == 0 { base } else { base.wrapping_add(64 * k - offset) };
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(line) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (value, lines);
}
