//! BSDF leaf: Lambert, energy-conserving Phong, mirror and smooth dielectric, evaluated in a
//! shading frame. Imports nothing from the pipeline.
//!
//! Sidedness: reflective BSDFs scatter on both sides of a surface: [`Bsdf::new`] turns the
//! frame to face `wo`. A dielectric keeps the surface's own orientation (its normal points
//! outside), because inside and outside differ.
//!
//! Delta BSDFs (mirror, dielectric) are flagged: `f` and `pdf_w` of a non-sampled pair are zero,
//! and a sample carries `delta = true` with `f` and `pdf_w` chosen so that `f·|cos|/pdf_w` is
//! the scattering weight (pbrt's convention; no infinities).

pub mod dielectric;
pub mod frame;
pub mod lambert;
pub mod mirror;
pub mod phong;

use glam::{Vec2, Vec3};

pub use crate::color::luminance;
pub use frame::Frame;

/// Which quantity a path carries, for the non-symmetric scattering of refraction
/// (Veach 1997, §5.2): radiance from the camera side, importance from the light side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    /// The path was traced from the camera; it carries radiance.
    Radiance,
    /// The path was traced from a light; it carries importance.
    Importance,
}

/// The scattering model of a surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BsdfKind {
    /// Lambertian reflection with the given albedo.
    Lambert {
        /// Diffuse albedo ρ.
        albedo: Vec3,
    },
    /// Modified Phong: diffuse + glossy lobe.
    Phong {
        /// Diffuse albedo.
        kd: Vec3,
        /// Specular albedo.
        ks: Vec3,
        /// Phong exponent n.
        exponent: f32,
    },
    /// Perfect mirror.
    Mirror {
        /// Reflectance.
        reflectance: Vec3,
    },
    /// Smooth dielectric interface.
    Dielectric {
        /// Index of refraction inside / outside.
        eta: f32,
        /// Transmission and reflection tint.
        tint: Vec3,
    },
}

/// One sampled scattering direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled incident direction (world space, pointing away from the surface).
    pub wi: Vec3,
    /// BSDF value f(wo, wi).
    pub f: Vec3,
    /// Solid-angle density of `wi` (a discrete probability for delta samples).
    pub pdf_w: f32,
    /// True for specular (delta) events.
    pub delta: bool,
}

/// A BSDF placed at a surface point.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    /// The scattering model.
    pub kind: BsdfKind,
    /// Shading frame (normal facing `wo` for reflective models).
    pub frame: Frame,
    /// Geometric normal, on the same side as `frame.n`.
    pub ng: Vec3,
}

impl Bsdf {
    /// Places `kind` at a point with shading normal `ns` and geometric normal `ng` (unit), seen
    /// from direction `wo`.
    pub fn new(kind: BsdfKind, ns: Vec3, ng: Vec3, wo: Vec3) -> Self {
        let (ns, ng) = match kind {
            BsdfKind::Dielectric { .. } => {
                let ng = if ng.dot(ns) < 0.0 { -ng } else { ng };
                (ns, ng)
            }
            _ => {
                let ng = if ng.dot(wo) < 0.0 { -ng } else { ng };
                let ns = if ns.dot(ng) < 0.0 { -ns } else { ns };
                (ns, ng)
            }
        };
        Bsdf { kind, frame: Frame::from_normal(ns), ng }
    }

    /// True when the BSDF is a pure delta distribution (mirror, dielectric).
    #[inline]
    pub fn is_delta(&self) -> bool {
        matches!(self.kind, BsdfKind::Mirror { .. } | BsdfKind::Dielectric { .. })
    }

    /// The diffuse albedo (for AOVs and the discontinuity buffer); white-ish for specular.
    pub fn albedo(&self) -> Vec3 {
        match self.kind {
            BsdfKind::Lambert { albedo } => albedo,
            BsdfKind::Phong { kd, ks, .. } => kd + ks,
            BsdfKind::Mirror { reflectance } => reflectance,
            BsdfKind::Dielectric { tint, .. } => tint,
        }
    }

