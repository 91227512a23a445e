//! The modified, energy-conserving Phong BRDF (Lafortune & Willems 1994; papers/000 §4.2.1):
//! `f = kd/π + ks (n+2)/(2π) cos^n α`, α the angle between wi and the mirror direction of wo.
//! Reciprocal, and energy conserving when kd + ks ≤ 1 per channel (the loader enforces it).

use std::f32::consts::{FRAC_1_PI, PI};

use glam::{Vec2, Vec3};

use super::frame::Frame;
use super::luminance;
use crate::sampling::warp::{cosine_hemisphere_pdf_w, phong_lobe_pdf_w, sample_cosine_hemisphere, sample_phong_lobe};

/// Mirror direction of `wo` about +z.
#[inline]
fn reflect_z(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

/// Probability of sampling the diffuse lobe.
#[inline]
pub fn diffuse_probability(kd: Vec3, ks: Vec3) -> f32 {
    let d = luminance(kd);
    let s = luminance(ks);
    if d + s <= 0.0 { 1.0 } else { d / (d + s) }
}

/// f(wo, wi) in the local frame (wo on +z).
#[inline]
pub fn eval(kd: Vec3, ks: Vec3, exponent: f32, wo: Vec3, wi: Vec3) -> Vec3 {
    if wo.z * wi.z <= 0.0 {
        return Vec3::ZERO;
    }
    let cos_a = reflect_z(wo).dot(wi).max(0.0);
    kd * FRAC_1_PI + ks * ((exponent + 2.0) / (2.0 * PI) * cos_a.powf(exponent))
}

/// Samples the diffuse lobe or the specular lobe (by [`diffuse_probability`]); `None` when the
/// specular sample falls below the surface.
#[inline]
pub fn sample(kd: Vec3, ks: Vec3, exponent: f32, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
    let wo_up = if wo.z < 0.0 { -wo } else { wo };
    let wi = if u_lobe < diffuse_probability(kd, ks) {
        sample_cosine_hemisphere(u)
    } else {
        let axis = reflect_z(wo_up).normalize();
        Frame::from_normal(axis).to_world(sample_phong_lobe(u, exponent))
    };
    if wi.z <= 0.0 {
        return None;
    }
    Some(if wo.z < 0.0 { -wi } else { wi })
}

/// Solid-angle density of [`sample`] (the mixture of both lobes).
#[inline]
pub fn pdf_w(kd: Vec3, ks: Vec3, exponent: f32, wo: Vec3, wi: Vec3) -> f32 {
    if wo.z * wi.z <= 0.0 {
        return 0.0;
    }
    let pd = diffuse_probability(kd, ks);
    let cos_a = reflect_z(wo).dot(wi);
    pd * cosine_hemisphere_pdf_w(wi.z.abs()) + (1.0 - pd) * phong_lobe_pdf_w(cos_a, exponent)
}
