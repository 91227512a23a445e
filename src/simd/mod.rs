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

pub use lanes::{F4, F8, LANES_4, LANES_8, Lanes};
pub use packet::{LaneRay, RayPacket};
pub use vec3x::Vec3x;
