//! Packet builders for the gather's coherent ray patterns (docs/design.md §4): primary rays of small
//! pixel blocks, and shadow rays that share an end point (one VPL, many pixels) or an origin
//! (one pixel, several VPLs). Every lane is exactly the single ray the scalar code would trace
//! (same camera ray, same [`offset_origin`] policy, same t_max), so packets and single rays give
//! the same answers.

use glam::{Vec2, Vec3, vec2};

use super::{SHADOW_T_MAX, offset_origin};
use crate::scene::{Camera, Scene, SurfacePoint};
use crate::simd::{LaneRay, Lanes, RayPacket};

/// The lanes of the G-buffer's camera packets: 16 (a 4×4 pixel block) where the build targets
/// AVX-512, where a 16-lane comparison is one instruction and the packet kernel traces 16 camera
/// rays faster than two packets of 8; 8 (4×2) otherwise, where 16 lanes are two 8-lane halves.
/// Measured in benches/results/2026-12-06-embree.md (packet rows) and the view loop.
#[cfg(target_feature = "avx512f")]
pub type CameraLanes = crate::simd::F16;
/// See the AVX-512 variant.
#[cfg(not(target_feature = "avx512f"))]
pub type CameraLanes = crate::simd::F8;

/// The pixel block of a packet of `F::LANES` rays: 2×2 for 4 lanes, 4×2 for 8 lanes (lane
/// `i` is pixel `(i mod w, i div w)` of the block).
pub fn block_size<F: Lanes>() -> (u32, u32) {
    match F::LANES {
        16 => (4, 4),
        8 => (4, 2),
        _ => (2, 2),
    }
}

/// Primary rays through the pixel centres of the block whose top-left pixel is (x0, y0), with
/// lens sample `u_lens`; lanes outside the image are inactive.
pub fn primary_packet<F: Lanes>(camera: &Camera, x0: u32, y0: u32, u_lens: Vec2) -> RayPacket<F> {
    let (bw, _) = block_size::<F>();
    RayPacket::from_fn(|i| {
        let (x, y) = (x0 + i as u32 % bw, y0 + i as u32 / bw);
        (x < camera.width && y < camera.height).then(|| {
            let ray = camera.generate_ray(vec2(x as f32 + 0.5, y as f32 + 0.5), u_lens);
            LaneRay::new(ray.origin, ray.dir, f32::INFINITY)
        })
    })
}

/// The primary packets covering the tile `[x0, x0 + w) × [y0, y0 + h)`, block by block in
/// scanline order.
pub fn primary_tile<F: Lanes>(camera: &Camera, x0: u32, y0: u32, w: u32, h: u32, u_lens: Vec2) -> Vec<RayPacket<F>> {
    let (bw, bh) = block_size::<F>();
    let mut out = Vec::with_capacity((w.div_ceil(bw) * h.div_ceil(bh)) as usize);
    for y in (y0..y0 + h).step_by(bh as usize) {
        for x in (x0..x0 + w).step_by(bw as usize) {
            out.push(primary_packet(camera, x, y, u_lens));
        }
    }
    out
}

/// The shadow ray from surface point `sp` to `target`: origin offset off the surface towards
/// the target ([`offset_origin`]), ending just before the target ([`SHADOW_T_MAX`]).
#[inline]
pub fn shadow_ray(scene: &Scene, sp: &SurfacePoint, target: Vec3) -> LaneRay {
    let origin = offset_origin(sp, &scene.mesh.corners(sp.tri), target - sp.p);
    LaneRay::new(origin, target - origin, SHADOW_T_MAX)
}

/// Shadow rays sharing an end point: from each receiver (at most `F::LANES`) to `target`
/// (one VPL or light point seen by many pixels).
pub fn shadow_to_point<F: Lanes>(scene: &Scene, receivers: &[SurfacePoint], target: Vec3) -> RayPacket<F> {
    debug_assert!(receivers.len() <= F::LANES);
    RayPacket::from_fn(|i| receivers.get(i).map(|sp| shadow_ray(scene, sp, target)))
}

/// Shadow rays sharing an origin: from one receiver to each of `targets` (at most `F::LANES`;
/// one pixel and its VPL subset).
pub fn shadow_from_point<F: Lanes>(scene: &Scene, receiver: &SurfacePoint, targets: &[Vec3]) -> RayPacket<F> {
    debug_assert!(targets.len() <= F::LANES);
    RayPacket::from_fn(|i| targets.get(i).map(|&t| shadow_ray(scene, receiver, t)))
}

/// Shadow rays from each receiver to its own target (`pairs` of at most `F::LANES`): the
/// general case, coherent only when the caller groups rays that are.
pub fn shadow_pairs<F: Lanes>(scene: &Scene, pairs: &[(SurfacePoint, Vec3)]) -> RayPacket<F> {
    debug_assert!(pairs.len() <= F::LANES);
    RayPacket::from_fn(|i| pairs.get(i).map(|(sp, t)| shadow_ray(scene, sp, *t)))
}
