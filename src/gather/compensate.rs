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

/// A compensation ray sampled at a receiver.
#[derive(Clone, Copy, Debug)]
pub struct ResidualRay {
    /// Origin, offset off the receiver's surface towards `dir`.
    pub origin: Vec3,
    /// Unit direction, sampled from the receiver's BSDF.
    pub dir: Vec3,
    /// |cos θ_x| at the receiver (shading normal).
    pub cos_x: f32,
    /// Receiver throughput × BSDF × cosine / pdf along `dir`.
    pub weight: Vec3,
}

impl Compensation<'_> {
    /// The residual radiance towards `r.wo` of receiver `r` (see the module doc), including
    /// `r.beta`.
    pub fn residual(&self, r: &Receiver, sampler: &mut impl Sampler, st: &mut RayStats) -> Vec3 {
        match self.sample_ray(r, sampler) {
            Some(ray) => self.trace(r.sp.p, &ray, sampler, st),
            None => Vec3::ZERO,
        }
    }

    /// Receiver `r`'s compensation ray, sampled from its BSDF (two samples: lobe, direction);
    /// None where nothing was clamped along it (a specular sample) or no direction was found.
    pub fn sample_ray(&self, r: &Receiver, sampler: &mut impl Sampler) -> Option<ResidualRay> {
        let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
        let bs = r.bsdf.sample(r.wo, u_lobe, u, TransportMode::Radiance)?;
        if bs.delta {
            return None;
        }
        let cos_x = r.bsdf.abs_cos(bs.wi);
        let origin = offset_origin(&r.sp, &self.scene.mesh.corners(r.sp.tri), bs.wi);
        Some(ResidualRay { origin, dir: bs.wi, cos_x, weight: r.beta * bs.f * (cos_x / bs.pdf_w) })
    }

    /// The residual along `ray`, sampled at the receiver at `p`.
    pub fn trace(&self, p: Vec3, ray: &ResidualRay, sampler: &mut impl Sampler, st: &mut RayStats) -> Vec3 {
        let Compensation { scene, accel, g_max, min_d2 } = *self;
        if !g_max.is_finite() || g_max <= 0.0 || !(ray.cos_x > 0.0) {
            return Vec3::ZERO;
        }
        let ResidualRay { origin, dir: wi, cos_x, weight } = *ray;
        st.closest += 1;
        // G = cos θ_x cos θ_y / d² > B needs d < √(cos θ_x / B): nothing further counts.
        let Some(hit) = accel.intersect(origin, wi, (cos_x / g_max).sqrt()) else { return Vec3::ZERO };
        let y = scene.surface_point(hit.tri, hit.b1, hit.b2);
        let d2 = (y.p - p).length_squared();
        if !(d2 > 0.0) || d2 < min_d2 {
            return Vec3::ZERO;
        }
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
