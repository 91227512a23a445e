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
//! G·max(0, 1 − B/G) and changing the second part to solid angle gives the formula). L(y → x)
//! is the radiance leaving y: its emission, plus the clamped VPL gather at y, plus y's own
//! residual, recursively (the gather at y takes the receiver's interleave subset and the VPLs
//! spread over every pixel, as the receiver's own gather does). Estimated with one BSDF-sampled direction per level: only a surface
//! closer than 1/√B can have G > B, so the ray is traced no further than that, and most rays
//! end there at no further cost. Emission at y takes its weight with the cosine at the light's
//! geometric normal (the normal VPLs on lights carry), the reflected part with y's shading
//! normal (that of surface VPLs). Russian roulette on the path's throughput ends it; a
//! specular y (a mirror, glass) is not followed: its residual is left out (biased, documented).

use glam::Vec3;

use super::interleave::Interleave;
use crate::accel::{Accel, offset_origin};
use crate::bsdf::TransportMode;
use crate::color::luminance;
use crate::sampling::Sampler;
use crate::scene::{Ray, Scene};
use crate::stats::RayStats;
use crate::vpl::VplSet;
use crate::vpl::transfer::{Receiver, contribution, receiver_from_hit};

/// Longest compensation path (levels of the recursion).
pub const MAX_LEVELS: u32 = 16;

/// What the residual estimate of one receiver needs.
pub struct Compensation<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its acceleration structure.
    pub accel: &'a Accel,
    /// The VPLs gathered.
    pub vpls: &'a VplSet,
    /// Their subsets.
    pub inter: &'a Interleave,
    /// The gather's bound B on G (finite).
    pub g_max: f32,
    /// Squared distance below which the first segment is left out (the gather's `min_distance`).
    pub min_d2: f32,
}

impl Compensation<'_> {
    /// The residual radiance towards `r.wo` of receiver `r`, which gathers `subset` (see the
    /// module doc), including `r.beta`.
    pub fn residual(&self, r: &Receiver, subset: usize, sampler: &mut impl Sampler, st: &mut RayStats) -> Vec3 {
        let Compensation { scene, accel, vpls, inter, g_max, min_d2 } = *self;
        if !g_max.is_finite() || g_max <= 0.0 {
            return Vec3::ZERO;
        }
        let reach = 1.0 / g_max.sqrt();
        let (ids, scale) = (&inter.subsets[subset], inter.scales[subset]);
        let mut total = Vec3::ZERO;
        let mut beta = r.beta;
        let mut cur = *r;
        for level in 0..MAX_LEVELS {
            let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
            let Some(bs) = cur.bsdf.sample(cur.wo, u_lobe, u, TransportMode::Radiance) else { break };
            if bs.delta {
                break;
            }
            let wi = bs.wi;
            let cos_x = cur.bsdf.abs_cos(wi);
            let origin = offset_origin(&cur.sp, &scene.mesh.corners(cur.sp.tri), wi);
            st.closest += 1;
            let Some(hit) = accel.intersect(origin, wi, reach) else { break };
            let y = scene.surface_point(hit.tri, hit.b1, hit.b2);
            let d2 = (y.p - cur.sp.p).length_squared();
            if !(d2 > 0.0) || (level == 0 && d2 < min_d2) {
                break;
            }
            let weight = bs.f * (cos_x / bs.pdf_w);
            let (recv, emitted) =
                receiver_from_hit(scene, accel, Ray { origin, dir: wi }, Some(hit), &mut || 0.5, 0, st);
            if emitted != Vec3::ZERO {
                let g = cos_x * y.ng.dot(wi).abs() / d2;
                total += beta * weight * emitted * (1.0 - g_max / g).max(0.0);
            }
            let Some(mut recv) = recv else { break };
            let g = cos_x * recv.bsdf.abs_cos(wi) / d2;
            let keep = (1.0 - g_max / g).max(0.0);
            if keep <= 0.0 {
                break;
            }
            beta *= weight * keep;
            recv.beta = Vec3::ONE;
            let mut gathered = Vec3::ZERO;
            for &i in ids {
                gathered += contribution(scene, accel, vpls, i as usize, &recv, g_max, st);
            }
            gathered *= scale;
            for &i in &inter.everywhere {
                gathered += contribution(scene, accel, vpls, i as usize, &recv, g_max, st);
            }
            total += beta * gathered;
            // Russian roulette on the throughput (it only shrinks: keep ≤ 1, albedo < 1).
            let q = luminance(beta).min(1.0);
            if !(q > 0.0) || sampler.next_1d() >= q {
                break;
            }
            beta /= q;
            cur = recv;
        }
        total
    }
}
