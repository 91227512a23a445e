//! Perfect specular reflection (a delta BSDF).

use glam::Vec3;

/// The reflected direction of `wo` about +z in the local frame.
#[inline]
pub fn reflect(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}