    /// f(wo, wi) for world directions; zero for delta BSDFs and for pairs on inconsistent
    /// sides of the geometric surface (no light leaks through shading normals).
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let reflect = wo.dot(self.ng) * wi.dot(self.ng) > 0.0;
        if !reflect {
            return Vec3::ZERO;
        }
        let (lo, li) = (self.frame.to_local(wo), self.frame.to_local(wi));
        match self.kind {
            BsdfKind::Lambert { albedo } => lambert::eval(albedo, lo, li),
            BsdfKind::Phong { kd, ks, exponent } => phong::eval(kd, ks, exponent, lo, li),
            BsdfKind::Mirror { .. } | BsdfKind::Dielectric { .. } => Vec3::ZERO,
        }
    }

    /// Solid-angle density with which [`sample`](Self::sample) picks `wi` given `wo`.
    pub fn pdf_w(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.dot(self.ng) * wi.dot(self.ng) <= 0.0 {
            return 0.0;
        }
        let (lo, li) = (self.frame.to_local(wo), self.frame.to_local(wi));
        match self.kind {
            BsdfKind::Lambert { .. } => lambert::pdf_w(lo, li),
            BsdfKind::Phong { kd, ks, exponent } => phong::pdf_w(kd, ks, exponent, lo, li),
            BsdfKind::Mirror { .. } | BsdfKind::Dielectric { .. } => 0.0,
        }
    }

    /// Samples wi given wo with two uniform numbers for the direction and one for the lobe.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let lo = self.frame.to_local(wo);
        if lo.z == 0.0 {
            return None;
        }
        let (li, f, pdf_w, delta) = match self.kind {
            BsdfKind::Lambert { albedo } => {
                let li = lambert::sample(lo, u);
                (li, lambert::eval(albedo, lo, li), lambert::pdf_w(lo, li), false)
            }
            BsdfKind::Phong { kd, ks, exponent } => {
                let li = phong::sample(kd, ks, exponent, lo, u_lobe, u)?;
                (li, phong::eval(kd, ks, exponent, lo, li), phong::pdf_w(kd, ks, exponent, lo, li), false)
            }
            BsdfKind::Mirror { reflectance } => {
                let li = mirror::reflect(lo);
                (li, reflectance / li.z.abs(), 1.0, true)
            }
            BsdfKind::Dielectric { eta, tint } => {
                let fr = dielectric::fresnel(lo.z, eta);
                if u_lobe < fr {
                    let li = mirror::reflect(lo);
                    (li, tint * (fr / li.z.abs()), fr, true)
                } else {
                    let (li, eta_rel) = dielectric::refract(lo, eta)?;
                    let mut ft = tint * ((1.0 - fr) / li.z.abs());
                    if mode == TransportMode::Radiance {
                        // Radiance is compressed into the denser medium (Veach 1997, §5.2).
                        ft /= eta_rel * eta_rel;
                    }
                    (li, ft, 1.0 - fr, true)
                }
            }
        };
        if pdf_w <= 0.0 || !pdf_w.is_finite() || li.z == 0.0 {
            return None;
        }
        let wi = self.frame.to_world(li);
        // Reject directions whose geometric side contradicts the sampled event.
        let same_side_shading = lo.z * li.z > 0.0;
        let same_side_geometric = wo.dot(self.ng) * wi.dot(self.ng) > 0.0;
        if same_side_shading != same_side_geometric {
            return None;
        }
        Some(BsdfSample { wi, f, pdf_w, delta })
    }

    /// |cos| between `w` and the shading normal.
    #[inline]
    pub fn abs_cos(&self, w: Vec3) -> f32 {
        w.dot(self.frame.n).abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;
    use glam::vec2;

    fn bsdfs() -> Vec<BsdfKind> {
        vec![
            BsdfKind::Lambert { albedo: Vec3::new(0.8, 0.5, 0.2) },
            BsdfKind::Phong { kd: Vec3::splat(0.3), ks: Vec3::splat(0.6), exponent: 30.0 },
            BsdfKind::Phong { kd: Vec3::splat(0.0), ks: Vec3::splat(0.9), exponent: 1.0 },
        ]
    }

    /// ∫ f |cos| dωi = albedo ≤ 1 estimated by importance sampling; sample weights must agree
    /// with eval / pdf.
    #[test]
    fn sampled_weights_match_eval_over_pdf_and_conserve_energy() {
        let n = Vec3::new(0.2, 0.3, 0.9).normalize();
        let wo = Vec3::new(-0.4, 0.1, 0.5).normalize();
        for kind in bsdfs() {
            let b = Bsdf::new(kind, n, n, wo);
            let mut r = Pcg32::new(9);
            let count = 200_000;
            let mut sum = Vec3::ZERO;
            for _ in 0..count {
                let Some(s) = b.sample(wo, r.next_f32(), vec2(r.next_f32(), r.next_f32()), TransportMode::Radiance)
                else {
                    continue;
                };
                let f = b.f(wo, s.wi);
                let p = b.pdf_w(wo, s.wi);
                assert!((f - s.f).abs().max_element() < 1e-3 * f.max_element().max(1.0), "{kind:?}");
                assert!((p - s.pdf_w).abs() < 1e-3 * p.max(1.0), "{kind:?}");
                sum += s.f * b.abs_cos(s.wi) / s.pdf_w;
            }
            let albedo = sum / count as f32;
            assert!(albedo.max_element() <= 1.0 + 0.01, "{kind:?}: {albedo}");
        }
    }

    #[test]
    fn surfaces_reflect_on_both_sides() {
        let kind = BsdfKind::Lambert { albedo: Vec3::ONE };
        let n = Vec3::Z;
        let wo = -Vec3::new(0.1, 0.2, 0.9).normalize();
        let b = Bsdf::new(kind, n, n, wo);
        let wi = Vec3::new(0.3, -0.2, -0.9).normalize();
        assert!(b.f(wo, wi).x > 0.0);
        assert_eq!(b.f(wo, -wi), Vec3::ZERO);
    }

    /// Lambert albedo estimate equals ρ exactly (cosine sampling has zero variance).
    #[test]
    fn lambert_cosine_sampling_weight_is_the_albedo() {
        let rho = Vec3::new(0.7, 0.4, 0.1);
        let b = Bsdf::new(BsdfKind::Lambert { albedo: rho }, Vec3::Y, Vec3::Y, Vec3::Y);
        let s = b.sample(Vec3::Y, 0.5, vec2(0.3, 0.8), TransportMode::Radiance).unwrap();
        assert!((s.f * b.abs_cos(s.wi) / s.pdf_w - rho).abs().max_element() < 1e-5);
    }

    #[test]
    fn dielectric_conserves_energy_in_importance_mode() {
        let b = Bsdf::new(BsdfKind::Dielectric { eta: 1.5, tint: Vec3::ONE }, Vec3::Z, Vec3::Z, Vec3::Z);
        let wo = Vec3::new(0.5, 0.0, 0.8).normalize();
        let mut r = Pcg32::new(2);
        let mut sum = 0.0;
        let n = 20_000;
        for _ in 0..n {
            if let Some(s) = b.sample(wo, r.next_f32(), vec2(0.5, 0.5), TransportMode::Importance) {
                sum += s.f.x * b.abs_cos(s.wi) / s.pdf_w;
            }
        }
        assert!((sum / n as f32 - 1.0).abs() < 1e-3);
    }
}
