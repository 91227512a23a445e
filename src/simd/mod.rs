//! SIMD leaf: the only importer of `wide`. Lane types of 4 and 8 `f32` lanes behind one trait
//! ([`Lanes`], with [`LANES_4`] / [`LANES_8`]), the structure-of-arrays vector [`Vec3x`] and the
//! ray packet [`RayPacket`] with its conversions to and from single rays.
//!
//! Kernels elsewhere are generic over `F: Lanes` and instantiated for [`F4`] and [`F8`]; with
//! `-C target-cpu=native` on an AVX-512 machine `F8` compiles to 256-bit AVX instructions with
//! mask registers for comparisons. Imports nothing from the pipeline.

pub mod lanes;
pub mod packet;
pub mod vec3x;

pub use lanes::{F4, F8, F16, LANES_4, LANES_8, Lanes};
pub use packet::{LaneRay, RayPacket};
pub use vec3x::Vec3x;

/// Asks the CPU to start loading the cache lines of `value` (at most the first `lines` of
/// them, 64 bytes each) into L1. A hint only: no effect on results, and no fault whatever the
/// address (x86-64 `prefetcht0`; a no-op on other targets).
#[inline(always)]
#[allow(unsafe_code)]
pub fn prefetch<T>(value: &T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let base = (value as *const T).cast::<i8>();
        for k in 0..lines.min(std::mem::size_of::<T>().div_ceil(64)) {
            // SAFETY: prefetch instructions never fault and do not change memory; `base` points
            // into a live value and `wrapping_add` stays within (or one line past) it.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(base.wrapping_add(64 * k)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (value, lines);
}
