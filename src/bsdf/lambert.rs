//! Lambertian reflection: f = ρ/π.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};

use crate::sampling::warp::{cosine_hemisphere_pdf_w, sample_cosine_hemisphere};

/// f(wo, wi) in the local frame (wo on +z). Reflection only.
#[inline]
pub fn eval(albedo: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    if wo.z * wi.z <= 0.0 { Vec3::ZERO } else { albedo * FRAC_1_PI }
}

/// Cosine-weighted sample on the side of `wo`.
#[inline]
pub fn sample(wo: Vec3, u: Vec2) -> Vec3 {
    let w = sample_cosine_hemisphere(u);
    if wo.z < 0.0 { -w } else { w }
}

/// Solid-angle density of [`sample`].
#[inline]
pub fn pdf_w(wo: Vec3, wi: Vec3) -> f32 {
    if wo.z * wi.z <= 0.0 { 0.0 } else { cosine_hemisphere_pdf_w(wi.z.abs()) }
}
