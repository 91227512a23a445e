//! Compensation of the geometry-term clamp (Kollig & Keller 2004, "Illumination in the presence
//! of weak singularities", §3; docs/bibliography.md): what the clamp removes from a receiver is
//! estimated by a short path from the receiver, so that the clamped gather plus the residual
//! has the expectation of the unclamped gather, with finite variance.
//!
//! The gather bounds G(x, y) = cos θ_x cos θ_y / |x − y|² at B. The light it removes at a
//! receiver x towards ω_o is, with y(ω) the surface seen from x in direction ω,
//!
//! ```text
//! L_r(x, ω_o) = ∫_Ω f(x, ω, ω_o) L(y(ω) → x) |cos θ_x| max(0, 1 − B / G(x, y(ω))) dω
//! ```
//!
//! (the VPLs estimate the integral over surfaces of f L G; splitting G = min(G, B) +
//! G·max(0, 1 − B/G) and changing the second part to solid angle gives the formula; this is
//! Kollig & Keller's eq. 5 with their bound b = B). It is estimated with one BSDF-sampled
//! direction per receiver: only a surface closer than 1/√B can have G > B, so the ray is
//! traced no further than that, and most rays end there at no further cost. Where it finds
//! such a surface y, L(y → x) is y's emission (weighted with the cosine at the light's
//! geometric normal, the normal VPLs on lights carry) plus the light y reflects, estimated by
//! the path tracer ([`crate::offline::pt::radiance`], weighted with y's shading normal, that of
//! surface VPLs). A specular y carries no VPL, so nothing was clamped there: it is skipped.
//!
//! Kollig & Keller estimate the reflected light at y with the VPLs themselves, recursively.
//! That is unbiased for VPLs that are a physical estimate of the light everywhere (instant
//! radiosity's), but not usable with MIR's: those are placed in proportion to their response
//! to the camera, so the surfaces next to a receiver that the camera does not see (the faces of
//! a slit, of a tunnel) are lit only by rare VPLs of enormous weight, or by none. Measured on
//! `ajar-door-thick` (32×24, 32 seeds × 16 frames): the recursive VPL residual added 0.157 of
//! pt's light where the clamp had removed 0.30 (image 0.85 × pt); the path-traced one adds
//! 0.287 (image 0.98 ± 0.03 × pt). The path tracer does not depend on which VPLs there are.

use glam::Vec3;

use crate::accel::{Accel, offset_origin};
use crate::bsdf::TransportMode;
use crate::offline::pt;
use crate::sampling::Sampler;
use crate::scene::{Ray, Scene};
use crate::stats::RayStats;
use crate::vpl::transfer::{Receiver, receiver_from_hit};

/// Longest path the path tracer follows from a surface found by a compensation ray (bounces;
/// Russian roulette ends most paths far earlier).
pub const MAX_DEPTH: u32 = 128;

/// What the residual estimate of one receiver needs.
#[derive(Clone, Copy)]
pub struct Compensation<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its acceleration structure.
    pub accel: &'a Accel,
    /// The gather's bound B on G (finite).
    pub g_max: f32,
    /// Squared distance below which the segment is left out (the gather's `min_distance`).
    pub min_d2: f32,
}

impl Compensation<'_> {
    /// The residual radiance towards `r.wo` of receiver `r` (see the module doc), including
    /// `r.beta`.
    pub fn residual(&self, r: &Receiver, sampler: &mut impl Sampler, st: &mut RayStats) -> Vec3 {
        let Compensation { scene, accel, g_max, min_d2 } = *self;
        if !g_max.is_finite() || g_max <= 0.0 {
            return Vec3::ZERO;
        }
        let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
        let Some(bs) = r.bsdf.sample(r.wo, u_lobe, u, TransportMode::Radiance) else { return Vec3::ZERO };
        if bs.delta {
            return Vec3::ZERO;
        }
        let wi = bs.wi;
        let cos_x = r.bsdf.abs_cos(wi);
        let origin = offset_origin(&r.sp, &scene.mesh.corners(r.sp.tri), wi);
        st.closest += 1;
        let Some(hit) = accel.intersect(origin, wi, 1.0 / g_max.sqrt()) else { return Vec3::ZERO };
        let y = scene.surface_point(hit.tri, hit.b1, hit.b2);
        let d2 = (y.p - r.sp.p).length_squared();
        if !(d2 > 0.0) || d2 < min_d2 {
            return Vec3::ZERO;
        }
        let weight = r.beta * bs.f * (cos_x / bs.pdf_w);
        let ray = Ray { origin, dir: wi };
        let (recv, emitted) = receiver_from_hit(scene, accel, ray, Some(hit), &mut || 0.5, 0, st);
        let mut total = Vec3::ZERO;
        if emitted != Vec3::ZERO {
            let g = cos_x * y.ng.dot(wi).abs() / d2;
            total += weight * emitted * (1.0 - g_max / g).max(0.0);
        }
        let Some(recv) = recv else { return total };
        let keep = (1.0 - g_max * d2 / (cos_x * recv.bsdf.abs_cos(wi))).max(0.0);
        // The light y reflects towards x, weighted by `keep`: traced with probability `keep`
        // and then counted at weight 1 (Russian roulette: the same expectation, and no path
        // where the clamp removed little).
        if keep > 0.0 && sampler.next_1d() < keep {
            // The path tracer's estimate along the same ray, less the emission it counts at y
            // (weighted above).
            let (l, _) = pt::radiance(scene, accel, ray, sampler, MAX_DEPTH, st);
            total += weight * (l - emitted);
        }
        total
    }
}
