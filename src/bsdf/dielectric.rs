//! Smooth dielectric interface: Fresnel-weighted specular reflection and refraction (delta
//! BSDF). Local frame: +z is the outside of the surface (the side the normal points to), `eta`
//! is the relative index inside / outside.

use glam::Vec3;

/// Unpolarised Fresnel reflectance for a dielectric; `cos_i` signed w.r.t. +z (outside).
pub fn fresnel(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 { (-cos_i, 1.0 / eta) } else { (cos_i, eta) };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// The refracted direction of `wo` (pointing away from the surface), and the relative index
/// `eta_t / eta_i` along the way; `None` on total internal reflection.
pub fn refract(wo: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let (n, eta_rel, cos_i) = if wo.z >= 0.0 { (Vec3::Z, eta, wo.z) } else { (-Vec3::Z, 1.0 / eta, -wo.z) };
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta_rel * eta_rel);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let wi = -wo / eta_rel + (cos_i / eta_rel - cos_t) * n;
    Some((wi.normalize(), eta_rel))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_at_normal_incidence_and_total_internal_reflection() {
        let r0 = ((1.5f32 - 1.0) / (1.5 + 1.0)).powi(2);
        assert!((fresnel(1.0, 1.5) - r0).abs() < 1e-5);
        assert!((fresnel(-1.0, 1.5) - r0).abs() < 1e-5);
        // Inside glass at grazing incidence: total internal reflection.
        assert_eq!(fresnel(-0.1, 1.5), 1.0);
        assert!(refract(Vec3::new((1.0f32 - 0.01).sqrt(), 0.0, -0.1).normalize(), 1.5).is_none());
    }

    #[test]
    fn refraction_obeys_snell() {
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let (wi, eta) = refract(wo, 1.5).unwrap();
        assert!(wi.z < 0.0);
        let sin_o = (1.0 - wo.z * wo.z).sqrt();
        let sin_i = (1.0 - wi.z * wi.z).sqrt();
        assert!((sin_o - eta * sin_i).abs() < 1e-5);
        assert!(wi.x < 0.0, "refracted ray continues across the normal");
    }
}
